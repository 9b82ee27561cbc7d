"""`railguard verify`: the closed-loop analysis, the report, and the command (issue 6)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from monitor.offline.controller import Controller, closed_loop_matrix
from verification import closed_loop as cl
from verification import run as verify_run


@pytest.fixture(scope="module")
def m1_loop():
    return cl.table_controller("m1")


def test_two_phase_chain_is_the_closed_loop(m1_loop):
    """Two transitions of the two-phase chain, A -> B -> A, are one step of the closed loop."""
    model, ctrl, _ = m1_loop
    P2 = cl.two_phase_chain(model, ctrl).toarray()
    NS = ctrl.nodes * model.shape[0]
    P, _ = closed_loop_matrix(model, ctrl)
    assert np.allclose(P2[:NS, NS:] @ P2[NS:, :NS], P.toarray(), atol=1e-15)
    assert np.allclose(P2.sum(axis=1), 1.0)


def test_exact_and_storm_agree_and_match_the_table(m1_loop):
    model, ctrl, table = m1_loop
    ex, P, target = cl.exact(model, ctrl, 300)
    st = cl.storm(model, ctrl, P, target, 300)
    assert ex.value == pytest.approx(table.header["controller_value"], abs=1e-9)
    assert abs(st.value - ex.value) <= 1e-6 and abs(st.crash - ex.crash) <= 1e-6
    assert 0.0 < ex.crash < 1.0


def test_crash_probability_grows_with_the_horizon(m1_loop):
    model, ctrl, _ = m1_loop
    probs = [cl.exact(model, ctrl, h)[0].crash for h in (1, 10, 100, 300)]
    assert probs == sorted(probs) and probs[0] < probs[-1]


def test_a_wrong_controller_is_told_apart(m1_loop):
    """The checks can fail: flipping the table's actions changes value and crash probability."""
    model, ctrl, table = m1_loop
    flipped = Controller(2 - ctrl.action, ctrl.next, ctrl.start)
    ex, _, _ = cl.exact(model, flipped, 300)
    assert abs(ex.value - table.header["controller_value"]) > 1.0


def test_baselines_order_as_physics_says(m1_loop):
    """Always braking makes the hazard least likely; always maintaining makes it most likely."""
    model, _, _ = m1_loop
    figs = {name: cl.exact(model, c, 300)[0] for name, c in cl.baselines(model).items()}
    assert figs["always emergency"].crash < figs["threshold on zone"].crash < figs["always maintain"].crash


def test_belief_policy_monte_carlo_is_seeded(m1_loop):
    from importlib import resources

    from monitor.offline.pipeline import read_alphas

    model, _, table = m1_loop
    alphas, actions = read_alphas(resources.files("monitor.tables").joinpath("m1.alphas.npz"), table.sha256)
    a = cl.belief_policy(model, alphas, actions, 100, 500, seed=3)
    b = cl.belief_policy(model, alphas, actions, 100, 500, seed=3)
    assert a == b and a.value_ci > 0


def test_alphas_of_another_table_are_refused(tmp_path):
    from importlib import resources

    from monitor.offline.pipeline import read_alphas

    with pytest.raises(ValueError, match="belong to table"):
        read_alphas(resources.files("monitor.tables").joinpath("m1.alphas.npz"), "0" * 64)


def test_a_part_that_crashes_is_a_failed_check(tmp_path, monkeypatch):
    import types

    broken = types.ModuleType("verification.broken")

    def section(out_dir, quick, progress):
        raise RuntimeError("planted")

    broken.section = section
    monkeypatch.setitem(sys.modules, "verification.broken", broken)
    sections, report = verify_run.run(tmp_path, True, lambda m: None, ("broken",))
    assert [c.passed for c in sections[0].checks] == [False]
    assert [s.title for s in sections] == ["broken"]      # no scale checks without the parts they are about
    assert "planted" in report.read_text()
    data = json.loads((tmp_path / "report.json").read_text())
    assert data["passed"] is False


# parts whose section its own test module already runs and asserts, check by check, in CI
# (tests/test_verify_seed000.py, test_verify_seed001.py: the quick section, 24 s of the serial
# phase; tests/test_physics.py: the full physics part through the same command, 35 s;
# tests/test_campaign.py: the quick campaign's every check, and its vcan0 sample, 19 s;
# tests/test_fuzz.py: the quick fuzz section): run once, not twice
# parts whose own tests run them (the evaluate part: tests/test_evaluate.py, on the same quick runs
# its fixture makes as users run them)
OWN_TESTS = ("seed000", "seed001", "physics", "campaign", "fuzz", "evaluate")


def test_verify_quick_passes_with_report_and_json(tmp_path):
    """The command CI relies on: every part, quick mode, all checks pass (but OWN_TESTS)."""
    skip = [arg for part in OWN_TESTS for arg in ("--skip", part)]
    res = subprocess.run([sys.executable, "-m", "railguard", "verify", "--quick", "--json", "--out", str(tmp_path), *skip],
                         capture_output=True, text=True)
    data = json.loads(res.stdout)
    failed = [c for c in data["checks"] if not c["passed"]]
    assert res.returncode == 0 and data["passed"], failed
    assert {p["title"] for p in data["parts"]} and len(data["checks"]) >= 30
    assert "Scale" not in {p["title"] for p in data["parts"]}    # about the seed parts too: test_scale_section_...
    assert all({"name", "passed", "figure"} <= set(c) for c in data["checks"])
    text = (tmp_path / "report.md").read_text()
    for png in (p for part in data["parts"] for p in part["figures"]):
        assert (tmp_path / png).read_bytes()[:4] == b"\x89PNG" and png in text


def test_scale_section_sums_the_parts_train_seconds():
    """Issue 6's scale target: the train-seconds of every part's train-seconds check add up,
    and the full mode checks them against 1,000,000 (the quick mode only reports)."""
    from verification.report import Check, Section
    from verification.run import scale_section

    parts = [Section("a", "", [Check("a: simulated train-seconds", True, "", {"all": 400_000.0})], seconds=2.0),
             Section("b", "", [Check("b: train-seconds simulated", True, "", {"all": 700_000.0})], seconds=3.0)]
    full = scale_section(parts, ["closed_loop", "seed000"], quick=False, total_s=10.0)
    assert [c.passed for c in full.checks] == [True] and "1,100,000" in full.markdown
    short = scale_section(parts[:1], ["closed_loop"], quick=False, total_s=10.0)
    assert [c.passed for c in short.checks] == [False]
    assert scale_section(parts, ["closed_loop", "seed000"], quick=True, total_s=10.0).checks == []

