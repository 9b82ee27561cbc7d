"""The policy graph of the point-based backups: every alpha vector the lower bound ever held,
as a controller node whose successors are the vectors its backup chose.

A backup at b makes alpha = R_a + g T_a sum_o O[a, :, o] alpha_{k(o)} for every observation o
(the chosen k(o) of an unlikely o included). The node (a, next[o] = node of k(o)) has exactly
that form with its successors' values in place of alpha_{k(o)}; the blind vectors' nodes
(always a) have exactly their vector's value. By induction every node is worth at least its
vector, in every state. The controller that starts in the node of the best vector at b0 is
therefore worth at least the lower bound there: the alpha policy, compiled without loss
(Hansen 1998; SARSOP's and APPL's policy graph output). The vectors pruned from the lower
bound stay in the graph while a kept node leads to them.
"""
from __future__ import annotations

import numpy as np


class PolicyGraph:
    """Nodes in growable arrays: action[i], next[i, o] (node ids), and each node's alpha
    vector (a lower bound on its value, state by state) and witness belief."""

    def __init__(self, observations: int, states: int):
        self.Z = observations
        self.n = 0
        self._act = np.zeros(64, dtype=np.int64)
        self._next = np.zeros((64, observations), dtype=np.int64)
        self._vec = np.zeros((64, states))
        self._wit = np.zeros((64, states))

    def add(self, action: int, successors: np.ndarray | None, vector: np.ndarray, witness: np.ndarray) -> int:
        """A node; `successors` (Z,) node ids, or None for a node that stays (always `action`)."""
        if self.n == len(self._act):
            self._act = np.concatenate([self._act, np.zeros_like(self._act)])
            self._next = np.vstack([self._next, np.zeros_like(self._next)])
            self._vec = np.vstack([self._vec, np.zeros_like(self._vec)])
            self._wit = np.vstack([self._wit, np.zeros_like(self._wit)])
        i = self.n
        self._act[i] = action
        self._next[i] = i if successors is None else successors
        self._vec[i], self._wit[i] = vector, witness
        self.n += 1
        return i

    def vectors(self, ids: np.ndarray) -> np.ndarray:
        """(len(ids), S) the nodes' alpha vectors: each node is worth at least its vector."""
        return self._vec[ids]

    def witnesses(self, ids: np.ndarray) -> np.ndarray:
        """(len(ids), S) the beliefs the nodes' vectors were backed up at."""
        return self._wit[ids]

    def closure(self, start: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The nodes `start` leads to, in breadth-first order: (action, next renumbered, ids)."""
        order = [int(start)]
        seen = {int(start): 0}
        i = 0
        while i < len(order):
            for m in np.unique(self._next[order[i]]):
                if int(m) not in seen:
                    seen[int(m)] = len(order)
                    order.append(int(m))
            i += 1
        ids = np.array(order, dtype=np.int64)
        remap = np.vectorize(seen.__getitem__, otypes=[np.int64])
        return self._act[ids].copy(), remap(self._next[ids]), ids
