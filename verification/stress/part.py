"""Adaptive stress testing as a verification part: `section(out_dir, quick, progress, ...)`
runs `railguard stress` on edge-30 (quick: m2; full: m1, m2 and m2 with every emergency held),
checks that every failure replays from its candump log, and sets the rare-event estimates
against the hazard section's tolerable hazard rates.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

from monitor.core.config import Config

from ..report import Check, Progress, Section, md_table
from ..scale import Cluster
from .command import run, summarise
from .disturbances import BETA, BLIND_STAYS, DISTURBANCES, P_BLIND, P_MISS, P_MODULE_MISS, WINDOW
from .encounters import NOISE_SIGMA_M
from .importance import NO_FAILURE, W_MAX


OLD_LIKELIEST = -9.65     # the likeliest failure before the obstacle memory (a 1.2 s blackout during braking)


def failure_class(failure: Optional[dict], cfg: Config) -> str:
    """What the likeliest failure is (issue 29 item 8): 'none found'; 'unsurvivable' (every
    channel blind from the appearance on, and nothing else: no monitor brakes for what no
    channel has seen); 'beyond the forgetting time' (a blindness at least forget_ms long, less
    likely than the failure found before the memory); or 'survivable' (a defect)."""
    if failure is None:
        return "none found"
    blind = sorted(e["cycle"] for e in failure["events"] if e["kind"] == "blind")
    others = [e for e in failure["events"] if e["kind"] not in ("blind", "noise")]
    if blind and blind[0] == 0 and blind == list(range(len(blind))) and not others:
        return f"unsurvivable: every channel blind from the appearance for {len(blind)} cycles"
    longest, run = 0, 0
    for a, b in zip([None] + blind, blind):
        run = run + 1 if a is not None and b == a + 1 else 1
        longest = max(longest, run)
    if longest * cfg.period_ms >= cfg.forget_ms and failure["log_likelihood"] < OLD_LIKELIEST:
        return f"beyond the forgetting time: blind for {longest * cfg.period_ms / 1000:g} s"
    return "survivable"


def section(out_dir, quick: bool, progress: Progress, config: Optional[Config] = None, world=None,
            margin_m: float = 0.0, cluster: Cluster = Cluster()) -> Section:
    """Adaptive stress testing and rare events as a report part (both tables, edge-30)."""
    cfg = config or Config()
    out = Path(out_dir)
    checks, rows, figures = [], [], []
    results = {}
    # quick: the m2 table only; full: both, and m2 with every emergency held to standstill
    # (emergency_release = 0), the other side of the release trade-off
    variants = [("m2", "m2", cfg)] if quick else [("m1", "m1", cfg), ("m2", "m2", cfg),
                                                  ("m2", "m2 held", cfg._replace(emergency_release=0))]
    for model, name, run_cfg in variants:
        tag = name.replace(" ", "-")
        r = run(model, "edge-30", out / f"stress-{tag}", quick=quick, cfg=run_cfg, world=world, margin_m=margin_m,
                cluster=cluster, progress=progress)
        results[name] = r
        figures.append(f"stress-{tag}/stress-{model}-edge-30.png")
        for key in ("most_likely_failure", "most_likely_failure_after_release"):
            f = r[key]
            if f is not None:
                checks.append(Check(f"stress {name}: the {key.replace('_', ' ')} replays from its candump log",
                                    bool(f["replay_reproduces"]), f"{f['candump']}: "
                                    + ("same demand every cycle" if f["replay_reproduces"] else "demands differ")))
        verdict = failure_class(r["most_likely_failure"], run_cfg)
        checks.append(Check(f"stress {name}: the likeliest failure is one no monitor survives, or a blindness longer than "
                            f"forget_ms below log-likelihood {OLD_LIKELIEST}", verdict != "survivable",
                            verdict, {"class": verdict}))
        rare = r["rare_event"]
        for key, label in (("most_likely_failure", "likeliest"), ("most_likely_failure_after_release", "after a release")):
            f = r[key]
            rows.append([name, label, "none found" if f is None else f"{f['log_likelihood']:.2f}",
                         "-" if f is None else summarise(f["events"])])
        rows.append([name, "P(collision per encounter)",
                     f"IS {rare['p_importance_sampling']:.3g} ({rare['ci95'][0]:.2g}..{rare['ci95'][1]:.2g}, "
                     f"{rare['effective_failures']:.1f} effective failures)",
                     f"naive MC {rare['naive']['failures']}/{rare['samples']} (95 % upper {rare['naive']['ci95_upper']:.2g})"])
    from ..hazard import THR_CATASTROPHIC, THR_SIL3

    thr_rows = []
    for name, r in results.items():
        rare = r["rare_event"]
        for how, p, hi in (("importance sampling", rare["p_importance_sampling"], rare["ci95"][1]),
                           ("naive Monte Carlo", rare["naive"]["p"], rare["naive"]["ci95_upper"])):
            thr_rows.append([name, how, f"{p:.3g} /h (95 % upper {hi:.2g})",
                             f"{p / THR_SIL3:.2g}x" if p else "0", f"{p / THR_CATASTROPHIC:.2g}x" if p else "0"])
    md = ("The search (`railguard stress`, cross-entropy method; `verification/stress/`) looks for the likeliest "
          "disturbance sequence that makes the world's train (the declaration's worst corner) hit an obstacle it could "
          "have stopped for, in the hardest encounter the supervision is built for: a static object appearing one cycle "
          "of travel beyond EBI at 30 m/s. Disturbances per cycle, in the "
          f"{WINDOW * cfg.period_ms / 1000:g} s from the appearance (the slowest encounter stands still within "
          "them): a common-cause blindness of every channel "
          f"{P_BLIND:.3g} of the time (seed 002's p_n = {P_MISS} times a beta factor of {BETA}: it begins with "
          f"{DISTURBANCES['blind']:.3g} per clear cycle and goes on with {BLIND_STAYS}, 1 s on average), independent "
          f"misses ({DISTURBANCES['miss']:.4g} per channel, so that each channel misses {P_MISS} of the cycles), lost "
          f"frames ({DISTURBANCES['drop']}), ghosts ({DISTURBANCES['ghost']}) and {NOISE_SIGMA_M} m distance noise; "
          f"per encounter, a module whose two channels never see the object ({P_MODULE_MISS} per module: a shorter "
          "range or another sensor kind, issue 38; an assumption). "
          "Log-likelihoods are against the undisturbed run. The probability of a collision per such encounter is "
          "estimated by importance sampling with the search's proposal (a defensive mixture with the nominal model, "
          f"weights at most {W_MAX:g}; 95 % interval: Clopper-Pearson on the effective number of failures, and "
          f"0..{NO_FAILURE:.2g}/n with none) and by naive Monte Carlo at the same budget. These figures "
          "hold under this disturbance model only; "
          "its rates are assumptions, not measurements. Against the tolerable hazard rates of the hazard section "
          "(1e-9 /h, CSM-DT catastrophic; 1e-7 /h, SIL 3): at one such encounter per train-hour, the probability per "
          "encounter must stay below those numbers. `m2 held` (full mode) is the same table with every emergency held to "
          "standstill (`emergency_release = 0`): the other side of the release trade-off. How long the monitor "
          "remembers an obstacle no channel shows (forget_ms) is chosen from the sweep of "
          "`python -m verification.stress.tradeoff` (docs/supervision.md section 5).\n\n"
          + md_table(["table", "what", "log-likelihood / estimate", "disturbance"], rows)
          + "\nThe rare-event estimates against the hazard section's tolerable hazard rates, at one such encounter "
            "per train-hour (the collision rate per hour is then the probability per encounter):\n\n"
          + md_table(["table", "estimate", "collisions per train-hour", "against THR 1e-7 /h (SIL 3)",
                      "against 1e-9 /h (CSM-DT catastrophic)"], thr_rows)
          + "\n" + "".join(f"![stress {name}]({f})\n" for name, f in zip(results, figures)))
    return Section("Adaptive stress testing and rare events", md, checks, figures,
                   headline={"stress": {m: {"most_likely_failure": r["most_likely_failure"] and
                                            r["most_likely_failure"]["log_likelihood"],
                                            "p_collision_per_encounter": r["rare_event"]["p_importance_sampling"]}
                                        for m, r in results.items()}})
