"""Seed 000 as a verification part: `section(out_dir, quick, progress)` simulates the five
worlds, replays trains through the real core, checks collisions, the obstacle generator,
the noise, R1/R2 and the phantom stops, and draws Fig. 7.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..report import Check, Progress, Section
from .figures import draw_fig7, draw_zone_bars, episode_series, pick_episode
from .markdown import section_markdown
from .runs import (
    CORE_TRAINS, FULL, PHANTOM_STOPS_BEFORE, PHANTOM_STOPS_FACTOR, QUICK, RUN_KEYS, SEEDS, TARGET, stops_per_hour,
)
from .world import (
    LITERAL, PAPER, PHANTOMS, PHANTOMS_HELD, Run, SHIPPED, core_agreement, expected_obstacle_fraction, simulate,
)


TITLE = "Seed 000 reproduced: Model 1 simulation through the monitor core (Fig. 7)"


def section(out_dir: Path, quick: bool, progress: Progress) -> Section:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    sizes = QUICK if quick else FULL
    runs: dict[str, Run] = {}
    for sc in (SHIPPED, PAPER, LITERAL, PHANTOMS, PHANTOMS_HELD):
        n, secs = sizes[sc.key]
        progress(f"seed000: simulating {sc.key}: {n} trains x {secs:.0f} s")
        runs[sc.key] = simulate(sc, n, secs, SEEDS[sc.key], record=max(24, CORE_TRAINS[quick]), progress=progress)
    main, paper, literal, phantoms, held = (runs[k] for k in RUN_KEYS)

    checks: list[Check] = []
    agree = {}
    for key in ("shipped", "paper_zones", "shipped_phantoms", "phantoms_held"):
        progress(f"seed000: replaying {CORE_TRAINS[quick]} trains of {key} through the real core")
        ok, cycles, k = core_agreement(runs[key], CORE_TRAINS[quick])
        agree[key] = (ok, cycles, k)
        checks.append(Check(f"seed000: {key} run agrees with monitor.core.cycle.step", ok and k >= 20,
                            f"{k} trains, {cycles:,} cycles identical" if ok else f"mismatch after {cycles:,} cycles",
                            {"trains": k, "cycles": cycles}))
    for r in (main, paper):
        c = r.metrics["collisions"]
        checks.append(Check(f"seed000: collisions ({r.scenario.key})", c == 0,
                            f"{c} collisions in {r.metrics['appearances']:,} obstacles, {r.train_seconds:,.0f} train-s",
                            {"collisions": c}))
    total = sum(r.train_seconds for r in runs.values())
    target = TARGET[quick]
    checks.append(Check("seed000: simulated train-seconds (shipped run)", main.train_seconds >= target,
                        f"{main.train_seconds:,.0f} >= {target:,.0f} (all runs {total:,.0f})",
                        {"shipped": main.train_seconds, "all": total}))
    # obstacle generator against the paper's "about 20 % of the time"
    fr = main.per_train_obstacle / main.steps
    got, se = float(fr.mean()), float(fr.std(ddof=1) / math.sqrt(len(fr)))
    want = expected_obstacle_fraction(SHIPPED, main.steps)
    tol = max(0.005, 4.0 * se)
    checks.append(Check("seed000: time with an obstacle (paper: about 20 %)", abs(got - want) <= tol,
                        f"{got:.4f} vs {want:.4f} expected (+- {tol:.4f}); stationary 0.2000",
                        {"measured": got, "expected": want, "tolerance": tol}))
    lo, hi = SHIPPED.appear_window_m()
    mm = main.metrics
    mean_app = mm["appear_sum"] / max(1, mm["appearances"])
    ok_app = lo <= mm["appear_min"] and mm["appear_max"] <= hi and abs(mean_app - 0.5 * (lo + hi)) <= 2.0
    checks.append(Check("seed000: obstacles appear uniformly in [(a1+a2)/2, +50 m]", ok_app,
                        f"{mm['appear_min']:.1f}..{mm['appear_max']:.1f} m, mean {mean_app:.1f} in [{lo:.1f}, {hi:.1f}]",
                        {"min": mm["appear_min"], "max": mm["appear_max"], "mean": mean_app}))
    nmean = mm["noise_sum"] / max(1, mm["noise_n"])
    nsd = math.sqrt(max(0.0, mm["noise_sq"] / max(1, mm["noise_n"]) - nmean ** 2))
    sig = SHIPPED.noise_sigma_m
    checks.append(Check("seed000: Gaussian distance noise", abs(nsd - sig) <= 0.03 * sig and abs(nmean) <= 0.05 * sig,
                        f"mean {nmean:+.3f} m, sd {nsd:.3f} m vs sigma {sig:.1f} m over {mm['noise_n']:,} reports",
                        {"mean": nmean, "sd": nsd, "n": mm["noise_n"]}))
    r2m = mm["r2_first_sum"] / max(1, mm["r2_first_n"])
    checks.append(Check("seed000: R1/R2 at an obstacle's first report (paper Fig. 7c: R2 about 0.5, R1 low)",
                        0.3 <= r2m <= 0.55 and mm["r1_first_max"] < 0.1,
                        f"R2 mean {r2m:.3f} ({mm['r2_first_min']:.3f}..{mm['r2_first_max']:.3f}), R1 max {mm['r1_first_max']:.3f}",
                        {"r2_mean": r2m, "r1_max": mm["r1_first_max"]}))
    checks.append(phantom_stops_check(phantoms, held, quick))

    # figures: one train of the shipped run (it is among the trains replayed through the core)
    progress("seed000: drawing Fig. 7a-d")
    train, start, stop = pick_episode(main)
    series = episode_series(main, train, start, stop)
    figs = draw_fig7(series, out_dir, "seed000_fig7", (300.0, 100.0))
    ptrain, pstart, pstop = pick_episode(paper, before_s=5.0, length_s=30.0)
    pseries = episode_series(paper, ptrain, pstart, pstop)
    figs += draw_fig7(pseries, out_dir, "seed000_paperzones_fig7", (300.0, 100.0))
    figs.append(draw_zone_bars([main, paper, literal, phantoms, held], out_dir, "seed000_zones.png"))

    md = section_markdown(runs, agree, series, (train, start, stop), pseries, (ptrain, pstart, pstop), figs, quick)
    return Section(TITLE, md, checks, figs)


def phantom_stops_check(phantoms: Run, held: Run, quick: bool) -> Check:
    """Issue 11: a phantom must no longer stop the train. With the revocable release the
    phantom world stops without an obstacle at most PHANTOM_STOPS_FACTOR as often as it
    stopped at all before the braking curves (then nearly every stop was a phantom's: 593 of
    613 onsets had no obstacle); held to standstill (emergency_release = 0) it must stop so
    more often than revocable. Stops for a real obstacle are not counted: since issue 12 the
    m1 table brakes an obstacle that stays reported down to standstill, as it should."""
    before = PHANTOM_STOPS_BEFORE["quick" if quick else "full"]["stops"]
    after, after_held = stops_per_hour(phantoms, "stops_no_obstacle"), stops_per_hour(held, "stops_no_obstacle")
    return Check("seed000: stops without an obstacle per train-hour with Model 1's 2 % phantoms (revocable release vs "
                 "every stop before the curves)",
                 after <= PHANTOM_STOPS_FACTOR * before and after < after_held,
                 f"{after:.1f} <= {PHANTOM_STOPS_FACTOR:g} x {before:.1f} (commit {PHANTOM_STOPS_BEFORE['commit']}); "
                 f"held to standstill {after_held:.1f}; all stops now {stops_per_hour(phantoms):.1f}",
                 {"before": before, "after_revocable": after, "after_held": after_held,
                  "all_stops_revocable": stops_per_hour(phantoms)})
