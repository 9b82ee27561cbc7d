"""What a policy costs in a seed world, counted per train so that every figure has a
confidence interval: braking without need, the part of it the policy alone asked for, stops,
and demand changes per encounter.

"Without need" is the world's to say (`PolicyCost.cycle`): no obstacle on the line (seed
000), or no obstacle above eq. 11's low risk (seed 001, where obstacles are on the line 75 %
of the time and mostly far). Every policy runs behind the same supervision (curves, memory,
fault handling), and where that supervision brakes alike for every policy (seed 001: the
memory keeps eq. 9's misperceived nearer distances) only `policy_braking` separates them:
the cycles without need in which the policy asked for braking and no supervision cause did.

Each figure is a ratio of sums over trains (X / Y); trains are independent, so its 95 %
interval comes from the linearised ratio estimator: SE = sqrt(n / (n - 1) sum (X_i - r Y_i)^2) / sum Y_i.

Two policies run on the same trains (the same seed: common random numbers) are compared
train by train (`paired`): the difference of their figures has the linearised per-train
differences e_i = (X_i - r Y_i) / mean(Y) of one minus the other's, and
SE = sqrt(sum (e_i - e'_i)^2 / (n (n - 1))), far smaller than either figure's own interval
when the trains' luck is shared.
"""
from __future__ import annotations

import math

import numpy as np

from monitor.core.types import (
    R_DEADLINE, R_DISPUTE, R_ENVELOPE, R_IMPLAUSIBLE, R_INIT, R_MEMORY, R_PERCEPTOR, R_SAFE_STOP, R_SBI, R_STALE,
    R_SYSTEM_ERROR, R_TABLE, R_TRAIN_INPUT,
)

Z95 = 1.96
# What the supervision brakes for by itself, whatever the policy proposes (monitor.core.types)
SUPERVISION_CAUSES = (R_ENVELOPE | R_SBI | R_MEMORY | R_SYSTEM_ERROR | R_INIT | R_SAFE_STOP | R_STALE | R_PERCEPTOR
                      | R_DEADLINE | R_TRAIN_INPUT | R_DISPUTE | R_IMPLAUSIBLE)


def policy_alone(reasons: np.ndarray) -> np.ndarray:
    """Cycles whose brake demand only the policy asked for (R_TABLE, no supervision cause)."""
    r = np.asarray(reasons, dtype=np.int64)
    return ((r & R_TABLE) != 0) & ((r & SUPERVISION_CAUSES) == 0)


def ratio(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(sum x / sum y, half-width of its 95 % interval) over independent trains."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    total = float(y.sum())
    if total <= 0:
        return float("nan"), float("nan")
    r = float(x.sum()) / total
    n = len(x)
    if n < 2:
        return r, float("nan")
    e = x - r * y
    return r, Z95 * math.sqrt(n / (n - 1) * float((e * e).sum())) / total


def _influence(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per-train linearised deviations of the ratio sum x / sum y (mean 0)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    r = float(x.sum()) / float(y.sum())
    return (x - r * y) / float(y.mean())


def paired(a: tuple, b: tuple) -> tuple[float, float]:
    """(figure of a - figure of b, standard error of that difference) for two ratio figures
    (x, y per train) measured on the same trains. nan, nan when either has no denominator
    or the trains differ in number."""
    (xa, ya), (xb, yb) = a, b
    n = len(xa)
    if n != len(xb) or n < 2 or float(np.sum(ya)) <= 0 or float(np.sum(yb)) <= 0:
        return float("nan"), float("nan")
    diff = float(np.sum(xa)) / float(np.sum(ya)) - float(np.sum(xb)) / float(np.sum(yb))
    d = _influence(xa, ya) - _influence(xb, yb)
    return diff, math.sqrt(float((d * d).sum()) / (n * (n - 1)))


def wilson_upper(hits: int, n: int) -> float:
    """Upper end of the 95 % Wilson score interval of a binomial proportion. Unlike the
    normal approximation (p +- 1.96 sqrt(p (1 - p) / n)) it stays honest when no or few
    episodes hit: 0 of 2000 gives 0.0019, not 0."""
    if n <= 0:
        return 1.0
    p, z2 = hits / n, Z95 * Z95
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return min(1.0, centre + half)


class PolicyCost:
    """Per-train counters, updated once per cycle with the world's truth and the demand sent."""

    def __init__(self, n: int, dt: float, encounters: np.ndarray | None = None):
        self.dt = dt
        self.free = np.zeros(n)              # cycles without need to brake (the world's `need`)
        self.brake_free = np.zeros(n)        # ... with a brake demand
        self.alone_free = np.zeros(n)        # ... that only the policy asked for
        self.stops = np.zeros(n)             # moving -> standstill
        self.changes = np.zeros(n)           # demand different from the cycle before
        self.encounters = np.zeros(n) if encounters is None else np.asarray(encounters, dtype=float).copy()
        self.cycles = np.zeros(n)
        self.prev = np.zeros(n, dtype=np.int64)

    def cycle(self, need: np.ndarray, demand: np.ndarray, alone: np.ndarray | None = None) -> None:
        """One cycle: `need` where the world gives a cause to brake, the demand sent, and
        where that demand came from the policy alone (`policy_alone`; None: nowhere)."""
        free = ~np.asarray(need, dtype=bool)
        self.free += free
        self.brake_free += free & (demand > 0)
        if alone is not None:
            self.alone_free += free & (demand > 0) & np.asarray(alone, dtype=bool)
        self.changes += demand != self.prev
        self.prev = np.asarray(demand, dtype=np.int64).copy()
        self.cycles += 1

    def moved(self, v_before: np.ndarray, v_after: np.ndarray, new_encounters: np.ndarray) -> None:
        self.stops += (v_before > 0) & (v_after <= 0)
        self.encounters += new_encounters

    def figures(self) -> dict:
        """The four Monte Carlo figures, each with its 95 % half-width (`*_ci`)."""
        out = {}
        for key, (x, y) in self.per_train().items():
            value, ci = ratio(x, y)
            out[key], out[key + "_ci"] = value, ci
        out["train_hours"] = float((self.cycles * self.dt / 3600.0).sum())
        out["encounters"] = int(self.encounters.sum())
        return out

    def per_train(self) -> dict:
        """figure -> (X, Y) per train, the sums each figure is the ratio of (for `paired`)."""
        hours = self.cycles * self.dt / 3600.0
        return {"unnecessary_braking": (self.brake_free.copy(), self.free.copy()),
                "policy_braking": (self.alone_free.copy(), self.free.copy()),
                "stops_per_train_hour": (self.stops.copy(), hours),
                "demand_changes_per_encounter": (self.changes.copy(), self.encounters.copy())}
