"""The search for the likeliest failure: the cross-entropy method (draw from the proposal,
refit its blindness chain to the runs closest to failure, then to the failures weighted by
their likelihood ratio), the greedy pruning of a failure to what it cannot do without, and
`search`, which ends with the rare-event estimate from the proposal it converged to.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np
from monitor.core.config import Config

from .. import world_train
from ..report import Progress
from ..scale import Cluster
from .disturbances import KINDS, NOMINAL, WINDOW, Disturbance, Proposal, log_weight
from .encounters import Encounter
from .importance import rare_events
from .loop import closed_loop, evaluate_all


@dataclass(frozen=True)
class Budget:
    samples: int = 200        # per cross-entropy iteration
    iterations: int = 10
    elite: float = 0.1
    smoothing: float = 0.7
    is_samples: int = 1000    # importance sampling (and naive Monte Carlo) after the search


QUICK = Budget(samples=100, iterations=6, is_samples=400)


def _refit(proposal: Proposal, elites: list[Disturbance], cycles: np.ndarray, weights: np.ndarray,
           smoothing: float) -> Proposal:
    """The blindness chain refitted to the elites (weighted) over the `cycles` of the window
    each read (a cycle no elite read keeps its probabilities); every other event keeps its
    nominal rate: each hides the obstacle from one channel only, which the 2oo2 and 3oo3
    voting answers (six independent misses in one cycle: 1e-8), and adapting thousands more
    parameters would only spread the importance weights."""
    w = weights / weights.sum()

    def blend(est, old, lo=1e-4, hi=0.98):
        return np.clip(smoothing * est + (1 - smoothing) * old, lo, hi)

    seen = (np.arange(WINDOW)[None, :] < np.asarray(cycles)[:, None]).astype(float)     # (E, WINDOW)

    def fit(event: np.ndarray, given: np.ndarray, old: np.ndarray) -> np.ndarray:
        """P(event | given) per cycle over the cycles the elites read, blended into `old`."""
        n = w @ (given * seen)
        return np.where(n > 0, blend((w @ (event * given * seen)) / np.maximum(n, 1e-300), old), old)

    blind = np.stack([e.blind for e in elites]).astype(float)
    prev = np.concatenate([np.zeros((len(elites), 1)), blind[:, :-1]], axis=1)
    p = {**proposal.p, "blind": fit(blind, 1 - prev, proposal.p["blind"])}
    # a module's miss (per encounter) refitted like the blindness's start: the share of the
    # weighted elites that have it
    module = blend(w @ np.stack([e.module for e in elites]).astype(float), proposal.module)
    behind = blend(w @ np.stack([e.behind for e in elites]).astype(float), proposal.behind)   # (the same, per encounter)
    # the noise keeps its nominal spread and mean: it moves the voted distance by a few
    # sigmas (1 to 2 m) against margins of metres
    return Proposal(p, proposal.mu, fit(blind, prev, proposal.stays), module, behind)


def prune(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, margin_m: float,
          released: bool = False) -> Disturbance:
    """Remove every disturbance the failure does without (greedy): a locally most likely
    failure (with `released`: one that still comes after a released emergency)."""

    def fails(trial: Disturbance) -> bool:
        """still a failure, and a likelier one (ending a blindness in its middle may cost more)"""
        if trial.log_likelihood() <= best.log_likelihood():
            return False
        r = closed_loop(model, enc, trial, world, cfg, margin_m)
        return r["failure"] and (r["released"] or not released)

    best = d.copy()
    # most failures need neither the noise, nor any one channel's events, nor a module's miss
    for kinds in (("z",), KINDS[1:], ("module",)):
        quiet = best.copy()
        for kind in kinds:
            getattr(quiet, kind)[:] = 0
        if fails(quiet):
            best = quiet
    changed = True
    while changed:
        changed = False
        for kind in ("ghost", "drop", "miss", "module", "blind"):   # the likeliest events are kept longest
            for where in np.argwhere(getattr(best, kind)):
                trial = best.copy()
                getattr(trial, kind)[tuple(where)] = False
                if fails(trial):
                    best, changed = trial, True
        big = np.argwhere(np.abs(best.z) > 0.5)
        for j, c in big:
            trial = best.copy()
            trial.z[j, c] = 0.0
            if fails(trial):
                best, changed = trial, True
    return best


PRUNED = 8           # failures pruned to find the likeliest


def _likeliest(candidates: list, model: str, enc: Encounter, world, cfg: Config, margin_m: float,
               released: bool = False) -> Optional[dict]:
    """The candidates pruned (prune), the likeliest that still fails (and, with `released`,
    still fails after releasing an emergency), as the JSON of a failure."""
    best = None
    for d in candidates:
        d = prune(model, enc, d, world, cfg, margin_m, released)
        if best is None or d.log_likelihood() > best.log_likelihood():
            best = d
    if best is None:
        return None
    out = closed_loop(model, enc, best, world, cfg, margin_m)
    return {"log_likelihood": round(best.log_likelihood(), 3), "events": best.events(cfg.period_ms),
            "disturbance": best.as_lists(), "closest_m": out["closest_m"], "impact_speed_mps": out["impact_speed_mps"],
            "released_emergency": out["released"]}


def search(model: str, enc: Encounter, *, world=None, cfg: Config = Config(), budget: Budget = Budget(),
           margin_m: float = 0.0, seed: int = 0, cluster: Cluster = Cluster(), progress: Optional[Progress] = None) -> dict:
    """The cross-entropy search, the pruned most likely failure, and the rare-event estimate."""
    say = progress or (lambda msg: None)
    world = world or world_train.corners(cfg)[0]
    t0 = time.perf_counter()
    root = np.random.SeedSequence(seed)
    proposal = NOMINAL.explore()
    failures: list[tuple[float, bool, Disturbance]] = []
    history = []
    sims = 0
    n_elite = max(2, int(budget.elite * budget.samples))
    for it, ss in enumerate(root.spawn(budget.iterations)):
        rng = np.random.default_rng(ss)
        ds = proposal.sample(rng, budget.samples)
        res = evaluate_all(model, enc, ds, world, cfg, margin_m, cluster)
        sims += len(ds)
        read = [d.cut(r["cycles"]) for d, r in zip(ds, res)]     # what came after a run's end decided nothing
        fail = [i for i, r in enumerate(res) if r["failure"]]
        failures += [(read[i].log_likelihood(), res[i]["released"], read[i]) for i in fail]
        # failures first, the likeliest first (by their events: the noise, some 0.5 nats per
        # channel and cycle, would rank them at random), then the runs that came closest
        order = sorted(range(len(ds)), key=lambda i: (0, -read[i].events_log_likelihood()) if res[i]["failure"]
                       else (1, res[i]["closest_m"]))
        top = order[:n_elite]
        cycles = np.array([res[i]["cycles"] for i in top])
        if len(fail) >= n_elite:        # the failure level is reached: weight elites towards the likeliest
            lw = np.array([log_weight(ds[i], proposal, c) for i, c in zip(top, cycles)])
            weights = np.exp(lw - lw.max())
        else:
            weights = np.ones(len(top))
        proposal = _refit(proposal, [ds[i] for i in top], cycles, weights, budget.smoothing)
        best = max((f[0] for f in failures), default=None)
        history.append({"iteration": it, "failures": len(fail), "closest_m": min(r["closest_m"] for r in res),
                        "best_log_likelihood": best})
        say(f"stress {model} {enc.name}: iteration {it + 1}/{budget.iterations}: {len(fail)} of {len(ds)} runs fail, "
            f"closest {history[-1]['closest_m']:.2f} m"
            + (f", likeliest failure so far log-likelihood {best:.1f}" if best is not None else ""))
    most = most_released = None
    if failures:
        say(f"stress {model} {enc.name}: pruning the {min(PRUNED, len(failures))} likeliest failures "
            "(and of those after a released emergency)")
        by_events = sorted(failures, key=lambda f: -f[2].events_log_likelihood())
        most = _likeliest([f[2] for f in by_events[:PRUNED]], model, enc, world, cfg, margin_m)
        rel = [f for f in by_events if f[1]][:PRUNED // 2]
        most_released = _likeliest([f[2] for f in rel], model, enc, world, cfg, margin_m, released=True)
    say(f"stress {model} {enc.name}: importance sampling ({budget.is_samples} runs) and naive Monte Carlo (same budget)")
    rare = rare_events(model, enc, proposal, world, cfg, margin_m, budget.is_samples, root, cluster)
    return {"table": model, "encounter": asdict(enc), "appear_m": enc.appear_m(cfg),
            "world_train": world_train.as_dict(world), "margin_m": margin_m, "seed": seed,
            "budget": asdict(budget), "simulations": sims + 2 * budget.is_samples, "history": history,
            "failures_found": len(failures), "most_likely_failure": most,
            "most_likely_failure_after_release": most_released, "rare_event": rare,
            "seconds": round(time.perf_counter() - t0, 1)}
