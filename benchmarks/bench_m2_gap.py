"""Where Model 2's certified gap comes from: the solver's own gap, and the table's class.

Run: python benchmarks/bench_m2_gap.py [--budget S] [--variants NAME ...] [--closure N] [--write-table DIR] [--json]

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
  not necessarily monotone in the conditions);
- `relaxation`: the information relaxation `railguard solve` uses for m2's upper bound (speed,
  type, track and brake read without error; monitor/offline/relaxation.py) solved alone for
  --budget seconds; its upper bound bounds the full model's optimum, its lower bound does not.
  The table is the shipped one (monitor/tables/m2.table.rgt, its exact value from its header).
  In `shipped`, UB is the run's certified bound: the smaller of the model's own and the
  relaxation's (solved in the time compilation leaves).

Three more variants of `reduced` ask which model feature the solver's gap comes from:
- `reduced-normal-start`: track and brakes known normal at the start (not a quarter each);
- `reduced-distance-exact`: the distance level reported without error;
- `reduced-kind-exact`: obstacle type and speed class reported without error.
`--all-rows` evaluates the sawtooth at every successor of a backup (the solver's default
leaves the unlikeliest 0.1 % of observation mass to the fast informed bound).
`--write-table DIR` writes the `reduced-hysteresis` table as a table of the full model (its
edges the same for every combination of reported conditions) to DIR/m2.table.rgt, for
`railguard evaluate DIR/m2.table.rgt` (with `--budget 27`, the time split of a 60 s
`railguard solve`; docs/models.md section 5 records how it fares).
`--closure N` asks whether more upper-bound points would close the gap: after the solve, the
sawtooth's Bellman operator is iterated to its fixed point over the solver's points, then N
times the successors of every point (greedy action, probability over 1 %) join the set and
it is iterated again (every iterate is a valid upper bound). Printed: points, upper bound,
solver gap and seconds per round.
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

VARIANTS = ("shipped", "reduced", "reduced-hysteresis", "full-hysteresis", "relaxation")
DIAGNOSTIC = {                       # variant -> Model2Params overrides (on the `reduced` model)
    "reduced-normal-start": {"start_conditions": "normal"},
    "reduced-distance-exact": {"misperception": [0.0, 0.05, 0.05, 0.02, 0.01]},
    "reduced-kind-exact": {"misperception": [0.02, 0.0, 0.0, 0.02, 0.01]},
}


def run(variant: str, budget: float, all_rows: bool, closure_rounds: int = 0, write_table: str = "") -> dict:
    """One variant's bounds, table and gaps; `all_rows` only labels the row (main sets the solver)."""
    from monitor.offline import pipeline, solver
    from monitor.offline.controller import compile_controller
    from monitor.offline.layered import ConditionLayer, reduced_model
    from monitor.offline.hysteresis import with_last_demand
    from monitor.offline.models import MODELS
    from monitor.offline.params import override

    spec = MODELS["m2"]
    model, plan = spec.build(override(spec.params, DIAGNOSTIC.get(variant, {}))), spec.plan
    t0 = time.perf_counter()
    upper = None
    if variant == "shipped":
        res = pipeline.run(model, replace(plan, settings=replace(plan.settings, time_budget_s=budget)))
        sol, value, nodes, states = res.solution, res.compiled.value, res.compiled.controller.nodes, model.shape[0]
        upper = res.upper_bound
    elif variant == "relaxation":
        from importlib import resources

        from monitor.core.table import decode
        from monitor.offline.models import model2

        relax = model2.relaxation(model)
        relax.check(model)
        target = relax.model
        sol = solver.solve(target, replace(plan.settings, time_budget_s=budget))
        shipped = decode(resources.files("monitor.tables").joinpath(f"m2{pipeline.TABLE_SUFFIX}").read_bytes(),
                         expect_model="m2")
        value, nodes, states = shipped.header["controller_value"], shipped.nodes, target.shape[0]
    else:
        base = reduced_model(model, ConditionLayer.of(model.observations, plan.conditions)) if variant.startswith("reduced") \
            else model
        target = with_last_demand(base) if variant.endswith("hysteresis") else replace(base, release_cost=0.0)
        sol = solver.solve(target, replace(plan.settings, time_budget_s=budget))
        comp = compile_controller(target, sol, max_nodes=plan.max_nodes, deadline=time.perf_counter() + budget)
        value, nodes, states = comp.value, comp.controller.nodes, target.shape[0]
    seconds = time.perf_counter() - t0          # solve and compile; each closure round reports its own
    if write_table and variant == "reduced-hysteresis":
        print(f"wrote {write_blind(model, plan, sol, comp, write_table)}", file=sys.stderr, flush=True)
    grown = closure(target, sol, closure_rounds) if closure_rounds and variant not in ("shipped", "relaxation") else []
    upper = sol.upper_bound if upper is None else upper
    return {
        "variant": variant, "states": states, "all_rows": all_rows, "budget_s": budget,
        "seconds": seconds, "lower_bound": sol.lower_bound, "upper_bound": upper, "model_upper_bound": sol.upper_bound,
        "trials": sol.iterations, "stop_reason": sol.stop_reason,
        "solver_gap_percent": pipeline.gap_percent(upper, sol.lower_bound),
        "table_value": value, "nodes": nodes,
        "certified_gap_percent": pipeline.gap_percent(upper, value), "closure": grown,
    }


