"""The release rule with the obstacle memory, proved as an inductive invariant over one
monitor cycle (issue 30 item 4), the way a KeYmaera proof of a controller loop splits.

The invariant, at every cycle while an obstacle is remembered:

    (M) the remembered position is never beyond the obstacle by more than the sensors'
        distance accuracy a: x >= N - a, where x is the true gap and N the remembered
        distance (N came from a report, within a of the truth; the error budget);
    (F) at a cycle whose demand is not an emergency, N > EBI(v) of the remembered obstacle
        (the core's rule: supervision_demand, combine, keep_held and hold only ever raise a
        demand; their CrossHair contracts), so x > EBI(v) - a: EBI counts a.

The step, for every train inside the declaration:

* `memory`: (M) is kept over a cycle: the gap shrinks at most by the train's travel (the
  reaction phase's dI bound, from a true speed within the speed error of the measured one)
  and the obstacle's, and the shipped `memory.near_travel` (run symbolically) moves N at
  least that much; after a sighting the same holds over the period *and the report's age*,
  which is why the age is counted there, once, and not by the remembered curves;
* `free cycle`: from (F), after one period without an emergency, an emergency demanded at
  the next cycle still stops the train `standstill_margin` short (the sufficiency chain
  with the closing speed the memory holds: the obstacle's own speed anything up to it; the
  curves count the sampling period, which is this free period);
* `never inside EBD`: from (F), after that period the true gap is still at least EBD at the
  true speed (stopping distance at the declared deceleration, worst gradient, plus margin
  and the obstacle's travel meanwhile).

Every emergency is preceded by a cycle without one (or by a voted obstacle, whose cycle the
sufficiency obligations cover), and a held emergency is released only where the rule no
longer demands it, that is in (F): so the train never comes closer than EBD to a remembered
obstacle while the brake is released, and stops short whenever it is demanded.
"""
from __future__ import annotations

import time
from fractions import Fraction

import z3

from monitor.core import memory, tracks
from monitor.core.config import Config, track_accel_mms2
from monitor.core.types import MAX_SPEED_CMS, Track

from . import symbolic
from .model import MAX_UPHILL, Declaration, G, band_sums, pos, q
from .obligations import CONDITIONS, EXPLORE_TIMEOUT_MS, TIMEOUT_MS, Lemmas, Result, refute, timed, value

MAX_OWN_CMS = 15000          # memory.near_travel's obstacle bound (the remembered own speed)


def memory_step(d: Declaration, accel: Fraction, timeout_ms: int = TIMEOUT_MS, count_age: bool = True) -> Result:
    """(M) over one cycle, real-valued: x >= N before, the train runs at most the reaction
    phase's bound over tau = period + age (age: a sighting's report age, else 0), the
    obstacle closes at most W tau, and N moves by at least the real near-travel bound
    (proved for the integer code in `near_travel_results`). `count_age=False`: the position
    moved by the period alone, as before the age was counted there (a test refutes it)."""
    v, v0, x, n, w, w0, grad, age, xp, moved = z3.Reals("v v0 x N W w0 grad age xp moved")
    a = q(d.distance_accuracy)       # (M) with the error budget: x >= N - a (N came from a report)
    e = q(d.speed_error)
    tau = age + q(d.period)
    step = tau if count_age else q(d.period)
    a_plus = pos(q(d.max_accel) + q(G) * grad)
    f = z3.And(0 <= v, v <= q(Fraction(MAX_SPEED_CMS, 100)), v * (1 - e) <= v0, v0 <= v * (1 + e),
               0 <= age, age <= q(d.max_age), -q(MAX_UPHILL) <= grad, grad <= q(d.max_gradient), 0 <= w, w0 <= w,
               n - a <= x, 0 <= xp, xp <= v0 * tau + a_plus * tau * tau / 2,    # the reaction phase's dI bound
               moved >= v * (1 + e) * step + q(accel) * step * step / 2 + w * step,  # near_travel's proved bound
               x - xp - pos(w0) * tau < n - a - moved)
    r = Result("memory: the remembered position never passes the obstacle over a cycle (the period, and a "
               "sighting's report age once)", "release", "memory")
    return timed(r, f, {"measured_speed": v, "true_speed": v0, "report_age": age, "gap": x, "remembered": n,
                        "train_travel": xp}, timeout_ms)


