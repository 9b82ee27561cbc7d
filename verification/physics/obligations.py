"""The proof obligations of `railguard verify --part physics` and their checking with Z3.

Three kinds, each named after the phase or the piece of code it covers:

* `dI`: a phase's bound is a differential invariant of the model (model.phase_invariants);
* `sufficiency`: from the phases' bounds, a brake demanded at distance >= the real-valued
  curve stops the train `standstill_margin` before the obstacle, for every train, gradient,
  speed error, report age and closing speed inside the declaration (issue 30 item 2), per
  curve (emergency: EBI; service: the service-brake curve alpha1), obstacle kind (static,
  receding, oncoming) and reported condition (normal, slippery, degraded, both);
* `integer`: the integer curves of the shipped monitor/core/braking.py, run symbolically
  (symbolic.py), and those of the C core's rg_curves (c_symbolic.py), are never shorter than
  the real-valued ones, on every path (item 3);
* `release`: the release rule with the obstacle memory as an inductive invariant over one
  cycle (release.py, item 4).

An obligation is refuted by a Z3 model (a counterexample), proved when Z3 says unsat, and
unknown on a timeout; only `proved` counts.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from fractions import Fraction
from functools import lru_cache
from types import SimpleNamespace
from typing import Callable, Optional

import z3

from monitor.core.config import Config
from monitor.core.types import MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS

from . import symbolic
from .model import (CONTRACT_PERIODS, CONTRACT_ZONE_PERIODS, G, MAX_TRACK_CLOSING_CMS, MAX_UPHILL, Declaration,
                    band_sums, band_terms, band_top, invariant_obligation, phase_invariants, pos, q, real_curves)

CONDITIONS = ((0, 0, "normal"), (1, 0, "slippery"), (0, 1, "degraded"), (1, 1, "slippery+degraded"))
SERVICE_CONDITIONS = CONDITIONS[:1]   # the core uses the service curve (the table's alpha1) under normal conditions only
KINDS = ("static", "receding", "oncoming")
CURVES = ("ebd", "ebi", "sbi", "warning")
STEPS_FROM = {"sbi": "ebi", "warning": "sbi"}     # each curve is the one before it plus a lead's run
TIMEOUT_MS = 60000
EXPLORE_TIMEOUT_MS = 2000     # a branch side Z3 cannot rule out this fast is followed (sound: one more path)


@dataclass
class Result:
    name: str
    kind: str                      # dI, sufficiency, integer, release
    phase: str
    status: str = "unknown"        # proved, refuted, unknown
    seconds: float = 0.0
    model: dict = field(default_factory=dict)     # the counterexample, in SI units (refuted only)
    context: dict = field(default_factory=dict)   # curve, obstacle kind, condition

    @property
    def proved(self) -> bool:
        return self.status == "proved"

    def line(self) -> str:
        return f"{'PROVED ' if self.proved else self.status.upper():8} {self.seconds:6.2f} s  {self.name}"


def refute(formula, timeout_ms: int = TIMEOUT_MS) -> tuple[str, Optional[z3.ModelRef]]:
    s = z3.Solver()
    s.set("timeout", timeout_ms)
    s.add(formula)
    r = s.check()
    if r == z3.unsat:
        return "proved", None
    if r == z3.sat:
        return "refuted", s.model()
    return "unknown", None


def value(model: z3.ModelRef, term) -> float:
    v = model.eval(term, model_completion=True)
    if z3.is_rational_value(v):
        return float(Fraction(v.numerator_as_long(), v.denominator_as_long()))
    if z3.is_algebraic_value(v):
        return float(v.approx(12).as_fraction())
    return float(str(v))


def timed(result: Result, formula, named: dict, timeout_ms: int) -> Result:
    t0 = time.perf_counter()
    result.status, model = refute(formula, timeout_ms)
    result.seconds = time.perf_counter() - t0
    if model is not None:
        result.model = {k: value(model, t) for k, t in named.items()}
    return result


# ------------------------------------------------------------------------------------ dI


def invariant_results(d: Declaration, timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    return [timed(Result(f"dI {inv.name}", "dI", inv.phase), invariant_obligation(inv), {}, timeout_ms)
            for inv in phase_invariants(d)]


# ---------------------------------------------------------------------------- sufficiency


class Lemmas:
    """The model's variables and the steps from the phases' dI bounds to "stops short", each a
    formula to refute, named after the phase it covers (the way a KeYmaera proof splits)."""

    def __init__(self, d: Declaration, service: bool, track: int, brake: int, curve_d: Optional[Declaration] = None,
                 remembered: bool = False, periods: int = CONTRACT_PERIODS):
        """`curve_d`: the declaration the curve is computed from (default `d`, the train's): a
        test plants a weaker one to see the proof fail. `remembered`: the closing speed is the
        memory's (the remembered own speed, at least the obstacle's, plus the train's least
        speed), not a measurement: the obstacle's own speed is anything up to it (release.py).
        `periods`: monitor periods in the reaction, the train's and the curve's (the supervision's
        CONTRACT_PERIODS; one for a zone limit, where the brake is demanded at the limit itself).
        The sensors err within the declared accuracy on a supervised curve (the error budget:
        the true distance D within `distance_accuracy` of the reported Dr, the true closing
        within `closing_accuracy` of the measured c) and measure exactly at a zone limit."""
        self.d, self.service, self.track, self.brake = d, service, track, brake
        v, v0, c, w0, age, grad, D, Dr = z3.Reals("v v0 c w0 age grad D D_reported")
        self.v, self.v0, self.c, self.w0, self.age, self.grad, self.D, self.Dr = v, v0, c, w0, age, grad, D, Dr
        zone = periods == CONTRACT_ZONE_PERIODS
        err_d, err_c = d.budget(not zone)                   # what the world's sensors may do
        self.x1, self.v1, self.x2, self.v2, self.xb, self.tb = z3.Reals("x1 v1 x2 v2 xb tb")
        self.brakes = d.brake(service)
        self.dec = [z3.Real(f"d{i}") for i in range(len(self.brakes))]
        e = q(d.speed_error)
        self.gg = q(G) * grad
        self.real = real_curves(curve_d or d, v, c, age, track, brake, service, periods, budget=not zone)
        self.domain = [0 <= v, v <= q(Fraction(MAX_SPEED_CMS, 100)), v * (1 - e) <= v0, v0 <= v * (1 + e),
                       0 <= age, age <= q(d.max_age), -q(MAX_UPHILL) <= grad, grad <= q(d.max_gradient),
                       Dr - q(err_d) <= D, D <= Dr + q(err_d),
                       -q(Fraction(MAX_CLOSING_CMS, 100)) <= c,
                       c <= q(Fraction(MAX_TRACK_CLOSING_CMS, 100))]
        self.domain += ([w0 <= c + q(err_c) - v * (1 - e)] if remembered else
                        [c - q(err_c) <= v0 + w0, v0 + w0 <= c + q(err_c)])
        self.domain += [di >= q(a * d.factor(track, brake)) for di, (_, a) in zip(self.dec, self.brakes)]
        self.t1 = age + q(periods * d.period + d.traction_cutoff)
        self.t2 = q(max(Fraction(0), d.buildup(service) - d.traction_cutoff))
        # the dI bounds of each phase at the true start values (model.phase_invariants)
        a1, a2 = pos(q(d.max_accel) + self.gg), pos(self.gg)
        self.reaction = [self.x1 <= v0 * self.t1 + a1 * self.t1 * self.t1 / 2, 0 <= self.v1,
                         self.v1 <= v0 + a1 * self.t1]
        self.buildup = [self.x2 <= self.v1 * self.t2 + a2 * self.t2 * self.t2 / 2, 0 <= self.v2,
                        self.v2 <= self.v1 + a2 * self.t2]
        self.band_x = [z3.Real(f"xb{i}") for i in range(len(self.brakes))]
        self.band_t = [z3.Real(f"tb{i}") for i in range(len(self.brakes))]
        self.braking = [self.xb == z3.Sum(self.band_x), self.tb == z3.Sum(self.band_t)]
        for i, ((lo, _), di) in enumerate(zip(self.brakes, self.dec)):
            net = di - self.gg
            top, inside = band_top(self.brakes, i, self.v2), self.v2 > q(lo)
            # the band's dI bounds, entered at top and left at lo, multiplied out (net > 0)
            self.braking += [z3.If(inside, z3.And(2 * net * self.band_x[i] <= top * top - q(lo) * q(lo),
                                                  net * self.band_t[i] <= top - q(lo), self.band_x[i] >= 0,
                                                  self.band_t[i] >= 0),
                                   z3.And(self.band_x[i] == 0, self.band_t[i] == 0))]
        self.closed = pos(w0) * (self.t1 + self.t2 + self.tb)
        # each band's distance and time at the declared deceleration (worst gradient), from the true v2
        gg_max = q(G * d.max_gradient)
        self.declared_net = [q(a * d.factor(track, brake)) - gg_max for _, a in self.brakes]
        terms = band_terms(self.brakes, self.declared_net, self.v2)
        self.bound_x, self.bound_t = [x for x, _ in terms], [t for _, t in terms]

    def ends_short_of(self, keep, kind: Optional[str] = None):
        """The whole chain as one formula to refute: the phases' dI bounds, the braking within
        the declared deceleration's bound, D >= EBI, and the train ending less than `keep` m
        short (a direct check beside the named steps, for a curve that may be weaker)."""
        s_decl, t_decl = self.declared()
        gap = self.D - self.x1 - self.x2 - self.xb - self.closed
        return z3.And(*self.domain, *(self.kind(kind) if kind else []), *self.reaction, *self.buildup,
                      self.xb <= s_decl, 0 <= self.tb, self.tb <= t_decl, self.Dr >= self.real.ebi, gap < q(keep))

    def theorem(self, kind: str):
        """The steps glued by one formula (issue 40 item 5): the phases' dI bounds, each step's
        conclusion (reaction and build-up within phases 1 and 2, braking within phase 3, the
        obstacle's travel within the curve's, each proved on its own above) and D >= EBI,
        against the train ending less than `standstill_margin` short. Refuted if the steps do
        not compose; the conclusions make the solver's way linear."""
        p = self.real.phases
        steps = [self.x1 <= p["s1"], self.v1 <= p["v1"], self.x2 <= p["s2"], self.v2 <= p["v2"], self.xb <= p["s3"],
                 self.tb <= p["t3"], self.closed <= p["w"] * (p["t1"] + p["t2"] + p["t3"])]
        return z3.And(self.ends_short_of(self.d.margin, kind), *steps)

    def sum_step(self) -> object:
        """The bands' bounds add up (linear): each band within its bound b_i (the band steps),
        the bounds' sum within the curve's phase 3 (the monotone step) => the whole braking
        within phase 3. The b_i stand for the bounds' terms, so the step is plain linear arithmetic."""
        p = self.real.phases
        n = len(self.brakes)
        bx, bt = [z3.Real(f"bx{i}") for i in range(n)], [z3.Real(f"bt{i}") for i in range(n)]
        s3, t3 = z3.Reals("S3 T3")
        return z3.And(self.xb == z3.Sum(self.band_x), self.tb == z3.Sum(self.band_t),
                      *(x <= b for x, b in zip(self.band_x, bx)), *(t <= b for t, b in zip(self.band_t, bt)),
                      z3.Sum(bx) <= s3, z3.Sum(bt) <= t3, z3.Or(self.xb > s3, self.tb > t3))

    def named(self) -> dict:
        out = {"measured_speed": self.v, "true_speed": self.v0, "closing_speed": self.c, "obstacle_speed": self.w0,
               "report_age": self.age, "gradient": self.grad, "distance": self.D, "reported_distance": self.Dr,
               "curve_ebi": self.real.ebi,
               "reaction_travel": self.x1, "buildup_travel": self.x2, "braking_travel": self.xb,
               "braking_time": self.tb, "speed_after_reaction": self.v1, "speed_at_braking": self.v2}
        out.update({f"decel{i}": di for i, di in enumerate(self.dec)})
        return out

    def kind(self, kind: str) -> list:
        if kind == "remembered":                   # any own speed up to the remembered one
            return []
        return [self.w0 == 0] if kind == "static" else [self.w0 < 0] if kind == "receding" else [self.w0 > 0]

    def declared(self) -> tuple:
        """(distance, time) to brake from v2 at the declared decelerations (worst gradient)."""
        return z3.Sum(self.bound_x), z3.Sum(self.bound_t)

    def steps(self) -> list[tuple[str, str, object]]:
        """(name, phase, formula to refute) of the steps that do not depend on the obstacle."""
        p = self.real.phases
        net_ok = [di - self.gg > 0 for di in self.dec]
        base = self.domain
        s_decl, t_decl = self.declared()
        u = z3.Real("u")
        out = [
            ("reaction: travel and speed within the curve's phase 1", "reaction",
             z3.And(*base, *self.reaction, z3.Or(self.x1 > p["s1"], self.v1 > p["v1"]))),
            ("build-up: travel and speed within the curve's phase 2", "build-up",
             z3.And(*base, *self.reaction, *self.buildup, self.v1 <= p["v1"],
                    z3.Or(self.x2 > p["s2"], self.v2 > p["v2"]))),
            ("braking: the declared deceleration is positive under the worst gradient", "braking",
             z3.And(*base, z3.Not(z3.And(*net_ok))))]
        for i, (lo, _) in enumerate(self.brakes):
            out.append((f"braking: band {i + 1} from {float(lo):g} m/s, distance and time within the declared "
                        "deceleration's", "braking",
                        z3.And(*base, *net_ok, self.v2 >= 0, *self.braking,
                               z3.Or(self.band_x[i] > self.bound_x[i], self.band_t[i] > self.bound_t[i]))))
        s_u, t_u = band_sums(self.brakes, self.declared_net, u)
        out.append(("braking: the declared bands' distance and time grow with the speed (up to the curve's v2)",
                    "braking", z3.And(*base, 0 <= self.v2, self.v2 <= u, z3.Or(s_decl > s_u, t_decl > t_u))))
        out.append(("braking: the bands add up to within the curve's phase 3", "braking", self.sum_step()))
        return out

    def kind_steps(self, kind: str) -> list[tuple[str, str, object]]:
        """(name, phase, formula to refute) of the steps that do: the obstacle's travel, the sum."""
        p = self.real.phases
        base = self.domain + self.kind(kind)
        return [
            (f"obstacle ({kind}): its travel until the train stands within the curve's", "obstacle",
             z3.And(*base, 0 <= self.tb, self.tb <= p["t3"], self.closed > p["w"] * (p["t1"] + p["t2"] + p["t3"]))),
            (f"stops short ({kind}): the reported distance >= EBI, the sensors' error and the phases' bounds leave "
             "the margin", "composition",
             z3.And(*base, self.x1 <= p["s1"], self.x2 <= p["s2"], self.xb <= p["s3"],
                    self.closed <= p["w"] * (p["t1"] + p["t2"] + p["t3"]), self.Dr >= self.real.ebi,
                    self.D - self.x1 - self.x2 - self.xb - self.closed < q(self.d.margin))),
        ]


