"""The disturbance model: what can go wrong on the six channels in the WINDOW cycles after the
appearance (a common-cause blindness, misses, lost frames, ghosts, distance noise), its
nominal probabilities, a disturbance sequence, and the proposal densities the search draws
from (the nominal one among them), with the likelihoods that rank failures and weight samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .encounters import CHANNELS, NOISE_SIGMA_M


WINDOW = 100              # cycles from the appearance on in which disturbances are searched (10 s)
P_MISS = 0.04             # seed 002: p_n, a channel's probability of a false negative
BETA = 0.05               # common-cause share of misses (IEC 61508-6 annex D's beta: 1 % to 10 %)
BLIND_STAYS = 0.9         # a common-cause blindness (glare, spray) goes on to the next cycle: 1 s on average
# nominal probability per cycle: `blind` (all six channels at once, a common cause) begins,
# and then lasts with BLIND_STAYS; the others per channel, independent
DISTURBANCES = {"blind": BETA * P_MISS, "miss": (1 - BETA) * P_MISS, "drop": 0.001, "ghost": 0.001}
EXPLORE = 0.05            # the search's first proposal: a common-cause blindness begins this likely


KINDS = tuple(DISTURBANCES)
SHAPES = {"blind": (WINDOW,), "miss": (WINDOW, CHANNELS), "drop": (WINDOW, CHANNELS), "ghost": (WINDOW, CHANNELS)}


@dataclass
class Disturbance:
    """One disturbance sequence over the WINDOW cycles from the appearance (shapes: SHAPES)."""

    blind: np.ndarray         # (WINDOW,): every channel misses (a common cause)
    miss: np.ndarray          # (WINDOW, 6)
    drop: np.ndarray
    ghost: np.ndarray
    z: np.ndarray             # (WINDOW, 6) distance noise in standard deviations

    @staticmethod
    def none() -> "Disturbance":
        return Disturbance(*(np.zeros(SHAPES[k], dtype=bool) for k in KINDS), np.zeros((WINDOW, CHANNELS)))

    def copy(self) -> "Disturbance":
        return Disturbance(*(getattr(self, k).copy() for k in KINDS), self.z.copy())

    def count(self) -> int:
        return int(sum(getattr(self, k).sum() for k in KINDS))

    def log_likelihood(self) -> float:
        """Nominal log-likelihood relative to the undisturbed sequence (no event, no noise)."""
        return NOMINAL.log_density(self) - NOMINAL.log_density(Disturbance.none())

    def events_log_likelihood(self) -> float:
        """The same without the noise: what ranks failures before they are pruned."""
        return self.log_likelihood() + 0.5 * float(np.sum(self.z ** 2))

    def events(self, period_ms: int) -> list[dict]:
        """The disturbances as a list (noise listed where it exceeds 2 sigma)."""
        out = []
        for j in range(WINDOW):
            if self.blind[j]:
                out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": "all",
                            "kind": "blind"})
            for c in range(CHANNELS):
                for kind in KINDS[1:]:
                    if getattr(self, kind)[j, c]:
                        out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": c,
                                    "kind": kind})
                if abs(self.z[j, c]) > 2.0:
                    out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": c,
                                "kind": "noise", "metres": round(float(self.z[j, c]) * NOISE_SIGMA_M, 3)})
        return out

    def as_lists(self) -> dict:
        return {**{k: getattr(self, k).astype(int).tolist() for k in KINDS}, "z": np.round(self.z, 6).tolist()}

    @staticmethod
    def from_lists(data: dict) -> "Disturbance":
        return Disturbance(*(np.array(data[k], dtype=bool) for k in KINDS), np.array(data["z"], dtype=float))


@dataclass
class Proposal:
    """Blindness a Markov chain over the cycles (p["blind"][j]: it begins at j, `stays[j]`: it
    goes on from j - 1 to j); the other events independent per cycle and channel; Gaussian
    noise of unit spread around `mu`."""

    p: dict                   # kind -> probabilities of shape SHAPES[kind]
    mu: np.ndarray            # (WINDOW, 6) noise means, in sigmas
    stays: np.ndarray         # (WINDOW,) probability that a blindness goes on into cycle j

    @staticmethod
    def nominal() -> "Proposal":
        return Proposal({k: np.full(SHAPES[k], v) for k, v in DISTURBANCES.items()}, np.zeros((WINDOW, CHANNELS)),
                        np.full(WINDOW, BLIND_STAYS))

    def explore(self) -> "Proposal":
        """The search's first proposal: blindness (the one event that hides an obstacle from
        every channel at once) begins with EXPLORE in every cycle; the per-channel events
        start at their nominal rates (six independent misses in one cycle are 1e-8 likely)."""
        return Proposal({**self.p, "blind": np.maximum(self.p["blind"], EXPLORE)}, self.mu.copy(), self.stays.copy())

    def sample(self, rng: np.random.Generator) -> Disturbance:
        ev = [rng.random(SHAPES[k]) < self.p[k] for k in KINDS]
        u = rng.random(WINDOW)
        blind = np.zeros(WINDOW, dtype=bool)
        for j in range(WINDOW):
            blind[j] = u[j] < (self.stays[j] if j and blind[j - 1] else self.p["blind"][j])
        ev[0] = blind
        return Disturbance(*ev, self.mu + rng.standard_normal((WINDOW, CHANNELS)))

    def log_density(self, d: Disturbance) -> float:
        out = -0.5 * float(np.sum((d.z - self.mu) ** 2))
        for k in KINDS[1:]:
            x, p = getattr(d, k), self.p[k]
            out += float(np.sum(np.where(x, np.log(p), np.log1p(-p))))
        prev = np.r_[False, d.blind[:-1]]
        q = np.where(prev, self.stays, self.p["blind"])
        return out + float(np.sum(np.where(d.blind, np.log(q), np.log1p(-q))))


NOMINAL = Proposal.nominal()


def log_weight(d: Disturbance, proposal: Proposal) -> float:
    """log p(d) / q(d): the importance weight of a sample drawn from `proposal`."""
    return NOMINAL.log_density(d) - proposal.log_density(d)
