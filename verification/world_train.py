"""The world's train: a Python twin of the train FMU's physics, with parameters of its own.

A campaign that judges "unsafe" with the monitor's own braking curves proves nothing about
the world. Here the world is the judge: its train brakes as `TrainTwin` (the same equations
as fmu/c/train/model.c, internal step 10 ms: brake dead time, a linear build-up, speed bands,
Davis resistance, gradient, traction held after a demand; tests/test_world_train.py holds it
equal to the FMU in FMPy), and its parameters come from a `WorldTrain` that does not read
the monitor's configuration:

* `within(cfg, rng)` draws a train inside the braking declaration the monitor was given
  (deceleration at or above the guaranteed one, equivalent build-up at or below the declared,
  downhill at most the steepest, traction at most as declared, speed under-reported at most
  by the declared error), with `corners(cfg)` (every limit at once) among the draws;
* `load(path)` reads a train from a TOML file (`railguard campaign --world-train FILE`),
  which may brake worse than any declaration: then the campaign must report unsafe runs.

The timing of the world is part of it: `sensor_latency_s` (an obstacle is sensed this long
before its frame is received; the monitor counts ages from reception) and
`output_latency_s` (a demand reaches the brakes this long after the cycle that made it).
"""
from __future__ import annotations

import hashlib
import math
import random
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Optional

from monitor.scenario import FMU_TRAIN_NAMES, band_decel

STEP_S = 0.01                 # the FMU's FIXED_STEP
G = 9.81
SPEED_GAIN = 1.0              # 1/s, the FMU's cruise controller
MAX_DELAY_STEPS = 500
REACTION_S = 0.1              # the world's sensors report every 100 ms: the earliest any monitor can know


class WorldTrainError(ValueError):
    """A world-train file that cannot be used; the message names the file and the key."""


@dataclass(frozen=True)
class WorldTrain:
    """One world train, SI units, the train FMU's parameter names (docs/train_fmu.md)."""

    emergency_decel: tuple = ((0.0, 3.0),)   # ((from_speed m/s, decel m/s^2), ...), 1..3 bands
    service_decel: float = 1.0               # m/s^2
    brake_delay: float = 0.2                 # s of pure dead time before a brake acts
    brake_buildup: float = 0.5               # s for the full emergency deceleration to build up
    traction_cutoff: float = -1.0            # s of full traction after a demand (< 0: cut at once)
    max_traction: float = 0.5                # m/s^2
    gradient: float = 0.0                    # per mille, positive uphill
    speed_error: float = 0.0                 # the reported speed is true / (1 + speed_error)
    mass: float = 400000.0                   # kg
    davis_a: float = 0.0                     # N (no running resistance: it would help the brakes)
    davis_b: float = 0.0                     # N s/m
    davis_c: float = 0.0                     # N s^2/m^2
    sensor_latency_s: float = 0.0            # s from sensing an obstacle to its frame's reception
    output_latency_s: float = 0.0            # s from the cycle's demand to the brakes

    def equivalent_buildup_s(self) -> float:
        """Dead time plus half the ramp: what a declaration's build-up time stands for."""
        return self.brake_delay + self.brake_buildup / 2

    def emergency_at(self, v: float) -> float:
        return band_decel(self.emergency_decel, v)

    def fmu_parameters(self) -> dict:
        """The train FMU's parameters for this train (tests hold the twin equal to it)."""
        bands = list(self.emergency_decel) + [(0.0, 0.0)] * (3 - len(self.emergency_decel))
        return {"emergency_decel": bands[0][1], "emergency_band2_speed": bands[1][0],
                "emergency_band2_decel": bands[1][1], "emergency_band3_speed": bands[2][0],
                "emergency_band3_decel": bands[2][1], "service_decel": self.service_decel,
                "brake_delay": self.brake_delay, "brake_buildup": self.brake_buildup,
                "traction_cutoff": self.traction_cutoff, "max_traction": self.max_traction,
                "gradient": self.gradient, "speed_error": self.speed_error, "mass": self.mass,
                "davis_a": self.davis_a, "davis_b": self.davis_b, "davis_c": self.davis_c}

    def describe(self) -> str:
        bands = ", ".join(f"{a:g} m/s^2" + (f" from {lo:g} m/s" if lo else "") for lo, a in self.emergency_decel)
        return (f"emergency {bands}, service {self.service_decel:g} m/s^2, dead time {self.brake_delay:g} s + "
                f"ramp {self.brake_buildup:g} s, gradient {self.gradient:g} per mille, traction "
                f"{self.max_traction:g} m/s^2 for {max(self.traction_cutoff, 0):g} s, speed error {self.speed_error:g}, "
                f"latencies {1000 * self.sensor_latency_s:.0f} / {1000 * self.output_latency_s:.0f} ms")


