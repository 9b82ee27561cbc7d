"""`railguard solve --pareto`: the cost weights swept, each table judged on risk and needless braking.

A reward is a choice; the frontier shows what the choice costs. For each weight vector
(collision, braking, demand change: the models' `collision_weight`, `braking_weight`,
`release_cost`) the model is solved and compiled, and its table is judged exactly as
`railguard evaluate` judges it: p_hazard exact on the closed loop with the supervision in
front, unnecessary braking by Monte Carlo in the seed world (the quick size, the same seed
for every point: common random numbers). The frontier is the set of points no other point
beats on both. A table may ship only from the frontier and only if it dominates the
baselines its model is held to (ACAS X's acceptance rule, evaluate.ACCEPTED: threshold and
belief tracking); `recommended` is the frontier point that does so with
the least unnecessary braking.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Optional

from monitor.core.table import decode
from monitor.offline import pipeline
from monitor.offline.models import MODELS
from monitor.offline.params import override

from . import evaluate
from .evaluate import SEED, SIZES, draw_policies, hazard_axes, load_target, no_worse
from .closed_loop import HORIZON_S
from .scale import Cluster, map_ordered

GRIDS = {
    "m1": [{"braking_weight": b, "release_cost": c} for c in (0.0, 5.0, 20.0) for b in (0.5, 1.0, 2.0, 4.0)],
    # Model 2 (reward "hazard"): the price of the hazard against braking; the release cost
    # stays at its default (2): hysteresis is a requirement, not a trade (docs/models.md section 7)
    "m2": [{"collision_weight": w} for w in (0.125, 0.25, 0.5, 1.0, 2.0)],
}
WEIGHTS = ("collision_weight", "braking_weight", "release_cost")


def read_grid(path) -> list[dict]:
    """A TOML file of weight lists (keys WEIGHTS, each a list of numbers >= 0) as every
    combination of them."""
    import itertools

    from monitor.offline.params import ConfigError, read_toml

    data = read_toml(path)
    unknown = sorted(set(data) - set(WEIGHTS))
    if unknown or not data:
        raise ConfigError(f"{path}: a grid sets lists of {', '.join(WEIGHTS)}"
                          + (f"; unknown: {', '.join(unknown)}" if unknown else ""))
    for key, values in data.items():
        if not isinstance(values, list) or not values or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0 for v in values):
            raise ConfigError(f"{path}: {key} must be a non-empty list of numbers >= 0")
    keys = list(data)
    return [dict(zip(keys, map(float, combo))) for combo in itertools.product(*(data[k] for k in keys))]


def solve_point(name: str, weights: dict, out_dir: Path, time_budget: Optional[float],
                layered_search: Optional[str] = None) -> Path:
    """Solve and compile the model with these weights; the table's path (alphas beside it).
    `layered_search` overrides the model's plan (layered.SEARCHES), as `railguard solve` does."""
    spec = MODELS[name]
    model = spec.build(override(spec.params, weights))
    plan = spec.plan if time_budget is None else replace(spec.plan, settings=replace(spec.plan.settings, time_budget_s=time_budget))
    plan = replace(plan, layered_search=layered_search or plan.layered_search)
    # the frontier judges tables in the world; the relaxation's bound would certify nothing it shows
    result = pipeline.run(model, replace(plan, relaxation=None))
    return pipeline.write(result, out_dir)["table"]


def judge_table(table: Path, quick: bool, seed: int) -> dict:
    """The table's figures, judged as `railguard evaluate` judges it."""
    target = load_target(str(table))
    row = evaluate.judge(target, SIZES["quick" if quick else "full"], seed, names=("table",))["table"]
    return {**row, "nodes": target.controller.nodes, "sha256": decode(target.table).sha256}


def baselines(table: Path, quick: bool, seed: int) -> dict:
    """The baselines judged the same way (belief tracking with this table's alpha vectors)."""
    rows = evaluate.judge(load_target(str(table)), SIZES["quick" if quick else "full"], seed)
    rows.pop("table")
    return rows


def dominates(a: dict, b: dict) -> bool:
    """a no worse than b on both p_hazard and unnecessary braking (evaluate.no_worse)."""
    return all(no_worse(a, b).values())


def frontier(points: list[dict]) -> list[int]:
    """Indices of the points that no other point beats on both (strictly on one)."""
    keep = []
    for i, p in enumerate(points):
        beaten = any(dominates(q, p) and (q["p_hazard"] < p["p_hazard"] or q["unnecessary_braking"] < p["unnecessary_braking"])
                     for j, q in enumerate(points) if j != i)
        if not beaten:
            keep.append(i)
    return sorted(keep, key=lambda i: points[i]["unnecessary_braking"])


