"""Seed 000 (Chelouati et al., IEEE Access 2024) section V reproduced through the monitor.

The paper's simulation: a train at 40 m/s (Table 1), obstacles generated about 20 % of the
time uniformly between the mean of alpha1 and alpha2 and 50 m beyond it (section V-B), the
observed distance corrupted by Gaussian noise (section V-A), the train moved by eqs. 6-11
with the action's deceleration (Table 1: 0, -1, -3 m/s^2), every 0.1 s. Here that
environment runs vectorised over many trains at once (numpy), and every train is watched by
the monitor core with the shipped Model 1 table through `fastcore.VectorMonitor`; a sample
of the trains is replayed through the real `monitor.core.cycle.step` (`agrees_with_core`),
which ties every figure to the real core. Figures like the paper's Fig. 7a-d come from one
train of that same trace.

The pieces, one concept each: `world` (the scenarios and the vectorised simulation),
`figures` (Fig. 7 for one train), `runs` (the runs' sizes and seeds and their rates and
tables), `part` (`section` and its checks) and `markdown` (the section's text). This package
re-exports their public names (and `_move`, which the tests pin), so `from verification
import seed000` reads as before.
"""
from __future__ import annotations

from .world import (
    DISCOUNT_STEPS, EPISODE_KEYS, GAMMA, LITERAL, MAX_DM, PAPER, PAPER_REWARDS, PAPER_ZONES, PHANTOMS, PHANTOMS_HELD,
    SHIPPED, STATE_NAMES, TRACE_KEYS, ZONE_NAMES, Run, Scenario, core_agreement, expected_obstacle_fraction, simulate,
    _move,
)
from .figures import draw_fig7, draw_zone_bars, episode_series, pick_episode
from .runs import (
    CORE_TRAINS, FULL, PHANTOM_STOPS_BEFORE, PHANTOM_STOPS_FACTOR, QUICK, RUN_KEYS, SEEDS, TARGET, metrics_table,
    stops_per_hour,
)
from .part import TITLE, phantom_stops_check, section

__all__ = [
    "DISCOUNT_STEPS", "EPISODE_KEYS", "GAMMA", "LITERAL", "MAX_DM", "PAPER", "PAPER_REWARDS", "PAPER_ZONES", "PHANTOMS",
    "PHANTOMS_HELD", "SHIPPED", "STATE_NAMES", "TRACE_KEYS", "ZONE_NAMES", "Run", "Scenario", "core_agreement",
    "expected_obstacle_fraction", "simulate", "_move", "draw_fig7", "draw_zone_bars", "episode_series", "pick_episode",
    "CORE_TRAINS", "FULL", "PHANTOM_STOPS_BEFORE", "PHANTOM_STOPS_FACTOR", "QUICK", "RUN_KEYS", "SEEDS", "TARGET",
    "metrics_table", "stops_per_hour", "TITLE", "phantom_stops_check", "section",
]
