"""Run the monitor over a recorded bus log and report its decisions, as the live runner would.

Frames go through `runner.MonitorCore`, the receive path of the live runner, in file
order (a live monitor reads frames in the order they arrive); the tick of a frame is its
time since the segment's first frame in ms, and the core steps at every period boundary
with what had arrived by then. The result depends only on the file.

The log is streamed: memory stays constant whatever its length, and decisions are handed
out one cycle at a time (`Replay.run` is a generator).

Timestamps. A frame stamped earlier than the one before it is taken at the time of the one
before it (the order in the file is the order of arrival; a log's clock that steps back
does not make a frame older) and reported with its line. A jump of more than `max_gap_s`
either way (a stray `(0.000000)` in an epoch-time log, a recording paused for a day) ends
the segment: with `on_time_error="split"` (the default) the next segment is replayed as a
fresh start of the monitor, which never carries a picture across the jump; with "refuse"
the replay stops with a LogError naming the line. Either way the work is bounded by the
log's length, never by the size of the jump.

Where the log holds the monitor's own BrakeDemand frames, the replayed demands are
compared with the recorded ones; frames on the monitor's output IDs that are not the
recorded monitor's count as `foreign_output` (see `MonitorCore`). Every frame also goes to
the reference brake receiver (brake_receiver.py), as the brake controller on that bus would
have read it: where the log has BrakeDemand frames, `brake_receiver` gives the cycles it
would have held the brakes, by cause (a second sender on BrakeDemand, silence, ...).
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Iterator, Optional

from monitor.core import cycle as core

from .brake_receiver import BrakeReceiver
from .codec import BRAKE_DEMAND_ID, Receiver
from .logfile import LogError, LogFrame, read
from monitor.risk_summary import RiskTally

from .runner import CycleRecord, MonitorCore, TrackTally
from .security import UNSECURED, describe

ReplayError = LogError     # the CLI's name for a log that cannot be replayed
Decision = CycleRecord     # a replayed cycle is recorded exactly like a live one
ON_TIME_ERROR = ("split", "refuse")
DEFAULT_MAX_GAP_S = 60.0
LISTED = 20                # anomalies and segments listed by line; all are counted


@dataclass
class Segment:
    index: int
    first_line: int
    start_tick: int          # replay tick of its first cycle (ticks run on across segments)
    reason: str              # "start", "gap" or "backwards"


@dataclass
class ReplayStats:
    period_ms: int = 100
    frames: int = 0
    cycles: int = 0
    accepted: int = 0
    rejected: Counter = field(default_factory=Counter)
    filtered: int = 0
    kinds: Counter = field(default_factory=Counter)
    bus_events: Counter = field(default_factory=Counter)
    bus_state: str = "error_active"
    segments: list = field(default_factory=list)       # the first LISTED Segment objects
    segment_count: int = 0
    anomalies: list = field(default_factory=list)      # the first LISTED (line, kind, jump_s, action)
    anomaly_counts: Counter = field(default_factory=Counter)
    recorded_demands: int = 0
    agreeing: int = 0
    brake_side: Counter = field(default_factory=Counter)   # cycles the brake receiver braked, by cause
    brake_frames: int = 0                                  # BrakeDemand frames in the log
    bus_security: str = UNSECURED              # security.describe of the replay's bus
    track: TrackTally = field(init=False)      # the remembered obstacle, cycle by cycle
    risk: RiskTally = field(init=False)        # the papers' risk and the table's, cycle by cycle

    def __post_init__(self) -> None:
        self.track = TrackTally(self.period_ms)
        self.risk = RiskTally(self.period_ms)

    def absorb(self, mon: MonitorCore, brakes: BrakeReceiver) -> None:
        """Add a finished segment's counters (and its brake receiver's)."""
        self.brake_side.update(brakes.causes)
        self.accepted += mon.receiver.accepted
        self.rejected.update(mon.receiver.rejected)
        self.filtered += mon.tally.filtered
        self.kinds.update(mon.tally.kinds)
        self.bus_events.update(mon.tally.bus_events)
        if mon.tally.bus_events:
            self.bus_state = mon.tally.bus_state

    def as_dict(self) -> dict:
        out = {
            "frames": self.frames, "cycles": self.cycles, "accepted": self.accepted,
            "rejected": dict(sorted(self.rejected.items())), "filtered": self.filtered,
            "frame_kinds": dict(sorted(self.kinds.items())), "bus_state": self.bus_state,
            "bus_events": dict(sorted(self.bus_events.items())),
            "segments": self.segment_count,
            "segment_starts": [{"segment": s.index, "line": s.first_line, "tick": s.start_tick, "reason": s.reason}
                               for s in self.segments],
            "time_anomalies": dict(sorted(self.anomaly_counts.items())),
            "time_anomaly_lines": [{"line": ln, "kind": k, "jump_s": round(j, 6), "action": a}
                                   for ln, k, j, a in self.anomalies],
            "recorded_demands": self.recorded_demands,
            "track": self.track.as_dict(),
            "risk": self.risk.as_dict(),
        }
        if self.recorded_demands:
            out["agreement_with_recorded"] = self.agreeing / self.recorded_demands
        if self.brake_frames:
            out["brake_receiver"] = dict(sorted(self.brake_side.items()))
        out["bus_security"] = self.bus_security
        if self.bus_security == UNSECURED and self.rejected.get("fd_frame"):
            out["note"] = "the log holds CAN FD frames (a secured bus?): replay it with --keys DIR, the run's key set"
        return out


class Replay:
    """One replay of one log: iterate `run(frames)` for the decisions, then read `stats`."""

    def __init__(self, setup: core.Setup, *, max_gap_s: float = DEFAULT_MAX_GAP_S, on_time_error: str = "split",
                 source: str = "log", keys=None) -> None:
        if on_time_error not in ON_TIME_ERROR:
            raise ValueError(f"on_time_error must be one of {ON_TIME_ERROR}")
        if not max_gap_s > 0:
            raise ValueError("max_gap_s must be > 0")
        self.setup = setup
        self.period = setup.config.period_ms
        self.max_gap_s = max_gap_s
        self.on_time_error = on_time_error
        self.source = source
        self.keys = keys              # the key set of a secured log (None: unsecured, E2E only)
        self.stats = ReplayStats(self.period)
        self.stats.bus_security = describe(self._security("brakes"))
        self._recent: dict = {}      # tick -> demand of the last two cycles (agreement)
        self._brakes: tuple = self._brake_side_anew()   # the brake side (receiver, brake receiver), per segment
        self._pending: dict = {}     # tick -> recorded levels waiting for that cycle

    # ------------------------------------------------------------------ stream
    def run(self, frames: Iterable[LogFrame]) -> Iterator[CycleRecord]:
        st = self.stats
        mon: Optional[MonitorCore] = None
        tick = 0                     # next cycle's tick
        seg_t0 = seg_tick0 = 0
        last_ts = 0.0
        last_ftick = 0
        for f in frames:
            st.frames += 1
            ts = f.timestamp
            reason = None
            if mon is None:
                reason = "start"
            else:
                jump = ts - last_ts
                if abs(jump) > self.max_gap_s:
                    kind = "gap" if jump > 0 else "backwards"
                    self._anomaly(f.line, kind, jump, "new segment" if self.on_time_error == "split" else "refused")
                    if self.on_time_error == "refuse":
                        raise jump_error(self.source, f.line, jump, self.max_gap_s)
                    reason = kind
                elif jump < 0:
                    self._anomaly(f.line, "backwards", jump, "taken at the previous frame's time")
                    ts = last_ts
            if reason is not None:
                if mon is not None:
                    yield from self._cycles(mon, tick, last_ftick + self.period)
                    tick = (last_ftick + self.period) // self.period * self.period + self.period
                    st.absorb(mon, self._brakes[1])
                mon = MonitorCore(self.setup, recorded_outputs=True, security=self._security("monitor"))
                self._brakes = self._brake_side_anew()
                seg_t0, seg_tick0 = ts, tick
                st.segment_count += 1
                if len(st.segments) < LISTED:
                    st.segments.append(Segment(st.segment_count, f.line, tick, reason))
            ftick = max(last_ftick, seg_tick0 + round((ts - seg_t0) * 1000))
            yield from self._cycles(mon, tick, ftick - 1)
            if ftick > tick:
                tick = ftick + (-ftick) % self.period
            mon.ingest(f.msg, ftick)
            self._brake_side(f.msg, ftick)
            if mon.recorded_demands:
                for rec_tick, level in mon.recorded_demands:
                    self._recorded(rec_tick, level)
                mon.recorded_demands.clear()
            last_ts, last_ftick = ts, ftick
        if mon is None:
            raise LogError(f"{self.source}: no CAN frames in the file")
        yield from self._cycles(mon, tick, last_ftick + self.period)
        st.absorb(mon, self._brakes[1])

    def _security(self, node: str):
        """A fresh Security for a segment's node (freshness in memory: the log is its own session)."""
        if self.keys is None:
            return None
        from .keys import SENDERS
        from .security import for_node

        return for_node(self.keys, node, SENDERS if node == "monitor" else ("monitor",), state=False)

    def _brake_side_anew(self) -> tuple:
        return (Receiver(channels=self.setup.config.channels, security=self._security("brakes")),
                BrakeReceiver(self.period))

    def _brake_side(self, msg, tick: int) -> None:
        """The frame as the brake controller's receiver reads it (every frame on the bus)."""
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        self._brakes[0].accept(msg.arbitration_id, msg.data, tick)
        self.stats.brake_frames += msg.arbitration_id == BRAKE_DEMAND_ID

    def _cycles(self, mon: MonitorCore, first: int, last: int) -> Iterator[CycleRecord]:
        """Cycles at first, first + period, ... up to `last` included."""
        rx, brakes = self._brakes
        for tick in range(first, last + 1, self.period):
            brakes.level(rx, tick, 1.0 if rx.train is None else rx.train.speed_cms / 100)   # counts its causes
            _, rec = mon.decide(tick)
            self.stats.cycles += 1
            self.stats.track.add(rec)
            self.stats.risk.add(rec)
            self._decided(tick, rec.demand)
            yield rec

    # ------------------------------------------------------------------ bookkeeping
    def _anomaly(self, line: int, kind: str, jump: float, action: str) -> None:
        self.stats.anomaly_counts[kind] += 1
        if len(self.stats.anomalies) < LISTED:
            self.stats.anomalies.append((line, kind, jump, action))

    def _recorded(self, tick: int, level: int) -> None:
        """A recorded demand sent after the cycle at tick T is compared with our decision at T."""
        self.stats.recorded_demands += 1
        at = tick - tick % self.period
        if at in self._recent:
            self.stats.agreeing += int(self._recent[at] == level)
        else:
            self._pending.setdefault(at, []).append(level)

    def _decided(self, tick: int, demand: int) -> None:
        self._recent[tick] = demand
        self._recent.pop(tick - 2 * self.period, None)
        for level in self._pending.pop(tick, ()):
            self.stats.agreeing += int(level == demand)
        if len(self._pending) > 64:                      # recorded frames far ahead of any cycle
            for at in sorted(self._pending)[:-64]:
                del self._pending[at]


