"""The papers' risk estimators, live (monitor/core/risk.py and rg_core.c's rg_r1_ppm ...):
against the equations in floats, Python against C, and in the running core."""
from __future__ import annotations

import ctypes
import itertools
import random
import subprocess

import pytest

from conftest import ROOT
from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.risk import CRITICAL, K_LIMIT, ONE, PPM, exp_neg_q30, r1_ppm, r2_ppm, risk_category, risk_score
from monitor.core.types import ABSENT, DEGRADED, PRESENT, STATIC, Inputs, Report, Train
from monitor.offline import risk as paper
from monitor.tables import read

GRID = [(d, a) for d in list(range(0, 4000, 7)) + [10**4, 10**5, 10**6] for a in (1, 3, 58, 700, 3001, 4758, 33333)]


def test_the_exponential_is_positive_bounded_and_decreasing_for_every_k():
    values = [exp_neg_q30(k) for k in range(K_LIMIT + 2)]
    assert values[0] == ONE and all(0 < b <= a for a, b in zip(values, values[1:]))


def test_r1_is_eq_16_within_one_ppm():
    for d, a in GRID:
        assert abs(r1_ppm(d, a) - PPM * paper.r1_logistic(d, a)) <= 1.0, (d, a)
        assert 0 <= r1_ppm(d, a) <= 500_000
    assert r1_ppm(0, 4758) == 500_000 and r1_ppm(0, 0) == 500_000 and r1_ppm(5, 0) == 0


def test_r2_is_eq_17_rounded_up_and_clipped():
    for d, a in GRID:
        for a2 in (0, a // 3, a):
            want = PPM * paper.r2_linear(d, a, a2) if a > a2 else (PPM if d <= a2 else 0)
            got = r2_ppm(d, a, a2)
            assert want <= got <= want + 1, (d, a, a2, got, want)
    assert r2_ppm(100, 300, 100) == PPM and r2_ppm(300, 300, 100) == 0 and r2_ppm(200, 300, 100) == 500_000
    # rounded up where 10^6 (alpha1 - d) leaves a remainder of one span unit: 10^6 / 3
    assert r2_ppm(2, 3, 0) == 333_334 and r2_ppm(1, 3, 0) == 666_667


def test_r1_without_a_distance_scale_is_the_equations_limit():
    """alpha1 <= 0 (no curve: standstill, a receding obstacle): eq. 16's limit, 50 % at the
    obstacle and 0 anywhere in front of it."""
    assert r1_ppm(0, 0) == PPM // 2 and r1_ppm(0, -5) == PPM // 2
    assert r1_ppm(1, 0) == 0 and r1_ppm(60000, 0) == 0
    assert r1_ppm(1, 1) == 6_693                  # the smallest scale is a scale: 10^6 / (1 + e^5)


def test_score_and_category_are_eq_11_as_printed():
    for levels in itertools.product(range(4), range(3), range(3), range(2), range(2)):
        score = risk_score(*levels)
        assert score == paper.risk_score(*levels)
        assert risk_category(score) == paper.risk_category(score)
    assert risk_score(3, 2, 2, 1, 1) == 20 and risk_category(20) == CRITICAL


@pytest.fixture(scope="module")
def c_risk(tmp_path_factory):
    """rg_core.c built as a shared library, to call its risk functions directly."""
    core = ROOT / "fmu" / "c" / "core"
    lib = tmp_path_factory.mktemp("risk") / "librg.so"
    subprocess.run(["gcc", "-std=c99", "-O2", "-shared", "-fPIC", "-I", str(core), str(core / "rg_core.c"),
                    str(core / "rg_sha256.c"), "-o", str(lib)], check=True)
    c = ctypes.CDLL(str(lib))
    for name, n in (("rg_r1_ppm", 2), ("rg_r2_ppm", 3), ("rg_risk_score", 5), ("rg_risk_category", 1)):
        getattr(c, name).argtypes = [ctypes.c_int32] * n
        getattr(c, name).restype = ctypes.c_int32
    return c


def test_the_c_estimators_equal_the_python_ones(c_risk):
    rng = random.Random(31)
    triples = [(d, a, a2) for d, a in GRID for a2 in (0, a // 2)]
    triples += [(rng.randint(0, 70_000), rng.randint(-5, 60_000), 0) for _ in range(20_000)]
    for d, a1, a2 in triples:
        a2 = min(a2, max(a1, 0))
        assert c_risk.rg_r1_ppm(d, a1) == r1_ppm(d, a1), (d, a1)
        if a1 >= a2:
            assert c_risk.rg_r2_ppm(d, a1, a2) == r2_ppm(d, a1, a2), (d, a1, a2)
    for levels in itertools.product(range(4), range(3), range(3), range(2), range(2)):
        assert c_risk.rg_risk_score(*levels) == risk_score(*levels)
    for score in range(21):
        assert c_risk.rg_risk_category(score) == risk_category(score)


def run(reports_of, cycles: int, speed_cms: int = 2000, table: str = "m2"):
    """The Python core for `cycles` cycles of 100 ms with the reports `reports_of(k)`."""
    setup = cycle.create(Config(), read(table))
    state, outs = cycle.initial_state(setup), []
    for k in range(cycles):
        tick = 100 * k
        state, out = cycle.step(setup, state, Inputs(reports_of(k, tick), Train(speed_cms)), tick)
        outs.append(out)
    return setup, outs


def test_the_core_reports_the_risk_of_what_it_sees_and_never_calms_on_silence():
    """An obstacle approached from 600 m at 20 m/s: R1 and R2 rise as it nears, R2 reaches
    10^6 inside alpha2 (where the table observes 'critical'), the table's risk is its column
    at the node; then every channel goes blind: the remembered obstacle keeps the risk up."""
    def approach(k, tick):
        d = max(6000 - 20 * k, 0)
        return (Report(PRESENT, d, 2000, STATIC, tick),) * 6 if k < 280 else (Report(DEGRADED, 0, 0, STATIC, tick),) * 6

    setup, outs = run(approach, 300)
    seen = outs[5:280]
    assert all(o.table_risk_ppm == setup.table.risk[o.node] for o in outs)
    assert [o.r1_ppm for o in seen] == sorted(o.r1_ppm for o in seen)         # nearer, never less risky
    assert [o.r2_ppm for o in seen] == sorted(o.r2_ppm for o in seen)
    assert seen[0].r2_ppm == 0 and seen[-1].r2_ppm == PPM and seen[-1].observation // 36 == 3
    assert 0 < seen[-1].r1_ppm <= 500_000
    assert max(o.risk_category for o in seen) > min(o.risk_category for o in seen)
    blind = outs[281:]
    assert all(o.r2_ppm == PPM and o.r1_ppm >= seen[-1].r1_ppm for o in blind)


def test_a_clear_line_has_no_risk_and_a_blind_one_reads_as_an_obstacle_at_zero():
    _, clear = run(lambda k, tick: (Report(ABSENT, 0, 0, STATIC, tick),) * 6, 20)
    assert clear[-1].r1_ppm == clear[-1].r2_ppm == 0
    _, blind = run(lambda k, tick: (Report(DEGRADED, 0, 0, STATIC, tick),) * 6, 20)
    assert blind[-1].r1_ppm == 500_000 and blind[-1].r2_ppm == PPM
