"""Belief tracking's P(hazard) by the sharp estimator: estimate, 95 % half-width, episodes and seconds.

Run: python benchmarks/bench_sharp.py [--models m1 m2] [--sizes quick full] [--plain] [--json]

For each shipped table and size, `railguard evaluate`'s estimate of belief tracking's
P(hazard within 30 s) (verification/sharp_hazard.py: conditional Monte Carlo with the
exact next-step hazard, importance sampling guided by the table's exact values; the
episodes of evaluate.belief_episodes) against the table's exact figure, with the seconds
it took (the guide's exact values included). `--plain` adds the conditional estimator
without the guide over the same episodes, to show what the importance sampling buys: its
half-width is the one to compare (m2: about 15 times wider).
Figures vary with the machine's load; the 95 % half-width does not.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", nargs="+", default=["m1", "m2"], choices=["m1", "m2"])
    p.add_argument("--sizes", nargs="+", default=["quick", "full"], choices=["quick", "full"])
    p.add_argument("--plain", action="store_true", help="also the estimator without the guide")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)

    from verification import evaluate as ev
    from verification import sharp_hazard as sh
    from verification.closed_loop import HORIZON_S

    steps = int(round(HORIZON_S / 0.1))
    rows = []
    for name in args.models:
        target = ev.load_target(name)
        exact = ev.hazard_exact(target.model, target.controller, steps)
        for size in args.sizes:
            episodes = ev.belief_episodes(target.model, ev.SIZES[size])
            t0 = time.perf_counter()
            est = ev.hazard_belief(target, steps, episodes, ev.SEED)
            row = {"model": name, "size": size, "episodes": episodes, "estimate": est.p, "half_width": est.ci,
                   "relative": est.relative, "seconds": time.perf_counter() - t0, "table_exact": exact}
            if args.plain:
                plain = sh.estimate(target.model, sh.belief_tracking(target.model, *target.alphas), steps, episodes, ev.SEED)
                row.update(plain_estimate=plain.p, plain_half_width=plain.ci, plain_seconds=plain.seconds)
            rows.append(row)
    if args.json:
        print(json.dumps(rows))
        return 0
    print(f"{'model':<6}{'size':<7}{'episodes':>9}{'estimate':>12}{'± 95 %':>11}{'relative':>10}{'seconds':>9}"
          f"{'table (exact)':>15}" + (f"{'plain ± 95 %':>22}" if args.plain else ""))
    for r in rows:
        print(f"{r['model']:<6}{r['size']:<7}{r['episodes']:>9,}{r['estimate']:>12.4g}{r['half_width']:>11.2g}"
              f"{r['relative']:>10.1%}{r['seconds']:>9.1f}{r['table_exact']:>15.4g}"
              + (f"{r['plain_estimate']:>12.3g} ± {r['plain_half_width']:<8.2g}" if args.plain else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
