"""The scenario player: a simulated train and six simulated sensor channels on the bus.

Every period it reads BrakeDemand through the reference brake receiver (brake_receiver.py:
no valid frame yet, none for three periods, a second sender or an unknown level is an
emergency held to standstill: the train fails safe), moves the train (brake force
building up over `brake_buildup_s`), and sends TrainState and one ObstacleReport per channel
with Gaussian distance noise, missed detections and the scenario's injected faults. An
obstacle is on the track from its `appear_s` until its `leave_s`: only then can the sensors
see it and the train hit it.

The train waits at the entry of the section (speed 0) until the monitor reports NORMAL
with no demand, as a train waits for its protection system, then enters at its speed.
"""
from __future__ import annotations

import math
import random
from collections import deque
from dataclasses import dataclass, field
from typing import Optional

import can

from monitor.core.types import ABSENT, PRESENT, Report, Train

from .brake_receiver import BrakeReceiver
from .codec import (BRAKE_DEMAND_ID, MONITOR_STATUS_ID, OBSTACLE_IDS, TRAIN_STATE_ID, Receiver, Sender, report_signals,
                    train_signals)
from .hostile import HOSTILE_KINDS, STOLEN_KEY_OF, Hostile
from .scenario import CHANNEL_FREE_KINDS, OBSTACLE_TYPES, Scenario

STALE_REPORT_PERIODS = 10


@dataclass
class TraceRow:
    t_s: float
    speed_mps: float
    distance_m: Optional[float]   # true distance to the nearest obstacle ahead, None if none
    demand: int
    mode: Optional[int]
    tick: int = -1                # the period's tick (ms): joins the world's truth to the bus log


