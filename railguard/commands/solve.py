"""`railguard solve`: a POMDP solved by point-based value iteration and compiled into the
fixed policy table; `--pareto` sweeps the cost weights and writes the frontier."""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Callable

from .. import options, output
from ..errors import UserError, naming
from ..setup import cluster


def progress_printer(stream) -> Callable:
    """Solver progress on one refreshed line for a terminal, one line per 25 iterations otherwise."""
    tty = stream.isatty()

    def show(p) -> None:
        text = (f"iter {p.iteration:4d}  lower {p.lower:12.4f}  upper {p.upper:12.4f}  gap {p.gap:10.4f}  "
                f"alphas {p.alphas:4d}  beliefs {p.beliefs:4d}  {p.elapsed:6.1f} s")
        if tty:
            stream.write("\r" + text)
            stream.flush()
        elif p.iteration % 25 == 0:
            stream.write(text + "\n")

    def finish() -> None:
        if tty:
            stream.write("\n")

    def line(text: str) -> None:
        stream.write(text + "\n")
        stream.flush()

    show.finish = finish  # type: ignore[attr-defined]
    show.line = line  # type: ignore[attr-defined]
    return show


def pareto(args: argparse.Namespace) -> int:
    from verification import pareto as sweep

    if not args.model:
        raise UserError("--pareto sweeps one of the papers' models: give --model m1 or m2")
    grid = sweep.read_grid(args.grid) if args.grid else None
    out = Path(args.out) / f"pareto-{args.model}"
    result = sweep.sweep(args.model, out, quick=True, time_budget=args.time_budget, grid=grid,
                         progress=lambda text: print(text, file=sys.stderr, flush=True), cluster=cluster(args, 1),
                         layered_search=args.layered_search)
    files = [output.write_json(out / "frontier.json", result), sweep.plot(result, out / "frontier.png")]
    if args.json:
        print(json.dumps({**result, "files": output.files_of(*files)}))
    else:
        sys.stdout.write(sweep.render(result))
        output.wrote(files)
        print(f"      and one table folder per point under {out}")
    return 0


def solve(args: argparse.Namespace) -> int:
    from monitor.offline import models, pipeline, pomdp_file

    if args.pareto:
        return pareto(args)
    from monitor.offline.params import ConfigError
    from monitor.offline.pomdp import ModelError

    with naming(args.config, ConfigError, ModelError):
        if args.pomdp:
            model = pomdp_file.read(args.pomdp)
            plan = models.plan_for_pomdp_file(args.config)
        else:
            model, plan = models.load(args.model, args.config)
    settings = plan.settings
    for flag, name in (("seed", "seed"), ("time_budget", "time_budget_s"), ("max_iterations", "max_iterations"),
                       ("max_beliefs", "max_beliefs"), ("target_gap", "target_gap")):
        value = getattr(args, flag)
        if value is not None:
            settings = replace(settings, **{name: value})
    plan = replace(plan, settings=settings, max_nodes=args.max_nodes or plan.max_nodes,
                   layered_search=args.layered_search or plan.layered_search)
    printer = progress_printer(sys.stderr) if (not args.json or sys.stderr.isatty()) else None
    started = {"done": False}

    def compile_line(text: str) -> None:
        if printer is None:
            return
        if not started["done"]:
            printer.finish()
            started["done"] = True
        printer.line(text)

    result = pipeline.run(model, plan, printer, compile_line)
    paths = pipeline.write(result, args.out)
    if args.json:
        figures = pipeline.figures(result)
        figures.update(table=str(paths["table"]), pomdp=str(paths["pomdp"]), summary=str(paths["summary"]),
                       files=output.files_of(*paths.values()))
        print(json.dumps(figures))
    else:
        sys.stdout.write(pipeline.summary_text(result))
        output.wrote(paths.values())
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "solve",
        help="solve a POMDP with point-based value iteration and compile the fixed policy table",
        description=(
            "Solve one of the papers' models (--model) or any Cassandra .pomdp file (--pomdp) with "
            "point-based value iteration, compile the alpha vectors into a finite-state controller, "
            "evaluate it exactly and write DIR/<name>.table.rgt, DIR/<name>.pomdp and DIR/<name>.summary.txt. "
            "For m2 the time compilation leaves (up to 85 % of the budget, and at least 10 % of it even when "
            "compilation ran late, which then makes the run that much longer) goes to an information relaxation "
            "(the model with all but the distance read without error), whose upper bound also bounds the model's "
            "optimum; the smaller bound is printed and written. "
            "Progress (iteration, bounds, gap, elapsed) goes to stderr."
        ),
        epilog="A TOML file given with --config sets model parameters at top level and solver settings "
               "in a [solver] table (seed, max_iterations, max_beliefs, expand_every, target_gap, "
               "time_budget_s, max_nodes, layered_search). See docs/models.md for every parameter.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--model", choices=["m1", "m2"], help="m1: seed 000, 4 states; m2: seed 001, 144 states")
    src.add_argument("--pomdp", metavar="FILE", help="a Cassandra .pomdp file")
    p.add_argument("--config", metavar="FILE.toml", help="parameter and solver overrides (default: the model's own)")
    options.add_out(p)
    p.add_argument("--seed", type=int, help="seed of the belief-set expansion (default: 0)")
    p.add_argument("--time-budget", type=options.positive_float, metavar="S",
                   help="bound the whole run (solve, compile, evaluate) to about S seconds; with --pareto, per point "
                        "(default: the model's, m1 30 s, m2 60 s)")
    p.add_argument("--max-iterations", type=options.positive_int, metavar="N",
                   help="stop after N backups; a build that stops on this, not on the clock, is reproducible "
                        "(same table bytes; docs/models.md section 7) (default: the model's)")
    p.add_argument("--max-beliefs", type=options.positive_int, metavar="N", help="cap on the belief set (default: the model's)")
    p.add_argument("--target-gap", type=options.positive_float, metavar="X",
                   help="stop when gap <= X * max(1, |upper|) (default: the model's)")
    p.add_argument("--max-nodes", type=options.positive_int, metavar="N",
                   help="node budget of the compiled controller (default: the model's)")
    p.add_argument("--layered-search", choices=["actions", "exact"],
                   help="m2 (a table monotone in the reported conditions): how its layered controller is improved. "
                        "actions: every node's best action at once, the release cost counted on leaving a node only "
                        "(the shipped table). exact: actions and shared edges, the most promising first, each change "
                        "kept only if the exact value rises, the release cost counted both ways, the memory solved "
                        "with the last demand in the state: worth more in the model (-0.182 against -0.206 in 60 s), "
                        "but at the shipped weights it brakes needlessly more in the world, and from solve to solve it "
                        "varies more (docs/models.md sections 5 and 7); with --pareto, for every point (default: actions)")
    p.add_argument("--pareto", action="store_true",
                   help="sweep the cost weights (collision, braking, demand change), solve each, judge each table "
                        "like `railguard evaluate --quick` and write DIR/pareto-MODEL/frontier.json and frontier.png "
                        "(p_hazard against unnecessary braking, baselines as points)")
    p.add_argument("--grid", metavar="FILE.toml",
                   help="with --pareto: the weights to sweep, e.g. braking_weight = [1.0, 2.0] and "
                        "release_cost = [0.0, 1.0] (every combination) (default: the built-in grid of the model)")
    options.add_cluster(p, "1: the points one after the other, each with a core to itself", "with --pareto: ")
    options.add_json(p, "print one JSON object with the figures and paths")
    p.set_defaults(func=solve)
