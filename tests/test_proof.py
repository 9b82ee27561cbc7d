"""The Frama-C proof of the C core (verification/proof.py, docs/proof.md).

(a) the committed sources: every WP goal proved, EVA 0 alarms on rg_step and the table check;
(b) planted bugs in the C voters, the braking curves, the hold, the choice of the supervised
    obstacle and the obstacle memory make the proof fail on the goal of the broken property;
(c) every contracted function carries its ACSL contract (requires/assigns/ensures).
No skip when Frama-C is missing: the proof is part of CI (apt-get install frama-c-base why3
z3 cvc4), so a missing tool is a failure, as it is in `railguard verify`.
"""
from __future__ import annotations

import re
from typing import NamedTuple

import pytest

from verification import proof
from verification.report import Section

SOURCE = (proof.CORE_DIR / "rg_core.c").read_text()


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """WP's cache for this module's runs, empty at the start: the real sources are proved
    afresh, and each planted bug's run sends only the goals it changed to the provers."""
    return tmp_path_factory.mktemp("wp-cache")


@pytest.fixture(scope="module")
def result(cache):
    r = proof.run(cache_dir=cache)
    assert not r["missing"], f"{r.get('error')}: the proof needs Frama-C ({proof.INSTALL_HINT})"
    return r


# ---------------------------------------------------------------- (a) the real sources

def test_all_wp_goals_proved(result):
    wp = result["wp"]
    assert wp["returncode"] == 0, wp.get("error")
    assert wp["failed"] == [], wp["failed_detail"]
    assert wp["total"] > 300 and wp["proved"] == wp["total"] == wp["summary_total"] == wp["summary_proved"]
    for fn in (*proof.FUNCTIONS, "rg_step"):
        f = wp["per_function"][fn]
        assert f["total"] > 0 and f["proved"] == f["total"], (fn, f)
    # both SMT provers take part (Qed, WP's simplifier, closes the easy goals itself)
    assert wp["by_prover"].get("Z3", 0) > 0 and wp["by_prover"].get("CVC4", 0) > 0, wp["by_prover"]


def test_eva_no_alarm_on_the_step_and_the_table_check(result):
    runs = {e["name"]: e for e in result["eva"]}
    assert set(runs) == {"eva_step-m1", "eva_step-m2", "eva_table-m1"}
    for name, e in runs.items():
        assert e["alarms"] == 0, (name, e["alarm_messages"], e["unproved"])
        assert e["ok"] and e["completed"] and e["clean"], (name, e.get("error"))
        assert e["preconditions"]["unknown"] == e["preconditions"]["invalid"] == 0, (name, e["preconditions"])
        assert e["rte_valid"] > 100, (name, e["rte_valid"])
        assert e["subject_rte_valid"] > 30, (name, e["rte_valid_by_function"])   # rg_step / rg_table_check reached
    # on the step, EVA leaves the contracts' postconditions and `present_in_range` to WP,
    # and every one of them is a property WP proved
    for name in ("eva_step-m1", "eva_step-m2"):
        assert runs[name]["proved_by_wp"] > len(proof.FUNCTIONS)


def test_section_and_checks(result):
    checks = {c.name: c for c in proof.checks_of(result)}
    wp = result["wp"]
    assert checks["proof: all WP goals proved"].passed
    assert checks["proof: all WP goals proved"].figure == f"{wp['total']}/{wp['total']} goals"
    assert checks["proof: EVA alarms on rg_step"].passed
    assert checks["proof: EVA alarms on rg_step"].figure.startswith("0 alarms")
    assert checks["proof: EVA alarms on the table check"].passed
    md = proof.markdown(result)
    assert "frama-c" in md and "rg_vote_2oo2" in md


# ---------------------------------------------------------------- (b) planted bugs

class Bug(NamedTuple):
    old: str                      # the text replaced (once) in rg_core.c
    new: str
    prove: tuple[str, ...]        # the functions WP proves for this bug
    fail: tuple[str, ...]         # of those, the ones whose goals must fail, each of them
    goal: str                     # a prefix one of the failed goals must have
    every: bool = False           # ... that every failed goal must have


