"""Where Model 2's certified gap comes from: the solver's own gap, and the table's class.

Run: python benchmarks/bench_m2_gap.py [--budget S] [--variants NAME ...] [--json]

The shipped m2 table is certified against the sawtooth upper bound of the full model
without the release cost, while the table is layered (monotone in the reported conditions)
and pays the release cost: part of the printed gap is the class, not the solver. Each
variant below solves a model for --budget seconds (HSVI, m2's plan settings), compiles an
unconstrained controller on it (except `shipped`, the pipeline as `railguard solve` runs it)
and prints lower bound, upper bound, the table's exact value and the certified gap:

- `shipped`: pipeline.run (reduced model for the memory, full model for the bounds, layered
  compile with the release cost charged in compilation only);
- `reduced`: the model with the track and brake reports unobserved (a table that does not
  read them, so trivially monotone in them), release cost 0;
- `reduced-hysteresis`: the same with the last demand in the state and the release cost in
  the reward, so the solver's bounds bound exactly the class of that table;
- `full-hysteresis`: the full model with the last demand in the state (an unconstrained table:
  not necessarily monotone in the conditions).

Three more variants of `reduced` ask which model feature the solver's gap comes from:
- `reduced-normal-start`: track and brakes known normal at the start (not a quarter each);
- `reduced-distance-exact`: the distance level reported without error;
- `reduced-kind-exact`: obstacle type and speed class reported without error.
`--all-rows` evaluates the sawtooth at every successor of a backup (the solver's default
leaves the unlikeliest 0.1 % of observation mass to the fast informed bound).
Figures vary with the machine's load; docs/models.md section 5 records a run.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

VARIANTS = ("shipped", "reduced", "reduced-hysteresis", "full-hysteresis")
DIAGNOSTIC = {                       # variant -> Model2Params overrides (on the `reduced` model)
    "reduced-normal-start": {"start_conditions": "normal"},
    "reduced-distance-exact": {"misperception": [0.0, 0.05, 0.05, 0.02, 0.01]},
    "reduced-kind-exact": {"misperception": [0.02, 0.0, 0.0, 0.02, 0.01]},
}


def run(variant: str, budget: float, all_rows: bool) -> dict:
    """One variant's bounds, table and gaps; `all_rows` only labels the row (main sets the solver)."""
    from monitor.offline import pipeline, solver
    from monitor.offline.controller import ConditionLayer, compile_controller, reduced_model
    from monitor.offline.hysteresis import with_last_demand
    from monitor.offline.models import MODELS
    from monitor.offline.params import override

    spec = MODELS["m2"]
    model, plan = spec.build(override(spec.params, DIAGNOSTIC.get(variant, {}))), spec.plan
    t0 = time.perf_counter()
    if variant == "shipped":
        res = pipeline.run(model, replace(plan, settings=replace(plan.settings, time_budget_s=budget)))
        sol, value, nodes, states = res.solution, res.compiled.value, res.compiled.controller.nodes, model.shape[0]
    else:
        base = reduced_model(model, ConditionLayer.of(model.observations, plan.conditions)) if variant.startswith("reduced") \
            else model
        target = with_last_demand(base) if variant.endswith("hysteresis") else replace(base, release_cost=0.0)
        sol = solver.solve(target, replace(plan.settings, time_budget_s=budget))
        comp = compile_controller(target, sol, max_nodes=plan.max_nodes, deadline=time.perf_counter() + budget)
        value, nodes, states = comp.value, comp.controller.nodes, target.shape[0]
    return {
        "variant": variant, "states": states, "all_rows": all_rows, "budget_s": budget,
        "seconds": time.perf_counter() - t0, "lower_bound": sol.lower_bound, "upper_bound": sol.upper_bound,
        "trials": sol.iterations, "stop_reason": sol.stop_reason,
        "solver_gap_percent": pipeline.gap_percent(sol.upper_bound, sol.lower_bound),
        "table_value": value, "nodes": nodes,
        "certified_gap_percent": pipeline.gap_percent(sol.upper_bound, value),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=60.0, help="seconds per variant (default: 60)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=VARIANTS + tuple(DIAGNOSTIC),
                    help=f"default: {' '.join(VARIANTS)}; diagnostic: {' '.join(DIAGNOSTIC)}")
    ap.add_argument("--all-rows", action="store_true",
                    help="sawtooth at every successor of a backup (default: the likeliest 99.9 %% of the mass)")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    args = ap.parse_args()
    if args.all_rows:
        from monitor.offline import solver

        solver.SIGNIFICANT = 1.0           # a module constant, not a setting: settings go into the table header
        if not args.json:
            print("sawtooth at every successor of a backup (--all-rows)")
    rows = []
    for v in args.variants:
        rows.append(run(v, args.budget, args.all_rows))
        if not args.json:
            r = rows[-1]
            print(f"{r['variant']:<20} {r['states']:>4} states  LB {r['lower_bound']:.4f}  UB {r['upper_bound']:.4f}  "
                  f"solver gap {r['solver_gap_percent']:5.1f} %  table {r['table_value']:.4f} ({r['nodes']} nodes)  "
                  f"certified gap {r['certified_gap_percent']:5.1f} %  {r['seconds']:.0f} s ({r['trials']} trials, "
                  f"stopped on {r['stop_reason']})", flush=True)
    if args.json:
        print(json.dumps({"budget_s": args.budget, "variants": rows}))


if __name__ == "__main__":
    main()
