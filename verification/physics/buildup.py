"""The equivalent build-up proved (issue 40 item 4): a brake with a dead time and a linear ramp
stops the train no farther and no later than the equivalent build-up the curves count.

**The claim.** Time s from the demand at the brakes; the worst gradient, gg = g max_gradient >= 0;
D_i = band i's declared deceleration x the reported adhesion factors (the model's `decels` + gg).
**Real** brake: effort r(s) = 0 before td, (s - td)/tr on the ramp, 1 after; in the band i of its
own speed v, acc <= drift - r(s) D_i. **Equivalent** (the curves' phases: traction until the
cut-off, coasting until Te = max(T, traction_cutoff), then the bands), at its bound:
acc_eq = drift - [s >= Te] D_k in its band k. drift = gg + traction, the same for both: at most
gg + max_accel before Te, gg after (Te >= the cut-off). For every td, tr >= 0 with
td + tr/2 <= T (the declared equivalent build-up; emergency and service), from x = x_eq = 0 and
any v < v_eq: until the real train stands, v < v_eq; so it stands first, and x <= x_eq always.
With v_eq -> v (the equivalent's stop is continuous in its start speed) the real train stands no
later and no farther than the equivalent, whose stop the sufficiency chain bounds (s2 + s3 after
phase 1's travel, within t1 + t2 + t3). A train braking harder than declared, on a gentler
gradient or pulling less meets the same bounds, so these constants cover every train.

**Why a ramp per band.** The effort (brake pressure) rises linearly and gives its fraction of the
band's full deceleration. A ramp towards the weakest band's deceleration looks conservative but is
false: in a stronger band the train then runs faster than the equivalent (refuted, `ramp="weakest"`).
The per-band ramp needs, wherever drift > 0, decelerations that do not rise with speed: a train
reaching a weaker lower band early loses its lead downhill or under traction (refuted; the shipped
and example declarations all fall with speed; the configuration check does not require it).

**The invariant** (both trains at the same time, dI as in model.py): tau(w) = time to stop from w
at the pure decelerations D (no drift), piecewise linear; F(s) = integral of r - [s >= Te] (the
real brake's lead in effort); p = tau(v_eq) - tau(v) - F. In bands j <= k, p' >= drift (1/D_k -
1/D_j) >= 0. p > 0 at the start; p > 0 and F >= 0 give v < v_eq, hence j <= k: p never reaches 0
while the real train moves (a standing one stays: its bound only falls). Z3 checks p' per segment
of time (dead, ramp and full brake, each before and after Te), the segments' coverage and F's
continuity, F >= 0 (where td + tr/2 <= T enters), the start, the order, and x <= x_eq. The Lie
derivative along (v, acc, v_eq, acc_eq, 1) is computed here as model.lie_derivative does.
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import z3

from . import obligations
from .model import G, Declaration, q

X, V, XE, VE, S = z3.Reals("x v x_eq v_eq s")
ACC, ACC_E, DRIFT, TD, TR = z3.Reals("acc acc_eq drift td tr")
FLOW = ((X, V), (V, ACC), (XE, VE), (VE, ACC_E), (S, z3.RealVal(1)))
NAMED = {"dead_time": TD, "ramp": TR, "time": S, "speed": V, "equivalent_speed": VE, "drift": DRIFT,
         "acc": ACC, "acc_equivalent": ACC_E, "x": X, "x_equivalent": XE}
TIMEOUT_MS = 10000


def lie_derivative(p, flow=FLOW) -> tuple:
    """(p', third difference) of a polynomial p along `flow` ((state, derivative), ...), as
    model.lie_derivative: p(z + h f) = p + h p' + h^2 r exactly when the third difference is 0."""
    def shift(h):
        return z3.substitute(p, *[(var, var + h * f) for var, f in flow])
    p1, p2, p3 = shift(1), shift(2), shift(3)
    return 2 * (p1 - p) - (p2 - p) / 2, p3 - 3 * p2 + 3 * p1 - p


def di_fails(p, constraint: list):
    """The dI condition as a formula to refute: p' < 0 under the constraint, or p' not p's derivative."""
    deriv, third = lie_derivative(p)
    return z3.Or(z3.And(*constraint, deriv < 0), third != 0)


@dataclass(frozen=True)
class Segment:
    """A stretch of time where both brakes' efforts are polynomials: real acc <= drift - D r_num/r_den,
    the equivalent braking or not, F = f_num / f_den (dens 1 or tr > 0: p stays a polynomial)."""
    name: str
    when: tuple
    ramp: bool          # the real brake's effort still rising
    r_num: object
    r_den: object
    eq_brakes: bool
    f_num: object
    f_den: object


def segments(te) -> list[Segment]:
    """Dead time, ramp before / after Te, full brake before / after Te (closed, covering s >= 0)."""
    one, ramp_f = z3.RealVal(1), (S - TD) * (S - TD)
    end = TD + TR
    return [
        Segment("dead time", (0 <= S, S <= TD), False, z3.RealVal(0), one, False, z3.RealVal(0), one),
        Segment("ramp, the equivalent coasting", (TR > 0, TD <= S, S <= end, S <= te), True, S - TD, TR, False,
                ramp_f, 2 * TR),
        Segment("ramp, the equivalent braking", (TR > 0, te <= S, S <= end), True, S - TD, TR, True,
                ramp_f - 2 * TR * (S - te), 2 * TR),
        Segment("full brake, the equivalent coasting", (end <= S, S <= te), False, one, one, False,
                S - TD - TR / 2, one),
        Segment("full brake, both braking", (end <= S, te <= S), False, one, one, True, te - TD - TR / 2, one),
    ]


@dataclass
class Brake:
    """One brake under one reported condition: its bands' decelerations and the drift's range."""
    lows: list          # band starts, m/s
    decel: list         # D_i, m/s^2 (declared x factors; the gradient is in the drift)
    gg: Fraction
    accel: Fraction     # max traction before Te
    buildup: Fraction   # declared equivalent build-up T
    te: Fraction        # when the equivalent brakes: max(T, traction_cutoff)

    @classmethod
    def of(cls, d: Declaration, service: bool, track: int, brake: int) -> "Brake":
        bands = d.brake(service)
        return cls([lo for lo, _ in bands], [a * d.factor(track, brake) for _, a in bands], G * d.max_gradient,
                   d.max_accel, d.buildup(service), max(d.buildup(service), d.traction_cutoff))

    def band(self, i: int, w) -> list:
        top = [] if i + 1 == len(self.lows) else [w < q(self.lows[i + 1])]
        return [w >= q(self.lows[i]), *top]

    def tau(self, i: int, w):
        """Time to stop from w in band i at the pure brake decelerations: sum of the lower bands' plus this one's."""
        below = sum((self.lows[b + 1] - self.lows[b]) / self.decel[b] for b in range(i))
        return q(below) + (w - q(self.lows[i])) / q(self.decel[i])

    def pairs(self, ordered: bool = False) -> list[tuple[int, int]]:
        """(real's band, equivalent's band); ordered: the real's never above (where the dI must hold)."""
        n = len(self.lows)
        return [(j, k) for j in range(n) for k in range(n) if j <= k or not ordered]


def hypotheses(b: Brake, equivalent: Fraction) -> list:
    """Every dead time and ramp the declared equivalent build-up covers: td + equivalent tr <= T."""
    return [TD >= 0, TR >= 0, TD + q(equivalent) * TR <= q(b.buildup)]


def invariant(b: Brake, seg: Segment, j: int, k: int):
    """f_den (tau(v_eq) - tau(v) - F): the comparison, scaled by f_den > 0 to stay a polynomial."""
    return seg.f_den * (b.tau(k, VE) - b.tau(j, V)) - seg.f_num


def dynamics(b: Brake, seg: Segment, j: int, k: int, ramp: str) -> list:
    """Both trains' accelerations in bands j (real) and k (equivalent) during the segment."""
    gg = q(b.gg)
    drift = [DRIFT == gg] if seg.eq_brakes else [gg <= DRIFT, DRIFT <= gg + q(b.accel)]
    dj = q(min(b.decel)) if ramp == "weakest" and seg.ramp else q(b.decel[j])
    real = seg.r_den * ACC <= seg.r_den * DRIFT - dj * seg.r_num
    eq = ACC_E == (DRIFT - q(b.decel[k]) if seg.eq_brakes else DRIFT)
    return [*drift, real, eq]


def state(b: Brake, j: int, k: int) -> list:
    return [V >= 0, VE >= 0, *b.band(j, V), *b.band(k, VE)]


def segment_formula(b: Brake, seg: Segment, equivalent: Fraction, ramp: str):
    """dI of the comparison within the segment, in every ordered pair of bands (j <= k)."""
    hyp = hypotheses(b, equivalent)
    return z3.Or(*[di_fails(invariant(b, seg, j, k), [*hyp, *seg.when, *state(b, j, k), *dynamics(b, seg, j, k, ramp)])
                   for j, k in b.pairs(ordered=True)])


def start_formula(b: Brake, equivalent: Fraction):
    """At the demand (s = 0, dead time: F = 0) an equivalent started faster leads: p > 0."""
    seg = segments(q(b.te))[0]
    return z3.Or(*[z3.And(*hypotheses(b, equivalent), S == 0, V < VE, *state(b, j, k), invariant(b, seg, j, k) <= 0)
                   for j, k in b.pairs()])


def order_formula(b: Brake, equivalent: Fraction):
    """p > 0 and F >= 0 give v < v_eq in every pair of bands: the real train is behind, its band
    never above the equivalent's (the dI's pairs j <= k are the only ones), and it stands first;
    tau is continuous where the bands meet (so p is continuous when a train changes band)."""
    hyp = hypotheses(b, equivalent)
    seams = [b.tau(i, q(b.lows[i])) != b.tau(i - 1, q(b.lows[i])) for i in range(1, len(b.lows))]
    return z3.Or(*seams, *[z3.And(*hyp, *seg.when, *state(b, j, k), seg.f_num >= 0, invariant(b, seg, j, k) > 0,
                                  V >= VE) for seg in segments(q(b.te)) for j, k in b.pairs()])


def position_formula():
    """x <= x_eq from x = x_eq = 0: its derivative v_eq - v >= 0 once v < v_eq (the order)."""
    return z3.Or(z3.And(X == 0, XE == 0, XE - X < 0), di_fails(XE - X, [V < VE, V >= 0]))


def effort_formula(b: Brake, equivalent: Fraction):
    """F >= 0 at every time: the real brake has applied at least the equivalent's effort so far.
    This is where td + tr/2 <= T is used (a ramp counted at a quarter fails here)."""
    hyp = hypotheses(b, equivalent)
    return z3.Or(*[z3.And(*hyp, *seg.when, seg.f_num < 0) for seg in segments(q(b.te))])


def pieces_formula(b: Brake, equivalent: Fraction):
    """The segments cover every s >= 0, and F agrees where two meet (so p is continuous in time)."""
    hyp, segs = hypotheses(b, equivalent), segments(q(b.te))
    gap = z3.And(*hyp, S >= 0, *[z3.Not(z3.And(*seg.when)) for seg in segs])
    seams = [z3.And(*hyp, *a.when, *c.when, a.f_num * c.f_den != c.f_num * a.f_den)
             for i, a in enumerate(segs) for c in segs[i + 1:]]
    return z3.Or(gap, *seams)


def buildup_results(d: Declaration, timeout_ms: int = TIMEOUT_MS, equivalent: Fraction = Fraction(1, 2),
                    ramp: str = "band") -> list:
    """The build-up equivalence's obligations (kind dI, phase build-up) per brake and reported
    condition. `equivalent` (the ramp's share the declared T must cover) and `ramp` ("band": the
    effort's fraction of the band's deceleration; "weakest": of the weakest band's) let a test plant
    a wrong claim and see it refuted."""
    if ramp not in ("band", "weakest"):
        raise ValueError(f"ramp {ramp!r}: 'band' or 'weakest'")
    out = []
    for service in (False, True):
        which = "service" if service else "emergency"
        conditions = obligations.SERVICE_CONDITIONS if service else obligations.CONDITIONS
        base = Brake.of(d, service, 0, 0)
        for name, formula in (("td + tr/2 <= T: the real brake's effort so far is never below the equivalent's "
                               "(F >= 0)", effort_formula(base, equivalent)),
                              ("the time segments cover every instant and F is continuous across them",
                               pieces_formula(base, equivalent)),
                              ("dI x <= x_eq while v < v_eq: the real train stands no farther", position_formula())):
            r = obligations.Result(f"build-up ({which}): {name}", "dI", "build-up", context={"service": service})
            out.append(obligations.timed(r, formula, NAMED, timeout_ms))
        for track, brake, cond in conditions:
            b = Brake.of(d, service, track, brake)
            steps = [("p = tau(v_eq) - tau(v) - F > 0 at the demand (the equivalent started faster)",
                      start_formula(b, equivalent))]
            steps += [(f"dI p >= 0 in the {seg.name}", segment_formula(b, seg, equivalent, ramp))
                      for seg in segments(q(b.te))]
            steps += [("p > 0 and F >= 0 give v < v_eq (tau continuous): bands ordered, the real train stands first",
                       order_formula(b, equivalent))]
            for name, formula in steps:
                r = obligations.Result(f"build-up ({which}, {cond}): {name}", "dI", "build-up",
                                       context={"service": service, "track": track, "brake": brake})
                out.append(obligations.timed(r, formula, NAMED, timeout_ms))
    return out
