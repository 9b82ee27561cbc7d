"""Model 1: the 4-state anti-collision POMDP of seed 000 (IEEE Access 2024), section IV.

States are the zones of the obstacle in the adaptive grid (eq. 4): Safe (free zone, no
obstacle within the warning distance), ObstacleDetected (warning zone), AboutToCrash
(emergency zone), Crash (critical zone). Actions are the paper's accelerations
(Table 1). The paper gives no numbers for T and O; they are derived here from the
kinematics (eqs. 6-11) and the Gaussian distance noise of section V-A. The derivation,
and where we had to add to the paper, is in docs/models.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..pomdp import POMDP, ModelError
from .zones import (
    ZONE_SOURCES,
    boundary_deceleration,
    crossing_probabilities,
    gaussian_zone_confusion,
    interval_overlap,
    margin_step,
    monitor_zones,
    paper_margin_step,
    paper_slope,
)

STATES = ("Safe", "ObstacleDetected", "AboutToCrash", "Crash")
ACTIONS = ("maintain", "nominal_braking", "emergency_braking")
OBSERVATIONS = ("free", "warning", "emergency", "critical")
SAFE, WARNING, EMERGENCY, CRITICAL = range(4)


@dataclass(frozen=True)
class Model1Params:
    """Defaults are seed 000's Table 1 and section V; additions are marked (ours)."""

    zones: str = "monitor"                       # (ours) "monitor": the monitor's zones from the braking
                                                 # curves; "paper": alpha1_m / alpha2_m / warning_length_m
    speed_mps: float = 40.0                      # Table 1, initial train speed
    time_step_s: float = 0.1                     # Table 1, time sample
    alpha1_m: float = 300.0                      # Table 1, nominal braking distance
    alpha2_m: float = 100.0                      # Table 1, emergency braking distance
    warning_length_m: float = 200.0              # (ours) length of the warning zone, d_w - alpha1
    decelerations_mps2: tuple = (0.0, 1.0, 3.0)  # Table 1, action forces (magnitudes)
    rewards: tuple = (10.0, -10.0, -100.0, -1000.0)  # eq. 13 / Table 1
    braking_costs: tuple = (0.0, 1.0, 5.0)       # (ours) cost per step of each action
    collision_weight: float = 1.0                # (ours) x the Crash reward: the Pareto sweep's risk weight
    braking_weight: float = 1.0                  # (ours) x braking_costs: the sweep's braking weight
    release_cost: float = 5.0                    # (ours) paid by the controller each time it lowers its demand
    crash_energy_weighting: bool = True          # (ours) Crash penalty scaled by impact energy
    discount: float = 0.95                       # Table 1
    obstacle_fraction: float = 0.2               # section V-B, obstacles ~20 % of the time
    obstacle_duration_s: float = 30.0            # (ours) mean time an obstacle stays
    appear_offset_m: float = 50.0                # section V-B, U[(a1+a2)/2, (a1+a2)/2 + 50]
    noise_sigma_m: float = 10.0                  # (ours) std of the Gaussian distance noise
    false_positive: float = 0.02                 # (ours) phantom report per step, no obstacle
    missed_detection: float = 0.02               # (ours) obstacle not reported per step

    def check(self) -> None:
        if self.zones not in ZONE_SOURCES:
            raise ModelError(f"unknown zones {self.zones!r}; known: {', '.join(ZONE_SOURCES)}")
        if self.zones == "monitor" and (self.alpha1_m, self.alpha2_m, self.warning_length_m) != (300.0, 100.0, 200.0):
            raise ModelError("alpha1_m, alpha2_m and warning_length_m are the paper's fixed zones: they apply with "
                             "zones = \"paper\"; with zones = \"monitor\" the braking curves set them")
        positive = ("speed_mps", "time_step_s", "alpha1_m", "alpha2_m", "warning_length_m", "obstacle_duration_s")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ModelError(f"{name} must be > 0, got {getattr(self, name)}")
        if not self.alpha2_m < self.alpha1_m:
            raise ModelError(f"alpha2_m ({self.alpha2_m}) must be below alpha1_m ({self.alpha1_m})")
        if any(d < 0 for d in self.decelerations_mps2):
            raise ModelError(f"decelerations_mps2 must be >= 0 (magnitudes), got {self.decelerations_mps2}")
        if list(self.decelerations_mps2) != sorted(self.decelerations_mps2):
            raise ModelError("decelerations_mps2 must be ordered maintain <= nominal <= emergency")
        for name in ("obstacle_fraction", "false_positive", "missed_detection"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ModelError(f"{name} must be in [0, 1), got {getattr(self, name)}")
        if not 0.0 <= self.discount < 1.0:
            raise ModelError(f"discount must be in [0, 1), got {self.discount}")
        if self.noise_sigma_m < 0 or self.appear_offset_m < 0:
            raise ModelError("noise_sigma_m and appear_offset_m must be >= 0")
        if any(c < 0 for c in self.braking_costs):
            raise ModelError(f"braking_costs must be >= 0, got {self.braking_costs}")
        for name in ("collision_weight", "braking_weight", "release_cost"):
            if not getattr(self, name) >= 0:
                raise ModelError(f"{name} must be >= 0, got {getattr(self, name)}")


def geometry(p: Model1Params) -> tuple[float, float, float, float, float]:
    """(alpha1, alpha2, slope1, slope2, warning length): the zone limits at the model's
    speed and how fast each recedes per m/s of speed lost (see zones.margin_step)."""
    if p.zones == "monitor":
        return monitor_zones(p.speed_mps)
    v = p.speed_mps
    return p.alpha1_m, p.alpha2_m, paper_slope(v, p.alpha1_m), paper_slope(v, p.alpha2_m), p.warning_length_m


def zone_edges(p: Model1Params) -> list[float]:
    """Distance edges of critical, emergency, warning (ascending from the train head)."""
    alpha1, alpha2, _, _, warning = geometry(p)
    return [0.0, alpha2, alpha1, alpha1 + warning]


def transition(p: Model1Params) -> np.ndarray:
    """T[a, s, s'] from margin kinematics, obstacle appearance and clearance."""
    dt, v = p.time_step_s, p.speed_mps
    alpha1, alpha2, slope1, slope2, warning = geometry(p)
    p_clear = min(1.0, dt / p.obstacle_duration_s)
    p_appear = p_clear * p.obstacle_fraction / (1.0 - p.obstacle_fraction)
    mid = 0.5 * (alpha1 + alpha2)
    edges = zone_edges(p)
    appear = interval_overlap(mid, mid + p.appear_offset_m, edges)  # critical, emergency, warning
    lengths = {CRITICAL: alpha2, EMERGENCY: alpha1 - alpha2, WARNING: warning}
    T = np.zeros((3, 4, 4))
    for a, b in enumerate(p.decelerations_mps2):
        if p.zones == "paper":   # margin to alpha1 (and to d_w, which moves with it), to alpha2
            d1 = paper_margin_step(v, v, b, boundary_deceleration(v, alpha1), dt)
            d2 = paper_margin_step(v, v, b, boundary_deceleration(v, alpha2), dt)
        else:
            d1 = margin_step(v, slope1, b, dt)
            d2 = margin_step(v, slope2, b, dt)
        motion = np.zeros((4, 4))
        motion[SAFE, SAFE] = 1.0 - p_appear
        motion[SAFE, CRITICAL] += p_appear * appear[0]
        motion[SAFE, EMERGENCY] += p_appear * appear[1]
        motion[SAFE, WARNING] += p_appear * appear[2]
        motion[SAFE, SAFE] += p_appear * (1.0 - appear.sum())
        # lower boundary step, upper boundary step, zone below, zone above
        moves = {
            CRITICAL: (0.0, d2, CRITICAL, EMERGENCY),   # collision keeps it critical
            EMERGENCY: (d2, d1, CRITICAL, WARNING),
            WARNING: (d1, d1, EMERGENCY, SAFE),         # beyond d_w counts as free
        }
        for z, (lo, hi, below, above) in moves.items():
            down, up = crossing_probabilities(lo, hi, lengths[z])
            row = np.zeros(4)
            row[below] += down
            row[above] += up
            row[z] += 1.0 - down - up
            row = (1.0 - p_clear) * row
            row[SAFE] += p_clear
            motion[z] = row
        T[a] = motion
    return T


def observation(p: Model1Params) -> np.ndarray:
    """O[a, s', o]: zone of the measured distance (true + Gaussian noise), with misses and phantoms."""
    edges = zone_edges(p)
    far = edges[-1] + 10.0 * p.noise_sigma_m + 1.0
    # zones ascending: critical, emergency, warning, free
    C = gaussian_zone_confusion(edges + [far], p.noise_sigma_m)
    asc_to_obs = [CRITICAL, EMERGENCY, WARNING, SAFE]  # index of each ascending zone in OBSERVATIONS
    O = np.zeros((4, 4))
    phantom = interval_overlap(0.0, edges[-1], edges)  # phantom distance uniform within d_w
    O[SAFE, SAFE] = 1.0 - p.false_positive
    for k in range(3):
        O[SAFE, asc_to_obs[k]] += p.false_positive * phantom[k]
    for k in range(3):  # true zone ascending k
        s = asc_to_obs[k]
        O[s, SAFE] += p.missed_detection
        for j in range(4):
            O[s, asc_to_obs[j]] += (1.0 - p.missed_detection) * C[k, j]
    O = O / O.sum(axis=1, keepdims=True)
    return np.repeat(O[None], 3, axis=0)


def reward(p: Model1Params) -> np.ndarray:
    """R[s, a] = eq. 13 reward of s (Crash scaled by impact energy) minus the braking cost of a."""
    R = np.zeros((4, 3))
    v = p.speed_mps
    for a, b in enumerate(p.decelerations_mps2):
        for s in range(4):
            r = p.rewards[s] * (p.collision_weight if s == CRITICAL else 1.0)
            if s == CRITICAL and p.crash_energy_weighting:
                # mean kinetic energy at impact, obstacle uniform in [0, alpha2], relative to v^2
                d = np.linspace(0.0, geometry(p)[1], 1001)
                r *= float(np.mean(np.maximum(0.0, v * v - 2.0 * b * d)) / (v * v))
            R[s, a] = r - p.braking_weight * p.braking_costs[a]
    return R


def build(p: Model1Params = Model1Params()) -> POMDP:
    p.check()
    from ..params import as_dict

    return POMDP(
        name="m1",
        states=STATES,
        actions=ACTIONS,
        observations=OBSERVATIONS,
        T=transition(p),
        O=observation(p),
        R=reward(p),
        discount=p.discount,
        b0=np.array([1.0, 0.0, 0.0, 0.0]),
        params=as_dict(p),
        release_cost=p.release_cost,
    )