def jump_error(source: str, line: int, jump: float, max_gap_s: float) -> LogError:
    return LogError(f"{source}:{line}: timestamp jumps {jump:+.6f} s, more than the {max_gap_s:g} s allowed "
                    f"(--max-gap); --on-time-error split replays the log in segments")


def check(path: str | Path, *, max_gap_s: float = DEFAULT_MAX_GAP_S, on_time_error: str = "split") -> int:
    """Read the whole log once without replaying it (constant memory): raise the LogError a
    replay would raise (bad line, no frames, a refused jump) before any output; return the
    number of frames."""
    n = 0
    last = None
    for f in read(path):
        n += 1
        if on_time_error == "refuse" and last is not None and abs(f.timestamp - last) > max_gap_s:
            raise jump_error(str(path), f.line, f.timestamp - last, max_gap_s)
        last = f.timestamp
    if n == 0:
        raise LogError(f"{path}: no CAN frames in the file")
    return n


class Thinned:
    """At most `limit` evenly spaced cycles of a stream of any length, for a plot: when full,
    every other point is dropped and the stride doubles (constant memory)."""

    def __init__(self, limit: int = 20000) -> None:
        self.limit = limit
        self.stride = 1
        self.seen = 0
        self.points: list = []

    def add(self, item) -> None:
        if self.seen % self.stride == 0:
            self.points.append(item)
            if len(self.points) >= self.limit:
                self.points = self.points[::2]
                self.stride *= 2
        self.seen += 1


def replay_file(setup: core.Setup, path: str | Path, **options) -> tuple[list[CycleRecord], dict]:
    """Every decision of a (short) log in a list, and the stats: for tests and small tools."""
    rp = Replay(setup, source=str(path), **options)
    decisions = list(rp.run(read(path)))
    return decisions, rp.stats.as_dict()
