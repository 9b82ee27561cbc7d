"""The sample through the real product on python-can's virtual bus: the bus runs' plan, the
world scenario as a can_bus Scenario for the Player, and one run through `MonitorRunner`,
the codec and the Player (a clock that makes cycles late for the overrun, the Player alone
for a refused table), with exceptions the core's fail-safe swallows counted as crashes.
"""
from __future__ import annotations

import os
import tempfile
import traceback
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Optional

from monitor.core import cycle
from monitor.core.config import Config, ConfigurationError

from .. import world_train
from ..world_train import WorldTrain
from .catalogue import HOSTILE_KINDS, PLAYER_KINDS, TABLE_KINDS
from .judge import bus_detection, evaluate_bus
from .specs import Fault
from .scenarios import NOISE_SIGMA_M, RANGE_M, SCENARIO_BY_NAME
from .tables import faulty_table, shipped_table
from .world import core_step


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
    secured: bool = False    # on the secured bus (issue 39: a test key set; the hostile node holds no key)

    @property
    def kinds(self) -> tuple:
        return tuple(f.kind for f in self.faults)


def secured_kind(kind: str) -> str:
    """A fault kind's name for its detection on the secured bus."""
    return f"{kind} (secured bus)"


def bus_scenario(spec: BusSpec, cfg: Optional[Config] = None, world: Optional[WorldTrain] = None):
    """The world scenario as a can_bus Scenario for the Player (same obstacles, noise, faults);
    its train brakes at the world train's decelerations (default: the declaration's worst
    corner; the emergency brake at its weakest band), its force ramping up in twice the
    equivalent build-up time (dead time + half the ramp)."""
    cfg = cfg or Config()
    world = world or world_train.corners(cfg)[0]
    from can_bus.scenario import FaultSpec, Scenario, SensorSpec, TrainSpec, check

    w = SCENARIO_BY_NAME[spec.scenario]
    faults = []
    for f in spec.faults:
        if f.kind in PLAYER_KINDS + HOSTILE_KINDS:
            rate = f.variant[0] if f.kind == "babble" and f.variant else 20
            faults.append(FaultSpec(f.kind, f.channel, float(f.start_s), float(f.end_s), rate))
    scen = Scenario(
        name=spec.name, description=w.description, duration_s=spec.duration_s or w.duration_s,
        train=TrainSpec(speed_mps=w.train.speed_mps, service_decel_mps2=world.service_decel,
                        emergency_decel_mps2=((0.0, min(a for _, a in world.emergency_decel)),),
                        brake_buildup_s=2 * world.equivalent_buildup_s()),
        obstacles=w.obstacles, sensors=SensorSpec(RANGE_M, NOISE_SIGMA_M, 0.0, spec.seed), faults=tuple(faults))
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
    specs.append(BusSpec("bus-forge_absent-detect", "static-700m-30",
                         tuple(Fault("forge_absent", ch, 1.0, 1e9) for ch in range(6)), "m2", 40, True, 30.0))
    specs.append(BusSpec("bus-forge_brake_none-detect", "static-700m-30", (Fault("forge_brake_none", 0, 1.0, 1e9),),
                         "m1", 41, True, 30.0))     # 30 s: without the defence the train reaches the obstacle
    for spec in specs[-2:]:                         # the same two attacks on the secured bus
        specs.append(replace(spec, name=spec.name.replace("-detect", "-secured-detect"), secured=True))
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


def counting_core():
    """Patch monitor.core.cycle.step (which the runner calls) so that exceptions swallowed by
    the core's fail-safe are counted; returns (counter, restore)."""
    original = cycle.step
    inner = core_step()
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
    from can_bus.security import made_test_keys

    out = {"name": spec.name, "kinds": spec.kinds, "scenario": spec.scenario, "model": spec.model,
           "detection_run": spec.detection, "crash": None, "unsafe": 0, "collision": False, "false_braking": False,
           "brake_without_obstacle": False}
    counter, restore = counting_core()
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
            if not player.started:      # the Player's "incomplete" (no verdict) would hide the safe side's verdict
                out["outcome"] = "held"
            return out
        overrun = [f for f in spec.faults if f.kind == "deadline_overrun"]
        with tempfile.TemporaryDirectory(prefix="railguard-campaign-") as tmp:
            if not overrun:
                keys = made_test_keys(Path(tmp) / "keys") if spec.secured else None
                res = session.run_virtual(setup, scen, Path(tmp), plot=False, keys=keys)
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
        detected = bus_detection(spec.faults, runner.records, runner.receiver.rejected, player.brakes.causes)
        out["detected"] = {secured_kind(k) if spec.secured else k: v for k, v in detected.items()}
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


def bus_work(job: tuple) -> list:
    specs, cfg, world, margin_m = job
    return [bus_run(s, cfg, world, margin_m) for s in specs]
