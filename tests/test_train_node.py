"""The train as a network FMU (issue 42): the train-dynamics model behind an FMI-LS-BUS CAN
terminal, closed over the bus with the monitor node in an fmu-manipulation-toolbox container
run by FMPy, held to the signal co-simulation (fmu/cosim.py) of the same scenario: the same
demands cycle by cycle and the same stop; and a 0x000 flood that starves BrakeDemand makes
the train model's alive timeout brake."""
from __future__ import annotations

import csv
import subprocess
from importlib import resources

import pytest

from can_bus import keys as keyfiles
from fmu import build, cosim, lsbus_system as S, network_nodes, scenario, train_node
from fmu.build import BuildError
from monitor import tables

SCENARIO = "static-obstacle"
STEP = 1e-4                 # the container's step
PERIOD = 0.1
OUTPUTS = ["position", "true_speed", "brake_level", "applied_demand", "applied_cycle", "frames_rx", "frames_rejected",
           "frames_tx", "demand_frames", "receiver_brake", "receiver_brake_time", "last_demand_time", "collided",
           "secured"]


@pytest.fixture(scope="module")
def scen():
    return scenario.load(SCENARIO)            # as `railguard cosim static-obstacle` loads it


@pytest.fixture(scope="module")
def signal(scen, tmp_path_factory):
    out = tmp_path_factory.mktemp("signal")
    monitor = build.build_monitor(tables.read(scen.table), 2, out)
    return cosim.run_scenario(scen, monitor, build.build_train(out))


@pytest.fixture(scope="module", params=[False], ids=["classical"])   # secured: tests/test_cosim_bus.py
def system(request, scen, tmp_path_factory):
    out = tmp_path_factory.mktemp("trainnode")
    keys = None
    if request.param:
        keys = out / "keys"
        keyfiles.new_set(keys, test=True)
    monitor = network_nodes.build_monitor_node(tables.read(scen.table), out, keys=keys)
    train = train_node.build_train_node(out, scen.train, keys=keys)
    return out, monitor, train, S.build_bus(2, out), request.param


def run(system, name: str, duration: float, starts: dict | None = None):
    from fmpy import simulate_fmu
    out, monitor, train, bus, _ = system
    trace = out / f"{name}.csv"
    container = S.build_container([S.Node(monitor), S.Node(train)], bus, out / f"{name}.fmu", STEP,
                                  {("canbus.fmu", "trace_file"): str(trace), **(starts or {})},
                                  [("train.fmu", n, n) for n in OUTPUTS] + [("monitor.fmu", "cycle", "monitor_cycles")])
    result = simulate_fmu(str(container), stop_time=duration, step_size=STEP, output_interval=PERIOD,
                          use_event_mode=False, fmi_type="CoSimulation")
    with open(trace) as fh:
        rows = list(csv.DictReader(fh))
    return {n: result[n][-1] for n in result.dtype.names}, rows


def decoded(rows, frame_id: int):
    """(end_s, raw signals) of every frame_id delivered (secured frames: the payload first)."""
    import cantools
    db = cantools.database.load_file(str(resources.files("can_bus").joinpath("railguard.dbc")))
    return [(float(r["end_s"]), db.decode_message(frame_id, bytes.fromhex(r["data"])[:8], decode_choices=False,
                                                  scaling=False))
            for r in rows if r["id"] == f"0x{frame_id:03X}" and r["kind"] == "delivered"]


def brake_demands(rows):
    """(end_s, Cycle, Level) of every BrakeDemand delivered."""
    return [(t, d["Cycle"], d["Level"]) for t, d in decoded(rows, 0x10)]


@pytest.fixture(scope="module")
def closed(system, scen):
    return run(system, "closed", scen.duration_s)


def test_the_train_and_monitor_nodes_validate_in_fmpy_and_the_toolbox_checker(system):
    from fmpy.validation import validate_fmu
    for fmu in system[1:3]:
        assert validate_fmu(str(fmu)) == [], fmu.name
        res = subprocess.run(["fmutool", "-input", str(fmu), "-check"], capture_output=True, text=True)
        text = res.stdout + res.stderr
        assert res.returncode == 0 and "No semantic error" in text and "compliant with FMI-3.0" in text, text


