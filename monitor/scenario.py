"""The one scenario language of railguard: the loader, its dataclasses and checks, the
catalogue shipped in monitor/scenarios/*.toml, and what each player can play.

A scenario is one world: the train (its speed and brakes), the obstacles, the six sensor
channels, the faults injected into them, and optionally the monitor's configuration, the
table it is meant for and campaign settings. Three players play scenarios:

* ``run``      the scenario player on CAN (`railguard run` / `railguard play`, can_bus);
* ``cosim``    the train FMU + monitor FMU closed loop in FMPy (`railguard cosim`, fmu);
* ``campaign`` the fault campaign's worlds (`railguard campaign`, verification).

Each player adapts a `Scenario` to what it can play and refuses, in one line naming the file
and the key, what it cannot (`require`); `refusal` says why without raising; `catalogue` lists
the shipped scenarios with their players. docs/scenarios.md documents the language key by key.

This module is on the ground floor: it imports nothing from can_bus, fmu or verification.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import NamedTuple, Optional

from monitor.core.config import Config, ConfigurationError, check as check_config
from monitor.declaration import DeclarationError, fields as declaration_fields

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

DEFAULT = "static-obstacle"          # the default of `railguard run` (and the README's)
PLAYERS = ("run", "cosim", "campaign")
OBSTACLE_TYPES = ("static", "dynamic", "train")
TRACKS = ("normal", "slippery")
BRAKES = ("normal", "degraded")
# fault kinds each player injects (frame faults exist only on the bus; degraded and nan_distance
# only in the train FMU)
RUN_FAULT_KINDS = ("silence", "stuck", "bad_crc", "counter_freeze", "counter_jump", "wrong_length", "babble",
                   "contradiction", "noise_burst", "missed_detection", "stale_timestamp", "blind", "forge_absent",
                   "forge_brake_none", "replay_absent", "replay_brake_none", "forge_absent_stolen_key")   # hostile.py
COSIM_FAULT_KINDS = ("silence", "stuck", "noise_burst", "missed_detection", "degraded", "nan_distance",
                     "contradiction", "blind", "monitor_stop")     # monitor_stop: the master stops stepping it
FAULT_KINDS = RUN_FAULT_KINDS + tuple(k for k in COSIM_FAULT_KINDS if k not in RUN_FAULT_KINDS)
CHANNEL_FREE_KINDS = ("blind", "forge_brake_none", "replay_brake_none", "monitor_stop")   # no channel key
FOREVER_S = 1e9
ALL_CHANNELS = (0, 1, 2, 3, 4, 5)

# [train] keys -> the train FMU's parameter names (fmu/variables.py), which are also the
# field names of verification/world_train.WorldTrain where it has them (its [world_train] tables
# accept both; it has no cruise_speed: a world train cruises at its encounter speed)
FMU_TRAIN_NAMES = {
    "speed_mps": "initial_speed", "service_decel_mps2": "service_decel", "emergency_decel_mps2": "emergency_decel",
    "brake_delay_s": "brake_delay", "brake_buildup_s": "brake_buildup", "traction_cutoff_s": "traction_cutoff",
    "max_traction_mps2": "max_traction", "gradient_permille": "gradient", "speed_error": "speed_error",
    "cruise_speed_mps": "cruise_speed", "mass_kg": "mass", "davis_a_n": "davis_a", "davis_b_n_per_mps": "davis_b",
    "davis_c_n_per_mps2": "davis_c",
    "slippery_factor": "slippery_factor", "degraded_factor": "degraded_factor",
}


def band_decel(bands, v: float) -> float:
    """The deceleration of speed `v` in ((from_speed, decel), ...) bands from 0 m/s up."""
    a = bands[0][1]
    for lo, decel in bands[1:]:
        if v >= lo:
            a = decel
    return a


class ScenarioError(ValueError):
    """A scenario that cannot be read or played; one line naming the file and the key."""


# ----------------------------------------------------------------------------- the dataclasses

@dataclass(frozen=True)
class TrainSpec:
    """The world's train (not the monitor's declaration of it). The defaults are the simple
    train every player plays: brakes ramping up in brake_buildup_s, no dead time, no running
    resistance, no gradient, no traction after a release."""

    speed_mps: float = 30.0
    service_decel_mps2: float = 1.0
    emergency_decel_mps2: tuple = ((0.0, 3.0),)   # ((from_speed_mps, decel_mps2), ...), 1..3 bands
    brake_delay_s: float = 0.0          # pure dead time before a new demand acts
    brake_buildup_s: float = 0.5        # ramp of the brake force from zero to the full emergency level
    traction_cutoff_s: float = -1.0     # full traction this long after a demand (< 0: cut at once)
    max_traction_mps2: float = 0.0      # traction that holds (or regains) the cruising speed
    cruise_speed_mps: float = -1.0      # the cruising speed (< 0: speed_mps); above it, the train pulls
    gradient_permille: float = 0.0      # positive uphill
    speed_error: float = 0.0            # the reported speed is true / (1 + speed_error)
    mass_kg: float = 400000.0
    davis_a_n: float = 0.0              # running resistance A + B v + C v^2, newtons
    davis_b_n_per_mps: float = 0.0
    davis_c_n_per_mps2: float = 0.0
    track: str = "normal"               # reported to the monitor: normal or slippery
    brake: str = "normal"               # reported to the monitor: normal or degraded
    slippery_factor: float = 1.0        # the brakes' decelerations x this on a slippery track
    degraded_factor: float = 1.0        # ... and with degraded brakes

    def emergency_at(self, v: float) -> float:
        """The emergency deceleration at speed `v` (its speed band)."""
        return band_decel(self.emergency_decel_mps2, v)


@dataclass(frozen=True)
class ObstacleSpec:
    position_m: float = 1200.0          # ahead of the train's start position
    appear_s: float = 0.0               # after the train's entry
    speed_mps: float = 0.0              # along the track, positive in the train's direction (< 0: oncoming)
    type: str = "static"
    leave_s: float = FOREVER_S          # it leaves the track then (after the train's entry; FOREVER_S: never)
    # hidden from these channels from hidden_from_s until hidden_until_s (a curve, a cutting, a
    # low-reflecting object): they see past it, to the next obstacle or none; the train still hits it
    hidden_from_s: float = FOREVER_S
    hidden_until_s: float = FOREVER_S
    hidden_channels: tuple = ALL_CHANNELS

    def there(self, t: float) -> bool:      # on the track `t` s after the train's entry: appear_s until leave_s
        return self.appear_s <= t < self.leave_s

    def seen_by(self, t: float, ch: int) -> bool:      # there, and not hidden from channel `ch` then
        hidden = self.hidden_from_s <= t < self.hidden_until_s and ch in self.hidden_channels
        return self.there(t) and not hidden


@dataclass(frozen=True)
class SensorSpec:
    range_m: float = 1000.0
    noise_sigma_m: float = 0.5
    miss_probability: float = 0.0
    seed: int = 1
    distance_bias_m: float = 0.0        # added to every report (+: farther); closing_bias_mps: to every closing speed
    closing_bias_mps: float = 0.0


@dataclass(frozen=True)
class FaultSpec:
    kind: str
    channel: int = 0                    # 0..5 (the FMU's ch1..ch6); none for blind
    start_s: float = 0.0
    end_s: float = FOREVER_S
    rate: int = 20                      # babble: frames per period


@dataclass(frozen=True)
class CampaignSpec:
    fault_start_s: tuple = (0.5, 10.0)  # the campaign's fault windows start in this range


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str = ""
    duration_s: float = 60.0
    train: TrainSpec = TrainSpec()
    obstacles: tuple = ()
    sensors: SensorSpec = SensorSpec()
    faults: tuple = ()
    table: Optional[str] = None         # the table the scenario is meant for (m1, m2 or a path)
    demand_delay_cycles: int = 1        # cosim: the demand reaches the train this many cycles late
    monitor: dict = field(default_factory=dict)      # Config field -> value
    braking: Optional[dict] = None      # a braking declaration (monitor/declaration.py keys, SI)
    campaign: Optional[CampaignSpec] = None
    source: str = ""                    # the file, for messages

    @property
    def label(self) -> str:
        return self.source or f"{self.name}.toml"


# ----------------------------------------------------------------------------- reading

TOP_KEYS = ("description", "duration_s", "table", "demand_delay_cycles", "train", "obstacles", "sensors", "faults",
            "monitor", "braking", "campaign")
MONITOR_KEYS = tuple(f for f in Config._fields if f != "period_ms")
TOPOLOGY_CODES = {"3oo3": 3, "2oo2": 2}
# (lo, hi) of every number; None: no bound on that side
LIMITS = {
    "duration_s": (0.0, 86400.0), "demand_delay_cycles": (0, 50),
    "speed_mps": (0.0, 120.0), "service_decel_mps2": (0.0, 20.0), "brake_delay_s": (0.0, 5.0),
    "brake_buildup_s": (0.0, 60.0), "traction_cutoff_s": (-1.0, 30.0), "max_traction_mps2": (0.0, 5.0),
    "cruise_speed_mps": (-1.0, 120.0),
    "gradient_permille": (-60.0, 60.0), "speed_error": (0.0, 0.5), "mass_kg": (1.0, 1e8), "davis_a_n": (0.0, 1e7),
    "davis_b_n_per_mps": (0.0, 1e6), "davis_c_n_per_mps2": (0.0, 1e5), "slippery_factor": (0.0, 1.0),
    "degraded_factor": (0.0, 1.0),
    "position_m": (0.0, 100000.0), "appear_s": (0.0, 86400.0), "leave_s": (0.0, FOREVER_S),
    "hidden_from_s": (0.0, FOREVER_S), "hidden_until_s": (0.0, FOREVER_S), "hidden_channel": (0, 5),
    "obstacle_speed_mps": (-120.0, 120.0),
    "range_m": (0.0, 6000.0), "noise_sigma_m": (0.0, 1000.0), "miss_probability": (0.0, 1.0),
    "distance_bias_m": (-6000.0, 6000.0), "closing_bias_mps": (-150.0, 150.0), "seed": (0, 2**31 - 1), "channel": (0, 5), "start_s": (0.0, 86400.0), "end_s": (0.0, FOREVER_S),
    "rate": (1, 200),
}


class _Reader:
    def __init__(self, label: str):
        self.label = label

    def fail(self, where: str, msg: str):
        raise ScenarioError(f"{self.label}: {where}: {msg}" if where else f"{self.label}: {msg}")

    def table(self, where: str, value) -> dict:
        if not isinstance(value, dict):
            self.fail(where, f"must be a table, got {value!r}")
        return value

    def keys(self, where: str, data: dict, known) -> None:
        unknown = sorted(set(data) - set(known))
        if unknown:
            self.fail(where, f"unknown key(s) {', '.join(unknown)}; known: {', '.join(known)}")

    def number(self, where: str, key: str, value, limit: str | None = None, *, integer: bool = False,
               open_low: bool = False):
        name = f"{where}.{key}" if where else key
        if isinstance(value, bool) or not isinstance(value, int if integer else (int, float)):
            self.fail(name, f"must be {'a whole number' if integer else 'a number'}, got {value!r}")
        if not integer and not math.isfinite(value):
            self.fail(name, f"must be finite, got {value!r}")
        lo, hi = LIMITS[limit or key]
        if value < lo or value > hi or (open_low and value <= lo):
            self.fail("", f"{name} = {value!r}: must be in {'(' if open_low else '['}{lo:g}, {hi:g}]")
        return value if integer else float(value)

    def string(self, where: str, key: str, value, choices=None) -> str:
        name = f"{where}.{key}" if where else key
        if not isinstance(value, str):
            self.fail(name, f"must be a string, got {value!r}")
        if choices is not None and value not in choices:
            self.fail("", f"{name} = {value!r}: must be one of {', '.join(choices)}")
        return value

    def bands(self, where: str, value) -> tuple:
        name = f"{where}.emergency_decel_mps2"
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [[0.0, value]]
        if not isinstance(value, list) or not 1 <= len(value) <= 3:
            self.fail(name, "a number or 1 to 3 bands [[from_speed_mps, decel_mps2], ...]")
        bands = []
        for band in value:
            if (not isinstance(band, list) or len(band) != 2
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in band)
                    or not 0 <= band[0] <= 120 or not 0 < band[1] <= 20):
                self.fail(name, f"band {band!r}: [from_speed 0..120 m/s, decel in (0, 20] m/s^2]")
            bands.append((float(band[0]), float(band[1])))
        if bands[0][0] != 0.0 or any(b[0] <= a[0] for a, b in zip(bands, bands[1:])):
            self.fail(name, "bands start at 0 m/s and their speeds increase")
        return tuple(bands)

    # -- sections

    def train(self, data) -> TrainSpec:
        data = self.table("train", data)
        self.keys("train", data, [f.name for f in fields(TrainSpec)])
        out = {}
        for key, value in data.items():
            if key == "emergency_decel_mps2":
                out[key] = self.bands("train", value)
            elif key == "track":
                out[key] = self.string("train", key, value, TRACKS)
            elif key == "brake":
                out[key] = self.string("train", key, value, BRAKES)
            else:
                out[key] = self.number("train", key, value, open_low=key in ("service_decel_mps2",))
        train = TrainSpec(**out)
        if train.service_decel_mps2 > min(a for _, a in train.emergency_decel_mps2):
            self.fail("", f"train.service_decel_mps2 = {train.service_decel_mps2:g} exceeds an emergency deceleration")
        return train

    def obstacle(self, i: int, data) -> ObstacleSpec:
        where = f"obstacles[{i}]"
        data = self.table(where, data)
        self.keys(where, data, [f.name for f in fields(ObstacleSpec)])
        out = {}
        for key, value in data.items():
            if key == "type":
                out[key] = self.string(where, key, value, OBSTACLE_TYPES)
            elif key == "hidden_channels":
                out[key] = self.channels(where, key, value)
            else:
                out[key] = self.number(where, key, value, "obstacle_speed_mps" if key == "speed_mps" else None,
                                       open_low=key == "position_m")
        return self.leaves_after_appearing(where, ObstacleSpec(**out))

    def channels(self, where: str, key: str, value) -> tuple:
        """A non-empty list of distinct channels 0..5."""
        if not isinstance(value, (list, tuple)) or not value:
            self.fail(f"{where}.{key}", f"must be a non-empty list of channels 0..5, got {value!r}")
        out = tuple(self.number(where, key, v, "hidden_channel", integer=True) for v in value)
        if len(set(out)) != len(out):
            self.fail(f"{where}.{key}", f"names a channel twice: {list(out)}")
        return out

    def leaves_after_appearing(self, where: str, o: ObstacleSpec) -> ObstacleSpec:
        if o.leave_s <= o.appear_s:
            self.fail("", f"{where}.leave_s = {o.leave_s:g}: must be after appear_s = {o.appear_s:g}")
        if o.hidden_from_s == FOREVER_S and (o.hidden_until_s, o.hidden_channels) != (FOREVER_S, ALL_CHANNELS):
            self.fail(where, "hidden_until_s and hidden_channels need hidden_from_s (else nothing is hidden)")
        if o.hidden_until_s <= o.hidden_from_s and o.hidden_from_s != FOREVER_S:
            self.fail("", f"{where}.hidden_until_s = {o.hidden_until_s:g}: must be after hidden_from_s = "
                          f"{o.hidden_from_s:g}")
        return o

    def sensors(self, data) -> SensorSpec:
        data = self.table("sensors", data)
        self.keys("sensors", data, [f.name for f in fields(SensorSpec)])
        out = {k: self.number("sensors", k, v, integer=k == "seed", open_low=k == "range_m") for k, v in data.items()}
        if out.get("miss_probability", 0.0) >= 1.0:
            self.fail("sensors.miss_probability", "must be below 1")
        return SensorSpec(**out)

    def fault(self, i: int, data) -> FaultSpec:
        where = f"faults[{i}]"
        data = self.table(where, data)
        self.keys(where, data, [f.name for f in fields(FaultSpec)])
        if "kind" not in data or "start_s" not in data:
            self.fail(where, "needs kind and start_s" + ("" if data.get("kind") in CHANNEL_FREE_KINDS else " and channel"))
        kind = self.string(where, "kind", data["kind"], FAULT_KINDS)
        if kind in CHANNEL_FREE_KINDS and "channel" in data:
            self.fail(f"{where}.channel", f"a {kind} fault hits every channel: no channel")
        if kind not in CHANNEL_FREE_KINDS and "channel" not in data:
            self.fail(where, "needs a channel (0..5)")
        out = {k: self.number(where, k, v, integer=k in ("channel", "rate")) for k, v in data.items() if k != "kind"}
        f = FaultSpec(kind, **out)
        if f.end_s <= f.start_s:
            self.fail(where, f"end_s = {f.end_s:g} must be after start_s = {f.start_s:g}")
        if "rate" in data and kind != "babble":
            self.fail(f"{where}.rate", "only a babble fault has a rate")
        return f

    def monitor(self, data) -> dict:
        data = self.table("monitor", data)
        self.keys("monitor", data, MONITOR_KEYS)
        out = {}
        for key, value in data.items():
            if key == "topology":
                codes = {v: k for k, v in TOPOLOGY_CODES.items()}
                if value in codes and not isinstance(value, bool):
                    value = codes[value]
                out[key] = self.string("monitor", key, value, tuple(TOPOLOGY_CODES))
            elif isinstance(value, bool) or not isinstance(value, int):
                self.fail(f"monitor.{key}", f"must be a whole number (the units are in the name), got {value!r}")
            else:
                out[key] = value
        return out

    def campaign(self, data) -> CampaignSpec:
        data = self.table("campaign", data)
        self.keys("campaign", data, [f.name for f in fields(CampaignSpec)])
        out = {}
        if "fault_start_s" in data:
            v = data["fault_start_s"]
            if (not isinstance(v, list) or len(v) != 2
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
                    or not 0 <= v[0] <= v[1] <= 3600):
                self.fail("", f"campaign.fault_start_s = {v!r}: must be [earliest, latest] in seconds, "
                              "0 <= earliest <= latest <= 3600")
            out["fault_start_s"] = (float(v[0]), float(v[1]))
        return CampaignSpec(**out)


def parse(data: dict, name: str, source: str = "") -> Scenario:
    """A Scenario from the mapping of a TOML file (every key checked; unknown keys refused)."""
    r = _Reader(source or f"{name}.toml")
    r.keys("", data, TOP_KEYS)
    kw: dict = {}
    if "description" in data:
        kw["description"] = r.string("", "description", data["description"])
    if "duration_s" in data:
        kw["duration_s"] = r.number("", "duration_s", data["duration_s"], open_low=True)
    if "table" in data:
        kw["table"] = r.string("", "table", data["table"])
    if "demand_delay_cycles" in data:
        kw["demand_delay_cycles"] = r.number("", "demand_delay_cycles", data["demand_delay_cycles"], integer=True)
    if "train" in data:
        kw["train"] = r.train(data["train"])
    if "sensors" in data:
        kw["sensors"] = r.sensors(data["sensors"])
    for key, one in (("obstacles", r.obstacle), ("faults", r.fault)):
        if key in data:
            items = data[key]
            if not isinstance(items, list):
                r.fail(key, f"must be an array of tables ([[{key}]])")
            kw[key] = tuple(one(i, item) for i, item in enumerate(items))
    if "monitor" in data:
        kw["monitor"] = r.monitor(data["monitor"])
    if "braking" in data:
        kw["braking"] = dict(r.table("braking", data["braking"]))
    if "campaign" in data:
        kw["campaign"] = r.campaign(data["campaign"])
    scen = Scenario(name, source=source or f"{name}.toml", **kw)
    monitor_parameters(scen)            # [monitor] and [braking] checked together
    return scen


def monitor_parameters(scen: Scenario) -> dict:
    """The monitor's Config fields the scenario sets: its [braking] declaration's, then its
    [monitor] keys (a key may not be set by both); checked together on the default Config."""
    declared = {}
    if scen.braking is not None:
        try:
            declared = declaration_fields(scen.braking, f"{scen.label}: braking")
        except DeclarationError as exc:
            raise ScenarioError(str(exc)) from None
    both = sorted(set(declared) & set(scen.monitor))
    if both:
        raise ScenarioError(f"{scen.label}: monitor: {', '.join(both)} set by both [braking] and [monitor]; keep one")
    params = {**scen.monitor, **declared}
    try:
        check_config(Config()._replace(**params))
    except ConfigurationError as exc:
        where = "braking" if scen.braking is not None and not scen.monitor else "monitor"
        raise ScenarioError(f"{scen.label}: {where}: {exc}") from None
    return params


def monitor_config(scen: Scenario, base: Config = Config()) -> Config:
    """`base` with the scenario's [braking] and [monitor] values (what a player that honours
    them configures the monitor with)."""
    cfg = base._replace(**monitor_parameters(scen))
    try:
        check_config(cfg)
    except ConfigurationError as exc:
        raise ScenarioError(f"{scen.label}: monitor: {exc}") from None
    return cfg


def loads(text: str, name: str, source: str = "") -> Scenario:
    """A Scenario from TOML text; malformed TOML is refused with its line."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source or name + '.toml'}: malformed TOML: {exc}") from None
    return parse(data, name, source)


