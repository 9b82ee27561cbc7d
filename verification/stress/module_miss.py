"""What a module that never sees the obstacle costs (issue 38 item 5): P(collision per encounter
| module 0 never sees the object) by naive Monte Carlo under the nominal disturbance model (its
blindness, misses, lost frames, ghosts and noise), with the memory as shipped and with the
memory of before issue 38 (only a confirmed picture creates a track: `memory.observe` called
with sighted = confirmed). Multiplied by P(some module misses) = 1 - (1 - P_MODULE_MISS)^3 it is
the module misses' share of P(collision per encounter).

    python -m verification.stress.module_miss [--runs N] [--table m2] [--encounter edge-30] [--case module|behind] [--json]

About 12 ms per run on this machine (5,000 runs per memory: a minute each).

`--case behind`: what a nearer hidden obstacle costs (issue 38 item 2): the same encounters
with a farther object behind the obstacle (the channels that miss the obstacle see past it,
to the object, `disturbances.P_BEHIND`), against the same sequences with none behind; the
shipped memory both times. Times P_BEHIND, the difference is its share.
"""
from __future__ import annotations

import argparse
import json
import math
from contextlib import contextmanager

import numpy as np

from monitor.core import cycle, memory
from monitor.core.config import Config
from monitor.core.types import NO_TRACK

from .. import world_train
from .disturbances import MODULES, NOMINAL, P_BEHIND, P_MODULE_MISS, log_weight
from .encounters import ENCOUNTERS
from .loop import closed_loop

MEMORIES = ("shipped", "before-issue-38")


@contextmanager
def memory_rule(name: str):
    """The core's memory as shipped, or as it was before issue 38 (in this process only)."""
    if name == "shipped":
        yield
        return
    real, real_insert = cycle.observe, cycle.insert
    cycle.observe = lambda near, far, closing, d, own, age, confirmed, sighted: memory.observe(
        near, far, closing, d, own, age, confirmed, confirmed)
    # (several tracks: a picture that creates nothing then must not take a slot)
    cycle.insert = lambda tracks, ages, states, new, age, state: (
        (tracks, ages, states) if new.near == NO_TRACK else real_insert(tracks, ages, states, new, age, state))
    try:
        yield
    finally:
        cycle.observe, cycle.insert = real, real_insert


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95 % Wilson interval of k in n."""
    p = k / n
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    centre = p + z * z / (2 * n)
    return max(0.0, (centre - half) / (1 + z * z / n)), (centre + half) / (1 + z * z / n)


def estimate(model: str = "m2", encounter: str = "edge-30", runs: int = 5000, seed: int = 38,
             memory_name: str = "shipped") -> dict:
    """Failures among `runs` encounters with module 0 blind to the object throughout."""
    world = world_train.corners(Config())[0]
    ds = NOMINAL.sample(np.random.default_rng(seed), runs)
    failures = 0
    with memory_rule(memory_name):
        for d in ds:
            d.module[:] = [m == 0 for m in range(MODULES)]
            failures += closed_loop(model, ENCOUNTERS[encounter], d, world)["failure"]
    share = 1.0 - (1.0 - P_MODULE_MISS) ** MODULES
    lo, hi = wilson(failures, runs)
    return {"memory": memory_name, "table": model, "encounter": encounter, "runs": runs, "seed": seed,
            "failures": failures, "p_given_module_miss": failures / runs, "ci95": [lo, hi],
            "p_some_module_misses": share, "share_of_p_collision": share * failures / runs}


def estimate_behind(model: str = "m2", encounter: str = "edge-30", runs: int = 5000, seed: int = 38) -> list[dict]:
    """P(failure per encounter) with an object behind the obstacle and, on the same sequences,
    with none (the shipped memory both times), importance-sampled from the search's first
    proposal (a common-cause blindness begins with 5 % per cycle: what makes the memory
    decide), each run weighted by p / q over the cycles it read; and the sequences whose
    outcome the object behind changes."""
    world = world_train.corners(Config())[0]
    proposal = NOMINAL.explore()
    ds = proposal.sample(np.random.default_rng(seed), runs)
    out = {}
    for behind in (True, False):
        fails, weights = [], []
        for d in ds:
            d.behind[:] = behind
            r = closed_loop(model, ENCOUNTERS[encounter], d, world)
            fails.append(r["failure"])
            d.behind[:] = False                       # (the weight of the sequence without its object behind:
            weights.append(math.exp(log_weight(d, proposal, r["cycles"])))    # it is the condition, not drawn)
        out[behind] = (np.array(fails), np.array(weights))
    rows = []
    for behind in (True, False):
        f, w = out[behind]
        p = float(np.mean(f * w))
        se = float(np.std(f * w) / math.sqrt(runs))
        rows.append({"memory": "shipped", "object_behind": behind, "table": model, "encounter": encounter,
                     "runs": runs, "seed": seed, "failures": int(f.sum()), "p_given": p,
                     "ci95": [max(0.0, p - 1.96 * se), p + 1.96 * se],
                     "effective_failures": float((f * w).sum() ** 2 / max((f * w * w).sum(), 1e-300)),
                     "changed_by_the_object": int(np.sum(out[True][0] != out[False][0])),
                     "p_object_behind": P_BEHIND})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification.stress.module_miss", description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5000, help="encounters per memory (default: 5000)")
    ap.add_argument("--table", choices=("m1", "m2"), default="m2", help="(default: m2)")
    ap.add_argument("--encounter", choices=sorted(ENCOUNTERS), default="edge-30", help="(default: edge-30)")
    ap.add_argument("--seed", type=int, default=38, help="(default: 38)")
    ap.add_argument("--case", choices=("module", "behind"), default="module",
                    help="module: a module that never sees the obstacle; behind: a farther object behind it "
                         "(default: module)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    if args.case == "behind":
        rows = estimate_behind(args.table, args.encounter, args.runs, args.seed)
        extra = (rows[0]["p_given"] - rows[1]["p_given"]) * P_BEHIND
        lines = [f"{'object behind' if r['object_behind'] else 'none behind':>16}: {r['failures']} of {r['runs']} "
                 f"sampled encounters fail; P(collision per encounter) = {r['p_given']:.2e} "
                 f"(95 % {r['ci95'][0]:.2e}..{r['ci95'][1]:.2e}, {r['effective_failures']:.1f} effective failures)"
                 for r in rows]
        lines += [f"outcomes the object behind changes: {rows[0]['changed_by_the_object']} of {args.runs}",
                  f"share of P(collision per encounter): ({rows[0]['p_given']:.2e} - {rows[1]['p_given']:.2e}) x "
                  f"P_BEHIND {P_BEHIND} = {extra:.1e}"]
    else:
        rows = [estimate(args.table, args.encounter, args.runs, args.seed, m) for m in MEMORIES]
        lines = [f"{r['memory']:>16}: {r['failures']} of {r['runs']} encounters fail = {r['p_given_module_miss']:.2e} "
                 f"(95 % {r['ci95'][0]:.2e}..{r['ci95'][1]:.2e}) given a module's miss; times "
                 f"P(some module misses) {r['p_some_module_misses']:.4f} = {r['share_of_p_collision']:.2e} per encounter"
                 for r in rows]
    print(json.dumps({"rows": rows}) if args.json else "\n".join(lines))
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
