"""The fault-injection campaign (verification/campaign/): the quick campaign passes, and
its checkers can fail: a planted unsafe monitor is reported unsafe, the old nominal envelope
collides in the campaign's world (which brakes only as the declaration guarantees), a
monitor blind to a fault is reported undetected, a monitor that brakes for a ghost fails the
ghost and false-braking checks, a refused table is a detection and not a crash, and the
virtual-bus runs count the codec's own rejects."""
from __future__ import annotations

import dataclasses
import os
import shutil

import pytest

from monitor.core import cycle
from monitor.core import table as table_mod
from monitor.core.braking import Curves
from monitor.core.config import Config, ConfigurationError
from monitor.core.types import (
    EMERGENCY, R_DISPUTE, R_ENVELOPE, R_LATCH, R_PERCEPTOR, R_SAFE_STOP, R_STALE, R_SYSTEM_ERROR, SERVICE,
)
from verification import campaign as cp
from verification import world_train as wt


@pytest.fixture(scope="module")
def quick():
    messages = []
    summary = cp.run(True, messages.append, vcan_runs=False)
    return summary, messages


def test_quick_campaign_is_safe_and_detects_every_fault(quick):
    summary, _ = quick
    core = summary["core"]
    assert 300 <= core["runs"] <= 1000
    assert core["unsafe"] == 0, core["unsafe_examples"]
    assert core["crashes"] == 0, core["crash_examples"]
    for kind in cp.KINDS:                       # every kind manifested and was seen by its diagnostic
        d = core["detection"][kind]
        assert d["manifest"] > 0 and d["detected"] == d["manifest"], (kind, d)
    assert all(summary["detection"].values())
    # the fault-free runs never brake without an obstacle; silence always does (the safe side's price),
    # and that is the reaction to a diagnosed fault, not false braking
    assert core["single"]["none"]["brake_without_obstacle"] == core["single"]["none"]["false_braking"] == 0
    silence = core["cells"]["silence|no-obstacle"]
    assert silence["brake_without_obstacle"] == silence["runs"] > 0 and silence["false_braking"] == 0
    # issue 11: false braking at most 5 %, none unsafe; a 0.3 s ghost beyond SBI never stops the train
    assert core["false_braking_rate"] <= 0.05 < core["brake_without_obstacle_rate"]
    ghost = summary["ghost"]
    # (the world's train may run faster than 40 m/s downhill, so a ghost placed just beyond SBI at 40 m/s
    # can fall inside it: a moment of service braking, never a stop)
    assert ghost["runs"] == 24 and not ghost["stopped"] and ghost["min_speed_mps"] >= 39.5 and not ghost["undiagnosed"]
    # collisions only where the object appears inside the emergency braking distance
    assert all(c["collisions"] == 0 for key, c in core["cells"].items() if not key.endswith("|sudden-120m"))
    bus = summary["bus"]
    assert bus["runs"] >= 12 and bus["unsafe"] == 0 and bus["crashes"] == 0 and bus["false_braking"] == 0
    # every fault kind, and the hostile nodes of issue 39 (forged absent, forged brake release), seen
    secured = {f"{k} (secured bus)" for k in cp.HOSTILE_KINDS}     # the same attacks, keyless, on the secured bus
    assert set(bus["detected"]) == set(cp.KINDS) | set(cp.HOSTILE_KINDS) | secured and all(bus["detected"].values())
    assert all(c.passed for c in cp.checks(summary)), [c.line() for c in cp.checks(summary) if not c.passed]


def test_report_section_tables_and_figure(quick, tmp_path):
    summary, _ = quick
    fig = cp.heatmap(summary["core"], tmp_path / "heat.png")
    assert fig.stat().st_size > 10_000 and fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = cp.markdown(summary, fig.name)
    for kind in cp.KINDS:
        assert f"`{kind}`" in md
    assert "| fault \\ scenario |" in md and "sudden-120m" in md and "heat.png" in md
    checks = cp.checks(summary)
    names = [c.name for c in checks]
    assert len(names) == len(set(names))
    # every check of the quick campaign's report section passes (the verify part's, which
    # tests/test_verify.py leaves to this module; the vcan0 sample: test_vcan_sample_in_the_sandbox)
    assert all(c.passed for c in checks), [c.line() for c in checks if not c.passed]
    assert sum(n.startswith("campaign: ") and " detected (" in n for n in names) == len(cp.KINDS) + 2 * len(cp.HOSTILE_KINDS)


def test_plan_sizes():
    full = cp.plan(False)
    assert len(full) >= 10_000
    assert len({s.key for s in full}) == len(full)
    combos = cp.combos()
    assert sum(len(c) == 1 for c in combos) == len(cp.KINDS) == 14
    assert sum(len(c) == 2 for c in combos) == 14 * 13 // 2 + len(cp.CHANNEL_KINDS)
    assert {s.scenario for s in full} == {s.name for s in cp.SCENARIOS}


