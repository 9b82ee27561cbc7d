"""Zone kinematics shared by both models (the derivation is in docs/models.md).

Zones are intervals of obstacle distance measured against braking distances
(seed 000 eq. 3): critical [0, alpha2], emergency (alpha2, alpha1],
warning (alpha1, alpha1 + L_w], free beyond. In the adaptive grid the boundaries are
braking distances, alpha_i(v) = v^2 / (2 a_i), so they move when the train brakes. The
obstacle's margin to boundary i therefore changes at

    dm_i/dt = -v_c + v * b / a_i

(v_c closing speed, v train speed, b applied deceleration, a_i = v0^2 / (2 alpha_i) the
deceleration the boundary distance stands for). Assuming the obstacle is spread
uniformly over a zone of length L, one step of dt crosses the lower boundary with
probability max(0, -dm_lower dt) / L and the upper one with max(0, dm_upper dt) / L.
"""
from __future__ import annotations

import numpy as np
from math import erf, sqrt


ZONE_SOURCES = ("monitor", "paper")


def boundary_deceleration(speed_mps: float, distance_m: float) -> float:
    """The deceleration a braking distance stands for at this speed: v^2 / (2 d)."""
    return speed_mps ** 2 / (2.0 * distance_m)


def margin_step(closing_mps: float, slope_s: float, braking_mps2: float, dt: float) -> float:
    """Change of the margin to a braking-distance boundary over one step (negative: closer):
    the obstacle closes at `closing_mps`, the boundary recedes at slope x braking, `slope_s`
    being d(boundary distance)/d(speed). For v^2 / 2a the slope is v / a."""
    return (-closing_mps + slope_s * braking_mps2) * dt


def paper_margin_step(closing_mps: float, speed_mps: float, braking_mps2: float, boundary_decel: float, dt: float) -> float:
    """margin_step for a pure braking distance v^2 / 2a, in the operation order the tables
    solved before the monitor's zones used (so their models rebuild bit for bit)."""
    return (-closing_mps + speed_mps * braking_mps2 / boundary_decel) * dt


def paper_slope(speed_mps: float, distance_m: float) -> float:
    """d(alpha)/dv of a pure braking distance alpha = v^2 / 2a at this speed: v / a = 2 alpha / v."""
    return speed_mps / boundary_deceleration(speed_mps, distance_m)


def monitor_zones(speed_mps: float, warning_m: float | None = None) -> tuple[float, float, float, float, float]:
    """(alpha1, alpha2, slope1, slope2, warning length) of the monitor's own zones for a
    static obstacle at this speed, from the braking curves of the shipped declaration
    (monitor.core.braking, docs/supervision.md): alpha2 = EBI, alpha1 = the service brake's
    EBI, both under normal conditions with a fresh report; slopes d(alpha)/dv by a central
    difference over +-1 m/s (the obstacle static: closing speed = train speed)."""
    from monitor.core.braking import ebi_dm
    from monitor.core.config import Config

    cfg = Config()
    v = int(round(speed_mps * 100))

    def alpha(cms: int, service: bool) -> float:
        return ebi_dm(cfg, cms, 0, 0, cms, 0, service) / 10.0

    a2, a1 = alpha(v, False), max(alpha(v, True), alpha(v, False))
    lo = max(v - 100, 0)
    s2 = (alpha(v + 100, False) - alpha(lo, False)) / ((v + 100 - lo) / 100.0)
    s1 = (alpha(v + 100, True) - alpha(lo, True)) / ((v + 100 - lo) / 100.0)
    return a1, a2, s1, s2, cfg.warning_margin_dm / 10.0 if warning_m is None else warning_m


def crossing_probabilities(step_lower: float, step_upper: float, length: float) -> tuple[float, float]:
    """(P(cross lower), P(cross upper)) for a uniform position in a zone of this length."""
    down = min(1.0, max(0.0, -step_lower) / length)
    up = min(1.0 - down, max(0.0, step_upper) / length)
    return down, up


def interval_overlap(lo: float, hi: float, edges: list[float]) -> np.ndarray:
    """Fraction of the uniform interval [lo, hi] falling in each zone bounded by edges."""
    fr = []
    for a, b in zip(edges[:-1], edges[1:]):
        fr.append(max(0.0, min(hi, b) - max(lo, a)))
    fr = np.array(fr)
    total = hi - lo
    return fr / total if total > 0 else fr


def _phi(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.vectorize(erf)(x / sqrt(2.0)))


def gaussian_zone_confusion(edges: list[float], sigma: float, points: int = 2001) -> np.ndarray:
    """C[i, j] = P(measured distance in zone j | true distance uniform in zone i).

    Measured = true + N(0, sigma^2); readings below 0 count in the first zone and above the
    last edge in the last. sigma = 0 gives the identity. Integrated with the midpoint rule
    over `points` true positions per zone.
    """
    n = len(edges) - 1
    if sigma <= 0:
        return np.eye(n)
    C = np.zeros((n, n))
    inner = np.array(edges[1:-1], dtype=float)
    for i in range(n):
        lo, hi = edges[i], edges[i + 1]
        x = lo + (np.arange(points) + 0.5) * (hi - lo) / points
        cdf = _phi((inner[None, :] - x[:, None]) / sigma)  # P(measured <= edge)
        cum = np.column_stack([np.zeros(points), cdf, np.ones(points)])
        C[i] = np.diff(cum, axis=1).mean(axis=0)
    return C / C.sum(axis=1, keepdims=True)
