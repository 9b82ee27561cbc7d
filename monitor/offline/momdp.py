"""Both bounds of HSVI split by the model's fully observed part (blocks.py), as SARSOP's
MOMDP representation does: the costly products run over one block's states and vectors.

A belief after the first observation lies in one block X. The lower bound's products at such
a belief run over X's states only; its max still runs over every vector (keeping one set per
block, SARSOP's alpha_x(y), lost bound: Tag at 60 trials -7.015 against -6.678, a vector
backed up in another block being the best choice at 351 of 1,325 successor rows). Every
stored vector is a full-length backup, a valid lower bound in every state (policy_graph.py's
argument is unchanged), and Solution.alphas keeps them all.

The sawtooth needs no such argument: a point b_i outside b's block has a zero ratio
min b(s) / b_i(s), so it never counts at b; evaluating a belief against its own block's
points gives exactly the value of the whole set. Beliefs over several blocks (the start
belief) are valued against everything, as before.
"""
from __future__ import annotations

import numpy as np

from .blocks import MIXED, Blocks
from .bounds import Dynamics, UpperBound
from .lower_bound import LowerBound


def joint(dyn: Dynamics, blocks: Blocks, b: np.ndarray, x: int, a: int) -> np.ndarray:
    """Dynamics.joint for a belief in block x: only the observations that can follow x
    under a get a row product (the others are zero there anyway)."""
    if x == MIXED:
        return dyn.joint(b, a)
    poss = blocks.possible[x][a]
    U = np.zeros((dyn.Z, dyn.S))
    U[poss] = dyn.predict(b, a)[None, :] * dyn.OT[a][poss]
    return U