def test_runs_are_deterministic():
    spec = cp.RunSpec(("bad_crc", "noise_burst"), "static-700m-30", 3, "m2")
    a, b = cp.simulate(spec), cp.simulate(spec)
    assert a == b
    assert a["rejects"].get("bad_crc", 0) > 0


def test_the_world_judges_collisions_it_could_have_avoided():
    """Unsafe is the world's verdict: a collision with an obstacle the world's train could
    have stopped for (or a gap below the margin). An object appearing inside the train's own
    stopping distance is unavoidable, whatever the monitor does."""
    corner = wt.corners(Config())[0]
    sudden = cp.simulate(cp.RunSpec((), "sudden-120m", 0, "m1"), world=corner)
    assert sudden["collision"] and sudden["unavoidable"] and sudden["unsafe"] == 0
    assert cp.simulate(cp.RunSpec((), "crossing-500m-30", 0, "m1"), world=corner)["unsafe"] == 0
    stop = cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), world=corner)
    assert not stop["collision"] and stop["unsafe"] == 0 and stop["stop_margin_m"] > 20.0
    near = cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), world=corner, margin_m=stop["stop_margin_m"] + 1.0)
    assert near["unsafe"] == 1 and not near["collision"] and near["unsafe_first"]["gap_m"] == stop["stop_margin_m"]


def _never_braking_table(model: str = "m1") -> bytes:
    t = table_mod.decode(cp.shipped_table(model))
    return table_mod.encode(dict(t.header), (0,) * t.nodes, t.next)


def _no_supervision(monkeypatch):
    monkeypatch.setattr(cycle, "supervision_demand", lambda present, distance, ebi, sbi, warning, held: (0, False))


def test_a_planted_unsafe_monitor_is_reported_unsafe(monkeypatch):
    """No supervision, a table that never brakes, service braking on errors: the world's train
    hits the obstacle it could have stopped for, and the campaign calls it unsafe."""
    _no_supervision(monkeypatch)
    cfg = Config(safe_reaction=SERVICE)
    table = _never_braking_table()
    corner = wt.corners(cfg)[0]
    bad = cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), config=cfg, table_bytes=table, keep_trace=True,
                      world=corner)
    assert bad["crash"] is None
    assert bad["unsafe"] == 1 and bad["collision"] and not bad["unavoidable"]
    assert bad["unsafe_first"]["gap_m"] <= 0.0 and bad["unsafe_first"]["impact_speed_mps"] > 15.0
    assert all(row[4] != EMERGENCY for row in bad["trace"])
    # a fault that raises a system error only gets service braking: still unsafe
    faulty = cp.simulate(cp.RunSpec(("noise_burst",), "static-150m-10", 0, "m1"), config=cfg, table_bytes=table)
    assert faulty["unsafe"] == 1
    # the same world with the real monitor is safe
    assert cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), world=corner)["unsafe"] == 0


def test_a_monitor_blind_to_stale_reports_fails_the_silence_check(monkeypatch):
    from monitor.core.types import PRESENT

    def blind(report, now, timeout):                          # never DEGRADED: reports never age
        return report.status if report is not None else PRESENT
    monkeypatch.setattr(cycle, "channel_status", blind)
    res = cp.simulate(cp.RunSpec(("silence",), "no-obstacle", 0, "m1"))
    (fault,) = res["faults"]
    assert fault["manifest_cycle"] is not None and not fault["detected"]


@pytest.mark.parametrize("kind,variants", [("table_corrupted", ("flip", "digest", "truncate", "magic")),
                                           ("table_mismatch", ("expect_model", "period", "relabel", "reorder"))])
def test_a_refused_table_is_detected_and_not_a_crash(kind, variants):
    for model in ("m1", "m2"):
        for v in variants:
            fault = cp.Fault(kind, -1, 0.0, 0.0, (v, 0.37))
            data, expect, cfg = cp.faulty_table(fault, model, Config())
            with pytest.raises(ConfigurationError):
                cycle.create(cfg, data, expect)
    res = cp.simulate(cp.RunSpec((kind, "silence"), "static-300m-20", 2, "m2"))
    assert res["crash"] is None and res["config_error"]
    assert res["unsafe"] == 0 and not res["entered"] and not res["collision"]
    assert res["brake_without_obstacle"] and not res["false_braking"]   # held at the entry: a diagnosed fault's price
    table_fault = next(f for f in res["faults"] if f["kind"] == kind)
    assert table_fault["detected"]


