"""Upper bounds from an information relaxation: the same model, observed better.

A relaxation keeps the states, actions, transitions, rewards, start belief and discount,
and observes more: the model's observation is the relaxed one passed through a noise
channel G that depends on neither the state nor the action (O[a] = O_R[a] @ G). Any policy
of the model then runs on the relaxation by drawing its observation from G, with the same
value, so the relaxation's optimum is at least the model's (Blackwell's garbling argument),
and any upper bound on the relaxation at the start belief bounds the model's optimum.

Why: Model 2's own sawtooth closes slowly (docs/models.md section 5); with everything but
the distance level read without error, a belief is spread over four distance levels only,
and the relaxation's sawtooth gets far lower in the same seconds. `check` proves the
garbling on the arrays themselves, so a relaxation that observes *less* is refused.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional

import numpy as np

from .pomdp import POMDP, ModelError

TOLERANCE = 1e-12


@dataclass(frozen=True)
class Relaxation:
    """`model` observes better than the base: base O[a] = model.O[a] @ garbling."""

    model: POMDP
    garbling: np.ndarray        # (Z_relaxed, Z): row o_R is P(base observation | relaxed o_R)
    label: str                  # what the relaxation reveals, for people

    def check(self, base: POMDP) -> None:
        """Raise ModelError unless this is a relaxation of `base` (same dynamics, garbled O)."""
        m, G = self.model, np.asarray(self.garbling, dtype=np.float64)
        where = f"relaxation ({self.label}) of {base.name}"
        if m.states != base.states or m.actions != base.actions:
            raise ModelError(f"{where}: states or actions differ")
        for name in ("T", "R", "b0"):
            if not np.array_equal(getattr(m, name), getattr(base, name)):
                raise ModelError(f"{where}: {name} differs")
        if m.discount != base.discount:
            raise ModelError(f"{where}: discount differs")
        if G.shape != (m.O.shape[2], base.O.shape[2]):
            raise ModelError(f"{where}: garbling has shape {G.shape}, expected {(m.O.shape[2], base.O.shape[2])}")
        if G.min() < 0 or np.abs(G.sum(axis=1) - 1.0).max() > TOLERANCE:
            raise ModelError(f"{where}: garbling rows are not probability distributions")
        worst = max(float(np.abs(m.O[a] @ G - base.O[a]).max()) for a in range(len(m.actions)))
        if worst > TOLERANCE:
            raise ModelError(f"{where}: the model's observation is not the relaxed one garbled "
                             f"(off by {worst:.3g}): it would not be an upper bound")


def describe_upper(own: float, entry: Optional[Mapping]) -> str:
    """Where a printed upper bound comes from, in words: the model's own sawtooth (`own`), or
    the relaxation recorded in a table header's `relaxation` entry where that is lower."""
    if entry is None:
        return "sawtooth upper bound at the start belief"
    if entry["upper_bound"] < own:
        return (f"information relaxation, {entry['reveals']}, {entry['iterations']} iterations; "
                f"the model's own sawtooth: {own:.4f}")
    return f"sawtooth upper bound at the start belief; the information relaxation's: {entry['upper_bound']:.4f}"