def write_blind(model, plan, sol, comp, out_dir: str) -> Path:
    """The conditions-blind table as a table of the full model (every combination of reported
    conditions takes the edge of its base observation), valued exactly on the full model; the
    header's bounds are those of its class (the reduced model with the last demand in the state)."""
    from monitor.core import table as table_format
    from monitor.offline import pipeline
    from monitor.offline.controller import Controller, evaluate, value_at
    from monitor.offline.layered import ConditionLayer

    layer, c = ConditionLayer.of(model.observations, plan.conditions), comp.controller
    full = Controller(c.action, c.next[:, layer.base], c.start)
    value = value_at(model, full, evaluate(model, full))
    header = pipeline.table_header(model, plan, sol, replace(comp, controller=full, value=value))
    path = Path(out_dir) / f"m2{pipeline.TABLE_SUFFIX}"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(table_format.encode(header, full.action.tolist(), full.next.tolist()))
    return path


def closure(model, sol, rounds: int, min_p: float = 0.01, top: int = 12) -> list[dict]:
    """Upper bound at b0 after iterating the sawtooth Bellman operator to its fixed point over
    the solver's points, then over the set grown `rounds` times by its likely successors.

    The sawtooth of a successor keeps, per successor, the `top` points with the largest ratio
    among those whose likeliest (distance, speed, type) is the successor's: dropping points from
    a sawtooth only loosens it, so each iterate stays an upper bound."""
    import numpy as np

    from monitor.offline import bounds, pipeline

    dyn, ub, A = bounds.Dynamics(model), sol.upper, model.shape[1]
    corner = ub.corner
    group = np.unique(["-".join(s.split("-")[:3]) for s in model.states], return_inverse=True)[1].ravel()
    n_groups = int(group.max()) + 1

    def likeliest(B):
        M = np.zeros((len(B), n_groups))
        np.add.at(M.T, group, B.T)
        return M.argmax(axis=1)

    def fixed_point(P, V):
        N = len(P)
        succ, weight, owner, reward, rest = [], [], [], np.empty((N, A)), np.zeros(N * A)
        for n in range(N):
            for a in range(A):
                U = dyn.joint(P[n], a)
                p = U.sum(axis=1)
                keep, drop = np.flatnonzero(p > 1e-7), np.flatnonzero((p <= 1e-7) & (p > 0))
                succ.append(U[keep] / p[keep, None]); weight.append(p[keep]); owner.append(np.full(len(keep), n * A + a))
                reward[n, a] = P[n] @ dyn.R[a]
                rest[n * A + a] = np.minimum(U[drop] @ corner, ub.fib(U[drop])).sum()
        succ, weight, owner = np.vstack(succ), np.concatenate(weight), np.concatenate(owner)
        base = succ @ corner
        linear = np.minimum(base, ub.fib(succ))
        rows, cols, ratios = [], [], []
        pk, sk = likeliest(P), likeliest(succ)
        for key in np.unique(sk):
            pi, si = np.flatnonzero(pk == key), np.flatnonzero(sk == key)
            if len(pi) == 0:
                continue
            part = ub.over(P[pi], V[pi])
            step = max(1, 4_000_000 // part.size)      # bounds the (successors, points) block
            for lo in range(0, len(si), step):
                R = part.ratios(succ[si[lo:lo + step]])
                k = min(top, len(pi))
                idx = np.argpartition(-R, k - 1, axis=1)[:, :k]
                r = np.take_along_axis(R, idx, axis=1)
                i, j = np.nonzero(r > 1e-9)
                rows.append(si[lo:lo + step][i]); cols.append(pi[idx[i, j]]); ratios.append(r[i, j])
        rows, cols, ratios = (np.concatenate(x) for x in (rows, cols, ratios))
        order = np.argsort(rows, kind="stable")
        rows, cols, ratios = rows[order], cols[order], ratios[order]
        heads, starts = np.unique(rows, return_index=True)
        for _ in range(5000):
            m = np.zeros(len(weight))
            m[heads] = np.minimum.reduceat(ratios * (V - P @ corner)[cols], starts)
            upper = np.minimum(linear, base + np.minimum(0.0, m))
            Q = (reward.ravel() + dyn.g * (np.bincount(owner, weights=weight * upper, minlength=N * A) + rest)).reshape(N, A)
            new = np.minimum(V, Q.max(axis=1))
            done = float((V - new).max()) < 1e-10
            V = new
            if done:
                break
        greedy = Q.argmax(axis=1)
        likely = (owner % A == greedy[owner // A]) & (weight > min_p)
        return V, bounds.truncate(succ[likely])

    P = np.vstack([model.b0[None, :], ub.beliefs])
    V = np.concatenate([ub.value(model.b0[None, :]), ub.values])
    out = []
    for r in range(rounds + 1):
        t0 = time.perf_counter()
        V, grown = fixed_point(P, V)
        out.append({"round": r, "points": len(P), "upper_bound": float(V[0]), "seconds": time.perf_counter() - t0,
                    "solver_gap_percent": pipeline.gap_percent(float(V[0]), sol.lower_bound)})
        if r < rounds:
            both = np.vstack([P, grown])
            _, first = np.unique(np.round(both, 6), axis=0, return_index=True)
            new = both[np.sort(first[first >= len(P)])]
            if not len(new):
                break
            V = np.concatenate([V, ub.over(P, V).value(new)])
            P = np.vstack([P, new])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=60.0, help="seconds per variant (default: 60)")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=VARIANTS + tuple(DIAGNOSTIC),
                    help=f"default: {' '.join(VARIANTS)}; diagnostic: {' '.join(DIAGNOSTIC)}")
    ap.add_argument("--all-rows", action="store_true",
                    help="sawtooth at every successor of a backup (default: the likeliest 99.9 %% of the mass)")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    ap.add_argument("--closure", type=int, default=0, metavar="N",
                    help="after each solve, the upper bound's fixed point over the solver's points grown N times "
                         "by their likely successors (not for `shipped`)")
    ap.add_argument("--write-table", default="", metavar="DIR",
                    help="write the reduced-hysteresis table, for the full model, to DIR/m2.table.rgt")
    args = ap.parse_args()
    if args.write_table and "reduced-hysteresis" not in args.variants:
        ap.error("--write-table writes the reduced-hysteresis table: add --variants reduced-hysteresis")
    if args.all_rows:
        from monitor.offline import solver

        solver.SIGNIFICANT = 1.0           # a module constant, not a setting: settings go into the table header
        if not args.json:
            print("sawtooth at every successor of a backup (--all-rows)")
    rows = []
    for v in args.variants:
        rows.append(run(v, args.budget, args.all_rows, args.closure, args.write_table))
        if not args.json:
            r = rows[-1]
            print(f"{r['variant']:<20} {r['states']:>4} states  LB {r['lower_bound']:.4f}  UB {r['upper_bound']:.4f}  "
                  f"solver gap {r['solver_gap_percent']:5.1f} %  table {r['table_value']:.4f} ({r['nodes']} nodes)  "
                  f"certified gap {r['certified_gap_percent']:5.1f} %  {r['seconds']:.0f} s ({r['trials']} trials, "
                  f"stopped on {r['stop_reason']})", flush=True)
            for c in r["closure"]:
                print(f"    closure round {c['round']}: {c['points']} points, UB {c['upper_bound']:.4f}, "
                      f"solver gap {c['solver_gap_percent']:5.1f} %, {c['seconds']:.0f} s", flush=True)
    if args.json:
        print(json.dumps({"budget_s": args.budget, "variants": rows}))


if __name__ == "__main__":
    main()