def _point(job: tuple) -> dict:
    """One point of the sweep (a dask task): solve, compile and judge."""
    name, weights, out_dir, time_budget, quick, seed, layered_search = job
    table = solve_point(name, weights, out_dir, time_budget, layered_search)
    return {"weights": weights, "table": str(table), **judge_table(table, quick, seed)}


def sweep(name: str, out_dir: Path, quick: bool = True, time_budget: Optional[float] = None,
          grid: Optional[list[dict]] = None, seed: int = SEED, progress: Optional[Callable[[str], None]] = None,
          cluster: Cluster = Cluster(1), layered_search: Optional[str] = None) -> dict:
    """Every weight vector of `grid` solved and judged, one dask task per point on `cluster`
    (default: in this process; each solve is time-budgeted, so points that share a core get
    less solver time each); `layered_search` as in solve_point."""
    say = progress or (lambda text: None)
    grid = GRIDS[name] if grid is None else grid
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    say(f"pareto {name}: {len(grid)} points (solve, compile and judge each) on {cluster.describe()}")
    search = layered_search or MODELS[name].plan.layered_search
    jobs = [(name, weights, out_dir / f"{name}-point{i:02d}", time_budget, quick, seed, search)
            for i, weights in enumerate(grid)]
    points = map_ordered(_point, jobs, cluster, progress=say, label=f"pareto {name}", unit="points")
    defaults = MODELS[name].params      # belief tracking with the alpha vectors of the model's own weights
    default = next((i for i, w in enumerate(grid) if all(getattr(defaults, k, None) == v for k, v in w.items())), 0)
    say(f"pareto {name}: baselines (belief tracking with point {default}'s alpha vectors)")
    base = baselines(Path(points[default]["table"]), quick, seed)
    front = frontier(points)
    ok = [i for i in front if all(dominates(points[i], base[b]) for b in evaluate.ACCEPTED.get(name, ()) if b in base)]
    return {
        "model": name,
        "horizon_s": HORIZON_S,
        "quick": quick,
        "seed": seed,
        "layered_search": search if MODELS[name].plan.conditions else None,
        "points": points,
        "frontier": front,
        "dominating": ok,
        "recommended": min(ok, key=lambda i: (points[i]["unnecessary_braking"], points[i]["p_hazard"])) if ok else None,
        "baselines": base,
        "seconds": time.perf_counter() - t0,
    }


def render(result: dict) -> str:
    search = f"; layered search {result['layered_search']}" if result.get("layered_search") else ""
    lines = [f"Pareto sweep of {result['model']}: {len(result['points'])} weight vectors, p_hazard (exact, "
             f"{result['horizon_s']:g} s) against unnecessary braking (seed world{search})", ""]
    names = [", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in p["weights"].items())
             for p in result["points"]]
    wide = max([48, *(len(w) + 2 for w in names)])
    lines.append(f"{'#':>3} {'weights':<{wide}}{'p_hazard':>12}{'unnecessary':>14}{'nodes':>7}  ")
    for i, (p, w) in enumerate(zip(result["points"], names)):
        mark = ("*" if i == result["recommended"] else "F") if i in result["frontier"] else " "
        lines.append(f"{i:>3} {w:<{wide}}{p['p_hazard']:>12.6f}{p['unnecessary_braking']:>14.5f}{p['nodes']:>7}  {mark}")
    lines.append("")
    for name, b in result["baselines"].items():
        lines.append(f"    {name:<{wide}}{b['p_hazard']:>12.6f}{b['unnecessary_braking']:>14.5f}")
    lines.append("")
    held = " and ".join(evaluate.ACCEPTED.get(result["model"], ())) or "no baseline"
    lines.append(f"F: on the frontier; *: recommended (on the frontier, no worse than {held} on both figures, "
                 "least unnecessary braking)")
    if result["recommended"] is None:
        lines.append(f"no frontier point dominates {held}")
    return "\n".join(lines) + "\n"


def plot(result: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = result["points"]
    fig, ax = plt.subplots(figsize=(7.5, 5.2), constrained_layout=True)
    ax.scatter([p["unnecessary_braking"] for p in pts], [p["p_hazard"] for p in pts], color="tab:gray", s=25,
               label="solved tables")
    front = result["frontier"]
    ax.plot([pts[i]["unnecessary_braking"] for i in front], [pts[i]["p_hazard"] for i in front], "o-", color="tab:blue",
            label="frontier")
    if result["recommended"] is not None:
        r = pts[result["recommended"]]
        ax.scatter([r["unnecessary_braking"]], [r["p_hazard"]], marker="*", s=220, color="tab:green", zorder=5,
                   label="recommended")
    draw_policies(ax, result["baselines"], highlight="", color="tab:red")
    hazard_axes(ax, result["horizon_s"], f"{result['model']}: tables over the cost weights, and the baselines "
                                         "(lower left is better)")
    ax.legend(loc="upper right")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
