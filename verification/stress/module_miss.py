"""What a module that never sees the obstacle costs (issue 38 item 5): P(collision per encounter
| module 0 never sees the object) by naive Monte Carlo under the nominal disturbance model (its
blindness, misses, lost frames, ghosts and noise), with the memory as shipped and with the
memory of before issue 38 (only a confirmed picture creates a track: `memory.observe` called
with sighted = confirmed). Multiplied by P(some module misses) = 1 - (1 - P_MODULE_MISS)^3 it is
the module misses' share of P(collision per encounter).

    python -m verification.stress.module_miss [--runs N] [--table m2] [--encounter edge-30] [--json]

About 12 ms per run on this machine (5,000 runs per memory: a minute each).
"""
from __future__ import annotations

import argparse
import json
import math
from contextlib import contextmanager

import numpy as np

from monitor.core import cycle, memory
from monitor.core.config import Config

from .. import world_train
from .disturbances import MODULES, NOMINAL, P_MODULE_MISS
from .encounters import ENCOUNTERS
from .loop import closed_loop

MEMORIES = ("shipped", "before-issue-38")


@contextmanager
def memory_rule(name: str):
    """The core's memory as shipped, or as it was before issue 38 (in this process only)."""
    if name == "shipped":
        yield
        return
    real = cycle.observe
    cycle.observe = lambda near, far, closing, d, own, age, confirmed, sighted: memory.observe(
        near, far, closing, d, own, age, confirmed, confirmed)
    try:
        yield
    finally:
        cycle.observe = real


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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification.stress.module_miss", description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5000, help="encounters per memory (default: 5000)")
    ap.add_argument("--table", choices=("m1", "m2"), default="m2", help="(default: m2)")
    ap.add_argument("--encounter", choices=sorted(ENCOUNTERS), default="edge-30", help="(default: edge-30)")
    ap.add_argument("--seed", type=int, default=38, help="(default: 38)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    rows = [estimate(args.table, args.encounter, args.runs, args.seed, m) for m in MEMORIES]
    if args.json:
        print(json.dumps({"rows": rows}))
    else:
        for r in rows:
            print(f"{r['memory']:>16}: {r['failures']} of {r['runs']} encounters fail = {r['p_given_module_miss']:.2e} "
                  f"(95 % {r['ci95'][0]:.2e}..{r['ci95'][1]:.2e}) given a module's miss; times "
                  f"P(some module misses) {r['p_some_module_misses']:.4f} = {r['share_of_p_collision']:.2e} per encounter")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
