"""The rare-event estimate: the probability of a failure per encounter by importance sampling
from a defensive mixture of the nominal model and the search's proposal (bounded
likelihood-ratio weights, a 95 % interval), beside naive Monte Carlo at the same budget.
"""
from __future__ import annotations

import math

import numpy as np
from monitor.core.config import Config

from ..scale import Cluster
from ..world_metrics import wilson_upper
from .disturbances import NOMINAL, Disturbance, Proposal
from .encounters import Encounter
from .loop import evaluate_all


DEFENSIVE = 0.5           # importance sampling draws from the nominal model this often (bounded weights)


def rare_events(model: str, enc: Encounter, proposal: Proposal, world, cfg: Config, margin_m: float, n: int,
                root: np.random.SeedSequence, cluster: Cluster) -> dict:
    """P(failure per encounter): importance sampling from the defensive mixture of the nominal
    model and `proposal` (likelihood-ratio weights, at most 1 / DEFENSIVE; 95 % normal
    interval) against naive Monte Carlo from the nominal model at the same budget."""
    is_ss, mc_ss = root.spawn(2)
    rng = np.random.default_rng(is_ss)
    ds = [(NOMINAL if rng.random() < DEFENSIVE else proposal).sample(rng) for _ in range(n)]
    res = evaluate_all(model, enc, ds, world, cfg, margin_m, cluster)

    def weight(d: Disturbance) -> float:            # p / (a p + (1 - a) q): at most 1 / a
        lp, lq = NOMINAL.log_density(d), proposal.log_density(d)
        top = max(lp, lq)
        return math.exp(lp - top) / (DEFENSIVE * math.exp(lp - top) + (1 - DEFENSIVE) * math.exp(lq - top))

    w = np.array([weight(d) if r["failure"] else 0.0 for d, r in zip(ds, res)])
    p_is = float(w.mean())
    half = 1.96 * float(w.std(ddof=1)) / math.sqrt(n) if n > 1 else math.inf
    rng = np.random.default_rng(mc_ss)
    mc = evaluate_all(model, enc, [NOMINAL.sample(rng) for _ in range(n)], world, cfg, margin_m, cluster)
    hits = sum(r["failure"] for r in mc)
    return {"samples": n, "p_importance_sampling": p_is, "ci95": [max(0.0, p_is - half), p_is + half],
            "failures_in_is_samples": int(sum(r["failure"] for r in res)),
            "effective_sample_size": float(w.sum() ** 2 / (w ** 2).sum()) if w.any() else 0.0,
            "naive": {"failures": hits, "p": hits / n, "ci95_upper": wilson_upper(hits, n)}}
