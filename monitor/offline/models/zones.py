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


def boundary_deceleration(speed_mps: float, distance_m: float) -> float:
    """The deceleration a braking distance stands for at this speed: v^2 / (2 d)."""
    return speed_mps ** 2 / (2.0 * distance_m)


def margin_step(closing_mps: float, speed_mps: float, braking_mps2: float, boundary_decel: float, dt: float) -> float:
    """Change of the margin to a braking-distance boundary over one step (negative: closer)."""
    return (-closing_mps + speed_mps * braking_mps2 / boundary_decel) * dt


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
