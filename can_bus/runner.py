"""The cyclic monitor on a python-can bus: drain frames, latch, step the core, send.

Every period (default 100 ms) the runner hands the core the newest valid report of each
channel with the tick it arrived, the newest TrainState (None once it is older than the
channel timeout, which the core reads as a train-input error), and the number of
consecutive deadline overruns; then it sends BrakeDemand, MonitorStatus and MonitorTrack (the
remembered obstacle). A cycle whose frames would leave after its deadline is an overrun; it
sends no BrakeDemand below emergency (the brakes' receiver times out instead, which the
supervision's timing contract counts); `max_overruns` in a row put the core in SAFE_STOP.

The receive path and the core step live in `MonitorCore`, which knows no bus and no
clock: the live runner feeds it frames from the bus, `railguard replay` frames from a log,
so that both decide the same on the same traffic. The runner's drain is bounded by the
cycle's deadline after every frame, the kernel (SocketCAN) or `frames.monitored` drops
what the monitor does not read, and per-ID policing refuses a babbling sender before any
decoding: at any arrival rate the BrakeDemand frame leaves every cycle.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import can
from cantools.autosar.end_to_end import check_profile2_crc

from monitor.core import cycle as core
from monitor.core.risk import CRITICAL, MAX_SCORE, PPM
from monitor.risk_summary import RiskTally
from monitor.risk_summary import risk_columns as columns_of
from monitor.core.types import (
    EMERGENCY, NO_DISTANCE, R_MEMORY, R_PERCEPTOR, R_SAFE_STOP, R_STALE, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD,
    TRACK_NONE, TRACK_PASSED, Inputs, Outputs,
)

from . import frames
from .codec import (
    BRAKE_DEMAND_ID, FRAME_LENGTH, MONITOR_RISK_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, Receiver, Sender, data_id, database,
)

FOREIGN_HOLD_CYCLES = 10   # ForeignOutput stays set this many cycles after the last foreign frame
SEND_RETRY_S = 0.005       # a full transmit queue is retried this long, then counted as a failure
SWEEP_FRAMES = 32          # frames already queued at the deadline still taken into the cycle,
SWEEP_MS = 2               # ... for at most this long after it

# MonitorStatus.ErrorFlags (the DBC's VAL_ table names each bit)
FLAG_MODULES = 0b111              # bit m: module m+1 is in error
FLAG_SYSTEM_ERROR = 1 << 3
FLAG_STALE = 1 << 4
FLAG_PERCEPTOR = 1 << 5
NO_DISTANCE_RAW = 65535           # VotedDistance "no_distance", TrackDistance "no_track"
TRACK_AGE_MAX = 65535             # MonitorTrack.TrackAge, 0.1 s: saturates at 6553.5 s
UNSEEN = (TRACK_HELD, TRACK_CONFIRMING)   # track states of an obstacle remembered while no channel shows it


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
    foreign_output: bool = False     # another sender used the monitor's output IDs lately
    track_dm: int = NO_DISTANCE      # the remembered obstacle's predicted distance (NO_DISTANCE: none)
    track_cycles: int = 0            # cycles since it was last voted
    track_state: int = TRACK_NONE    # monitor.core.types.TRACK_NAMES
    r1_ppm: int = 0                  # the papers' risk and the table's (monitor.core.risk, MonitorRisk)
    r2_ppm: int = 0
    risk_score: int = 0
    risk_category: int = 1
    table_risk_ppm: int = 0


def held_unseen(rec) -> bool:
    """The cycle's track is remembered while no channel shows it (held, or confirming its absence)."""
    return rec.track_state in UNSEEN


@dataclass
class TrackTally:
    """The remembered obstacle over a run, added one cycle at a time (constant memory: the live
    summary and the streamed replay use it alike). `held_*` is the time a track was remembered
    while no channel showed it (track state held or confirming): the longest spell and the
    total; `forgotten` counts tracks dropped on evidence, `passed` those the train ran past;
    `memory_cycles` the cycles whose curves supervised a remembered obstacle (reason `memory`)."""

    period_ms: int
    held_cycles: int = 0
    longest_cycles: int = 0
    forgotten: int = 0
    passed: int = 0
    memory_cycles: int = 0
    spell: int = 0

    def add(self, rec) -> None:
        if held_unseen(rec):
            self.spell += 1
            self.held_cycles += 1
            self.longest_cycles = max(self.longest_cycles, self.spell)
        else:
            self.spell = 0
        self.forgotten += rec.track_state == TRACK_FORGOTTEN
        self.passed += rec.track_state == TRACK_PASSED
        self.memory_cycles += bool(rec.reasons & R_MEMORY)

    def as_dict(self) -> dict:
        return {"held_longest_s": self.longest_cycles * self.period_ms / 1000,
                "held_total_s": self.held_cycles * self.period_ms / 1000,
                "forgotten": self.forgotten, "passed": self.passed, "memory_cycles": self.memory_cycles}


