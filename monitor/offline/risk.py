"""Risk estimators of the papers, used for reporting next to the policy.

R1 and R2 are seed 000 eqs. 16-17; the score rho and its four categories are seed 001
eq. 11. They are written as printed; R2 is clipped to [0, 1] as the paper states both
estimators are probabilities.
"""
from __future__ import annotations

import math

RISK_WEIGHTS = (3, 2, 2, 1, 2)  # distance, relative speed, obstacle type, track, brake
RISK_NAMES = ("low", "moderate", "high", "critical")


def r1_logistic(distance_m: float, alpha1_m: float) -> float:
    """Seed 000 eq. 16: R1 = 1 - 1 / (1 + exp(-5 d / alpha1))."""
    return 1.0 - 1.0 / (1.0 + math.exp(-5.0 * distance_m / alpha1_m))


def r2_linear(distance_m: float, alpha1_m: float, alpha2_m: float) -> float:
    """Seed 000 eq. 17: R2 = (alpha1 - d) / (alpha1 - alpha2), clipped to [0, 1]."""
    return min(1.0, max(0.0, (alpha1_m - distance_m) / (alpha1_m - alpha2_m)))


def risk_score(distance: int, rel_speed: int, obstacle: int, track: int, brake: int) -> int:
    """Seed 001 eq. 11: rho = 3 alpha + 2 beta + 2 phi + psi + 2 omega (levels from 0)."""
    return sum(w * x for w, x in zip(RISK_WEIGHTS, (distance, rel_speed, obstacle, track, brake)))


def risk_category(score: int) -> int:
    """Seed 001 categories: 1 low (<= 7), 2 moderate (8-11), 3 high (12-15), 4 critical (>= 16)."""
    if score <= 7:
        return 1
    if score <= 11:
        return 2
    if score <= 15:
        return 3
    return 4
