"""The fully observed part of a POMDP, found from its arrays: a partition of the states into
blocks such that, once the belief is inside one block, the action and the observation say
which block the next state is in (the x of a mixed-observability MOMDP, Ong et al. 2010, as
SARSOP uses it: Tag's robot cell, RockSample's robot position).

The partition is the finest one with two closure properties: (1) for every action a and
observation o, the states that can follow the start belief's support under (a, o) lie in one
block; (2) the same for every block in place of the start support. By induction every belief
after the first observation then lies inside one block. It is found from singletons by
merging what (1) and (2) force: every forced merge is also forced in any partition with the
two properties, so the fixed point is the finest one. A model whose observations never pin
the block (Tiger, railguard's m2) comes out as one block, and the solver then runs as before.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .pomdp import POMDP

MIXED = -1      # block id of a belief whose support spans several blocks (the start belief)


class Blocks:
    """of_state[s] the block of state s; members[k] the states of block k (sorted); after
    `link`, following[x, a, o] the block of the next state from block x under (a, o)."""

    following: np.ndarray | None = None

    def __init__(self, of_state: np.ndarray):
        _, self.of_state = np.unique(np.asarray(of_state), return_inverse=True)
        self.count = int(self.of_state.max()) + 1 if len(self.of_state) else 0
        order = np.argsort(self.of_state, kind="stable")
        cuts = np.cumsum(np.bincount(self.of_state, minlength=self.count))[:-1]
        self.members = np.split(order, cuts)
        self.order = order                                       # states block by block
        self.start = np.concatenate([[0], cuts, [len(order)]]).astype(np.int64)   # block x: order[start[x]:start[x + 1]]

    def of(self, b: np.ndarray) -> int:
        """The block holding the support of b, or MIXED."""
        labels = self.of_state[np.flatnonzero(b)]
        if len(labels) == 0:
            return MIXED
        first = labels[0]
        return int(first) if np.all(labels == first) else MIXED

    def of_rows(self, U: np.ndarray) -> np.ndarray:
        """The block of each row of U (MIXED for a row over several blocks or an empty row)."""
        nz = U != 0
        lab = np.where(nz, self.of_state[None, :], self.count)
        lo = lab.min(axis=1)
        hi = np.where(nz, self.of_state[None, :], -1).max(axis=1)
        return np.where((lo == hi) & (lo < self.count), lo, MIXED)


    def link(self, model: POMDP) -> "Blocks":
        """Tabulate following[x, a, o] (-1 where o cannot follow block x under a): the partition
        guarantees one block, read off as (sum of the blocks) / (number of states)."""
        S, A, Z = model.shape
        member = sp.csr_matrix((np.ones(S, dtype=np.int64), (self.of_state, np.arange(S))), shape=(self.count, S))
        out = np.full((self.count, A, Z), MIXED, dtype=np.int64)
        for a in range(A):
            reach = ((member @ sp.csr_matrix(model.T[a] > 0, dtype=np.int64)) > 0).astype(np.int64)
            E = sp.csr_matrix(model.O[a] > 0, dtype=np.int64)
            n = np.asarray((reach @ E).todense())
            total = np.asarray((reach @ E.multiply(self.of_state[:, None]).tocsr()).todense())
            out[:, a, :] = np.where(n > 0, total // np.maximum(n, 1), MIXED)
        self.following = out
        self.possible = [[np.flatnonzero(out[x, a] >= 0) for a in range(A)] for x in range(self.count)]
        return self


def _forced_edges(groups: np.ndarray, T: sp.csr_matrix, O: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """Edges state -- key (group, o) of one action, keys numbered after the states: two states
    joined through a key can both follow a state of that group under that observation (so they
    must share a block). groups[s] is s's group, -1 for none."""
    S, Z = O.shape
    G = int(groups.max()) + 1
    rows = np.flatnonzero(groups >= 0)
    member = sp.csr_matrix((np.ones(len(rows)), (groups[rows], rows)), shape=(G, S))
    g, dst = (member @ T).nonzero()                             # distinct (group, next state) pairs
    per = np.diff(O.indptr)[dst]                                # observations each next state can emit
    within = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    obs = O.indices[np.repeat(O.indptr[dst], per) + within]
    return np.repeat(dst, per), S + np.repeat(g, per) * Z + obs


def find_blocks(model: POMDP) -> Blocks:
    """The finest partition with the closure properties above: forced merges, one action at a
    time, until a pass over the actions merges nothing (or everything is one block)."""
    S, A, Z = model.shape
    T = [sp.csr_matrix(model.T[a] > 0, dtype=np.float64) for a in range(A)]
    O = [sp.csr_matrix(model.O[a] > 0) for a in range(A)]
    label = np.arange(S)
    start = np.where(model.b0 > 0, 0, -1)      # property (1) first: it often merges the most
    while True:
        changed = False
        for a in range(A):
            groups = start if start is not None else label
            i, j = _forced_edges(groups, T[a], O[a])
            n_nodes = S + (int(groups.max()) + 1) * Z
            first = np.unique(label, return_index=True)[1][label]          # keep each block together
            graph = sp.coo_matrix((np.ones(len(i) + S), (np.concatenate([i, np.arange(S)]), np.concatenate([j, first]))),
                                  shape=(n_nodes, n_nodes))
            _, comp = connected_components(graph, directed=False)
            new = np.unique(comp[:S], return_inverse=True)[1]
            changed |= new.max() != label.max()
            label = new
            if label.max() == 0:
                return Blocks(label).link(model)
        if start is None and not changed:
            return Blocks(label).link(model)
        start = None
