"""railguard verify, hazard part: the 2oo2 module CTMC of seed 002, the 3oo3 hazard rate and
seed 004's SNCF estimate."""
from __future__ import annotations

import math
from dataclasses import replace
from fractions import Fraction

import numpy as np
import pytest

from verification import hazard as hz

PNG = b"\x89PNG\r\n\x1a\n"


def test_pfn_at_paper_point_is_0_0016():
    p = hz.p_fn(hz.ModuleParams())
    assert abs(p - 0.0016) / 0.0016 <= 0.05
    # with every fault but the perceptors' switched off it is exactly p_n * p_c
    clean = hz.ModuleParams(p_v=0.0, p_s=0.0, p_com=0.0)
    assert hz.p_fn(clean) == pytest.approx(0.04 * 0.04, rel=1e-12)
    assert hz.p_fn(replace(clean, p_n=0.1, p_c=0.02)) == pytest.approx(0.002, rel=1e-12)


def test_pfn_increases_with_p_n_and_p_c():
    ps = [0.02, 0.04, 0.06, 0.1]
    base = hz.ModuleParams()
    for fixed in ps:
        along_n = [hz.p_fn(replace(base, p_n=x, p_c=fixed)) for x in ps]
        along_c = [hz.p_fn(replace(base, p_n=fixed, p_c=x)) for x in ps]
        assert all(b > a for a, b in zip(along_n, along_n[1:]))
        assert all(b > a for a, b in zip(along_c, along_c[1:]))


def test_pfn_grows_with_voter_failure_and_matches_hand_formula():
    # obstacle demand, only perceptor and voter faults: FN = both miss (voter keeps r=0 or r=2
    # unflagged: 1 - pv/3) + one misses (any voter failure leaves the contradiction unflagged)
    # + both see it (voter fails to r=0 or r=2 unflagged: 2pv/3).
    pn, pc, pv = 0.05, 0.03, 1e-3
    p = hz.ModuleParams(p_n=pn, p_c=pc, p_v=pv, p_s=0.0, p_com=0.0, q_obs=1.0)
    hand = pn * pc * (1 - pv / 3) + (pn * (1 - pc) + pc * (1 - pn)) * pv + (1 - pn) * (1 - pc) * 2 * pv / 3
    assert hz.p_fn(p) == pytest.approx(hand, rel=1e-12)
    assert hz.p_fn(replace(p, p_v=2e-3)) > hz.p_fn(p)


def test_rates_do_not_change_pfn_and_eq4_decomposition():
    base = hz.ModuleParams()
    rates = tuple((a, r) for a, r in zip(hz.ACTIONS, (0.3, 7.0, 0.5, 2.0, 9.0, 0.1, 4.0, 1.5)))
    assert hz.p_fn(replace(base, rates=rates)) == pytest.approx(hz.p_fn(base), abs=1e-15)
    total, direct = hz.eq4(base)
    assert total == pytest.approx(direct, abs=1e-15)


def test_grid_batch_solver_equals_pointwise_solve():
    g = hz.grid_values(5)
    Z = hz.p_fn_grid(g, g)
    for i, j in ((0, 0), (1, 3), (4, 2), (4, 4)):
        p = replace(hz.ModuleParams(), p_n=float(g[j]), p_c=float(g[i]))
        assert Z[i, j] == pytest.approx(hz.p_fn(p), abs=1e-15)


def test_hazard_rate_formula():
    assert hz.hazard_rate(0.0016) == pytest.approx(2 / 24 * 0.0016 ** 3, rel=1e-15)
    assert hz.hazard_rate(0.0016) == pytest.approx(3.413e-10, rel=1e-3)
    arr = np.array([0.001, 0.002])
    assert np.allclose(hz.hazard_rate(arr), hz.LAMBDA_OD * arr ** 3, rtol=1e-15)
    assert hz.hazard_rate(0.01, lam=1.0) == pytest.approx(1e-6, rel=1e-12)


def test_storm_agrees_with_numpy():
    storm = hz.Storm()          # must import: no skip
    for p in (hz.ModuleParams(), hz.ModuleParams(p_n=0.1, p_c=0.02, p_v=1e-3),
              hz.ModuleParams(guards="race"), hz.ModuleParams(degraded="sensor", fin="clear")):
        value, _ = storm.p_fn_exact(p)
        assert abs(value - hz.p_fn(p)) <= 1e-9
    fn, evaluate, _ = storm.p_fn_parametric(hz.ModuleParams())
    for a, b in ((Fraction(1, 50), Fraction(1, 10)), (Fraction(1, 25), Fraction(1, 25))):
        p = replace(hz.ModuleParams(), p_n=float(a), p_c=float(b))
        assert abs(evaluate(a, b) - hz.p_fn(p)) <= 1e-9


def test_sncf_recomputation_from_the_table():
    s = hz.sncf()
    # by hand: ESRs 1, 3, 5, 4 -> mean 13/4, squared deviations sum 8.75, SD sqrt(8.75/3)
    assert s["mean"] == 3.25
    assert s["sd"] == pytest.approx(math.sqrt(8.75 / 3), rel=1e-12)
    assert s["sem"] == pytest.approx(math.sqrt(8.75 / 3) / 2, rel=1e-12)
    assert s["hours"] == 16 * 365 * 15000 == 87_600_000
    assert s["rate"] == pytest.approx(3.25 / 87.6e6, rel=1e-12)
    half = 1.959964 * math.sqrt(8.75 / 3) / 2
    assert s["ci_year_normal"] == pytest.approx((3.25 - half, 3.25 + half), rel=1e-6)
    lo, hi = s["ci_hour_normal"]
    assert f"{lo:.1e}" == "1.8e-08" and f"{hi:.1e}" == "5.6e-08"      # the paper's per-hour interval
    assert not (1.7 < s["ci_year_normal"][0] < 1.9)                    # ... but not its per-year one


def test_section_quick(tmp_path):
    sec = hz.section(tmp_path, quick=True, progress=print)
    failed = [c.line() for c in sec.checks if not c.passed]
    assert not failed, failed
    assert any("Storm" in c.name for c in sec.checks)
    assert sorted(sec.figures) == ["hazard_hr.png", "hazard_pfn.png"]
    for name in sec.figures:
        assert (tmp_path / name).read_bytes()[:8] == PNG
        assert f"]({name})" in sec.markdown
    assert "3.413e-10" in sec.markdown
    assert "| quantity | ours | paper | verdict |" in sec.markdown