def successor_blocks(blocks: Blocks, x: int, a: int, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the non-empty rows of U = the joint of a belief in block x under a, their blocks):
    read from the table when x is one block, found from the rows for a mixed belief."""
    if x == MIXED:
        live = np.flatnonzero(U.any(axis=1))
        return live, blocks.of_rows(U[live])
    poss = blocks.possible[x][a]
    live = poss[U[poss].any(axis=1)]
    return live, blocks.following[x, a, live]


class BlockLowerBound(LowerBound):
    """LowerBound that values a belief inside one block over that block's states only.

    The vectors are also kept with their states in block order, so that block x's part of
    every vector is one slice; the max runs over all vectors, so values and choices are the
    plain LowerBound's (the products only skip states where the belief is zero)."""

    def __init__(self, alphas, actions, witnesses, observations: int, blocks: Blocks):
        super().__init__(alphas, actions, witnesses, observations)
        self.blocks = blocks
        self._index()

    def _index(self) -> None:
        """(Re)build the block-ordered copy of the vectors (after a prune)."""
        self._p = np.zeros_like(self._a)
        self._p[: self.n] = self._a[: self.n][:, self.blocks.order]

    def restricted(self, x: int) -> np.ndarray:
        """(n, |x|): every vector on block x's states."""
        return self._p[: self.n, self.blocks.start[x]:self.blocks.start[x + 1]]

    def value(self, b: np.ndarray) -> float:
        x = self.blocks.of(b)
        if x == MIXED:
            return super().value(b)
        return float((self.restricted(x) @ b[self.blocks.members[x]]).max())

    def add(self, vec, action, witness, pick) -> None:
        super().add(vec, action, witness, pick)
        if len(self._p) < len(self._a):
            self._p = np.vstack([self._p, np.zeros((len(self._a) - len(self._p), self._a.shape[1]))])
        self._p[self.n - 1] = vec[self.blocks.order]

    def best(self, U: np.ndarray, live: np.ndarray, lab: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For rows U[o] = p(o) b_o (`live` the non-empty ones, `lab` their blocks): the index
        of the best vector at each row (0 for an empty row, as bounds.lower_backup) and its
        value p(o) V_lower(b_o)."""
        pick = np.zeros(len(U), dtype=np.int64)
        score = np.zeros(len(U))
        for o, x in zip(live.tolist(), lab.tolist()):
            s = self.alphas @ U[o] if x == MIXED else self.restricted(x) @ U[o, self.blocks.members[x]]
            j = int(s.argmax())
            pick[o], score[o] = j, s[j]
        return pick, score

    def joints(self, dyn: Dynamics, b: np.ndarray) -> list:
        x = self.blocks.of(b)
        return [joint(dyn, self.blocks, b, x, a) for a in range(dyn.A)]

    def _row_sums(self, dyn: Dynamics) -> np.ndarray:
        """(A, S) sum_o O[a, s, o]: 1 to within the model's tolerance, kept exact here."""
        if getattr(self, "_osum", None) is None:
            self._osum = np.stack([o.sum(axis=1) for o in dyn.O])
        return self._osum

    def backup(self, dyn: Dynamics, b: np.ndarray, joints: list):
        """bounds.lower_backup with the products over each successor's block."""
        best = (None, -1, -np.inf, None)
        lj = []
        x = self.blocks.of(b)
        for a in range(dyn.A):
            U = joints[a]
            live, lab = successor_blocks(self.blocks, x, a, U)
            pick, score = self.best(U, live, lab)
            lj.append(score)
            # sum_o O[a, :, o] alpha_{pick[o]}: every empty row picks vector 0, so only the
            # live columns need a product of their own
            Ol = dyn.O[a][:, live]
            rest = np.maximum(0.0, self._row_sums(dyn)[a] - Ol.sum(axis=1))
            W = (Ol * self.alphas[pick[live]].T).sum(axis=1) + self.alphas[0] * rest
            vec = dyn.R[a] + dyn.g * dyn.back(a, W)
            val = float(b @ vec)
            if val >= best[2] - 1e-12 * max(1.0, abs(best[2])):
                best = (vec, a, val, pick)
        return best[0], best[1], best[2], lj, best[3]

    def prune(self, points: np.ndarray) -> int:
        dropped = super().prune(points)
        if dropped:
            self._index()
        return dropped


class BlockUpperBound:
    """UpperBound's interface with one point store per block (and one for mixed points),
    all sharing the corner values. `merged()` gives the plain UpperBound of all points."""

    def __init__(self, fib_q: np.ndarray, blocks: Blocks):
        self.blocks = blocks
        self.mixed = UpperBound(fib_q)
        self.fib_q, self.corner, self.S = self.mixed.fib_q, self.mixed.corner, self.mixed.S
        self.parts = [UpperBound(fib_q) for _ in range(blocks.count)]
        for part in self.parts:
            part.corner = self.corner                           # one array: corner updates reach all
        self.size = 0                                           # points in all stores
        self._seq = [[] for _ in range(blocks.count + 1)]       # insertion order, store by store
        self._next = 0

    def _store(self, x: int) -> UpperBound:
        return self.mixed if x == MIXED else self.parts[x]

    def _all(self) -> list:
        """(seq, belief, value) of every point, oldest first."""
        out = []
        for store, seqs in zip([*self.parts, self.mixed], self._seq):
            out.extend(zip(seqs, store._beliefs, store._values))
        return sorted(out, key=lambda t: t[0])

    @property
    def beliefs(self) -> np.ndarray:
        pts = self._all()
        return np.array([b for _, b, _ in pts]) if pts else np.zeros((0, self.S))

    @property
    def values(self) -> np.ndarray:
        return np.array([v for _, _, v in self._all()])

    def merged(self) -> UpperBound:
        """The plain UpperBound over the same points and corners (the same values)."""
        pts = self._all()
        return self.mixed.over([b for _, b, _ in pts], [v for _, _, v in pts])

    def fib(self, B: np.ndarray) -> np.ndarray:
        return self.mixed.fib(B)

    def sawtooth(self, B: np.ndarray, lab: np.ndarray | None = None) -> np.ndarray:
        """The sawtooth at beliefs B (N, S) whose blocks are `lab` (found when not given)."""
        B = np.atleast_2d(B)
        if lab is None:
            lab = np.array([self.blocks.of(B[0])]) if len(B) == 1 else self.blocks.of_rows(B)
        out = B @ self.corner
        for x in (np.unique(lab) if len(lab) > 1 else lab):
            rows = np.flatnonzero(lab == x)
            stores = [self.mixed, *self.parts] if x == MIXED else [self.parts[x]]
            for store in stores:
                if store.size:
                    out[rows] = np.minimum(out[rows], store.sawtooth(B[rows]))
        return out

    def value(self, B: np.ndarray) -> np.ndarray:
        return np.minimum(self.sawtooth(B), self.fib(B))

    def backup(self, dyn: Dynamics, b: np.ndarray, sig: float = 1.0):
        """bounds.upper_backup, each successor valued against its own block's points."""
        x = self.blocks.of(b)
        q = np.empty(dyn.A)
        joints, uj = [], []
        for a in range(dyn.A):
            U = joint(dyn, self.blocks, b, x, a)
            live, lab = successor_blocks(self.blocks, x, a, U)
            v = np.zeros(len(U))
            if len(live):
                Ul = U[live]
                p = Ul.sum(axis=1)
                v[live] = np.minimum(Ul @ self.corner, (Ul @ self.fib_q.T).max(axis=1))
                keep = np.arange(len(live))
                if sig < 1.0:
                    order = np.argsort(-p, kind="stable")
                    keep = order[: int(np.searchsorted(np.cumsum(p[order]), sig * p.sum())) + 1]
                if self.size:
                    saw = p[keep] * self.sawtooth(Ul[keep] / p[keep, None], lab[keep])
                    v[live[keep]] = np.minimum(v[live[keep]], saw)
            q[a] = float(b @ dyn.R[a]) + dyn.g * float(v.sum())
            joints.append(U)
            uj.append(v)
        return q, joints, uj

    def add(self, b: np.ndarray, value: float) -> bool:
        """Store (b, value) in its block's store if it tightens the bound at b."""
        now = float(self.value(b[None, :])[0])
        if not value < now - 1e-12 * max(1.0, abs(now)):
            return False
        nz = np.flatnonzero(b)
        x = self.blocks.of(b)
        if len(nz) == 1:
            self.corner[nz[0]] = value
            for store in (self.mixed, self.parts[x]):          # the slacks that depend on it
                store._reset(store._beliefs, store._values)
        else:
            self._store(x)._append(b, value)
            self.size += 1
            self._seq[x].append(self._next)
            self._next += 1
        return True

    def prune(self) -> int:
        """Prune each store against its own points (exact for a block: no other point counts
        there; a mixed point is only compared with the mixed ones, which keeps more)."""
        dropped = 0
        for x, store in [*enumerate(self.parts), (MIXED, self.mixed)]:
            before = list(store._beliefs)
            n = store.prune()
            if n:
                kept = {id(b) for b in store._beliefs}
                self._seq[x] = [q for b, q in zip(before, self._seq[x]) if id(b) in kept]
                dropped += n
        self.size -= dropped
        return dropped