def near_travel_results(cfg: Config, d: Declaration, accel: int, timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    """The shipped memory.near_travel and memory.distance_dm, run symbolically: the travel is
    never less than the real bound `memory_step` assumes, the acceleration it is given is at
    least traction plus the steepest downhill, and the distance read from a position is never
    farther than the position."""
    s, w, p = z3.Reals("speed_cms own_cms period_ms")
    e = cfg.speed_error_permille
    max_p = cfg.period_ms + cfg.timeout_cycles * cfg.period_ms
    domain = [0 <= s, s <= MAX_SPEED_CMS, 0 <= w, w <= MAX_OWN_CMS, cfg.period_ms <= p, p <= max_p]
    out = []
    t0 = time.perf_counter()
    r = Result("memory: near_travel (shipped, symbolic) >= the speed plus its error, traction and downhill, and the "
               "obstacle's own speed over the period and a report's age", "integer", "memory.near_travel")
    real_accel = d.max_accel + G * d.max_gradient
    paths = symbolic.explore(memory.near_travel, {"speed_cms": s, "error_permille": e, "accel_mms2": accel,
                                                  "obstacle_cms": w, "period_ms": p}, domain,
                             timeout_ms=EXPLORE_TIMEOUT_MS)
    tau, vm = p / 1000, s / 100 * (1 + q(d.speed_error))
    bound = vm * tau + q(real_accel) * tau * tau / 2 + w / 100 * tau
    r.status = "proved" if Fraction(accel, 1000) >= real_accel else "refuted"
    if r.status == "proved":
        for path in paths:
            st, m = refute(z3.And(*domain, *path.condition, *path.side, path.value / 100000 < bound), timeout_ms)
            if st != "proved":
                r.status = st
                if m is not None:
                    r.model = {"speed": value(m, s) / 100, "own_speed": value(m, w) / 100,
                               "period_and_age": value(m, p) / 1000}
                break
    else:
        r.model = {"accel": accel / 1000, "traction_and_downhill": float(real_accel)}
    r.seconds = time.perf_counter() - t0
    out.append(r)
    t0 = time.perf_counter()
    near = z3.Real("near_units")
    r2 = Result("memory: distance_dm (shipped, symbolic) never reads a remembered position farther", "integer",
                "memory.distance_dm")
    dom = [0 <= near, near <= 655350000]
    r2.status = "proved"
    for path in symbolic.explore(memory.distance_dm, {"near": near}, dom, timeout_ms=EXPLORE_TIMEOUT_MS):
        st, _ = refute(z3.And(*dom, *path.condition, *path.side, path.value * 10000 > near), timeout_ms)
        if st != "proved":
            r2.status = st
            break
    r2.seconds = time.perf_counter() - t0
    out.append(r2)
    return out


def _symbolic_check(r: Result, fn, inputs: dict, domain: list, violated, named: dict, timeout_ms: int) -> Result:
    """`r` proved if on no feasible path of the shipped `fn` (run symbolically) `violated(value)`
    can hold together with the domain; else refuted with a model of its inputs, or unknown."""
    t0 = time.perf_counter()
    r.status = "proved"
    for path in symbolic.explore(fn, inputs, domain, timeout_ms=EXPLORE_TIMEOUT_MS):
        st, m = refute(z3.And(*domain, *path.condition, *path.side, violated(path.value)), timeout_ms)
        if st != "proved":
            r.status = st
            if m is not None:
                r.model = {k: value(m, t) for k, t in named.items()}
            break
    r.seconds = time.perf_counter() - t0
    return r


def tracks_results(timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    """(M) for every remembered obstacle through what the memory does to its tracks (issue 38
    item 2), on the shipped code run symbolically: a sighting (`memory.observe`) never puts
    a track beyond the sighting or beyond where the track already was, and never remembers a
    slower obstacle than it saw (confirmed: the measured speed; otherwise not below what was
    remembered either); two tracks merged when the memory is full (`tracks.merge`) are never
    farther or slower than either, and are forgotten or passed only where the farther could
    be. The sensors report their nearest object (the declaration), so the true gap x to a
    remembered obstacle is at least the sighting d as well as its old position: x >= N after."""
    out = []
    near, far, closing, dist, own, x = z3.Reals("near far closing distance_dm obstacle_cms gap")
    dom = [-1 <= near, near <= 600000000, near <= far, far <= 600000000, 0 <= closing, closing <= MAX_OWN_CMS,
           0 <= dist, dist <= 60000, -30000 <= own, own <= 30000, z3.Or(near == -1, near >= 0)]
    for confirmed, sighted, kind in ((True, True, "a confirmed sighting"), (False, True, "a module's sighting"),
                                     (False, False, "a disputed sighting no module confirms")):
        def seen(v, confirmed=confirmed):                 # (-1: no track, NO_TRACK)
            n2, _, c2, _ = v
            gap_ok = z3.Implies(z3.And(z3.Or(near == -1, x >= near), x >= dist * 10000), z3.Or(n2 == -1, x >= n2))
            speed_ok = z3.Implies(n2 != -1, z3.And(c2 >= own, z3.Or(confirmed, near == -1, c2 >= closing)))
            return z3.Not(z3.And(gap_ok, speed_ok))
        r = Result(f"memory: observe (shipped, symbolic) after {kind} keeps every track at or before its obstacle "
                   "and its speed at least the one seen (the sensors report their nearest object)", "release",
                   "memory.observe")
        out.append(_symbolic_check(
            r, memory.observe,
            {"near": near, "far": far, "closing": closing, "distance_dm": dist, "obstacle_cms": own, "age_now": 0,
             "confirmed": confirmed, "sighted": sighted}, dom, seen,
            {"near": near, "far": far, "closing": closing, "distance_dm": dist, "obstacle_cms": own, "gap": x},
            timeout_ms))
    an, af, ac, bn, bf, bc = z3.Reals("a_near a_far a_closing b_near b_far b_closing")
    mdom = [0 <= an, an <= af, 0 <= bn, bn <= bf, 0 <= ac, 0 <= bc]

    def merged(v):
        n2, f2, c2 = v[0], v[1], v[2]
        return z3.Or(n2 > an, n2 > bn, f2 < af, f2 < bf, c2 < ac, c2 < bc)

    r = Result("memory: merge (shipped, symbolic) of two tracks when the memory is full is never farther, nearer in "
               "its least position or slower than either", "release", "tracks.merge")
    out.append(_symbolic_check(
        r, lambda a_near, a_far, a_closing, b_near, b_far, b_closing: tracks.merge(
            Track(a_near, a_far, a_closing, 0, 0, True), Track(b_near, b_far, b_closing, 0, 0, False)),
        {"a_near": an, "a_far": af, "a_closing": ac, "b_near": bn, "b_far": bf, "b_closing": bc}, mdom, merged,
        {"a_near": an, "a_far": af, "a_closing": ac, "b_near": bn, "b_far": bf, "b_closing": bc}, timeout_ms))
    return out


def cycle_results(d: Declaration, timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    """(F) one free period on, per reported condition: an emergency demanded at the next
    cycle stops the train `standstill_margin` short of the remembered obstacle (the whole
    sufficiency chain, on the memory's closing speed: the curves count the sampling period,
    so the free period is the first of the reaction's two), and the train is still outside
    EBD at its true speed."""
    out = []
    for track, brake, cond in CONDITIONS:
        ctx = {"service": False, "kind": "remembered", "track": track, "brake": brake}
        lem = Lemmas(d, False, track, brake, remembered=True)
        for name, phase, formula in lem.steps() + lem.kind_steps("remembered"):
            r = Result(f"release, {cond}: {name.replace('(remembered)', '(remembered obstacle)')}", "release",
                       phase, context=ctx)
            out.append(timed(r, formula, lem.named(), timeout_ms))
        # never inside EBD after a free period: the train's travel and speed after one period
        # (the reaction phase's dI bounds over T), the EBD at its true speed then
        base = lem.domain
        p = lem.real.phases
        period = q(d.period)
        a_plus = pos(q(d.max_accel) + lem.gg)
        xp, u = z3.Reals("xp u")
        sd, td = band_sums(lem.brakes, lem.declared_net, u)
        free = [0 <= xp, xp <= lem.v0 * period + a_plus * period * period / 2, 0 <= u, u <= lem.v0 + a_plus * period]
        ebd_after = z3.Reals("S_ebd T_ebd")
        steps = [
            ("after a free period, the stopping distance and time at the true speed within the curve's phase 3",
             "braking", z3.And(*base, *free, z3.Or(sd > p["s3"], td > p["t3"]))),
            ("after a free period, the true gap is still at least EBD at the true speed", "composition",
             z3.And(*base, *free, ebd_after[0] <= p["s3"], ebd_after[1] <= p["t3"], lem.Dr >= lem.real.ebi,
                    lem.D - xp - pos(lem.w0) * period
                    < ebd_after[0] + q(d.margin) + pos(lem.w0) * ebd_after[1]))]
        for name, phase, formula in steps:
            r = Result(f"release, {cond}: {name}", "release", phase, context=ctx)
            out.append(timed(r, formula, {**lem.named(), "travel_in_period": xp, "speed_after_period": u},
                             timeout_ms))
    return out


def release_results(cfg: Config, d: Declaration, timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    accel = track_accel_mms2(cfg)
    return ([memory_step(d, Fraction(accel, 1000), timeout_ms)] + near_travel_results(cfg, d, accel, timeout_ms)
            + tracks_results(timeout_ms) + cycle_results(d, timeout_ms))

