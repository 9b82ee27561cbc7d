"""Co-simulation scenarios: TOML files that set the train FMU's and the monitor FMU's
parameters, the policy table and the duration (several ship in fmu/scenarios).

    description = "static obstacle 600 m ahead at 20 m/s"
    duration_s = 60.0
    table = "m1"                 # shipped m1 / m2, or a table file path
    demand_delay_cycles = 1      # the demand reaches the train this many monitor cycles late
    [train]                      # train FMU parameters; sections become dotted names
    initial_speed = 20.0
    [train.obstacle]
    position = 600.0             # -> "obstacle.position"
    [monitor]                    # monitor FMU parameters (names of monitor/core/config.py)
    topology = 3
    [braking]                    # the train's braking declaration (monitor/declaration.py, SI)
    emergency_decel = 2.4        # ... every key; it sets the monitor's parameters

Every name is checked against the FMUs' variables; an unknown one is refused. A braking
declaration is checked as `railguard ... --braking FILE` checks it, and its values become
monitor parameters (a [monitor] key may not set the same one again).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from monitor.core.config import Config
from monitor.declaration import DeclarationError, apply, fields

from .variables import MONITOR, TRAIN

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

DEFAULT = "static-obstacle"
FAULT_KINDS = ("none", "silence", "stuck", "noise_burst", "missed_detection", "degraded", "nan_distance", "contradiction",
               "blind")
_TRAIN_PARAMS = {v.name: v for v in TRAIN if v.causality == "parameter"}
_MONITOR_PARAMS = {v.name: v for v in MONITOR if v.causality == "parameter"}


class CosimScenarioError(ValueError):
    """A scenario that cannot be run; the message names the key and says why."""


@dataclass(frozen=True)
class CosimScenario:
    name: str
    description: str = ""
    duration_s: float = 60.0
    table: str = "m1"
    train: dict = field(default_factory=dict)
    monitor: dict = field(default_factory=dict)
    demand_delay_cycles: int = 1
    braking: dict | None = None      # the declaration as written (SI), if the scenario has one


def _flatten(prefix: str, table: dict) -> dict:
    out = {}
    for key, value in table.items():
        name = f"{prefix}.{key}" if prefix else key
        if isinstance(value, dict):
            out.update(_flatten(name, value))
        else:
            out[name] = value
    return out


def _check_params(section: str, values: dict, known: dict) -> dict:
    checked = {}
    for name, value in values.items():
        var = known.get(name)
        if var is None:
            raise CosimScenarioError(f"[{section}] {name}: unknown parameter; known: {', '.join(sorted(known))}")
        if name == "fault.kind" and isinstance(value, str):
            if value not in FAULT_KINDS:
                raise CosimScenarioError(f"[{section}] fault.kind = {value!r}: known kinds: {', '.join(FAULT_KINDS)}")
            value = FAULT_KINDS.index(value)
        if var.type == "Real" and not isinstance(value, bool) and isinstance(value, (int, float)):
            value = float(value)
        elif var.type == "Integer" and not isinstance(value, bool) and isinstance(value, int):
            pass
        elif var.type == "Boolean" and isinstance(value, bool):
            pass
        else:
            raise CosimScenarioError(f"[{section}] {name} = {value!r}: must be a {var.type.lower()}")
        checked[name] = value
    return checked


def parse(text: str, name: str) -> CosimScenario:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CosimScenarioError(f"{name}: not valid TOML: {exc}") from None
    known = {"description", "duration_s", "table", "demand_delay_cycles", "train", "monitor", "braking"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise CosimScenarioError(f"{name}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    duration = data.get("duration_s", 60.0)
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not 0.1 <= duration <= 86400:
        raise CosimScenarioError(f"{name}: duration_s = {duration!r}: must be 0.1..86400 s")
    table = data.get("table", "m1")
    if not isinstance(table, str):
        raise CosimScenarioError(f"{name}: table = {table!r}: must be m1, m2 or a table file path")
    delay = data.get("demand_delay_cycles", 1)
    if isinstance(delay, bool) or not isinstance(delay, int) or not 0 <= delay <= 50:
        raise CosimScenarioError(f"{name}: demand_delay_cycles = {delay!r}: must be a whole number 0..50")
    train = _check_params("train", _flatten("", data.get("train", {})), _TRAIN_PARAMS)
    monitor = _check_params("monitor", _flatten("", data.get("monitor", {})), _MONITOR_PARAMS)
    scen = CosimScenario(name, str(data.get("description", "")), float(duration), table, train, monitor, delay)
    braking = data.get("braking")
    if braking is None:
        return scen
    if not isinstance(braking, dict):
        raise CosimScenarioError(f"{name}: [braking] must be a table of the declaration's keys")
    return with_braking(scen, braking, f"{name}: [braking]")


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
    return sorted(p.name[:-5] for p in resources.files("fmu.scenarios").iterdir() if p.name.endswith(".toml"))


def load(spec: str | None) -> CosimScenario:
    """A shipped scenario by name, or a TOML file by path."""
    spec = spec or DEFAULT
    if spec in shipped():
        return parse(resources.files("fmu.scenarios").joinpath(f"{spec}.toml").read_text(), spec)
    path = Path(spec)
    if not path.is_file():
        raise CosimScenarioError(f"{spec}: no such scenario file; shipped scenarios: {', '.join(shipped())}")
    return parse(path.read_text(), path.stem)
