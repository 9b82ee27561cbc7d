"""The scenario player's view of the one scenario language (monitor/scenario.py,
docs/scenarios.md): the player plays a `monitor.scenario.Scenario` as it is, and refuses in
one line (file and key) what it cannot play: a brake dead time, traction, a gradient, a
speed error, running resistance, adhesion factors, fault kinds of the train FMU only, or a
monitor configuration of its own (`railguard run` takes it from --braking).
"""
from __future__ import annotations

from monitor import scenario as _ground
from monitor.scenario import FaultSpec, ObstacleSpec, Scenario, SensorSpec, TrainSpec, check, refusal

__all__ = ["CHANNEL_FREE_KINDS", "FAULT_KINDS", "OBSTACLE_TYPES", "FaultSpec", "ObstacleSpec", "Scenario", "ScenarioError",
           "SensorSpec", "TrainSpec", "check", "load", "parse", "refusal", "shipped_names"]

FAULT_KINDS = _ground.RUN_FAULT_KINDS
CHANNEL_FREE_KINDS = _ground.CHANNEL_FREE_KINDS
OBSTACLE_TYPES = _ground.OBSTACLE_TYPES


class ScenarioError(_ground.ScenarioError):
    """A scenario file that the player cannot play; the message says which key and why."""


def parse(data: dict, name: str) -> Scenario:
    """A player scenario from the mapping of a TOML file."""
    try:
        return _ground.require(_ground.parse(data, name), "run", ScenarioError)
    except ScenarioError:
        raise
    except _ground.ScenarioError as exc:
        raise ScenarioError(str(exc)) from None


def load(path_or_name: str) -> Scenario:
    """A scenario by file path, or by the name of one shipped with the package
    (monitor/scenarios), if the player can play it."""
    try:
        return _ground.require(_ground.load(path_or_name), "run", ScenarioError)
    except ScenarioError:
        raise
    except _ground.ScenarioError as exc:
        raise ScenarioError(str(exc)) from None


def shipped_names() -> list[str]:
    """The shipped scenarios the player can play."""
    return [name for name, _, players in _ground.catalogue() if "run" in players]