class TrainTwin:
    """fmu/c/train/model.c's internal_step in Python, for a train that has entered (its
    demands obeyed at once): same order of operations, same floats."""

    def __init__(self, world: WorldTrain, speed: float, record: bool = False):
        self.w = world
        self.speed = float(speed)
        self.cruise = float(speed)
        self.position = 0.0
        self.acceleration = 0.0
        self.running = speed > 0.0
        self.brake_decel = 0.0
        self.brake_target = 0.0
        self.brake_level = 0
        self.last_demand = 0
        self.demand_start = 0.0
        self.time = 0.0
        self.steps = 0
        self.delay_steps = min(MAX_DELAY_STEPS, int(math.floor(world.brake_delay / STEP_S + 0.5)))
        self.ring = [0] * (MAX_DELAY_STEPS + 1)
        self.head = 0
        self.history = ([0.0], [float(speed)]) if record else None    # position, speed at every step

    def copy(self) -> "TrainTwin":
        twin = TrainTwin.__new__(TrainTwin)
        twin.__dict__.update(self.__dict__)
        twin.ring = list(self.ring)
        twin.history = None
        return twin

    def at(self, t: float) -> tuple[float, float]:
        """(position, speed) at time `t` <= now, interpolated between steps (needs record=True):
        what a sensor that sampled at `t` saw."""
        xs, vs = self.history
        f = min(max(t, 0.0) / STEP_S, len(xs) - 1.0)
        i = min(int(f), len(xs) - 2)
        if i < 0:
            return xs[0], vs[0]
        w = f - i
        return xs[i] + w * (xs[i + 1] - xs[i]), vs[i] + w * (vs[i + 1] - vs[i])

    def _level_decel(self, level: int, v: float) -> float:
        if level == 0:
            return 0.0
        return self.w.service_decel if level == 1 else self.w.emergency_at(v)

    def _resistance(self, v: float) -> float:
        w = self.w
        return (w.davis_a + w.davis_b * v + w.davis_c * v * v) / w.mass

    def _traction(self, demand: int, level: int, t: float, v: float) -> float:
        w = self.w
        if not self.running or self.cruise <= 0.0:
            return 0.0
        if w.traction_cutoff >= 0.0 and demand > 0:
            return w.max_traction if t - self.demand_start < w.traction_cutoff - 1e-9 else 0.0
        if level != 0:
            return 0.0
        traction = self._resistance(v) + G * w.gradient / 1000.0 + SPEED_GAIN * (self.cruise - v)
        return min(max(traction, 0.0), w.max_traction)

    def step(self, demand: int) -> None:
        """One internal step of STEP_S under `demand` (0 none, 1 service, 2 emergency)."""
        demand = 0 if demand == 0 else 1 if demand == 1 else 2
        t = self.time
        v = self.speed
        if demand > 0 and self.last_demand == 0:
            self.demand_start = t
        self.last_demand = demand
        n = len(self.ring)
        self.head = (self.head + 1) % n
        self.ring[self.head] = demand
        previous = self.brake_level
        level = self.ring[(self.head + n - self.delay_steps) % n]
        self.brake_level = level
        target = self._level_decel(level, v)
        if self.w.brake_buildup <= 0.0 or (level == previous and self.brake_decel == self.brake_target):
            self.brake_decel = target
        else:
            ramp = self.w.emergency_at(v) / self.w.brake_buildup * STEP_S
            if self.brake_decel < target:
                self.brake_decel = min(self.brake_decel + ramp, target)
            elif self.brake_decel > target:
                self.brake_decel = max(self.brake_decel - ramp, target)
        self.brake_target = target
        self.steps += 1
        self.time = self.steps * STEP_S

        traction = self._traction(demand, level, t, v)
        grade = G * self.w.gradient / 1000.0
        if v > 0.0:
            a = traction - self._resistance(v) - grade - self.brake_decel
            v_new = v + a * STEP_S
            if v_new <= 0.0:
                t_stop = v / -a if a < 0.0 else STEP_S
                dx = 0.5 * v * min(t_stop, STEP_S)
                v_new = 0.0
                if self.running and (level > 0 or self.brake_decel > 0.0):
                    self.running = False            # stopped by the brakes: waits for the rest of the run
            else:
                dx = 0.5 * (v + v_new) * STEP_S
        else:
            a = 0.0
            if traction > 0.0:
                a = max(0.0, traction - self._resistance(0.0) - grade - self.brake_decel)
            v_new = a * STEP_S
            dx = 0.5 * v_new * STEP_S
        self.speed = v_new
        self.position += dx
        self.acceleration = a
        if self.history is not None:
            self.history[0].append(self.position)
            self.history[1].append(self.speed)

    def cycle(self, before: int, demand: int, period_ms: int):
        """The internal steps of one monitor cycle (a generator, one yield per step): the
        previous demand `before` still acts for the output latency, then `demand`."""
        late = math.ceil(self.w.output_latency_s / STEP_S - 1e-9)
        for j in range(max(1, round(period_ms / (1000 * STEP_S)))):
            self.step(before if j < late else demand)
            yield

    def can_stop_for(self, gap_m: float, obstacle_speed: float, held: int) -> bool:
        """Whether the collision with an obstacle that has just come into sensor range is
        avoidable: this train stops short of it with an emergency demand from one sensor report
        (REACTION_S) plus the output latency on, `held` acting meanwhile. The allowance is the
        world's own, not the monitor's cycle."""
        return self.stops_within(gap_m, obstacle_speed, REACTION_S + self.w.output_latency_s, held)

    def measured_speed(self) -> float:
        """What the train's speed sensor reports (low by its error)."""
        return self.speed / (1.0 + self.w.speed_error)

    def stops_within(self, gap_m: float, obstacle_speed: float = 0.0, after_s: float = 0.0, hold: int = 0,
                     limit_s: float = 600.0) -> bool:
        """Whether this train, demanding `hold` for `after_s` and emergency from then on,
        stays short of an obstacle `gap_m` ahead moving at `obstacle_speed` (a copy is
        stepped; this twin is unchanged)."""
        twin = self.copy()
        start = twin.position
        wait = round(after_s / STEP_S)
        for k in range(int(limit_s / STEP_S)):
            twin.step(hold if k < wait else 2)
            gap = gap_m + obstacle_speed * (k + 1) * STEP_S - (twin.position - start)
            if gap <= 0.0:
                return False
            if twin.speed == 0.0:
                return True
        return True


