"""The world's train as a hybrid model, and the real-valued braking curves (issue 30 items 1, 2).

The model is what the proofs speak about. A train on a line, an obstacle ahead; time starts
when the obstacle's distance `D` was measured (the report's age before the monitor's cycle).
Each phase is a differential equation with bounded inputs, as in the train FMU
(fmu/c/train/model.c) and its Python twin (verification/world_train.py):

1. **reaction**, for `t1 = age + CONTRACT_PERIODS x period + traction_cutoff` (the report's
   age; the monitor's timing contract below; traction until it is cut): x' = v, v' = acc with
   acc <= max_accel + g grad (full traction and the downhill pull) and v >= 0;
2. **build-up**, for `t2 = max(0, buildup - traction_cutoff)` (the declared *equivalent*
   build-up: dead time plus half the ramp, which covers a linear ramp; docs/supervision.md 2.4):
   acc <= g grad (coasting downhill);
3. **braking** to standstill: in speed band i, acc <= -(d_i - g grad), where d_i is the train's
   real deceleration there, at or above the declared one times the adhesion factors the train
   reports;
4. **the obstacle** closes at its own constant speed w0 (static: 0; receding: < 0, and it may
   stop at once; oncoming: > 0) until the train stands.

Every declared bound is a variable inside its bound, not a constant: the true speed anywhere
within the speed error of the measured one (v (1 - e) <= v0 <= v (1 + e)), the true distance
and closing speed anywhere within the sensors' declared accuracy of the reported ones (the
error budget: |D - D_reported| <= distance_accuracy, |v0 + w0 - c| <= closing_accuracy), any gradient from
60 per mille uphill down to the steepest downhill, any deceleration at or above the guaranteed
one, any report age up to `timeout_cycles x period`, any closing speed the core accepts. What
the model assumes (and the proofs with it) is listed in `ASSUMPTIONS`.

The phases' bounds are proved as differential invariants (dI, as KeYmaera X would): the
invariant holds at the phase's start and its Lie derivative along the dynamics has the right
sign under the phase's constraints; the derivative itself is checked by Z3, not written by hand.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import z3

from monitor.core.config import Config, emergency_bands
from monitor.core.types import MAX_CLOSING_CMS, MAX_SPEED_CMS

G = Fraction(981, 100)                   # m/s^2, as gradient_accel_mms2 uses it (rounded up there)
MAX_UPHILL = Fraction(60, 1000)          # the model's gradient ranges from this uphill ...
MAX_TRACK_CLOSING_CMS = 2 * MAX_CLOSING_CMS + MAX_SPEED_CMS   # a remembered obstacle's closing: its own speed + ours

# The monitor's timing contract, stated here and never read from the code it judges (issue 40
# item 1: a reference that imported braking.SUPERVISED_PERIODS shrank with it, and a curve that
# forgot the sampling period proved). Between the last cycle that found the train outside a
# supervised curve and the brakes, the world may let pass, at worst:
# - running: the sampling period (the first cycle inside may come one period later) and the
#   demand's way to the brakes (one period): 2 periods;
# - stalled (item 3: a monitor that hangs, crashes or overruns after that cycle): that cycle's
#   BrakeDemand on its way (one period: a late cycle sends none below emergency,
#   can_bus/runner.py) and the brakes' receiver timeout, which brakes once the newest frame is
#   RECEIVER_TIMEOUT_PERIODS old (can_bus/brake_receiver.py, the train FMU's brake_timeout):
#   1 + 3 = 4 periods, the worse of the two, whatever `max_overruns` lets pass.
# A zone limit is demanded at the limit itself, so only the demand's period; the supervised
# curves are the floor that carries the stall. The code's own constants (braking.SUPERVISED_
# PERIODS, ZONE_PERIODS; RG_SUPERVISED_PERIODS, RG_ZONE_PERIODS) stay on the code's side of
# every obligation.
RECEIVER_TIMEOUT_PERIODS = 3  # the brakes' receiver: the newest BrakeDemand counts for less than this
CONTRACT_PERIODS = max(2, 1 + RECEIVER_TIMEOUT_PERIODS)    # running: sampling + way; stalled: way + timeout
CONTRACT_ZONE_PERIODS = 1     # the demand's way to the brakes

ASSUMPTIONS = (
    "the reported distance is within `distance_accuracy` of the true distance when the report was measured, and "
    "the measured closing speed within `closing_accuracy` of the train's true speed plus the obstacle's own speed "
    "towards it (the sensors' declared accuracy: the error budget; a zone limit is proved for exact sensors, the "
    "supervised curves for every error inside the budget)",
    "an obstacle keeps a constant speed after the last reading (a receding one may stop at once; an oncoming one "
    "does not speed up); the figure that breaks it (`rolling_limit`): a static obstacle that starts rolling towards "
    "the train at 2 margin / t^2, t the stop time, uses the margin up (papers' train: 0.24 m/s^2 at 10 m/s, "
    "0.023 m/s^2 at 40 m/s; a vehicle rolling free on the line's 20 per mille gains up to 0.196 m/s^2)",
    "a demand reaches the brakes within one monitor period (`period_ms`), as measured on CAN",
    "during a report's age the train ran no faster than the speed error allows around the speed the cycle "
    "measures, accelerating at most at traction plus the steepest downhill (the age is at most "
    "`timeout_cycles x period`)",
    "the brakes apply emergency at most `RECEIVER_TIMEOUT_PERIODS` (3) periods after the newest valid BrakeDemand, "
    "and a cycle whose frames would leave late sends none below emergency: a monitor that stalls, crashes or "
    "overruns brakes the train at most 4 periods after its last cycle outside EBI (`CONTRACT_PERIODS`)",
    "while the monitor runs, a remembered obstacle is moved once per period, at the speed that cycle measured",
    "the train's equivalent build-up (dead time + half a linear ramp) is at most the declared one",
    "in each speed band the brake decelerates at least as declared, times the adhesion factors the train reports",
    "the gradient is at most `max_downhill_gradient` downhill, and traction at most `max_accel`",
)


def q(x) -> z3.ArithRef:
    """An exact rational as a Z3 real."""
    f = Fraction(x)
    return z3.RealVal(f"{f.numerator}/{f.denominator}")


@dataclass(frozen=True)
class Declaration:
    """A Config's braking declaration in SI units, exact (the integers the core runs on)."""

    bands: tuple                   # ((from m/s, decel m/s^2), ...), emergency
    service_decel: Fraction
    emergency_buildup: Fraction    # s
    service_buildup: Fraction
    traction_cutoff: Fraction
    max_accel: Fraction
    speed_error: Fraction
    slippery: Fraction
    degraded: Fraction
    max_gradient: Fraction         # downhill, as a fraction (20 per mille: 1/50)
    margin: Fraction               # m
    period: Fraction
    warning: Fraction
    max_age: Fraction              # s: timeout_cycles x period
    distance_accuracy: Fraction    # m: a reported distance is within this of the true one (the error budget)
    closing_accuracy: Fraction     # m/s: a measured closing speed is within this of the true one

    @classmethod
    def of(cls, cfg: Config) -> "Declaration":
        ms = lambda v: Fraction(v, 1000)  # noqa: E731
        return cls(tuple((Fraction(lo, 100), ms(a)) for lo, a in emergency_bands(cfg)), ms(cfg.service_decel_mms2),
                   ms(cfg.emergency_buildup_ms), ms(cfg.service_buildup_ms), ms(cfg.traction_cutoff_ms),
                   ms(cfg.max_accel_mms2), ms(cfg.speed_error_permille), ms(cfg.slippery_permille),
                   ms(cfg.degraded_permille), ms(cfg.max_gradient_permille), Fraction(cfg.standstill_margin_dm, 10),
                   ms(cfg.period_ms), ms(cfg.warning_ms), ms(cfg.timeout_cycles * cfg.period_ms),
                   Fraction(cfg.distance_accuracy_dm, 10), Fraction(cfg.closing_accuracy_cms, 100))

    def brake(self, service: bool) -> tuple:
        """((from m/s, declared decel), ...) of the emergency or the service brake."""
        return ((Fraction(0), self.service_decel),) if service else self.bands

    def factor(self, track: int, brake: int) -> Fraction:
        return (self.slippery if track else 1) * (self.degraded if brake else 1)

    def buildup(self, service: bool) -> Fraction:
        return self.service_buildup if service else self.emergency_buildup

    def budget(self, counted: bool) -> tuple:
        """(distance m, closing m/s) of the sensors' error a curve counts: the declared accuracy
        for a supervised curve, none for a zone limit (proved for exact sensors)."""
        return (self.distance_accuracy, self.closing_accuracy) if counted else (Fraction(0), Fraction(0))


