"""The lower bound of HSVI: alpha vectors with their actions, witnesses and policy-graph nodes.

Kept in its own module so that the mixed-observability variant (momdp.py) can extend it
without the solver importing itself.
"""
from __future__ import annotations

import numpy as np

from .bounds import Dynamics, lower_backup
from .policy_graph import PolicyGraph


class LowerBound:
    """Alpha vectors with actions, witnesses and their nodes in the policy graph (the blind
    vectors' nodes stay in place), in growable arrays."""

    def __init__(self, alphas: np.ndarray, actions: np.ndarray, witnesses: np.ndarray, observations: int):
        self.n = len(alphas)
        cap = max(64, 2 * self.n)
        S = alphas.shape[1]
        self._a = np.zeros((cap, S)); self._a[: self.n] = alphas
        self._w = np.zeros((cap, S)); self._w[: self.n] = witnesses
        self._act = np.zeros(cap, dtype=np.int64); self._act[: self.n] = actions
        self.graph = PolicyGraph(observations, S)
        self._node = np.zeros(cap, dtype=np.int64)
        self._node[: self.n] = [self.graph.add(int(a), None, v, w) for a, v, w in zip(actions, alphas, witnesses)]

    @property
    def nodes(self) -> np.ndarray:
        return self._node[: self.n]

    @property
    def alphas(self) -> np.ndarray:
        return self._a[: self.n]

    @property
    def actions(self) -> np.ndarray:
        return self._act[: self.n]

    @property
    def witnesses(self) -> np.ndarray:
        return self._w[: self.n]

    def value(self, b: np.ndarray) -> float:
        return float((self.alphas @ b).max())

    def add(self, vec: np.ndarray, action: int, witness: np.ndarray, pick: np.ndarray) -> None:
        """A backed-up vector; `pick` (Z,) the vectors (indices now) its backup chose."""
        if self.n == len(self._a):
            self._a = np.vstack([self._a, np.zeros_like(self._a)])
            self._w = np.vstack([self._w, np.zeros_like(self._w)])
            self._act = np.concatenate([self._act, np.zeros_like(self._act)])
            self._node = np.concatenate([self._node, np.zeros_like(self._node)])
        self._a[self.n], self._act[self.n], self._w[self.n] = vec, action, witness
        self._node[self.n] = self.graph.add(action, self.nodes[pick], vec, witness)
        self.n += 1

    def prune(self, points: np.ndarray) -> int:
        """Keep the vectors that are best at some point (b0, upper-bound beliefs, witnesses)."""
        X = np.vstack([points, self.witnesses])
        best = np.unique((X @ self.alphas.T).argmax(axis=1))
        dropped = self.n - len(best)
        if dropped:
            a, w, act, node = self.alphas[best], self.witnesses[best], self.actions[best], self.nodes[best]
            self.n = len(best)
            self._a[: self.n], self._w[: self.n], self._act[: self.n], self._node[: self.n] = a, w, act, node
        return dropped

    def joints(self, dyn: Dynamics, b: np.ndarray) -> list:
        """u[a][o, s'] = P(s', o | b, a) for every action."""
        return [dyn.joint(b, a) for a in range(dyn.A)]

    def backup(self, dyn: Dynamics, b: np.ndarray, joints: list):
        """The point-based backup at b (bounds.lower_backup over every vector)."""
        return lower_backup(dyn, self.alphas, b, joints)
