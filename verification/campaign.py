"""Fault-injection campaign: every single fault and every pair of faults from a catalogue,
crossed with obstacle scenarios, through the monitor core, the real runner and codec on the
virtual bus, and real SocketCAN vcan0 in the user-mode-Linux sandbox.

Core-level runs (the bulk, >= 10,000 in full mode, two processes): a small simulated world
(a train that brakes as its braking declaration guarantees at worst, six sensor channels
with Gaussian distance noise, the obstacle scenario) drives `monitor.core.cycle` directly.
Each fault acts where it acts in the product:

* value faults (stuck, noise burst, missed detection, contradiction) change a channel's report
  before it is framed, exactly as `can_bus.player.Player` does;
* frame faults (CRC corruption, counter freeze and jump, wrong length, babbling) are injected
  into real frames (`can_bus.codec.Sender`) that go through the real `can_bus.codec.Receiver`
  from shortly before the fault until after it (healthy frames are latched directly: the
  receiver accepts every one of them), so the reject counters are the codec's own;
* silence: no frame; stale timestamps: the report handed to the core carries a tick from the
  past (older than the timeout) or from the future; deadline overrun: `Inputs.overruns`
  counts consecutive late cycles and the late cycle's demand reaches the brakes one period
  late; a corrupted or mismatched table: `cycle.create` must refuse it (ConfigurationError),
  and the train is then held at the entry under an emergency demand.

Each run counts an *unsafe outcome* (at some cycle a voted obstacle, or a true obstacle at
the true speed, inside the emergency intervention curve EBI of `monitor.core.braking.curves`
with the run's configuration while the monitor demands less than emergency at that cycle and
at the next one), crashes (any exception, in the harness, the codec's receive path or
swallowed by the core's fail-safe), collisions, *false braking* (a brake demand while no true
obstacle is within sensor range that is not the reaction to a fault the monitor diagnosed)
and, the wider measure, *braking without an obstacle* (any such demand, fault reactions and
trains held at the entry included). Every fault kind is shown detected by its named
diagnostic in every single-fault run in which it manifested. Ghost runs (a 0.3 s phantom on
one channel beyond SBI, clear track, 40 m/s) must never bring the train to a standstill.

`run(quick, progress, config=cfg)` and `section(out_dir, quick, progress, config=cfg)` take
the monitor's Config (a braking declaration applied: `monitor.declaration`); the world's
train brakes as that declaration guarantees.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import random
import shlex
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Optional

import numpy as np
from monitor.core import cycle
from monitor.core import table as table_mod
from monitor.core.braking import curves
from monitor.core.config import Config, ConfigurationError
from monitor.core.freshness import channel_status
from monitor.core.types import (
    ABSENT, EMERGENCY, MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS, NORMAL, PRESENT, R_DEADLINE,
    R_INIT, R_LATCH, R_PERCEPTOR, R_SAFE_STOP, R_STALE, R_TRAIN_INPUT, REASON_NAMES, SAFE_STOP, STATIC,
    Inputs, Report, Train,
)

from . import world_train
from .scale import Cluster, map_ordered
from .report import Check, Progress, Section, md_table
from .world_train import WorldTrain

# ----------------------------------------------------------------------------- the catalogue

CHANNEL_KINDS = ("silence", "stuck", "noise_burst", "missed_detection", "bad_crc", "counter_freeze",
                 "counter_jump", "wrong_length", "babble", "contradiction", "stale_timestamp")
VALUE_KINDS = ("stuck", "noise_burst", "missed_detection", "contradiction")
FRAME_KINDS = ("bad_crc", "counter_freeze", "counter_jump", "wrong_length", "babble")
TABLE_KINDS = ("table_corrupted", "table_mismatch")
KINDS = CHANNEL_KINDS + ("deadline_overrun",) + TABLE_KINDS
PLAYER_KINDS = CHANNEL_KINDS            # what can_bus.player injects on a bus

REJECT_OF = {"bad_crc": "bad_crc", "counter_freeze": "repeated_counter", "counter_jump": "counter_jump",
             "wrong_length": "wrong_length", "babble": "rate_exceeded"}


@dataclass(frozen=True)
class FaultKind:
    name: str
    label: str
    injection: str      # how the campaign injects it
    diagnostic: str     # what shows that the monitor detected it
    short: str = ""     # the diagnostic in a few words (check names)


CATALOGUE = {f.name: f for f in (
    FaultKind("silence", "channel silence", "the channel sends nothing during the window",
              "reason bit `stale`: the channel ages into DEGRADED after `timeout_cycles`", "stale"),
    FaultKind("stuck", "stuck-at value", "the channel repeats the report it had when the fault began (the player's `stuck`)",
              "`module_flags` bit of the channel's module (2oo2: ABSENT/PRESENT disagreement or distances more than "
              "`distance_tolerance_dm` apart)", "module flag"),
    FaultKind("noise_burst", "noise burst", "distance noise sigma x 50 (0.5 m -> 25 m) on the channel",
              "`module_flags` bit of the channel's module (distances more than `distance_tolerance_dm` apart)", "module flag"),
    FaultKind("missed_detection", "missed detection", "the channel reports ABSENT while the obstacle is in range",
              "`module_flags` bit of the channel's module (ABSENT/PRESENT disagreement)", "module flag"),
    FaultKind("bad_crc", "CRC corruption", "one byte (or 2-4 bytes) of each real frame XORed after the CRC was applied",
              "codec reject `bad_crc`, then reason bit `stale`", "bad_crc reject, stale"),
    FaultKind("counter_freeze", "counter freeze", "the alive counter repeats (the player's `counter_freeze`)",
              "codec reject `repeated_counter`, then reason bit `stale`", "repeated_counter reject, stale"),
    FaultKind("counter_jump", "counter jump", "the alive counter skips 1..14 values on every frame",
              "codec reject `counter_jump`, then reason bit `stale`", "counter_jump reject, stale"),
    FaultKind("wrong_length", "wrong frame length", "frames cut to 0..7 bytes",
              "codec reject `wrong_length`, then reason bit `stale`", "wrong_length reject, stale"),
    FaultKind("babble", "babbling at high rate", "4, 8 or 20 valid frames per period from the channel",
              "codec reject `rate_exceeded` (quarantine, report withdrawn), then reason bit `stale`", "rate_exceeded reject, stale"),
    FaultKind("contradiction", "contradiction within a module",
              "the channel's status flipped: PRESENT -> ABSENT, ABSENT -> a phantom obstacle at 30..900 m",
              "`module_flags` bit of the channel's module at once (with every channel fresh a dispute: reason bits "
              "`dispute` and `warning`); and reason bit `perceptor` (mode SAFE_STOP) once the disagreement has "
              "persisted `persistence_cycles` cycles in a row", "module flag, perceptor if it persists"),
    FaultKind("stale_timestamp", "stale timestamps",
              "the report handed to the core carries a tick older than the timeout, or one from the future",
              "reason bit `stale` (a report from the past or the future counts as DEGRADED)", "stale"),
    FaultKind("deadline_overrun", "deadline overrun",
              "the shell reports consecutive overruns (`Inputs.overruns`); a late cycle's demand reaches the brakes one period late",
              "reason bit `deadline` (mode SAFE_STOP after `max_overruns` in a row)", "deadline, SAFE_STOP"),
    FaultKind("table_corrupted", "corrupted table file", "a flipped byte, a flipped digest byte, a truncated file or bad magic",
              "`ConfigurationError` from `cycle.create`: the monitor refuses to start, the train is held under emergency", "ConfigurationError"),
    FaultKind("table_mismatch", "mismatched table file",
              "the other model's table (expect_model), a period that is not the table's time step, a re-hashed table "
              "claiming the other model, or one with its observations reordered",
              "`ConfigurationError` from `cycle.create`: the monitor refuses to start, the train is held under emergency", "ConfigurationError"),
)}
assert tuple(CATALOGUE) == KINDS

# ----------------------------------------------------------------------------- the world

PERIOD_MS = 100
RANGE_M = 1000.0
NOISE_SIGMA_M = 0.5
BURST_FACTOR = 50.0
FAULT_REACTION = R_STALE | R_SAFE_STOP | R_DEADLINE | R_TRAIN_INPUT | R_INIT   # reasons of a diagnosed fault
FALSE_BRAKING_LIMIT = 0.05     # issue 11: at most 5 % of the runs brake falsely
# The quick campaign's core-level and ghost runs (324 + 24) with the monitor before the braking
# curves (commit 75a5c9f: nominal alpha2, a 2oo2 disagreement answered by safe_reaction, every
# emergency latched to standstill), in that commit's own world (a train braking at the nominal
# 1 and 3 m/s^2), measured by running this module's measures over that commit's core.
BEFORE_QUICK = {"commit": "75a5c9f", "runs": 348, "false_braking": 32, "brake_without_obstacle": 146,
                "ghosts": 24, "ghosts_stopped": 24, "unsafe": 0}
OBSTACLE_TYPES = ("static", "dynamic", "train")
ROUTE_BEFORE_S, ROUTE_AFTER_S = 0.3, 0.8     # frame faults: real codec path around the window
SEEDS = 11          # full mode: 117 combinations x 8 scenarios x 11 seeds = 10,296 core-level runs
SETTLE_S = 2.0      # a run ends once the train has stood still this long and every fault ended this long ago


@dataclass(frozen=True)
class Obstacle:
    position_m: float       # ahead of the train's entry point
    appear_s: float = 0.0   # time after the train's entry
    speed_mps: float = 0.0  # along the track, same direction as the train
    type: str = "static"


@dataclass(frozen=True)
class WorldScenario:
    name: str
    description: str
    speed_mps: float
    duration_s: float
    obstacles: tuple = ()
    fault_start_s: tuple = (0.5, 10.0)    # fault windows start in this range (after the entry)


SCENARIOS = (
    WorldScenario("no-obstacle", "clear track, 30 m/s", 30.0, 25.0, (), (0.5, 18.0)),
    WorldScenario("static-150m-10", "static obstacle 150 m ahead, 10 m/s", 10.0, 60.0, (Obstacle(150.0),), (0.5, 12.0)),
    WorldScenario("static-300m-20", "static obstacle 300 m ahead, 20 m/s", 20.0, 60.0, (Obstacle(300.0),), (0.5, 10.0)),
    WorldScenario("static-700m-30", "static obstacle 700 m ahead, 30 m/s", 30.0, 60.0, (Obstacle(700.0),), (0.5, 12.0)),
    WorldScenario("static-1200m-40", "static obstacle 1200 m ahead, 40 m/s", 40.0, 60.0, (Obstacle(1200.0),), (0.5, 16.0)),
    WorldScenario("train-ahead", "a train 600 m ahead at 8 m/s, ours at 30 m/s", 30.0, 60.0,
                  (Obstacle(600.0, 0.0, 8.0, "train"),), (0.5, 12.0)),
    WorldScenario("vehicle-ahead", "a vehicle 400 m ahead at 3 m/s, ours at 20 m/s", 20.0, 60.0,
                  (Obstacle(400.0, 0.0, 3.0, "dynamic"),), (0.5, 14.0)),
    WorldScenario("sudden-120m", "an object appears 120 m ahead (inside EBI) at 5 s, 30 m/s", 30.0, 20.0,
                  (Obstacle(270.0, 5.0, 0.0, "static"),), (0.5, 6.0)),
    WorldScenario("crossing-500m-30", "a vehicle stops on the track 500 m ahead at 5 s (a level crossing), 30 m/s",
                  30.0, 40.0, (Obstacle(650.0, 5.0, 0.0, "dynamic"),), (0.5, 8.0)),
)
GHOST_SCENARIO = WorldScenario("ghost-clear-40", "clear track, 40 m/s, a 0.3 s ghost on one channel beyond SBI", 40.0, 40.0)
GHOST_S = 0.3
SCENARIO_BY_NAME = {s.name: s for s in SCENARIOS + (GHOST_SCENARIO,)}
UNAVOIDABLE = "sudden-120m"      # the object appears inside the emergency intervention curve: collisions are physics


@dataclass(frozen=True)
class Fault:
    kind: str
    channel: int            # -1 for faults that are not a channel's
    start_s: float
    end_s: float
    variant: tuple = ()     # kind-specific parameters


@dataclass(frozen=True)
class RunSpec:
    kinds: tuple            # () fault-free, (k,) single, (k1, k2) pair
    scenario: str
    seed: int
    model: str

    @property
    def key(self) -> str:
        return f"{'+'.join(self.kinds) or 'none'}/{self.scenario}/{self.seed}/{self.model}"


def combos() -> list[tuple]:
    """(), every single kind, every pair of distinct kinds, and two channels with the same
    channel fault."""
    out = [()] + [(k,) for k in KINDS]
    for i, a in enumerate(KINDS):
        for b in KINDS[i:]:
            if a == b and a not in CHANNEL_KINDS:
                continue
            out.append((a, b))
    return out


def plan(quick: bool) -> list[RunSpec]:
    """Full: every combination x every scenario x SEEDS seeds (m1 and m2 tables alternating).
    Quick: fault-free and singles x scenarios, plus every pair on a rotating scenario."""
    specs = []
    all_combos = combos()
    if quick:
        for c in all_combos:
            if len(c) <= 1:
                for si, s in enumerate(SCENARIOS):
                    specs.append(RunSpec(c, s.name, 0, ("m1", "m2")[si % 2]))
        pairs = [c for c in all_combos if len(c) == 2]
        for i, c in enumerate(pairs):
            for j in range(2):
                s = SCENARIOS[(2 * i + j) % len(SCENARIOS)]
                specs.append(RunSpec(c, s.name, 1, ("m1", "m2")[(i + j) % 2]))
        return specs
    for seed in range(SEEDS):
        for ci, c in enumerate(all_combos):
            for si, s in enumerate(SCENARIOS):
                specs.append(RunSpec(c, s.name, seed, ("m1", "m2")[(seed + si + ci) % 2]))
    return specs


def instantiate(spec: RunSpec, rng: random.Random) -> list[Fault]:
    """Channels, windows and variants of the faults of one run, drawn from its seed."""
    scen = SCENARIO_BY_NAME[spec.scenario]
    chans = [k for k in spec.kinds if k in CHANNEL_KINDS]
    channels: list[int] = []
    if len(chans) == 1:
        channels = [rng.randrange(6)]
    elif len(chans) == 2:
        m = rng.randrange(3)
        a = 2 * m + rng.randrange(2)
        if rng.random() < 0.5:
            b = a ^ 1                                   # both channels of one module
        else:
            b = 2 * ((m + rng.randrange(1, 3)) % 3) + rng.randrange(2)
        channels = [a, b]
    faults = []
    ci = 0
    for kind in spec.kinds:
        lo, hi = scen.fault_start_s
        start = round(rng.uniform(lo, hi), 1)
        end = round(start + rng.uniform(1.0, 6.0), 1)
        ch = -1
        if kind in CHANNEL_KINDS:
            ch = channels[ci]
            ci += 1
        if kind == "bad_crc":
            variant = ("multi" if rng.random() < 0.5 else "byte",)
        elif kind == "counter_jump":
            variant = (rng.randint(1, 14),)
        elif kind == "wrong_length":
            variant = (rng.randint(0, 7),)
        elif kind == "babble":
            variant = (rng.choice((4, 8, 20)),)
        elif kind == "contradiction":
            variant = (rng.randint(300, 9000),)                 # phantom distance, dm
        elif kind == "stale_timestamp":
            variant = ("past", rng.randint(1, 5000)) if rng.random() < 0.5 else ("future", rng.randint(1, 2000))
        elif kind == "table_corrupted":
            variant = (rng.choice(("flip", "digest", "truncate", "magic")), rng.random())
        elif kind == "table_mismatch":
            variant = (rng.choice(("expect_model", "period", "relabel", "reorder")),)
        else:
            variant = ()
        faults.append(Fault(kind, ch, start, end, variant))
    return faults


# ----------------------------------------------------------------------------- tables

@lru_cache(maxsize=None)
def shipped_table(model: str) -> bytes:
    from monitor.tables import read

    return read(model)


def faulty_table(fault: Fault, model: str, cfg: Config) -> tuple[bytes, Optional[str], Config]:
    """(table bytes, expect_model, config) for a table fault; cycle.create must refuse them."""
    good = shipped_table(model)
    other = "m2" if model == "m1" else "m1"
    how = fault.variant[0]
    if fault.kind == "table_corrupted":
        pos = int(fault.variant[1] * (len(good) - 1))
        if how == "flip":                                # a byte of the content: SHA-256 mismatch
            pos = min(pos, len(good) - 33)
            data = bytearray(good)
            data[pos] ^= 0x01 << (pos % 8)
            return bytes(data), None, cfg
        if how == "digest":
            data = bytearray(good)
            data[len(good) - 1 - pos % 32] ^= 0x80
            return bytes(data), None, cfg
        if how == "truncate":
            return good[: max(0, pos)], None, cfg
        data = bytearray(good)
        data[0:8] = b"RGTABLX\n"
        return bytes(data), None, cfg
    if how == "expect_model":
        return shipped_table(other), model, cfg
    if how == "period":
        return good, None, cfg._replace(period_ms=2 * cfg.period_ms)
    t = table_mod.decode(good)
    header = dict(t.header)
    if how == "relabel":                                 # valid hash, claims the other model
        header["model"] = other
    else:                                                # valid hash, observations reordered
        header["observations"] = list(reversed(header["observations"]))
    return table_mod.encode(header, t.action, t.next), None, cfg


# ----------------------------------------------------------------------------- one core-level run

@lru_cache(maxsize=8)
def _shipped_setup(model: str, cfg: Config) -> cycle.Setup:
    """cycle.create of a shipped table (pure, so one per process is enough)."""
    return cycle.create(cfg, shipped_table(model))


def reaction_to_fault(reasons: int, held_by_fault: bool) -> bool:
    """A demand that answers a fault the monitor diagnosed (stale, safe stop, deadline, train
    input, init), or an emergency the latch still holds after such an answer."""
    return bool(reasons & FAULT_REACTION) or bool(reasons & R_LATCH and held_by_fault)


def false_braking_cycles(demands: list, reasons: list, obstacle_in_range: list, moving: list) -> tuple[bool, bool]:
    """(braking without an obstacle, false braking) of a run: a brake demand while the train
    is on its way and no true obstacle is in sensor range; false unless it is the reaction to
    a diagnosed fault (the latch's hold after such a reaction included)."""
    without = false = False
    held_by_fault = False
    for demand, r, near, on in zip(demands, reasons, obstacle_in_range, moving):
        reaction = reaction_to_fault(r, held_by_fault)
        if demand == EMERGENCY and not r & R_LATCH:
            held_by_fault = reaction
        elif demand != EMERGENCY:
            held_by_fault = False
        if on and demand > 0 and not near:
            without = True
            false = false or not reaction
    return without, false


def _core_step():
    step = getattr(cycle, "_step", None)
    if step is None:
        raise RuntimeError("monitor.core.cycle._step is gone: the campaign cannot tell swallowed exceptions apart")
    return step


def simulate(spec: RunSpec, *, config: Optional[Config] = None, table_bytes: Optional[bytes] = None,
             keep_trace: bool = False, faults: Optional[list] = None, world: Optional[WorldTrain] = None,
             margin_m: float = 0.0) -> dict:
    """One core-level run (faults drawn from the spec's seed unless given) in a world whose
    train is `world` (None: drawn from the run's key inside the declaration of `config`,
    world_train.for_run). Never raises: an exception anywhere is the run's `crash`."""
    try:
        return _simulate(spec, config or Config(), table_bytes, keep_trace, faults, world, margin_m)
    except Exception as exc:  # noqa: BLE001 - a crash is a result of the campaign, not its end
        return {"key": spec.key, "kinds": spec.kinds, "scenario": spec.scenario, "seed": spec.seed,
                "model": spec.model, "crash": f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=6)}",
                "unsafe": 0, "collision": False, "false_braking": False, "brake_without_obstacle": False,
                "faults": [], "cycles": 0}


