"""`railguard evaluate` and `solve --pareto`: the table against the simple rules, supervision in front."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path
import sys

import numpy as np
import pytest

from conftest import ROOT
from monitor.core import table as table_format
from monitor.core.table import decode
from monitor.core.types import R_MEMORY, R_TABLE, R_WARNING
from monitor.offline.controller import Controller
from monitor.offline.models import load
from verification import evaluate as ev
from verification import pareto
from verification import sharp_hazard as sh
from verification.fastcore import TablePolicy, VectorMonitor
from verification.policies import BeliefTracking, finite_baselines, supervised, supervision_floor
from verification.world_metrics import PolicyCost, paired, policy_alone, ratio, wilson_upper

ENV = {**os.environ, "MPLBACKEND": "Agg"}


def railguard(*args: str, timeout: float = 900) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "railguard", *args], capture_output=True, text=True, cwd=ROOT,
                          env=ENV, timeout=timeout)


# ------------------------------------------------------------------ the supervision in front

def test_supervised_controller_demands_the_floor_after_every_observation():
    """Walk random observation sequences through the product controller and through a
    reference (node of the table, max with the floor of the last observation)."""
    rng = np.random.default_rng(3)
    Z = 12
    ctrl = Controller(rng.integers(0, 3, 7), rng.integers(0, 7, (7, Z)), 2)
    floor = np.where(np.arange(Z) >= 9, 2, 0)
    sup = supervised(ctrl, floor)
    for _ in range(200):
        n, m = ctrl.start, sup.start
        assert sup.action[m] == ctrl.action[n]
        for o in rng.integers(0, Z, 30):
            n, m = ctrl.next[n, o], sup.next[m, o]
            assert sup.action[m] == max(ctrl.action[n], floor[o])


def test_floor_is_emergency_in_the_critical_zone_only():
    m1, _ = load("m1")
    m2, _ = load("m2")
    assert supervision_floor(m1).tolist() == [0, 0, 0, 2]
    f2 = supervision_floor(m2)
    assert all((f2[o] == 2) == name.startswith("critical") for o, name in enumerate(m2.observations))


def sample_hazard(model, ctrl: Controller, steps: int, episodes: int, seed: int) -> float:
    """The supervised closed loop sampled directly (the table steps, the floor applies)."""
    rng = np.random.default_rng(seed)
    S, _, Z = model.shape
    floor = supervision_floor(model)
    hazard = np.zeros(S, dtype=bool)
    hazard[[i for i, s in enumerate(model.states) if s in ("Crash",) or s.startswith("critical")]] = True
    s = rng.choice(S, size=episodes, p=model.b0)
    n = np.full(episodes, ctrl.start)
    a = ctrl.action[n]
    hit = hazard[s].copy()
    cumT, cumO = np.cumsum(model.T, axis=2), np.cumsum(model.O, axis=2)
    for _ in range(steps):
        s = np.minimum((rng.random(episodes)[:, None] > cumT[a, s]).sum(axis=1), S - 1)
        o = np.minimum((rng.random(episodes)[:, None] > cumO[a, s]).sum(axis=1), Z - 1)
        n = ctrl.next[n, o]
        a = np.maximum(ctrl.action[n], floor[o])
        hit |= hazard[s]
    return float(hit.mean())


@pytest.mark.parametrize("name", ["threshold", "never"])
def test_exact_hazard_matches_a_sampled_closed_loop(name):
    model, _ = load("m1")
    ctrl = finite_baselines(model)[name]
    exact = ev.hazard_exact(model, ctrl, 300)
    sampled = sample_hazard(model, ctrl, 300, 40000, seed=5)
    tol = 4 * np.sqrt(max(exact * (1 - exact), 1e-6) / 40000) + 1e-4
    assert abs(exact - sampled) <= tol, (exact, sampled)
    assert exact > 0


def test_never_is_riskier_than_threshold_and_always_emergency_is_safest():
    model, _ = load("m1")
    b = finite_baselines(model)
    p = {k: ev.hazard_exact(model, c, 300) for k, c in b.items()}
    assert p["always_emergency"] < p["threshold"] < p["never"]


def test_belief_tracking_is_the_bayes_filter_of_the_model():
    model, _ = load("m1")
    rng = np.random.default_rng(1)
    alphas = rng.normal(size=(5, 4))
    actions = np.array([0, 1, 2, 1, 0])
    bt = BeliefTracking(model, alphas, actions, 3)
    refs = [model.b0.copy() for _ in range(3)]
    applied = np.zeros(3, dtype=np.int64)
    for k in range(40):
        obs = rng.integers(0, 4, 3)
        act, best = bt.step(obs, applied)
        for i in range(3):
            if k:
                refs[i], _ = model.belief_update(refs[i], int(applied[i]), int(obs[i]))
            else:
                post = refs[i] * model.O[0][:, obs[i]]
                refs[i] = post / post.sum()
            assert np.allclose(bt.b[i], refs[i], atol=1e-12)
            assert act[i] == actions[int(np.argmax(alphas @ refs[i]))]
        applied = rng.integers(0, 3, 3)


def test_vector_monitor_with_the_table_policy_equals_the_default():
    from monitor.core import cycle
    from monitor.core.config import Config
    from monitor.tables import read

    setup = cycle.create(Config(), read("m1"))
    rng = np.random.default_rng(2)
    a = VectorMonitor(setup, 16)
    b = VectorMonitor(setup, 16, TablePolicy(setup.action, setup.next, setup.table.start, 16))
    for _ in range(300):
        present = rng.random(16) < 0.6
        dist = rng.integers(0, 20000, 16)
        speed = rng.integers(0, 4000, 16)
        oa, ob = a.step(present, dist, speed), b.step(present, dist, speed)
        for key in ("demand", "reasons", "node", "observation"):
            assert np.array_equal(oa[key], ob[key]), key


# ------------------------------------------------------------------ Monte Carlo figures

def test_ratio_interval_of_equal_trains_is_zero_and_grows_with_spread():
    r, ci = ratio(np.array([1.0, 1.0, 1.0]), np.array([2.0, 2.0, 2.0]))
    assert r == 0.5 and ci == 0.0
    r, ci = ratio(np.array([0.0, 2.0, 1.0]), np.array([2.0, 2.0, 2.0]))
    assert r == 0.5 and ci > 0.2


def test_wilson_upper_bound_is_honest_when_nothing_hits():
    """Belief tracking's Monte Carlo hazard: 0 of 2000 episodes must not read as 'exactly 0'
    (the normal approximation's half-width is 0 there); for many hits it agrees with it."""
    assert wilson_upper(0, 2000) == pytest.approx(1.96 ** 2 / (2000 + 1.96 ** 2), rel=1e-12)
    assert 0.0018 < wilson_upper(0, 2000) < 0.0020
    p, n = 0.3, 100000
    assert wilson_upper(int(p * n), n) == pytest.approx(p + 1.96 * np.sqrt(p * (1 - p) / n), rel=1e-3)
    assert wilson_upper(5, 1000) < wilson_upper(6, 1000) and wilson_upper(5, 1000) > wilson_upper(5, 2000)
    assert wilson_upper(0, 0) == 1.0 and wilson_upper(10, 10) == 1.0


def test_policy_cost_counts_braking_without_need_the_policys_own_stops_and_changes():
    cost = PolicyCost(2, dt=0.1, encounters=np.array([1.0, 0.0]))
    need = [[True, False], [True, False], [False, False], [False, False]]
    demand = [[1, 0], [1, 2], [0, 2], [2, 0]]
    reasons = [[R_TABLE, 0], [R_TABLE, R_TABLE], [0, R_TABLE | R_MEMORY], [R_TABLE | R_WARNING, 0]]
    for o, d, r in zip(need, demand, reasons):
        cost.cycle(np.array(o), np.array(d), policy_alone(np.array(r)))
    cost.moved(np.array([1.0, 1.0]), np.array([0.0, 1.0]), np.array([True, False]))
    f = cost.figures()
    assert f["unnecessary_braking"] == pytest.approx(3 / 6)     # train 0: 1 of 2 free cycles; train 1: 2 of 4
    # the policy alone: train 0's last cycle (a warning is no cause to brake), train 1's second
    # (its third is the memory's too); a braking cycle with need never counts
    assert f["policy_braking"] == pytest.approx(2 / 6)
    assert f["demand_changes_per_encounter"] == pytest.approx((3 + 2) / 2)   # encounters: 1 + 1 new, 0
    assert f["stops_per_train_hour"] == pytest.approx(1 / (8 * 0.1 / 3600))


# ------------------------------------------------------------------ the sharp estimator

STEPS = 300


def _z(est: sh.Sharp, exact: float) -> float:
    return abs(est.p - exact) / (est.ci / 1.96)


@pytest.mark.parametrize("name, policy, guide, episodes", [
    ("m1", "threshold", "table", 2000),      # guided by a different, safer controller
    ("m1", "table", "threshold", 2000),      # guided by a riskier one
    ("m1", "never", None, 2000),             # conditional Monte Carlo alone
    ("m1", "repaired", "threshold", 5000),   # the shipped, risk-repaired table: its exact figure by sampling
    ("m2", "table", "threshold", 1000),
])
def test_sharp_estimator_reproduces_exact_hazards(name, policy, guide, episodes):
    """The estimator belief tracking is judged with, run on finite-state controllers whose
    P(hazard) is known exactly: it must land within evaluate.AGREE_Z standard errors, and
    its interval must be sharp (m1 near 0.001 to a few per cent with 2,000 episodes; plain
    Monte Carlo would need about a million)."""
    target = ev.load_target(name)
    model = target.model
    ctrls = {**finite_baselines(model), "table": target.compiled,    # as compiled: belief tracking's guide
             "repaired": target.controller}
    exact = ev.hazard_exact(model, ctrls[policy], STEPS)
    guides = () if guide is None else (sh.Guide(model, ctrls[guide], STEPS),)
    est = sh.estimate(model, sh.controller(ctrls[policy]), STEPS, episodes, seed=11, guides=guides)
    assert _z(est, exact) <= ev.AGREE_Z, (est, exact)
    assert est.relative <= (0.45 if name == "m2" else 0.1), est
    assert est.episodes == episodes and "conditional Monte Carlo" in est.method


def test_guided_estimate_of_its_own_guide_has_no_spread_and_the_guide_is_exact():
    """With LAMBDA = 1 the change of measure is the zero-variance one for the guide itself:
    every episode returns the exact figure, which the guide's own values reproduce."""
    model, ctrl = ev.load_target("m1").model, ev.load_target("m1").controller
    exact = ev.hazard_exact(model, ctrl, STEPS)
    guide = sh.Guide(model, ctrl, STEPS)
    assert guide.exact == pytest.approx(exact, rel=1e-6)
    est = sh.estimate(model, sh.controller(ctrl), STEPS, 200, seed=1, guides=(guide,), lam=1.0)
    assert est.p == pytest.approx(exact, rel=1e-6) and est.ci <= 1e-6 * exact


def test_an_estimator_without_its_likelihood_ratios_is_caught(monkeypatch):
    """The check above fails a biased estimator: steering the draws towards the hazard but
    not weighting them back (ratio 1) lands far outside AGREE_Z."""
    target = ev.load_target("m1")
    model = target.model
    threshold = finite_baselines(model)["threshold"]
    exact = ev.hazard_exact(model, threshold, STEPS)
    real = sh._draw
    monkeypatch.setattr(sh, "_draw", lambda *args: (real(*args)[0], 1.0))
    est = sh.estimate(model, sh.controller(threshold), STEPS, 2000, seed=11, guides=(sh.Guide(model, target.controller, STEPS),))
    assert _z(est, exact) > 3 * ev.AGREE_Z, (est, exact)


def test_belief_tracking_sharp_estimate_m1():
    """Belief tracking's P(hazard) on m1 as evaluate estimates it (guided by the table) agrees
    with the estimate guided by threshold, and is sharp: a tenth of the rule's quarter."""
    target = ev.load_target("m1")
    model = target.model
    est = ev.hazard_belief(target, STEPS, 2000, seed=3)
    other = sh.estimate(model, sh.belief_tracking(model, *target.alphas), STEPS, 4000, seed=4,
                        guides=(sh.Guide(model, finite_baselines(model)["threshold"], STEPS),))
    assert est.relative <= sh.RELATIVE_HALF_WIDTH / 10 and "guided by the table" in est.method
    assert abs(est.p - other.p) <= ev.AGREE_Z * np.hypot(est.ci, other.ci) / 1.96, (est, other)


# ------------------------------------------------------------------ the paired tests

def test_paired_difference_has_the_bootstrap_error_and_beats_the_unpaired_one():
    """Two policies on the same trains: the linearised paired standard error matches a
    bootstrap over trains, and shared luck makes it much smaller than the two intervals."""
    rng = np.random.default_rng(4)
    n = 200
    y = rng.integers(50, 150, n).astype(float)
    luck = rng.gamma(2.0, 0.05, n)
    xa = rng.binomial(y.astype(int), np.clip(luck, 0, 1)).astype(float)
    xb = np.minimum(y, xa + rng.binomial(5, 0.5, n))
    diff, se = paired((xa, y), (xb, y))
    assert diff == pytest.approx(xa.sum() / y.sum() - xb.sum() / y.sum())
    boot = []
    for _ in range(2000):
        i = rng.integers(0, n, n)
        boot.append(xa[i].sum() / y[i].sum() - xb[i].sum() / y[i].sum())
    assert se == pytest.approx(np.std(boot), rel=0.1)
    unpaired = np.hypot(ratio(xa, y)[1], ratio(xb, y)[1]) / 1.96
    assert se < unpaired / 3
    assert all(np.isnan(v) for v in paired((xa[:5], y[:5]), (xb, y)))


@pytest.mark.parametrize("diff, se, decision", [
    (-0.01, 0.006, "better"),               # z = -1.67: one-sided 5 % rejects 'table >= baseline'
    (-0.01, 0.0062, "indistinguishable"),    # z = -1.61: it does not
    (-0.01, 0.004, "better"),
    (0.01, 0.004, "worse"),
    (0.0, 0.004, "indistinguishable"),
    (-1e-9, 0.0, "better"),
    (1e-9, 0.0, "worse"),
    (0.0, 0.0, "equal"),
    (float("nan"), 0.1, "indistinguishable"),
])
def test_decide_puts_the_burden_on_the_table(diff, se, decision):
    d = ev.decide(diff, se)
    assert d["decision"] == decision, d
    if se and not np.isnan(diff):
        assert d["p_better"] + d["p_worse"] == pytest.approx(1.0)


def test_verdict_words():
    v = ev.verdict
    assert v({"a": "better", "b": "indistinguishable"}) == "better"
    assert v({"a": "better", "b": "equal", "c": "better"}) == "better"
    assert v({"a": "worse", "b": "indistinguishable"}) == "worse"
    assert v({"a": "better", "b": "worse"}) == "trade-off"
    assert v({"a": "indistinguishable", "b": "equal"}) == "indistinguishable"
    assert set(ev.VERDICTS) == {"better", "worse", "trade-off", "indistinguishable"}


def test_a_table_below_a_wide_upper_bound_is_not_better():
    """Issue 31: the old rule passed a table whose exact P(hazard) was below belief tracking's
    Monte Carlo upper bound. Judged with the burden on the table, the same table against a
    sharp estimate below it is worse, against a wide one indistinguishable, never better;
    it is better only against an estimate clearly above it."""
    table = {"p_hazard": 0.000906, "p_hazard_ci": 0.0}
    sharp = ev.compare_figure("p_hazard", table, {"p_hazard": 0.00088, "p_hazard_ci": 3.4e-6})
    wide = ev.compare_figure("p_hazard", table, {"p_hazard": 0.00085, "p_hazard_ci": 0.0002})
    above = ev.compare_figure("p_hazard", table, {"p_hazard": 0.00095, "p_hazard_ci": 1e-5})
    assert (sharp["decision"], wide["decision"], above["decision"]) == ("worse", "indistinguishable", "better")
    assert sharp["difference"] == pytest.approx(0.000026) and "one-sample" in sharp["test"]
    exact = ev.compare_figure("p_hazard", table, {"p_hazard": 0.000988, "p_hazard_ci": 0.0})
    assert exact["decision"] == "better" and exact["ci"] == 0 and exact["test"] == "exact against exact"


def test_world_figures_are_compared_train_by_train():
    """The same mean difference is 'better' when the trains agree (paired) and not when each
    train's luck differs: the test reads the per-train sums, not the two intervals."""
    y = np.full(50, 100.0)
    rng = np.random.default_rng(0)
    luck = rng.integers(0, 40, 50).astype(float)
    table = {"unnecessary_braking": 0.0, "_per_train": {"unnecessary_braking": (luck, y)}}
    shared = {"unnecessary_braking": 0.0, "_per_train": {"unnecessary_braking": (luck + 1.0, y)}}
    own = {"unnecessary_braking": 0.0, "_per_train": {"unnecessary_braking": (rng.permutation(luck) + 1.0, y)}}
    assert ev.compare_figure("unnecessary_braking", table, shared)["decision"] == "better"
    assert ev.compare_figure("unnecessary_braking", table, own)["decision"] == "indistinguishable"


# ------------------------------------------------------------------ the acceptance, as users run it

@pytest.fixture(scope="module")
def evaluated(tmp_path_factory) -> dict:
    """`railguard evaluate NAME --quick` as users run it: m1 in text (its JSON file read
    back), m2 with --json; each result carries the text or JSON it printed."""
    out = tmp_path_factory.mktemp("evaluate")
    proc = railguard("evaluate", "m1", "--quick", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    m1 = json.loads((out / "evaluate-m1.json").read_text())
    proc2 = railguard("evaluate", "m2", "--quick", "--json", "--out", str(out), "--no-plot")
    assert proc2.returncode == 0, proc2.stderr
    return {"m1": {**m1, "stdout": proc.stdout, "out": out}, "m2": json.loads(proc2.stdout)}


def test_the_report_part_judges_the_runs_users_make(evaluated, tmp_path, monkeypatch):
    """`verification.evaluate.section` (the report's part: `verify --quick` leaves it to this
    test, which has the same quick runs at hand) on the very results of `railguard evaluate
    m1|m2 --quick` above: every ACAS X check passes and both tables are reported."""
    results = {n: {k: v for k, v in evaluated[n].items() if k not in ("stdout", "out")} for n in ("m1", "m2")}
    asked = []

    def evaluate(name, quick=False, progress=None, **kw):
        asked.append((name, quick, kw))
        return results[name]

    monkeypatch.setattr(ev, "evaluate", evaluate)
    sec = ev.section(tmp_path, True, lambda _: None)
    assert asked == [("m1", True, {}), ("m2", True, {})]          # the CLI's --quick runs, default seed
    failed = [(c.name, c.figure) for c in sec.checks if not c.passed]
    assert len(sec.checks) >= 4 and not failed, failed
    assert "### m1 (" in sec.markdown and "### m2 (" in sec.markdown
    # issue 41: both values of each shipped table, as `table show --json` gives them
    for name in ("m1", "m2"):
        shown = json.loads(railguard("table", "show", name, "--json").stdout)
        assert (f"{shown['controller_value_without_release_cost']:.4f} without it" in sec.markdown
                and f"{abs(shown['compilation_loss_percent']):.2f} % " in sec.markdown), name
    assert "-0.1962 with the release cost (2 per release" in sec.markdown


@pytest.mark.parametrize("name", ["m1", "m2"])
def test_evaluate_json_has_every_figure_for_the_table_and_every_baseline(evaluated, name):
    r = evaluated[name]
    assert set(r["baselines"]) == {"threshold", "belief_tracking", "always_emergency", "never"}
    for row in (r["table"], *r["baselines"].values()):
        for key in ev.METRICS:
            assert key in row and key + "_ci" in row and np.isfinite(row[key])
        assert not any(k.startswith("_") for k in row)          # no per-train arrays in the JSON
    assert r["baselines"]["always_emergency"]["unnecessary_braking"] == 1.0
    assert r["baselines"]["always_emergency"]["p_hazard"] <= r["table"]["p_hazard"]
    assert r["baselines"]["never"]["p_hazard"] > r["table"]["p_hazard"]
    assert r["baselines"]["threshold"]["p_hazard_ci"] == 0.0      # a finite-state baseline: exact
    if "files" in r:
        assert all(os.path.isfile(f) for f in r["files"])


@pytest.mark.parametrize("name", ["m1", "m2"])
def test_evaluate_gives_belief_trackings_sharp_hazard_and_a_verdict_per_baseline(evaluated, name):
    """Issue 31's acceptance: the sharp estimate with its interval and method, the paired
    test per figure, a verdict word per baseline that follows from the decisions."""
    r = evaluated[name]
    bt = r["belief_tracking_p_hazard"]
    assert {"p", "ci", "low", "high", "episodes", "method", "relative_half_width"} <= set(bt)
    assert "conditional Monte Carlo" in bt["method"] and bt["ci"] > 0
    assert bt["relative_half_width"] <= sh.RELATIVE_HALF_WIDTH and bt["low"] < bt["p"] < bt["high"]
    assert bt["p"] == r["baselines"]["belief_tracking"]["p_hazard"]
    assert set(r["comparisons"]) == set(r["baselines"]) == set(r["verdicts"]) == set(r["acceptance_verdicts"])
    for base, c in r["comparisons"].items():
        assert set(c["figures"]) == set(ev.METRICS)
        for key, f in c["figures"].items():
            assert f["decision"] in ("better", "worse", "indistinguishable", "equal")
            assert f["difference"] == pytest.approx(f["table"] - f["baseline"])
            if key != "p_hazard":
                assert "paired" in f["test"] and np.isfinite(f["ci"])
        assert c["verdict"] == r["verdicts"][base] == ev.verdict({k: f["decision"] for k, f in c["figures"].items()})
        assert c["acceptance"] == ev.verdict({k: c["figures"][k]["decision"] for k in ev.ACCEPTANCE})
    # exact against exact is decided by the figures themselves
    assert r["comparisons"]["never"]["figures"]["p_hazard"]["decision"] == "better"
    assert r["comparisons"]["always_emergency"]["figures"]["p_hazard"]["decision"] == "worse"
    assert r["comparisons"]["always_emergency"]["figures"]["unnecessary_braking"]["decision"] == "better"


@pytest.mark.parametrize("name", ["m1", "m2"])
def test_shipped_table_against_the_rules_it_is_held_to_and_the_verdicts_stated(evaluated, name):
    """ACAS X's rule as held (evaluate.ACCEPTED): m1 better than threshold on p_hazard and
    unnecessary braking and, risk-repaired (issue 41), than belief tracking on p_hazard; m2
    better than threshold on p_hazard; what is stated against belief tracking (m1 brakes
    needlessly less; m2 is riskier and, in its world since issue 41, brakes needlessly more)
    and m2 no better than threshold on needless braking (STATED); rule_checks says so."""
    r = evaluated[name]
    assert ev.ACCEPTED == {"m1": {"threshold": ("p_hazard", "unnecessary_braking"), "belief_tracking": ("p_hazard",)},
                           "m2": {"threshold": ("p_hazard",)}}
    for base, figures in ev.ACCEPTED[name].items():
        assert ev.verdict({k: r["comparisons"][base]["figures"][k]["decision"] for k in figures}) == "better"
    bt = r["comparisons"]["belief_tracking"]["figures"]
    assert bt["p_hazard"]["decision"] == ("better" if name == "m1" else "worse")
    assert bt["unnecessary_braking"]["decision"] != ("worse" if name == "m1" else "better")
    assert r["acceptance_verdicts"]["belief_tracking"] in (("better", "indistinguishable") if name == "m1"
                                                           else ("trade-off", "worse"))
    checks = ev.rule_checks(name, name, r["comparisons"], quick=True)
    assert checks and all(c.passed for c in checks), [c.line() for c in checks if not c.passed]
    said = "better on unnecessary_braking" if name == "m1" else "worse on p_hazard, worse on unnecessary_braking"
    assert any(f"belief_tracking {said}" in c.name for c in checks)


def test_a_statement_holds_only_while_the_decisions_say_it():
    def comp(p, u, c="better"):
        return {"figures": {"p_hazard": {"decision": p}, "unnecessary_braking": {"decision": u},
                            "demand_changes_per_encounter": {"decision": c}}}

    assert ev.holds_statement("m1", "belief_tracking", comp("better", "better"), quick=False)
    assert not ev.holds_statement("m1", "belief_tracking", comp("better", "indistinguishable"), quick=False)
    assert ev.holds_statement("m1", "belief_tracking", comp("better", "indistinguishable"), quick=True)
    assert not ev.holds_statement("m1", "belief_tracking", comp("better", "worse"), quick=True)
    assert not ev.holds_statement("m1", "belief_tracking", comp("better", "better", "indistinguishable"), quick=False)
    assert not ev.holds_statement("m1", "belief_tracking", comp("better", "better", "worse"), quick=True)
    assert not ev.holds_statement("m2", "belief_tracking", comp("worse", "better"), quick=True)
    assert ev.holds_statement("m2", "belief_tracking", comp("worse", "worse"), quick=False)
    assert ev.holds_statement("m2", "threshold", comp("better", "worse"), quick=False)
    assert not ev.holds_statement("m2", "threshold", comp("better", "better"), quick=True)
    def threshold(u):
        return {"threshold": {"figures": {"p_hazard": {"decision": "better", "difference": -1e-4, "ci": 0.0},
                                          "unnecessary_braking": {"decision": u, "difference": 0.01, "ci": 0.001,
                                                                  "p_better": 1.0, "p_worse": 1e-9}}}}

    assert ev.rule_checks("m1", "m1", threshold("indistinguishable"), quick=False)[0].passed     # better, none worse
    checks = ev.rule_checks("m1", "m1", threshold("worse"), quick=False)                     # a trade-off
    assert not checks[0].passed and "unnecessary_braking +0.01 ± 0.001: worse" in checks[0].figure
    assert not checks[-1].passed and "belief_tracking missing" in checks[-1].figure


@pytest.mark.parametrize("name", ["m1", "m2"])
def test_risk_axis_rests_on_the_model_when_nothing_collides(evaluated, name):
    r = evaluated[name]
    collisions = [row["world_collisions"] for row in (r["table"], *r["baselines"].values())]
    assert (r["risk_axis"] is not None) == (len(set(collisions)) == 1)
    if r["risk_axis"]:
        assert "never included" in r["risk_axis"] and "model alone" in r["risk_axis"]
    assert ev.risk_axis({"a": {"world_collisions": 0}, "b": {"world_collisions": 1}}) is None
    same = ev.risk_axis({"a": {"world_collisions": 3, "world_collisions_initial": 3},
                         "b": {"world_collisions": 3, "world_collisions_initial": 3}})
    assert same.startswith("every policy collided the same 3 times") and "no demand avoids them" in same


def test_evaluate_human_output(evaluated):
    """The text output says what the JSON says: the sharp estimate, each test, each verdict."""
    r, text = evaluated["m1"], evaluated["m1"]["stdout"]
    bt = r["belief_tracking_p_hazard"]
    assert f"belief tracking's P(hazard): {bt['p']:.3g} ± {bt['ci']:.2g} (95 %" in text
    for base, c in r["comparisons"].items():
        assert f"table vs {base}: {c['verdict']} (" in text
        assert f"(ACAS X's acceptance figures): {c['acceptance']}" in text
    assert "the burden on the table" in text
    assert (r["risk_axis"] in text) if r["risk_axis"] else True
    assert (r["out"] / "evaluate-m1.png").stat().st_size > 1000


def test_held_out_world_check_fails_a_table_that_brakes_always_or_lacks_a_baseline(tmp_path):
    """verify's check in the world the sweep did not select on holds a table to the same rule:
    braking all the time is worse than threshold on needless braking (a trade-off, not
    better), and a table whose belief-tracking baseline cannot be built (no alpha vectors
    beside it) does not pass the statement about it by default."""
    shipped = decode((ROOT / "monitor" / "tables" / "m1.table.rgt").read_bytes())
    path = tmp_path / "brake.table.rgt"
    path.write_bytes(table_format.encode(shipped.header, [2], [[0] * len(shipped.header["observations"])]))
    check = ev.held_out_check(str(path), lambda text: None, sizes=ev.Sizes(trains=8, seconds=60.0, episodes=100))
    assert not check.passed and f"seed {ev.HELD_OUT_SEED}" in check.name
    assert check.figure.startswith("FAILS p_hazard -0.000988 (exact): better; unnecessary_braking +0.")
    assert ": worse (p " in check.figure and check.figure.endswith("| FAILS belief_tracking missing")
    assert ev.HELD_OUT_SEED != ev.SEED


def test_evaluate_errors_are_one_line(tmp_path):
    bad = tmp_path / "x.table.rgt"
    bad.write_bytes(b"not a table, but long enough to have a header and a digest: " * 4)
    proc = railguard("evaluate", str(bad), "--quick", "--out", str(tmp_path))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0
    assert f"{bad}: not a railguard table" in proc.stderr


def test_the_shipped_table_must_have_the_recommended_weights_and_be_no_riskier_than_its_point():
    shipped = decode((ROOT / "monitor" / "tables" / "m2.table.rgt").read_bytes())
    front = {"recommended": 1, "points": [{"weights": {"collision_weight": 0.25}, "p_hazard": 5e-5},
                                          {"weights": {"collision_weight": 0.5}, "p_hazard": 4.14e-5}]}
    assert ev.sweep_check("m2", front, shipped, 3.14e-5).passed
    assert not ev.sweep_check("m2", front, shipped, 4.2e-5).passed             # riskier than the point
    assert not ev.sweep_check("m2", {**front, "recommended": 0}, shipped, 3.14e-5).passed   # other weights
    assert not ev.sweep_check("m2", {**front, "recommended": None}, shipped, 3.14e-5).passed


def test_pareto_frontier_keeps_only_unbeaten_points():
    pts = [{"p_hazard": 0.1, "unnecessary_braking": 0.1}, {"p_hazard": 0.2, "unnecessary_braking": 0.05},
           {"p_hazard": 0.2, "unnecessary_braking": 0.2}, {"p_hazard": 0.1, "unnecessary_braking": 0.1}]
    assert pareto.frontier(pts) == [1, 0, 3]


def test_recommendation_is_the_safest_point_the_world_cannot_tell_from_the_least_braking():
    rng = np.random.default_rng(3)
    y = np.full(200, 100.0)
    luck = rng.poisson(2.0, 200).astype(float)

    def point(p, extra):
        x = luck + extra
        return {"p_hazard": p, "unnecessary_braking": float(x.sum() / y.sum()),
                "_per_train": {"unnecessary_braking": (x, y)}}
    noise = rng.normal(0.0, 0.05, 200)
    pts = [point(4e-5, 0.0), point(3e-5, noise - noise.mean() + 0.002), point(1e-5, 3.0)]    # 1: alike within the noise; 2: worse
    assert pts[1]["unnecessary_braking"] > pts[0]["unnecessary_braking"]
    assert pareto.recommend(pts, [0, 1, 2]) == 1
    assert pareto.recommend(pts, [0, 2]) == 0 and pareto.recommend(pts, []) is None


def test_solve_pareto_writes_the_frontier_and_its_plot(tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_text("braking_weight = [1.0, 4.0]\n", encoding="utf-8")
    # the two points as two dask tasks on a 2-worker local cluster
    proc = railguard("solve", "--pareto", "--model", "m1", "--grid", str(grid), "--out", str(tmp_path), "--json",
                     "--workers", "2")
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout)
    assert [p["weights"] for p in r["points"]] == [{"braking_weight": 1.0}, {"braking_weight": 4.0}]
    assert r["frontier"] and set(r["frontier"]) <= {0, 1}
    assert {"threshold", "belief_tracking", "always_emergency", "never"} == set(r["baselines"])
    assert set(r["better_than"]) == set(r["baselines"]) | {pareto.REFERENCE}
    for i, p in enumerate(r["points"]):
        assert set(p["against"]) == set(r["baselines"]) | {pareto.REFERENCE}
        for base, a in p["against"].items():
            assert a["verdict"] == ev.verdict({k: a[k]["decision"] for k in ev.ACCEPTANCE})
            assert (i in r["better_than"][base]) == (a["verdict"] == "better")
        assert not any(k.startswith("_") for k in p)
        # belief tracking as evaluate holds this point to it: its own alpha vectors (the two
        # points' reward weights differ, so their belief tracking does too); the default
        # point's is the reference yardstick, and for the default point the two are the same
        own = p["own_belief_tracking"]
        assert p["against"]["belief_tracking"]["p_hazard"]["difference"] == pytest.approx(p["p_hazard"] - own["p_hazard"])
        ref = r["baselines"]["belief_tracking"]["p_hazard"]
        assert p["against"][pareto.REFERENCE]["p_hazard"]["difference"] == pytest.approx(p["p_hazard"] - ref)
    assert r["points"][0]["own_belief_tracking"]["p_hazard"] == r["baselines"]["belief_tracking"]["p_hazard"]
    assert r["points"][1]["own_belief_tracking"]["p_hazard"] != r["points"][0]["own_belief_tracking"]["p_hazard"]
    assert set(r["dominating"]) == {i for i in r["frontier"] if r["points"][i]["against"]["threshold"]["verdict"] == "better"}
    better_bt = [i for i in r["dominating"] if r["points"][i]["against"]["belief_tracking"]["verdict"] == "better"]
    assert r["preferred"] == (better_bt or r["dominating"])
    if r["preferred"]:                                    # the least braking, or the safest it cannot be told from
        least = min(r["points"][i]["unnecessary_braking"] for i in r["preferred"])
        assert r["points"][r["recommended"]]["unnecessary_braking"] >= least
    else:
        assert r["recommended"] is None
    assert r["baselines"]["belief_tracking"]["p_hazard_ci"] > 0 and "better than belief_tracking" in pareto.render(r)
    assert "own BT p" in pareto.render(r) and "vs BT, default weights" in pareto.render(r)
    assert "policy own" in pareto.render(r) and all(0.0 <= p["policy_braking"] <= p["unnecessary_braking"]
                                                    for p in r["points"])
    front = tmp_path / "pareto-m1"
    assert json.loads((front / "frontier.json").read_text())["points"] == r["points"]
    assert (front / "frontier.png").read_bytes()[:4] == b"\x89PNG"
    assert all(os.path.isfile(p["table"]) for p in r["points"])
    assert r["layered_search"] is None                    # m1's table is not layered


def test_solve_pareto_builds_m2_with_the_layered_search_asked_for(tmp_path):
    """`--layered-search` reaches every point of the sweep (it once used the plan's default
    whatever the flag said): the point's table header and the frontier record it."""
    grid = tmp_path / "grid.toml"
    grid.write_text("collision_weight = [0.5]\n", encoding="utf-8")
    proc = railguard("solve", "--pareto", "--model", "m2", "--grid", str(grid), "--layered-search", "exact",
                     "--time-budget", "6", "--out", str(tmp_path), "--json")
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout)
    assert r["layered_search"] == "exact"
    header = decode(Path(r["points"][0]["table"]).read_bytes()).header
    assert header["solver"]["layered_search"] == "exact" and header["params"]["collision_weight"] == 0.5
    assert "layered search exact" in pareto.render(r)


@pytest.mark.parametrize("text, words", [("bogus = [1.0]\n", "unknown: bogus"), ("braking_weight = 2.0\n", "non-empty list"),
                                         ("braking_weight = [-1.0]\n", "numbers >= 0")])
def test_pareto_grid_errors_are_one_line(tmp_path, text, words):
    grid = tmp_path / "grid.toml"
    grid.write_text(text, encoding="utf-8")
    proc = railguard("solve", "--pareto", "--model", "m1", "--grid", str(grid), "--out", str(tmp_path))
    assert proc.returncode == 2 and words in proc.stderr and str(grid) in proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_m1_table_holds_its_demand_through_the_default_scenario(tmp_path):
    """Hysteresis (issue 12): the obstacle stays reported in the 1 km warning zone, so the m1
    table brakes once and holds; before, it released and re-braked as the zones shrank with speed."""
    proc = railguard("run", "--table", "m1", "--json", "--no-plot", "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["outcome"] == "stopped" and d["demand_changes"] <= 2, d["demand_changes"]


def test_m2_table_brakes_once_in_the_default_scenario(tmp_path):
    """Hysteresis (issue 12) for the default table: `railguard run` as the README gives it.
    The default scenario silences a channel for 4 s at standstill; the monitor answers with
    an emergency and returns (two changes any table gets). Without that fault, the table's
    own changes: at most two (service braking to a stop; issue 41's table releases it at
    standstill, 544 m from the obstacle, in the far zone), against 17 to 21 without release
    cost."""
    proc = railguard("run", "--json", "--no-plot", "--out", str(tmp_path / "default"))
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["table"] == "m2" and d["outcome"] == "stopped" and d["demand_changes"] <= 4, d
    assert d["final_speed_mps"] == 0.0 and d["margin_m"] > 500, d
    assert 1 <= d["demand_changes_by_cause"]["encounter"] <= 2, d["demand_changes_by_cause"]
    assert d["demand_changes_by_cause"]["faults"] == 2, d["demand_changes_by_cause"]
    text = (ROOT / "monitor" / "scenarios" / "static-obstacle.toml").read_text(encoding="utf-8")
    assert "[[faults]]" in text
    calm = tmp_path / "static-obstacle-no-fault.toml"
    calm.write_text(text[:text.index("[[faults]]")], encoding="utf-8")
    proc = railguard("run", "--scenario", str(calm), "--json", "--no-plot", "--out", str(tmp_path / "calm"))
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d["outcome"] == "stopped" and 1 <= d["demand_changes"] <= 2, d["demand_changes"]
    assert d["demand_changes_by_cause"]["faults"] == 0, "no fault injected, none counted"
