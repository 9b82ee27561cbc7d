"""The table's own risk: for every node, P(hazard within the horizon | the monitor is in it).

Computed offline from the exact closed loop of the model the table was solved for, with the
braking curves' supervision in front (closed_chain), so the online core carries it at no
cost: one array read per cycle.

- **Horizon**: HORIZON_S (30 s, the horizon of `railguard evaluate` and of the closed-loop
  figures), in cycles of the model's time step.
- **Reach**: x(n, f, s) = P(hazard within the horizon | the cycle starts in supervised node
  (n, f), world state s), by bounded reachability on the two-phase chain.
- **Weighting** (what "given the monitor is in node n" averages over): the expected number
  of cycles spent in (n, f, s) by a train run from the start node and the model's start
  belief for WINDOW_S (300 s, the quick world's train run). That is how the worlds of
  `railguard verify` visit the table, so the column can be checked against them
  (calibration). The long-run occupation was measured and rejected: Model 2's chain mixes
  so slowly (track and brake conditions persist) that 20,000 power iterations (600 s) did
  not converge and a sparse LU of the 69,120-state system did not finish in 600 s; its
  answer would also weight the conditions by where they drift, not by the start belief.
- **Never visited in the window**: the largest reach over the node's states (the safe side:
  a node the model does not predict still names the worst it could lead to).

risk_ppm(n) = round(10^6 * sum_{f,s} occ x / sum_{f,s} occ), an integer in [0, 10^6].
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from .closed_chain import bounded_reach, hazard_states, hazard_target, supervised_product, supervision_floor, two_phase_chain
from .controller import Controller

HORIZON_S = 30.0
WINDOW_S = 300.0
PPM = 1_000_000


def describe(model, time_step_s: float) -> dict:
    """The header entry that says what the column means (covered by the table's SHA-256)."""
    return {
        "unit": "ppm",
        "horizon_s": HORIZON_S,
        "hazard": [model.states[i] for i in hazard_states(model)],
        "weighting": f"occupation of a train run for {WINDOW_S:g} s from the start node and belief",
        "supervised": "the braking curves' floor in front (emergency in the critical zone)",
        "cycles": int(round(HORIZON_S / time_step_s)),
    }


@dataclass(frozen=True)
class NodeRisk:
    """What the closed loop says about each table node."""

    ppm: np.ndarray          # (N,) int64: the risk column
    occupation: np.ndarray   # (N,) share of the window's cycles spent in each node
    successors: np.ndarray   # (N, N) P(next node = m | node n), rows of visited nodes sum to 1


def analyse(model, ctrl: Controller, time_step_s: float, progress: Optional[Callable[[str], None]] = None) -> NodeRisk:
    """Each table node's risk (module docstring), occupation and successor probabilities."""
    say = progress or (lambda text: None)
    S = model.shape[0]
    N = ctrl.nodes
    sup, table_node = supervised_product(ctrl, supervision_floor(model))
    NS = sup.nodes * S
    P = two_phase_chain(model, sup)
    steps = int(round(HORIZON_S / time_step_s))
    window = int(round(WINDOW_S / time_step_s))
    say(f"risk column: P(hazard within {HORIZON_S:g} s) from each node, {steps} cycles")
    reach = bounded_reach(P, hazard_target(model, sup.nodes), 2 * steps)[:NS]
    say(f"risk column: where a train run from the start spends {window} cycles")
    move, read = P[:NS, NS:].T.tocsr(), P[NS:, :NS]
    read_t = read.T.tocsr()
    x = np.zeros(NS)
    x[sup.start * S:(sup.start + 1) * S] = model.b0
    occ = np.zeros(NS)
    for _ in range(window):
        occ += x
        x = read_t @ (move @ x)
    of_state = np.repeat(table_node, S)                       # table node of each A (and B) state
    mass = np.bincount(of_state, weights=occ, minlength=N)
    hits = np.bincount(of_state, weights=occ * reach, minlength=N)
    worst = np.zeros(N)
    np.maximum.at(worst, of_state, reach)
    p = np.where(mass > 0, hits / np.where(mass > 0, mass, 1.0), worst)
    # flow n -> m: the occupation moved by the world (B keeps the source node), then read
    moved = move @ occ
    to_node = sp.csr_matrix((np.ones(NS), (np.arange(NS), of_state)), shape=(NS, N))
    from_node = sp.csr_matrix((moved, (of_state, np.arange(NS))), shape=(N, NS))
    flow = (from_node @ read @ to_node).toarray()
    out = flow.sum(axis=1, keepdims=True)
    succ = np.divide(flow, out, out=np.zeros_like(flow), where=out > 0)
    return NodeRisk(np.rint(np.clip(p, 0.0, 1.0) * PPM).astype(np.int64), mass / max(mass.sum(), 1e-300), succ)


def node_risk(model, ctrl: Controller, time_step_s: float,
              progress: Optional[Callable[[str], None]] = None) -> np.ndarray:
    """(N,) int64: each table node's risk in ppm (module docstring)."""
    return analyse(model, ctrl, time_step_s, progress).ppm