def _simulate(spec: RunSpec, cfg: Config, table_bytes: Optional[bytes], keep_trace: bool,
              faults: Optional[list], world: Optional[WorldTrain], margin_m: float) -> dict:
    from can_bus.codec import OBSTACLE_IDS, Receiver, Sender, report_signals

    rng = random.Random(f"railguard-campaign/{spec.key}")
    scen = SCENARIO_BY_NAME[spec.scenario]
    faults = instantiate(spec, rng) if faults is None else list(faults)
    period = cfg.period_ms

    # ---- monitor start-up (a table fault must be refused)
    data, expect, run_cfg = (table_bytes if table_bytes is not None else shipped_table(spec.model)), None, cfg
    for f in faults:
        if f.kind in TABLE_KINDS:
            data, expect, run_cfg = faulty_table(f, spec.model, cfg)
    config_error = None
    setup = None
    try:
        if table_bytes is None and not any(f.kind in TABLE_KINDS for f in faults):
            setup = _shipped_setup(spec.model, cfg)
        else:
            setup = cycle.create(run_cfg, data, expect)
    except ConfigurationError as exc:
        config_error = str(exc)
    step = _core_step()
    state = cycle.initial_state(setup) if setup is not None else None

    # ---- channels and their faults
    by_channel = defaultdict(list)
    overrun_faults = [f for f in faults if f.kind == "deadline_overrun"]
    for f in faults:
        if f.channel >= 0:
            by_channel[f.channel].append(f)
    frame_faults = {ch: [f for f in fs if f.kind in FRAME_KINDS] for ch, fs in by_channel.items()}
    n_cycles = int(round(scen.duration_s * 1000 / period)) + 40     # room for the wait at the entry
    seed = int.from_bytes(hashlib.sha256(f"railguard-campaign/{spec.key}/noise".encode()).digest()[:8], "little")
    noise = np.random.default_rng(seed).standard_normal((n_cycles, 6)).tolist()
    receiver = Receiver(channels=6, rate_window_ms=period)
    sender = Sender()
    latched: list = [None] * 6
    frozen: dict = {}
    manifest: dict = {}            # fault index -> first cycle at which it manifested
    fault_index = {id(f): i for i, f in enumerate(faults)}
    tol2 = 2 * cfg.distance_tolerance_dm
    undetected_corrupt = 0

    # ---- the world: its own train (not the monitor's declaration), its timing, the obstacles
    world = world or world_train.for_run(cfg, spec.key)
    twin = world_train.TrainTwin(world, scen.speed_mps, record=True)
    phase_ms = int.from_bytes(hashlib.sha256(f"railguard-campaign/{spec.key}/phase".encode()).digest()[:2], "little") % period
    seen_ago_s = phase_ms / 1000.0 + world.sensor_latency_s     # a report handed now was sensed this long ago
    t = 0.0
    speed = scen.speed_mps
    started = False
    collision = False
    collided_with = None
    impact_speed = None
    stop_margin = None
    min_speed = speed
    applied_before = 0
    obstacles = [(o.position_m, o.appear_s, o.speed_mps, OBSTACLE_TYPES.index(o.type)) for o in scen.obstacles]
    in_sight: set = set()           # obstacles that have come into sensor range
    unavoidable: set = set()        # ... when not even an emergency demand at the next cycle stopped the world's train
    closest: dict = {}              # obstacle -> smallest gap, metres

    def nearest(at: float, position: float):
        """(gap, obstacle speed, type, index) of the nearest obstacle there at `at`, or None."""
        best = None
        for j, (pos, appear, v, typ) in enumerate(obstacles):
            if at < appear:
                continue
            d = pos + v * (at - appear) - position
            if best is None or d < best[0]:
                best = (d, v, typ, j)
        return best

    demands, reasons_l, flags_l, modes_l, near_l, moving_l = [], [], [], [], [], []
    streak: dict = {}              # contradiction fault index -> consecutive cycles of an ABSENT/PRESENT split
    persisted: dict = {}           # contradiction fault index -> cycle its streak reached persistence_cycles
    braked = False
    overruns = 0
    prev_demand = EMERGENCY
    core_exceptions = 0
    trace = [] if keep_trace else None
    last = None
    still = 0                                       # cycles at standstill after the entry
    settle = int(SETTLE_S * 1000 / period)
    faults_over = max((f.end_s for f in faults if f.kind not in TABLE_KINDS), default=0.0) + SETTLE_S
    for k in range(n_cycles):
        if last is not None and k > last:
            break
        tick = k * period
        t = twin.time if started else 0.0
        speed = twin.speed if started else 0.0
        near = nearest(t, twin.position)                         # the truth now
        v_in = min(MAX_SPEED_CMS, round(twin.measured_speed() * 100)) if started else 0
        if near is not None and 0 <= near[0] <= RANGE_M and near[3] not in in_sight:
            in_sight.add(near[3])
            if started and not twin.can_stop_for(near[0], near[1], applied_before):
                unavoidable.add(near[3])

        # ---- sensors (what they saw seen_ago_s before this tick, received phase_ms before it), faults, frames, latch
        stamp = max(0, tick - phase_ms)
        seen_at = max(0.0, t - seen_ago_s)
        seen_x, seen_v = twin.at(seen_at) if started else (0.0, 0.0)
        seen = nearest(seen_at, seen_x)
        if seen is None or seen[0] > RANGE_M or seen[0] < 0:
            absent = True
        else:
            absent = False
            d, ov, typ, _ = seen
            closing = max(-MAX_CLOSING_CMS, min(MAX_CLOSING_CMS, round((seen_v - ov) * 100)))
        gk = noise[k]
        if absent:
            absent_report = Report(ABSENT, 0, 0, 0, stamp)
        for ch in range(6):
            g = gk[ch]
            fs = by_channel.get(ch)
            if fs is None:                       # a healthy channel: its frame would be accepted
                if absent:
                    latched[ch] = absent_report
                else:
                    x = d + NOISE_SIGMA_M * g
                    latched[ch] = Report(PRESENT, min(MAX_DISTANCE_DM, round(x * 10)) if x > 0 else 0, closing, typ, stamp)
                continue
            active = [f for f in fs if f.start_s <= t < f.end_s]
            kinds = {f.kind for f in active}
            if absent:
                clean = rep = (ABSENT, 0, 0, 0)
            else:
                clean = rep = (PRESENT, min(MAX_DISTANCE_DM, round(max(0.0, d + NOISE_SIGMA_M * g) * 10)), closing, typ)
                if "noise_burst" in kinds:
                    rep = (PRESENT, min(MAX_DISTANCE_DM, round(max(0.0, d + NOISE_SIGMA_M * BURST_FACTOR * g) * 10)),
                           closing, typ)
                if "missed_detection" in kinds:
                    rep = (ABSENT, 0, rep[2], rep[3])
            if "stuck" in kinds:
                rep = frozen.setdefault(ch, rep)
            else:
                frozen.pop(ch, None)
            for f in active:
                if f.kind == "contradiction":
                    rep = (ABSENT, 0, rep[2], rep[3]) if rep[0] == PRESENT else (PRESENT, rep[1] or f.variant[0], rep[2], rep[3])
                elif f.kind == "ghost":           # a static-looking phantom at a fixed distance
                    rep = (PRESENT, f.variant[0], round(speed * 100) if started else 0, STATIC)
            # manifestation of value faults: the report differs from the fault-free one
            if rep[0] != clean[0] or (rep[0] == PRESENT and abs(rep[1] - clean[1]) > tol2):
                for f in active:
                    if f.kind in VALUE_KINDS:
                        manifest.setdefault(fault_index[id(f)], k)
            if "silence" in kinds:
                for f in active:
                    if f.kind == "silence":
                        manifest.setdefault(fault_index[id(f)], k)
            else:
                ffs = frame_faults.get(ch)
                routed = ffs and any(f.start_s - ROUTE_BEFORE_S <= t < f.end_s + ROUTE_AFTER_S for f in ffs)
                report = Report(rep[0], rep[1], rep[2], rep[3], stamp)
                if not routed:
                    receiver.reports[ch] = report
                else:
                    fid = OBSTACLE_IDS[ch]
                    copies = 1
                    for f in active:
                        if f.kind == "babble":
                            copies = f.variant[0]
                    for _ in range(copies):
                        if "counter_freeze" in kinds and fid in sender.counters:
                            sender.counters[fid] = (sender.counters[fid] - 1) & 0xF
                        for f in active:
                            if f.kind == "counter_jump" and fid in sender.counters:
                                sender.counters[fid] = (sender.counters[fid] + f.variant[0]) & 0xF
                        frame = bytearray(sender.frame(fid, report_signals(report, ch)))
                        for f in active:
                            if f.kind == "bad_crc":
                                if f.variant[0] == "byte":
                                    frame[rng.randrange(8)] ^= rng.randint(1, 255)
                                else:
                                    for pos in rng.sample(range(8), rng.randint(2, 4)):
                                        frame[pos] ^= rng.randint(1, 255)
                            elif f.kind == "wrong_length":
                                frame = frame[: f.variant[0]]
                        before = receiver.rejected_total
                        name = receiver.accept(fid, bytes(frame), stamp)
                        if "bad_crc" in kinds and name is not None:
                            undetected_corrupt += 1
                        if receiver.rejected_total > before:
                            for f in active:
                                if f.kind in FRAME_KINDS:
                                    manifest.setdefault(fault_index[id(f)], k)
                latched[ch] = receiver.reports[ch]
                continue
            latched[ch] = receiver.reports[ch]
        # stale timestamps act on what the shell hands the core
        handed = list(latched)
        for ch, fs in by_channel.items():
            for f in fs:
                if f.kind == "stale_timestamp" and f.start_s <= t < f.end_s and handed[ch] is not None:
                    timeout = cfg.timeout_cycles * period
                    shift = -(timeout + f.variant[1]) if f.variant[0] == "past" else f.variant[1]
                    handed[ch] = handed[ch]._replace(tick=tick + shift)
                    manifest.setdefault(fault_index[id(f)], k)

        # a contradiction persists while its channel and the partner, as handed, split ABSENT/PRESENT
        for fi, f in enumerate(faults):
            if f.kind == "contradiction" and f.start_s <= t < f.end_s:
                pair = {channel_status(handed[c], tick, cfg.timeout_cycles * period) for c in (f.channel, f.channel ^ 1)}
                streak[fi] = streak.get(fi, 0) + 1 if pair == {ABSENT, PRESENT} else 0
                if streak[fi] >= cfg.persistence_cycles:
                    persisted.setdefault(fi, k)

        overrun_now = any(f.start_s <= t < f.end_s for f in overrun_faults)
        if overrun_now:
            manifest.setdefault(fault_index[id(overrun_faults[0])], k)

        # ---- the monitor (or the shell's emergency when it refused to start)
        if setup is not None:
            inputs = Inputs(tuple(handed), Train(v_in, 0, 0), overruns)
            try:
                state, out = step(setup, state, inputs, tick)
            except Exception:  # noqa: BLE001 - counted; the product's fail-safe answer is used
                core_exceptions += 1
                state, out = cycle.step(setup, state, inputs, tick)
            demand, mode = out.demand, out.mode
            reasons_l.append(out.reasons)
            flags_l.append(out.module_flags)
        else:
            demand, mode = EMERGENCY, None
            reasons_l.append(0)
            flags_l.append(0)
        overruns = overruns + 1 if overrun_now else 0
        demands.append(demand)
        modes_l.append(mode)
        near_l.append(near is not None and 0 <= near[0] <= RANGE_M)
        moving_l.append(started)
        braked = braked or (started and demand > 0)
        if trace is not None:
            trace.append((tick, t, speed, None if near is None else near[0], demand, mode, reasons_l[-1]))

        # ---- the world moves with the demand (a late cycle's demand arrives one period late; every
        # demand reaches the brakes output_latency_s after its cycle)
        applied = prev_demand if overrun_now else demand
        prev_demand = demand
        if not started and mode == NORMAL and demand == 0:
            started = True
        if started and twin.time < scen.duration_s - 1e-9:
            for _ in twin.cycle(applied_before, applied, period):
                hit = nearest(twin.time, twin.position)
                if hit is None:
                    continue
                closest[hit[3]] = min(closest.get(hit[3], math.inf), hit[0])
                if hit[0] <= 0:
                    collision, collided_with, impact_speed = True, hit[3], twin.speed
                    break
                if twin.speed == 0.0 and stop_margin is None:
                    stop_margin = hit[0]
            applied_before = applied
            min_speed = min(min_speed, twin.speed)
            speed = twin.speed
            t = twin.time
            if collision:
                break
        if started and speed == 0.0:
            still += 1
        else:
            still = 0
        if last is None and started and (t >= scen.duration_s - 1e-9 or (still >= settle and t >= faults_over)):
            last = k + 1                 # one more cycle, so that the last one evaluated has its successor

    n = len(demands)
    too_close = sorted(j for j, gap in closest.items() if j not in unavoidable and (gap < margin_m or gap <= 0.0))
    unsafe = bool(too_close)
    without, false_braking = false_braking_cycles(demands, reasons_l, near_l, moving_l)
    if setup is None:
        without = True                  # held at the entry by the shell's emergency demand (a diagnosed fault)

    # ---- detection of each fault
    seen_bits = 0
    for r in reasons_l:
        seen_bits |= r
    fault_out = []
    for i, f in enumerate(faults):
        first = manifest.get(i)
        detected, diag_cycle = False, None
        if f.kind in TABLE_KINDS:
            detected = config_error is not None
            first = 0
        elif first is not None and setup is not None:
            diag_cycle = _first_diagnostic(f, first, reasons_l, flags_l, modes_l, receiver, persisted.get(i))
            detected = diag_cycle is not None
        elif setup is None:
            first = None                 # the monitor never ran: nothing to manifest in
        fault_out.append({"kind": f.kind, "channel": f.channel, "start_s": f.start_s, "end_s": f.end_s,
                          "variant": list(f.variant), "manifest_cycle": first,
                          "detected": detected, "latency_cycles": None if diag_cycle is None or first is None
                          else diag_cycle - first})
    res = {
        "key": spec.key, "kinds": spec.kinds, "scenario": spec.scenario, "seed": spec.seed, "model": spec.model,
        "cycles": n, "unsafe": int(unsafe),
        "unsafe_first": None if not unsafe else {"obstacle": too_close[0], "gap_m": round(closest[too_close[0]], 2),
                                                  "impact_speed_mps": None if impact_speed is None else round(impact_speed, 2),
                                                  "margin_m": margin_m, "world": world.describe()},
        "unavoidable": bool(collision and collided_with in unavoidable),
        "crash": None, "core_exceptions": core_exceptions, "undecodable": receiver.rejected.get("undecodable", 0),
        "collision": collision, "impact_speed_mps": None if impact_speed is None else round(impact_speed, 2),
        "false_braking": false_braking, "brake_without_obstacle": without, "braked": braked, "entered": started,
        "min_speed_mps": round(min_speed, 3), "max_demand": max(demands, default=0),
        "world": {"corner": world in world_train.corners(cfg), "emergency_mps2": min(a for _, a in world.emergency_decel),
                  "buildup_s": round(world.equivalent_buildup_s(), 3), "gradient": world.gradient},
        "closest_m": None if not closest else round(min(closest.values()), 2),
        "stop_margin_m": None if stop_margin is None else round(stop_margin, 2),
        "rejects": dict(receiver.rejected), "corrupt_frames_accepted": undetected_corrupt,
        "config_error": config_error, "reasons_seen": [REASON_NAMES[b] for b in range(len(REASON_NAMES)) if seen_bits >> b & 1],
        "safe_stop": SAFE_STOP in modes_l, "faults": fault_out,
    }
    if core_exceptions:
        res["crash"] = f"{core_exceptions} exception(s) inside the core, answered by its fail-safe"
    elif res["undecodable"]:
        res["crash"] = f"{res['undecodable']} exception(s) in the receive path (codec 'undecodable')"
    if trace is not None:
        res["trace"] = trace
    return res