def sufficiency_results(d: Declaration, timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    """Per brake (emergency at EBI, service at alpha1) and reported condition: every step from
    the phases' bounds to "stops standstill_margin short", the last two per obstacle kind. The
    braking steps chain: each band's dI bound within the declared deceleration's at the true
    speed v2, that within the curve's at its v2 (monotone), and the sum (linear, in the last step)."""
    out = []
    for service in (False, True):
        # the service brake at alpha1 is a zone limit of the table (braking.ebi_dm): where the
        # brake must be commanded, so the claim is for a demand at the limit itself
        curve = "alpha1 (service, a zone limit: demanded at it)" if service else "EBI (emergency)"
        for track, brake, cond in SERVICE_CONDITIONS if service else CONDITIONS:
            lemmas = Lemmas(d, service, track, brake, periods=CONTRACT_ZONE_PERIODS if service else CONTRACT_PERIODS)
            steps = [(s, None) for s in lemmas.steps()] + [(s, k) for k in KINDS for s in lemmas.kind_steps(k)]
            # the theorem (issue 40 item 5): the steps glued by one formula Z3 checks, from the
            # phases' dI bounds and the bands' bound to "stops standstill_margin short"
            steps += [(("theorem: the whole chain in one formula, from the phases' bounds to stopping "
                        f"standstill_margin short ({kind})", "composition", lemmas.theorem(kind)), kind)
                      for kind in KINDS]
            for (name, phase, formula), kind in steps:
                r = Result(f"{curve}, {cond}: {name}", "sufficiency", phase,
                           context={"service": service, "kind": kind, "track": track, "brake": brake})
                out.append(timed(r, formula, lemmas.named(), timeout_ms))
    return out


# -------------------------------------------------------------------------------- integer


@lru_cache(maxsize=1)
def chain_holds() -> bool:
    """The linear step behind a chained curve, proved once over fresh reals: with R, P the
    integer curve and the one before it, r, p the real ones and `reach` the farthest distance,
    R - P >= r - p, (P >= p or P >= reach) and r >= p give R >= r or R >= reach."""
    R, P, r, p, reach = z3.Reals("R P r p reach")
    return refute(z3.And(R - P >= r - p, z3.Or(P >= p, P >= reach), r >= p, R < r, R < reach))[0] == "proved"


def c_code(core_dir=None) -> SimpleNamespace:
    """The C core's curves (rg_core.c's rg_curves, run symbolically by c_symbolic) in the
    place of braking.py's: `curves` with RG_SUPERVISED_PERIODS, `ebi_dm` with RG_ZONE_PERIODS."""
    from . import c_symbolic

    prog = c_symbolic.program(core_dir or c_symbolic.CORE_DIR)      # preprocessed and parsed once
    return SimpleNamespace(curves=c_symbolic.curves(prog), ebi_dm=c_symbolic.ebi_dm(prog), LABEL="C ",
                           WHERE="rg_core.c rg_curves")


def integer_results(cfg: Config, d: Declaration, braking, timeout_ms: int = TIMEOUT_MS,
                    progress: Callable[[str], None] = lambda _: None, first_failure: bool = False) -> list[Result]:
    """The shipped integer curves (`braking.curves`, run symbolically; or the C's, `c_code()`)
    against the real ones. `first_failure`: stop after the first brake and condition with a
    curve not proved (a planted weakening needs one; the emergency curves under normal
    conditions come first, the replay's target)."""
    lang, source = getattr(braking, "LABEL", ""), getattr(braking, "WHERE", "braking")
    s, c, a = z3.Reals("speed_cms closing_cms age_ms")
    domain = [0 <= s, s <= MAX_SPEED_CMS, -MAX_CLOSING_CMS <= c, c <= MAX_TRACK_CLOSING_CMS,
              0 <= a, a <= cfg.timeout_cycles * cfg.period_ms]
    out = []
    reach = q(Fraction(MAX_DISTANCE_DM, 10))
    for service in (False, True):
        for track, brake, cond in SERVICE_CONDITIONS if service else CONDITIONS:
            t0 = time.perf_counter()
            # the emergency curves the supervision uses (braking.curves), and alpha1, the table's
            # service zone limit, as the core computes it (braking.ebi_dm, service=True)
            fn = braking.ebi_dm if service else braking.curves
            paths = symbolic.explore(fn, {"cfg": cfg, "speed_cms": s, "track": track, "brake": brake,
                                          "closing_cms": c, "age_ms": a, "service": service}, domain,
                                     timeout_ms=EXPLORE_TIMEOUT_MS)
            explored = time.perf_counter() - t0
            # what the physics needs, on the monitor's timing contract (model.CONTRACT_*): the
            # code's own constants are only inside `fn`
            real = real_curves(d, s / 100, c / 100, a / 1000, track, brake, service,
                               CONTRACT_ZONE_PERIODS if service else CONTRACT_PERIODS, budget=not service)
            names = ("ebi",) if service else CURVES
            proved_facts = [[] for _ in paths]       # per path: curves already proved there (sound hypotheses)
            proved_on = {name: set() for name in names}
            for name in names:
                before = None if service else STEPS_FROM.get(name)
                # the real curves grow in this order (each adds a lead's run)
                grew = before is not None and refute(z3.And(*domain, getattr(real, name) < getattr(real, before)),
                                                     timeout_ms)[0] == "proved"
                label = "alpha1" if service else name.upper()
                where = (f"{source}.ebi_dm(service=True)" if service and not lang else
                         f"{source}(service=1, RG_ZONE_PERIODS).ebi_dm" if service else
                         f"{source}.curves().{name}_dm" if not lang else
                         f"{source}(service=0, RG_SUPERVISED_PERIODS).{name}_dm")
                r = Result(f"integer {lang}{label} >= real, {cond} ({len(paths)} paths of {fn.__name__})", "integer",
                           where, context={"curve": name, "service": service, "track": track, "brake": brake,
                                           "code": "C" if lang else "Python"})
                t1 = time.perf_counter()
                status, model = "proved", None
                for i, p in enumerate(paths):
                    rounded = (p.value if service else getattr(p.value, f"{name}_dm")) / 10
                    # shorter than the real curve, where that matters: below the farthest distance the
                    # core ever compares a curve with (a voted or remembered obstacle is never farther)
                    chained = False
                    if before is not None and grew and i in proved_on[before]:
                        # a lemma: this curve exceeds the one before it (EBI for SBI, SBI for the
                        # warning) by at least the real curves' difference. With the one before
                        # proved on this path and the real curves growing, the curve follows by
                        # linear arithmetic alone (chain_holds, checked once), which nlsat finds slowly
                        prev = getattr(p.value, f"{before}_dm") / 10
                        gap = rounded - prev < getattr(real, name) - getattr(real, before)
                        chained = chain_holds() and refute(z3.And(*domain, *p.condition, *p.side, gap),
                                                           timeout_ms)[0] == "proved"
                    st, m = ("proved", None) if chained else refute(
                        z3.And(*domain, *p.condition, *p.side, *proved_facts[i], rounded < getattr(real, name),
                               rounded < reach), timeout_ms)
                    if st == "proved":
                        proved_facts[i].append(z3.Or(rounded >= getattr(real, name), rounded >= reach))
                        proved_on[name].add(i)
                    if st != "proved":
                        status, model = st, m
                        if model is not None:
                            r.model = {"speed": value(model, s) / 100, "closing_speed": value(model, c) / 100,
                                       "report_age": value(model, a) / 1000, "integer_m": value(model, rounded),
                                       "real_m": value(model, getattr(real, name))}
                        break
                r.status = status
                r.seconds = time.perf_counter() - t1 + explored / len(names)
                out.append(r)
            progress(f"physics: integer curves ({'C' if lang else 'Python'}), {'service' if service else 'emergency'}, {cond}: "
                     f"{len(paths)} paths, {time.perf_counter() - t0:.1f} s")
            if first_failure and not all(r.proved for r in out):
                return out
    return out


def check_all(cfg: Config, braking, timeout_ms: int = TIMEOUT_MS,
              progress: Callable[[str], None] = lambda _: None, core_dir=None, whole: bool = True) -> list[Result]:
    """Every obligation: the phases and the build-up equivalence, sufficiency, the release
    rule, the whole cycle (`whole`: Python and C), and the integer curves of braking.py (`braking`) and of the C core
    (`core_dir`, default the shipped one)."""
    d = Declaration.of(cfg)
    out = invariant_results(d, timeout_ms)
    progress(f"physics: {len(out)} differential invariants")
    suff = sufficiency_results(d, timeout_ms)
    progress(f"physics: {len(suff)} sufficiency obligations")
    from .release import release_results

    rel = release_results(cfg, d, timeout_ms)
    progress(f"physics: the release rule over one cycle: {sum(r.proved for r in rel)} of {len(rel)} proved")
    from .buildup import buildup_results
    from .whole_cycle import whole_cycle_results

    build = buildup_results(d)
    progress(f"physics: the build-up equivalence: {sum(r.proved for r in build)} of {len(build)} proved")
    cycle = whole_cycle_results(cfg, c_core=core_dir, timeout_ms=timeout_ms) if whole else []
    progress(f"physics: the whole cycle (Python and C): {sum(r.proved for r in cycle)} of {len(cycle)} proved")
    return (out + build + suff + rel + cycle + integer_results(cfg, d, braking, timeout_ms, progress)
            + integer_results(cfg, d, c_code(core_dir), timeout_ms, progress))
