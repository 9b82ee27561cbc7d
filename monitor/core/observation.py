"""The voted picture as the table's observation symbol, for both models.

Names and order match the offline builders (monitor/offline/models); the monitor refuses
a table whose observation names differ, so a mismatch cannot go unnoticed.
"""
from __future__ import annotations

import itertools

from .types import TRAIN

M1_OBSERVATIONS = ("free", "warning", "emergency", "critical")
M2_COMPONENTS = (
    ("far", "medium", "close", "critical"),
    ("away", "slow", "fast"),
    ("static", "dynamic", "train"),
    ("normal", "slippery"),
    ("normal", "degraded"),
)
M2_OBSERVATIONS = tuple("-".join(p) for p in itertools.product(*M2_COMPONENTS))
OBSERVATIONS = {"m1": M1_OBSERVATIONS, "m2": M2_OBSERVATIONS}


def speed_class(closing_cms: int, fast_cms: int) -> int:
    """0 moving away, 1 stable or approaching slowly, 2 approaching fast (seed 001, beta).

    pre: fast_cms >= 1
    post: __return__ == (0 if closing_cms < 0 else (1 if closing_cms < fast_cms else 2))
    """
    if closing_cms < 0:
        return 0
    return 1 if closing_cms < fast_cms else 2


def m1_observation(zone: int) -> int:
    """Model 1 observes the zone itself (free, warning, emergency, critical).

    pre: 0 <= zone <= 3
    post: __return__ == zone
    """
    return zone


def m2_observation(zone: int, speed: int, obstacle: int, track: int, brake: int) -> int:
    """Index of (distance level, speed class, obstacle type, track, brake) in M2_OBSERVATIONS.

    pre: 0 <= zone <= 3 and 0 <= speed <= 2 and 0 <= obstacle <= 2 and 0 <= track <= 1 and 0 <= brake <= 1
    post: 0 <= __return__ < 144
    """
    return (((zone * 3 + speed) * 3 + obstacle) * 2 + track) * 2 + brake


assert M2_OBSERVATIONS[m2_observation(3, 2, TRAIN, 1, 1)] == "critical-fast-train-slippery-degraded"