# ----------------------------------------------------------------------------- from the declaration

def _bands_of(cfg) -> list[tuple[float, float]]:
    from monitor.core.config import emergency_bands

    return [(lo / 100.0, a / 1000.0) for lo, a in emergency_bands(cfg)]


def corners(cfg) -> list[WorldTrain]:
    """The worst trains the monitor's declaration (its Config) admits: the guaranteed
    decelerations exactly, the steepest downhill, full traction for the whole cut-off, the
    speed reported low by the whole error, and the declared equivalent build-up spent as pure
    dead time or as dead time plus a ramp twice as long; latencies of 10 ms each way."""
    bands = tuple(_bands_of(cfg))
    buildup = cfg.emergency_buildup_ms / 1000.0
    base = WorldTrain(emergency_decel=bands, service_decel=cfg.service_decel_mms2 / 1000.0,
                      brake_delay=buildup, brake_buildup=0.0, traction_cutoff=cfg.traction_cutoff_ms / 1000.0,
                      max_traction=cfg.max_accel_mms2 / 1000.0, gradient=-float(cfg.max_gradient_permille),
                      speed_error=cfg.speed_error_permille / 1000.0, sensor_latency_s=0.01, output_latency_s=0.01)
    half = buildup / 2
    return [base, replace(base, brake_delay=round(half, 3), brake_buildup=round(buildup, 3))]