def test_a_refused_table_on_the_bus_holds_the_train_at_the_entry():
    """The bus run of a refused table: the Player alone, its train never enters; the outcome
    says so ("held"), not "incomplete" (the Player's word for a run cut short)."""
    spec = cp.BusSpec("t-refused", "static-300m-20", (cp.Fault("table_corrupted", -1, 0.0, 0.0, ("flip", 0.37)),),
                      "m1", 7)
    res = cp.bus_run(spec)
    assert res["config_error"] and res["crash"] is None and res["unsafe"] == 0
    assert res["outcome"] == "held" and not res["entered"] and not res["collision"]


def test_virtual_bus_run_counts_bad_crc_rejects():
    spec = cp.BusSpec("t-bad-crc", "static-700m-30", (cp.Fault("bad_crc", 2, 1.0, 3.0),), "m1", 5, True, 20.0)
    res = cp.bus_run(spec)
    assert res["crash"] is None and res["unsafe"] == 0
    assert res["rejects"]["bad_crc"] >= 15                    # 2 s of frames of one channel, 100 ms period
    assert res["detected"] == {"bad_crc": True}
    assert "bad_crc@ch2" in res["faults_injected"]


def test_virtual_bus_deadline_overrun_reaches_safe_stop():
    spec = cp.BusSpec("t-overrun", "static-700m-30", (cp.Fault("deadline_overrun", -1, 1.0, 2.0),), "m2", 6, True, 20.0)
    res = cp.bus_run(spec)
    assert res["crash"] is None and res["unsafe"] == 0
    assert res["deadline_misses"] >= 3 and res["detected"] == {"deadline_overrun": True}


def test_vcan_sample_in_the_sandbox():
    from can_bus import vcan

    if shutil.which("apt-get") is None and not (vcan.cache_dir() / "root/usr/bin/linux.uml").is_file():
        if os.environ.get("CI") == "true":
            pytest.fail("no apt-get to fetch user-mode-linux, and no cached sandbox")
        pytest.skip("needs apt-get (Debian) for the user-mode-linux sandbox")
    out = cp.vcan_sample(cp.vcan_plan(True), lambda _: None)
    (run,) = out["runs"]
    assert run["crash"] is None, run["crash"]
    assert run["unsafe"] == 0 and not run["collision"]
    assert run["cycles"] >= 50 and run["frames_received"] > 300
    assert all(run["detected"].values()) and run["detected"]


def _nominal_envelope(cfg, speed, track, brake, closing, age, service=False):
    """The envelope before issue 11: v^2 / 2a + v t_r with the nominal 3 (1) m/s^2 and 0.5 s."""
    a = 1000 if service else 3000
    d = -(-(speed * speed * 10000 + 2 * a * speed * 500) // (2 * a * 10000))
    return Curves(d, d, d, d)


def test_the_old_nominal_envelope_collides_in_the_campaigns_world(monkeypatch):
    """The world's train on the declaration's worst corner (2.2 m/s^2 above 30 m/s, 1 s dead
    time, downhill): the nominal alpha2 of the old core is too short there, and the world says so."""
    corner = wt.corners(Config())[0]
    monkeypatch.setattr(cycle, "curves", _nominal_envelope)
    res = cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), table_bytes=_never_braking_table(), world=corner)
    assert res["collision"] and res["unsafe"] == 1 and not res["unavoidable"]
    monkeypatch.undo()
    good = cp.simulate(cp.RunSpec((), "static-300m-20", 0, "m1"), table_bytes=_never_braking_table(), world=corner)
    assert not good["collision"] and good["unsafe"] == 0 and good["stop_margin_m"] >= Config().standstill_margin_dm / 10


def test_a_world_train_worse_than_declared_collides_and_the_declared_one_does_not():
    """The witness does not share the monitor's assumptions: with a world train braking at
    1.0 m/s^2 after 1.5 s (the monitor still believes the declaration), the level-crossing
    scenario ends in collisions the train could have avoided; the declaration's corners stop.
    m1's risk-repaired table (issue 41) brakes on the crossing's first "emergency" and stops
    even that train 2 m short, so m1 is judged on its curves alone (a table never braking)."""
    weak = wt.WorldTrain(emergency_decel=((0.0, 1.0),), service_decel=0.5, brake_delay=1.5, brake_buildup=0.0)
    for model in ("m1", "m2"):
        spec = cp.RunSpec((), "crossing-500m-30", 0, model)
        table = _never_braking_table("m1") if model == "m1" else None
        res = cp.simulate(spec, world=weak, table_bytes=table)
        assert res["unsafe"] == 1 and res["collision"] and not res["unavoidable"], res["unsafe_first"]
        for corner in wt.corners(Config()):
            ok = cp.simulate(spec, world=corner, table_bytes=table)
            assert ok["unsafe"] == 0 and not ok["collision"] and ok["closest_m"] > 50.0
    repaired = cp.simulate(cp.RunSpec((), "crossing-500m-30", 0, "m1"), world=weak)
    assert repaired["unsafe"] == 0 and not repaired["collision"]


