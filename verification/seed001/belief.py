"""The paper's "risk estimated from the belief state": `BeliefFilter`, a Bayes filter over
Model 2's 144 states for many trains at once, with the transition factorised into its
(distance, speed, obstacle) and (track, brake) parts (checked to rebuild T exactly).
"""
from __future__ import annotations

import numpy as np

from .metrics import N_STATES


class BeliefFilter:
    """Bayes filter b' ~ (b T[a]) * O[:, o] over Model 2's 144 states, for many trains.

    Model 2's transition factorises: (distance, speed, obstacle) moves given the action and
    (track, brake), and (track, brake) moves on its own, so T[a] = W[a, j] (x -> x') times
    E[a] (j -> j'), with x the first three components and j = (track, brake). The factors
    are read off T and the product is checked to rebuild T; the update then costs a quarter
    of the dense one. Beliefs are kept as b[j, train, x].
    """

    def __init__(self, model, n: int, chunk: int = 128):
        T = np.asarray(model.T)
        T5 = T.reshape(3, 36, 4, 36, 4)                                    # a, x, j, x', j'
        self.W = np.ascontiguousarray(T5.sum(axis=4).transpose(0, 2, 1, 3))   # a, j, x, x'
        self.E = np.ascontiguousarray(T5.sum(axis=3)[:, 0])                 # a, j, j'
        rebuilt = np.einsum("ajxy,ajk->axjyk", self.W, self.E).reshape(T.shape)
        self.error = float(np.abs(rebuilt - T).max())
        if self.error > 1e-12:
            raise RuntimeError(f"Model 2's transition does not factorise (error {self.error:.1e})")
        like = np.asarray(model.O[0])                                       # O[s, o]
        self.like = np.ascontiguousarray(like.T.reshape(-1, 36, 4).transpose(0, 2, 1))   # o, j, x
        self.b = np.ascontiguousarray(np.tile(np.asarray(model.b0).reshape(36, 4).T[:, None, :], (1, n, 1)))
        self.n, self.chunk, self.started = n, chunk, False

    def step(self, action: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """Predict with the previous action (not before the first observation), correct with
        this observation; returns the most probable state of each train."""
        b = self.b
        if self.started:
            for c0 in range(0, self.n, self.chunk):
                sl = slice(c0, c0 + self.chunk)
                block, act = b[:, sl], action[sl]
                out = np.empty_like(block)
                for a in range(3):
                    m = act == a
                    if m.any():
                        y = np.matmul(block[:, m], self.W[a])               # j, train, x'
                        out[:, m] = np.tensordot(self.E[a], y, axes=([0], [0]))
                b[:, sl] = out
        self.started = True
        b *= self.like[obs].transpose(1, 0, 2)
        b /= b.sum(axis=(0, 2))[None, :, None]
        b[b < 1e-30] = 0.0        # no subnormal numbers: they slow the products down tenfold
        flat = b.transpose(1, 2, 0).reshape(self.n, N_STATES)               # state = x * 4 + j
        return np.argmax(flat, axis=1)
