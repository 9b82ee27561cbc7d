"""Obstacle scenarios for the player, read from TOML files (several ship in can_bus/scenarios).

A scenario sets the train (initial speed, decelerations, brake build-up), obstacles
(position ahead of the start, when they appear, their speed and type), the six simulated
sensor channels (range, Gaussian distance noise, missed detections, seed) and injected
faults per channel and time window. Every key is checked; unknown keys are refused.
"""
from __future__ import annotations

from dataclasses import MISSING, dataclass, fields
from importlib import resources
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

FAULT_KINDS = ("silence", "stuck", "bad_crc", "counter_freeze", "counter_jump", "wrong_length",
               "babble", "contradiction", "noise_burst", "missed_detection", "stale_timestamp")
OBSTACLE_TYPES = ("static", "dynamic", "train")


class ScenarioError(ValueError):
    """A scenario file that cannot be played; the message says which key and why."""


@dataclass(frozen=True)
class TrainSpec:
    speed_mps: float = 30.0
    service_decel_mps2: float = 1.0
    emergency_decel_mps2: float = 3.0
    brake_delay_s: float = 0.5      # time for the brake force to build up to its level
    track: str = "normal"
    brake: str = "normal"


@dataclass(frozen=True)
class ObstacleSpec:
    position_m: float = 1200.0      # ahead of the train's start position
    appear_s: float = 0.0
    speed_mps: float = 0.0          # along the track, same direction as the train
    type: str = "static"


@dataclass(frozen=True)
class SensorSpec:
    range_m: float = 1000.0
    noise_sigma_m: float = 0.5
    miss_probability: float = 0.0
    seed: int = 1


@dataclass(frozen=True)
class FaultSpec:
    kind: str
    channel: int
    start_s: float
    end_s: float = 1e9
    rate: int = 20                  # babble: frames per period


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str = ""
    duration_s: float = 60.0
    train: TrainSpec = TrainSpec()
    obstacles: tuple = ()
    sensors: SensorSpec = SensorSpec()
    faults: tuple = ()


def _build(cls, data: dict, where: str):
    if not isinstance(data, dict):
        raise ScenarioError(f"{where} must be a table")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ScenarioError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(known)}")
    kwargs = {}
    for key, value in data.items():
        default = known[key].default
        if default is MISSING:
            default = {"kind": "", "channel": 0, "start_s": 0.0}.get(key)
        if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if isinstance(default, (int, float, str)) and (type(value) is not type(default)):
            raise ScenarioError(f"{where}.{key} must be a {type(default).__name__}, got {value!r}")
        kwargs[key] = value
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ScenarioError(f"{where}: {exc}") from None


def parse(data: dict, name: str) -> Scenario:
    data = dict(data)
    train = _build(TrainSpec, data.pop("train", {}), "train")
    sensors = _build(SensorSpec, data.pop("sensors", {}), "sensors")
    obstacles = tuple(_build(ObstacleSpec, o, f"obstacles[{i}]") for i, o in enumerate(data.pop("obstacles", [])))
    faults = []
    for i, f in enumerate(data.pop("faults", [])):
        if not isinstance(f, dict) or not {"kind", "channel", "start_s"} <= set(f):
            raise ScenarioError(f"faults[{i}] needs kind, channel and start_s")
        f = dict(f)
        for key in ("start_s", "end_s"):
            if isinstance(f.get(key), int) and not isinstance(f.get(key), bool):
                f[key] = float(f[key])
        faults.append(_build(FaultSpec, f, f"faults[{i}]"))
    data.setdefault("name", name)
    scen = _build(Scenario, data, "scenario")
    scen = Scenario(scen.name, scen.description, scen.duration_s, train, obstacles, sensors, tuple(faults))
    check(scen)
    return scen


def check(s: Scenario) -> None:
    def need(ok: bool, msg: str) -> None:
        if not ok:
            raise ScenarioError(msg)

    need(0 < s.duration_s <= 3600, f"duration_s = {s.duration_s}: must be in (0, 3600]")
    need(0 <= s.train.speed_mps <= 120, f"train.speed_mps = {s.train.speed_mps}: must be 0..120")
    need(s.train.service_decel_mps2 > 0 and s.train.emergency_decel_mps2 >= s.train.service_decel_mps2,
         "train decelerations must be > 0 with emergency >= service")
    need(s.train.brake_delay_s >= 0, "train.brake_delay_s must be >= 0")
    need(s.train.track in ("normal", "slippery"), f"train.track = {s.train.track!r}: normal or slippery")
    need(s.train.brake in ("normal", "degraded"), f"train.brake = {s.train.brake!r}: normal or degraded")
    for i, o in enumerate(s.obstacles):
        need(o.type in OBSTACLE_TYPES, f"obstacles[{i}].type = {o.type!r}: one of {', '.join(OBSTACLE_TYPES)}")
        need(o.position_m > 0 and o.appear_s >= 0, f"obstacles[{i}]: position_m > 0 and appear_s >= 0")
    need(s.sensors.range_m > 0 and s.sensors.noise_sigma_m >= 0 and 0 <= s.sensors.miss_probability < 1,
         "sensors: range_m > 0, noise_sigma_m >= 0, 0 <= miss_probability < 1")
    for i, f in enumerate(s.faults):
        need(f.kind in FAULT_KINDS, f"faults[{i}].kind = {f.kind!r}: one of {', '.join(FAULT_KINDS)}")
        need(0 <= f.channel < 6, f"faults[{i}].channel = {f.channel}: 0..5")
        need(0 <= f.start_s < f.end_s, f"faults[{i}]: 0 <= start_s < end_s")
        need(1 <= f.rate <= 200, f"faults[{i}].rate = {f.rate}: 1..200 frames per period")


def load(path_or_name: str) -> Scenario:
    """A scenario by file path, or by the name of one shipped with the package."""
    p = Path(path_or_name)
    if p.suffix != ".toml" and not p.exists():
        shipped = resources.files("can_bus").joinpath("scenarios", f"{path_or_name}.toml")
        if not shipped.is_file():
            raise ScenarioError(f"no scenario {path_or_name!r}; shipped: {', '.join(shipped_names())}")
        text, name = shipped.read_text(encoding="utf-8"), path_or_name
    else:
        try:
            text, name = p.read_text(encoding="utf-8"), p.stem
        except (OSError, UnicodeDecodeError) as exc:
            raise ScenarioError(f"{p}: cannot read: {exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{name}: malformed TOML: {exc}") from None
    return parse(data, name)


def shipped_names() -> list[str]:
    folder = resources.files("can_bus").joinpath("scenarios")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))