# WP is modular (a caller is proved against its callees' contracts, never their bodies), so
# bugs whose proved functions are disjoint are planted together and proved in one run: each
# is judged on the goals of its own functions, as if it were planted alone
BUGS = {
    # the 2oo2 voter takes the longer of two PRESENT distances: only its goals may fail, the
    # disagreement beside it still proves
    "2oo2 distance max": Bug("*distance = da < db ? da : db;", "*distance = da > db ? da : db;",
                             ("rg_vote_2oo2", "rg_disagreement"), ("rg_vote_2oo2",),
                             "typed_rg_vote_2oo2_ensures", True),
    # the 3oo3 voter forgets that modules 2 and 3 may disagree
    "3oo3 missing error term": Bug("s[0] != s[1] || s[1] != s[2] || st == RG_DEGRADED",
                                   "s[0] != s[1] || st == RG_DEGRADED", ("rg_vote_3oo3",), ("rg_vote_3oo3",),
                                   "typed_rg_vote_3oo3_ensures", True),
    # the run distance rounded up with a constant one short (the curve one dm short whenever the
    # exact distance is 1e-8 m above a whole dm): no random test finds this; the postcondition
    # `\result * 2e8 >= v t 2e4 + a t^2` does
    "curve rounding": Bug("return (num + 199999999) / 200000000;", "return (num + 199999998) / 200000000;",
                          ("rg_run_dm",), ("rg_run_dm",), "typed_rg_run_dm_ensures", True),
    # the revocable release one cycle late (calm reaches confirm while still held)
    "late release": Bug("} else if (calm >= confirm - 1) {", "} else if (calm >= confirm) {", ("rg_hold",),
                        ("rg_hold",), "typed_rg_hold_ensures"),
    # issue 29 (a): the hold lowers a brake one cycle early; rg_decide, which relies on
    # rg_hold's contract, still proves, rg_hold's own postconditions do not
    "early release": Bug("} else if (calm >= confirm - 1) {", "} else if (calm >= confirm - 2) {",
                         ("rg_hold", "rg_decide"), ("rg_hold",), "typed_rg_hold_ensures"),
    # (a) the supervision ignores the remembered obstacle when no channel shows one (the
    # common-cause blindness the memory exists for): inside EBI it no longer demands emergency
    "remembered obstacle ignored when blind": Bug(
        "    if (remembered) {\n        track_demand",
        "    if (remembered && voted_dm != RG_NO_DISTANCE) {\n        track_demand",
        ("rg_supervised_demand",), ("rg_supervised_demand",), "typed_rg_supervised_demand_ensures_2"),
    # (b) the track's prediction drops the speed measurement error (the train may be faster
    # than it says): the remembered gap shrinks too little per cycle
    "prediction without speed error": Bug("const int64_t x = speed_cms * (1000 + error_permille);",
                                          "const int64_t x = speed_cms * 1000;", ("rg_near_travel",),
                                          ("rg_near_travel",), "typed_rg_near_travel_"),
    # (b) ... drops the train's acceleration (traction plus downhill): Python's two
    # postconditions of near_travel do not see this one, the C contract's third does
    "prediction without acceleration": Bug("return v_max * period_ms + run + obstacle_cms * period_ms;",
                                           "return v_max * period_ms + obstacle_cms * period_ms;",
                                           ("rg_near_travel",), ("rg_near_travel",), "typed_rg_near_travel_"),
    # (c) absence counts as evidence wherever the remembered obstacle is, also beyond the
    # sensors' declared range, where ABSENT says nothing about it
    "forget outside sensor range": Bug("if (!evidence || far > (int64_t)range_dm * RG_UNITS_PER_DM) {",
                                       "if (!evidence) {", ("rg_forget",), ("rg_forget",), "typed_rg_forget_"),
}


def _groups() -> list[list[str]]:
    """The bugs in as few runs as their proved functions allow (disjoint within a run)."""
    groups: list[list[str]] = []
    for name, bug in BUGS.items():
        for g in groups:
            if not any(set(bug.prove) & set(BUGS[o].prove) for o in g):
                g.append(name)
                break
        else:
            groups.append([name])
    return groups


PLANTED_TIMEOUT_S = 4


@pytest.fixture(scope="module")
def planted(cache) -> dict:
    """Each bug's run (shared by the bugs planted with it)."""
    out = {}
    for group in _groups():
        source = SOURCE
        for name in group:
            assert SOURCE.count(BUGS[name].old) == 1 and source.count(BUGS[name].old) == 1, name
            source = source.replace(BUGS[name].old, BUGS[name].new)
        functions = tuple(fn for name in group for fn in BUGS[name].prove)
        # a planted bug's goals are false: a prover gives up at its timeout, so these runs
        # take PLANTED_TIMEOUT_S (the real sources' slowest goal takes about 1 s, CI's
        # timeout is 10 s); the other functions must still prove within it
        r = proof.run_modified(source, functions=functions, cache_dir=cache, wp_timeout=PLANTED_TIMEOUT_S)
        out.update({name: r for name in group})
    return out