def _first_diagnostic(f: Fault, first: int, reasons_l, flags_l, modes_l, receiver,
                      persisted: Optional[int] = None) -> Optional[int]:
    """The first cycle at or after `first` that shows the fault kind's named diagnostic (for a
    contradiction that persisted `persistence_cycles`, from cycle `persisted`: also perceptor)."""
    n = len(reasons_l)
    if f.kind in ("silence", "stale_timestamp"):
        return next((i for i in range(first, n) if reasons_l[i] & R_STALE), None)
    if f.kind in ("stuck", "noise_burst", "missed_detection"):
        bit = 1 << (f.channel // 2)
        return next((i for i in range(first, n) if flags_l[i] & bit), None)
    if f.kind == "contradiction":
        bit = 1 << (f.channel // 2)
        flag = next((i for i in range(first, n) if flags_l[i] & bit), None)
        if persisted is None or flag is None:
            return flag
        perceptor = next((i for i in range(persisted, n) if reasons_l[i] & R_PERCEPTOR), None)
        return None if perceptor is None else max(flag, perceptor)
    if f.kind in FRAME_KINDS:
        if receiver.rejected.get(REJECT_OF[f.kind], 0) == 0:
            return None
        return next((i for i in range(first, n) if reasons_l[i] & R_STALE), None)
    if f.kind == "deadline_overrun":
        return next((i for i in range(first, n) if reasons_l[i] & R_DEADLINE and modes_l[i] == SAFE_STOP), None)
    return None


def _work(job: tuple) -> list:
    specs, cfg, world, margin_m = job
    out = []
    for spec in specs:
        r = simulate(spec, config=cfg, world=world, margin_m=margin_m)
        r.pop("trace", None)
        out.append(r)
    return out


CHUNK = 40           # core-level runs per dask task


def run_core(specs: list[RunSpec], progress: Progress, cluster: Cluster = Cluster(), config: Optional[Config] = None,
             world: Optional[WorldTrain] = None, margin_m: float = 0.0) -> list[dict]:
    """Every spec through `simulate` with `config` (default Config()) and `world` (None: each
    run's own train inside the declaration), on `cluster` (order kept). Each run draws its
    faults, noise and world train from its own key, so the results do not depend on the
    number of workers."""
    cfg = config or Config()
    chunks = [(specs[i:i + CHUNK], cfg, world, margin_m) for i in range(0, len(specs), CHUNK)]
    done = map_ordered(_work, chunks, cluster, progress=progress, label="campaign: core runs",
                       weight=lambda job: len(job[0]))
    return [r for chunk in done for r in chunk]


def ghost_plan(quick: bool, cfg: Config) -> list[tuple]:
    """(spec, faults) of the ghost runs: on a clear track at 40 m/s, one channel reports a
    static obstacle for GHOST_S at a fixed distance beyond SBI (just beyond, half-way to the
    warning curve, just beyond the warning curve, far), every channel in turn, with the m1
    and m2 tables alternating (full mode: both tables)."""
    scen = GHOST_SCENARIO
    v = round(scen.speed_mps * 100)
    c = curves(cfg, v, 0, 0, v, cfg.period_ms)          # a report up to one period old (the world's phase)
    far = int(RANGE_M * 10) - 100
    distances = sorted({min(x, far) for x in (c.sbi_dm + 1, (c.sbi_dm + c.warning_dm) // 2, c.warning_dm + 1, far)})
    out = []
    for ch in range(6):
        for i, d in enumerate(distances):
            start = round(2.0 + 0.7 * i + 0.3 * ch, 1)
            for model in (("m1", "m2")[(i + ch) % 2],) if quick else ("m1", "m2"):
                spec = RunSpec(("ghost",), scen.name, 100 * ch + i, model)
                out.append((spec, [Fault("ghost", ch, start, round(start + GHOST_S, 1), (d,))]))
    return out


def run_ghosts(quick: bool, cfg: Optional[Config] = None, world: Optional[WorldTrain] = None,
               margin_m: float = 0.0) -> list[dict]:
    """The ghost runs through `simulate` (each result also carries the ghost's distance)."""
    cfg = cfg or Config()
    out = []
    for spec, faults in ghost_plan(quick, cfg):
        r = simulate(spec, config=cfg, faults=faults, world=world, margin_m=margin_m)
        r.pop("trace", None)
        out.append(dict(r, ghost_dm=faults[0].variant[0]))
    return out


def ghost_summary(runs: list[dict]) -> dict:
    """The ghosts' verdict: the train never stands still, nothing unsafe, and the monitor shows
    the disagreement (reason bit `dispute`)."""
    stopped = [r["key"] for r in runs if r["crash"] or not r.get("min_speed_mps")]
    return {"runs": len(runs), "stopped": stopped, "unsafe": sum(bool(r["unsafe"]) for r in runs),
            "false_braking": sum(bool(r["false_braking"]) for r in runs),
            "undiagnosed": [r["key"] for r in runs if "dispute" not in r.get("reasons_seen", ())],
            "min_speed_mps": min((r.get("min_speed_mps") or 0.0 for r in runs), default=0.0),
            "max_demand": max((r.get("max_demand") or 0 for r in runs), default=0),
            "distances_dm": sorted({r["ghost_dm"] for r in runs})}


# ----------------------------------------------------------------------------- the bus samples

@dataclass(frozen=True)
class BusSpec:
    """One run through the real MonitorRunner, codec and Player on a bus."""

    name: str
    scenario: str
    faults: tuple           # Fault instances (player kinds, deadline_overrun or a table fault)
    model: str = "m1"
    seed: int = 1
    detection: bool = False  # a run whose faults are placed so that each must be detected
    duration_s: Optional[float] = None

    @property
    def kinds(self) -> tuple:
        return tuple(f.kind for f in self.faults)


def bus_scenario(spec: BusSpec, cfg: Optional[Config] = None, world: Optional[WorldTrain] = None):
    """The world scenario as a can_bus Scenario for the Player (same obstacles, noise, faults);
    its train brakes at the world train's decelerations (default: the declaration's worst
    corner; the emergency brake at its weakest band), its force ramping up in twice the
    equivalent build-up time (dead time + half the ramp)."""
    cfg = cfg or Config()
    world = world or world_train.corners(cfg)[0]
    from can_bus.scenario import FaultSpec, ObstacleSpec, Scenario, SensorSpec, TrainSpec, check

    w = SCENARIO_BY_NAME[spec.scenario]
    faults = []
    for f in spec.faults:
        if f.kind in PLAYER_KINDS:
            rate = f.variant[0] if f.kind == "babble" and f.variant else 20
            faults.append(FaultSpec(f.kind, f.channel, float(f.start_s), float(f.end_s), rate))
    scen = Scenario(
        name=spec.name, description=w.description, duration_s=spec.duration_s or w.duration_s,
        train=TrainSpec(w.speed_mps, world.service_decel, min(a for _, a in world.emergency_decel),
                        2 * world.equivalent_buildup_s()),
        obstacles=tuple(ObstacleSpec(o.position_m, o.appear_s, o.speed_mps, o.type) for o in w.obstacles),
        sensors=SensorSpec(RANGE_M, NOISE_SIGMA_M, 0.0, spec.seed), faults=tuple(faults))
    check(scen)
    return scen


def bus_plan(quick: bool) -> list[BusSpec]:
    """Full: every player fault kind and the deadline overrun on a detection run (static
    obstacle in sight, train at speed during the fault) and on three other scenarios, a few
    pairs, and both table faults: 58 runs. Quick: the detection runs and the table faults."""
    kinds = PLAYER_KINDS + ("deadline_overrun",)
    specs = []
    for i, kind in enumerate(kinds):
        variant = (20,) if kind == "babble" else ()
        specs.append(BusSpec(f"bus-{kind}-detect", "static-700m-30", (Fault(kind, i % 6, 1.0, 4.0, variant),),
                             "m1" if i % 2 == 0 else "m2", 10 + i, True, 20.0))
    for t in TABLE_KINDS:
        specs.append(BusSpec(f"bus-{t}", "static-300m-20", (Fault(t, -1, 0.0, 0.0, ("flip", 0.5) if t == "table_corrupted"
                                                                 else ("expect_model",)),), "m1", 1, True, 5.0))
    if quick:
        return specs
    others = ("no-obstacle", "train-ahead", "sudden-120m")
    for j, scen in enumerate(others):
        for i, kind in enumerate(kinds):
            variant = (12,) if kind == "babble" else ()
            start = (2.0, 3.0, 4.0)[j]
            specs.append(BusSpec(f"bus-{kind}-{scen}", scen, (Fault(kind, (i + j) % 6, start, start + 3.0, variant),),
                                 ("m1", "m2")[(i + j) % 2], 30 + 20 * j + i, False, 20.0))
    pairs = (("silence", 0, "silence", 1), ("stuck", 2, "missed_detection", 4), ("bad_crc", 1, "babble", 3),
             ("contradiction", 4, "noise_burst", 5), ("counter_freeze", 0, "stale_timestamp", 1),
             ("wrong_length", 2, "deadline_overrun", -1), ("counter_jump", 3, "counter_jump", 2),
             ("stuck", 0, "stuck", 1))
    for i, (a, ca, b, cb) in enumerate(pairs):
        scen = ("static-300m-20", "vehicle-ahead", "static-1200m-40", "no-obstacle")[i % 4]
        specs.append(BusSpec(f"bus-{a}+{b}-{scen}", scen, (Fault(a, ca, 1.5, 5.0), Fault(b, cb, 3.0, 7.0)),
                             ("m1", "m2")[i % 2], 80 + i, False, 25.0))
    return specs


def _counting_core():
    """Patch monitor.core.cycle.step (which the runner calls) so that exceptions swallowed by
    the core's fail-safe are counted; returns (counter, restore)."""
    original = cycle.step
    inner = _core_step()
    counter = [0]

    def counting(setup, state, inputs, tick):
        try:
            return inner(setup, state, inputs, tick)
        except Exception:  # noqa: BLE001 - counted as a crash; the fail-safe answer is used
            counter[0] += 1
            return original(setup, state, inputs, tick)

    cycle.step = counting

    def restore() -> None:
        cycle.step = original

    return counter, restore


def bus_run(spec: BusSpec, config: Optional[Config] = None, world: Optional[WorldTrain] = None,
            margin_m: float = 0.0) -> dict:
    """One run on python-can's virtual bus (simulated clock): `can_bus.session.run_virtual`
    for the player's faults; the same loop with a clock that makes cycles finish late for the
    deadline overrun; a refused table leaves the Player alone on the bus."""
    import can

    from can_bus import session
    from can_bus.clock import SimClock
    from can_bus.player import Player
    from can_bus.runner import MonitorRunner

    out = {"name": spec.name, "kinds": spec.kinds, "scenario": spec.scenario, "model": spec.model,
           "detection_run": spec.detection, "crash": None, "unsafe": 0, "collision": False, "false_braking": False,
           "brake_without_obstacle": False}
    counter, restore = _counting_core()
    try:
        cfg = config or Config()
        scen = bus_scenario(spec, cfg, world)
        data, expect, run_cfg = shipped_table(spec.model), None, cfg
        for f in spec.faults:
            if f.kind in TABLE_KINDS:
                data, expect, run_cfg = faulty_table(f, spec.model, cfg)
        try:
            setup = cycle.create(run_cfg, data, expect)
        except ConfigurationError as exc:
            out["config_error"] = str(exc)
            bus = can.Bus(interface="virtual", channel=f"campaign-{os.getpid()}-{spec.name}", receive_own_messages=False)
            try:
                player = Player(bus, scen, cfg.period_ms)
                for i in range(int(scen.duration_s * 1000 / cfg.period_ms)):
                    player.step(i * cfg.period_ms)
            finally:
                bus.shutdown()
            out.update(player.outcome(), entered=player.started, collision=player.collision,
                       brake_without_obstacle=True, cycles=len(player.trace), detected={f.kind: True for f in spec.faults})
            return out
        overrun = [f for f in spec.faults if f.kind == "deadline_overrun"]
        with tempfile.TemporaryDirectory(prefix="railguard-campaign-") as tmp:
            if not overrun:
                res = session.run_virtual(setup, scen, Path(tmp), plot=False)
                runner, player = res.runner, res.player
            else:
                clock = SimClock()
                buses = [can.Bus(interface="virtual", channel=f"campaign-{os.getpid()}-{spec.name}",
                                 receive_own_messages=False) for _ in range(2)]
                try:
                    runner = MonitorRunner(buses[0], setup, clock)
                    player = Player(buses[1], scen, cfg.period_ms)
                    late = {"ms": 0}
                    base_now = clock.now_ms
                    clock.now_ms = lambda: base_now() + late["ms"]          # the cycle "ends" late
                    tick = 0
                    for _ in range(int(scen.duration_s * 1000 / cfg.period_ms) + 600):
                        clock.sleep_until_ms(tick)
                        player.step(tick)
                        runner.drain()
                        if any(f.start_s <= player.t < f.end_s for f in overrun):
                            late["ms"] = cfg.period_ms + 20
                        runner.cycle()
                        late["ms"] = 0
                        if player.finished:
                            break
                        tick += cfg.period_ms
                finally:
                    for b in buses:
                        b.shutdown()
        out.update(evaluate_bus(runner.records, [(r.t_s, r.speed_mps, r.distance_m) for r in player.trace], None,
                                spec.scenario, margin_m))
        out.update(player.outcome(), collision=player.collision, entered=player.started)
        out["rejects"] = dict(runner.receiver.rejected)
        out["deadline_misses"] = runner.deadline_misses
        out["faults_injected"] = sorted(f"{k}@ch{c}" for k, c in player.faults_injected)
        out["detected"] = bus_detection(spec.faults, runner.records, runner.receiver.rejected)
        problems = []
        if counter[0]:
            problems.append(f"{counter[0]} exception(s) inside the core")
        if runner.receiver.rejected.get("undecodable"):
            problems.append(f"{runner.receiver.rejected['undecodable']} exception(s) in the receive path")
        out["crash"] = "; ".join(problems) or None
    except Exception as exc:  # noqa: BLE001 - a crash is a result
        out["crash"] = f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=6)}"
    finally:
        restore()
    return out


def evaluate_bus(records, trace, trace_ticks, scenario: str, margin_m: float = 0.0) -> dict:
    """The world's verdict on a run on a bus (unsafe: the player's train reached the obstacle
    or came closer than `margin_m`, outside UNAVOIDABLE), and false braking.

    `records` are the runner's CycleRecords; `trace` the player's (t_s, speed_mps,
    distance_m) rows. On the virtual bus row i is the world the reports of cycle i came from;
    on a real bus (`trace_ticks` given) the row of cycle i is the newest one stepped at or
    before its tick."""
    import bisect

    rows = []
    for i, rec in enumerate(records):
        if trace_ticks is None:
            j = i if i < len(trace) else None
        else:
            j = bisect.bisect_right(trace_ticks, rec.tick) - 1
            j = j if j >= 0 else None
        rows.append(trace[j] if j is not None else None)
    cut = next((i for i, row in enumerate(rows) if row is not None and row[2] is not None and row[2] <= 0), None)
    if cut is not None:                      # a collision: the world ends there, as in the core-level runs
        records, rows = records[:cut + 1], rows[:cut + 1]
    gaps = [row[2] for row in trace if row[2] is not None]
    closest = min(gaps, default=None)
    near, moving = [], []
    entered = False
    for rec, row in zip(records, rows):
        entered = entered or (row is not None and row[1] > 0)
        moving.append(entered)
        near.append(row is not None and row[2] is not None and row[2] <= RANGE_M)
    demands = [r.demand for r in records]
    reasons = [r.reasons for r in records]
    n = len(demands)
    unsafe = scenario != UNAVOIDABLE and closest is not None and (closest <= 0.0 or closest < margin_m)
    without, false = false_braking_cycles(demands, reasons, near, moving)
    held = not entered and not any(r & FAULT_REACTION for r in reasons)     # never let go, no diagnosed fault
    return {"cycles": n, "unsafe": int(unsafe), "closest_m": None if closest is None else round(closest, 2),
            "unsafe_first": None if not unsafe else {"gap_m": round(closest, 2), "margin_m": margin_m},
            "brake_without_obstacle": without or not entered, "false_braking": false or held}


def bus_detection(faults, records, rejected) -> dict:
    """Per fault kind of a bus run: was its diagnostic seen? (The player's `stale_timestamp`
    replays a report from 10 periods earlier with a fresh frame, so on the bus it shows as a
    2oo2 disagreement, not as a stale channel.)"""
    seen = 0
    flags = 0
    modes = set()
    for r in records:
        seen |= r.reasons
        flags |= r.module_flags
        modes.add(r.mode)
    out = {}
    for f in faults:
        k = f.kind
        if k == "silence":
            ok = bool(seen & R_STALE)
        elif k in ("stuck", "noise_burst", "missed_detection", "stale_timestamp"):
            ok = bool(flags & (1 << (f.channel // 2)))
        elif k == "contradiction":            # the player's windows outlast persistence_cycles
            ok = bool(flags & (1 << (f.channel // 2))) and bool(seen & R_PERCEPTOR)
        elif k in FRAME_KINDS:
            ok = rejected.get(REJECT_OF[k], 0) > 0 and bool(seen & R_STALE)
        elif k == "deadline_overrun":
            ok = bool(seen & R_DEADLINE) and SAFE_STOP in modes
        else:
            ok = False
        out[k] = out.get(k, True) and ok
    return out


def _bus_work(job: tuple) -> list:
    specs, cfg, world, margin_m = job
    return [bus_run(s, cfg, world, margin_m) for s in specs]


# ----------------------------------------------------------------------------- vcan0 in the sandbox

VCAN_SCENARIO = "static-300m-20"


def vcan_plan(quick: bool) -> list[BusSpec]:
    kinds = (("silence", 2), ("bad_crc", 0), ("babble", 3), ("counter_jump", 4), ("contradiction", 1))
    specs = [BusSpec(f"vcan-{k}", VCAN_SCENARIO, (Fault(k, ch, 1.5, 3.5, (20,) if k == "babble" else ()),),
                     ("m1", "m2")[i % 2], 40 + i, True, 9.0) for i, (k, ch) in enumerate(kinds)]
    return specs[:1] if quick else specs


def vcan_guest(spec_path: str, out_dir: str) -> int:
    """Runs inside the sandbox: each session is the monitor (MonitorRunner, wall clock) and
    the Player (in a thread, as `railguard run` does) on the real SocketCAN vcan0; writes one
    JSON file per session."""
    import threading

    import can

    from can_bus.clock import WallClock
    from can_bus.player import Player
    from can_bus.runner import MonitorRunner

    from can_bus.codec import Receiver, Sender, database

    specs = json.loads(Path(spec_path).read_text())
    cfg = Config(**specs[0]["config"]) if specs else Config()
    out = Path(out_dir)
    # warm up (parse the DBC, encode and check every message once, build the setups) so that
    # the first session does not start with a cold process, as a deployed monitor would not
    rx, tx = Receiver(rate_window_ms=0), Sender()
    for msg in database().messages:
        rx.accept(msg.frame_id, tx.frame(msg.frame_id, {}), 0)
    for raw in specs:
        cycle.create(cfg, shipped_table(raw["model"]))
    bus_kwargs = {"interface": "socketcan", "channel": "vcan0"}
    for i, raw in enumerate(specs):
        spec = BusSpec(raw["name"], raw["scenario"], tuple(Fault(*f[:4], tuple(f[4])) for f in raw["faults"]),
                       raw["model"], raw["seed"], raw["detection"], raw["duration_s"])
        result = {"name": spec.name}
        counter, restore = _counting_core()
        try:
            scen = bus_scenario(spec, cfg)
            setup = cycle.create(cfg, shipped_table(spec.model))
            clock = WallClock()
            mon_bus, player_bus = can.Bus(**bus_kwargs), can.Bus(**bus_kwargs)
            stop = threading.Event()
            player = Player(player_bus, scen, setup.config.period_ms)
            steps: list = []

            def play() -> None:
                tick = clock.now_ms()
                while not stop.is_set() and not player.finished:
                    clock.sleep_until_ms(tick)
                    player.step(tick)
                    steps.append(tick)
                    tick += player.period_ms

            try:
                runner = MonitorRunner(mon_bus, setup, clock)
                thread = threading.Thread(target=play, daemon=True)
                thread.start()
                limit = int((scen.duration_s + 10) * 1000 / setup.config.period_ms)
                for _ in range(limit):
                    runner.drain(runner.next_tick)
                    clock.sleep_until_ms(runner.next_tick)
                    runner.cycle()
                    if player.finished:
                        break
                stop.set()
                runner.send_final_emergency()
                thread.join(timeout=2)
            finally:
                mon_bus.shutdown()
                player_bus.shutdown()
            n = min(len(steps), len(player.trace))
            result.update(
                records=[[r.tick, r.demand, r.reasons, r.mode, r.node, r.distance_dm, r.module_flags, r.system_error,
                          r.speed_cms, r.warning] for r in runner.records],
                trace=[[row.t_s, row.speed_mps, row.distance_m] for row in player.trace[:n]], trace_ticks=steps[:n],
                outcome=player.outcome(), collision=player.collision, entered=player.started,
                rejects=dict(runner.receiver.rejected), deadline_misses=runner.deadline_misses,
                frames_received=runner.frames_received, core_exceptions=counter[0],
                faults_injected=sorted(f"{k}@ch{c}" for k, c in player.faults_injected))
        except Exception as exc:  # noqa: BLE001 - reported to the host as the session's crash
            result["error"] = f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=6)}"
        finally:
            restore()
        (out / f"session-{i}.json").write_text(json.dumps(result))
    return 0


def vcan_sample(specs: list[BusSpec], progress: Progress, config: Optional[Config] = None, margin_m: float = 0.0) -> dict:
    """Boot the sandbox once and run every session in it (the world's train: the
    declaration's worst corner); evaluate them on the host."""
    cfg = config or Config()
    from can_bus import vcan
    from can_bus.runner import CycleRecord

    root = Path(__file__).resolve().parents[1]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="railguard-campaign-vcan-") as tmp:
        spec_path = Path(tmp) / "sessions.json"
        spec_path.write_text(json.dumps([{"name": s.name, "scenario": s.scenario, "model": s.model, "seed": s.seed,
                                          "detection": s.detection, "duration_s": s.duration_s, "config": cfg._asdict(),
                                          "faults": [[f.kind, f.channel, f.start_s, f.end_s, list(f.variant)]
                                                     for f in s.faults]} for s in specs]))
        script = Path(tmp) / "sessions.sh"
        script.write_text("set -u\n" + f"{shlex.quote(sys.executable)} -m verification.campaign --vcan-guest "
                          f"{shlex.quote(str(spec_path))} {shlex.quote(tmp)}\n")
        budget = 40.0 + sum((s.duration_s or 20.0) + 6.0 for s in specs)
        progress(f"campaign: {len(specs)} session(s) on vcan0 in the user-mode-Linux sandbox (up to {budget:.0f} s)")
        res = vcan.run(["sh", str(script)], timeout=budget, cwd=root, env={"PYTHONPATH": str(root)})
        runs = []
        for i, spec in enumerate(specs):
            p = Path(tmp) / f"session-{i}.json"
            if not p.exists():
                runs.append({"name": spec.name, "kinds": spec.kinds, "crash": "session did not finish "
                             f"(timed out: {res.timed_out}; stderr: {res.stderr.strip()[-300:]})", "unsafe": 0,
                             "collision": False, "false_braking": False, "detected": {}})
                continue
            raw = json.loads(p.read_text())
            run = {"name": spec.name, "kinds": spec.kinds, "scenario": spec.scenario, "model": spec.model,
                   "crash": raw.get("error"), "unsafe": 0, "collision": False, "false_braking": False, "detected": {}}
            if "records" in raw:
                records = [CycleRecord(*r) for r in raw["records"]]
                run.update(evaluate_bus(records, [tuple(x) for x in raw["trace"]], raw["trace_ticks"], spec.scenario,
                                        margin_m))
                run.update(raw["outcome"], collision=raw["collision"], entered=raw["entered"], rejects=raw["rejects"],
                           deadline_misses=raw["deadline_misses"], frames_received=raw["frames_received"],
                           faults_injected=raw["faults_injected"])
                run["detected"] = bus_detection(spec.faults, records, raw["rejects"])
                problems = [run["crash"]] if run["crash"] else []
                if raw["core_exceptions"]:
                    problems.append(f"{raw['core_exceptions']} exception(s) inside the core")
                if raw["rejects"].get("undecodable"):
                    problems.append(f"{raw['rejects']['undecodable']} exception(s) in the receive path")
                run["crash"] = "; ".join(problems) or None
            runs.append(run)
    return {"runs": runs, "seconds": time.perf_counter() - t0, "timed_out": res.timed_out,
            "returncode": res.returncode}


# ----------------------------------------------------------------------------- the campaign

def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _row_label(kinds: tuple) -> str:
    return "none" if not kinds else "+".join(kinds)


def aggregate(results: list[dict]) -> dict:
    """Counts over core-level runs: totals, per fault kind (single and in pairs), per
    scenario, per (fault kind, scenario), detection per kind."""
    def blank():
        return {"runs": 0, "unsafe": 0, "unsafe_runs": 0, "unavoidable": 0, "crashes": 0, "collisions": 0, "false_braking": 0,
                "brake_without_obstacle": 0}

    def add(cell, r):
        cell["runs"] += 1
        cell["unsafe"] += bool(r["unsafe"])
        cell["unsafe_runs"] += bool(r["unsafe"])
        cell["unavoidable"] += bool(r.get("unavoidable"))
        cell["crashes"] += r["crash"] is not None
        cell["collisions"] += bool(r["collision"])
        cell["false_braking"] += bool(r["false_braking"])
        cell["brake_without_obstacle"] += bool(r.get("brake_without_obstacle"))

    total = blank()
    single = defaultdict(blank)        # kind ("none" for fault-free) -> counts
    paired = defaultdict(blank)        # kind -> counts over pairs that contain it
    scen = defaultdict(blank)
    cells = defaultdict(blank)         # (row, scenario): rows "none", kind (single), "pair:kind"
    models = defaultdict(blank)
    detection = {k: {"single_runs": 0, "manifest": 0, "detected": 0, "max_latency": 0, "missed": []} for k in KINDS}
    pair_manifest = pair_detected = 0
    pair_missed = []
    margins = defaultdict(list)
    corrupt_accepted = 0
    for r in results:
        add(total, r)
        add(scen[r["scenario"]], r)
        add(models[r["model"]], r)
        corrupt_accepted += r.get("corrupt_frames_accepted", 0)
        if r.get("stop_margin_m") is not None and not r["kinds"]:
            margins[r["model"]].append(r["stop_margin_m"])
        if len(r["kinds"]) <= 1:
            label = r["kinds"][0] if r["kinds"] else "none"
            add(single[label], r)
            add(cells[(label, r["scenario"])], r)
        else:
            for k in set(r["kinds"]):
                add(paired[k], r)
                add(cells[("pair:" + k, r["scenario"])], r)
        if len(r["kinds"]) == 1 and r["faults"] and r["faults"][0]["kind"] in detection:
            f = r["faults"][0]
            d = detection[f["kind"]]
            d["single_runs"] += 1
            if f["manifest_cycle"] is not None:
                d["manifest"] += 1
                if f["detected"]:
                    d["detected"] += 1
                    d["max_latency"] = max(d["max_latency"], f["latency_cycles"] or 0)
                elif len(d["missed"]) < 5:
                    d["missed"].append(r["key"])
        elif len(r["kinds"]) == 2 and r["faults"]:
            if any(f["manifest_cycle"] is not None for f in r["faults"]):
                pair_manifest += 1
                if any(f["detected"] for f in r["faults"]):
                    pair_detected += 1
                elif len(pair_missed) < 5:
                    pair_missed.append(r["key"])
    unsafe_examples = [{"key": r["key"], "first": r["unsafe_first"]} for r in results if r["unsafe"]][:10]
    crash_examples = [{"key": r["key"], "crash": r["crash"]} for r in results if r["crash"]][:10]
    runs = max(1, total["runs"])
    return {
        "runs": total["runs"], "unsafe": total["unsafe_runs"], "unavoidable": total["unavoidable"],
        "crashes": total["crashes"], "collisions": total["collisions"], "false_braking": total["false_braking"],
        "false_braking_rate": total["false_braking"] / runs, "brake_without_obstacle": total["brake_without_obstacle"],
        "brake_without_obstacle_rate": total["brake_without_obstacle"] / runs,
        "false_braking_examples": [r["key"] for r in results if r["false_braking"]][:10], "single": dict(single), "paired": dict(paired), "by_scenario": dict(scen),
        "by_model": dict(models), "cells": {f"{a}|{b}": v for (a, b), v in cells.items()}, "detection": detection,
        "pairs": {"manifest": pair_manifest, "detected": pair_detected, "missed": pair_missed},
        "unsafe_examples": unsafe_examples, "crash_examples": crash_examples,
        "corrupt_frames_accepted": corrupt_accepted,
        "fault_free_stop_margin_m": {m: (min(v), max(v)) for m, v in margins.items()},
    }


def _bus_summary(runs: list[dict]) -> dict:
    kinds_detected: dict = {}
    for r in runs:
        if r.get("detection_run", True):
            for k, ok in (r.get("detected") or {}).items():
                kinds_detected[k] = kinds_detected.get(k, True) and bool(ok)
    n = len(runs)
    fb = sum(bool(r.get("false_braking")) for r in runs)
    without = sum(bool(r.get("brake_without_obstacle")) for r in runs)
    return {"runs": n, "unsafe": sum(bool(r.get("unsafe")) for r in runs),
            "crashes": sum(r.get("crash") is not None for r in runs),
            "collisions": sum(bool(r.get("collision")) for r in runs),
            "collisions_avoidable": sum(bool(r.get("collision")) and r.get("scenario") != UNAVOIDABLE for r in runs),
            "false_braking": fb, "false_braking_rate": fb / n if n else 0.0, "brake_without_obstacle": without,
            "brake_without_obstacle_rate": without / n if n else 0.0, "detected": kinds_detected,
            "frames_rejected": dict(sum((Counter(r.get("rejects") or {}) for r in runs), Counter())),
            "unsafe_examples": [{"name": r["name"], "first": r.get("unsafe_first")} for r in runs if r.get("unsafe")][:5],
            "crash_examples": [{"name": r["name"], "crash": r["crash"]} for r in runs if r.get("crash")][:5]}


def run(quick: bool, progress: Progress, *, bus: bool = True, vcan_runs: bool = True, cluster: Cluster = Cluster(),
        config: Optional[Config] = None, world: Optional[WorldTrain] = None, margin_m: float = 0.0) -> dict:
    """The whole campaign with the monitor's `config` (default Config(), the shipped braking
    declaration) in a world whose train is `world` (None: each run's own, drawn inside the
    declaration, corners included); unsafe: the world's train reaches an obstacle it could
    have stopped for, or comes closer than `margin_m`. Returns the summary (module docstring)."""
    t0 = time.perf_counter()
    cfg = config or Config()
    specs = plan(quick)
    progress(f"campaign: {len(specs):,} core-level runs ({len(combos()) - 1} fault combinations x "
             f"{len(SCENARIOS)} scenarios{'' if quick else f' x {SEEDS} seeds'})"
             + (f"; world train: {world.describe()}" if world else "; world trains drawn inside the declaration"))
    progress(f"campaign: running on {cluster.describe()}")
    results = run_core(specs, progress, cluster, cfg, world, margin_m)
    progress("campaign: ghost runs (a 0.3 s ghost on one channel beyond SBI, clear track, 40 m/s)")
    ghosts = run_ghosts(quick, cfg, world, margin_m)
    core = aggregate(results + ghosts)
    core["seconds"] = time.perf_counter() - t0
    progress(f"campaign: core runs done in {core['seconds']:.0f} s: {core['unsafe']} unsafe, {core['crashes']} crashes")
    summary = {"mode": "quick" if quick else "full", "core": core, "config": cfg._asdict(), "ghost": ghost_summary(ghosts),
               "world_train": world_train.as_dict(world), "margin_m": margin_m,
               "runs_digest": runs_digest(results + ghosts)}

    bus_runs: list = []
    if bus:
        t1 = time.perf_counter()
        bspecs = bus_plan(quick)
        progress(f"campaign: {len(bspecs)} runs through the runner, codec and player on the virtual bus")
        chunks = [((s,), cfg, world, margin_m) for s in bspecs]
        bus_runs = [r for res in map_ordered(_bus_work, chunks, cluster, progress=progress, label="campaign: bus runs")
                    for r in res]
        summary["bus"] = dict(_bus_summary(bus_runs), seconds=time.perf_counter() - t1,
                              runs_detail=[{k: v for k, v in r.items() if k != "unsafe_first"} for r in bus_runs])
    vruns: list = []
    if vcan_runs:
        try:
            v = vcan_sample(vcan_plan(quick), progress, cfg, margin_m)
            vruns = v["runs"]
            summary["vcan"] = dict(_bus_summary(vruns), seconds=v["seconds"], timed_out=v["timed_out"], runs_detail=vruns_detail(vruns))
        except Exception as exc:  # noqa: BLE001 - SandboxError or an unexpected failure: reported, never a crash of the campaign
            summary["vcan"] = {"runs": 0, "error": f"{type(exc).__name__}: {exc}"}
    summary["runs"] = core["runs"] + len(bus_runs) + len(vruns)
    summary["unsafe"] = core["unsafe"] + sum(bool(r.get("unsafe")) for r in bus_runs + vruns)
    summary["crashes"] = core["crashes"] + sum(r.get("crash") is not None for r in bus_runs + vruns)
    summary["collisions"] = core["collisions"] + sum(bool(r.get("collision")) for r in bus_runs + vruns)
    for key in ("false_braking", "brake_without_obstacle"):
        count = core[key] + sum(bool(r.get(key)) for r in bus_runs + vruns)
        summary[key + "_rate"] = count / summary["runs"] if summary["runs"] else 0.0
    summary["detection"] = {k: core["detection"][k]["manifest"] > 0 and core["detection"][k]["detected"] == core["detection"][k]["manifest"]
                            for k in KINDS}
    summary["readme_table"] = faults_table(core)
    summary["seconds"] = time.perf_counter() - t0
    return summary


OUTCOME_KEYS = ("unsafe", "unavoidable", "collision", "closest_m", "stop_margin_m", "false_braking", "max_demand",
                "cycles", "crash")


def runs_digest(results: list[dict]) -> str:
    """SHA-256 over every core-level run's key (scenario, faults, seed, table) and outcome, in
    key order: the same for any number of workers and any order the runs came back in."""
    h = hashlib.sha256()
    for r in sorted(results, key=lambda r: (r["key"], r.get("ghost_dm", 0))):
        h.update(json.dumps([r["key"], r.get("ghost_dm", 0)] + [r.get(k) for k in OUTCOME_KEYS],
                            sort_keys=True, default=str).encode() + b"\n")
    return h.hexdigest()


def vruns_detail(runs: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in ("unsafe_first",)} for r in runs]


# ----------------------------------------------------------------------------- the report

def _cell(c: dict) -> str:
    if not c or not c["runs"]:
        return "-"
    return (f"{c['unsafe_runs']}/{c['crashes']}/{c['collisions']}/{100 * c['false_braking'] / c['runs']:.0f}%/"
            f"{100 * c['brake_without_obstacle'] / c['runs']:.0f}%")


def faults_by_scenarios_table(core: dict, pairs: bool = True) -> str:
    """Rows: fault-free, each single fault, each fault in pairs; columns: scenarios; cell:
    unsafe runs / crashes / collisions / false-braking rate."""
    cells = core["cells"]
    rows = []
    labels = [("none", "none (fault-free)")] + [(k, CATALOGUE[k].label) for k in KINDS]
    if pairs:
        labels += [("pair:" + k, f"{CATALOGUE[k].label} + another") for k in KINDS]
    for key, label in labels:
        row = [label]
        for s in SCENARIOS:
            row.append(_cell(cells.get(f"{key}|{s.name}")))
        rows.append(row)
    return md_table(["fault \\ scenario"] + [s.name for s in SCENARIOS], rows)


def faults_table(core: dict) -> str:
    """One row per fault kind over all scenarios (the README table)."""
    rows = []
    for key in ("none",) + KINDS:
        c = core["single"].get(key)
        p = core["paired"].get(key)
        det = core["detection"].get(key)
        label = "none (fault-free)" if key == "none" else CATALOGUE[key].label
        both = {k: (c or {}).get(k, 0) + (p or {}).get(k, 0)
                for k in ("runs", "unsafe_runs", "crashes", "collisions", "false_braking", "brake_without_obstacle")}
        detected = "-" if det is None else f"{det['detected']}/{det['manifest']}"
        rows.append([label, f"{both['runs']:,}", both["unsafe_runs"], both["crashes"], both["collisions"],
                     _pct(both["false_braking"] / both["runs"]) if both["runs"] else "-",
                     _pct(both["brake_without_obstacle"] / both["runs"]) if both["runs"] else "-", detected])
    rows.append(["**all runs**", f"{core['runs']:,}", core["unsafe"], core["crashes"], core["collisions"],
                 _pct(core["false_braking_rate"]), _pct(core["brake_without_obstacle_rate"]), ""])
    return md_table(["fault (single or in a pair)", "runs", "unsafe", "crashes", "collisions", "false braking",
                     "braking without an obstacle", "detected (single runs)"], rows)


def heatmap(core: dict, path: Path, measure: str = "brake_without_obstacle") -> Path:
    """Faults x scenarios, coloured by the share of runs with `measure` (braking without an
    obstacle by default: where the fault reactions brake; false braking is in the tables)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    what = {"brake_without_obstacle": "braking without an obstacle", "false_braking": "false braking"}[measure]
    rows = [("none", "none")] + [(k, CATALOGUE[k].label) for k in KINDS]
    fig, axes = plt.subplots(1, 2, figsize=(15, 7.5), sharey=True)
    for ax, prefix, title in ((axes[0], "", "single faults"), (axes[1], "pair:", "the fault in a pair")):
        grid = np.full((len(rows), len(SCENARIOS)), np.nan)
        for i, (key, _) in enumerate(rows):
            k = key if (key == "none" or not prefix) else prefix + key
            for j, s in enumerate(SCENARIOS):
                c = core["cells"].get(f"{k}|{s.name}")
                if c and c["runs"]:
                    grid[i, j] = c[measure] / c["runs"]
        im = ax.imshow(grid, vmin=0, vmax=1, cmap="magma_r", aspect="auto")
        for i in range(grid.shape[0]):
            for j in range(grid.shape[1]):
                if not np.isnan(grid[i, j]):
                    ax.text(j, i, f"{100 * grid[i, j]:.0f}", ha="center", va="center", fontsize=7,
                            color="white" if grid[i, j] > 0.6 else "black")
        ax.set_xticks(range(len(SCENARIOS)), [s.name for s in SCENARIOS], rotation=40, ha="right", fontsize=8)
        ax.set_title(f"{what} (% of runs): {title}")
    axes[0].set_yticks(range(len(rows)), [label for _, label in rows], fontsize=8)
    fig.colorbar(im, ax=axes, shrink=0.7, label=f"runs with {what}")
    fig.suptitle(f"railguard fault campaign: {core['runs']:,} core-level runs, {core['unsafe']} unsafe, "
                 f"{core['crashes']} crashes")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def checks(summary: dict) -> list[Check]:
    core = summary["core"]
    quick = summary["mode"] == "quick"
    out = [
        Check("campaign: the world's train never reaches an obstacle it could stop for (core-level runs)",
              core["unsafe"] == 0,
              f"{core['unsafe']} unsafe runs in {core['runs']:,} runs ({core['collisions']} collisions, "
              f"{core['unavoidable']} unavoidable)", {"examples": core["unsafe_examples"]}),
        Check("campaign: no crash or exception (core-level runs)", core["crashes"] == 0,
              f"{core['crashes']} crashes in {core['runs']:,} runs", {"examples": core["crash_examples"]}),
    ]
    if not quick:
        out.append(Check("campaign: at least 10,000 core-level runs (full mode)", core["runs"] >= 10_000,
                         f"{core['runs']:,} >= 10,000 in {core['seconds']:.0f} s"))
    sudden = {s.name for s in SCENARIOS if any(o.appear_s > 0 for o in s.obstacles)}
    elsewhere = {name: c["unavoidable"] for name, c in core["by_scenario"].items() if name not in sudden}
    out.append(Check(f"campaign: the world finds collisions unavoidable only where an object appears suddenly, and in {UNAVOIDABLE}",
                     sum(elsewhere.values()) == 0 and core["by_scenario"].get(UNAVOIDABLE, {}).get("unavoidable", 0) > 0,
                     f"{sum(elsewhere.values())} unavoidable where the obstacle is there from the start; "
                     f"{core['by_scenario'].get(UNAVOIDABLE, {}).get('unavoidable', 0)} in {UNAVOIDABLE}",
                     {"by_scenario": elsewhere}))
    none = core["single"].get("none", {"runs": 0, "brake_without_obstacle": 0})
    out.append(Check("campaign: fault-free runs never brake without an obstacle",
                     none["runs"] > 0 and none["brake_without_obstacle"] == 0,
                     f"{none['brake_without_obstacle']} of {none['runs']} fault-free runs"))
    out.append(Check(f"campaign: false braking at most {FALSE_BRAKING_LIMIT:.0%} of the core-level runs, none unsafe (issue 11)",
                     core["runs"] > 0 and core["false_braking_rate"] <= FALSE_BRAKING_LIMIT and core["unsafe"] == 0,
                     f"{_pct(core['false_braking_rate'])} ({core['false_braking']:,} of {core['runs']:,}), {core['unsafe']} unsafe; "
                     f"braking without an obstacle, fault reactions included: {_pct(core['brake_without_obstacle_rate'])}",
                     {"examples": core["false_braking_examples"]}))
    if "ghost" in summary:
        g = summary["ghost"]
        out.append(Check("campaign: a 0.3 s ghost on one channel beyond SBI never stops the train (clear track, 40 m/s)",
                         g["runs"] > 0 and not g["stopped"] and g["unsafe"] == 0 and not g["undiagnosed"],
                         f"{g['runs']} runs: lowest speed {g['min_speed_mps']:.1f} m/s, highest demand {g['max_demand']}, "
                         f"{len(g['stopped'])} stopped, {len(g['undiagnosed'])} without the dispute diagnostic",
                         {"stopped": g["stopped"], "undiagnosed": g["undiagnosed"]}))
    for k in KINDS:
        d = core["detection"][k]
        ok = d["manifest"] > 0 and d["detected"] == d["manifest"]
        lat = f", within {d['max_latency']} cycles" if k not in TABLE_KINDS else ""
        out.append(Check(f"campaign: {k} detected ({CATALOGUE[k].short})", ok,
                         f"{d['detected']} of {d['manifest']} single-fault runs in which it manifested "
                         f"({d['single_runs']} runs){lat}", {"missed": d["missed"]}))
    pr = core["pairs"]
    out.append(Check("campaign: every pair run with a manifested fault shows a diagnostic", pr["detected"] == pr["manifest"],
                     f"{pr['detected']} of {pr['manifest']}", {"missed": pr["missed"]}))
    if "bus" in summary:
        b = summary["bus"]
        need = 12 if quick else 50
        out.append(Check(f"campaign: virtual-bus sample through runner, codec and player (>= {need})",
                         b["runs"] >= need and b["unsafe"] == 0 and b["crashes"] == 0 and b["collisions_avoidable"] == 0,
                         f"{b['runs']} runs, {b['unsafe']} unsafe, {b['crashes']} crashes, {b['collisions']} collisions "
                         f"({b['collisions_avoidable']} outside {UNAVOIDABLE})",
                         {"unsafe": b["unsafe_examples"], "crashes": b["crash_examples"]}))
        missing = sorted(k for k in PLAYER_KINDS + ("deadline_overrun",) + TABLE_KINDS if not b["detected"].get(k))
        out.append(Check("campaign: virtual bus: every injected fault kind detected", not missing,
                         "all detected" if not missing else f"not detected: {', '.join(missing)}", {"detected": b["detected"]}))
    if "vcan" in summary:
        v = summary["vcan"]
        need = 1 if quick else 5
        if "error" in v:
            if os.environ.get("CI") == "true" or not _sandbox_unavailable(v["error"]):
                out.append(Check(f"campaign: vcan0 sample in the sandbox (>= {need})", False, v["error"]))
        else:
            missed = sorted(k for k, ok in v["detected"].items() if not ok)
            out.append(Check(f"campaign: vcan0 sample in the sandbox (>= {need})",
                             v["runs"] >= need and v["unsafe"] == 0 and v["crashes"] == 0 and not missed,
                             f"{v['runs']} runs, {v['unsafe']} unsafe, {v['crashes']} crashes, "
                             f"faults detected: {len(v['detected']) - len(missed)} of {len(v['detected'])}, {v['seconds']:.0f} s",
                             {"crashes": v["crash_examples"], "unsafe": v["unsafe_examples"]}))
    return out


def _sandbox_unavailable(error: str) -> bool:
    return error.startswith("SandboxError") and "apt-get" in error


def _ghost_and_before(summary: dict) -> str:
    """The ghost runs, and the quick campaign's figures before the braking curves."""
    core, g, b = summary["core"], summary.get("ghost"), BEFORE_QUICK
    out = ""
    if g:
        out += (f"**Ghost runs** ({g['runs']}): clear track, 40 m/s, one channel reports a static obstacle for {GHOST_S} s at "
                f"{', '.join(f'{d / 10:.1f}' for d in g['distances_dm'])} m (just beyond SBI, half-way to the warning "
                "curve, just beyond it, far), every channel in turn. The disagreement is a dispute: a warning and a "
                f"diagnostic, not a brake. Lowest speed {g['min_speed_mps']:.1f} m/s, highest demand {g['max_demand']}, "
                f"{len(g['stopped'])} stopped, {g['false_braking']} braked falsely, {len(g['undiagnosed'])} without the "
                "`dispute` diagnostic.\n\n")
    if summary["mode"] == "quick":
        out += (f"**Before the braking curves** (commit {b['commit']}: nominal alpha2, a 2oo2 disagreement answered by "
                "`safe_reaction`, every emergency held to standstill; that commit's world, whose train braked at the "
                f"nominal 1 and 3 m/s^2): the same {b['runs']} quick runs gave false braking in {b['false_braking']} "
                f"({_pct(b['false_braking'] / b['runs'])}), braking without an obstacle in {b['brake_without_obstacle']} "
                f"({_pct(b['brake_without_obstacle'] / b['runs'])}), {b['unsafe']} unsafe; {b['ghosts_stopped']} of "
                f"{b['ghosts']} ghosts stopped the train. Now: {core['false_braking']} ({_pct(core['false_braking_rate'])}) "
                f"and {core['brake_without_obstacle']} ({_pct(core['brake_without_obstacle_rate'])}).\n")
    return out


def markdown(summary: dict, figure: Optional[str]) -> str:
    core = summary["core"]
    quick = summary["mode"] == "quick"
    lines = [
        f"Every single fault and every pair of faults from the catalogue ({len(KINDS)} kinds; "
        f"{len(combos()) - 1} fault combinations: {len(KINDS)} singles and {len(combos()) - 1 - len(KINDS)} pairs, "
        f"two channels with the same channel fault among them; and the fault-free case) crossed with {len(SCENARIOS)} obstacle "
        f"scenarios{'' if quick else f' and {SEEDS} seeds'} (channels, windows and variants drawn from each run's seed; "
        "tables m1 and m2 alternating), plus the ghost runs, through `monitor.core.cycle` in a simulated world that "
        "does not share the monitor's assumptions. Its train is the train FMU's physics (`verification/world_train.py`, "
        "a Python twin held equal to the FMU in FMPy: dead time, linear build-up, speed bands, gradient, traction "
        "held after a demand), with parameters of its own: "
        + (f"**the world train given with `--world-train`**: {world_train.from_mapping(summary['world_train'], 'world').describe()}. "
           if summary.get("world_train") else
           "one run in four on a corner of the braking declaration (the guaranteed decelerations exactly, the whole "
           "equivalent build-up as dead time, or as half of it plus a ramp twice as long, the steepest downhill, "
           "full traction for the whole cut-off, the speed reported low by the whole error), the others drawn "
           "inside it (each value between the declared limit and a better one), each from the run's own key. ")
        + "Reports reach the monitor as the runner sees them: received up to one period before the cycle that uses "
        "them (a phase drawn per run; the monitor counts that age) and sensed up to 10 ms before their reception "
        "(which it does not see); a demand reaches the brakes up to 10 ms after its cycle. Six channels with "
        f"{NOISE_SIGMA_M} m Gaussian noise and {RANGE_M:.0f} m range. "
        "Frame faults go through the real `can_bus.codec.Receiver` with real encoded frames. A sample runs through the "
        "real `MonitorRunner`, codec and `Player` on the virtual bus (its train: the world train's decelerations, by "
        "default the declaration's worst corner, the emergency one of the weakest band, the force ramping up in twice "
        "the equivalent build-up; its collisions outside sudden-120m are unsafe), and a few sessions on "
        "SocketCAN vcan0 in the user-mode-Linux sandbox. `railguard campaign --braking FILE.toml` runs it all with "
        "another declaration, `--world-train FILE.toml` with another world train.\n",
        "**Unsafe outcome** (the world's verdict): the world's train reaches an obstacle, or comes closer to it than "
        f"the margin ({summary.get('margin_m', 0.0):g} m; `--unsafe-margin`), that it could have stopped for: "
        "*unavoidable* is an obstacle for which, when it came into sensor range, not even an emergency demand "
        "from the next cycle on would have stopped the world's own train (its twin, stepped ahead). "
        "The monitor's braking curves play no part in the verdict. **Crash**: any "
        "exception in a run, including those the core's fail-safe swallows and those the receive path counts as "
        "`undecodable`. **False braking** (issue 11's measure): a run with a brake demand, after the train entered, "
        "while no true obstacle is within sensor range, that is not the reaction to a fault the monitor diagnosed "
        "(reason bits `stale`, `safe_stop`, `deadline`, `train_input`, `init`, a refused table; an emergency the latch "
        "still holds after such a reaction counts as the reaction). **Braking without an obstacle** (the earlier "
        "measure): any such demand, fault reactions and trains held at the entry by a refused table included. "
        "`sudden-120m` puts an object inside the stopping distance: the world finds its collisions unavoidable, "
        "and a check holds that it finds none elsewhere.\n",
        f"**Core-level runs**: {core['runs']:,} in {core['seconds']:.0f} s; unsafe {core['unsafe']}, crashes "
        f"{core['crashes']}, collisions {core['collisions']}, **false braking {core['false_braking']:,} "
        f"({_pct(core['false_braking_rate'])})**, braking without an obstacle {core['brake_without_obstacle']:,} "
        f"({_pct(core['brake_without_obstacle_rate'])}). Corrupted frames that passed the CRC-8 (multi-byte corruption) "
        f"and were accepted: {core['corrupt_frames_accepted']}. Fault-free stop margins: "
        + ", ".join(f"{m} {a:.1f}..{b:.1f} m" for m, (a, b) in sorted(core["fault_free_stop_margin_m"].items())) + ". "
        + "; ".join(f"Table {m}: {c['runs']:,} runs, {c['unsafe_runs']} unsafe, {c['crashes']} crashes, "
                    f"{c['collisions']} collisions, false braking {_pct(c['false_braking'] / c['runs'])}"
                    for m, c in sorted(core["by_model"].items())) + ".\n",
        _ghost_and_before(summary),
        "### Catalogue and detection\n",
        md_table(["fault", "how it is injected", "diagnostic that shows it", "single runs: detected / manifested",
                  "max latency (cycles)"],
                 [[CATALOGUE[k].label + f" (`{k}`)", CATALOGUE[k].injection, CATALOGUE[k].diagnostic,
                   f"{core['detection'][k]['detected']} / {core['detection'][k]['manifest']}",
                   "-" if k in TABLE_KINDS else core["detection"][k]["max_latency"]] for k in KINDS]),
        "\nA value fault *manifests* when the channel's report differs from its fault-free report (status, or "
        "distance by more than twice `distance_tolerance_dm`); a stuck value that stays true (a clear track, a "
        "train at standstill) or a missed detection with nothing in range cannot be seen by any monitor and harms "
        "nothing. Frame faults, silence, stale timestamps and overruns manifest whenever their window is reached; "
        "table faults always.\n",
        "### Results per fault\n", faults_table(core),
        "\n### Faults x scenarios\n",
        "Cell: unsafe runs / crashes / collisions / false-braking rate / rate of braking without an obstacle.\n",
        faults_by_scenarios_table(core),
        "\n### Per scenario\n",
        md_table(["scenario", "description", "runs", "unsafe", "crashes", "collisions", "false braking",
                  "braking without an obstacle"],
                 [[s.name, s.description, f"{c['runs']:,}", c["unsafe_runs"], c["crashes"], c["collisions"],
                   _pct(c["false_braking"] / c["runs"]), _pct(c["brake_without_obstacle"] / c["runs"])]
                  for s in SCENARIOS + (GHOST_SCENARIO,) if (c := core["by_scenario"].get(s.name))]),
    ]
    if figure:
        lines.append(f"\n![braking without an obstacle, faults x scenarios]({figure})\n")
    if "bus" in summary:
        b = summary["bus"]
        lines += ["\n### Through the real runner and codec on the virtual bus\n",
                  f"{b['runs']} runs of `can_bus.session.run_virtual` (the deadline overrun: the same loop with a clock "
                  "that makes the cycle end 120 ms after its tick; a refused table: the Player alone on the bus) in "
                  f"{b['seconds']:.0f} s: unsafe {b['unsafe']}, crashes {b['crashes']}, collisions {b['collisions']} "
                  f"({b['collisions_avoidable']} outside {UNAVOIDABLE}), false braking {_pct(b['false_braking_rate'])}, braking "
                  f"without an obstacle {_pct(b['brake_without_obstacle_rate'])}. The player's faults are its "
                  "own (`can_bus.player`): its `stale_timestamp` replays the report of 10 periods earlier in a fresh "
                  "frame, so on the bus it shows as a 2oo2 disagreement (module flag) rather than as a stale channel; "
                  "runs named `-detect` place each fault while the train approaches a static obstacle in sight and must "
                  "show its diagnostic. Frames rejected by reason: "
                  + (", ".join(f"{k} {v:,}" for k, v in sorted(b["frames_rejected"].items())) or "none") + ".\n",
                  md_table(["run", "scenario", "table", "outcome", "unsafe", "crash", "detected"],
                           [[r["name"], r.get("scenario", ""), r.get("model", ""), r.get("outcome", ""), r.get("unsafe", 0),
                             "yes" if r.get("crash") else "no",
                             ", ".join(f"{k} {'yes' if ok else 'NO'}" for k, ok in (r.get("detected") or {}).items())]
                            for r in b["runs_detail"]])]
    if "vcan" in summary:
        v = summary["vcan"]
        lines.append("\n### On SocketCAN vcan0 (user-mode-Linux sandbox)\n")
        if "error" in v:
            lines.append(f"Not run: {v['error']}\n")
        else:
            lines += [f"{v['runs']} sessions in one sandbox boot ({v['seconds']:.0f} s): the monitor (`MonitorRunner`, "
                      "wall clock) and the `Player` in a thread on the real vcan0. Unsafe "
                      f"{v['unsafe']}, crashes {v['crashes']}, collisions {v['collisions']}.\n",
                      md_table(["session", "outcome", "margin (m)", "frames received", "rejected", "deadline misses",
                                "unsafe", "detected"],
                               [[r["name"], r.get("outcome", r.get("crash", "")), r.get("margin_m"), r.get("frames_received"),
                                 ", ".join(f"{k} {n}" for k, n in sorted((r.get("rejects") or {}).items())) or "none",
                                 r.get("deadline_misses"), r.get("unsafe"),
                                 ", ".join(f"{k} {'yes' if ok else 'NO'}" for k, ok in (r.get("detected") or {}).items())]
                                for r in v["runs_detail"]])]
    return "\n".join(lines)


def section(out_dir, quick: bool, progress: Progress, config: Optional[Config] = None,
            world: Optional[WorldTrain] = None, margin_m: float = 0.0, cluster: Cluster = Cluster()) -> Section:
    """The campaign as a report part; `config` (default Config()) carries the braking
    declaration, `world` the world's train (None: drawn inside the declaration), `cluster`
    where the runs go."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary = run(quick, progress, config=config, world=world, margin_m=margin_m, cluster=cluster)
    fig = heatmap(summary["core"], out / "campaign_false_braking.png")
    found = checks(summary)
    summary["passed"] = all(c.passed for c in found)
    (out / "campaign.json").write_text(json.dumps(summary, indent=1, default=str))
    headline = {"runs": summary["runs"], "unsafe": summary["unsafe"], "collisions": summary["collisions"],
                "workers": cluster.scheduler or cluster.size(),
                "runs_digest": summary["runs_digest"], "world_train": summary["world_train"], "margin_m": margin_m}
    return Section("Fault-injection campaign", markdown(summary, fig.name), found, [fig.name], summary["seconds"],
                   headline)


def main(argv: Optional[list] = None) -> int:
    import argparse

    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["--vcan-guest"]:
        return vcan_guest(argv[1], argv[2])
    ap = argparse.ArgumentParser(prog="python -m verification.campaign", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", default="railguard-out/campaign")
    args = ap.parse_args(argv)

    def progress(msg: str) -> None:
        if not args.json:
            print(msg, file=sys.stderr, flush=True)

    sec = section(Path(args.out), args.quick, progress)
    if args.json:
        print(json.dumps({"passed": all(c.passed for c in sec.checks),
                          "checks": [{"name": c.name, "passed": bool(c.passed), "figure": c.figure} for c in sec.checks]}))
    else:
        for c in sec.checks:
            print(c.line())
    return 0 if all(c.passed for c in sec.checks) else 1


if __name__ == "__main__":
    sys.exit(main())