def risk_summary(records: list, period_ms: int) -> dict:
    tally = RiskTally(period_ms)
    for rec in records:
        tally.add(rec)
    return tally.as_dict()


def track_columns(recs) -> dict:
    """monitor.plot.plot_run's track columns from cycle records (live or replayed): the
    remembered obstacle's predicted distance in m (None: no track) and its state."""
    return {"track_m": [None if r.track_dm == NO_DISTANCE else r.track_dm / 10 for r in recs],
            "track_state": [r.track_state for r in recs]}


def per_mille_up(ppm: int) -> int:
    """MonitorRisk.R1 / R2 raw (0.1 %) from ppm, rounded up: a risk is never shown lower."""
    return (ppm + 999) // 1000


def risk_columns(recs) -> dict:
    """monitor.plot.plot_run's risk columns from cycle records (live or replayed)."""
    return columns_of([r.r1_ppm for r in recs], [r.r2_ppm for r in recs], [r.table_risk_ppm for r in recs],
                      [r.risk_category for r in recs])


def track_age(cycles: int, period_ms: int) -> int:
    """MonitorTrack.TrackAge in 0.1 s: `cycles` periods, rounded to the nearest 0.1 s, saturating."""
    return min((cycles * period_ms + 50) // 100, TRACK_AGE_MAX)


@dataclass
class OwnStream:
    """The recorded monitor's frames on one output ID (replay): E2E counter and tick."""

    counter: int
    tick: int


@dataclass
class MonitorCore:
    """Receive path, core step and output diagnostics, without bus or clock.

    `ingest(msg, tick)` takes one frame as it arrived: it is counted by kind (`frames`),
    dropped if the receive filter would not deliver it (`filtered`), refused if it is not
    a classical data frame (`fd_frame`, `remote_frame`, `error_frame`; error frames also
    update the bus state), counted as `foreign_output` if it is on the monitor's own
    output IDs and not the monitor's, else handed to the codec's Receiver.
    `decide(tick, overruns)` steps the core.

    Live, the monitor never receives its own frames, so every frame on an output ID is
    foreign. A log (`recorded_outputs=True`) holds the recorded monitor's own frames: on
    each output ID the one stream with valid CRC and alive counter stepping by one is the
    monitor's (a stream silent for ten periods may restart); every other frame there is
    foreign. A foreign frame that happens to continue the counter is taken for the
    monitor's and the monitor's next frame is then counted instead: the count is right,
    only the blame may fall on the other frame.
    """

    setup: core.Setup
    recorded_outputs: bool = False
    security: Optional[object] = None        # security.Security of a secured bus; None: unsecured (E2E only)
    receiver: Receiver = field(init=False)
    tally: frames.FrameTally = field(default_factory=frames.FrameTally)
    recorded_demands: list = field(default_factory=list)     # (tick, level) of the recorded monitor
    foreign_until: int = -1

    def __post_init__(self) -> None:
        cfg = self.setup.config
        self.receiver = Receiver(channels=cfg.channels, rate_window_ms=cfg.period_ms, security=self.security)
        self.frame_kind = "classical" if self.security is None else "fd"   # the only kind decoded
        self.state = core.initial_state(self.setup)
        self.period = cfg.period_ms
        self.own: dict = {}
        self.outputs: Optional[Outputs] = None

    @property
    def rejected(self):
        return self.receiver.rejected

    def ingest(self, msg: can.Message, tick: int) -> Optional[str]:
        """Take one frame that arrived at `tick`; return the message name if accepted."""
        kind = self.tally.count(msg)
        if not frames.monitored(msg):
            self.tally.filtered += 1
            return None
        if kind != self.frame_kind:          # (a secured bus: a classical frame is an unsecured one)
            self.receiver.rejected[f"{kind}_frame"] += 1
            return None
        fid = msg.arbitration_id
        data = bytes(msg.data)
        if fid in frames.OUTPUT_IDS:
            if not self._own_output(fid, data, tick):
                self.receiver.rejected["foreign_output"] += 1
                self.foreign_until = tick + FOREIGN_HOLD_CYCLES * self.period
            return None
        return self.receiver.accept(fid, data, tick, msg.is_extended_id)

    def _own_output(self, fid: int, data: bytes, tick: int) -> bool:
        if not self.recorded_outputs:
            return False
        if self.security is not None:           # the recorded monitor's frames verify under its key
            verdict, data = self.security.open(fid, data)
            if verdict != "ok":
                return False
        if len(data) != FRAME_LENGTH or not check_profile2_crc(data, data_id(fid)):
            return False
        counter = data[1] & 0xF
        last = self.own.get(fid)
        if last is not None and tick - last.tick <= 10 * self.period:
            if (counter - last.counter) & 0xF != 1:
                return False
        self.own[fid] = OwnStream(counter, tick)
        if fid == BRAKE_DEMAND_ID:
            level = database().get_message_by_frame_id(fid).decode(data, decode_choices=False)["Level"]
            self.recorded_demands.append((tick, level))
        return True

    def decide(self, tick: int, overruns: int = 0) -> tuple[Outputs, "CycleRecord"]:
        """Step the core at `tick` with what has arrived; return its outputs and the record."""
        rx = self.receiver
        train = rx.train
        if rx.train_tick is None or tick - rx.train_tick > self.setup.timeout_ticks:
            train = None
        self.state, out = core.step(self.setup, self.state, Inputs(tuple(rx.reports), train, overruns), tick)
        self.outputs = out
        rec = CycleRecord(tick, out.demand, out.reasons, out.mode, out.node, out.distance_dm,
                          out.module_flags, out.system_error, None if train is None else train.speed_cms,
                          out.warning, tick <= self.foreign_until, out.track_dm, out.track_cycles, out.track_state,
                          out.r1_ppm, out.r2_ppm, out.risk_score, out.risk_category, out.table_risk_ppm)
        return out, rec


@dataclass
class MonitorRunner:
    bus: can.BusABC
    setup: core.Setup
    clock: object
    on_cycle: Optional[Callable[[CycleRecord], None]] = None
    security: Optional[object] = None        # security.Security (the monitor's keys); None: unsecured
    monitor: MonitorCore = field(init=False)
    sender: Sender = field(init=False)
    records: list = field(default_factory=list)
    overruns: int = 0            # consecutive
    deadline_misses: int = 0     # total
    frames_received: int = 0
    frames_sent: int = 0
    send_failures: int = 0
    demands_withheld: int = 0    # late cycles' BrakeDemand below emergency, not sent (cycle())
    max_send_gap_ms: int = 0     # largest gap between two BrakeDemand sends (wall clock; 0 when simulated)

    def __post_init__(self) -> None:
        self.monitor = MonitorCore(self.setup, security=self.security)
        self.sender = Sender(self.security)
        self.period = self.setup.config.period_ms
        self.next_tick = self.clock.now_ms()
        self.table_hash = int(self.setup.table.sha256[:3], 16)
        self.last_send_ms: Optional[int] = None

    @property
    def receiver(self) -> Receiver:
        return self.monitor.receiver

    @property
    def state(self):
        return self.monitor.state

    @property
    def outputs(self) -> Optional[Outputs]:
        """The core's outputs of the last cycle."""
        return self.monitor.outputs

    # ------------------------------------------------------------------ receive
    def drain(self, until_ms: Optional[int] = None) -> None:
        """Accept frames until the clock reaches `until_ms` (simulated clock: until the bus is
        empty). The deadline is checked after every frame, so a flood cannot hold the cycle;
        at the deadline, frames already queued are still taken (at most SWEEP_FRAMES, for at
        most SWEEP_MS), so that a report that arrived just before the cycle is not left for
        the next one."""
        swept = 0
        while True:
            if self.clock.simulated or until_ms is None:
                timeout = 0.0
            else:
                late = self.clock.now_ms() - until_ms
                timeout = -late / 1000
                if late >= 0:
                    if swept >= SWEEP_FRAMES or late > SWEEP_MS:
                        return
                    swept += 1
                    timeout = 0.0
            try:
                msg = self.bus.recv(timeout=timeout)
            except can.CanError:
                self.monitor.rejected["receive_error"] += 1
                return
            if msg is None:
                if self.clock.simulated or until_ms is None or swept or self.clock.now_ms() >= until_ms:
                    return
                continue
            self.frames_received += 1
            # after an overrun the clock is past the next cycle's tick: a frame is stamped no later
            # than that tick, never in the cycle's future; a frame that waited in the socket's
            # queue is as old as its kernel timestamp says (older: it ages sooner, the safe side)
            tick = min(self.clock.now_ms(), self.next_tick)
            stamped = self.clock.tick_of_stamp(msg.timestamp)
            if stamped is not None:
                tick = min(tick, stamped)
            self.monitor.ingest(msg, tick)

    # ------------------------------------------------------------------ one cycle
    def cycle(self) -> CycleRecord:
        """Step the core, send its outputs, keep and return the cycle's record."""
        tick = self.next_tick
        out, rec = self.monitor.decide(tick, self.overruns)
        # a late cycle (its frames would leave after its period: an overrun) never sends a
        # BrakeDemand below emergency: a demand that left late and said less would restart the
        # brakes' receiver timeout on a picture older than a period, and the supervision's
        # timing contract (braking.SUPERVISED_PERIODS) counts one period for the frame's way
        late = self.clock.now_ms() > tick + self.period
        self.send(out, rec.foreign_output, withhold_demand=late and out.demand != EMERGENCY)
        if late or self.clock.now_ms() > tick + self.period:      # late, or its sending made it late
            self.overruns += 1
            self.deadline_misses += 1
        else:
            self.overruns = 0
        self.next_tick = tick + self.period
        self.records.append(rec)
        if self.on_cycle is not None:
            self.on_cycle(rec)
        return rec

    def send(self, out: Outputs, foreign_output: bool = False, withhold_demand: bool = False) -> None:
        """The cycle's four frames; `withhold_demand`: all but BrakeDemand (a late cycle's
        demand below emergency, counted in `demands_withheld`)."""
        flags = (out.module_flags & FLAG_MODULES) | (FLAG_SYSTEM_ERROR if out.system_error else 0)
        flags |= (FLAG_STALE if out.reasons & R_STALE else 0) | (FLAG_PERCEPTOR if out.reasons & R_PERCEPTOR else 0)
        distance = out.distance_dm if out.distance_dm != NO_DISTANCE else NO_DISTANCE_RAW
        messages = (
            (BRAKE_DEMAND_ID, {"Level": out.demand, "Warning": int(out.warning), "Reason": out.reasons & 0xFFFF,
                               "Cycle": out.cycle & 0xFFFFFFFF}),
            (MONITOR_STATUS_ID, {"Mode": out.mode, "Warning": int(out.warning), "ForeignOutput": int(foreign_output),
                                 "Node": min(out.node, 1023), "ErrorFlags": flags,
                                 "VotedDistance": distance, "TableHash": self.table_hash,
                                 "DeadlineMisses": min(self.deadline_misses, 15)}),
            (MONITOR_TRACK_ID, {"TrackState": out.track_state, "Memory": int(bool(out.reasons & R_MEMORY)),
                                "TrackDistance": min(out.track_dm, NO_DISTANCE_RAW),
                                "TrackAge": track_age(out.track_cycles, self.period)}),
            (MONITOR_RISK_ID, {"RiskCategory": out.risk_category, "RiskScore": out.risk_score,
                               "R1": per_mille_up(out.r1_ppm), "R2": per_mille_up(out.r2_ppm),
                               "TableRisk": out.table_risk_ppm, "Unsecured": int(self.security is None)}),
        )
        for frame_id, signals in messages:
            if withhold_demand and frame_id == BRAKE_DEMAND_ID:
                self.demands_withheld += 1
                continue
            data = self.sender.frame(frame_id, signals)
            if self._transmit(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False,
                                          is_fd=len(data) > FRAME_LENGTH)):
                self.frames_sent += 1
                if frame_id == BRAKE_DEMAND_ID and not self.clock.simulated:
                    now = time.monotonic_ns() // 1_000_000
                    if self.last_send_ms is not None:
                        self.max_send_gap_ms = max(self.max_send_gap_ms, now - self.last_send_ms)
                    self.last_send_ms = now
            else:
                self.send_failures += 1

    def _transmit(self, msg: can.Message) -> bool:
        """Send once; a full transmit queue (a flooded bus) is retried for SEND_RETRY_S."""
        give_up = time.monotonic() + (0.0 if self.clock.simulated else SEND_RETRY_S)
        while True:
            try:
                self.bus.send(msg)
                return True
            except can.CanError:
                if time.monotonic() >= give_up:
                    return False
                time.sleep(0.0005)

    def send_final_emergency(self) -> None:
        """On shutdown: one last emergency demand, so that silence is never read as 'no brake'
        (the monitor stops supervising: its MonitorTrack says no track, its MonitorRisk the
        worst, as the core's safe stop does: nothing is known any more)."""
        last = self.records[-1] if self.records else None
        out = Outputs(EMERGENCY, R_SAFE_STOP, NO_DISTANCE, 0 if last is None else last.node, 3, 0, True, 0,
                      len(self.records) + 1, 0, r1_ppm=PPM // 2, r2_ppm=PPM, risk_score=MAX_SCORE,
                      risk_category=CRITICAL, table_risk_ppm=PPM)
        self.send(out)

    # ------------------------------------------------------------------ loop
    def run(self, cycles: Optional[int] = None, stop: Callable[[], bool] = lambda: False,
            before_cycle: Optional[Callable[[int], None]] = None) -> list:
        """The one monitor loop, on a real bus or the simulated one: take frames until each
        period boundary, then run the cycle (`on_cycle` sees every cycle's record);
        `before_cycle(tick)` runs first (on a simulated clock: the player's turn). Returns the
        records kept."""
        done = 0
        while (cycles is None or done < cycles) and not stop():
            if before_cycle is not None:
                before_cycle(self.next_tick)
            self.drain(self.next_tick)
            self.clock.sleep_until_ms(self.next_tick)
            self.cycle()
            done += 1
        return self.records