def pos(x):
    return z3.If(x > 0, x, 0)


def band_top(bands: tuple, i: int, u):
    """The speed at which braking from u enters band i (u, or the band's upper end)."""
    return u if i + 1 == len(bands) else z3.If(u < q(bands[i + 1][0]), u, q(bands[i + 1][0]))


def band_terms(bands: tuple, decels: list, u) -> list:
    """[(distance, time), ...] braking from speed u spends in each band [lo, hi) when band i
    decelerates at decels[i]: (top^2 - lo^2) / 2 d and (top - lo) / d, 0 above u."""
    out = []
    for i, (lo, _) in enumerate(bands):
        top, inside = band_top(bands, i, u), u > q(lo)
        out.append((z3.If(inside, (top * top - q(lo) * q(lo)) / (2 * decels[i]), 0),
                    z3.If(inside, (top - q(lo)) / decels[i], 0)))
    return out


def band_sums(bands: tuple, decels: list, u) -> tuple:
    """(distance, time) to brake from speed u to standstill (the sums of band_terms)."""
    terms = band_terms(bands, decels, u)
    return z3.Sum([x for x, _ in terms]), z3.Sum([t for _, t in terms])


@dataclass
class RealCurves:
    ebd: z3.ArithRef
    ebi: z3.ArithRef
    sbi: z3.ArithRef
    warning: z3.ArithRef
    phases: dict                 # the pieces of EBI: t1 s1 v1 t2 s2 v2 s3 t3 w (m, s, m/s)


