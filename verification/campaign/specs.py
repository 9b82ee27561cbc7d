"""Which runs the campaign makes: the fault combinations (none, every single kind, every pair),
crossed with the scenarios and seeds (quick and full), and each run's faults (channels,
windows and variants) drawn from its own seed, so that a run is the same wherever it goes.
"""
from __future__ import annotations

import random
from dataclasses import dataclass

from .catalogue import CHANNEL_KINDS, KINDS
from .scenarios import SCENARIO_BY_NAME, SCENARIOS


SEEDS = 11          # full mode: 117 combinations x 8 scenarios x 11 seeds = 10,296 core-level runs


@dataclass(frozen=True)
class Fault:
    kind: str
    channel: int            # -1 for faults that are not a channel's
    start_s: float
    end_s: float
    variant: tuple = ()     # kind-specific parameters


@dataclass(frozen=True)
class RunSpec:
    kinds: tuple            # () fault-free, (k,) single, (k1, k2) pair
    scenario: str
    seed: int
    model: str

    @property
    def key(self) -> str:
        return f"{'+'.join(self.kinds) or 'none'}/{self.scenario}/{self.seed}/{self.model}"


def combos() -> list[tuple]:
    """(), every single kind, every pair of distinct kinds, and two channels with the same
    channel fault."""
    out = [()] + [(k,) for k in KINDS]
    for i, a in enumerate(KINDS):
        for b in KINDS[i:]:
            if a == b and a not in CHANNEL_KINDS:
                continue
            out.append((a, b))
    return out


def plan(quick: bool) -> list[RunSpec]:
    """Full: every combination x every scenario x SEEDS seeds (m1 and m2 tables alternating).
    Quick: fault-free and singles x scenarios, plus every pair on a rotating scenario."""
    specs = []
    all_combos = combos()
    if quick:
        for c in all_combos:
            if len(c) <= 1:
                for si, s in enumerate(SCENARIOS):
                    specs.append(RunSpec(c, s.name, 0, ("m1", "m2")[si % 2]))
        pairs = [c for c in all_combos if len(c) == 2]
        for i, c in enumerate(pairs):
            for j in range(2):
                s = SCENARIOS[(2 * i + j) % len(SCENARIOS)]
                specs.append(RunSpec(c, s.name, 1, ("m1", "m2")[(i + j) % 2]))
        return specs
    for seed in range(SEEDS):
        for ci, c in enumerate(all_combos):
            for si, s in enumerate(SCENARIOS):
                specs.append(RunSpec(c, s.name, seed, ("m1", "m2")[(seed + si + ci) % 2]))
    return specs


def instantiate(spec: RunSpec, rng: random.Random) -> list[Fault]:
    """Channels, windows and variants of the faults of one run, drawn from its seed."""
    scen = SCENARIO_BY_NAME[spec.scenario]
    chans = [k for k in spec.kinds if k in CHANNEL_KINDS]
    channels: list[int] = []
    if len(chans) == 1:
        channels = [rng.randrange(6)]
    elif len(chans) == 2:
        m = rng.randrange(3)
        a = 2 * m + rng.randrange(2)
        if rng.random() < 0.5:
            b = a ^ 1                                   # both channels of one module
        else:
            b = 2 * ((m + rng.randrange(1, 3)) % 3) + rng.randrange(2)
        channels = [a, b]
    faults = []
    ci = 0
    for kind in spec.kinds:
        lo, hi = scen.campaign.fault_start_s
        start = round(rng.uniform(lo, hi), 1)
        end = round(start + rng.uniform(1.0, 6.0), 1)
        ch = -1
        if kind in CHANNEL_KINDS:
            ch = channels[ci]
            ci += 1
        if kind == "bad_crc":
            variant = ("multi" if rng.random() < 0.5 else "byte",)
        elif kind == "counter_jump":
            variant = (rng.randint(1, 14),)
        elif kind == "wrong_length":
            variant = (rng.randint(0, 7),)
        elif kind == "babble":
            variant = (rng.choice((4, 8, 20)),)
        elif kind == "contradiction":
            variant = (rng.randint(300, 9000),)                 # phantom distance, dm
        elif kind == "stale_timestamp":
            variant = ("past", rng.randint(1, 5000)) if rng.random() < 0.5 else ("future", rng.randint(1, 2000))
        elif kind == "table_corrupted":
            variant = (rng.choice(("flip", "digest", "truncate", "magic")), rng.random())
        elif kind == "table_mismatch":
            variant = (rng.choice(("expect_model", "period", "relabel", "reorder")),)
        else:
            variant = ()
        faults.append(Fault(kind, ch, start, end, variant))
    return faults
