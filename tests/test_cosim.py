"""The closed loop in FMPy: train-dynamics FMU + monitor FMU, the shipped scenarios, the
SSP of the same loop, and the `build-fmu` / `cosim` commands (issue 5)."""
from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from fmu import cosim, scenario
from fmu.scenario import CosimScenarioError

OBSTACLE_SCENARIOS = ["static-obstacle", "late-obstacle", "moving-obstacle"]
FAULT_SCENARIOS = [s for s in scenario.shipped() if s.startswith("fault-")]


def run(name: str, monitor_fmus, train_fmu, table: str | None = None, fmi: int = 2):
    scen = scenario.load(name)
    return scen, cosim.run(monitor_fmus[(table or scen.table, fmi)], train_fmu, scen.train, scen.monitor, scen.duration_s)


def column(result, name: str) -> list:
    i = result.columns.index(name)
    return [row[i] for row in result.rows]


def test_every_fault_kind_has_a_shipped_scenario():
    assert len(FAULT_SCENARIOS) == 7
    kinds = {scenario.load(s).train["fault.kind"] for s in FAULT_SCENARIOS}
    assert kinds == set(range(1, 8))


@pytest.mark.parametrize("name", ["static-obstacle", "late-obstacle"])
@pytest.mark.parametrize("table", ["m1", "m2"])
def test_train_stops_before_a_static_obstacle(name, table, monitor_fmus, train_fmu):
    scen, res = run(name, monitor_fmus, train_fmu, table)
    assert res.outcome == "stopped", (res.outcome, res.margin_m)
    assert res.margin_m > 0
    dist = column(res, "true_distance")
    assert min(dist) > 0
    # the obstacle came into sensor range before braking started, and braking brought the train to 0
    range_m = scen.train["sensor.range"]
    seen_at = next(r[0] for r in res.rows if r[res.columns.index("true_distance")] <= range_m)
    assert res.first_brake_s is not None and res.first_brake_s >= seen_at - 0.1
    assert column(res, "train.speed")[-1] == 0.0


def test_late_obstacle_is_seen_at_the_emergency_braking_distance_plus_margin(monitor_fmus, train_fmu):
    """The scenario the issue names: sensor range = emergency braking distance + margin."""
    from monitor.core.envelope import braking_distance_dm

    scen, res = run("late-obstacle", monitor_fmus, train_fmu)
    alpha2_m = braking_distance_dm(round(scen.train["initial_speed"] * 100), 3000, 500) / 10
    assert alpha2_m < scen.train["sensor.range"] < alpha2_m + 30
    assert res.outcome == "stopped" and res.margin_m > 0
    assert res.max_demand == 2        # only the emergency envelope can stop the train in time


def test_moving_obstacle_is_never_hit(monitor_fmus, train_fmu):
    _, res = run("moving-obstacle", monitor_fmus, train_fmu)
    assert res.outcome in ("stopped", "running")
    assert min(column(res, "true_distance")) > 0
    assert res.max_demand >= 1


def test_clear_track_no_false_braking(monitor_fmus, train_fmu):
    _, res = run("no-obstacle", monitor_fmus, train_fmu)
    assert res.outcome == "no_obstacle"
    assert res.max_demand == 0 and res.first_brake_s is None
    assert set(column(res, "mode")) == {1}             # NORMAL throughout
    assert column(res, "train.speed")[-1] == pytest.approx(30.0, abs=0.01)


@pytest.mark.parametrize("name", FAULT_SCENARIOS)
def test_every_single_fault_ends_in_braking(name, monitor_fmus, train_fmu):
    scen, res = run(name, monitor_fmus, train_fmu)
    start = scen.train["fault.start"]
    assert res.first_brake_s is not None and res.first_brake_s >= start - 0.1, res.first_brake_s
    demand = column(res, "brake_demand")
    t = column(res, "time_s")
    assert max(d for d, ti in zip(demand, t) if ti > start) >= 1
    assert res.outcome == "stopped", res.outcome
    reasons = {r for r, ti in zip(column(res, "reasons"), t) if ti > start}
    # the monitor said why: a system error (2oo2 flag, including distances more than
    # distance_tolerance_dm apart), a stale channel or a persisting disagreement
    assert any(r & (4 | 64 | 128) for r in reasons), sorted(reasons)


def test_fmi3_monitor_gives_the_same_closed_loop(monitor_fmus, train_fmu):
    _, a = run("late-obstacle", monitor_fmus, train_fmu, "m1", 2)
    _, b = run("late-obstacle", monitor_fmus, train_fmu, "m1", 3)
    assert a.rows == b.rows