@dataclass
class Player:
    bus: can.BusABC
    scenario: Scenario
    period_ms: int = 100
    wait_for_monitor: bool = True
    receiver: Receiver = field(default_factory=Receiver)
    sender: Sender = field(default_factory=Sender)
    trace: list = field(default_factory=list)
    frames_sent: int = 0
    late_periods: int = 0        # periods whose frames were not sent: the player woke up after the next one began
    faults_injected: set = field(default_factory=set)

    def __post_init__(self) -> None:
        s = self.scenario
        self.rngs = [random.Random(s.sensors.seed * 101 + ch) for ch in range(6)]
        self.started = not self.wait_for_monitor
        self.t = 0.0
        self.position = 0.0
        self.speed = s.train.speed_mps
        self.decel = 0.0
        self.collision = False
        self.impact_mps = 0.0                           # our speed when an obstacle was reached
        self.stop_margin: Optional[float] = None
        self.history: deque = deque(maxlen=STALE_REPORT_PERIODS + 1)
        self.frozen: dict = {}
        self.brakes = BrakeReceiver(self.period_ms)
        self.hostile: Optional[Hostile] = None     # join_hostile: a second node for the hostile faults
        self.security = None                       # secure(): the sensors' and train's keys

    def secure(self, security) -> None:
        """Sign the sensors' and the train's frames and verify the monitor's under `security`
        (security.Security; None leaves the bus unsecured). The hostile node stays keyless."""
        self.security = security
        if security is not None:
            self.receiver = Receiver(security=security)
            self.sender = Sender(security)

    @property
    def wants_hostile(self) -> bool:
        """The scenario has faults a hostile node injects (forge_*, replay_*): give it a bus connection."""
        return any(f.kind in HOSTILE_KINDS for f in self.scenario.faults)

    def join_hostile(self, bus: can.BusABC) -> None:
        """Play the scenario's hostile faults as a second node on its own connection `bus`."""
        self.hostile = Hostile(bus, secured=self.security is not None)
        if self.security is not None and any(f.kind == "forge_absent_stolen_key" for f in self.scenario.faults):
            self.hostile.key = self.security.keyset.keys[STOLEN_KEY_OF]       # a sensor node taken over

    # ------------------------------------------------------------------ world
    def obstacle_distance(self, ch: Optional[int] = None) -> Optional[tuple[float, object]]:
        """(distance, spec) of the nearest obstacle on the track (that channel `ch` can see, if
        given: a sensor reports the nearest object it sees), None if none."""
        best = None
        for o in self.scenario.obstacles:
            if not (o.there(self.t) if ch is None else o.seen_by(self.t, ch)):
                continue
            pos = o.position_m + o.speed_mps * (self.t - o.appear_s)
            d = pos - self.position
            if best is None or d < best[0]:
                best = (d, o)
        return best

    def demand(self, tick: int) -> int:
        return self.brakes.level(self.receiver, tick, self.speed if self.started else 0.0)

    def move(self, level: int) -> None:
        tr = self.scenario.train
        dt = self.period_ms / 1000
        emergency = tr.emergency_at(self.speed)         # its speed band
        target = (0.0, tr.service_decel_mps2, emergency)[level]
        rate = emergency / tr.brake_buildup_s if tr.brake_buildup_s > 0 else math.inf
        self.decel += max(-rate * dt, min(rate * dt, target - self.decel))
        if self.collision:
            self.speed = 0.0
            self.t += dt                 # the world's clock goes on: the run ends at the scenario's end
            return
        new_speed = max(0.0, self.speed - self.decel * dt)
        self.position += (self.speed + new_speed) / 2 * dt
        self.speed = new_speed
        self.t += dt
        near = self.obstacle_distance()
        if near is not None and near[0] <= 0:
            self.collision, self.impact_mps = True, self.speed
            self.speed = 0.0
        elif near is not None and self.speed == 0.0 and self.stop_margin is None:
            self.stop_margin = near[0]

    # ------------------------------------------------------------------ sensors
    def true_report(self, ch: int, tick: int) -> Report:
        s = self.scenario.sensors
        near = self.obstacle_distance(ch)
        if near is None or near[0] > s.range_m or near[0] < 0:
            return Report(ABSENT, 0, 0, 0, tick)
        d, spec = near
        sigma = s.noise_sigma_m * (50.0 if self.active("noise_burst", ch) else 1.0)
        rng = self.rngs[ch]
        noisy = max(0.0, d + s.distance_bias_m + (rng.gauss(0.0, sigma) if sigma > 0 else 0.0))
        missed = rng.random() < s.miss_probability or self.active("missed_detection", ch) or self.active("blind", ch)
        closing = (self.speed if self.started else 0.0) - spec.speed_mps + s.closing_bias_mps
        rep = Report(PRESENT, min(60000, round(noisy * 10)), max(-15000, min(15000, round(closing * 100))),
                     OBSTACLE_TYPES.index(spec.type), tick)
        return rep._replace(status=ABSENT, distance_dm=0) if missed else rep

    def active(self, kind: str, ch: int) -> bool:
        """A `kind` fault hits channel `ch` now (a channel-free fault, blind, hits every one)."""
        for f in self.scenario.faults:
            if f.kind == kind and (f.channel == ch or kind in CHANNEL_FREE_KINDS) and f.start_s <= self.t < f.end_s:
                self.faults_injected.add((f.kind, ch))
                return True
        return False

    def fault_rate(self, ch: int) -> int:
        for f in self.scenario.faults:
            if f.kind == "babble" and f.channel == ch and f.start_s <= self.t < f.end_s:
                self.faults_injected.add((f.kind, f.channel))
                return f.rate
        return 1

    def send(self, frame_id: int, data: bytes) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False, is_fd=len(data) > 8))
            self.frames_sent += 1
        except can.CanError:
            pass

    def send_reports(self, tick: int) -> None:
        reports = [self.true_report(ch, tick) for ch in range(6)]
        self.history.append(reports)
        for ch in range(6):
            rep = reports[ch]
            if self.active("stale_timestamp", ch):
                rep = self.history[0][ch]
            if self.active("stuck", ch):
                rep = self.frozen.setdefault(ch, rep)
            else:
                self.frozen.pop(ch, None)
            if self.active("contradiction", ch):
                rep = rep._replace(status=ABSENT if rep.status == PRESENT else PRESENT,
                                   distance_dm=rep.distance_dm or 1000)
            if self.active("silence", ch):
                continue
            fid = OBSTACLE_IDS[ch]
            if self.hostile is not None and self.active("forge_absent", ch):
                self.hostile.forge_absent(ch, self.sender.counters.get(fid, -1) + 1)
            if self.hostile is not None and self.active("forge_absent_stolen_key", ch):
                self.hostile.forge_absent(ch, self.sender.counters.get(fid, -1) + 1, "forge_absent_stolen_key")
            if self.hostile is not None and self.active("replay_absent", ch):
                self.hostile.replay("replay_absent", fid, self.sender.counters.get(fid, -1) + 1)
            for _ in range(self.fault_rate(ch)):
                if self.active("counter_freeze", ch) and fid in self.sender.counters:
                    self.sender.counters[fid] = (self.sender.counters[fid] - 1) & 0xF
                if self.active("counter_jump", ch) and fid in self.sender.counters:
                    self.sender.counters[fid] = (self.sender.counters[fid] + 4) & 0xF
                data = bytearray(self.sender.frame(fid, report_signals(rep, ch)))
                if self.active("bad_crc", ch):
                    data[0] ^= 0x5A
                if self.active("wrong_length", ch):
                    data = data[:6] if len(data) <= 8 else data[:16]   # (secured: a shorter FD length)
                self.send(fid, bytes(data))

    # ------------------------------------------------------------------ one period
    def drain(self, tick: int) -> None:
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            if not (msg.is_error_frame or msg.is_remote_frame):
                self.receiver.accept(msg.arbitration_id, msg.data, tick)

    def step(self, tick: int, send: bool = True) -> None:
        """One period of the world. `send=False` moves the train without sending frames: a
        player that woke up late (its host stalled) does not send a backlog of old reports in a
        burst, which no real sensor does and which the monitor rightly refuses as babbling."""
        self.drain(tick)
        if self.hostile is not None:
            self.hostile.listen()                     # what the other nodes sent, from its own connection
            if self.active("forge_brake_none", 0):
                self.hostile.forge_brake_none()
            if self.active("replay_brake_none", 0):
                self.hostile.replay("replay_brake_none", BRAKE_DEMAND_ID, self.hostile.brake_counter + 1)
        status = self.receiver.status
        mode = None if status is None else int(status["Mode"])
        level = self.demand(tick)                  # the brake receiver's verdict (standing, if not started)
        if not self.started and mode == 1 and level == 0:
            self.started = True                    # the protection system is up and releases the brakes
        if self.started:
            self.move(level)
        speed = self.speed if self.started else 0.0
        near = self.obstacle_distance()
        self.trace.append(TraceRow(self.t, speed, None if near is None else near[0], level, mode, tick))
        if not send:
            self.late_periods += 1
            return
        tr = self.scenario.train
        self.send(TRAIN_STATE_ID, self.sender.frame(TRAIN_STATE_ID, train_signals(
            Train(round(speed * 100), int(tr.track == "slippery"), int(tr.brake == "degraded")))))
        self.send_reports(tick)

    @property
    def finished(self) -> bool:
        return self.started and self.t >= self.scenario.duration_s - 1e-9

    def outcome(self) -> dict:
        saw_obstacle = any(r.distance_m is not None for r in self.trace)
        if self.collision:
            # an oncoming obstacle that reaches a standing train: not a collision of ours (as cosim)
            result = "collision" if self.impact_mps > 0.0 else "struck_at_standstill"
        elif not self.finished and not (self.started and self.speed == 0.0):
            # cut short (--duration, a signal) with the train still running or not yet started: no verdict
            result = "incomplete"
        elif saw_obstacle:
            # "avoided": an obstacle was there, no collision, but the train never stood still
            # ("stopped" without a margin: it stood after the obstacle had left the track)
            result = "stopped" if self.stop_margin is not None or self.speed == 0.0 else "avoided"
        else:
            result = "no_obstacle"
        return {
            "outcome": result,
            "margin_m": None if self.stop_margin is None else round(self.stop_margin, 2),
            "scenario_s": round(self.t, 1),
            "final_speed_mps": round(self.speed if self.started else 0.0, 3),
            "brake_receiver": self.brakes.summary(),
            "brake_timeout_after_ms": self.brakes.silent_ms,   # silence before the receiver braked, if it did
            "hostile_frames": {} if self.hostile is None else dict(sorted(self.hostile.sent.items())),
        }


__all__ = ["Player", "TraceRow", "MONITOR_STATUS_ID"]