def within(cfg, rng: random.Random) -> WorldTrain:
    """A train drawn inside the declaration: every value between the declared limit and a
    better one (decelerations up to 30 % above the guaranteed; build-up, gradient, traction,
    speed error and latencies down to none)."""
    worst = corners(cfg)[0]
    lift = 1.0 + 0.3 * rng.random()
    bands = tuple((lo, round(a * lift, 4)) for lo, a in worst.emergency_decel)
    service = round(min(worst.service_decel * (1.0 + 0.3 * rng.random()), bands[0][1]), 4)
    equivalent = worst.brake_delay * rng.random()
    delay = round(equivalent * rng.random(), 3)                    # the rest as a ramp twice as long
    ramp = round(2 * (equivalent - delay), 3)
    return replace(worst, emergency_decel=bands, service_decel=service, brake_delay=delay, brake_buildup=ramp,
                   traction_cutoff=round(worst.traction_cutoff * rng.random(), 3),
                   max_traction=round(worst.max_traction * rng.random(), 3),
                   gradient=round(worst.gradient * rng.random(), 2), speed_error=round(worst.speed_error * rng.random(), 4),
                   sensor_latency_s=round(0.01 * rng.random(), 4), output_latency_s=round(0.01 * rng.random(), 4))


def broken_bounds(world: WorldTrain, cfg) -> list[str]:
    """The braking declaration's bounds (the Config's, read as the physics model reads them:
    verification/physics/model.py) that this world's train breaks, key by key; [] inside."""
    from fractions import Fraction

    from .physics.model import Declaration

    d = Declaration.of(cfg)
    out = []
    declared = lambda v: float([a for lo, a in d.bands if v >= lo][-1])  # noqa: E731
    points = sorted({0.0, 120.0, *(float(lo) for lo, _ in d.bands), *(lo for lo, _ in world.emergency_decel)})
    points = sorted({p for v in points for p in (v, max(0.0, v - 1e-6))})
    worst = next((v for v in points if world.emergency_at(v) < declared(v) - 1e-9), None)
    if worst is not None:
        out.append(f"emergency_decel: {world.emergency_at(worst):g} m/s^2 at {worst:g} m/s, below the declared "
                   f"{declared(worst):g}")
    if world.service_decel < float(d.service_decel) - 1e-9:
        out.append(f"service_decel: {world.service_decel:g} m/s^2, below the declared {float(d.service_decel):g}")
    if Fraction(world.equivalent_buildup_s()).limit_denominator(10**6) > d.emergency_buildup:
        out.append(f"emergency_buildup_s: brake_delay + brake_buildup / 2 = {world.equivalent_buildup_s():g} s, above "
                   f"the declared {float(d.emergency_buildup):g}")
    if world.traction_cutoff > float(d.traction_cutoff) + 1e-9:
        out.append(f"traction_cutoff_s: {world.traction_cutoff:g} s, above the declared {float(d.traction_cutoff):g}")
    if world.traction_cutoff > 0 and world.max_traction > float(d.max_accel) + 1e-9:
        out.append(f"max_accel: traction {world.max_traction:g} m/s^2, above the declared {float(d.max_accel):g}")
    if -world.gradient > float(d.max_gradient) * 1000 + 1e-9:
        out.append(f"max_downhill_gradient: {-world.gradient:g} per mille downhill, beyond the declared "
                   f"{float(d.max_gradient) * 1000:g}")
    if world.speed_error > float(d.speed_error) + 1e-9:
        out.append(f"speed_error: {world.speed_error:g}, above the declared {float(d.speed_error):g}")
    return out


CORNER_SHARE = 4     # one run in CORNER_SHARE runs on a corner train (alternating the two corners)


