"""The paired one-sided tests that decide `railguard evaluate`'s comparisons (issue 31 item 7).

Each figure is lower-is-better; the difference is table - baseline. The burden is on the
table: it is called better on a figure only if "table >= baseline" is rejected at ALPHA, worse
only if "table <= baseline" is, and otherwise indistinguishable. A baseline's verdict
combines the figures: better (better somewhere, worse nowhere), worse, trade-off (better on
one, worse on another) or indistinguishable.
"""
from __future__ import annotations

import math

from .world_metrics import paired

ALPHA = 0.05
VERDICTS = ("better", "worse", "trade-off", "indistinguishable")
METRICS = ("p_hazard", "unnecessary_braking", "policy_braking", "stops_per_train_hour", "demand_changes_per_encounter")
ACCEPTANCE = ("p_hazard", "unnecessary_braking")   # what ACAS X's acceptance rule reads (DESIGN section 12)


def _phi(z: float) -> float:
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def decide(diff: float, se: float) -> dict:
    """One figure, lower is better, diff = table - baseline with standard error se (0: both
    exact). One-sided tests at ALPHA, the burden on the table: `p_better` is the p-value of
    "table >= baseline", `p_worse` of "table <= baseline"."""
    if math.isnan(diff) or math.isnan(se):
        return {"decision": "indistinguishable", "p_better": float("nan"), "p_worse": float("nan")}
    if se == 0.0:
        decision = "better" if diff < 0 else "worse" if diff > 0 else "equal"
        return {"decision": decision, "p_better": 0.0 if diff < 0 else 1.0, "p_worse": 0.0 if diff > 0 else 1.0}
    z = diff / se
    p_better, p_worse = _phi(z), _phi(-z)
    decision = "better" if p_better < ALPHA else "worse" if p_worse < ALPHA else "indistinguishable"
    return {"decision": decision, "p_better": p_better, "p_worse": p_worse}


def compare_figure(key: str, table: dict, base: dict) -> dict:
    """The table against a baseline on one figure: the difference (table - baseline), its
    95 % two-sided half-width, the test used and the decision (see decide)."""
    if key == "p_hazard":
        t_ci, b_ci = table.get("p_hazard_ci") or 0.0, base.get("p_hazard_ci") or 0.0
        diff = table["p_hazard"] - base["p_hazard"]
        se = math.hypot(t_ci, b_ci) / 1.96
        how = ("exact against exact" if se == 0 else
               "one-sample z on the baseline's sharp estimate (the table's figure is exact)" if t_ci == 0 else
               "two-sample z")
    else:
        a, b = table.get("_per_train", {}).get(key), base.get("_per_train", {}).get(key)
        diff, se = paired(a, b) if a is not None and b is not None else (float("nan"), float("nan"))
        how = f"paired z over {len(a[0]) if a is not None else 0} trains (common random numbers)"
    return {"table": table[key], "baseline": base[key], "difference": diff,
            "ci": 1.96 * se if not math.isnan(se) else float("nan"), "test": how, **decide(diff, se)}


def verdict(decisions: dict) -> str:
    """better / worse / trade-off / indistinguishable from per-figure decisions."""
    better = any(d == "better" for d in decisions.values())
    worse = any(d == "worse" for d in decisions.values())
    return "trade-off" if better and worse else "better" if better else "worse" if worse else "indistinguishable"


def compare(table: dict, base: dict, figures: tuple[str, ...] = METRICS) -> dict:
    """The table against one baseline on `figures`: each figure's test, the verdict on all of
    them and the verdict on the acceptance figures (ACCEPTANCE)."""
    per = {key: compare_figure(key, table, base) for key in figures}
    decisions = {k: v["decision"] for k, v in per.items()}
    return {"figures": per, "verdict": verdict(decisions),
            "acceptance": verdict({k: decisions[k] for k in ACCEPTANCE if k in decisions}),
            "better_on": [k for k, d in decisions.items() if d == "better"],
            "worse_on": [k for k, d in decisions.items() if d == "worse"]}