def test_runs_digest_depends_on_outcomes_not_on_order():
    runs = [cp.simulate(cp.RunSpec((), s, 0, "m2")) for s in ("static-150m-10", "no-obstacle", "train-ahead")]
    digest = cp.runs_digest(runs)
    assert cp.runs_digest(list(reversed(runs))) == digest and len(digest) == 64
    changed = [dict(runs[0], collision=True)] + runs[1:]
    assert cp.runs_digest(changed) != digest


def test_false_braking_counts_only_what_no_diagnosed_fault_explains():
    E, S = EMERGENCY, SERVICE
    clear, moving = [False] * 4, [True] * 4
    # a stale channel's emergency, then the latch holding it: the reaction to a fault
    assert cp.false_braking_cycles([E, E, E, 0], [R_STALE | R_SYSTEM_ERROR, R_LATCH, R_LATCH, 0], clear, moving) == (True, False)
    # a dispute's supervision emergency (a phantom inside EBI), held by the latch: false braking
    assert cp.false_braking_cycles([E, E, 0, 0], [R_ENVELOPE | R_DISPUTE, R_LATCH, 0, 0], clear, moving) == (True, True)
    # the latch after a stale reaction, then a new cause of its own: false from there
    assert cp.false_braking_cycles([E, E, S, 0], [R_STALE, R_LATCH, 1 << 10, 0], clear, moving) == (True, True)
    # a safe stop; braking with an obstacle in range or before the entry never counts
    assert cp.false_braking_cycles([E] * 4, [R_SAFE_STOP | R_PERCEPTOR] * 4, clear, moving) == (True, False)
    assert cp.false_braking_cycles([E] * 4, [R_ENVELOPE] * 4, [True] * 4, moving) == (False, False)
    assert cp.false_braking_cycles([E] * 4, [R_ENVELOPE] * 4, clear, [False] * 4) == (False, False)


def test_a_monitor_that_brakes_for_a_ghost_fails_the_ghost_and_false_braking_checks(monkeypatch):
    """A supervision that brakes for any reported obstacle, held to standstill (as the core
    before issue 11 answered a disagreement): the ghost stops the train."""
    cfg = Config(emergency_release=0)
    plan = cp.ghost_plan(True, cfg)[:4]
    flat = dataclasses.replace(wt.corners(cfg)[0], gradient=0.0)      # holds 40 m/s: the ghosts stay beyond SBI
    good = cp.ghost_summary([dict(cp.simulate(s, config=cfg, faults=f, world=flat), ghost_dm=f[0].variant[0])
                             for s, f in plan])
    assert good["runs"] == 4 and not good["stopped"] and good["false_braking"] == 0 and good["max_demand"] == 0
    monkeypatch.setattr(cycle, "supervision_demand",
                        lambda present, distance, ebi, sbi, warning, held: (EMERGENCY, True) if present else (0, False))
    bad = cp.ghost_summary([dict(cp.simulate(s, config=cfg, faults=f, world=flat), ghost_dm=f[0].variant[0])
                            for s, f in plan])
    assert len(bad["stopped"]) == 4 and bad["false_braking"] == 4
    summary = {"mode": "quick", "core": cp.aggregate([]), "ghost": bad}
    assert not next(c for c in cp.checks(summary) if "ghost" in c.name).passed


def test_a_contradiction_that_persists_needs_perceptor(monkeypatch):
    """The contradiction's diagnostic: the module flag at once, and perceptor once it has
    persisted persistence_cycles; a monitor that never counts the disagreement is caught."""
    fault = [cp.Fault("contradiction", 3, 2.0, 4.0, (5000,))]
    spec = cp.RunSpec(("contradiction",), "no-obstacle", 0, "m2")
    res = cp.simulate(spec, faults=fault)
    assert res["faults"][0]["detected"] and {"perceptor", "dispute"} <= set(res["reasons_seen"])
    monkeypatch.setattr(cycle, "disagreement", lambda sa, sb: False)
    blind = cp.simulate(spec, faults=fault)
    assert blind["faults"][0]["manifest_cycle"] is not None and not blind["faults"][0]["detected"]
    short = cp.simulate(spec, faults=[cp.Fault("contradiction", 3, 2.0, 2.5, (5000,))])   # 5 cycles: the flag suffices
    assert short["faults"][0]["detected"] and "perceptor" not in short["reasons_seen"]
