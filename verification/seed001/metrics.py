"""Seed 001's three metrics (section 4) and Model 2's risk categories, as plain functions.

Time with obstacles, risk-assessment accuracy and mean reward as the paper defines them;
eq. 11's risk category of every state; eq. 10's rewards by category; the exact expected
obstacle share of our obstacle process and the mean gap that calibrates it to 75 %.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from monitor.offline.models import model2
from monitor.offline.risk import RISK_WEIGHTS


PAPER = {"obstacles": 75.0, "accuracy": 96.3, "reward": -3.19}


DIMS = model2.DIMS                       # 4, 3, 3, 2, 2
N_STATES = int(np.prod(DIMS))


def time_with_obstacles(present: np.ndarray) -> float:
    """Seed 001 section 4: steps with an obstacle present / all steps, in per cent."""
    p = np.asarray(present, dtype=bool)
    return 100.0 * float(p.sum()) / p.size if p.size else float("nan")


def risk_accuracy(true_risk: np.ndarray, estimated_risk: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """Seed 001 section 4: steps where the true and the estimated risk category agree, in
    per cent (over the steps selected by `mask`, all by default)."""
    t, e = np.asarray(true_risk), np.asarray(estimated_risk)
    same = t == e
    if mask is not None:
        same = same[np.asarray(mask, dtype=bool)]
    return 100.0 * float(same.mean()) if same.size else float("nan")


def mean_reward(rewards: np.ndarray) -> float:
    """Seed 001 section 4: the sum of the rewards over all steps / the number of steps."""
    r = np.asarray(rewards, dtype=float)
    return float(r.mean()) if r.size else float("nan")


def risk_categories(distance, speed, obstacle, track, brake) -> np.ndarray:
    """Eq. 11 on arrays: rho = 3a + 2b + 2phi + psi + 2omega, categories 1..4."""
    w = RISK_WEIGHTS
    rho = (w[0] * np.asarray(distance) + w[1] * np.asarray(speed) + w[2] * np.asarray(obstacle)
           + w[3] * np.asarray(track) + w[4] * np.asarray(brake))
    return np.where(rho <= 7, 1, np.where(rho <= 11, 2, np.where(rho <= 15, 3, 4)))


def state_index(distance, speed, obstacle, track, brake):
    """Index in Model 2's state (and observation) order; the core's m2_observation."""
    return (((distance * 3 + speed) * 3 + obstacle) * 2 + track) * 2 + brake


def state_components(index) -> tuple:
    """The inverse of state_index: (distance, speed, obstacle, track, brake)."""
    i = np.asarray(index)
    brake, i = i % 2, i // 2
    track, i = i % 2, i // 2
    obstacle, i = i % 3, i // 3
    speed, distance = i % 3, i // 3
    return distance, speed, obstacle, track, brake


STATE_RISK = risk_categories(*state_components(np.arange(N_STATES)))


def reward_by_category(variant: str) -> np.ndarray:
    """R[category - 1, action] of eq. 10 as printed ("paper") or corrected, as Model 2 has them."""
    if variant == "paper":
        return np.array([[model2.PAPER_REWARD[c].get(a, 0.0) for a in range(3)] for c in (1, 2, 3, 4)])
    return np.array(model2.CORRECTED_REWARD, dtype=float)


def expected_obstacle_fraction(steps: int, dt: float, durations: tuple, prior: tuple, gap_s: float,
                               start_types: tuple = (1 / 3, 1 / 3, 1 / 3)) -> float:
    """Exact expected share of steps with an obstacle, in per cent, for our obstacle process
    (a Markov chain over absent / static / dynamic / train, per step: an obstacle of type k
    leaves with dt / D_k, a new one comes with dt / gap_s, its type drawn from `prior`),
    starting with an obstacle whose type is distributed as `start_types`. Collisions, which
    end an encounter early, are not in it."""
    q = np.array([min(1.0, dt / d) for d in durations])
    g = min(1.0, dt / gap_s)
    P = np.zeros((4, 4))
    P[0, 0] = 1 - g
    P[0, 1:] = g * np.asarray(prior)
    for k in range(3):
        P[1 + k, 0] = q[k]
        P[1 + k, 1 + k] = 1 - q[k]
    p = np.concatenate([[0.0], start_types])
    total = 0.0
    for _ in range(steps):
        total += 1.0 - p[0]
        p = p @ P
    return 100.0 * total / steps


def calibrated_gap_s(steps: int, dt: float, durations: tuple, prior: tuple, target: float = 75.0) -> float:
    """The mean gap between obstacles for which expected_obstacle_fraction is `target`."""
    lo, hi = 0.1, 10000.0              # the fraction falls as the gap grows
    for _ in range(80):
        mid = math.sqrt(lo * hi)
        if expected_obstacle_fraction(steps, dt, durations, prior, mid) > target:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def standard_error(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=float)
    return float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else float("nan")
