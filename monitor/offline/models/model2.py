"""Model 2: the 144-state anti-collision POMDP of seed 001 (ESREL 2025), section 3.

A state is (distance level, relative speed, obstacle type, track condition, brake
status) = 4 x 3 x 3 x 2 x 2. The paper states the dynamics only qualitatively
(eqs. 2-6) and gives no numbers; T is derived here with the same zone kinematics as
Model 1 (see zones.py and docs/models.md), the observation is the per-component
misperception of eq. 9, the reward eq. 10 as printed ("paper") or our corrected variant
("corrected"), and the risk score and categories are eq. 11.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from ..pomdp import POMDP, ModelError
from ..relaxation import Relaxation
from ..risk import risk_category, risk_score
from .zones import (ZONE_SOURCES, boundary_deceleration, crossing_probabilities, margin_step, monitor_zones,
                    paper_margin_step, paper_slope)

DISTANCE = ("far", "medium", "close", "critical")
REL_SPEED = ("away", "slow", "fast")
OBSTACLE = ("static", "dynamic", "train")
TRACK = ("normal", "slippery")
BRAKE = ("normal", "degraded")
COMPONENTS = (DISTANCE, REL_SPEED, OBSTACLE, TRACK, BRAKE)
ACTIONS = ("maintain", "nominal_braking", "emergency_braking")
CONDITIONS = (3, 4)  # track and brake: reported adverse, they must never lower the demand
REVEALED = (1, 2, 3, 4)  # the information relaxation's bound reads all but the distance without error
DIMS = tuple(len(c) for c in COMPONENTS)

# Eq. 10 as printed: a reward only where the printed case applies, 0 elsewhere.
PAPER_REWARD = {1: {0: 0.0}, 2: {0: -5.0, 1: -5.0}, 3: {0: -20.0, 2: -20.0}, 4: {0: -100.0, 1: -100.0}}
# Ours: penalties rise with risk and with the shortfall of the response; braking costs
# when the risk is low. Rows: risk category 1..4; columns: maintain, nominal, emergency.
CORRECTED_REWARD = ((0.0, -2.0, -5.0), (-5.0, 0.0, -2.0), (-20.0, -5.0, 0.0), (-100.0, -50.0, 0.0))
# "hazard": the costs the tables are judged by (docs/models.md section 7): the hazard itself
# (a step in the critical level) and the deceleration demanded anywhere else.
HAZARD_COST = 20000.0
REWARD_VARIANTS = ("corrected", "paper", "hazard")
# The start belief's track and brakes: "any" = the four combinations equally likely (the
# default since issue 11), "normal" = normal track and normal brakes (before issue 11).
START_CONDITIONS = ("any", "normal")


def state_tuples() -> list[tuple[int, ...]]:
    """All states as component levels, in the order of the model's state index."""
    return list(itertools.product(*(range(n) for n in DIMS)))


def state_name(levels: tuple[int, ...]) -> str:
    return "-".join(comp[i] for comp, i in zip(COMPONENTS, levels))