def test_over_the_bus_the_train_stops_where_the_signal_cosimulation_stops_it(system, closed, signal):
    final, rows = closed
    c = {n: i for i, n in enumerate(signal.columns)}
    assert signal.outcome == "stopped" and signal.first_brake_s is not None
    assert final["secured"] == system[4]
    assert final["true_speed"] == 0.0 and not final["collided"]
    # the same 10 ms steps under the same demands at the same grid instants: the same doubles
    assert final["position"] == pytest.approx(signal.rows[-1][c["position"]], abs=1e-9)
    assert final["frames_rejected"] == 0 and not final["receiver_brake"] and final["receiver_brake_time"] == -1.0


def test_the_monitor_node_demands_what_the_signal_monitor_demands_cycle_by_cycle(closed, signal, scen):
    final, rows = closed
    c = {n: i for i, n in enumerate(signal.columns)}
    ratio = round(PERIOD / 0.01)
    expected = [(r[c["cycle"]], r[c["brake_demand"]]) for r in signal.rows[::ratio]]
    got = [(cycle, level) for _, cycle, level in brake_demands(rows)]
    assert len(got) == len(expected) == round(scen.duration_s / PERIOD)
    assert got == expected
    assert {level for _, level in got} >= {0, 1} and max(level for _, level in got) == signal.max_demand
    assert final["demand_frames"] == len(got) and final["applied_cycle"] == got[-2][0]   # the last one acts next
    # what it saw: the voted distance (dm), the table node and the mode of every cycle (MonitorStatus)
    status = [(d["VotedDistance"], d["Node"], d["Mode"]) for _, d in decoded(rows, 0x40)]
    signal_status = [(r[c["voted_distance_dm"]], r[c["node"]], r[c["mode"]]) for r in signal.rows[::ratio]]
    assert status == signal_status and len({v for v, _, _ in status}) > 100


def test_a_silent_channel_sends_nothing(closed, scen):
    final, rows = closed
    fault = scen.train
    assert fault["fault.kind"] == 1                               # silence
    fid = f"0x{0x20 + fault['fault.channel'] - 1:03X}"
    sent = [float(r["queued_s"]) for r in rows if r["id"] == fid and r["kind"] == "delivered"]
    silent = round((fault["fault.end"] - fault["fault.start"]) / PERIOD)
    assert not [t for t in sent if fault["fault.start"] - 1e-9 <= t < fault["fault.end"] - 1e-9]
    assert len(sent) == round(scen.duration_s / PERIOD) - silent
    assert final["frames_tx"] == 7 * round(scen.duration_s / PERIOD) - silent


def test_a_flood_at_0x000_starves_brake_demand_and_the_alive_timeout_brakes(system, signal):
    timeout = 0.5                                                 # a container start value
    final, rows = run(system, "flood", 20.0, {("canbus.fmu", "flood_id"): 0, ("canbus.fmu", "flood_start"): 3.0,
                                             ("train.fmu", "brake_timeout"): timeout})
    demands = brake_demands(rows)
    last = demands[-1][0]
    assert 2.9 < last < 3.0 and final["last_demand_time"] == pytest.approx(last, abs=2 * STEP)
    assert final["receiver_brake"] and final["brake_level"] == 2          # emergency, held
    # the cycle it carried acts at the next instant; the timeout (0.5 s, not the built 0.3 s) counts from there
    assert last + timeout <= final["receiver_brake_time"] <= last + timeout + PERIOD
    assert final["true_speed"] == 0.0 and not final["collided"]
    c = {n: i for i, n in enumerate(signal.columns)}
    assert final["position"] < signal.rows[-1][c["position"]]               # braked earlier than the monitor would


def test_the_builder_refuses_unknown_parameters_and_leaves_the_train_model_as_it_is():
    with pytest.raises(BuildError, match="not train parameters: bogus"):
        train_node.train_spec({"bogus": 1.0})
    staged = dict(train_node.staged_train_model())
    assert '#include "train_variables.h"' in staged["train_model.c"] and '#include "train_model.h"' in staged["train_model.c"]
    assert '#include "train_config.h"' in staged["train_model.h"]
    for text in staged.values():
        assert '#include "config.h"' not in text and '#include "variables.h"' not in text