def _own(goals, functions) -> list[str]:
    return [g for g in goals if any(g.startswith(f"typed_{fn}_") for fn in functions)]


def test_planted_bugs_share_runs_only_where_their_functions_are_disjoint():
    groups = _groups()
    assert sorted(n for g in groups for n in g) == sorted(BUGS) and len(groups) < len(BUGS)
    for g in groups:
        proved = [fn for n in g for fn in BUGS[n].prove]
        assert len(proved) == len(set(proved)), g


@pytest.mark.parametrize("name", list(BUGS))
def test_planted_bug_fails_the_proof_on_its_own_goals(planted, name):
    """The proof must fail, on goals of the bug's `fail` functions only (among those it
    proves), on each of them, and on the property named."""
    bug, r = BUGS[name], planted[name]
    failed = _own(r["wp"]["failed"], bug.prove)
    assert not r["ok"] and not r["wp"]["ok"] and failed, r["wp"]
    assert failed == _own(failed, bug.fail), failed
    assert all(_own(failed, (fn,)) for fn in bug.fail), failed
    assert (all if bug.every else any)(g.startswith(bug.goal) for g in failed), failed
    # every other function this bug's run proves is proved: the bug stays where it is planted
    for fn in bug.prove:
        if fn not in bug.fail:
            f = r["wp"]["per_function"][fn]
            assert f["total"] > 0 and f["proved"] == f["total"], (name, fn, f)


def test_a_failed_proof_is_a_failed_check_naming_the_goal(planted):
    r = planted["2oo2 distance max"]
    checks = {c.name: c for c in proof.checks_of(r)}
    assert not checks["proof: all WP goals proved"].passed
    assert r["wp"]["proved"] < r["wp"]["summary_total"]
    assert r["wp"]["failed"][0] in checks["proof: all WP goals proved"].figure


def test_missing_frama_c_is_a_failed_check(monkeypatch, tmp_path):
    monkeypatch.setattr(proof, "missing_tools", lambda env=None: ["frama-c"])
    monkeypatch.setenv("CI", "true")
    sec = proof.section(tmp_path, True, lambda s: None)
    assert isinstance(sec, Section)
    names = {c.name: c for c in sec.checks}
    assert not names["proof: all WP goals proved"].passed and not names["proof: EVA alarms on rg_step"].passed
    assert "apt-get install frama-c-base why3 z3 cvc4" in names["proof: all WP goals proved"].figure


# ---------------------------------------------------------------- (c) the contracts are there

def _contract(function: str) -> str:
    """The ACSL comment right before the function's definition in rg_core.c."""
    m = re.search(r"/\*@((?:(?!\*/).)*)\*/\s*\n[^\n;{]*\b" + re.escape(function) + r"\s*\([^;{]*\)\s*\{", SOURCE, re.S)
    assert m, f"no ACSL contract before the definition of {function}"
    return m.group(1)


# functions whose arithmetic needs its arguments' ranges (as the Python preconditions say)
RANGED = ("rg_age_ms", "rg_gradient_accel_mms2", "rg_scaled_decel_mms2", "rg_effective_decel_mms2", "rg_run_dm",
          "rg_speed_after_cms", "rg_band_stop", "rg_obstacle_run_dm", "rg_cap_dm", "rg_hold", "rg_decide",
          "rg_accel_run", "rg_near_travel", "rg_far_travel", "rg_observe", "rg_forget")


@pytest.mark.parametrize("function", proof.FUNCTIONS)
def test_every_listed_function_has_a_contract(function):
    spec = _contract(function)
    assert re.search(r"\bassigns\b", spec), function
    assert re.search(r"\bensures\b", spec), function
    takes_pointer = re.search(r"\b" + function + r"\s*\(([^)]*)\)", SOURCE).group(1).count("*") > 0
    if takes_pointer or function in RANGED:
        assert re.search(r"\brequires\b", spec), function


