"""The policies a table is compared with, and the supervision in front of each of them.

A policy proposes a demand from what the monitor observes; the braking curves dispose
(docs/supervision.md): whatever the policy says, the monitor demands emergency inside EBI.
On the model's closed loop that is a floor on the action, a function of the observation:
the model's critical zone is "inside EBI under normal conditions", and the curves under the
reported conditions are never shorter, so `floor(critical) = emergency` is what the
supervision demands at least (its service inside SBI cuts through a zone and is left to the
worlds, where the real curves run).

Baselines (all finite-state controllers except belief tracking):
- `threshold`: emergency while the last observed zone is emergency or critical (seed 000's
  rule on alpha1), nothing otherwise;
- `always_emergency`, `never` (the curves alone);
- `belief_tracking`: the online POMDP policy of seed 000 eq. 14 with the solver's alpha
  vectors, not a finite-state controller.
"""
from __future__ import annotations

import numpy as np

from monitor.offline.closed_chain import EMERGENCY, supervised_product, supervision_floor, zone_of_observation
from monitor.offline.controller import Controller, minimise

BASELINES = ("threshold", "belief_tracking", "always_emergency", "never")
__all__ = ["BASELINES", "EMERGENCY", "BeliefTracking", "constant", "finite_baselines", "supervised",
           "supervision_floor", "threshold", "zone_of_observation"]


def constant(model, action: int) -> Controller:
    Z = model.shape[2]
    return Controller(np.array([action]), np.zeros((1, Z), dtype=np.int64), 0)


def threshold(model) -> Controller:
    """Node z = the last observed zone (0..3), node 4 = start (nothing observed yet)."""
    zone = zone_of_observation(model)
    return Controller(np.array([0, 0, EMERGENCY, EMERGENCY, 0]), np.tile(zone, (5, 1)), 4)


def finite_baselines(model) -> dict[str, Controller]:
    return {"threshold": threshold(model), "always_emergency": constant(model, EMERGENCY), "never": constant(model, 0)}


def supervised(ctrl: Controller, floor: np.ndarray) -> Controller:
    """The controller with the supervision in front, as one minimal finite-state controller
    (closed_chain.supervised_product, with nodes that behave alike merged)."""
    return minimise(supervised_product(ctrl, floor)[0])


class BeliefTracking:
    """Seed 000 eq. 14 for many trains at once: b' ~ (b T[a]) * O[a, :, o], demand = the
    action of the best alpha vector. `step` has the signature of fastcore.TablePolicy, so
    the vectorised monitor runs it behind the same supervision; it predicts with the demand
    the monitor really sent (after supervision and latch), which is what moved the train."""

    def __init__(self, model, alphas: np.ndarray, actions: np.ndarray, n: int):
        self.T, self.O = np.asarray(model.T), np.asarray(model.O)
        self.alphas, self.actions = np.asarray(alphas), np.asarray(actions, dtype=np.int64)
        self.b = np.tile(np.asarray(model.b0, dtype=float), (n, 1))
        self.started = False

    def step(self, obs: np.ndarray, applied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b = self.b
        a = np.asarray(applied, dtype=np.int64)
        if self.started:
            pred = np.empty_like(b)
            for act in np.unique(a):
                rows = a == act
                pred[rows] = b[rows] @ self.T[act]
            b = pred
        self.started = True
        post = b * self.O[a, :, obs]
        norm = post.sum(axis=1, keepdims=True)
        self.b = np.where(norm > 0, post / np.where(norm > 0, norm, 1.0), b)
        best = np.argmax(self.b @ self.alphas.T, axis=1)
        return self.actions[best], best
