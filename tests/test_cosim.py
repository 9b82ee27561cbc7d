"""The closed loop in FMPy: train-dynamics FMU + monitor FMU, the shipped scenarios, the
SSP of the same loop, and the `build-fmu` / `cosim` commands (issue 5); the demand one
monitor cycle late, scenarios with a braking declaration, oncoming obstacles and the
speed-distance diagram (issue 11)."""
from __future__ import annotations

import csv
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

from fmu import cosim, scenario
from fmu.scenario import CosimScenarioError
from monitor.core.types import R_DISPUTE

OBSTACLE_SCENARIOS = ["static-600m-20", "late-obstacle", "train-ahead-500m-25", "oncoming-obstacle"]
FAULT_SCENARIOS = [s for s in scenario.shipped() if s.startswith("fault-")]


def run(name: str, monitor_fmus, train_fmu, table: str | None = None, fmi: int = 2):
    scen = scenario.load(name)
    return scen, cosim.run_scenario(scen, monitor_fmus[(table or scen.table, fmi)], train_fmu)


def column(result, name: str) -> list:
    i = result.columns.index(name)
    return [row[i] for row in result.rows]


def test_every_fault_kind_has_a_shipped_scenario():
    assert len(FAULT_SCENARIOS) == 7
    kinds = {scenario.load(s).train["fault.kind"] for s in FAULT_SCENARIOS}
    assert kinds == set(range(1, 8))


@pytest.mark.parametrize("name", ["static-600m-20", "late-obstacle"])
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


def test_late_obstacle_is_seen_between_ebi_and_sbi(monitor_fmus, train_fmu):
    """The obstacle comes into view between the monitor's EBI and SBI at the train's
    speed: only an emergency brake stops the train in time, and it does."""
    from monitor.core.braking import curves
    from monitor.core.config import Config

    scen, res = run("late-obstacle", monitor_fmus, train_fmu)
    v = round(scen.train["initial_speed"] * 100)
    c = curves(Config(), v, 0, 0, v, 0)
    assert c.ebi_dm / 10 < scen.train["sensor.range"] < c.sbi_dm / 10
    assert res.outcome == "stopped" and res.margin_m > 0
    assert res.max_demand == 2


def test_moving_obstacle_is_never_hit(monitor_fmus, train_fmu):
    _, res = run("train-ahead-500m-25", monitor_fmus, train_fmu)
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
    assert min(column(res, "true_distance")) > 0
    reasons = {r for r, ti in zip(column(res, "reasons"), t) if ti > start}
    # the monitor said why: a system error (2oo2 flag, including distances more than
    # distance_tolerance_dm apart), a stale channel or a persisting disagreement
    assert any(r & (4 | 64 | 128) for r in reasons), sorted(reasons)
    if name == "fault-noise-burst":
        # a dispute about the distance only, every channel fresh (issue 11): the monitor
        # warns and supervises the curves on the shortest distance instead of stopping
        assert any(r & R_DISPUTE for r in reasons) and res.outcome in ("stopped", "running")
    else:
        assert res.outcome == "stopped", res.outcome


def test_an_oncoming_obstacle_reaches_our_standing_train(monitor_fmus, train_fmu):
    """We stop before an oncoming train; it then runs into us: contact, but at our speed 0,
    so not a collision of ours (struck_at_standstill), and the stop margin is kept."""
    scen, res = run("oncoming-obstacle", monitor_fmus, train_fmu)
    assert res.outcome == "struck_at_standstill" and not res.collision
    assert res.impact_speed == 0.0 and res.stop_margin_m > scen.braking["standstill_margin_m"]
    speed = column(res, "true_speed")
    hit = column(res, "true_distance").index(0.0)
    assert speed[hit - 1] == 0.0 and max(speed) == pytest.approx(scen.train["initial_speed"])


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_a_leaving_vehicle_is_released_and_a_blinded_one_is_not(table, monitor_fmus, train_fmu):
    """Issue 29 acceptance: the vehicle that leaves the crossing after the monitor braked for
    it is forgotten on confirmed absence (forget_ms) and the demand is released for good: the
    train never stands. The blinded one (every channel ABSENT alike, for less than forget_ms)
    is never forgotten: the train stops before it."""
    from fmu import cosim as cs
    leaves = scenario.load("vehicle-leaves-crossing")
    res = cs.run_scenario(dataclasses.replace(leaves, table=table), monitor_fmus[(table, 2)], train_fmu)
    demand, t = column(res, "brake_demand"), column(res, "time_s")
    leave = leaves.train["obstacle.leave_time"]
    assert res.max_demand == 2 and res.first_brake_s < leave                  # it braked for the vehicle
    assert res.outcome == "running" and min(column(res, "true_speed")) > 10.0  # and the train never stood
    released = max(ti for ti, d in zip(t, demand) if d > 0)
    assert leave + 7.5 < released < leave + 9.0                               # forget_ms, then the hold
    blinded = scenario.load("vehicle-blinded-crossing")
    res = cs.run_scenario(dataclasses.replace(blinded, table=table), monitor_fmus[(table, 2)], train_fmu)
    assert res.outcome == "stopped" and res.margin_m > 0


