"""Adaptive stress testing: the most likely way to a collision, and how likely collisions are.

ACAS X was validated by searching for the most likely path to failure, not only by random
runs. Here the path is a disturbance sequence on the six sensor channels during an
encounter: misses (a channel reports ABSENT with the obstacle in view; seed 002's p_n),
lost frames (the channel's latched report ages), ghosts (a phantom PRESENT) and distance
noise, each with a nominal probability (DISTURBANCES, calibrated so that a channel misses
p_n of the cycles, a share BETA of it in common: see `disturbances`), over the WINDOW cycles
from the appearance (until the slowest encounter stands still). The world is the
campaign's: the train FMU's physics (verification/world_train.py) on the braking declaration's worst
corner, its sensing and output latencies included; the monitor is the shipped table behind
the supervision, stepped by `monitor.core.cycle` exactly as the runner steps it. A failure is
a collision (or a gap below the margin) with an obstacle the world's train could have
stopped for.

The search is the cross-entropy method: disturbances are drawn from a proposal (independent
per cycle and channel), the runs closest to failure (then: the failures, weighted by their
likelihood ratio) refit the proposal, and the most likely failure seen is then pruned
greedily (every disturbance it can do without is removed). Its log-likelihood is given
relative to the undisturbed run (`log_likelihood`: the sum over its disturbances of
log(p / (1 - p)) for events and -z^2 / 2 for noise of z standard deviations).

The proposal the search converged to is also an importance-sampling density: the
probability of a collision per encounter is estimated with likelihood-ratio weights (over the
cycles each run read) and a 95 % interval that keeps its coverage with few failures and has
an upper end above 0 with none (Clopper-Pearson on the effective number of failures; the
weights are at most 1 / DEFENSIVE), beside naive Monte Carlo at the same budget.

A failure is written as a candump log (through the real codec) that `railguard replay`
reproduces cycle by cycle, and as a co-simulation scenario of the same encounter: a single
blindness is the train FMU's `blind` fault, so the real FMUs replay it
(monitor/scenarios/stress-blackout-release.toml is the failure found; tests/test_cosim.py);
other disturbances are listed in it as comments.

The pieces, one concept each: `encounters` (what is met, and the six channels that see it),
`disturbances` (the disturbance model, sequences and proposal densities), `loop` (one
encounter in closed loop, and batches as dask tasks), `cross_entropy` (the search and the
pruning), `importance` (the rare-event estimate), `artefacts` (candump log, replay check,
co-simulation scenario), `command` (`run`, `railguard stress`, and its text), `figures`
(the plot) and `part` (`section`). This package re-exports their public names, so `from
verification import stress` reads as before.
"""
from __future__ import annotations

from .encounters import APPEAR_S, CHANNELS, GHOST_M, NOISE_SIGMA_M, RANGE_M, ENCOUNTERS, Encounter
from .disturbances import (
    BETA, BLIND_STAYS, DISTURBANCES, EXPLORE, KINDS, NOMINAL, P_BLIND, P_MISS, P_MODULE_MISS, P_BEHIND, SHAPES, WINDOW,
    Disturbance, Proposal,
    log_weight,
)
from .loop import closed_loop, evaluate_all
from .importance import DEFENSIVE, NO_FAILURE, W_MAX, effective_failures, rare_events, weighted_interval
from .cross_entropy import PRUNED, QUICK, Budget, prune, search
from .artefacts import replay_matches, write_candump, write_cosim_scenario
from .command import render, run, summarise
from .figures import plot
from .part import section

__all__ = [
    "APPEAR_S", "CHANNELS", "GHOST_M", "NOISE_SIGMA_M", "RANGE_M", "ENCOUNTERS", "Encounter", "BETA", "BLIND_STAYS",
    "DISTURBANCES", "EXPLORE", "KINDS", "NOMINAL", "P_BLIND", "P_MISS", "P_MODULE_MISS", "P_BEHIND", "SHAPES", "WINDOW", "Disturbance", "Proposal",
    "log_weight", "closed_loop", "evaluate_all", "DEFENSIVE", "NO_FAILURE", "W_MAX", "effective_failures",
    "rare_events", "weighted_interval", "PRUNED", "QUICK", "Budget", "prune", "search", "replay_matches",
    "write_candump", "write_cosim_scenario", "render", "run", "summarise", "plot", "section",
]
