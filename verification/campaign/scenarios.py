"""The campaign's worlds: the catalogue scenarios it plays (monitor/scenarios/*.toml, read
through the one loader), the ghost runs' clear track, the one scenario whose collisions are
physics, and the sensors every world shares (range, noise, the cycle period).
"""
from __future__ import annotations

from monitor import scenario as scenario_mod


PERIOD_MS = 100
RANGE_M = 1000.0
NOISE_SIGMA_M = 0.5


# The campaign's worlds are catalogue scenarios (monitor/scenarios/*.toml, docs/scenarios.md),
# read through the one loader: the train's speed, the obstacles, the duration and, in their
# [campaign] table, the range the fault windows start in. Their order is the plan's (it
# decides the tables and the pairs' scenarios, hence the runs_digest).
SCENARIO_NAMES = ("no-obstacle", "static-150m-10", "static-300m-20", "static-700m-30", "static-1200m-40", "train-ahead",
                  "vehicle-ahead", "sudden-120m", "crossing-500m-30")
GHOST_NAME = "ghost-clear-40"    # clear track at 40 m/s: the ghost runs' world, not crossed with the faults


def world_scenario(name: str) -> scenario_mod.Scenario:
    """A catalogue scenario the campaign plays (refused in one line otherwise)."""
    return scenario_mod.require(scenario_mod.load(name), "campaign")


SCENARIOS = tuple(world_scenario(n) for n in SCENARIO_NAMES)
GHOST_SCENARIO = world_scenario(GHOST_NAME)
SCENARIO_BY_NAME = {s.name: s for s in SCENARIOS + (GHOST_SCENARIO,)}
UNAVOIDABLE = "sudden-120m"      # the object appears inside the emergency intervention curve: collisions are physics
