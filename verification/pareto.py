"""`railguard solve --pareto`: the cost weights swept, each table judged on risk and needless braking.

A reward is a choice; the frontier shows what the choice costs. For each weight vector
(collision, braking, demand change: the models' `collision_weight`, `braking_weight`,
`release_cost`) the model is solved and compiled, and its table is judged exactly as
`railguard evaluate` judges it: p_hazard exact on the closed loop with the supervision in
front, unnecessary braking by Monte Carlo in the seed world (the quick size, the same seed
for every point: common random numbers). The frontier is the set of points no other point
beats on both figures' estimates. Every point is compared with every baseline as
`railguard evaluate` compares the table (evaluate.compare on p_hazard and unnecessary
braking: one-sided tests with the burden on the table, belief tracking's P(hazard) by the
sharp estimator, unnecessary braking train by train); a table may ship only from the
frontier and only if its verdict is `better` against each baseline its model is held to,
on the figures it is held to (ACAS X's acceptance rule, evaluate.ACCEPTED); `recommended`
is, among those also better than belief tracking where there are any (issue 31), the safest
of the points whose unnecessary braking the paired test cannot tell from the least one's
(`recommend`, issue 41; before, the least point estimate). Each point meets belief tracking as
`evaluate` would judge it if it shipped: with the point's own alpha vectors (the same reward,
no compilation); `better_than` lists, per baseline, every point whose verdict against it is
`better`, and under REFERENCE the points better than belief tracking with the default
weights, one yardstick for all. Measured at full size (issue 31): no m1 or m2 point is as
safe as its own belief tracking, while m2's collision weights 2 to 16 beat the default
weights' belief tracking on both figures, with 15 to 24 more stops per train-hour.
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
from .evaluate import (
    ACCEPTANCE, SEED, SIZES, compare, compare_figure, draw_policies, hazard_axes, load_target, public_row,
)
from .closed_loop import HORIZON_S
from .policies import finite_baselines
from .scale import Cluster, map_ordered

GRIDS = {
    "m1": [{"braking_weight": b, "release_cost": c} for c in (0.0, 5.0, 20.0) for b in (0.5, 1.0, 2.0, 4.0)],
    # Model 2 (reward "hazard"): the price of the hazard against braking; the release cost
    # stays at its default (2): hysteresis is a requirement, not a trade (docs/models.md section 7).
    # 4 to 16 since issue 31: there the tables are safer than belief tracking with the default
    # weights and brake needlessly less, but still riskier than their own belief tracking
    "m2": [{"collision_weight": w} for w in (0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)],
}
WEIGHTS = ("collision_weight", "braking_weight", "release_cost")
SHORT = {"better": "better", "worse": "worse", "indistinguishable": "indist.", "equal": "equal"}
PREFERRED = "belief_tracking"
# Belief tracking with the default point's alpha vectors: one yardstick for every point (a
# point's own belief tracking moves with its weights). Reported, not what a point is held to.
REFERENCE = "belief_tracking_default_weights"


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
    """The table's figures, judged as `railguard evaluate` judges it (with its per-train
    sums under `_per_train`, for the paired tests), and under `_own` those of belief
    tracking with the table's own alpha vectors: the baseline `evaluate` holds it to."""
    target = load_target(str(table))
    rows = evaluate.judge(target, SIZES["quick" if quick else "full"], seed, names=("table", PREFERRED))
    return {**rows["table"], "nodes": target.controller.nodes, "sha256": decode(target.table).sha256,
            "_own": rows[PREFERRED]}


def baselines(point: dict, quick: bool, seed: int) -> dict:
    """The baselines judged the same way; belief tracking is the point's own (with its
    table's alpha vectors, its sharp estimate guided by that table), judged with the point."""
    target = load_target(point["table"])
    finite = tuple(finite_baselines(target.model))
    rows = evaluate.judge(target, SIZES["quick" if quick else "full"], seed, names=finite)
    return {**rows, PREFERRED: point["_own"]}