@dataclass(frozen=True)
class Model2Params:
    """Seed 001 fixes the structure; every number below is ours unless marked."""

    reward: str = "hazard"                       # "paper" = eq. 10 as printed, "corrected" = ours of it,
                                                 # "hazard" = the costs the tables are judged by (section 7)
    zones: str = "monitor"                       # "monitor": the levels are the monitor's zones from the
                                                 # braking curves; "paper": the three *_length_m below
    discount: float = 0.95                       # seed 000 Table 1 (seed 001 gives none)
    time_step_s: float = 0.1                     # seed 000 Table 1; the monitor's cycle
    speed_mps: float = 40.0                      # seed 000 Table 1
    critical_length_m: float = 100.0             # = alpha2 of seed 000
    close_length_m: float = 200.0                # = alpha1 - alpha2 of seed 000
    medium_length_m: float = 200.0               # warning zone, as Model 1
    far_length_m: float = 1000.0                 # approach horizon beyond the warning zone
    closing_speeds_mps: tuple = (-5.0, 10.0, 35.0)  # representative of away / slow / fast
    speed_class_width_mps: float = 20.0          # braking this much moves one speed class
    decelerations_mps2: tuple = (0.0, 1.0, 3.0)  # seed 000 Table 1
    slippery_braking_factor: float = 0.7         # achieved braking on a slippery track
    degraded_braking_factor: float = 0.5         # achieved braking with degraded brakes
    speed_change_dynamic: float = 0.01           # eq. 5, dynamic object: P(class +-1) per step
    speed_change_train: float = 0.004            # eq. 5, other train: P(class +-1) per step
    obstacle_duration_s: tuple = (60.0, 10.0, 30.0)  # mean stay of static / dynamic / train
    obstacle_prior: tuple = (0.5, 0.3, 0.2)      # type of the next obstacle
    speed_prior: tuple = (0.1, 0.4, 0.5)         # speed class of the next obstacle
    slippery_onset: float = 0.0005               # P(normal -> slippery) per step
    slippery_end: float = 0.002                  # P(slippery -> normal) per step
    degrade_normal_track: float = 0.0002         # eq. 6: P(brake degrades) on a normal track
    degrade_slippery_track: float = 0.002        # eq. 6: ... on a slippery track
    brake_recovery: float = 0.001                # P(degraded -> normal) per step
    misperception: tuple = (0.02, 0.05, 0.05, 0.02, 0.01)  # eq. 9, epsilon per component
    start_conditions: str = "any"                # see START_CONDITIONS and docs/models.md section 6
    collision_weight: float = 0.5                # "hazard": x the hazard's cost (0.5: the recommended point of the Pareto
                                                 # sweep, docs/verification/pareto-m2); "paper"/"corrected": x the
                                                 # penalties for braking less than the risk asks ("paper": unweighted)
    braking_weight: float = 1.0                  # x the penalties for braking more than the risk asks
    release_cost: float = 2.0                    # paid by the controller each time it lowers its demand
    far_braking_cost: float = 30.0               # reward "hazard": per m/s^2 demanded with the obstacle beyond the
                                                 # warning zone (the unnecessary braking the tables are judged by)
    near_braking_cost: float = 0.01              # reward "hazard": per m/s^2 demanded for an obstacle within it (lost time)

    def check(self) -> None:
        if self.zones not in ZONE_SOURCES:
            raise ModelError(f"unknown zones {self.zones!r}; known: {', '.join(ZONE_SOURCES)}")
        if self.zones == "monitor" and (self.critical_length_m, self.close_length_m, self.medium_length_m) != (100.0, 200.0, 200.0):
            raise ModelError("critical_length_m, close_length_m and medium_length_m apply with zones = \"paper\"; "
                             "with zones = \"monitor\" the braking curves set them")
        if self.reward not in REWARD_VARIANTS:
            raise ModelError(f"unknown reward variant {self.reward!r}; known: {', '.join(REWARD_VARIANTS)}")
        if self.start_conditions not in START_CONDITIONS:
            raise ModelError(f"unknown start_conditions {self.start_conditions!r}; "
                             f"known: {', '.join(START_CONDITIONS)}")
        if not 0.0 <= self.discount < 1.0:
            raise ModelError(f"discount must be in [0, 1), got {self.discount}")
        for name in ("time_step_s", "speed_mps", "critical_length_m", "close_length_m", "medium_length_m",
                     "far_length_m", "speed_class_width_mps"):
            if not getattr(self, name) > 0:
                raise ModelError(f"{name} must be > 0, got {getattr(self, name)}")
        if any(d < 0 for d in self.decelerations_mps2):
            raise ModelError(f"decelerations_mps2 must be >= 0 (magnitudes), got {self.decelerations_mps2}")
        probs = ("slippery_braking_factor", "degraded_braking_factor", "speed_change_dynamic",
                 "speed_change_train", "slippery_onset", "slippery_end", "degrade_normal_track",
                 "degrade_slippery_track", "brake_recovery")
        for name in probs:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ModelError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.speed_change_dynamic > 0.5 or self.speed_change_train > 0.5:
            raise ModelError("speed_change_* must be <= 0.5 (it applies in both directions)")
        for name in ("obstacle_prior", "speed_prior"):
            v = getattr(self, name)
            if any(x < 0 for x in v) or abs(sum(v) - 1.0) > 1e-9:
                raise ModelError(f"{name} must be probabilities summing to 1, got {v}")
        if any(d <= 0 for d in self.obstacle_duration_s):
            raise ModelError(f"obstacle_duration_s must be > 0, got {self.obstacle_duration_s}")
        for name in ("collision_weight", "braking_weight", "release_cost", "far_braking_cost", "near_braking_cost"):
            if not getattr(self, name) >= 0:
                raise ModelError(f"{name} must be >= 0, got {getattr(self, name)}")
        for i, e in enumerate(self.misperception):
            if not 0.0 <= e < 1.0:
                raise ModelError(f"misperception[{i}] must be in [0, 1), got {e}")


