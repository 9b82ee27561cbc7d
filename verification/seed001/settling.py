"""Where the m2 table settles when one observation repeats from its start node, by eq. 11's
risk (`settled_actions`), and what the solver's own alpha-vector policy does on the exact
belief after the same observations (`belief_policy_settled`): the section's explanation of
the table's choices.
"""
from __future__ import annotations

from importlib import resources
from typing import Optional

import numpy as np

from monitor.offline.pipeline import ALPHAS_SUFFIX, read_alphas

from .metrics import N_STATES, STATE_RISK


SETTLE_CYCLES = 30


def settled_actions(setup, cycles: Optional[int] = None) -> dict:
    """Where the table settles when one observation repeats (from the start node), by risk."""
    cycles = SETTLE_CYCLES if cycles is None else cycles
    action, nxt = np.asarray(setup.action), np.asarray(setup.next)
    node = np.full(N_STATES, setup.table.start)
    obs = np.arange(N_STATES)
    for _ in range(cycles):
        node = nxt[node, obs]
    act = action[node]
    names = setup.table.observations
    high = STATE_RISK >= 3
    low = STATE_RISK == 1
    hm = np.flatnonzero(high & (act == 0))
    lb = np.flatnonzero(low & (act > 0))
    return {"high_total": int(high.sum()), "high_maintain": int(hm.size), "low_total": int(low.sum()),
            "low_brake": int(lb.size), "high_maintain_examples": [names[i] for i in hm[:3]],
            "low_brake_examples": [names[i] for i in lb[:3]], "actions": act}


def belief_policy_settled(setup, model, cycles: Optional[int] = None) -> Optional[np.ndarray]:
    """The solver's own policy (its alpha vectors, seed 000 eq. 14) on the exact belief after the
    same repeated observations as settled_actions; None if the table ships no alpha vectors."""
    cycles = SETTLE_CYCLES if cycles is None else cycles
    try:
        with resources.as_file(resources.files("monitor.tables").joinpath("m2" + ALPHAS_SUFFIX)) as path:
            alphas, actions = read_alphas(path, setup.table.sha256)
    except (OSError, ValueError, KeyError):
        return None
    b = np.tile(model.b0, (N_STATES, 1))
    act = np.zeros(N_STATES, dtype=np.int64)
    like = np.asarray(model.O[0]).T                      # row i: P(observation i | s)
    for k in range(cycles):
        if k:
            b = np.stack([b[i] @ model.T[act[i]] for i in range(N_STATES)])
        b = b * like
        b /= b.sum(axis=1, keepdims=True)
        act = np.asarray(actions)[np.argmax(b @ np.asarray(alphas).T, axis=1)]
    return act