def against(point: dict, base: dict) -> dict:
    """A point against a baseline on the acceptance figures (evaluate.compare) and the
    policy's own braking: the verdict on the acceptance figures and, per figure, the
    difference, its 95 % half-width and the decision."""
    c = compare(point, base, (*ACCEPTANCE, "policy_braking"))
    return {"verdict": c["acceptance"],
            **{k: {key: f[key] for key in ("difference", "ci", "p_better", "p_worse", "decision")}
               for k, f in c["figures"].items()}}


def held(name: str, point: dict, base: dict) -> bool:
    """Does the point meet ACAS X's rule as the model's table is held to it (evaluate.ACCEPTED:
    the verdict on each held baseline's figures is `better`; a baseline not judged fails)?"""
    for b, figures in evaluate.ACCEPTED.get(name, {}).items():
        if b not in base:
            return False
        if evaluate.verdict({k: point["against"][b][k]["decision"] for k in figures}) != "better":
            return False
    return True


def frontier(points: list[dict]) -> list[int]:
    """Indices of the points that no other point beats on both estimates (at least as low on
    p_hazard and unnecessary braking, strictly lower on one), by unnecessary braking."""
    def beats(q: dict, p: dict) -> bool:
        return (q["p_hazard"] <= p["p_hazard"] and q["unnecessary_braking"] <= p["unnecessary_braking"]
                and (q["p_hazard"] < p["p_hazard"] or q["unnecessary_braking"] < p["unnecessary_braking"]))

    keep = [i for i, p in enumerate(points) if not any(beats(q, p) for j, q in enumerate(points) if j != i)]
    return sorted(keep, key=lambda i: points[i]["unnecessary_braking"])


def recommend(points: list[dict], preferred: list[int]) -> Optional[int]:
    """Of the preferred points, the safest (exact p_hazard) among those whose unnecessary
    braking the world cannot tell from the least one's (the paired test does not call them
    worse): braking decides where the world sees it, safety everywhere else. The least point
    estimate alone picked by noise: in m2's world every point brakes needlessly 0.49 of the
    low-risk time, +- 0.02, the memory's braking behind every policy (issue 41)."""
    if not preferred:
        return None
    key = "unnecessary_braking"
    least = min(preferred, key=lambda i: (points[i][key], points[i]["p_hazard"]))
    alike = [i for i in preferred if compare_figure(key, points[i], points[least])["decision"] != "worse"]
    return min(alike, key=lambda i: (points[i]["p_hazard"], points[i][key]))


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
    base = baselines(points[default], quick, seed)
    for p in points:
        # belief tracking as `railguard evaluate` would judge this point if it shipped: with its
        # own alpha vectors (the same reward); the default point's under REFERENCE
        p["against"] = {b: against(p, p["_own"] if b == PREFERRED else row) for b, row in base.items()}
        p["against"][REFERENCE] = against(p, base[PREFERRED])
        p["own_belief_tracking"] = public_row(p["_own"])
    front = frontier(points)
    ok = [i for i in front if held(name, points[i], base)]
    # issue 31: where frontier points that meet the rule are also better than belief tracking
    # (no riskier by its sharp estimate, less needless braking), the recommendation is among them
    preferred = [i for i in ok if points[i]["against"].get(PREFERRED, {}).get("verdict") == "better"] or ok
    return {
        "model": name,
        "horizon_s": HORIZON_S,
        "quick": quick,
        "seed": seed,
        "layered_search": search if MODELS[name].plan.conditions else None,
        "baseline_alphas": default,
        "points": [public_row(p) for p in points],
        "frontier": front,
        "dominating": ok,
        "better_than": {b: [i for i, p in enumerate(points) if p["against"][b]["verdict"] == "better"]
                        for b in (*base, REFERENCE)},
        "preferred": preferred,
        "recommended": recommend(points, preferred),
        "baselines": {b: public_row(row) for b, row in base.items()},
        "seconds": time.perf_counter() - t0,
    }


