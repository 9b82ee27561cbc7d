"""Co-simulation scenarios: the one scenario language (monitor/scenario.py,
docs/scenarios.md) adapted to the train FMU's and the monitor FMU's parameters.

A `monitor.scenario.Scenario` becomes a `CosimScenario`: its [train], its one obstacle, its
[sensors] and its one fault become the train FMU's parameters (every dynamics parameter is
set, so a scenario is the same world whatever the FMU's own defaults; channel c is the FMU's
ch{c+1}); its [monitor] and [braking] become the monitor FMU's parameters; its table (the default
table, m2, when it names none) and demand_delay_cycles are kept. An obstacle's leave_s is the FMU's
obstacle.leave_time. What the train FMU cannot play (more than one obstacle or fault, an obstacle
appearing late, the bus's frame faults) is refused in one line naming the file and the key.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from monitor import scenario as _ground
from monitor.core.config import Config
from monitor.declaration import DeclarationError, apply, fields
from monitor.tables import DEFAULT as DEFAULT_TABLE

from .variables import MONITOR, TOPOLOGY_CODES, TRAIN

DEFAULT = "static-600m-20"       # `railguard cosim` without a scenario (its default before the one language)
FAULT_KINDS = ("none", "silence", "stuck", "noise_burst", "missed_detection", "degraded", "nan_distance", "contradiction",
               "blind")
_TRAIN_PARAMS = {v.name: v for v in TRAIN if v.causality == "parameter"}
_MONITOR_PARAMS = {v.name: v for v in MONITOR if v.causality == "parameter"}


class CosimScenarioError(_ground.ScenarioError):
    """A scenario that cannot be run; the message names the key and says why."""


@dataclass(frozen=True)
class CosimScenario:
    name: str
    description: str = ""
    duration_s: float = 60.0
    table: str = DEFAULT_TABLE
    train: dict = field(default_factory=dict)
    monitor: dict = field(default_factory=dict)
    demand_delay_cycles: int = 1
    braking: dict | None = None      # the declaration as written (SI), if the scenario has one
    world: _ground.Scenario | None = None   # the scenario it was adapted from (its own table: world.table)
    monitor_stop_s: float = math.inf     # the monitor FMU is no longer stepped from then on (fault monitor_stop)


def train_parameters(scen: _ground.Scenario) -> dict:
    """The train FMU's parameters for a scenario cosim can play (every one it plays)."""
    tr = scen.train
    bands = list(tr.emergency_decel_mps2) + [(0.0, 0.0)] * (3 - len(tr.emergency_decel_mps2))
    p = {name: float(getattr(tr, key)) for key, name in _ground.FMU_TRAIN_NAMES.items() if key != "emergency_decel_mps2"}
    p.update({"emergency_decel": bands[0][1], "emergency_band2_speed": bands[1][0], "emergency_band2_decel": bands[1][1],
              "emergency_band3_speed": bands[2][0], "emergency_band3_decel": bands[2][1],
              "track_condition": _ground.TRACKS.index(tr.track), "brake_status": _ground.BRAKES.index(tr.brake)})
    p["obstacle.present"] = bool(scen.obstacles)
    if scen.obstacles:
        o = scen.obstacles[0]
        p.update({"obstacle.position": o.position_m, "obstacle.speed": o.speed_mps,
                  "obstacle.type": _ground.OBSTACLE_TYPES.index(o.type), "obstacle.leave_time": o.leave_s})
    s = scen.sensors
    p.update({"sensor.range": s.range_m, "sensor.noise_sigma": s.noise_sigma_m,
              "sensor.miss_probability": s.miss_probability, "sensor.seed": s.seed,
              "sensor.distance_bias": s.distance_bias_m, "sensor.closing_bias": s.closing_bias_mps})
    p["fault.kind"] = 0
    if scen.faults and scen.faults[0].kind != "monitor_stop":     # (the master's fault, not the train's)
        f = scen.faults[0]
        p.update({"fault.kind": FAULT_KINDS.index(f.kind), "fault.channel": f.channel + 1, "fault.start": f.start_s,
                  "fault.end": f.end_s})
    unknown = set(p) - set(_TRAIN_PARAMS)
    assert not unknown, f"not train FMU parameters: {unknown}"
    return p


def adapt(scen: _ground.Scenario) -> CosimScenario:
    """The CosimScenario of a scenario, or CosimScenarioError if cosim cannot play it."""
    _ground.require(scen, "cosim", CosimScenarioError)
    try:
        params = _ground.monitor_parameters(scen)
    except _ground.ScenarioError as exc:
        raise CosimScenarioError(str(exc)) from None
    monitor = {k: TOPOLOGY_CODES[v] if k == "topology" else v for k, v in params.items()}
    unknown = set(monitor) - set(_MONITOR_PARAMS)
    assert not unknown, f"not monitor FMU parameters: {unknown}"
    stop = next((f.start_s for f in scen.faults if f.kind == "monitor_stop"), math.inf)
    return CosimScenario(scen.name, scen.description, scen.duration_s, scen.table or DEFAULT_TABLE, train_parameters(scen),
                         monitor, scen.demand_delay_cycles, dict(scen.braking) if scen.braking is not None else None,
                         scen, stop)


def parse(text: str, name: str) -> CosimScenario:
    """A CosimScenario from the TOML text of a scenario."""
    try:
        return adapt(_ground.loads(text, name))
    except CosimScenarioError:
        raise
    except _ground.ScenarioError as exc:
        raise CosimScenarioError(str(exc)) from None


def with_braking(scen: CosimScenario, values: dict, where: str) -> CosimScenario:
    """`scen` with a braking declaration (SI keys of monitor.declaration) as the monitor's
    parameters; it replaces a declaration the scenario had, and refuses a [monitor] key
    that sets one of its values too."""
    own = set(fields(scen.braking, where)) if scen.braking else set()
    monitor = {k: v for k, v in scen.monitor.items() if k not in own}
    try:
        apply(Config(), values, where)          # the values checked together
        declared = fields(values, where)
    except DeclarationError as exc:
        raise CosimScenarioError(str(exc)) from None
    both = sorted(set(declared) & set(monitor))
    if both:
        raise CosimScenarioError(f"{where}: {', '.join(both)} set by both [braking] and [monitor]; keep one")
    return replace(scen, monitor={**monitor, **declared}, braking=dict(values))


def shipped() -> list[str]:
    """The shipped scenarios (monitor/scenarios) cosim can play."""
    return [name for name, _, players in _ground.catalogue() if "cosim" in players]


def load(spec: str | None) -> CosimScenario:
    """A shipped scenario by name (None: DEFAULT), or a TOML file by path."""
    try:
        return adapt(_ground.load(spec or DEFAULT))
    except CosimScenarioError:
        raise
    except _ground.ScenarioError as exc:
        raise CosimScenarioError(str(exc)) from None
