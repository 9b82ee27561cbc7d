"""The information relaxation's upper bound (monitor/offline/relaxation.py): refused unless
it observes at least as well as the model, above the optimum, and tighter on Model 2."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import replace

import numpy as np
import pytest

from conftest import ROOT, TABLES
from monitor.core import table as table_format
from monitor.offline import pipeline
from monitor.offline.models import model2
from monitor.offline.pomdp import ModelError
from monitor.offline.relaxation import Relaxation
from monitor.offline.solver import SolverSettings, solve


def perfect_listening(tiger) -> Relaxation:
    """Tiger whose `listen` hears the tiger without error; the model's 85 % is that garbled."""
    listen = tiger.actions.index("listen")
    O = np.array(tiger.O)
    G = O[listen].copy()                 # row s: what the model hears when the relaxation hears s
    O[listen] = np.eye(len(tiger.states))
    return Relaxation(replace(tiger, O=O), G, "the tiger heard without error")


def test_model2_relaxation_reads_all_but_the_distance_exactly(m2):
    model, _ = m2
    relax = model2.relaxation(model)
    relax.check(model)
    comps = [s.split("-") for s in model.states]
    for s in (0, 37, 101):
        seen = np.flatnonzero(relax.model.O[0, s] > 0)
        assert all(comps[o][1:] == comps[s][1:] for o in seen), "a revealed component was misread"
        assert len(seen) == 4                                 # the distance is still misread
    assert not np.array_equal(relax.model.O, model.O)


def test_a_relaxation_that_sees_less_or_moves_differently_is_refused(m2):
    model, _ = m2
    relax = model2.relaxation(model)
    backwards = Relaxation(model, relax.garbling, "the model posing as its own relaxation")
    with pytest.raises(ModelError, match="would not be an upper bound"):
        backwards.check(relax.model)
    T = np.array(model.T)
    T[0, 0] = np.roll(T[0, 0], 1)
    with pytest.raises(ModelError, match="T differs"):
        Relaxation(replace(relax.model, T=T), relax.garbling, "other dynamics").check(model)
    with pytest.raises(ModelError, match="not probability distributions"):
        Relaxation(relax.model, relax.garbling * 2.0, "no channel").check(model)


def test_tiger_relaxation_bounds_the_optimum_from_above(tiger):
    """Solved to 0.1 %, the relaxation's lower bound is above the model's upper bound: its
    optimum is strictly above the model's, as the garbling argument says it is at least."""
    relax = perfect_listening(tiger)
    relax.check(tiger)
    settings = SolverSettings(target_gap=1e-3, time_budget_s=60.0)
    own, relaxed = solve(tiger, settings), solve(relax.model, settings)
    assert own.stop_reason == relaxed.stop_reason == "target_gap"
    assert own.upper_bound < relaxed.lower_bound
    assert own.lower_bound == pytest.approx(19.37, abs=0.02)


def test_model2_relaxed_bound_is_valid_and_tighter_than_the_model_own(m2):
    """At equal trials (HSVI is deterministic), the relaxation's upper bound is below the
    model's own and above everything the model is known to reach: its alpha vectors and
    the shipped table's exact value."""
    model, plan = m2
    settings = replace(plan.settings, max_iterations=30, time_budget_s=1e9)
    own = solve(model, settings)
    relaxed = solve(model2.relaxation(model).model, settings)
    shipped = table_format.decode((TABLES / "m2.table.rgt").read_bytes(), expect_model="m2")
    assert relaxed.upper_bound < own.upper_bound - 1e-3
    assert relaxed.upper_bound >= own.lower_bound
    assert relaxed.upper_bound >= shipped.header["controller_value"]


def test_no_relaxation_is_started_without_time_left(m2):
    model, plan = m2
    said: list[str] = []
    assert pipeline.relaxed_bound(model2.relaxation(model), plan, time.perf_counter() + 0.5, said.append) is None
    assert said and "no time left" in said[0]


def test_a_late_compilation_still_leaves_the_relaxation_its_floor():
    """CI's realtime phase (2026-12-01): a compile round ended past RELAX_SHARE and the 90 s
    solve printed no relaxation bound. The relaxation now keeps RELAX_FLOOR_SHARE of the budget."""
    now = time.perf_counter()
    late = pipeline.relax_deadline(now - 80.0, 90.0)           # started 80 s ago: 85 % of 90 s is past
    assert late >= now + pipeline.RELAX_FLOOR_SHARE * 90.0 - 1e-6
    assert late - now < pipeline.RELAX_FLOOR_SHARE * 90.0 + 1.0
    early = pipeline.relax_deadline(now, 90.0)                 # on time: RELAX_SHARE of the budget
    assert abs(early - (now + pipeline.RELAX_SHARE * 90.0)) < 1e-6


# a wall-clock budget: under another test's load the compile used to leave the relaxation no time (since
# 2026-12-01 it keeps RELAX_FLOOR_SHARE of the budget whatever compilation took). The
# realtime phase runs two modules at a time, so the budget is 90 s (at 30 s one of three fresh-
# clone CI runs had the compile end too late, beside the vcan sandbox sessions; the relaxation
# has 70 % to 85 % of the budget since issue 41 gave compilation more of it: 13.5 s here)
@pytest.mark.realtime
def test_solve_m2_as_users_run_it_prints_the_tighter_bound(tmp_path):
    """`railguard solve --model m2` in a subprocess: the upper bound printed and written is the
    smaller of the model's own and the relaxation's, and the relaxation is named."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-m", "railguard", "solve", "--model", "m2", "--time-budget", "90",
                           "--json", "--out", str(tmp_path)], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    fig = json.loads(proc.stdout)
    assert fig["relaxation_upper_bound"] is not None, "90 s left no time for the relaxation"
    assert fig["upper_bound"] == min(fig["model_upper_bound"], fig["relaxation_upper_bound"])
    assert fig["lower_bound"] <= fig["upper_bound"] and fig["controller_value"] <= fig["upper_bound"]
    header = table_format.decode((tmp_path / "m2.table.rgt").read_bytes(), expect_model="m2").header
    assert header["upper_bound"] == fig["upper_bound"]
    assert header["relaxation"]["reveals"] == "speed, type, track and brake read without error"
    assert "information relaxation" in (tmp_path / "m2.summary.txt").read_text()