def test_the_vehicle_leaving_the_crossing_and_its_blind_contrast(monitor_fmus, train_fmu):
    """vehicle-leaves-crossing: the train FMU's obstacle is on the track until
    obstacle.leave_time, gone after it (true_distance 1e9), nothing to hit, no margin to tell;
    vehicle-blinded-crossing (the FMU's blind fault): the vehicle stays and the train stops
    before it."""
    scen, res = run("vehicle-leaves-crossing", monitor_fmus, train_fmu)
    leave = scen.train["obstacle.leave_time"]
    assert leave == scen.world.obstacles[0].leave_s
    t, dist = column(res, "time_s"), column(res, "true_distance")
    assert 0 < min(d for d, ti in zip(dist, t) if ti < leave - 1e-9)
    assert {d for d, ti in zip(dist, t) if ti >= leave - 1e-9} == {1e9}
    assert not res.collision and res.margin_m is None and res.outcome in ("running", "stopped")
    scen, res = run("vehicle-blinded-crossing", monitor_fmus, train_fmu)
    assert scen.train["fault.kind"] == scenario.FAULT_KINDS.index("blind")
    assert res.outcome == "stopped" and res.margin_m > 0


def test_the_demand_reaches_the_train_one_cycle_late(monitor_fmus, train_fmu):
    """By default the train holds, during each monitor cycle, the demand the monitor
    computed in the cycle before (as on CAN); with demand_delay_cycles 0, the same cycle's."""
    scen = scenario.load("late-obstacle")
    assert scen.demand_delay_cycles == 1
    for delay in (1, 0):
        res = cosim.run_scenario(scen, monitor_fmus[("m1", 2)], train_fmu, demand_delay_cycles=delay)
        per_cycle = res.rows[::10]
        computed = [r[res.columns.index("brake_demand")] for r in per_cycle]
        held = [r[res.columns.index("demand_in")] for r in per_cycle]
        assert max(computed) == 2
        assert held[delay:] == computed[:len(computed) - delay]


def test_a_scenario_braking_declaration_becomes_monitor_parameters(tmp_path):
    from monitor.declaration import fields, shipped

    scen = scenario.load("oncoming-obstacle")
    assert scen.braking == shipped() and scen.monitor == fields(shipped())
    decl = "\n".join(f"{k} = {v!r}" for k, v in {**shipped(), "emergency_decel": 2.0}.items())
    path = tmp_path / "s.toml"
    path.write_text(f"demand_delay_cycles = 0\n[braking]\n{decl}\n")
    scen = scenario.load(str(path))
    assert scen.monitor["emergency_decel_mms2"] == 2000 and scen.monitor["emergency_band2_cms"] == 0
    assert scen.demand_delay_cycles == 0
    for text, key in ((f"[monitor]\nemergency_decel_mms2 = 2400\n[braking]\n{decl}\n", "set by both"),
                      (f"[braking]\n{decl.replace('speed_error = 0.02', 'speed_error = 2.0')}\n", "speed_error"),
                      ("[braking]\nemergency_decel = 2.0\n", "missing key"),
                      ("demand_delay_cycles = -1\n", "demand_delay_cycles")):
        path.write_text(text)
        with pytest.raises(CosimScenarioError, match=key) as exc:
            scenario.load(str(path))
        assert "\n" not in str(exc.value)


def test_the_speed_distance_picture_follows_the_run(monitor_fmus, train_fmu):
    """The diagram's trajectory is the run's (true speed against true distance), its
    curves are the monitor's for the scenario's obstacle and conditions."""
    from monitor.plot import curve_points

    _, res = run("oncoming-obstacle", monitor_fmus, train_fmu)
    sd = cosim.speed_distance(res)
    assert sd.obstacle_speed_mps == -10.0 and sd.visible_m == 800.0
    assert sd.distance_m[0] == pytest.approx(1500.0 - 40 * 0.01, abs=0.01) and sd.speed_mps[0] == pytest.approx(30.0)
    assert sd.config.emergency_decel_mms2 == 2400 and sd.config.standstill_margin_dm == 50
    speeds, pts = curve_points(sd.config, 30.0, sd.obstacle_speed_mps)
    assert speeds[0] == 0 and speeds[-1] >= 30.0
    assert all(a < b < c < d for a, b, c, d in zip(pts["EBD"], pts["EBI"], pts["SBI"], pts["warning"]))
    assert pts["EBD"][0] == 55.0                     # at standstill: the standstill margin and the distance accuracy
    assert 2 in sd.demand


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
    bad.write_text('[[faults]]\nkind = "gremlins"\nchannel = 2\nstart_s = 1.0\n')
    with pytest.raises(CosimScenarioError, match="gremlins"):
        scenario.load(str(bad))
    bad.write_text('[train]\nspeed_mps = "fast"\n')
    with pytest.raises(CosimScenarioError, match="speed_mps"):
        scenario.load(str(bad))
    with pytest.raises(CosimScenarioError, match="no such scenario"):
        scenario.load("no-such-thing")


