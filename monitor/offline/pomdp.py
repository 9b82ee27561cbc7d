"""The discrete POMDP value type every offline step works on.

Validated once on construction so that solvers, file writers and compilers can
trust shapes and probabilities without re-checking them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

ROW_TOLERANCE = 1e-9


class ModelError(ValueError):
    """A model that is not a valid discrete POMDP; the message names the bad part."""


@dataclass(frozen=True, eq=False)
class POMDP:
    """States, actions, observations and the arrays that tie them together.

    T[a, s, s'] = P(s' | s, a); O[a, s', o] = P(o | s', a); R[s, a] the expected
    immediate reward; b0 the start belief. Arrays are float64 and read-only.
    """

    name: str
    states: tuple[str, ...]
    actions: tuple[str, ...]
    observations: tuple[str, ...]
    T: np.ndarray
    O: np.ndarray
    R: np.ndarray
    discount: float
    b0: np.ndarray
    params: Mapping[str, Any] = field(default_factory=dict)
    # Cost of each lowering of the action (actions ordered by strength: hysteresis that
    # never delays an onset). A controller remembers its action in its node, so compiling
    # and evaluating it charge the cost; belief-point backups do not see it, which keeps
    # their upper bound an upper bound.
    release_cost: float = 0.0

    def __post_init__(self) -> None:
        for label in ("states", "actions", "observations"):
            names = tuple(str(n) for n in getattr(self, label))
            if not names:
                raise ModelError(f"{self.name}: no {label}")
            if len(set(names)) != len(names):
                dup = sorted({n for n in names if names.count(n) > 1})
                raise ModelError(f"{self.name}: duplicate {label} names {dup}")
            object.__setattr__(self, label, names)
        S, A, Z = len(self.states), len(self.actions), len(self.observations)
        arrays = {
            "T": (self.T, (A, S, S)),
            "O": (self.O, (A, S, Z)),
            "R": (self.R, (S, A)),
            "b0": (self.b0, (S,)),
        }
        for label, (value, shape) in arrays.items():
            arr = np.array(value, dtype=np.float64, copy=True)
            if arr.shape != shape:
                raise ModelError(f"{self.name}: {label} has shape {arr.shape}, expected {shape}")
            if not np.all(np.isfinite(arr)):
                idx = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
                raise ModelError(f"{self.name}: {label}{list(idx)} is not a finite number")
            arr.setflags(write=False)
            object.__setattr__(self, label, arr)
        d = float(self.discount)
        if not (0.0 <= d < 1.0):
            raise ModelError(f"{self.name}: discount {d} outside [0, 1)")
        object.__setattr__(self, "discount", d)
        c = float(self.release_cost)
        if not (c >= 0.0 and np.isfinite(c)):
            raise ModelError(f"{self.name}: release_cost {c} must be a finite number >= 0")
        object.__setattr__(self, "release_cost", c)
        self._check_stochastic(self.T, "T", lambda a, s: f"T[{self.actions[a]}, {self.states[s]}, :]")
        self._check_stochastic(self.O, "O", lambda a, s: f"O[{self.actions[a]}, {self.states[s]}, :]")
        self._check_stochastic(self.b0[None, None, :], "start", lambda a, s: "start belief")
        object.__setattr__(self, "params", dict(self.params))

    def _check_stochastic(self, arr: np.ndarray, label: str, where) -> None:
        neg = np.argwhere(arr < 0)
        if len(neg):
            a, s, _ = (int(i) for i in neg[0])
            raise ModelError(f"{self.name}: {where(a, s)} has a negative probability")
        sums = arr.sum(axis=-1)
        bad = np.argwhere(np.abs(sums - 1.0) > ROW_TOLERANCE)
        if len(bad):
            a, s = (int(i) for i in bad[0])
            raise ModelError(
                f"{self.name}: {where(a, s)} sums to {sums[a, s]:.12g}, not 1 (tolerance {ROW_TOLERANCE:g})"
            )

    @property
    def shape(self) -> tuple[int, int, int]:
        """(states, actions, observations)."""
        return len(self.states), len(self.actions), len(self.observations)

    def belief_update(self, b: np.ndarray, a: int, o: int) -> tuple[np.ndarray, float]:
        """Bayes filter (seed 000 eq. 14): the successor belief and P(o | b, a)."""
        unnorm = (b @ self.T[a]) * self.O[a, :, o]
        p = float(unnorm.sum())
        if p <= 0.0:
            return b.copy(), 0.0
        return unnorm / p, p


def normalise_rows(arr: np.ndarray) -> np.ndarray:
    """Divide the last axis by its sum; builders use it to remove rounding drift."""
    arr = np.asarray(arr, dtype=np.float64)
    return arr / arr.sum(axis=-1, keepdims=True)


def uniform(n: int) -> np.ndarray:
    return np.full(n, 1.0 / n)


def index_of(names: Sequence[str], name: str, what: str) -> int:
    """Index of a name, with an error that lists the valid ones."""
    try:
        return list(names).index(name)
    except ValueError:
        raise ModelError(f"unknown {what} {name!r}; known: {', '.join(names)}") from None
