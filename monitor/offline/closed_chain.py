"""A controller and its model in closed loop, as a Markov chain, with the braking curves'
supervision in front.

The chain has two transitions per cycle: A(n, s) -> B(n, s') with T[a_n, s, s'] (the world
moves), then B(n, s') -> A(m, s') with the probability that an observation leads node n to
m (the controller reads). The same process as controller.closed_loop_matrix with far fewer
transitions (Model 2: 2.2 million instead of 25 million per cycle), which is what makes
bounded reachability and occupations over hundreds of cycles affordable.

The supervision in front of a table (docs/supervision.md) is a floor on the action, a
function of the observation: the model's critical zone is "inside EBI under normal
conditions", so the curves demand emergency there whatever the table says. Both
verification (the closed-loop figures, `railguard evaluate`) and the solver (the risk column
of a table, node_risk) read the loop from here.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .controller import Controller

EMERGENCY = 2


def hazard_states(model) -> np.ndarray:
    """Indices of the states the hazard probability is about: Model 1's Crash, otherwise
    every state at the critical distance level (Model 2's first component)."""
    if "Crash" in model.states:
        return np.array([model.states.index("Crash")])
    return np.array([i for i, s in enumerate(model.states) if s.startswith("critical")], dtype=np.int64)


def zone_of_observation(model) -> np.ndarray:
    """Zone (0 free/far .. 3 critical) of each observation: Model 1 observes the zone,
    Model 2's distance level is the first component (observations in product order)."""
    Z = model.shape[2]
    if model.name == "m1" or Z == 4:
        return np.arange(Z)
    if Z % 4:
        return np.zeros(Z, dtype=np.int64)           # not one of the papers' models: no zones
    return np.arange(Z) // (Z // 4)


def supervision_floor(model) -> np.ndarray:
    """The least demand the braking curves add after each observation: emergency in the
    critical zone (inside EBI), nothing elsewhere."""
    return np.where(zone_of_observation(model) == 3, EMERGENCY, 0).astype(np.int64)


def supervised_product(ctrl: Controller, floor: np.ndarray) -> tuple[Controller, np.ndarray]:
    """(the controller with the supervision in front, the table node of each of its nodes).

    Node (m, f) = table node m after an observation whose floor is f; it demands
    max(action[m], f). The start has no observation yet (floor 0). Not minimised, so that
    each node still names the table node the monitor is in."""
    levels = np.unique(np.r_[0, floor])
    F = len(levels)
    fidx = np.searchsorted(levels, floor)
    N = ctrl.nodes
    action = np.maximum(np.repeat(ctrl.action, F), np.tile(levels, N))
    nxt = ctrl.next[:, None, :] * F + fidx[None, None, :]                  # (N, 1, Z) -> same for every f
    nxt = np.repeat(nxt, F, axis=1).reshape(N * F, -1)
    return Controller(action.astype(np.int64), nxt.astype(np.int64), ctrl.start * F), np.repeat(np.arange(N), F)


def two_phase_chain(model, ctrl: Controller) -> sp.csr_matrix:
    """The closed loop as the two-phase chain of the module's docstring; A states are
    n * S + s, B states NS + n * S + s."""
    S = model.shape[0]
    N = ctrl.nodes
    NS = N * S
    rows, cols, vals = [], [], []
    for n in range(N):
        a = int(ctrl.action[n])
        s_i, t_i = np.nonzero(model.T[a])
        rows.append(n * S + s_i)
        cols.append(NS + n * S + t_i)
        vals.append(model.T[a][s_i, t_i])
        W = np.zeros((S, N))              # W[s', m] = sum of O[a, s', o] over o with next[n, o] == m
        np.add.at(W.T, ctrl.next[n], model.O[a].T)
        t_j, m_j = np.nonzero(W)
        rows.append(NS + n * S + t_j)
        cols.append(m_j * S + t_j)
        vals.append(W[t_j, m_j])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * NS, 2 * NS))


def hazard_target(model, nodes: int) -> np.ndarray:
    """(2 N S,) bool: the A states (a cycle's start) whose model state is a hazard state."""
    S = model.shape[0]
    NS = nodes * S
    target = np.zeros(2 * NS, dtype=bool)
    for s in hazard_states(model):
        target[s:NS:S] = True
    return target


def bounded_reach(P: sp.csr_matrix, target: np.ndarray, steps: int) -> np.ndarray:
    """x[i] = P(reach target within `steps` transitions from i): x_{k+1} = 1 on target, P x_k elsewhere."""
    x = target.astype(np.float64)
    for _ in range(steps):
        x = P @ x
        x[target] = 1.0
    return x
