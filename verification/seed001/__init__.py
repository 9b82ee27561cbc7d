"""Seed 001 (Chelouati et al., ESREL 2025) reproduced with the shipped Model 2 table.

The paper's section 4 reports three numbers from a simulation of its Model 2 POMDP:
75.0 % of the steps with an obstacle present, 96.3 % risk-assessment accuracy (the share
of steps where the risk category of the true state, eq. 11, equals the one estimated
from the belief state) and a mean reward of -3.19 per step (eq. 10). It does not say how
its obstacles, speeds or conditions are generated, how long an episode is, or how the
risk is estimated from the belief. This module runs the closest simulation we can state
completely, with the real monitor in the loop:

* the hidden world is physical: the train's speed follows eq. 2 with the achieved
  deceleration, the obstacle's distance eq. 4, its speed eq. 5 (by type), the track and
  the brakes eq. 6, with Model 2's numbers (the table header's parameters) where it has
  them and ours, listed in the section's Markdown, where it has none;
* the sensors report the true state through eq. 9 (per component, wrong with epsilon_i,
  then uniformly one of the other values), synthesised into the integer inputs of the
  monitor (distance in dm, closing speed in cm/s, type, track, brake);
* the monitor is `VectorMonitor` with the m2 table (policy table, braking-curve
  supervision, emergency latch and release), and the train brakes as it demands, after a
  dead time within the braking declaration's build-up;
* alongside, a Bayes filter over Model 2's 144 states (the POMDP the table was solved
  for) gives the paper's "risk estimated from the belief state".

Everything is vectorised over trains (numpy); a fixed seed makes every number
reproducible. `agrees_with_core` replays sampled trains of the same run through the real
core, and the invariants of the supervision and the latch are checked on every step.

The pieces, one concept each: `metrics` (the paper's metrics and Model 2's risk categories),
`world` (the simulation), `belief` (the Bayes filter), `settling` (where the table and the
solver's policy settle), `figures` and `part` (`section`). This package re-exports their
public names, so `from verification import seed001` reads as before.
"""
from __future__ import annotations

from .metrics import (
    DIMS, N_STATES, PAPER, STATE_RISK, calibrated_gap_s, expected_obstacle_fraction, mean_reward, reward_by_category,
    risk_accuracy, risk_categories, standard_error, state_components, state_index, time_with_obstacles,
)
from .world import CLASS_CLOSING_CMS, MAX_CLOSING_CMS, MAX_DISTANCE_DM, Run, Settings, load_setup, simulate
from .belief import BeliefFilter
from .settling import SETTLE_CYCLES, belief_policy_settled, settled_actions
from .figures import sample_column
from .part import AGREE_TRAINS, FULL, IMPACT_MPS, QUICK, SE_TOLERANCE, TITLE, durations_str, section

__all__ = [
    "DIMS", "N_STATES", "PAPER", "STATE_RISK", "calibrated_gap_s", "expected_obstacle_fraction", "mean_reward",
    "reward_by_category", "risk_accuracy", "risk_categories", "standard_error", "state_components", "state_index",
    "time_with_obstacles", "CLASS_CLOSING_CMS", "MAX_CLOSING_CMS", "MAX_DISTANCE_DM", "Run", "Settings", "load_setup",
    "simulate", "BeliefFilter", "SETTLE_CYCLES", "belief_policy_settled", "settled_actions", "sample_column",
    "AGREE_TRAINS", "FULL", "IMPACT_MPS", "QUICK", "SE_TOLERANCE", "TITLE", "durations_str", "section",
]
