"""The equivalent build-up proved (verification/physics/buildup.py, issue 40 item 4): every
obligation proves for the shipped and example declarations; each wrong claim is refuted, and a
plain simulation (written here, independent of the module) shows the refuted train running farther."""
from __future__ import annotations

import random
import time
from dataclasses import replace
from fractions import Fraction

import z3

from monitor.core.config import Config
from verification.physics import buildup, declarations, obligations
from verification.physics.buildup import ACC_E, S, VE, X, V, XE
from verification.physics.model import G, Declaration

PAPERS = Declaration.of(Config())


def per_declaration() -> int:
    """Obligations per declaration: 3 per brake, 7 per brake and reported condition."""
    return 2 * 3 + 7 * (len(obligations.CONDITIONS) + len(obligations.SERVICE_CONDITIONS))


# --------------------------------------------------------- an independent simulation


def stop(bands, u, gg, accel, tc, brake, settle, dt=1e-4):
    """(distance, time) to standstill from speed u at the demand: acc = gg + traction (until tc)
    - brake(s, v), Euler steps until `settle` (full brake, no traction), then the bands' closed form."""
    x, v, s = 0.0, u, 0.0
    while s < settle:
        a = gg + (accel if s < tc else 0.0) - brake(s, v)
        nv = max(v + a * dt, 0.0)
        x, v, s = x + (v + nv) / 2 * dt, nv, s + dt
        if v == 0.0 and a < 0:                  # held by the brake: its bound only falls
            return x, s
    for lo, d in reversed(bands):
        if v > lo:
            x, s, v = x + (v * v - lo * lo) / (2 * (d - gg)), s + (v - lo) / (d - gg), lo
    return x, s


def band_decel(bands, v):
    return [d for lo, d in bands if v >= lo][-1]


def compare(d: Declaration, u, td, tr, ramp="band", buildup_s=None):
    """(real - equivalent) stopping distance and time, emergency brake, normal conditions, worst gradient."""
    bands = [(float(lo), float(a)) for lo, a in d.bands]
    gg, tc = float(G * d.max_gradient), float(d.traction_cutoff)
    te = max(float(buildup_s if buildup_s is not None else d.emergency_buildup), tc)
    weakest = min(a for _, a in bands)

    def real(s, v):
        r = 0.0 if s < td else 1.0 if s >= td + tr else (s - td) / tr
        return r * (weakest if ramp == "weakest" and r < 1 else band_decel(bands, v))

    settle = max(td + tr, te, tc) + 1e-3
    xr, sr = stop(bands, u, gg, float(d.max_accel), tc, real, settle)
    xe, se = stop(bands, u, gg, float(d.max_accel), tc, lambda s, v: band_decel(bands, v) if s >= te else 0.0,
                  settle)
    return xr - xe, sr - se


# ------------------------------------------------------------------------- the proof


def test_the_equivalent_build_up_is_proved_for_the_shipped_and_example_declarations():
    for label, cfg in declarations(None):
        t0 = time.perf_counter()
        results = buildup.buildup_results(Declaration.of(cfg))
        assert time.perf_counter() - t0 < 10, label
        assert len(results) == per_declaration() == 41, label
        assert {(r.kind, r.phase) for r in results} == {("dI", "build-up")}
        assert [r.name for r in results if not r.proved] == [], label
        names = " ".join(r.name for r in results)
        for piece in ("dead time", "ramp, the equivalent coasting", "ramp, the equivalent braking",
                      "full brake, the equivalent coasting", "full brake, both braking", "x <= x_eq", "F >= 0"):
            assert piece in names


def test_a_ramp_counted_at_a_quarter_is_refuted_and_such_a_brake_stops_farther():
    results = buildup.buildup_results(PAPERS, equivalent=Fraction(1, 4))
    refuted = [r for r in results if r.status == "refuted"]
    assert [r.name for r in refuted] == [r.name for r in results if "never below" in r.name]
    assert {r.context["service"] for r in refuted} == {False, True}
    assert all(r.proved for r in results if r not in refuted)
    m = refuted[0].model                     # the emergency brake's counterexample
    T = float(PAPERS.emergency_buildup)
    assert m["dead_time"] + m["ramp"] / 4 <= T + 1e-9 < m["dead_time"] + m["ramp"] / 2
    dx, dt = compare(PAPERS, 20.0, m["dead_time"], m["ramp"])
    assert dx > 1.0 and dt > 0.05            # the real brake stops later and farther than T allows


