"""The release cost made part of the model: the last demand in the state.

A controller remembers its demand in its node, so compiling and evaluating charge the
release cost (controller.rewards) without it in the model; but then the solver's bounds
do not see it, and the gap they print is to a problem the table does not solve. With the
last demand in the state, state (s, p) and reward R(s, a) less the release cost when a < p,
the optimum is the optimum over controllers that pay the release cost, and every table of
the original model is a table of this one with the same exact value.
"""
from __future__ import annotations

import numpy as np

from .pomdp import POMDP


def with_last_demand(model: POMDP) -> POMDP:
    """The model with the last action (actions ordered by strength) in the state; it starts
    as if the last demand were the weakest, as a controller's first step pays no release."""
    S, A, _ = model.shape
    T = np.zeros((A, A * S, A * S))
    R = np.zeros((A * S, A))
    for p in range(A):
        rows = slice(p * S, (p + 1) * S)
        for a in range(A):
            T[a, rows, a * S:(a + 1) * S] = model.T[a]
            R[rows, a] = model.R[:, a] - (model.release_cost if a < p else 0.0)
    O = np.tile(model.O, (1, A, 1))                       # the observation does not depend on p
    b0 = np.concatenate([model.b0, np.zeros((A - 1) * S)])
    states = tuple(f"{s}|{model.actions[p]}" for p in range(A) for s in model.states)
    return POMDP(model.name, states, model.actions, model.observations, T, O, R, model.discount, b0, model.params)
