"""The risk repair (monitor/offline/risk_repair.py, issue 41): its first-order hazard change
against exact evaluations, what a repair may and may not do, monotonicity kept where the
model has conditions (judged by the independent product check), and `railguard table repair`
as a user runs it."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from monitor.core.table import decode
from monitor.offline.controller import Controller
from monitor.offline.layered import ConditionLayer
from monitor.offline.models import M1_HAZARD_PRICE, load
from monitor.offline.pipeline import horizon_cycles, read_alphas
from monitor.offline.risk_repair import hazard, hazard_gradient, monotone_pairs, raised_to_monotone, repair
from monitor.tables import read as read_table
from verification import monotone
from verification.closed_loop import hazard_within

from conftest import ROOT


@pytest.fixture(scope="module")
def m1():
    """Model 1 and its table as compiled, before the repair and the warning confirmation (the
    shipped table has both; the model prices the confirmation's wait as a free raise)."""
    from dataclasses import replace

    from monitor.offline.pipeline import run

    model, plan = load("m1")
    table = decode(run(model, replace(plan, hazard_price=0.0, warning_confirmation=0)).table)
    assert "risk_repair" not in table.header and "warning_confirmation" not in table.header
    return model, Controller.of_table(table), plan


def test_hazard_is_the_closed_loop_figure(m1):
    """The repair's P(hazard) is verification's figure for the same controller."""
    model, ctrl, _ = m1
    from verification.policies import supervised, supervision_floor

    steps = horizon_cycles(model)
    assert hazard(model, ctrl, steps) == pytest.approx(
        hazard_within(model, supervised(ctrl, supervision_floor(model)), steps)[0], rel=1e-9)


def test_first_order_hazard_change_matches_exact_single_raises(m1):
    """Every single raise of m1's table: the first-order change within 2 % (or 1e-9) of the
    exact change. A gradient with the backward reach off by a cycle, or without the
    supervision's floor, misses the large ones by far more."""
    model, ctrl, _ = m1
    steps = horizon_cycles(model)
    base = hazard(model, ctrl, steps)
    d = hazard_gradient(model, ctrl, steps)
    big = 0
    for n in range(ctrl.nodes):
        for a in range(int(ctrl.action[n]) + 1, 3):
            act = ctrl.action.copy()
            act[n] = a
            exact = hazard(model, Controller(act, ctrl.next, ctrl.start), steps) - base
            assert d[n, a] == pytest.approx(exact, rel=0.02, abs=1e-9), (n, a)
            big += abs(exact) > 1e-4
    assert big >= 2          # the test sees raises that matter


def test_repair_only_raises_and_pays_less_than_its_price(m1):
    model, ctrl, _ = m1
    steps = horizon_cycles(model)
    fixed = repair(model, ctrl, steps, M1_HAZARD_PRICE)
    assert (fixed.controller.action >= ctrl.action).all()
    assert (fixed.controller.next == ctrl.next).all() and fixed.controller.start == ctrl.start
    assert fixed.p_hazard < 5e-5 < 8e-4 < fixed.p_before
    assert fixed.p_hazard == pytest.approx(hazard(model, fixed.controller, steps), rel=1e-12)
    p, v = fixed.p_before, fixed.value_before
    for r in fixed.rounds:
        assert r.p_hazard < p and r.price < M1_HAZARD_PRICE
        assert r.price == pytest.approx(max(v - r.value, 0.0) / (p - r.p_hazard))
        p, v = r.p_hazard, r.value
    assert [n for n, _, _ in fixed.raised()] == np.flatnonzero(fixed.controller.action != ctrl.action).tolist()
    assert all(ctrl.action[n] == b < a == fixed.controller.action[n] for n, b, a in fixed.raised())
    # a price below the cheapest raise buys nothing
    cheap = repair(model, ctrl, steps, 1.0)
    assert not cheap.rounds and (cheap.controller.action == ctrl.action).all()


def test_raises_keep_m2_monotone_by_the_independent_check():
    """m2's shipped table: a raise that alone breaks monotonicity (found by verification's
    product check) passes it once raised_to_monotone adds the nodes it forces."""
    table = decode(read_table("m2"))
    ctrl = Controller.of_table(table)
    model, plan = load("m2")
    layer = ConditionLayer.of(model.observations, plan.conditions)
    pairs = monotone_pairs(ctrl, layer)

    def check(action):
        from monitor.core.table import encode

        header = {k: v for k, v in table.header.items() if k not in ("nodes", "index_bytes", "format_version", "risk")}
        return monotone.check(decode(encode(header, action.tolist(), [list(r) for r in table.next])))

    assert check(ctrl.action).monotone
    breaking = None
    for n in np.flatnonzero(ctrl.action < 2):
        act = ctrl.action.copy()
        act[n] = 2
        if (raised_to_monotone(act, pairs) != act).any():
            breaking = act
            break
    assert breaking is not None
    assert not check(breaking).monotone
    fixed = raised_to_monotone(breaking, pairs)
    assert (fixed >= breaking).all() and check(fixed).monotone


def test_table_repair_command(tmp_path):
    out = tmp_path / "m1.table.rgt"
    run = subprocess.run([sys.executable, "-m", "railguard", "table", "repair", "m1", "--out", str(out), "--json"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stderr
    got = json.loads(run.stdout)
    new = decode(out.read_bytes())
    assert got["sha256"] == new.sha256 and new.header["risk_repair"]["p_hazard"] == got["p_hazard"]
    assert got["p_hazard"] <= got["p_hazard_before"]
    read_alphas(tmp_path / "m1.alphas.npz", new.sha256)          # tied to the new digest
    shown = subprocess.run([sys.executable, "-m", "railguard", "table", "show", str(out)],
                           capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert shown.returncode == 0 and "risk repair      P(hazard within 30 s) 0.000906 -> 3.72e-05" in shown.stdout
    # m2 has no price of its own: refused in one line, exit 2
    run = subprocess.run([sys.executable, "-m", "railguard", "table", "repair", "m2", "--out", str(tmp_path / "x")],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 2 and "give --price" in run.stderr and len(run.stderr.strip().splitlines()) == 1
