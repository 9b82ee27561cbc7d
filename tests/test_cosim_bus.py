"""`railguard cosim SCENARIO --bus ls-bus` as a user runs it (issue 42): the monitor and the
train as network FMUs on the simulated CAN bus stop the train where the signal co-simulation
does; a babbling node at 0x000 starves BrakeDemand and the train's receiver brakes; the SSP it
writes is the same system."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from fmu.bus_timing import read_trace


def railguard(*args, check=True):
    res = subprocess.run([sys.executable, "-m", "railguard", *args], capture_output=True, text=True)
    if check:
        assert res.returncode == 0, res.stderr[-2000:]
    return res


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("cosim-bus")
    signal = json.loads(railguard("cosim", "static-obstacle", "--out", str(out / "signal"), "--json").stdout)
    bus = json.loads(railguard("cosim", "static-obstacle", "--bus", "ls-bus", "--out", str(out / "bus"),
                               "--json").stdout)
    flood = json.loads(railguard("cosim", "static-obstacle", "--bus", "ls-bus", "--flood-id", "0x000",
                                 "--flood-start", "20", "--flood-stop", "22", "--out", str(out / "flood"),
                                 "--json").stdout)
    stop = json.loads(railguard("cosim", "monitor-stop-30", "--bus", "ls-bus", "--out", str(out / "stop"),
                                "--json").stdout)
    return out, signal, bus, flood, stop


def test_over_the_bus_the_train_stops_where_the_signal_cosimulation_stops_it(runs):
    _, signal, bus, _, _ = runs
    assert bus["outcome"] == signal["outcome"] == "stopped"
    assert bus["margin_m"] == pytest.approx(signal["margin_m"], abs=1e-3)
    assert bus["first_brake_s"] == pytest.approx(signal["first_brake_s"], abs=1e-9)
    assert bus["secured"] and bus["receiver_brake_s"] is None
    assert bus["brake_demand_max_queue_delay_ms"] == 0.0          # BrakeDemand has the bus's highest priority
    for name in ("csv", "trace", "plot", "container", "ssp"):
        assert (runs[0] / "bus").exists() and __import__("pathlib").Path(bus[name]).is_file(), name


def test_a_flood_at_0x000_starves_brake_demand_and_the_receiver_brakes(runs):
    _, _, bus, flood, _ = runs
    rows = read_trace(flood["trace"])
    brake = [r for r in rows if r["id"] == "0x010" and r["kind"] == "delivered"]
    last = max(float(r["end_s"]) for r in brake if float(r["end_s"]) < 20.0)
    assert not any(20.0 < float(r["start_s"]) < 22.0 for r in brake)        # nothing gets through the flood
    assert flood["brake_demand_max_queue_delay_ms"] > 1900                    # frames queued since 20 s left at 22 s
    # the train model's alive timeout (0.3 s) on its 10 ms grid, after the last BrakeDemand it got
    assert last + 0.3 <= flood["receiver_brake_s"] <= last + 0.3 + 0.1
    assert flood["outcome"] == "stopped" and flood["stop_position_m"] < bus["stop_position_m"] - 50
    assert flood["peak_load_100ms"] == 1.0


def test_a_monitor_that_stops_is_caught_by_the_train_s_receiver(runs):
    """monitor-stop-30: the monitor node runs no cycle from 5 s on (a crash or a hang); its
    BrakeDemand falls silent and the train's alive check brakes 0.3 s later, as in the signal
    co-simulation (docs/fmu.md: 5.3 s, 1,183.7 m short of the obstacle)."""
    stop = runs[4]
    assert stop["receiver_brake_s"] == pytest.approx(5.3, abs=1e-9) and stop["max_demand"] == 0
    assert stop["outcome"] == "stopped" and stop["margin_m"] == pytest.approx(1183.681, abs=1e-3)


def test_the_ssp_is_the_system_that_ran(runs, tmp_path):
    """fmucontainer builds a container from the SSP; run by FMPy it stops the train where the
    command's container did."""
    from fmu_manipulation_toolbox.assembly import Assembly

    from fmu.lsbus_system import STEP_S, quiet_stdout, run_container
    _, _, bus, _, _ = runs
    ssp = tmp_path / "system.ssp"
    ssp.write_bytes(open(bus["ssp"], "rb").read())
    with quiet_stdout():
        Assembly("system.ssp", fmu_directory=tmp_path, default_step_size=STEP_S, default_sequential=True).make_fmu(
            fmi_version=3)
    result = run_container(tmp_path / "system.fmu", 60.0, 1.0)
    assert result["train.position"][-1] == pytest.approx(bus["stop_position_m"], abs=1e-3)   # the summary rounds to mm
    assert result["monitor.cycle"][-1] == 600


@pytest.mark.parametrize("args, message", [
    (["--bus", "ls-bus", "--step", "0.05"], "--step: options of the signal co-simulation"),
    (["--flood-id", "0"], "--flood-id: options of --bus ls-bus"),
])
def test_wrong_options_are_one_line_and_exit_2(args, message, tmp_path):
    res = railguard("cosim", "static-obstacle", *args, "--out", str(tmp_path), check=False)
    assert res.returncode == 2 and message in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr


@pytest.mark.parametrize("flood_id, start, stop, error_id, count, message", [
    (0x800, None, None, None, None, "11-bit CAN identifier"),
    (None, 3.0, None, None, None, "need --flood-id"),
    (0, 5.0, 4.0, None, None, "must be after"),
    (None, None, None, None, 2, "--error-count needs --error-id"),
])
def test_the_bus_faults_are_checked_before_anything_is_built(flood_id, start, stop, error_id, count, message):
    import argparse

    from railguard.commands.cosim_bus import faults_of
    from railguard.errors import UserError
    args = argparse.Namespace(flood_id=flood_id, flood_start=start, flood_stop=stop, error_id=error_id,
                              error_count=count)
    with pytest.raises(UserError, match=message):
        faults_of(args)
    ok = faults_of(argparse.Namespace(flood_id=0, flood_start=20.0, flood_stop=22.0, error_id=0x10, error_count=None))
    assert (ok.flood_id, ok.flood_start_s, ok.flood_stop_s, ok.error_id, ok.error_count) == (0, 20.0, 22.0, 0x10, 1)