def for_run(cfg, key: str) -> WorldTrain:
    """The world train of a campaign run, from the run's own key (so independent of the
    order and the process the runs are made in): a corner for one key in CORNER_SHARE,
    otherwise drawn inside the declaration."""
    h = int.from_bytes(hashlib.sha256(f"railguard-world/{key}".encode()).digest()[:8], "little")
    if h % CORNER_SHARE == 0:
        return corners(cfg)[(h // CORNER_SHARE) % 2]
    return within(cfg, random.Random(h))


# ----------------------------------------------------------------------------- from a file

NUMBER_KEYS = {f.name: f for f in fields(WorldTrain) if f.name != "emergency_decel"}
LIMITS = {"service_decel": (0.0, 20.0), "brake_delay": (0.0, 5.0), "brake_buildup": (0.0, 30.0),
          "traction_cutoff": (-1.0, 30.0), "max_traction": (0.0, 5.0), "gradient": (-60.0, 60.0),
          "speed_error": (0.0, 0.5), "mass": (1.0, 1e8), "davis_a": (0.0, 1e7), "davis_b": (0.0, 1e6),
          "davis_c": (0.0, 1e5), "sensor_latency_s": (0.0, 5.0), "output_latency_s": (0.0, 5.0)}


def _scenario_names() -> dict:
    """The [train] keys of the one scenario language (monitor/scenario.py) that name a field
    here: a [world_train] table may use them (a scenario's [train] dynamics, pasted)."""
    own = {f.name for f in fields(WorldTrain)}
    return {key: name for key, name in FMU_TRAIN_NAMES.items() if name in own and key != name}


def from_mapping(values: dict, where: str) -> WorldTrain:
    """A WorldTrain from a mapping of its field names, or of the scenario language's [train]
    names for them (brake_delay_s for brake_delay, ...); missing ones keep the defaults."""
    aliases = _scenario_names()
    both = sorted(k for k in values if k in aliases and aliases[k] in values)
    if both:
        raise WorldTrainError(f"{where}: {', '.join(both)} and {', '.join(aliases[k] for k in both)} name the same "
                              "value; keep one")
    values = {aliases.get(k, k): v for k, v in values.items()}
    unknown = sorted(set(values) - set(NUMBER_KEYS) - {"emergency_decel"})
    if unknown:
        raise WorldTrainError(f"{where}: unknown key(s) {', '.join(unknown)}; known: emergency_decel, "
                              f"{', '.join(NUMBER_KEYS)}")
    out = {}
    for key, value in values.items():
        if key == "emergency_decel":
            out[key] = _bands(where, value)
            continue
        lo, hi = LIMITS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not lo <= value <= hi:
            raise WorldTrainError(f"{where}: {key} = {value!r}: must be a number in {lo:g}..{hi:g}")
        out[key] = float(value)
    train = WorldTrain(**out)
    if train.service_decel > min(a for _, a in train.emergency_decel):
        raise WorldTrainError(f"{where}: service_decel = {train.service_decel:g} exceeds an emergency deceleration")
    return train


def _bands(where: str, value) -> tuple:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [[0.0, value]]
    if not isinstance(value, list) or not 1 <= len(value) <= 3:
        raise WorldTrainError(f"{where}: emergency_decel: a number or 1 to 3 bands [[from_speed_m_s, decel], ...]")
    bands = []
    for band in value:
        if (not isinstance(band, list) or len(band) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in band)
                or not 0 <= band[0] <= 120 or not 0 < band[1] <= 20):
            raise WorldTrainError(f"{where}: emergency_decel band {band!r}: [from_speed 0..120 m/s, decel 0..20 m/s^2]")
        bands.append((float(band[0]), float(band[1])))
    if bands[0][0] != 0.0 or any(b[0] <= a[0] for a, b in zip(bands, bands[1:])):
        raise WorldTrainError(f"{where}: emergency_decel: bands start at 0 m/s and their speeds increase")
    return tuple(bands)


def load(path: str | Path) -> WorldTrain:
    """A world train from a TOML file: a `[world_train]` table, or keys at top level."""
    from monitor.offline.params import ConfigError, read_toml

    try:
        data = read_toml(path)
    except ConfigError as exc:
        raise WorldTrainError(f"{exc} (world train)") from None
    table = data.get("world_train", data) if isinstance(data.get("world_train"), dict) else data
    return from_mapping(table, str(path))


def as_dict(train: Optional[WorldTrain]) -> Optional[dict]:
    return None if train is None else dict(asdict(train), emergency_decel=[list(b) for b in train.emergency_decel])