def _folder():
    return resources.files("monitor").joinpath("scenarios")


def shipped_names() -> list[str]:
    """The names of the shipped scenarios (monitor/scenarios/*.toml), sorted."""
    return sorted(p.name[:-5] for p in _folder().iterdir() if p.name.endswith(".toml"))


def load(spec: str | Path | None = None) -> Scenario:
    """A shipped scenario by name (None: DEFAULT), or a TOML file by path."""
    spec = str(spec) if spec is not None else DEFAULT
    p = Path(spec)
    if p.suffix != ".toml" and not p.exists():
        f = _folder().joinpath(f"{spec}.toml")
        if "/" in spec or not f.is_file():
            raise ScenarioError(f"{spec}: no such scenario file or shipped scenario; shipped: {', '.join(shipped_names())}")
        return loads(f.read_text(encoding="utf-8"), spec, f"{spec}.toml")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{spec}: no such scenario file or cannot read it: {exc}") from None
    return loads(text, p.stem, spec)


def check(scen: Scenario) -> None:
    """Check a Scenario built in code (the loader checks files as it reads them)."""
    r = _Reader(scen.label)
    r.number("", "duration_s", scen.duration_s, open_low=True)
    tr = scen.train
    for f in fields(TrainSpec):
        value = getattr(tr, f.name)
        if f.name == "emergency_decel_mps2":
            r.bands("train", [list(b) for b in value])
        elif f.name in ("track", "brake"):
            r.string("train", f.name, value, TRACKS if f.name == "track" else BRAKES)
        else:
            r.number("train", f.name, value, open_low=f.name == "service_decel_mps2")
    if tr.service_decel_mps2 > min(a for _, a in tr.emergency_decel_mps2):
        r.fail("", f"train.service_decel_mps2 = {tr.service_decel_mps2:g} exceeds an emergency deceleration")
    for i, o in enumerate(scen.obstacles):          # (the file's own checks, on the spec's fields)
        r.obstacle(i, asdict(o))
    r.sensors(asdict(scen.sensors))
    for i, f in enumerate(scen.faults):
        where = f"faults[{i}]"
        r.string(where, "kind", f.kind, FAULT_KINDS)
        r.number(where, "channel", f.channel, integer=True)
        r.number(where, "start_s", f.start_s)
        r.number(where, "end_s", f.end_s)
        r.number(where, "rate", f.rate, integer=True)
        if f.end_s <= f.start_s:
            r.fail(where, f"end_s = {f.end_s:g} must be after start_s = {f.start_s:g}")
    monitor_parameters(scen)