def test_same_scenario_same_trace(monitor_fmus, train_fmu):
    _, a = run("fault-noise-burst", monitor_fmus, train_fmu)
    _, b = run("fault-noise-burst", monitor_fmus, train_fmu)
    assert a.rows == b.rows


def test_step_must_divide_the_monitor_period(monitor_fmus, train_fmu):
    with pytest.raises(cosim.CosimError, match="divide"):
        cosim.run(monitor_fmus[("m1", 2)], train_fmu, {}, {}, 1.0, step_s=0.03)


def test_a_refused_parameter_is_reported_not_crashed(monitor_fmus, train_fmu):
    with pytest.raises(cosim.CosimError, match="initialisation refused"):
        cosim.run(monitor_fmus[("m1", 2)], train_fmu, {}, {"topology": 5}, 1.0)


def test_scenario_errors_name_the_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[train]\nwheels = 4\n')
    with pytest.raises(CosimScenarioError, match="wheels"):
        scenario.load(str(bad))
    bad.write_text('[train.fault]\nkind = "gremlins"\n')
    with pytest.raises(CosimScenarioError, match="gremlins"):
        scenario.load(str(bad))
    bad.write_text('[train]\ninitial_speed = "fast"\n')
    with pytest.raises(CosimScenarioError, match="initial_speed"):
        scenario.load(str(bad))
    with pytest.raises(CosimScenarioError, match="no such scenario"):
        scenario.load("no-such-thing")


def test_ssp_of_the_closed_loop_runs_in_fmpy(tmp_path, monitor_fmus, train_fmu):
    from fmpy.ssp.ssd import read_ssd

    from fmu import ssp

    scen = scenario.load("static-obstacle")
    path = ssp.write(tmp_path / "loop.ssp", train_fmu, monitor_fmus[("m1", 2)], scen.train, scen.monitor, scen.duration_s)
    read_ssd(str(path), validate=True)          # against the SSP 1.0 schema
    res = ssp.simulate(path)
    assert res["train.train.speed"][-1] == 0.0
    assert not res["train.collided"].any()
    assert 0 < res["train.true_distance"][-1] < scen.train["obstacle.position"]
    assert res["monitor.brake_demand"].max() >= 1
    # the binding carried the scenario: the train started at the scenario's speed
    assert res["train.train.speed"][0] == pytest.approx(scen.train["initial_speed"])


def cli(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "monitor.cli", *args], capture_output=True, text=True, cwd=cwd)


def test_cosim_command_json_csv_and_plot(tmp_path, monitor_fmus, train_fmu):
    res = cli("cosim", "late-obstacle", "--json", "--out", str(tmp_path), "--monitor-fmu", str(monitor_fmus[("m1", 2)]),
              "--train-fmu", str(train_fmu))
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert {"outcome", "margin_m", "steps", "realtime_factor", "csv", "plot"} <= set(out)
    assert out["outcome"] == "stopped" and out["margin_m"] > 0 and out["steps"] == 4000
    rows = list(csv.DictReader(open(out["csv"])))
    assert len(rows) == 4000 and {"time_s", "train.speed", "true_distance", "brake_demand", "mode"} <= set(rows[0])
    assert Path(out["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_build_fmu_command_prints_the_path(tmp_path):
    res = cli("build-fmu", "--fmi", "3", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    path = Path(res.stdout.strip())
    assert path.is_file() and path.name == "railguard-monitor-m1-fmi3.fmu"
    res = cli("build-fmu", "--ssp", "no-obstacle", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert Path(res.stdout.strip()).name == "railguard-no-obstacle.ssp"


def test_commands_fail_in_one_line(tmp_path):
    for args in (["build-fmu", "--model", str(tmp_path / "missing.rgt")], ["cosim", "no-such-scenario"],
                 ["cosim", "--step", "0.03", "--out", str(tmp_path)]):
        res = cli(*args)
        assert res.returncode == 2, (args, res.stderr)
        assert res.stderr.startswith("railguard: error: ") and res.stderr.count("\n") == 1, res.stderr
        assert "Traceback" not in res.stderr
    corrupted = tmp_path / "bad.rgt"
    from monitor.tables import read

    data = bytearray(read("m1"))
    data[100] ^= 1
    corrupted.write_bytes(bytes(data))
    res = cli("build-fmu", "--model", str(corrupted))
    assert res.returncode == 2 and "SHA-256" in res.stderr