def geometry(p: Model2Params) -> tuple[float, float, float, float, float]:
    """(critical, close, medium lengths, slope of alpha1, slope of alpha2): the distance
    levels and how fast their limits recede per m/s of speed lost (zones.margin_step)."""
    if p.zones == "monitor":
        alpha1, alpha2, s1, s2, warning = monitor_zones(p.speed_mps)
        return alpha2, alpha1 - alpha2, warning, s1, s2
    v = p.speed_mps
    alpha2 = p.critical_length_m
    alpha1 = alpha2 + p.close_length_m
    return alpha2, p.close_length_m, p.medium_length_m, paper_slope(v, alpha1), paper_slope(v, alpha2)


def _distance_row(p: Model2Params, dist: int, closing: float, braking: float) -> np.ndarray:
    """P(next distance level | level, closing speed, achieved braking) from margin kinematics."""
    dt, v = p.time_step_s, p.speed_mps
    critical, close, medium, slope1, slope2 = geometry(p)
    if p.zones == "paper":   # to alpha1 (and to d_w, which moves with it), to alpha2
        m1 = paper_margin_step(closing, v, braking, boundary_deceleration(v, critical + close), dt)
        m2 = paper_margin_step(closing, v, braking, boundary_deceleration(v, critical), dt)
    else:
        m1 = margin_step(closing, slope1, braking, dt)
        m2 = margin_step(closing, slope2, braking, dt)
    # level: (lower step, upper step, length); far's lower boundary is d_w, no upper
    spec = {
        0: (m1, 0.0, p.far_length_m),
        1: (m1, m1, medium),
        2: (m2, m1, close),
        3: (0.0, m2, critical),
    }
    lo, hi, length = spec[dist]
    down, up = crossing_probabilities(lo, hi, length)
    row = np.zeros(4)
    if dist < 3:
        row[dist + 1] += down  # closer
    if dist > 0:
        row[dist - 1] += up    # farther
    row[dist] += 1.0 - row.sum()
    return row


def _speed_row(p: Model2Params, rel: int, obstacle: int, braking: float) -> np.ndarray:
    """P(next relative-speed class): braking lowers the closing speed; eq. 5 moves it by obstacle type."""
    row = np.zeros(3)
    slow_down = min(1.0, braking * p.time_step_s / p.speed_class_width_mps)
    # a static obstacle cannot move away: the closing speed is the train speed, >= 0
    floor = 1 if obstacle == 0 else 0
    target = max(floor, rel - 1)
    row[target] += slow_down if target != rel else 0.0
    row[rel] += 1.0 - row.sum()
    change = (0.0, p.speed_change_dynamic, p.speed_change_train)[obstacle]
    mixed = np.zeros(3)
    for c, pc in enumerate(row):
        lo, hi = max(floor, c - 1), min(2, c + 1)
        mixed[lo] += change * pc
        mixed[hi] += change * pc
        mixed[c] += (1.0 - 2.0 * change) * pc
    return mixed


def transition(p: Model2Params) -> np.ndarray:
    states = state_tuples()
    index = {s: i for i, s in enumerate(states)}
    n = len(states)
    T = np.zeros((3, n, n))
    track_rows = np.array([[1 - p.slippery_onset, p.slippery_onset], [p.slippery_end, 1 - p.slippery_end]])
    for a, decel in enumerate(p.decelerations_mps2):
        for (d, r, o, k, b) in states:
            braking = decel * (p.slippery_braking_factor if k else 1.0) * (p.degraded_braking_factor if b else 1.0)
            dist_row = _distance_row(p, d, p.closing_speeds_mps[r], braking)
            speed_row = _speed_row(p, r, o, braking)
            degrade = p.degrade_slippery_track if k else p.degrade_normal_track
            brake_row = np.array([[1 - degrade, degrade], [p.brake_recovery, 1 - p.brake_recovery]])[b]
            p_clear = min(1.0, p.time_step_s / p.obstacle_duration_s[o])
            src = index[(d, r, o, k, b)]
            for k2 in range(2):
                for b2 in range(2):
                    env = track_rows[k, k2] * brake_row[b2]
                    if env == 0.0:
                        continue
                    for d2 in range(4):
                        for r2 in range(3):
                            w = (1.0 - p_clear) * dist_row[d2] * speed_row[r2]
                            if w:
                                T[a, src, index[(d2, r2, o, k2, b2)]] += env * w
                    # the obstacle leaves; the next one is far, of a type and speed drawn from the priors
                    for o2 in range(3):
                        for r2 in range(3):
                            w = p_clear * p.obstacle_prior[o2] * p.speed_prior[r2]
                            if w:
                                T[a, src, index[(0, r2, o2, k2, b2)]] += env * w
    return T / T.sum(axis=2, keepdims=True)