def render(result: dict) -> str:
    search = f"; layered search {result['layered_search']}" if result.get("layered_search") else ""
    lines = [f"Pareto sweep of {result['model']}: {len(result['points'])} weight vectors, p_hazard (exact, "
             f"{result['horizon_s']:g} s) against unnecessary braking (seed world{search})", ""]
    names = [", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in p["weights"].items())
             for p in result["points"]]
    wide = max([48, *(len(w) + 2 for w in names)])
    verdicts = all("against" in p for p in result["points"])
    own = verdicts and all("own_belief_tracking" in p for p in result["points"])
    policy_own = all("policy_braking" in p for p in result["points"])      # sweeps since issue 41
    bases = [b for b in ("threshold", "belief_tracking") if b in result["baselines"]] + ([REFERENCE] if own else [])
    heads = {REFERENCE: "vs BT, default weights", "belief_tracking": "vs belief_tracking (own)" if own else "vs belief_tracking"}
    lines.append(f"{'#':>3} {'weights':<{wide}}{'p_hazard':>12}{'unnecessary':>14}" + (f"{'policy own':>12}" if policy_own else "")
                 + f"{'nodes':>7}" + (f"{'own BT p':>12}" if own else "") + "  "
                 + ("".join(f"  {heads.get(b, 'vs ' + b):<26}" for b in bases) if verdicts else ""))
    for i, (p, w) in enumerate(zip(result["points"], names)):
        mark = ("*" if i == result["recommended"] else "F") if i in result["frontier"] else " "
        line = (f"{i:>3} {w:<{wide}}{p['p_hazard']:>12.6f}{p['unnecessary_braking']:>14.5f}"
                + (f"{p['policy_braking']:>12.5f}" if policy_own else "") + f"{p['nodes']:>7}")
        line += (f"{p['own_belief_tracking']['p_hazard']:>12.6f}" if own else "") + f"  {mark}"
        if verdicts:
            for b in bases:
                a = p["against"][b]
                word = f"{a['verdict']} ({SHORT[a['p_hazard']['decision']]}/{SHORT[a['unnecessary_braking']['decision']]})"
                line += f"  {word:<26}"
        lines.append(line)
    lines.append("")
    for name, b in result["baselines"].items():
        ci = b.get("p_hazard_ci") or 0.0
        name = f"{name} (default weights)" if own and name == PREFERRED else name
        lines.append(f"    {name:<{wide}}{b['p_hazard']:>12.6f}{b['unnecessary_braking']:>14.5f}"
                     + (f"{b['policy_braking']:>12.5f}" if policy_own else "")
                     + (f"  (p_hazard ± {ci:.2g}, sharp estimate)" if ci else ""))
    lines.append("")
    held = " and ".join(f"{b} on {' and '.join(f)}" for b, f in evaluate.ACCEPTED.get(result["model"], {}).items()) \
        or "no baseline"
    if verdicts:
        lines.append("vs B: the verdict on p_hazard and unnecessary braking against B (paired one-sided tests, the burden "
                     "on the table), then p_hazard's and unnecessary braking's decisions (indist.: indistinguishable)")
        lines.append(f"F: on the frontier; *: recommended (on the frontier, better than {held}; among those better than "
                     f"{PREFERRED} too where there are any; "
                     + ("the safest of those whose unnecessary braking the paired test cannot tell from the least)"
                        if policy_own else "least unnecessary braking)"))
        if policy_own:
            lines.append("policy own: the share of the time without need in which the policy alone asked for braking "
                         "(no supervision cause: what the policy adds to the curves' and the memory's braking)")
        if own:
            lines.append("own BT p: belief tracking with the point's own alpha vectors, its sharp P(hazard): what "
                         "`railguard evaluate` holds the table to; BT, default weights: the default point's, one yardstick")
        for b, idx in result.get("better_than", {}).items():
            lines.append(f"better than {b}: " + (", ".join(f"#{i}" for i in idx) if idx else "no point"))
    else:
        lines.append(f"F: on the frontier; *: recommended (on the frontier, no worse than {held} on both figures, "
                     "least unnecessary braking; a sweep from before the paired tests)")
    if result["recommended"] is None:
        lines.append(f"no frontier point is better than {held}")
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