def test_a_ramp_towards_the_weakest_band_is_refuted_and_such_a_brake_stops_farther():
    results = buildup.buildup_results(PAPERS, ramp="weakest")
    refuted = {r.name for r in results if r.status == "refuted"}
    for _, _, cond in obligations.CONDITIONS:
        assert f"build-up (emergency, {cond}): dI p >= 0 in the ramp, the equivalent coasting" in refuted
    assert all(r.proved for r in results if r.context["service"])     # one band: the weakest is the band
    assert all(r.proved for r in results if "ramp" not in r.name)
    one_band = Declaration.of(dict(declarations(None))["examples/braking-one-band.toml"])
    assert all(r.proved for r in buildup.buildup_results(one_band, ramp="weakest"))
    # in the stronger low band (2.4 against 2.2), a ramp that only reaches 2.2 stops farther
    dx, _ = compare(PAPERS, 20.0, 0.0, 2.0, ramp="weakest")
    assert dx > 0.1
    dx, dt = compare(PAPERS, 20.0, 0.0, 2.0)
    assert dx < 0 and dt < 1e-2


def test_decelerations_rising_with_speed_are_refuted_downhill_and_such_a_train_stops_farther():
    rising = replace(PAPERS, bands=((Fraction(0), Fraction(1)), (Fraction(30), Fraction(5))),
                     max_gradient=Fraction(50, 1000))
    results = buildup.buildup_results(rising)
    refuted = {r.name for r in results if r.status == "refuted"}
    for seg in buildup.segments(z3.RealVal(1)):
        assert f"build-up (emergency, normal): dI p >= 0 in the {seg.name}" in refuted
    assert all(r.proved for r in results if r.context["service"])
    # the lead is lost only to a drift: on the level without traction the same bands prove
    level = replace(rising, max_gradient=Fraction(0), max_accel=Fraction(0))
    assert all(r.proved for r in buildup.buildup_results(level))
    # the real train brakes into the weak low band early and, downhill, gains on the equivalent
    dx, dt = compare(rising, 30.2, 0.0, 2.0)
    assert dx > 5.0 and dt > 0.1


def test_the_comparison_s_lie_derivative_is_the_derivative_and_wrong_invariants_are_refuted():
    p = VE * S - X * X
    deriv, third = buildup.lie_derivative(p)
    assert obligations.refute(z3.Or(deriv != ACC_E * S + VE - 2 * X * V, third != 0))[0] == "proved"
    assert obligations.refute(buildup.di_fails(S * S * S, []))[0] == "refuted"          # a cubic is refused
    assert obligations.refute(buildup.di_fails(X - XE, [V < VE]))[0] == "refuted"       # x >= x_eq is wrong
    # v <= v_eq alone is not inductive once the equivalent brakes fully during the real ramp
    b = buildup.Brake.of(PAPERS, False, 0, 0)
    seg = buildup.segments(z3.RealVal(b.te))[2]
    cons = [*buildup.hypotheses(b, Fraction(1, 2)), *seg.when, *buildup.state(b, 0, 0),
            *buildup.dynamics(b, seg, 0, 0, "band")]
    assert obligations.refute(buildup.di_fails(VE - V, cons))[0] == "refuted"
    assert obligations.refute(buildup.di_fails(buildup.invariant(b, seg, 0, 0), cons))[0] == "proved"


def test_sampled_real_brakes_stop_no_farther_and_no_later_than_the_equivalent():
    rng = random.Random(40)
    for label, cfg in declarations(None):
        d = Declaration.of(cfg)
        T = float(d.emergency_buildup)
        lows = [float(lo) for lo, _ in d.bands]
        for _ in range(4):
            tr = rng.uniform(0, 2 * T)
            td = rng.uniform(0, T - tr / 2)
            u = max(0.5, rng.choice(lows) + rng.uniform(-2, 2))
            dx, dt = compare(d, u, td, tr)
            assert dx <= 1e-2 and dt <= 1e-2, (label, u, td, tr, dx, dt)


def test_the_pieces_the_start_and_the_order_can_fail_too(monkeypatch):
    """A stretch of time left out, a jump in F, a tau that falls with the speed: each is refuted."""
    segs, tau = buildup.segments, buildup.Brake.tau

    def refuted():
        return {r.name for r in buildup.buildup_results(PAPERS) if r.status == "refuted"}

    pieces = {f"build-up ({b}): the time segments cover every instant and F is continuous across them"
              for b in ("emergency", "service")}
    monkeypatch.setattr(buildup, "segments", lambda te: segs(te)[:-1])           # after both brake fully: a gap
    assert refuted() == pieces
    monkeypatch.setattr(buildup, "segments", lambda te: [*segs(te)[:-1], replace(
        segs(te)[-1], f_num=te - buildup.TD - buildup.TR / 4)])                    # F jumps at the last seam
    assert refuted() == pieces
    monkeypatch.setattr(buildup, "segments", segs)
    monkeypatch.setattr(buildup.Brake, "tau", lambda self, i, w: -tau(self, i, w))
    wrong = refuted()
    for _, _, cond in obligations.CONDITIONS:
        assert any(n.startswith(f"build-up (emergency, {cond}): p = tau(v_eq) - tau(v) - F > 0") for n in wrong)
        assert any(n.startswith(f"build-up (emergency, {cond}): p > 0 and F >= 0 give v < v_eq") for n in wrong)