def _component_confusion(size: int, eps: float) -> np.ndarray:
    """Eq. 9: right with 1 - eps, else one of the other values uniformly."""
    if size == 1:
        return np.ones((1, 1))
    return np.full((size, size), eps / (size - 1)) + np.eye(size) * (1.0 - eps - eps / (size - 1))


def observation(p: Model2Params) -> np.ndarray:
    """O[a, s', o]: the product of the per-component confusions (components independent)."""
    M = np.ones((1, 1))
    for size, eps in zip(DIMS, p.misperception):
        M = np.kron(M, _component_confusion(size, eps))
    return np.repeat(M[None], 3, axis=0)


# The response each risk category asks for (eq. 10's cases): maintain, nominal, emergency, emergency.
RESPONSE = (0, 1, 2, 2)


def reward(p: Model2Params) -> np.ndarray:
    """R[s, a]: "hazard" (docs/models.md section 4), or eq. 10 as printed ("paper", no weights)
    or corrected, where a penalty for braking less than the state's risk asks is
    x collision_weight, one for braking more x braking_weight."""
    R = np.zeros((len(state_tuples()), 3))
    if p.reward == "hazard":
        for i, s in enumerate(state_tuples()):
            per_mps2 = p.far_braking_cost if s[0] == 0 else p.near_braking_cost
            R[i] = (-HAZARD_COST * p.collision_weight if s[0] == 3
                    else -p.braking_weight * per_mps2 * np.asarray(p.decelerations_mps2, dtype=float))
        return R
    for i, s in enumerate(state_tuples()):
        cat = risk_category(risk_score(*s))
        for a in range(3):
            if p.reward == "paper":          # as printed: no weights
                R[i, a] = PAPER_REWARD[cat].get(a, 0.0)
                continue
            r = CORRECTED_REWARD[cat - 1][a]
            want = RESPONSE[cat - 1]
            R[i, a] = r * (p.collision_weight if a < want else p.braking_weight if a > want else 1.0)
    return R


def start_belief(p: Model2Params) -> np.ndarray:
    """An obstacle first seen in the far level, type and speed class from the priors; track and
    brakes normal, or (start_conditions = "any") each of the four combinations equally likely,
    so that the value the solver maximises weighs adverse conditions (docs/models.md section 6)."""
    b0 = np.zeros(len(state_tuples()))
    for i, (d, r, o, k, b) in enumerate(state_tuples()):
        if d == 0 and (p.start_conditions == "any" or k == 0 and b == 0):
            b0[i] = p.obstacle_prior[o] * p.speed_prior[r]
    return b0 / b0.sum()


def build(p: Model2Params = Model2Params()) -> POMDP:
    p.check()
    from ..params import as_dict

    names = [state_name(s) for s in state_tuples()]
    return POMDP(
        name="m2",
        states=tuple(names),
        actions=ACTIONS,
        observations=tuple(names),
        T=transition(p),
        O=observation(p),
        R=reward(p),
        discount=p.discount,
        b0=start_belief(p),
        params=as_dict(p),
        release_cost=p.release_cost,
    )


def relaxation(model: POMDP) -> Relaxation:
    """The model with speed, type, track and brake read without error (REVEALED): its optimum
    bounds the model's from above (relaxation.py), and its sawtooth gets far lower in the
    same seconds, because its beliefs spread over the four distance levels only.

    The model's observation is the relaxed one passed through the revealed components'
    confusions: G = I (distance) x C_speed x C_type x C_track x C_brake."""
    from ..params import override

    p = override(Model2Params(), model.params)
    eps = p.misperception
    sharp = replace(p, misperception=tuple(0.0 if i in REVEALED else e for i, e in enumerate(eps)))
    noise = replace(p, misperception=tuple(e if i in REVEALED else 0.0 for i, e in enumerate(eps)))
    relaxed = replace(build(sharp), release_cost=model.release_cost)
    return Relaxation(relaxed, observation(noise)[0], "speed, type, track and brake read without error")
