"""The cyclic monitor on a python-can bus: drain frames, latch, step the core, send.

Every period (default 100 ms) the runner hands the core the newest valid report of each
channel with the tick it arrived, the newest TrainState (None once it is older than the
channel timeout, which the core reads as a train-input error), and the number of
consecutive deadline overruns; then it sends BrakeDemand and MonitorStatus. A cycle that
ends after its deadline is an overrun; `max_overruns` in a row put the core in SAFE_STOP.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

import can

from monitor.core import cycle as core
from monitor.core.types import EMERGENCY, NO_DISTANCE, R_SAFE_STOP, Inputs, Outputs

from .codec import BRAKE_DEMAND_ID, MONITOR_STATUS_ID, Receiver, Sender


@dataclass
class CycleRecord:
    """What one cycle decided, for summaries, logs and plots."""

    tick: int
    demand: int
    reasons: int
    mode: int
    node: int
    distance_dm: int
    module_flags: int
    system_error: bool
    speed_cms: Optional[int]
    warning: bool = False


@dataclass
class MonitorRunner:
    bus: can.BusABC
    setup: core.Setup
    clock: object
    on_cycle: Optional[Callable[[CycleRecord], None]] = None
    receiver: Receiver = field(init=False)
    sender: Sender = field(default_factory=Sender)
    records: list = field(default_factory=list)
    overruns: int = 0            # consecutive
    deadline_misses: int = 0     # total
    frames_received: int = 0
    frames_sent: int = 0
    send_failures: int = 0

    def __post_init__(self) -> None:
        self.receiver = Receiver(channels=self.setup.config.channels, rate_window_ms=self.setup.config.period_ms)
        self.state = core.initial_state(self.setup)
        self.period = self.setup.config.period_ms
        self.next_tick = self.clock.now_ms()
        self.table_hash = int(self.setup.table.sha256[:3], 16)

    # ------------------------------------------------------------------ receive
    def drain(self, until_ms: Optional[int] = None) -> None:
        """Accept frames until the clock reaches `until_ms` (simulated clock: until the bus is empty)."""
        while True:
            if self.clock.simulated or until_ms is None:
                timeout = 0.0
            else:
                timeout = max(0.0, (until_ms - self.clock.now_ms()) / 1000)
            msg = self.bus.recv(timeout=timeout)
            if msg is None:
                if self.clock.simulated or until_ms is None or self.clock.now_ms() >= until_ms:
                    return
                continue
            self.frames_received += 1
            if msg.is_error_frame or msg.is_remote_frame:
                self.receiver.rejected["error_or_remote_frame"] += 1
                continue
            # after an overrun the clock is past the next cycle's tick: a frame is stamped no later
            # than that tick, never in the cycle's future (older, so it ages sooner: the safe side)
            self.receiver.accept(msg.arbitration_id, msg.data, min(self.clock.now_ms(), self.next_tick), msg.is_extended_id)

    # ------------------------------------------------------------------ one cycle
    def cycle(self) -> Outputs:
        tick = self.next_tick
        rx = self.receiver
        train = rx.train
        if rx.train_tick is None or tick - rx.train_tick > self.setup.timeout_ticks:
            train = None
        inputs = Inputs(tuple(rx.reports), train, self.overruns)
        self.state, out = core.step(self.setup, self.state, inputs, tick)
        self.send(out)
        finished = self.clock.now_ms()
        if finished > tick + self.period:
            self.overruns += 1
            self.deadline_misses += 1
        else:
            self.overruns = 0
        self.next_tick = tick + self.period
        rec = CycleRecord(tick, out.demand, out.reasons, out.mode, out.node, out.distance_dm,
                          out.module_flags, out.system_error, None if train is None else train.speed_cms,
                          out.warning)
        self.records.append(rec)
        if self.on_cycle is not None:
            self.on_cycle(rec)
        return out

    def send(self, out: Outputs) -> None:
        flags = (out.module_flags & 0b111) | (0b1000 if out.system_error else 0)
        flags |= (0b10000 if out.reasons & (1 << 6) else 0) | (0b100000 if out.reasons & (1 << 7) else 0)
        distance = out.distance_dm if out.distance_dm != NO_DISTANCE else 65535
        frames = (
            (BRAKE_DEMAND_ID, {"Level": out.demand, "Warning": int(out.warning), "Reason": out.reasons & 0xFFFF,
                               "Cycle": out.cycle & 0xFFFFFFFF}),
            (MONITOR_STATUS_ID, {"Mode": out.mode, "Warning": int(out.warning), "Node": min(out.node, 1023), "ErrorFlags": flags,
                                 "VotedDistance": distance, "TableHash": self.table_hash,
                                 "DeadlineMisses": min(self.deadline_misses, 15)}),
        )
        for frame_id, signals in frames:
            data = self.sender.frame(frame_id, signals)
            try:
                self.bus.send(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False))
                self.frames_sent += 1
            except can.CanError:
                self.send_failures += 1

    def send_final_emergency(self) -> None:
        """On shutdown: one last emergency demand, so that silence is never read as 'no brake'."""
        last = self.records[-1] if self.records else None
        out = Outputs(EMERGENCY, R_SAFE_STOP, NO_DISTANCE, 0 if last is None else last.node, 3, 0, True, 0,
                      len(self.records) + 1, 0)
        self.send(out)

    # ------------------------------------------------------------------ loop
    def run(self, cycles: Optional[int] = None, stop: Callable[[], bool] = lambda: False) -> None:
        """Real-time loop: wait for frames until each period boundary, then run the cycle."""
        done = 0
        while (cycles is None or done < cycles) and not stop():
            self.drain(self.next_tick)
            self.clock.sleep_until_ms(self.next_tick)
            self.cycle()
            done += 1