def real_curves(d: Declaration, v, c, age, track: int, brake: int, service: bool = False,
                periods: int = CONTRACT_PERIODS, budget: bool = True) -> RealCurves:
    """The curves of docs/supervision.md section 2 in exact real arithmetic, in m, at measured
    speed v (m/s), closing speed c (m/s) and report age (s): the yardstick for the integer code.
    `periods` in the reaction: the supervision's (CONTRACT_PERIODS) or a zone limit's one
    (CONTRACT_ZONE_PERIODS): the monitor's timing contract, not the code's constants. `budget`:
    the sensors' error counted (the obstacle up to `distance_accuracy` nearer than reported, and
    closing up to `closing_accuracy` faster than measured); a zone limit counts none."""
    gg = q(G * d.max_gradient)
    e = q(d.speed_error)
    near, faster = d.budget(budget)
    v_max, v_min = v * (1 + e), v * (1 - e)
    w = pos(c + q(faster) - v_min)
    decels = [q(a * d.factor(track, brake)) - gg for _, a in d.brake(service)]
    bands = d.brake(service)
    t1 = age + q(periods * d.period + d.traction_cutoff)
    a1 = q(d.max_accel) + gg
    s1, v1 = v_max * t1 + a1 * t1 * t1 / 2, v_max + a1 * t1
    t2 = q(max(Fraction(0), d.buildup(service) - d.traction_cutoff))
    s2, v2 = v1 * t2 + gg * t2 * t2 / 2, v1 + gg * t2
    s3, t3 = band_sums(bands, decels, v2)
    ebi = s1 + s2 + s3 + q(d.margin) + q(near) + w * (t1 + t2 + t3)
    ebd_s, ebd_t = band_sums(bands, decels, v)
    ebd = ebd_s + q(d.margin) + q(near) + w * ebd_t
    lead = v_max + w
    sbi = ebi + lead * q(d.service_buildup)
    return RealCurves(ebd, ebi, sbi, sbi + lead * q(d.warning),
                      {"t1": t1, "s1": s1, "v1": v1, "t2": t2, "s2": s2, "v2": v2, "s3": s3, "t3": t3, "w": w})


# ---------------------------------------------------------------------------------------------
# The hybrid model: differential invariants of the phases


@dataclass
class Invariant:
    """p >= 0 along x' = v, v' = acc, t' = 1 while `constraint` holds, from a start where p >= 0."""
    name: str
    phase: str
    p: z3.ArithRef
    constraint: list
    start: list              # the state at the phase's start (makes p >= 0 hold there)


X, V, T, ACC = z3.Reals("x v t acc")


