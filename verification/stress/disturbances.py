"""The disturbance model: what can go wrong on the six channels in the WINDOW cycles after the
appearance (a common-cause blindness, misses, lost frames, ghosts, distance noise), its
nominal probabilities, a disturbance sequence, and the proposal densities the search draws
from (the nominal one among them), with the likelihoods that rank failures and weight samples.

The window covers the encounter until standstill. The slowest encounter (edge-40: 40 m/s on
the declaration's worst corner, 2.2 m/s^2 less a 20 per mille down gradient, 0.5 to 1 s of
dead time) stands still about 225 to 235 cycles after the appearance when nothing disturbs
it, so a window of 300 cycles (30 s) lets a disturbance strike at any moment of any
encounter's braking, a few seconds of later braking included (tests/test_stress.py checks
that every encounter's undisturbed run ends within it). After the window the channels
report what they see.

Calibration of the misses to seed 002 (a channel misses with p_n = P_MISS) and a beta factor
BETA (the common-cause share of those misses, IEC 61508-6 annex D):
- the common-cause blindness (every channel at once) is a two-state Markov chain over the
  cycles: it begins with p_s in a cycle after a clear one and goes on with s = BLIND_STAYS
  (0.9: it lasts 1 / (1 - s) = 10 cycles, 1 s, on average). Its stationary share is
  p_s / (p_s + 1 - s); that share is the common-cause part of a channel's miss probability,
  P_BLIND = BETA * P_MISS = 0.002, so p_s = P_BLIND (1 - s) / (1 - P_BLIND) = 2.004e-4;
- a channel misses on its own, independently, with p_ind where the blindness leaves it
  seeing: P_BLIND + (1 - P_BLIND) p_ind = P_MISS, so p_ind = (P_MISS - P_BLIND) / (1 - P_BLIND)
  = 0.038076; every channel then misses P_MISS = 0.04 of the cycles, 5 % of it in common.
The chain starts in its stationary distribution (blind at the appearance with P_BLIND, the
weather does not wait for the obstacle), so every cycle of the window is blind with P_BLIND
and every channel misses with P_MISS (tests/test_stress.py samples it).

A module-level miss (issue 38): a module whose two channels never see this obstacle (a
shorter range, another sensor kind, an object its kind does not detect), per encounter and
module with P_MODULE_MISS. Sensors of different range and kind disagree normally; the rate
is this model's assumption, not a measurement (seed 002 gives none): 1 % per module and
encounter. It is the case the memory's "any module that saw it" rule exists for.

A nearer hidden obstacle (issue 38 item 2): behind the obstacle, BEHIND_M farther, a second
object stands in the sensors' sight (a vehicle, a buffer stop, a structure), per encounter
with P_BEHIND (this model's assumption, 5 %). A channel that misses the obstacle in a cycle
(blindness, its own miss, its module's miss) then sees past it and reports the farther
object, as a sensor that reports its nearest object does, instead of nothing. The memory
must count that as evidence that the obstacle is gone only as it counts ABSENT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .encounters import CHANNELS, NOISE_SIGMA_M


WINDOW = 300              # cycles from the appearance on in which disturbances are searched (30 s: to standstill)
P_MISS = 0.04             # seed 002: p_n, a channel's probability of a false negative
BETA = 0.05               # common-cause share of misses (IEC 61508-6 annex D's beta: 1 % to 10 %)
BLIND_STAYS = 0.9         # a common-cause blindness (glare, spray) goes on to the next cycle: 1 s on average
P_BLIND = BETA * P_MISS   # stationary share of the cycles in which every channel is blind
# nominal probability per cycle: `blind` (all six channels at once, a common cause) begins
# (after a clear cycle; the chain's stationary share is then P_BLIND), and then lasts with
# BLIND_STAYS; the others per channel, independent (a `miss` brings a channel's misses to P_MISS)
DISTURBANCES = {"blind": P_BLIND * (1 - BLIND_STAYS) / (1 - P_BLIND), "miss": (P_MISS - P_BLIND) / (1 - P_BLIND),
                "drop": 0.001, "ghost": 0.001}
EXPLORE = 0.05            # the search's first proposal: a common-cause blindness begins this likely
MODULES = CHANNELS // 2
P_MODULE_MISS = 0.01      # a module never sees this obstacle (per encounter and module; issue 38)
P_BEHIND = 0.05           # a farther object behind the obstacle, seen where it is missed (per encounter; issue 38)


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
    module: np.ndarray = None  # (3,): module m never sees the obstacle (None: no module misses)
    behind: np.ndarray = None  # (1,): a farther object stands behind it (None: none)

    def __post_init__(self):
        if self.module is None:
            self.module = np.zeros(MODULES, dtype=bool)
        if self.behind is None:
            self.behind = np.zeros(1, dtype=bool)

    @staticmethod
    def none() -> "Disturbance":
        return Disturbance(*(np.zeros(SHAPES[k], dtype=bool) for k in KINDS), np.zeros((WINDOW, CHANNELS)))

    def copy(self) -> "Disturbance":
        return Disturbance(*(getattr(self, k).copy() for k in KINDS), self.z.copy(), self.module.copy(),
                           self.behind.copy())

    def cut(self, cycles: int) -> "Disturbance":
        """Undisturbed from cycle `cycles` on (a run that read only `cycles` cycles of the
        window: what came after them decided nothing)."""
        out = self.copy()
        for k in (*KINDS, "z"):
            getattr(out, k)[cycles:] = 0
        return out                    # (a module's miss and the object behind hold from the start: every run read them)

    def count(self) -> int:
        return int(sum(getattr(self, k).sum() for k in KINDS)) + int(self.module.sum()) + int(self.behind.sum())

    def log_likelihood(self) -> float:
        """Nominal log-likelihood relative to the undisturbed sequence (no event, no noise)."""
        return NOMINAL.log_density(self) - NOMINAL.log_density(Disturbance.none())

    def events_log_likelihood(self) -> float:
        """The same without the noise: what ranks failures before they are pruned."""
        return self.log_likelihood() + 0.5 * float(np.sum(self.z ** 2))

    def events(self, period_ms: int) -> list[dict]:
        """The disturbances as a list (noise listed where it exceeds 2 sigma)."""
        out = [{"cycle": 0, "t_after_appearance_s": 0.0, "channel": f"module {m}", "kind": "module_miss"}
               for m in np.nonzero(self.module)[0]]
        if self.behind[0]:
            out.append({"cycle": 0, "t_after_appearance_s": 0.0, "channel": "all", "kind": "object_behind"})
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
        return {**{k: getattr(self, k).astype(int).tolist() for k in KINDS}, "z": np.round(self.z, 6).tolist(),
                "module": self.module.astype(int).tolist(), "behind": self.behind.astype(int).tolist()}

    @staticmethod
    def from_lists(data: dict) -> "Disturbance":
        """From `as_lists`; a sequence shorter than WINDOW (written with a shorter window) is
        undisturbed after its end; one written before module misses (or objects behind) has none."""
        arrays = [np.array(data[k], dtype=bool) for k in KINDS] + [np.array(data["z"], dtype=float)]
        if len(arrays[0]) > WINDOW:
            raise ValueError(f"a disturbance of {len(arrays[0])} cycles, longer than the window of {WINDOW}")
        return Disturbance(*(np.concatenate([a, np.zeros((WINDOW - len(a), *a.shape[1:]), a.dtype)]) for a in arrays),
                           np.array(data.get("module", [0] * MODULES), dtype=bool),
                           np.array(data.get("behind", [0]), dtype=bool))


@dataclass
class Proposal:
    """Blindness a Markov chain over the cycles (p["blind"][j]: it begins at j, `stays[j]`: it
    goes on from j - 1 to j); the other events independent per cycle and channel; Gaussian
    noise of unit spread around `mu`."""

    p: dict                   # kind -> probabilities of shape SHAPES[kind]
    mu: np.ndarray            # (WINDOW, 6) noise means, in sigmas
    stays: np.ndarray         # (WINDOW,) probability that a blindness goes on into cycle j
    module: np.ndarray = None  # (3,) probability that module m never sees the obstacle
    behind: np.ndarray = None  # (1,) probability of a farther object behind it

    def __post_init__(self):
        if self.module is None:
            self.module = np.full(MODULES, P_MODULE_MISS)
        if self.behind is None:
            self.behind = np.full(1, P_BEHIND)

    @staticmethod
    def nominal() -> "Proposal":
        """The disturbance model; its blindness chain starts stationary (blind at the
        appearance with P_BLIND)."""
        p = {k: np.full(SHAPES[k], v) for k, v in DISTURBANCES.items()}
        p["blind"][0] = P_BLIND
        return Proposal(p, np.zeros((WINDOW, CHANNELS)), np.full(WINDOW, BLIND_STAYS))

    def explore(self) -> "Proposal":
        """The search's first proposal: blindness (the one event that hides an obstacle from
        every channel at once) begins with EXPLORE in every cycle; the per-channel events
        start at their nominal rates (six independent misses in one cycle are 1e-8 likely)."""
        return Proposal({**self.p, "blind": np.maximum(self.p["blind"], EXPLORE)}, self.mu.copy(), self.stays.copy(),
                        self.module.copy(), self.behind.copy())

    def blind_chains(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """n runs of the blindness chain over the window, (n, WINDOW)."""
        blind = np.zeros((n, WINDOW), dtype=bool)
        before = np.zeros(n, dtype=bool)             # the cycle before the window: p["blind"][0] is the start
        for j in range(WINDOW):
            before = blind[:, j] = rng.random(n) < np.where(before, self.stays[j], self.p["blind"][j])
        return blind

    def sample(self, rng: np.random.Generator, n: int) -> list[Disturbance]:
        """n disturbance sequences drawn from this density."""
        blind = self.blind_chains(rng, n)
        ev = [rng.random((n, *SHAPES[k])) < self.p[k] for k in KINDS[1:]]
        z = self.mu + rng.standard_normal((n, WINDOW, CHANNELS))
        module = rng.random((n, MODULES)) < self.module          # drawn last: the other draws are those of before
        behind = rng.random((n, 1)) < self.behind                # (and after those)
        return [Disturbance(blind[i], *(e[i] for e in ev), z[i], module[i], behind[i]) for i in range(n)]

    def log_density(self, d: Disturbance, cycles: int = WINDOW) -> float:
        """log q(d), of its first `cycles` cycles (a run that read no more: the density of what
        it saw)."""
        z, mu = d.z[:cycles], self.mu[:cycles]
        out = -0.5 * float(np.sum((z - mu) ** 2))
        for k in KINDS[1:]:
            x, p = getattr(d, k)[:cycles], self.p[k][:cycles]
            out += float(np.sum(np.where(x, np.log(p), np.log1p(-p))))
        blind = d.blind[:cycles]
        prev = np.r_[False, blind[:-1]]
        q = np.where(prev, self.stays[:cycles], self.p["blind"][:cycles])
        out += float(np.sum(np.where(d.module, np.log(self.module), np.log1p(-self.module))))
        out += float(np.sum(np.where(d.behind, np.log(self.behind), np.log1p(-self.behind))))
        return out + float(np.sum(np.where(blind, np.log(q), np.log1p(-q))))


NOMINAL = Proposal.nominal()


def log_weight(d: Disturbance, proposal: Proposal, cycles: int = WINDOW) -> float:
    """log p(d) / q(d) over the first `cycles` cycles: the importance weight of a sample drawn
    from `proposal` whose run read no more (the run's end is a stopping time: the ratio up to
    it weights the samples without bias, and the cycles after it only add variance)."""
    return NOMINAL.log_density(d, cycles) - proposal.log_density(d, cycles)