def test_contracts_state_the_python_properties():
    """Spot checks that the contracts say what the PEP 316 contracts say."""
    assert r"*status == \max(sa, sb)" in _contract("rg_vote_2oo2")
    assert r"*distance == \min(da, db)" in _contract("rg_vote_2oo2")
    assert "*distance == rg_min3(d[0], d[1], d[2])" in _contract("rg_vote_3oo3")
    assert "s[0] != s[1] || s[1] != s[2] ==> *error == 1" in _contract("rg_vote_3oo3")
    assert "0 <= demand <= 2 && level == 2 && speed_cms > 0 && revocable == 0 ==> \\result == 2" in _contract("rg_hold")
    assert "speed_cms > 0 && calm + 1 < confirm ==> \\result >= level" in _contract("rg_hold")
    assert "*calm_out < confirm && (*calm_out == 0 || *calm_out == calm + 1)" in _contract("rg_hold")
    assert "demand == 2 && level <= 2 ==> \\result == 2" in _contract("rg_hold")
    assert "speed_cms > 0 && zone_free == 0 ==> \\result >= level" in _contract("rg_table_hold")
    assert "\\result >= envelope && \\result >= table_demand && \\result >= error_demand" in _contract("rg_combine")
    assert "\\result * 200000000 >= rg_run_num(speed_cms, accel_mms2, time_ms)" in _contract("rg_run_dm")
    assert "\\result * 1000 <= decel_mms2 * factor_permille" in _contract("rg_scaled_decel_mms2")
    assert "track == 0 && brake == 0 ==> \\result == decel_mms2 - gradient_mms2" in _contract("rg_effective_decel_mms2")
    assert "present != 0 && distance_dm <= ebi_dm ==> \\result == 2" in _contract("rg_supervision_demand")
    assert "rg_fresh_p(received, now, limit) ==> \\result == now - received" in _contract("rg_age_ms")
    # issue 29: a demand a curve raised is not lowered while the train is inside that curve for
    # the remembered obstacle: the choice of the supervised obstacle, and the whole decision
    assert "remembered != 0 && track_dm <= track_ebi_dm ==> \\result == 2" in _contract("rg_supervised_demand")
    assert "held == 2 && remembered != 0 && track_dm <= track_sbi_dm ==> \\result == 2" \
        in _contract("rg_supervised_demand")
    decide = _contract("rg_decide")
    assert "track_sup != 0 && track_dm <= remembered->ebi_dm ==> d->env == 2 && d->final_demand >= 2" in decide
    assert "level == 2 && track_sup != 0 && track_dm <= remembered->sbi_dm ==> d->env == 2" in decide
    # the memory: every term of the prediction, no evidence outside the sensor range
    assert "+ accel_mms2 * period_ms * period_ms + 20000 * obstacle_cms * period_ms" in _contract("rg_near_travel")
    assert "*state == 4 ==> evidence != 0 && 0 <= far <= range_dm * 10000" in _contract("rg_forget")
    assert "confirmed == 0 && \\old(track->near) != -1 ==>" in _contract("rg_observe")
    # a module's sighting creates the track (issue 38 item 1)
    assert "ensures sighted != 0 && \\old(track->near) == -1 ==>" in _contract("rg_observe")


def test_planted_runtime_error_is_an_eva_alarm(cache):
    """rg_is_fresh as it was before the proof (`now - received` overflows int64 for extreme
    ticks): WP cannot prove its RTE guard and EVA raises an alarm in the step."""
    old = "    return received <= now && now - received <= timeout_ticks;\n}"
    start = SOURCE.index("int32_t rg_is_fresh(int64_t received")
    body = SOURCE.index("{", start)
    end = SOURCE.index("\n}", body) + 2
    bug = SOURCE[:body] + "{\n" + old + SOURCE[end:]
    assert bug != SOURCE and "if (received >= 0) return" not in bug
    r = proof.run_modified(bug, eva=True, eva_runs=proof.EVA_RUNS[:1], functions=("rg_is_fresh", "rg_effective_status"),
                           cache_dir=cache)
    assert not r["ok"]
    assert any("rg_is_fresh_assert_rte_signed_overflow" in g for g in r["wp"]["failed"]), r["wp"]["failed"]
    step = r["eva"][0]
    assert step["alarms"] > 0
    assert any("signed_overflow" in m or "signed overflow" in m for m in step["alarm_messages"]), step["alarm_messages"]
    checks = {c.name: c for c in proof.checks_of(r)}
    assert not checks["proof: EVA alarms on rg_step"].passed
