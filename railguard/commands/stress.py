"""`railguard stress`: adaptive stress testing, the likeliest way to a collision, and
P(collision per encounter) by importance sampling."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from monitor.tables import DEFAULT

from .. import options, output
from ..setup import cluster, with_braking


def stress(args: argparse.Namespace) -> int:
    from monitor.core.config import Config
    from verification import stress as search
    from verification.world_train import load

    cfg = with_braking(Config(), args)
    world = load(args.world_train) if args.world_train else None
    say = output.stderr_lines(args.json)
    result = search.run(args.table, args.encounter, Path(args.out), quick=args.quick, cfg=cfg, world=world,
                        margin_m=args.unsafe_margin, seed=args.seed, cluster=cluster(args),
                        progress=say or (lambda _: None))
    if args.json:
        print(json.dumps(result, default=str))
    else:
        sys.stdout.write(search.render(result))
        output.wrote(result["files"])
    return 0


def register(sub) -> None:
    from verification.stress import ENCOUNTERS

    st = sub.add_parser(
        "stress",
        help="adaptive stress testing: the likeliest disturbance sequence that ends in a collision",
        description="Search (cross-entropy method) for the likeliest sequence of sensor disturbances (a common-cause "
                    "blindness of every channel, misses, lost frames, ghosts, distance noise) that makes the world's "
                    "train hit an obstacle it could have stopped for, with the shipped table and the supervision in the "
                    "loop; prune it to the disturbances it needs; write it as a candump log that `railguard replay` "
                    "reproduces (checked) and as a scenario of the encounter that `railguard cosim` plays; estimate "
                    "P(collision per encounter) by importance sampling against naive Monte Carlo. Encounters: "
                    + "; ".join(f"{e.name}: {e.description}" for e in ENCOUNTERS.values()) + ".",
    )
    st.add_argument("--table", choices=["m1", "m2"], default=DEFAULT,
                    help="the shipped table in the loop (default: %(default)s)")
    st.add_argument("--encounter", choices=sorted(ENCOUNTERS), default="edge-30", help="(default: %(default)s)")
    st.add_argument("--quick", action="store_true",
                    help="6 iterations of 100 runs, 400 importance samples, about a minute (default: the full search)")
    st.add_argument("--seed", type=int, default=0, help="root of every run's seed (default: %(default)s)")
    st.add_argument("--braking", metavar="FILE.toml", help=options.BRAKING_HELP)
    options.add_world_train(st, "the braking declaration's worst corner")
    options.add_unsafe_margin(st, "a gap below M metres counts as a failure")
    options.add_cluster(st)
    options.add_out(st, "railguard-out/stress")
    options.add_json(st, 'print {"most_likely_failure": null or {"log_likelihood", "events", "candump", "cosim", ...}, '
                         '"rare_event": {...}, ...}')
    st.set_defaults(func=stress)
