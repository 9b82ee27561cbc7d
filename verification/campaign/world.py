"""One core-level run in the simulated world: the world's own train (the train FMU's physics,
verification/world_train.py) meets the scenario's obstacles, six noisy sensor channels
report them, each fault acts where it acts in the product (values before framing, frames
through the real codec receiver, timestamps, overruns, the table), and `monitor.core.cycle`
decides every cycle. The run's verdict comes from `judge`; an exception anywhere is its crash.
"""
from __future__ import annotations

import hashlib
import math
import random
import traceback
from collections import defaultdict
from typing import Optional

import numpy as np
from monitor.core import cycle
from monitor.core.config import Config, ConfigurationError
from monitor.core.freshness import channel_status
from monitor.core.types import (
    ABSENT, EMERGENCY, MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS, NORMAL, PRESENT, REASON_NAMES, SAFE_STOP,
    STATIC, Inputs, Report, Train,
)

from .. import world_train
from ..world_train import WorldTrain
from .catalogue import FRAME_KINDS, TABLE_KINDS, VALUE_KINDS
from .judge import false_braking_cycles, first_diagnostic
from .specs import RunSpec, instantiate
from .scenarios import NOISE_SIGMA_M, RANGE_M, SCENARIO_BY_NAME
from .tables import faulty_table, shipped_setup, shipped_table


BURST_FACTOR = 50.0


OBSTACLE_TYPES = ("static", "dynamic", "train")
ROUTE_BEFORE_S, ROUTE_AFTER_S = 0.3, 0.8     # frame faults: real codec path around the window


SETTLE_S = 2.0      # a run ends once the train has stood still this long and every fault ended this long ago


def core_step():
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
            setup = shipped_setup(spec.model, cfg)
        else:
            setup = cycle.create(run_cfg, data, expect)
    except ConfigurationError as exc:
        config_error = str(exc)
    step = core_step()
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
    world_given = world is not None
    world = world or world_train.for_run(cfg, spec.key)
    twin = world_train.TrainTwin(world, scen.train.speed_mps, record=True)
    phase_ms = int.from_bytes(hashlib.sha256(f"railguard-campaign/{spec.key}/phase".encode()).digest()[:2], "little") % period
    seen_ago_s = phase_ms / 1000.0 + world.sensor_latency_s     # a report handed now was sensed this long ago
    t = 0.0
    speed = scen.train.speed_mps
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
    declared_avoidable: set = set() # ... of those, the ones a train at the declaration's corners would have stopped for
    outside = world_given and bool(world_train.broken_bounds(world, cfg))
    corners = world_train.corners(cfg) if outside else []
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
                if corners and all(world_train.TrainTwin(c, twin.speed).can_stop_for(near[0], near[1], applied_before)
                                   for c in corners):
                    declared_avoidable.add(near[3])

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
            diag_cycle = first_diagnostic(f, first, reasons_l, flags_l, modes_l, receiver, persisted.get(i))
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
        # a collision this (undeclared) world's train could not avoid, but a declared one would have
        "beyond_declaration": bool(collision and collided_with in declared_avoidable),
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