def lie_derivative(p) -> tuple:
    """The Lie derivative of a polynomial p(x, v, t) of degree <= 2 along (v, acc, 1), found by
    Z3 from p(z + h f) = p(z) + h p' + h^2 r: p' = 2 (p(z + f) - p(z)) - (p(z + 2f) - p(z)) / 2;
    with the third difference, which is 0 exactly when p(z + h f) has degree <= 2 in h."""
    def shift(h):
        return z3.substitute(p, (X, X + h * V), (V, V + h * ACC), (T, T + h))
    p1, p2, p3 = shift(1), shift(2), shift(3)
    return 2 * (p1 - p) - (p2 - p) / 2, p3 - 3 * p2 + 3 * p1 - p


def phase_invariants(d: Declaration) -> list[Invariant]:
    """The bounds each phase needs, for symbolic start values (x0 = 0, v0, t0 = 0)."""
    v0, a, dd, u, lo = z3.Reals("v0 a d u lo")
    out = []
    # reaction and build-up: acc <= a (a = max_accel + g grad, or g grad), a may be negative uphill:
    # the bounds use a+ = max(a, 0), since a standing train does not roll back
    ap = pos(a)
    for phase, what in (("reaction", "traction and downhill"), ("build-up", "coasting downhill")):
        cons = [ACC <= ap, V >= 0]
        out.append(Invariant(f"{phase}: speed <= v0 + a+ t", phase, v0 + ap * T - V, cons,
                             [X == 0, V == v0, T == 0]))
        # a differential cut: the speed bound just proved (on the same flow and domain) bounds the travel
        out.append(Invariant(f"{phase}: travel <= v0 t + a+ t^2/2 ({what}; the speed bound cut in)", phase,
                             v0 * T + ap * T * T / 2 - X, cons + [V <= v0 + ap * T], [X == 0, V == v0, T == 0]))
    # braking within one band: acc <= -d (d > 0) while lo < v <= u
    cons = [ACC <= -dd, dd > 0, V >= lo, lo >= 0]
    out.append(Invariant("braking: v^2 + 2 d x <= u^2 in a band decelerating at d", "braking",
                         u * u - V * V - 2 * dd * X, cons, [X == 0, V == u, T == 0]))
    out.append(Invariant("braking: v + d t <= u in a band decelerating at d", "braking",
                         u - V - dd * T, cons, [X == 0, V == u, T == 0]))
    return out


def circular(inv: Invariant) -> bool:
    """The constraint already says p >= 0 (the invariant's own bound in its evolution domain):
    dI would then prove anything, a false -t^2 >= 0 included. Z3 decides it: the constraint
    leaves no state with p < 0. (A bound proved before on the same flow may be cut in.)"""
    s = z3.Solver()
    s.set("timeout", 10000)
    s.add(*inv.constraint, inv.p < 0)
    return s.check() == z3.unsat


def invariant_obligation(inv: Invariant):
    """The dI proof obligation as one formula to refute: p >= 0 at the start, p' >= 0 under the
    constraint, and p of degree <= 2 along the flow (so that p' is its derivative); a circular
    constraint (`circular`) is refused: the formula is then satisfiable, never proved."""
    if circular(inv):
        return z3.BoolVal(True)
    deriv, third = lie_derivative(inv.p)
    start = z3.substitute(inv.p, *[(c.arg(0), c.arg(1)) for c in inv.start])
    # refute: start value negative, or derivative negative where the constraint holds
    return z3.Or(start < 0, z3.And(*inv.constraint, deriv < 0), third != 0)


def rolling_limit(d: Declaration, speed: Fraction) -> tuple[Fraction, Fraction]:
    """(stop time s, obstacle acceleration m/s^2): the figure that breaks the assumption that an
    obstacle keeps its speed (issue 40 item 3). A static obstacle that starts rolling towards
    the train at `a` just after the last reading closes `a t^2 / 2` more than the curves count
    over the stop time t (t1 + t2 + t3 of the real EBI at measured `speed` m/s, a fresh report,
    normal conditions); at the declaration's and the error budget's corner, where the train
    stops exactly `standstill_margin` short, that uses the margin up at a = 2 margin / t^2."""
    v = z3.RealVal(f"{speed.numerator}/{speed.denominator}")
    p = real_curves(d, v, v, z3.RealVal(0), 0, 0).phases
    t = z3.simplify(p["t1"] + p["t2"] + p["t3"])
    stop = Fraction(t.as_fraction()) if z3.is_rational_value(t) else Fraction(str(t.as_decimal(12)).rstrip("?"))
    return stop, 2 * d.margin / (stop * stop)