# ----------------------------------------------------------------------------- the players

def _train_beyond(tr: TrainSpec, allowed: tuple) -> Optional[str]:
    """The first [train] key (outside `allowed`) whose value differs from the default."""
    default = TrainSpec()
    for f in fields(TrainSpec):
        if f.name not in allowed and getattr(tr, f.name) != getattr(default, f.name):
            return f.name
    return None


RUN_TRAIN = ("speed_mps", "service_decel_mps2", "emergency_decel_mps2", "brake_buildup_s", "track", "brake",
             "mass_kg", "traction_cutoff_s")
RUN_TRAIN_WHY = {
    "brake_delay_s": "the player's brakes have no dead time (only the ramp brake_buildup_s)",
    "max_traction_mps2": "the player's train does not accelerate (no traction after a release)",
    "cruise_speed_mps": "the player's train does not accelerate (it cruises at speed_mps)",
    "gradient_permille": "the player's track is level",
    "speed_error": "the player reports the true speed",
    "slippery_factor": "the player's brakes keep their decelerations on a slippery track",
    "degraded_factor": "the player's brakes keep their decelerations when reported degraded",
}


def refusal(scen: Scenario, player: str) -> Optional[str]:
    """Why `player` (run, cosim, campaign) cannot play `scen`: "key: reason", or None."""
    if player == "run":
        if scen.duration_s > 3600:
            return f"duration_s = {scen.duration_s:g}: the player plays at most 3600 s"
        key = _train_beyond(scen.train, RUN_TRAIN)
        if key is not None:
            return f"train.{key}: {RUN_TRAIN_WHY.get(key, 'the player has no running resistance')}; run cannot play it"
        for i, f in enumerate(scen.faults):
            if f.kind not in RUN_FAULT_KINDS:
                return f"faults[{i}].kind = {f.kind!r}: the player injects {', '.join(RUN_FAULT_KINDS)}"
        if scen.demand_delay_cycles != 1:
            return "demand_delay_cycles: on the bus the demand arrives when its frame does; run plays only 1"
        if monitor_parameters(scen) and Config()._replace(**monitor_parameters(scen)) != Config():
            return (f"{'braking' if scen.braking is not None else 'monitor'}: `railguard run` configures the "
                    "monitor from its command line (--braking); run plays scenarios that keep the default configuration")
        return None
    if player == "cosim":
        if len(scen.obstacles) > 1:
            return "obstacles[1]: the train FMU has one obstacle; cosim plays scenarios with at most one"
        if scen.obstacles and scen.obstacles[0].appear_s != 0.0:
            return "obstacles[0].appear_s: the train FMU's obstacle is there from the start; cosim plays appear_s = 0 only"
        if scen.obstacles and scen.obstacles[0].hidden_from_s != FOREVER_S:
            return "obstacles[0].hidden_from_s: the train FMU's sensors always see its obstacle; cosim plays no hidden one"
        if len(scen.faults) > 1:
            return "faults[1]: the train FMU injects one fault; cosim plays scenarios with at most one"
        for i, f in enumerate(scen.faults):
            if f.kind not in COSIM_FAULT_KINDS:
                return f"faults[{i}].kind = {f.kind!r}: the train FMU injects {', '.join(COSIM_FAULT_KINDS)}"
        return None
    if player == "campaign":
        if scen.campaign is None:
            return "campaign: no [campaign] table (its fault windows): not one of the campaign's worlds"
        key = _train_beyond(scen.train, ("speed_mps",))
        if key is not None:
            return f"train.{key}: the campaign draws each run's train inside the braking declaration; it plays speed_mps only"
        if (scen.sensors.range_m, scen.sensors.noise_sigma_m, scen.sensors.distance_bias_m,
                scen.sensors.closing_bias_mps) != (SensorSpec.range_m, SensorSpec.noise_sigma_m, 0.0, 0.0):
            return (f"sensors: the campaign's sensors reach {SensorSpec.range_m:g} m with {SensorSpec.noise_sigma_m:g} m "
                    "noise and no bias; it plays those only")
        if scen.sensors.miss_probability != 0.0:
            return "sensors.miss_probability: the campaign's misses are its faults; it plays 0 only"
        if scen.faults:
            return "faults[0]: the campaign injects its own faults; it plays scenarios without [[faults]]"
        for i, o in enumerate(scen.obstacles):
            if o.leave_s != FOREVER_S:
                return f"obstacles[{i}].leave_s: the campaign's obstacles stay on the track; it plays no leave_s"
            if o.hidden_from_s != FOREVER_S:
                return f"obstacles[{i}].hidden_from_s: the campaign's faults hide obstacles; it plays no hidden_from_s"
        if monitor_parameters(scen):
            return f"{'braking' if scen.braking is not None else 'monitor'}: the campaign configures the monitor with --braking"
        return None
    raise ValueError(f"unknown player {player!r}; players: {', '.join(PLAYERS)}")


def require(scen: Scenario, player: str, error: type = ScenarioError) -> Scenario:
    """`scen` if `player` can play it, otherwise `error` (a ScenarioError) in one line naming
    the file and the key."""
    why = refusal(scen, player)
    if why is not None:
        raise error(f"{scen.label}: {why}")
    return scen


def players(scen: Scenario) -> tuple:
    """The players that can play `scen`."""
    return tuple(p for p in PLAYERS if refusal(scen, p) is None)


class Entry(NamedTuple):
    name: str
    description: str
    players: tuple          # of PLAYERS: the players that can play it


def catalogue() -> list[Entry]:
    """Every shipped scenario: (name, description, players that can play it), by name."""
    out = []
    for name in shipped_names():
        scen = load(name)
        out.append(Entry(name, scen.description, players(scen)))
    return out