def test_ssp_of_the_closed_loop_runs_in_fmpy(tmp_path, monitor_fmus, train_fmu):
    from fmpy.ssp.ssd import read_ssd

    from fmu import ssp

    scen = scenario.load("static-600m-20")
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
    return subprocess.run([sys.executable, "-m", "railguard", *args], capture_output=True, text=True, cwd=cwd)


def test_cosim_command_json_csv_and_plot(tmp_path, monitor_fmus, train_fmu):
    res = cli("cosim", "late-obstacle", "--json", "--out", str(tmp_path), "--monitor-fmu", str(monitor_fmus[("m1", 2)]),
              "--train-fmu", str(train_fmu))
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert {"outcome", "margin_m", "steps", "realtime_factor", "csv", "plot"} <= set(out)
    # the plot carries the speed-distance diagram beside the time series: a wide figure
    import struct

    width, height = struct.unpack(">II", Path(out["plot"]).read_bytes()[16:24])
    assert width > 1.5 * height
    assert out["outcome"] == "stopped" and out["margin_m"] > 0 and out["steps"] == 4000
    rows = list(csv.DictReader(open(out["csv"])))
    assert len(rows) == 4000 and {"time_s", "train.speed", "true_distance", "brake_demand", "mode"} <= set(rows[0])
    assert Path(out["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the monitor FMU's live risk, in the CSV and summarised: a late obstacle is approached
    # deep into the table's zones (R2 above 50 %), and the category seconds cover the run
    assert {"r1_ppm", "r2_ppm", "risk_score", "risk_category", "table_risk_ppm"} <= set(rows[0])
    risk = out["risk"]
    assert risk["peak_r2_pct"] == pytest.approx(max(int(r["r2_ppm"]) for r in rows) / 1e4, abs=0.005)
    assert risk["peak_r2_pct"] > 50
    assert risk["peak_table_ppm"] == max(int(r["table_risk_ppm"]) for r in rows) > 0
    assert sum(risk[f"{c}_s"] for c in ("low", "moderate", "high", "critical")) == pytest.approx(out["simulated_s"], abs=0.01)


def test_build_fmu_command_prints_the_path(tmp_path):
    res = cli("build-fmu", "--fmi", "3", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    path = Path(res.stdout.strip())
    assert path.is_file() and path.name == "railguard-monitor-m2-fmi3.fmu"     # the one default table
    res = cli("build-fmu", "--ssp", "no-obstacle", "--out", str(tmp_path))
    assert res.returncode == 0, res.stderr
    assert Path(res.stdout.splitlines()[-1]).name == "railguard-no-obstacle.ssp"


def test_commands_fail_in_one_line(tmp_path):
    for args in (["build-fmu", "--model", str(tmp_path / "missing.rgt")], ["cosim", "no-such-scenario"],
                 ["cosim", "--step", "0", "--out", str(tmp_path)]):
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


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_the_stress_failure_now_stops_in_cosimulation(monitor_fmus, train_fmu, table):
    """Issue 29 acceptance: the likeliest failure `railguard stress` found before the obstacle
    memory, replayed by the real FMUs (the train FMU's `blind` fault, every channel misses,
    for 1.2 s during emergency braking), no longer releases the emergency: the remembered
    obstacle stays inside the curve, the demand stays emergency through the blindness and the
    train stops. A forgetting time of one cycle (0.1 s) and a blindness 2.4 s longer bring
    the old failure back (m2, the table it was found with; 0.6 s longer before the sensors'
    error budget lengthened the curves, issue 40; the 1.2 s alone no longer collides since
    the curves count the sampling period): the memory, not luck, is what holds the brake."""
    scen = scenario.load("stress-blackout-release")
    assert scen.train["fault.kind"] == scenario.FAULT_KINDS.index("blind")
    res = cosim.run_scenario(dataclasses.replace(scen, table=table), monitor_fmus[(table, 2)], train_fmu)
    assert res.outcome == "stopped"
    demand, t = column(res, "brake_demand"), column(res, "time_s")
    start, end = scen.train["fault.start"], scen.train["fault.end"]
    assert max(demand[i] for i, ti in enumerate(t) if ti < start) == 2                     # braking before
    assert min(demand[i] for i, ti in enumerate(t) if start <= ti <= end) == 2             # held while blind
    longer = dataclasses.replace(scen, table=table, train={**scen.train, "fault.end": scen.train["fault.end"] + 2.4})
    assert cosim.run_scenario(longer, monitor_fmus[(table, 2)], train_fmu).outcome == "stopped"
    short = dataclasses.replace(longer, monitor={**scen.monitor, "forget_ms": 100})
    assert table == "m1" or cosim.run_scenario(short, monitor_fmus[(table, 2)], train_fmu).outcome == "collision"
