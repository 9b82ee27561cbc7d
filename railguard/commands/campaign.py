"""`railguard campaign`: the fault-injection campaign and receive-path fuzzing, judged by
the simulated world."""
from __future__ import annotations

import argparse

from .. import options
from .verify import run_parts


def campaign(args: argparse.Namespace) -> int:
    return run_parts(args, ("campaign", "fuzz"))


def register(sub) -> None:
    ca = sub.add_parser(
        "campaign",
        help="fault-injection campaign and receive-path fuzzing on the running monitor",
        description="Every single fault and every pair from the fault catalogue (silence, stuck value, noise burst, "
                    "missed detection, CRC corruption, counter freeze and jump, wrong length, babbling, contradiction, "
                    "stale timestamps, deadline overrun, corrupted or mismatched table) crossed with obstacle scenarios, "
                    "through the core, a sample through the real runner and codec on the virtual bus (with two hostile "
                    "nodes: forged absent and forged brake release in step) and on vcan0; then "
                    "random and mutated frames into the receive path. The simulated world is the judge: a run is "
                    "unsafe when the world's train (the train FMU's physics, with parameters of its own: --world-train) "
                    "reaches an obstacle it could have stopped for. Counts unsafe runs, crashes, collisions and false "
                    "braking; prints a digest of every run's seed and outcome; writes a report; exit status 1 if a "
                    "check fails.",
    )
    ca.add_argument("--quick", action="store_true",
                    help="a few hundred runs and 20,000 frames, what CI runs (default: the full campaign)")
    ca.add_argument("--braking", metavar="FILE.toml", help=options.BRAKING_HELP)
    options.add_world_train(ca, "every run its own train drawn inside the declaration, one in four on its worst corners")
    options.add_unsafe_margin(ca, "a run is unsafe when the world's train reaches an obstacle it could stop for, or "
                                  "comes closer to it than M metres")
    options.add_cluster(ca)
    options.add_out(ca, "railguard-out/campaign", "report folder")
    options.add_json(ca, 'print {"passed": bool, "unsafe": N, "runs": N, "runs_digest": "sha256", "checks": [...], ...}')
    ca.set_defaults(func=campaign)
