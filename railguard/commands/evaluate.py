"""`railguard evaluate`: a table against the simple rules on risk, needless braking, stops
and demand changes (the ACAS X acceptance rule)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from monitor.tables import DEFAULT

from .. import options, output
from ..setup import cluster


def evaluate(args: argparse.Namespace) -> int:
    from verification import evaluate as ev

    result = ev.evaluate(args.table, quick=args.quick, seed=args.seed, cluster=cluster(args, 1),
                         progress=None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True)))
    out = Path(args.out)
    stem = "evaluate-" + (args.table if args.table in ("m1", "m2") else Path(args.table).name.split(".")[0])
    files = [output.write_json(out / f"{stem}.json", result)]
    if not args.no_plot:
        files.append(ev.plot(result, out / f"{stem}.png"))
    if args.json:
        print(json.dumps({**result, "files": output.files_of(*files)}))
    else:
        sys.stdout.write(ev.render(result))
        output.wrote(files)
    return 0


def register(sub) -> None:
    e = sub.add_parser(
        "evaluate",
        help="a table against the simple rules: risk, needless braking, stops, demand changes",
        description="Evaluate a policy table and the baselines threshold, belief_tracking, always_emergency and "
                    "never, each with the braking-curve supervision in front: p_hazard = P(hazard within 30 s) on "
                    "the model's closed loop (exact for finite-state controllers; for belief tracking a sharp "
                    "estimate with its 95 % interval: conditional Monte Carlo with the exact next-step hazard and "
                    "importance sampling guided by the table's exact values); unnecessary_braking (fraction of "
                    "the time without need with a brake demand; m1: no obstacle on the line, m2: none above eq. "
                    "11's low risk), policy_braking (the part of it the policy alone asked for, no supervision "
                    "cause: what separates policies where the curves and the memory brake alike), stops_per_train_hour and demand_changes_per_encounter "
                    "by Monte Carlo in the model's seed world (m1: seed 000's world with 2 % phantoms and misses; "
                    "m2: seed 001's), every policy on the same trains, with 95 % intervals. Each figure is decided "
                    "by a one-sided test at 5 % with the burden on the table (better only if 'table >= baseline' is "
                    "rejected, worse only if 'table <= baseline' is; world figures train by train), and each "
                    "baseline gets a verdict: better, worse, trade-off or indistinguishable. Writes "
                    "DIR/evaluate-NAME.json and a plot of p_hazard against unnecessary braking.",
        epilog="JSON shape: {\"table\": {...}, \"baselines\": {\"threshold\": {...}, ...}, "
               "\"belief_tracking_p_hazard\": {\"p\", \"ci\", \"low\", \"high\", \"episodes\", \"method\", ...}, "
               "\"comparisons\": {BASELINE: {\"figures\": {FIGURE: {\"difference\", \"ci\", \"p_better\", \"p_worse\", "
               "\"decision\", \"test\"}}, \"verdict\", \"acceptance\", ...}}, \"verdicts\": {BASELINE: WORD}, "
               "\"acceptance_verdicts\": {BASELINE: WORD} (on p_hazard and unnecessary_braking), \"risk_axis\": "
               "null or why the world cannot rank risk}; every figure has a *_ci half-width. A table file's "
               "belief_tracking baseline needs its .alphas.npz beside it (railguard solve writes it).",
    )
    e.add_argument("table", nargs="?", default=DEFAULT, metavar="m1|m2|TABLE",
                   help="a shipped model name or a .table.rgt file of model m1 or m2 (default: %(default)s)")
    e.add_argument("--quick", action="store_true",
                   help="96 trains x 300 s; belief tracking's hazard from 500 episodes, m1 5,000 (default: 288 x 600 s; "
                        "4,000 episodes, m1 40,000)")
    e.add_argument("--seed", type=int, default=12, help="seed of every Monte Carlo run (default: %(default)s)")
    options.add_out(e)
    e.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    e.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    options.add_cluster(e, "1: the policies one after the other", "each policy a dask task; ")
    options.add_json(e, "print one JSON object (the figures and the files written)")
    e.set_defaults(func=evaluate)
