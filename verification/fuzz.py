"""Bad input through the front door: Hypothesis-driven fuzzing of the CAN receive path.

What runs is the real shell: `can_bus.runner.MonitorRunner` on an in-memory python-can bus
with the simulated clock. Each frame is put on the bus at its arrival time and the runner's
own `drain()` takes it (`MonitorCore.ingest`: kind tally, receive filter, FD/remote/error
refusal, foreign frames on the output IDs, then `Receiver.accept` with per-ID rate policing,
the E2E CRC, alive counter, range checks; the rate window is one period, as the runner sets
it); at every period boundary the runner's own `cycle()` steps the core
(`monitor.core.cycle.step`) with the latched reports, returns its CycleRecord and sends its
two frames.

What goes in: one Hypothesis example is one stream. Hypothesis draws the shipped table
(m1, m2), the topology (3oo3, 2oo2), a traffic profile and an 8 KB byte string; the byte
string is read as a program whose instructions make frames and move time (`Traffic`):
  * nominal cycles: every channel and the TrainState, consistent, with persistent faults
    (2oo2 disagreement, a distance offset, a silent or degraded channel, a silent or bad train);
  * valid frames of every DBC message, encoded by the codec (`codec.Sender`: CRC and counter),
    the monitor's own output IDs 0x010/0x040 among them (foreign frames);
  * mutated valid frames: bit flips, byte changes, truncation, extension up to 64 bytes,
    counter replay and jump, payload replacement, IDs swapped (DBC, 11-bit, 29-bit), the
    extended/remote/error/FD flags, then the CRC recomputed or not;
  * fully random frames: 11-bit, 29-bit and out-of-spec IDs, remote and error frames, FD,
    lengths 0..64, a DLC that disagrees with the data;
  * hostile frames the shell refuses or drops: CAN FD frames (valid payloads too), remote
    requests and controller error frames (warning, passive, bus-off, restart) on the
    monitored IDs, frames on the output IDs 0x010/0x040, 29-bit and unmonitored 11-bit
    neighbours of the monitored IDs;
  * signals out of their DBC range with a valid CRC and counter (module/channel mismatch too);
  * babbling bursts (4..23 frames of one sender, 0..39 ms apart; valid, with bad CRC or wrong
    length, or interleaved with FD/remote frames on the same ID), replays of earlier frames,
    small time steps, explicit cycles and silences of up to 40 periods.

What is checked, after every frame and every cycle:
  * no exception escapes the runner (`drain`, `cycle`); an exception swallowed inside the
    core's fail-safe (`step` returning its SAFE_STOP fallback) counts as one too;
  * accounting: each frame moves exactly one counter by exactly one (accepted, one reject
    reason, or `filtered`) and the kind tally by one, the runner counts it as received, and
    per stream frames received = accepted + sum of rejected by reason + filtered;
  * the reason: a reference receiver written here from the DBC and the documented rules
    (own classification, own receive filter, own CRC-8 0x2F, own bit unpacking, the rate
    window and quarantine) predicts the outcome of every frame, the frame's kind, the bus
    state error frames announce, the latched reports and TrainState; the runner must agree;
  * every cycle: the CycleRecord it returns agrees with `runner.outputs` and with the
    reference (the TrainState speed it used, the ForeignOutput diagnostic), and the
    BrakeDemand and MonitorStatus frames it sent carry a valid CRC, the demand and the
    ForeignOutput bit;
  * domains: every latched report is absent or (status 0..2, distance 0..60000 dm, closing
    -15000..15000 cm/s, obstacle 0..2, integer tick <= now), the TrainState is absent or in
    range; the core's State (mode 0..3, node < table nodes, seen within the channel mask,
    disagree/healthy/error counts >= 0, cycle +1 per cycle) and Outputs (demand 0..2, reasons
    < 8192, distance 0..60000 or 65535, observation < table observations, module flags,
    node/mode/cycle equal to the state's) and the documented mode rules (INIT, SAFE_STOP and
    the latch demand emergency).
A stream stops at its first exception or violation, so a fault is counted once and does
not cascade; the report keeps the first few with the frame's bytes.

`run(frames, progress, seed)` returns the figures; `section(out_dir, quick, progress)` is
the verification part (quick: 20,000 frames in one process; full: 1,000,000 frames over two
processes).
"""
from __future__ import annotations

import math
import os
import time
import traceback
import random
from collections import Counter, deque
from functools import lru_cache
from pathlib import Path
from typing import Optional

import can

from can_bus import codec
from can_bus.clock import SimClock
from can_bus.runner import MonitorRunner
from monitor import tables
from monitor.core import cycle as core
from monitor.core.config import Config
from monitor.core.types import (
    EMERGENCY, INIT, MAX_COUNT, NO_DISTANCE, R_INIT, R_LATCH, R_SAFE_STOP, R_SYSTEM_ERROR, SAFE_STOP, Inputs,
    Report, Train,
)

from .report import Check, Progress, Section, md_table

QUICK_FRAMES = 20_000
FULL_FRAMES = 1_000_000
TAPE_BYTES = 7900            # one Hypothesis example: this many bytes of traffic program
STREAM_FRAMES = 2500         # and at most this many frames (many varied streams rather than a few long ones)
CHUNK_FRAMES = 50_000        # frames per worker job
MAX_EXAMPLES_KEPT = 8        # violation/exception records kept in the result
MAX_FAULTS = 50              # a worker job stops after this many faults (the verdict is FAIL anyway)

ACCEPTED = "accepted"
FILTERED = "filtered"        # outside the receive filter: never seen live, not a reject

# ----------------------------------------------------------------------------- the DBC, read independently
# Frame IDs and signal layouts as railguard.dbc gives them, in raw units: (name, start bit,
# length, signed, raw minimum, raw maximum); all signals are little-endian (Intel, @1).
BRAKE_DEMAND = 0x10
OBSTACLES = tuple(range(0x20, 0x26))
TRAIN_STATE = 0x30
MONITOR_STATUS = 0x40
INPUTS = frozenset(OBSTACLES) | {TRAIN_STATE}
_E2E = (("Crc", 0, 8, False, 0, 255), ("Counter", 8, 4, False, 0, 15))
_OBSTACLE = _E2E + (("Status", 12, 2, False, 0, 2), ("ObstacleType", 14, 2, False, 0, 2),
                    ("Distance", 16, 16, False, 0, 60000),        # [0|6000] m at 0.1 m
                    ("ClosingSpeed", 32, 16, True, -15000, 15000),  # [-150|150] m/s at 0.01 m/s
                    ("Module", 48, 2, False, 0, 2), ("Channel", 50, 1, False, 0, 1))
LAYOUT = {
    BRAKE_DEMAND: _E2E + (("Level", 12, 2, False, 0, 2), ("Warning", 14, 1, False, 0, 1), ("Reason", 16, 16, False, 0, 8191),
                          ("Cycle", 32, 32, False, 0, 2**32 - 1)),
    **{fid: _OBSTACLE for fid in OBSTACLES},
    TRAIN_STATE: _E2E + (("TrackCondition", 12, 1, False, 0, 1), ("BrakeStatus", 13, 1, False, 0, 1),
                         ("Speed", 16, 16, False, 0, 12000)),    # [0|120] m/s at 0.01 m/s
    MONITOR_STATUS: _E2E + (("Mode", 12, 2, False, 0, 3), ("Warning", 14, 1, False, 0, 1),
                            ("ForeignOutput", 15, 1, False, 0, 1), ("Node", 16, 10, False, 0, 1023),
                            ("ErrorFlags", 26, 6, False, 0, 63), ("VotedDistance", 32, 16, False, 0, 65535),
                            ("TableHash", 48, 12, False, 0, 4095), ("DeadlineMisses", 60, 4, False, 0, 15)),
}
DBC_IDS = tuple(sorted(LAYOUT))

# ----------------------------------------------------------------------------- the rules, read independently
# The receive filter (standard frames on these IDs, and every error frame), the monitor's own
# output IDs (live, never received from itself: any frame there is foreign), and the
# ForeignOutput hold: set in every cycle within FOREIGN_HOLD_CYCLES periods of the last
# foreign frame ("within the last second", the DBC's comment on MonitorStatus.ForeignOutput).
MONITORED = frozenset((BRAKE_DEMAND, *OBSTACLES, TRAIN_STATE, MONITOR_STATUS))
OUTPUTS = (BRAKE_DEMAND, MONITOR_STATUS)
FOREIGN_HOLD_CYCLES = 10
KINDS = ("classical", "extended", "fd", "remote", "error")
SHELL_REASON = {"fd": "fd_frame", "remote": "remote_frame", "error": "error_frame"}
# linux/can/error.h: error class in the identifier, controller status in data[1]
CAN_ERR_FLAG = 0x20000000
ERR_CRTL, ERR_BUSOFF, ERR_RESTARTED = 0x004, 0x040, 0x100
CTRL_WARNING, CTRL_PASSIVE, CTRL_ACTIVE = 0x04 | 0x08, 0x10 | 0x20, 0x40
BUS_STATES = ("error_active", "error_warning", "error_passive", "bus_off")


def _crc_table() -> tuple:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ 0x2F) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


_CRC = _crc_table()


def crc8_h2f(data: bytes) -> int:
    """CRC-8 with polynomial 0x2F, start 0xFF, final XOR 0xFF, not reflected (AUTOSAR CRC8H2F)."""
    c = 0xFF
    for b in data:
        c = _CRC[c ^ b]
    return c ^ 0xFF


def e2e_crc(data: bytes, frame_id: int) -> int:
    """The E2E profile 2 CRC of a frame: over bytes 1..7 and then the data ID (the frame ID's low byte)."""
    return crc8_h2f(bytes(data[1:8]) + bytes((frame_id & 0xFF,)))


def unpack(frame_id: int, data: bytes) -> dict:
    """Raw signal values of an 8-byte frame of a DBC message."""
    word = int.from_bytes(data, "little")
    out = {}
    for name, start, length, signed, _, _ in LAYOUT[frame_id]:
        v = (word >> start) & ((1 << length) - 1)
        if signed and v >> (length - 1):
            v -= 1 << length
        out[name] = v
    return out


def in_dbc_range(frame_id: int, values: dict) -> bool:
    return all(lo <= values[name] <= hi for name, _, _, _, lo, hi in LAYOUT[frame_id])


def frame_kind(msg: can.Message) -> str:
    """The kind of a frame from its flags: error before remote before FD before 29-bit."""
    if msg.is_error_frame:
        return "error"
    if msg.is_remote_frame:
        return "remote"
    if msg.is_fd:
        return "fd"
    return "extended" if msg.is_extended_id else "classical"


def announced_state(msg: can.Message) -> Optional[str]:
    """The controller state an error frame announces (the worst one it names), or None."""
    cls = msg.arbitration_id & ~CAN_ERR_FLAG & 0x1FFFFFFF
    data = bytes(msg.data)
    ctrl = data[1] if cls & ERR_CRTL and len(data) >= 2 else 0
    if cls & ERR_BUSOFF:
        return "bus_off"
    if ctrl & CTRL_PASSIVE:
        return "error_passive"
    if ctrl & CTRL_WARNING:
        return "error_warning"
    if cls & ERR_RESTARTED or ctrl & CTRL_ACTIVE:
        return "error_active"
    return None


class ReferenceReceiver:
    """What the receive path must do with each frame, from the DBC and the documented rules
    (issue 13; can_bus/frames.py, runner.py and codec.py docstrings), written independently
    of the codec and the runner. In order, for each frame:

    1. its kind: error, remote, FD, 29-bit or classical (error frames also announce a bus state);
    2. not an error frame and 29-bit, or an ID outside 0x010, 0x020-0x025, 0x030, 0x040 ->
       `filtered` (the receive filter drops it: not a reject);
    3. an error, remote or FD frame -> error_frame, remote_frame, fd_frame;
    4. on the output IDs 0x010 or 0x040 -> foreign_output; ForeignOutput is set in every cycle
       within FOREIGN_HOLD_CYCLES periods of it;
    5. an ID not in the DBC -> unknown_id; on an input ID (obstacle channels, TrainState) every
       frame counts for the rate, valid or not, before length and CRC: more than
       MAX_FRAMES_PER_WINDOW frames within the window (one period) quarantines the ID until
       BABBLE_QUARANTINE_MS after its last excess frame; while quarantined -> rate_exceeded,
       the channel's report withdrawn and the ID's alive counter forgotten (the next frame
       that passes the CRC resynchronises without a counter check); then not 8 bytes ->
       wrong_length; CRC -> bad_crc; the alive counter is remembered from here on whatever
       follows; equal to the last -> repeated_counter, not last + 1 -> counter_jump; a signal
       outside its DBC range, or a report claiming another (or a missing) channel ->
       out_of_range; otherwise accepted and latched with the arrival tick.
    """

    def __init__(self, channels: int, window_ms: int) -> None:
        self.channels = channels
        self.window = window_ms
        self.reports: list = [None] * channels
        self.train: Optional[Train] = None
        self.train_tick: Optional[int] = None
        self.counter: dict = {}
        self.times: dict = {}
        self.quarantine_until: dict = {}
        self.foreign_tick: Optional[int] = None
        self.bus_state = "error_active"
        self.bus_events: Counter = Counter()

    def expect(self, msg: can.Message, now: int) -> tuple:
        """(kind, outcome) of one frame arriving at tick `now`; the outcome is ACCEPTED,
        FILTERED or the reject reason."""
        kind = frame_kind(msg)
        if kind == "error":
            state = announced_state(msg)
            if state is not None:
                self.bus_state = state
                self.bus_events[state] += 1
        elif msg.is_extended_id or msg.arbitration_id not in MONITORED:
            return kind, FILTERED
        if kind != "classical":
            return kind, SHELL_REASON[kind]
        fid = msg.arbitration_id
        if fid in OUTPUTS:
            self.foreign_tick = now
            return kind, "foreign_output"
        return kind, self.check(fid, bytes(msg.data), now)

    def check(self, fid: int, data: bytes, now: int) -> str:
        """Rule 5, a classical frame on a monitored input ID."""
        if fid not in LAYOUT:
            return "unknown_id"
        if self.window > 0 and fid in INPUTS:
            times = [t for t in self.times.get(fid, ()) if now - t < self.window]
            times.append(now)
            self.times[fid] = times
            if len(times) > codec.MAX_FRAMES_PER_WINDOW:
                self.quarantine_until[fid] = now + codec.BABBLE_QUARANTINE_MS
            if now < self.quarantine_until.get(fid, now):
                ch = fid - OBSTACLES[0]
                if fid in OBSTACLES and ch < self.channels:
                    self.reports[ch] = None
                self.counter[fid] = None
                return "rate_exceeded"
        if len(data) != 8:
            return "wrong_length"
        if e2e_crc(data, fid) != data[0]:
            return "bad_crc"
        counter = data[1] & 0xF
        last = self.counter.get(fid)
        self.counter[fid] = counter
        if last is not None:
            step = (counter - last) & 0xF
            if step == 0:
                return "repeated_counter"
            if step != 1:
                return "counter_jump"
        v = unpack(fid, data)
        if not in_dbc_range(fid, v):
            return "out_of_range"
        if fid in OBSTACLES:
            ch = fid - OBSTACLES[0]
            if ch >= self.channels or v["Module"] != ch // 2 or v["Channel"] != ch % 2:
                return "out_of_range"
            self.reports[ch] = Report(v["Status"], v["Distance"], v["ClosingSpeed"], v["ObstacleType"], now)
        elif fid == TRAIN_STATE:
            self.train = Train(v["Speed"], v["TrackCondition"], v["BrakeStatus"])
            self.train_tick = now
        return ACCEPTED

    def foreign(self, tick: int, period: int) -> bool:
        """Must the cycle at `tick` set the ForeignOutput diagnostic?"""
        return self.foreign_tick is not None and tick - self.foreign_tick <= FOREIGN_HOLD_CYCLES * period


# ----------------------------------------------------------------------------- results
class Stats:
    """Figures of one or more streams; `merge` adds another's `as_dict()`."""

    def __init__(self) -> None:
        self.frames = 0
        self.accepted = 0                 # the receiver's own count
        self.rejected: Counter = Counter()  # the receiver's own counts by reason
        self.filtered = 0                   # the runner's count of frames outside the receive filter
        self.frame_kinds: Counter = Counter()  # the runner's tally of frames by kind
        self.bus_states: Counter = Counter()   # bus states announced by error frames (the runner's tally)
        self.foreign_ids: Counter = Counter()  # foreign_output frames by ID
        self.foreign_cycles = 0                # cycles with the ForeignOutput diagnostic set
        self.expected: Counter = Counter()  # the reference receiver's outcomes
        self.kinds: Counter = Counter()     # frames by generator kind
        self.accepted_ids: Counter = Counter()
        self.exceptions = 0
        self.harness_errors = 0
        self.violations: Counter = Counter()
        self.accounting_errors = 0
        self.examples: list = []
        self.streams = 0
        self.stream_kinds: Counter = Counter()   # streams by "table/topology/profile"
        self.cycles = 0
        self.modes: Counter = Counter()
        self.demands: Counter = Counter()
        self.seconds = 0.0

    def faults(self) -> int:
        return self.exceptions + self.harness_errors + sum(self.violations.values())

    def record(self, kind: str, detail: dict) -> None:
        if len(self.examples) < MAX_EXAMPLES_KEPT:
            self.examples.append(dict(kind=kind, **detail))

    def as_dict(self) -> dict:
        return {
            "frames": self.frames, "accepted": self.accepted, "rejected": dict(self.rejected),
            "filtered": self.filtered, "frame_kinds": dict(self.frame_kinds), "bus_states": dict(self.bus_states),
            "foreign_ids": {f"0x{k:02X}": v for k, v in sorted(self.foreign_ids.items())},
            "foreign_cycles": self.foreign_cycles,
            "expected": dict(self.expected), "kinds": dict(self.kinds),
            "accepted_ids": {f"0x{k:02X}": v for k, v in sorted(self.accepted_ids.items())},
            "exceptions": self.exceptions, "harness_errors": self.harness_errors,
            "violations": sum(self.violations.values()), "violations_by_kind": dict(self.violations),
            "accounting_errors": self.accounting_errors, "examples": list(self.examples),
            "streams": self.streams, "stream_kinds": dict(self.stream_kinds), "cycles": self.cycles,
            "modes": dict(self.modes),
            "demands": dict(self.demands), "seconds": self.seconds,
        }

    def merge(self, d: dict) -> None:
        self.frames += d["frames"]
        self.accepted += d["accepted"]
        self.rejected.update(d["rejected"])
        self.filtered += d["filtered"]
        self.frame_kinds.update(d["frame_kinds"])
        self.bus_states.update(d["bus_states"])
        self.foreign_ids.update({int(k, 16): v for k, v in d["foreign_ids"].items()})
        self.foreign_cycles += d["foreign_cycles"]
        self.expected.update(d["expected"])
        self.kinds.update(d["kinds"])
        self.accepted_ids.update({int(k, 16): v for k, v in d["accepted_ids"].items()})
        self.exceptions += d["exceptions"]
        self.harness_errors += d["harness_errors"]
        self.violations.update(d["violations_by_kind"])
        self.accounting_errors += d["accounting_errors"]
        for e in d["examples"]:
            if len(self.examples) < MAX_EXAMPLES_KEPT:
                self.examples.append(e)
        self.streams += d["streams"]
        self.stream_kinds.update(d["stream_kinds"])
        self.cycles += d["cycles"]
        self.modes.update(d["modes"])
        self.demands.update(d["demands"])


def describe(msg: can.Message) -> dict:
    """A frame as the report shows it: enough to put it on a bus again."""
    return {"id": f"0x{msg.arbitration_id:X}", "extended": bool(msg.is_extended_id),
            "remote": bool(msg.is_remote_frame), "error": bool(msg.is_error_frame), "fd": bool(msg.is_fd),
            "dlc": msg.dlc, "data": bytes(msg.data).hex()}


# ----------------------------------------------------------------------------- the harness
class StreamStop(Exception):
    """End of a stream: tape used up, frame budget reached, or a fault recorded."""


class FrontDoorBus(can.BusABC):
    """An in-memory python-can bus: the harness puts a frame on it, the runner's drain() takes it."""

    def __init__(self) -> None:
        super().__init__(channel="railguard-fuzz")
        self.channel_info = "railguard fuzz front door"
        self.pending: deque = deque()
        self.sent = 0
        self.last_sent: dict = {}     # frame ID -> the newest frame the runner sent on it

    def _recv_internal(self, timeout):
        return (self.pending.popleft() if self.pending else None), True

    def send(self, msg, timeout=None) -> None:
        self.sent += 1
        self.last_sent[msg.arbitration_id] = msg


@lru_cache(maxsize=None)
def setup_for(table: str, topology: str) -> core.Setup:
    return core.create(Config(topology=topology), tables.read(table))


_FALLBACK_REASONS = R_SAFE_STOP | R_SYSTEM_ERROR | R_LATCH


class Harness:
    """The real runner on the in-memory bus, the reference receiver beside it, and the checks.

    `feed(t, msg, kind)` puts one frame on the bus at time t (running every cycle whose tick
    is before t first), lets the runner drain it and checks; `cycle()` runs the next cycle
    and checks. Both raise StreamStop after recording an exception or a violation.
    """

    def __init__(self, setup: core.Setup, stats: Stats, budget: Optional[int] = None, label: Optional[dict] = None):
        self.setup = setup
        self.stats = stats
        self.budget = budget
        self.label = label or {}
        self.clock = SimClock()
        self.bus = FrontDoorBus()
        self.runner = MonitorRunner(self.bus, setup, self.clock)
        self.rx = self.runner.receiver
        self.tally = self.runner.monitor.tally
        cfg = setup.config
        self.channels = cfg.channels
        self.modules = cfg.modules
        self.period = cfg.period_ms
        self.model = ReferenceReceiver(cfg.channels, cfg.period_ms)
        self.n_nodes = setup.table.nodes
        self.n_obs = len(setup.table.observations)
        self.all_seen = (1 << cfg.channels) - 1
        self.shadow: Counter = Counter()    # the receiver's reject counts as of the last frame
        self.shadow_total = 0
        self.shadow_kinds: Counter = Counter()   # the runner's kind tally as of the last frame
        self.filtered = 0                   # frames the reference expected to be filtered
        self.frames = 0
        self.cycles = 0
        self.failed = False
        self._checked: list = [None] * cfg.channels   # report objects already found in their domain

    # ------------------------------------------------------------------ faults
    def _fault(self, kind: str, what: str, msg: Optional[can.Message] = None, **extra) -> None:
        self.failed = True
        if kind == "exception":
            self.stats.exceptions += 1
        else:
            self.stats.violations[kind] += 1
        detail = dict(self.label, what=what, frame_index=self.frames, cycle_index=self.cycles,
                      now_ms=self.clock.now_ms(), **extra)
        if msg is not None:
            detail["frame"] = describe(msg)
        self.stats.record(kind, detail)
        raise StreamStop

    # ------------------------------------------------------------------ frames
    def feed(self, t: int, msg: can.Message, kind: str) -> str:
        if self.failed or (self.budget is not None and self.frames >= self.budget):
            raise StreamStop
        runner = self.runner
        while runner.next_tick < t:
            self.cycle()
        self.clock.sleep_until_ms(t)
        now = self.clock.now_ms()
        # the runner stamps a frame no later than the next tick, nor than its bus timestamp
        # says (the simulated clock has none: None)
        tick = min(now, runner.next_tick)
        stamped = self.clock.tick_of_stamp(msg.timestamp)
        if stamped is not None:
            tick = min(tick, stamped)
        frame_kind_, expected = self.model.expect(msg, tick)
        rx, tally = self.rx, self.tally
        accepted0, received0, filtered0 = rx.accepted, runner.frames_received, tally.filtered
        self.bus.pending.append(msg)
        self.frames += 1
        self.stats.frames += 1
        self.stats.kinds[kind] += 1
        self.stats.expected[expected] += 1
        try:
            runner.drain()
        except Exception as exc:  # noqa: BLE001 - what the fuzzing is looking for
            self._fault("exception", f"runner.drain raised {type(exc).__name__}: {exc}", msg,
                        traceback=traceback.format_exc(limit=-3), expected=expected)
        # accounting: exactly one counter moved, by exactly one
        rejected = rx.rejected
        total = sum(rejected.values())
        if expected == ACCEPTED:
            ok = rx.accepted == accepted0 + 1 and total == self.shadow_total and tally.filtered == filtered0
        elif expected == FILTERED:
            ok = rx.accepted == accepted0 and total == self.shadow_total and tally.filtered == filtered0 + 1
        else:
            ok = (rx.accepted == accepted0 and total == self.shadow_total + 1 and tally.filtered == filtered0
                  and rejected[expected] == self.shadow[expected] + 1)
        ok = ok and runner.frames_received == received0 + 1 and not self.bus.pending
        if not ok:
            moved = {k: v - self.shadow[k] for k, v in rejected.items() if v != self.shadow[k]}
            if rx.accepted != accepted0:
                moved[ACCEPTED] = rx.accepted - accepted0
            if tally.filtered != filtered0:
                moved[FILTERED] = tally.filtered - filtered0
            counted = sum(moved.values())
            kind_ = "reason" if counted == 1 and runner.frames_received == received0 + 1 else "accounting"
            if kind_ == "accounting":
                self.stats.accounting_errors += 1
            self._fault(kind_, f"expected {expected}, counters moved {moved or 'none'}"
                        f" (frames_received +{runner.frames_received - received0})", msg,
                        expected=expected, moved=moved)
        if expected == ACCEPTED:
            self.stats.accepted_ids[msg.arbitration_id] += 1
        elif expected == FILTERED:
            self.filtered += 1
        else:
            self.shadow[expected] += 1
            self.shadow_total += 1
            if expected == "foreign_output":
                self.stats.foreign_ids[msg.arbitration_id] += 1
        # the kind tally: one more of this frame's kind, nothing else
        kinds, shadow_kinds = tally.kinds, self.shadow_kinds
        if kinds[frame_kind_] != shadow_kinds[frame_kind_] + 1 or sum(kinds.values()) != sum(shadow_kinds.values()) + 1:
            moved = {k: kinds[k] - shadow_kinds[k] for k in set(kinds) | set(shadow_kinds)
                     if kinds[k] != shadow_kinds[k]}
            self._fault("kind", f"a {frame_kind_} frame, the kind tally moved {moved or 'none'}", msg,
                        expected=expected)
        shadow_kinds[frame_kind_] += 1
        if frame_kind_ == "error" and (tally.bus_state != self.model.bus_state
                                       or tally.bus_events != self.model.bus_events):
            self._fault("bus_state", f"bus state {tally.bus_state} {dict(tally.bus_events)}, reference "
                        f"{self.model.bus_state} {dict(self.model.bus_events)}", msg, expected=expected)
        # what is latched: within its domain, and what the reference receiver latched
        problem = self._latched_problem(now)
        if problem:
            self._fault("domain", problem, msg, expected=expected)
        if rx.reports != self.model.reports or rx.train != self.model.train or rx.train_tick != self.model.train_tick:
            self._fault("latched", "latched reports/train differ from the reference receiver's", msg,
                        expected=expected, receiver=repr((rx.reports, rx.train, rx.train_tick)),
                        reference=repr((self.model.reports, self.model.train, self.model.train_tick)))
        return expected

    def _latched_problem(self, now: int) -> str:
        reports = self.rx.reports
        if len(reports) != self.channels:
            return f"{len(reports)} report slots for {self.channels} channels"
        checked = self._checked
        for i, r in enumerate(reports):
            if r is None or r is checked[i]:     # absent, or the same object found in its domain before
                continue
            if not (type(r) is Report and all(type(x) is int for x in r)):
                return f"channel {i}: latched {r!r} is not a Report of integers"
            if not (0 <= r.status <= 2 and 0 <= r.distance_dm <= 60000 and -15000 <= r.closing_cms <= 15000
                    and 0 <= r.obstacle <= 2 and 0 <= r.tick <= now):
                return f"channel {i}: latched {r!r} outside its domain (now {now})"
            checked[i] = r
        tr = self.rx.train
        if tr is not None:
            if not (type(tr) is Train and all(type(x) is int for x in tr)
                    and 0 <= tr.speed_cms <= 12000 and tr.track in (0, 1) and tr.brake in (0, 1)):
                return f"train: latched {tr!r} outside its domain"
            if not (type(self.rx.train_tick) is int and 0 <= self.rx.train_tick <= now):
                return f"train tick {self.rx.train_tick!r} outside 0..now ({now})"
        return ""

    # ------------------------------------------------------------------ cycles
    def cycle(self):
        runner, rx = self.runner, self.rx
        if self.failed:
            raise StreamStop
        tick = runner.next_tick
        self.clock.sleep_until_ms(tick)
        before, overruns = runner.state, runner.overruns
        counts = (rx.accepted, sum(rx.rejected.values()), runner.frames_received, self.tally.filtered)
        sent0 = self.bus.sent
        try:
            rec = runner.cycle()
        except Exception as exc:  # noqa: BLE001
            self._fault("exception", f"runner.cycle raised {type(exc).__name__}: {exc}",
                        traceback=traceback.format_exc(limit=-3), tick=tick)
        self.cycles += 1
        state, out = runner.state, runner.outputs
        if out.mode == SAFE_STOP and out.reasons == _FALLBACK_REASONS and out.distance_dm == NO_DISTANCE \
                and out.module_flags == 0 and out.observation == 0:
            # the shape of step()'s fail-safe result: did the cycle raise inside?
            train = rx.train if rx.train_tick is not None and tick - rx.train_tick <= self.setup.timeout_ticks else None
            try:
                core._step(self.setup, before, Inputs(tuple(rx.reports), train, overruns), tick)
            except Exception as exc:  # noqa: BLE001
                self._fault("exception", f"core step raised inside (caught by its fail-safe) "
                            f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc(limit=-3), tick=tick)
        if (rx.accepted, sum(rx.rejected.values()), runner.frames_received, self.tally.filtered) != counts:
            self.stats.accounting_errors += 1
            self._fault("accounting", "a cycle changed the frame counters", tick=tick)
        problem = self._latched_problem(tick) or self._core_problem(before, state, out)
        if problem:
            self._fault("domain", problem, tick=tick, state=repr(state), outputs=repr(out))
        foreign = self.model.foreign(tick, self.period)
        problem = self._record_problem(tick, rec, out, foreign) or self._sent_problem(sent0, out, foreign)
        if problem:
            self._fault("cycle", problem, tick=tick, record=repr(rec), outputs=repr(out))
        self.stats.cycles += 1
        self.stats.modes[state.mode] += 1
        self.stats.demands[out.demand] += 1
        self.stats.foreign_cycles += foreign
        return out

    def _record_problem(self, tick: int, rec, out, foreign: bool) -> str:
        """The CycleRecord `cycle()` returned: the cycle's outputs, the TrainState speed the
        core was given (none once older than the timeout) and the ForeignOutput diagnostic."""
        if rec is None or rec is not (self.runner.records[-1] if self.runner.records else None):
            return f"cycle() returned {rec!r}, not the cycle's record"
        if rec.tick != tick:
            return f"record tick {rec.tick!r} for the cycle at {tick}"
        if (rec.demand, rec.reasons, rec.mode, rec.node, rec.distance_dm, rec.module_flags, rec.system_error,
                rec.warning) != (out.demand, out.reasons, out.mode, out.node, out.distance_dm, out.module_flags,
                                 out.system_error, out.warning):
            return "the record disagrees with runner.outputs"
        m = self.model
        fresh = m.train is not None and tick - m.train_tick <= self.setup.timeout_ticks
        speed = m.train.speed_cms if fresh else None
        if rec.speed_cms != speed:
            return f"record speed {rec.speed_cms!r}, the reference's fresh TrainState gives {speed!r}"
        if rec.foreign_output is not foreign:
            return (f"ForeignOutput {rec.foreign_output!r}, reference {foreign} "
                    f"(last foreign frame at {m.foreign_tick}, cycle at {tick})")
        return ""

    def _sent_problem(self, sent0: int, out, foreign: bool) -> str:
        """The two frames the cycle sent, read with the reference's own CRC and unpacking."""
        bus = self.bus
        if bus.sent != sent0 + 2:
            return f"the cycle sent {bus.sent - sent0} frames, not BrakeDemand and MonitorStatus"
        demand, status = bus.last_sent.get(BRAKE_DEMAND), bus.last_sent.get(MONITOR_STATUS)
        if demand is None or status is None:
            return "no BrakeDemand or no MonitorStatus sent"
        for fid, m in ((BRAKE_DEMAND, demand), (MONITOR_STATUS, status)):
            data = bytes(m.data)
            if m.is_extended_id or len(data) != 8 or e2e_crc(data, fid) != data[0]:
                return f"sent frame 0x{fid:02X} {data.hex()} is not a valid 8-byte E2E frame"
        d, st = unpack(BRAKE_DEMAND, bytes(demand.data)), unpack(MONITOR_STATUS, bytes(status.data))
        if d["Level"] != out.demand or st["Mode"] != out.mode:
            return f"sent Level {d['Level']} / Mode {st['Mode']} for demand {out.demand} / mode {out.mode}"
        if st["ForeignOutput"] != foreign:
            return f"sent ForeignOutput {st['ForeignOutput']}, reference {int(foreign)}"
        return ""

    def _core_problem(self, before, s, out) -> str:
        if not (type(s.mode) is int and 0 <= s.mode <= 3):
            return f"mode {s.mode!r}"
        if not (type(s.node) is int and 0 <= s.node < self.n_nodes):
            return f"node {s.node!r} not < {self.n_nodes}"
        if type(s.latched) is not bool:
            return f"latched {s.latched!r}"
        if not (type(s.seen) is int and 0 <= s.seen <= self.all_seen and s.seen & before.seen == before.seen):
            return f"seen {s.seen!r} (before {before.seen!r})"
        if not (type(s.disagree) is tuple and len(s.disagree) == self.modules
                and all(type(d) is int and 0 <= d <= MAX_COUNT for d in s.disagree)):
            return f"disagree {s.disagree!r}"
        if not (type(s.healthy) is int and 0 <= s.healthy <= MAX_COUNT):
            return f"healthy {s.healthy!r}"
        if s.cycle != min(before.cycle + 1, MAX_COUNT):
            return f"cycle {s.cycle!r} after {before.cycle!r}"
        if not (type(s.error_cycles) is int and before.error_cycles <= s.error_cycles <= before.error_cycles + 1
                and s.error_cycles <= s.cycle):
            return f"error_cycles {s.error_cycles!r} after {before.error_cycles!r}"
        if not (type(out.demand) is int and 0 <= out.demand <= 2):
            return f"demand {out.demand!r}"
        if not (type(out.reasons) is int and 0 <= out.reasons < 8192):
            return f"reasons {out.reasons!r}"
        if not (type(out.distance_dm) is int and (0 <= out.distance_dm <= 60000 or out.distance_dm == NO_DISTANCE)):
            return f"distance {out.distance_dm!r}"
        if not (type(out.observation) is int and 0 <= out.observation < self.n_obs):
            return f"observation {out.observation!r} not < {self.n_obs}"
        if not (type(out.module_flags) is int and 0 <= out.module_flags < 1 << self.modules):
            return f"module flags {out.module_flags!r}"
        if type(out.system_error) is not bool:
            return f"system_error {out.system_error!r}"
        if type(out.warning) is not bool:
            return f"warning {out.warning!r}"
        if not (type(s.calm) is int and 0 <= s.calm < self.setup.config.release_confirm_cycles):
            return f"calm {s.calm!r}"
        if (out.node, out.mode, out.cycle, out.error_cycles) != (s.node, s.mode, s.cycle, s.error_cycles):
            return "outputs disagree with the state (node, mode, cycle, error_cycles)"
        if s.mode == INIT and not (out.demand == EMERGENCY and out.reasons & R_INIT):
            return "INIT without emergency demand and the init reason"
        if s.mode == SAFE_STOP and not (out.demand == EMERGENCY and out.reasons & R_SAFE_STOP):
            return "SAFE_STOP without emergency demand and the safe_stop reason"
        if s.latched and out.demand != EMERGENCY:
            return "latched without emergency demand"
        return ""

    def finish(self) -> None:
        """Run the cycles up to the last frame's time and one more, then the stream's totals."""
        rx = self.rx
        if not self.failed:
            try:
                while self.runner.next_tick <= self.clock.now_ms():
                    self.cycle()
                self.cycle()
            except StreamStop:
                pass
        if not self.failed:
            total = rx.accepted + sum(rx.rejected.values()) + self.tally.filtered
            if not (total == self.frames == self.runner.frames_received == sum(self.tally.kinds.values())):
                self.stats.accounting_errors += 1
                try:
                    self._fault("accounting", f"frames in {self.frames}, received {self.runner.frames_received}, "
                                f"accepted + rejected + filtered {total}, by kind {sum(self.tally.kinds.values())}")
                except StreamStop:
                    pass
        self.stats.accepted += rx.accepted
        self.stats.rejected.update(rx.rejected)
        self.stats.filtered += self.tally.filtered
        self.stats.frame_kinds.update(self.tally.kinds)
        self.stats.bus_states.update(self.tally.bus_events)
        self.bus.shutdown()


# ----------------------------------------------------------------------------- traffic from a byte string
class TapeEnd(StreamStop):
    pass


_PAD = int.from_bytes(random.Random(0x5EED).randbytes(TAPE_BYTES), "little")


class Tape:
    """Reads the Hypothesis byte string; running out of it ends the stream.

    The bytes are XORed with a fixed pad first, so that Hypothesis's simplest example (all
    zeros) is an ordinary mixed program rather than thousands of identical nominal cycles."""

    __slots__ = ("buf", "pos")

    def __init__(self, raw: bytes) -> None:
        n = len(raw)
        pad = _PAD & ((1 << (8 * n)) - 1) if n <= TAPE_BYTES else _PAD
        self.buf = (int.from_bytes(raw, "little") ^ pad).to_bytes(n, "little")
        self.pos = 0

    def u8(self) -> int:
        if self.pos >= len(self.buf):
            raise TapeEnd
        v = self.buf[self.pos]
        self.pos += 1
        return v

    def u16(self) -> int:
        return self.u8() | self.u8() << 8

    def u32(self) -> int:
        return self.u16() | self.u16() << 16

    def below(self, n: int) -> int:
        return (self.u8() if n <= 256 else self.u16()) % n

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.buf):
            raise TapeEnd
        b = self.buf[self.pos:self.pos + n]
        self.pos += n
        return b


PROFILES = {   # traffic profile -> relative weights of the instructions (a nominal cycle is 7 frames)
    "mixed": dict(nominal=8, valid=16, mutated=18, random=12, shell=8, out_of_range=6, burst=1, replay=6,
                  advance=14, cycle=10, silence=1),
    "nominal with faults": dict(nominal=60, valid=3, mutated=4, random=3, shell=2, out_of_range=2, burst=1,
                                replay=2, advance=3, cycle=1, silence=1),
    "junk": dict(nominal=3, valid=10, mutated=30, random=30, shell=10, out_of_range=8, burst=2, replay=6,
                 advance=6, cycle=5),
    "babbling": dict(nominal=12, valid=12, burst=10, mutated=8, shell=3, replay=5, advance=20, cycle=8, silence=2),
    "hostile": dict(nominal=10, valid=8, shell=24, burst=6, mutated=8, random=4, replay=4, advance=16, cycle=8,
                    silence=1),
}
PROFILE_NAMES = tuple(PROFILES)


def _op_table(weights: dict) -> tuple:
    total = sum(weights.values())
    table = []
    for name, w in weights.items():
        table += [name] * round(256 * w / total)
    return tuple((table + [table[-1]] * 256)[:256])


OP_TABLES = {name: _op_table(w) for name, w in PROFILES.items()}
SPEEDS = (0, 0, 300, 1500, 4000, 8000, 12000)
FD_LENGTHS = (12, 16, 20, 24, 32, 48, 64)
MONITORED_IDS = tuple(sorted(MONITORED))
UNMONITORED_NEIGHBOURS = (0x000, 0x00F, 0x011, 0x01F, 0x026, 0x02F, 0x031, 0x03F, 0x041, 0x410, 0x420, 0x7FF)
ERROR_CLASSES = (ERR_CRTL, ERR_CRTL, ERR_CRTL, ERR_BUSOFF, ERR_RESTARTED, ERR_CRTL | ERR_RESTARTED,
                 0x001, 0x002, 0x008, 0x010, 0x020, 0x080, 0x200)     # the rest: TX timeout, arbitration, ...
CTRL_BYTES = (0x04, 0x08, 0x10, 0x20, 0x40, 0x14, 0x00, 0x01, 0x02)
FAULTS = ("none",) * 6 + ("disagree", "offset", "silent", "degraded", "train_silent", "train_bad", "far")


class Traffic:
    """Turns a byte string into frames and time steps and feeds them to the harness."""

    def __init__(self, harness: Harness, tape: Tape, profile: str) -> None:
        self.h = harness
        self.tape = tape
        self.ops = tuple(getattr(self, "op_" + name) for name in OP_TABLES[profile])
        self.sender = codec.Sender()     # the codec's encoder: correct CRC and alive counter per ID
        self.now = 0
        self.history: deque = deque(maxlen=64)
        self.channels = harness.channels
        self.period = harness.period
        self.world = dict(present=True, distance=30000, closing=500, obstacle=0, speed=4000, track=0, brake=0,
                          fault="none", target=0)

    def run(self) -> None:
        ops = self.ops
        tape = self.tape
        while True:
            ops[tape.u8()]()

    # ------------------------------------------------------------------ helpers
    def send(self, frame_id: int, data: bytes, kind: str, *, extended=False, remote=False, error=False, fd=False,
             dlc=None) -> None:
        msg = can.Message(timestamp=self.now / 1000, arbitration_id=frame_id, data=data, is_extended_id=extended,
                          is_remote_frame=remote, is_error_frame=error, is_fd=fd, bitrate_switch=fd, dlc=dlc,
                          check=False)
        self.history.append(msg)
        self.h.feed(self.now, msg, kind)

    def valid(self, frame_id: int, signals: dict) -> bytes:
        return self.sender.frame(frame_id, signals)

    def pick(self, lo: int, hi: int) -> int:
        """A value in lo..hi: often a bound or next to one, else uniform."""
        b = self.tape.u8()
        if b < 48:
            return (lo, hi, min(lo + 1, hi), max(hi - 1, lo), max(lo, min(hi, 0)), (lo + hi) // 2)[b % 6]
        return lo + self.tape.u16() % (hi - lo + 1) if hi - lo < 65536 else lo + self.tape.u32() % (hi - lo + 1)

    def signals(self, frame_id: int) -> dict:
        t = self.tape
        if frame_id in OBSTACLES:
            ch = frame_id - OBSTACLES[0]
            b = t.u8()
            return {"Status": b % 3, "ObstacleType": (b >> 2) % 3, "Distance": self.pick(0, 60000),
                    "ClosingSpeed": self.pick(-15000, 15000), "Module": ch // 2, "Channel": ch % 2}
        if frame_id == TRAIN_STATE:
            b = t.u8()
            return {"Speed": self.pick(0, 12000), "TrackCondition": b & 1, "BrakeStatus": (b >> 1) & 1}
        if frame_id == BRAKE_DEMAND:
            return {"Level": t.u8() % 3, "Warning": t.u8() % 2, "Reason": self.pick(0, 8191), "Cycle": t.u32()}
        return {"Mode": t.u8() & 3, "Node": t.u16() & 1023, "ErrorFlags": t.u8() & 63, "VotedDistance": t.u16(),
                "TableHash": t.u16() & 4095, "DeadlineMisses": t.u8() & 15}

    def pick_id(self) -> int:
        b = self.tape.u8()
        if b < 200:      # mostly what the monitor reads
            return (OBSTACLES + (TRAIN_STATE,))[b % 7]
        return DBC_IDS[b % len(DBC_IDS)]

    def crc(self, frame_id: int, data: bytearray) -> bytearray:
        """The CRC recomputed for frame_id, as a sender would (cantools' AUTOSAR profile 2)."""
        return bytearray(codec.apply_profile2_crc(bytes(data), codec.data_id(frame_id)))

    # ------------------------------------------------------------------ instructions
    def op_valid(self) -> None:
        fid = self.pick_id()
        self.send(fid, self.valid(fid, self.signals(fid)), "valid")

    def op_mutated(self) -> None:
        t = self.tape
        fid = self.pick_id()
        data = bytearray(self.valid(fid, self.signals(fid)))
        flags = dict(extended=False, remote=False, error=False, fd=False, dlc=None)
        recrc = None
        for _ in range(1 + t.u8() % 3):
            m = t.u8() % 13
            if m == 0 and data:                      # bit flip
                p = t.below(8 * len(data))
                data[p // 8] ^= 1 << (p % 8)
            elif m == 1 and data:                    # byte change
                data[t.below(len(data))] = t.u8()
            elif m == 2 and data:                    # truncation
                data = data[:t.below(len(data))]
            elif m == 3:                             # extension (CAN FD sizes too)
                b = t.u8()
                n = 1 + b % 8 if b < 160 else FD_LENGTHS[b % 7] - len(data)
                data += t.take(max(0, n))
                flags["fd"] = len(data) > 8 and b & 1 == 1
            elif m == 4 and len(data) > 1:           # counter replay (the previous frame's counter)
                data[1] = (data[1] & 0xF0) | ((data[1] - 1) & 0xF)
                recrc = True
            elif m == 5 and len(data) > 1:           # counter jump
                data[1] = (data[1] & 0xF0) | ((data[1] + 2 + t.u8() % 14) & 0xF)
                recrc = True
            elif m == 6:                             # ID swapped for another DBC message
                fid = DBC_IDS[t.u8() % len(DBC_IDS)]
            elif m == 7:                             # ID swapped for a random 11-bit ID
                fid = t.u16() & 0x7FF
            elif m == 8:                             # the same ID, 29-bit
                flags["extended"] = True
                fid = fid if t.u8() & 1 else t.u32() & 0x1FFFFFFF
            elif m == 9:                             # remote or error frame
                flags["remote" if t.u8() & 1 else "error"] = True
            elif m == 10:                            # CAN FD flag on a classic length
                flags["fd"] = True
            elif m == 11 and len(data) == 8:         # payload replaced, CRC made to fit
                data[1:] = t.take(7)
                recrc = True
            elif m == 12:                            # DLC that disagrees with the data
                flags["dlc"] = t.u8() % 16
        if recrc is None:
            recrc = t.u8() & 1 == 1
        if recrc and len(data) == 8:
            data = self.crc(fid, data)
        self.send(fid, bytes(data), "mutated", **flags)

    def op_random(self) -> None:
        t = self.tape
        b = t.u8()
        mode = b & 3
        extended = False
        if mode == 0:
            fid = t.u16() & 0x7FF
        elif mode == 1:
            fid, extended = t.u32() & 0x1FFFFFFF, True
        elif mode == 2:
            fid = DBC_IDS[(b >> 2) % len(DBC_IDS)]
            extended = b >> 6 == 3
        else:                                        # out-of-spec: an 11-bit frame with a wider ID
            fid = DBC_IDS[(b >> 2) % len(DBC_IDS)] | (1 << (11 + t.u8() % 18))
        f = t.u8()
        n = t.u8()
        length = n % 9 if n < 176 else (FD_LENGTHS[n % 7] if n < 240 else n % 65)
        data = t.take(length)
        self.send(fid, data, "random", extended=extended, remote=f < 16, error=16 <= f < 24,
                  fd=length > 8 or f >= 224, dlc=(f % 16) if 200 <= f < 224 else None)

    def op_out_of_range(self) -> None:
        t = self.tape
        b = t.u8()
        if b < 180:
            fid = OBSTACLES[b % 6]
            ch = fid - OBSTACLES[0]
            sig = self.signals(fid)
            which = t.u8() % 7
            if which == 0:
                sig["Status"] = 3
            elif which == 1:
                sig["ObstacleType"] = 3
            elif which == 2:
                sig["Distance"] = 60001 + t.u16() % 5535
            elif which == 3:
                sig["ClosingSpeed"] = 15001 + t.u16() % 17767
            elif which == 4:
                sig["ClosingSpeed"] = -15001 - t.u16() % 17768
            elif which == 5:
                sig["Module"] = 3 if t.u8() & 1 else (ch // 2 + 1) % 3
            else:
                sig["Channel"] = 1 - ch % 2
        elif b < 230:
            fid = TRAIN_STATE
            sig = self.signals(fid)
            sig["Speed"] = 12001 + t.u16() % 53535
        else:
            fid = BRAKE_DEMAND
            sig = self.signals(fid)
            if b & 1:
                sig["Level"] = 3
            else:
                sig["Reason"] = 1024 + t.u16() % 64512
        self.send(fid, self.valid(fid, sig), "out_of_range")

    def op_burst(self) -> None:
        """A babbling sender: valid frames, or with bad CRCs or wrong lengths among them (the rate
        policing counts every frame on the ID), or with FD/remote frames on the same ID among
        them (refused before the policing: they do not count)."""
        t = self.tape
        fid = (OBSTACLES + (TRAIN_STATE,))[t.u8() % 7]
        n = 4 + t.u8() % 20
        gap = t.u8() % 40
        style = t.u8() % 4
        sig = self.signals(fid)
        for _ in range(n):
            data = self.valid(fid, sig)
            b = t.u8() if style else 0
            if style == 1 and b & 1:                   # CRC broken
                self.send(fid, bytes([data[0] ^ (1 + (b >> 1))]) + data[1:], "burst")
            elif style == 2 and b & 1:                 # wrong length
                self.send(fid, data[:b % 8] if b & 2 else data + bytes(1 + b % 8), "burst")
            elif style == 3 and b & 1:                 # an FD or remote frame on the same ID
                if b & 2:
                    self.send(fid, data, "burst", fd=True)
                else:
                    self.send(fid, b"", "burst", remote=True, dlc=8)
            else:
                self.send(fid, data, "burst")
            self.now += gap

    def op_shell(self) -> None:
        """A frame the shell refuses or drops before the codec: CAN FD, remote, error frames,
        frames on the monitor's own output IDs, 29-bit or unmonitored 11-bit IDs."""
        t = self.tape
        b = t.u8()
        what = b % 8
        fid = MONITORED_IDS[t.u8() % len(MONITORED_IDS)]
        if what == 0:                                  # CAN FD on a monitored ID: a valid payload, or longer
            data = codec.encode(fid, self.signals(fid), t.u8())
            if b & 0x80:
                data += t.take(FD_LENGTHS[t.u8() % len(FD_LENGTHS)] - 8)
            self.send(fid, data, "fd", fd=True)
        elif what == 1:                                # a remote request
            self.send(fid, b"", "remote", remote=True, dlc=t.u8() % 9, extended=b & 0x80 == 0x80)
        elif what in (2, 3):                           # a controller error frame
            cls = ERROR_CLASSES[t.u8() % len(ERROR_CLASSES)] | (t.u8() & 0x3 if b & 0x80 else 0)
            n = 8 if b & 0x40 == 0 else t.u8() % 3
            data = bytearray(t.take(n))
            if n >= 2:
                data[1] = CTRL_BYTES[t.u8() % len(CTRL_BYTES)]
            self.send(cls | (CAN_ERR_FLAG if b & 0x20 else 0), bytes(data), "error", error=True,
                      extended=True)
        elif what in (4, 5):                           # on the monitor's own output IDs
            out = OUTPUTS[(b >> 7) & 1]
            if b & 0x40:
                data = self.valid(out, self.signals(out))
            else:
                data = t.take(t.u8() % 9)
            self.send(out, data, "foreign")
        elif what == 6:                                # a monitored ID, 29-bit
            self.send(fid, codec.encode(fid, self.signals(fid), t.u8()), "filtered", extended=True)
        else:                                          # an 11-bit ID next to the monitored ones
            self.send(UNMONITORED_NEIGHBOURS[t.u8() % len(UNMONITORED_NEIGHBOURS)], t.take(8), "filtered")

    def op_replay(self) -> None:
        if not self.history:
            return
        old = self.history[-1 - self.tape.below(len(self.history))]
        self.send(old.arbitration_id, bytes(old.data), "replay", extended=old.is_extended_id,
                  remote=old.is_remote_frame, error=old.is_error_frame, fd=old.is_fd, dlc=old.dlc)

    def op_advance(self) -> None:
        self.now += self.tape.u8() % 50

    def op_cycle(self) -> None:
        self.now = max(self.now, self.h.runner.next_tick)
        while self.h.runner.next_tick <= self.now:
            self.h.cycle()

    def op_silence(self) -> None:
        b = self.tape.u8()
        self.now = self.h.runner.next_tick + self.period * (b % 8 if b < 224 else b % 40)
        self.op_cycle()

    def op_nominal(self) -> None:
        """Every channel and the TrainState once, consistent up to the world's fault, then the cycle."""
        t, w = self.tape, self.world
        b = t.u8()
        if b < 16:                                   # a new situation
            w.update(present=t.u8() < 170, distance=self.pick(0, 60000), closing=self.pick(-3000, 3000),
                     obstacle=t.u8() % 3, speed=SPEEDS[t.u8() % 7], track=b & 1, brake=(b >> 1) & 1)
        elif b < 26:                                 # a new persistent fault (or its end)
            w["fault"] = FAULTS[t.u8() % len(FAULTS)]
            w["target"] = t.u8()
        elif w["present"]:
            w["distance"] = max(0, w["distance"] - w["speed"] // 100)
        noise = t.u8()
        order = list(range(self.channels)) + [None]
        rot = noise % len(order)
        order = order[rot:] + order[:rot]
        fault, target = w["fault"], w["target"]
        for ch in order:
            if ch is None:
                if fault == "train_silent":
                    continue
                speed = 12000 + 1 + target if fault == "train_bad" else w["speed"]
                self.send(TRAIN_STATE, self.valid(TRAIN_STATE, {"Speed": speed, "TrackCondition": w["track"],
                                                               "BrakeStatus": w["brake"]}), "nominal")
                continue
            status = 1 if w["present"] else 0
            distance = min(60000, w["distance"] + (noise >> 4) * (1 if ch & 1 else -1) // 2) if status else 0
            distance = max(0, distance)
            m = ch // 2
            if fault == "disagree" and m == target % (self.channels // 2) and ch % 2 == 1:
                status = 1 - status
            elif fault == "offset" and ch == target % self.channels:
                distance = min(60000, distance + 3000)
            elif fault == "silent" and ch == target % self.channels:
                continue
            elif fault == "degraded" and ch == target % self.channels:
                status = 2
            elif fault == "far" and ch == target % self.channels:
                distance = 60000
            fid = OBSTACLES[ch]
            self.send(fid, self.valid(fid, {"Status": status, "ObstacleType": w["obstacle"], "Distance": distance,
                                            "ClosingSpeed": w["closing"], "Module": m, "Channel": ch % 2}),
                      "nominal")
            self.now += (noise >> ch) & 3
        self.now = max(self.now, self.h.runner.next_tick)
        self.op_cycle()


def run_stream(table: str, topology: str, profile: str, tape: bytes, stats: Stats,
               budget: Optional[int] = None, label: Optional[dict] = None) -> Harness:
    """One stream: a fresh runner fed by the traffic program in `tape` (also how a failure is
    replayed: the same four values give the same frames)."""
    h = Harness(setup_for(table, topology), stats, budget,
                dict(label or {}, table=table, topology=topology, profile=profile))
    stats.streams += 1
    stats.stream_kinds[f"{table}/{topology}/{profile}"] += 1
    kept = len(stats.examples)
    try:
        Traffic(h, Tape(tape), profile).run()
    except StreamStop:
        pass
    except Exception as exc:  # noqa: BLE001 - a fault of this harness, not of the product
        stats.harness_errors += 1
        stats.record("harness", dict(h.label, what=f"{type(exc).__name__}: {exc}",
                                     traceback=traceback.format_exc(limit=-4)))
        h.failed = True
    if len(stats.examples) > kept:
        stats.examples[kept]["tape"] = tape.hex()   # with table, topology and profile: the stream again
    h.finish()
    return h


# ----------------------------------------------------------------------------- Hypothesis
def stream_strategy():
    from hypothesis import strategies as st

    return st.tuples(st.sampled_from(("m1", "m2")), st.sampled_from(("3oo3", "3oo3", "3oo3", "2oo2")),
                     st.sampled_from(PROFILE_NAMES), st.binary(min_size=TAPE_BYTES, max_size=TAPE_BYTES))


def _hypothesis_batch(stats: Stats, target: int, seed: int, examples: int) -> None:
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as fixed_seed

    counter = [0]

    @fixed_seed(seed)
    @settings(max_examples=examples, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck), report_multiple_bugs=False)
    @given(stream_strategy())
    def one_stream(params):
        counter[0] += 1
        if stats.frames >= target or stats.faults() >= MAX_FAULTS:
            return
        table, topology, profile, tape = params
        run_stream(table, topology, profile, tape, stats, budget=min(STREAM_FRAMES, target - stats.frames),
                   label={"hypothesis_seed": seed, "example": counter[0]})

    one_stream()


def fuzz_chunk(job: tuple) -> dict:
    """Hypothesis streams until `frames` frames went through the receive path (one worker job)."""
    seed, frames = job
    stats = Stats()
    t0 = time.perf_counter()
    batch = 0
    while stats.frames < frames and stats.faults() < MAX_FAULTS and batch < 10_000:
        left = frames - stats.frames
        _hypothesis_batch(stats, frames, seed * 1_000_003 + batch, max(2, min(60, left // 1000 + 2)))
        batch += 1
    stats.seconds = time.perf_counter() - t0
    return stats.as_dict()


def run(frames: int, progress: Progress, seed: int = 0, workers: Optional[int] = None) -> dict:
    """Fuzz the receive path with at least `frames` frames; the figures as a dict:
    frames, accepted, rejected (by reason), exceptions, violations, seconds, frames_per_s, ..."""
    t0 = time.perf_counter()
    if workers is None:
        workers = 1 if frames <= CHUNK_FRAMES else max(1, min(2, os.cpu_count() or 1))
    n_jobs = max(1, math.ceil(frames / CHUNK_FRAMES))
    jobs = [(seed * 1000 + i, frames // n_jobs + (1 if i < frames % n_jobs else 0)) for i in range(n_jobs)]
    total = Stats()
    if workers <= 1 or n_jobs == 1:
        for job in jobs:
            total.merge(fuzz_chunk(job))
            progress(f"fuzz: {total.frames:,} of {frames:,} frames")
    else:
        import multiprocessing as mp

        methods = mp.get_all_start_methods()
        ctx = mp.get_context("fork" if "fork" in methods else "spawn")
        with ctx.Pool(workers) as pool:
            for d in pool.imap_unordered(fuzz_chunk, jobs):
                total.merge(d)
                progress(f"fuzz: {total.frames:,} of {frames:,} frames")
    seconds = time.perf_counter() - t0
    result = total.as_dict()
    rejected_total = sum(result["rejected"].values())
    expected = dict(result["expected"])
    result.update(
        target=frames, seed=seed, workers=workers, seconds=seconds,
        frames_per_s=result["frames"] / seconds if seconds > 0 else 0.0,
        rejected_total=rejected_total,
        accounting_exact=(result["accounting_errors"] == 0
                          and result["frames"] == result["accepted"] + rejected_total + result["filtered"]
                          == sum(result["frame_kinds"].values())),
        reference_agrees=(expected.pop(ACCEPTED, 0) == result["accepted"]
                          and expected.pop(FILTERED, 0) == result["filtered"]
                          and {k: v for k, v in expected.items() if v}
                          == {k: v for k, v in result["rejected"].items() if v}),
    )
    return result


# ----------------------------------------------------------------------------- the verification part
# Reject reasons the fuzzing must produce: the codec's and the shell's, except those no frame
# through this front door can earn:
UNREACHABLE_REASONS = {
    # python-can's recv raising CanError (a broken socket): a virtual bus cannot produce it
    "receive_error": "needs a failing interface",
    # the codec's net for an exception inside its checks: a fault, never a frame's due (the
    # reference never predicts it, so every occurrence is a reason violation)
    "undecodable": "only a codec fault",
    # the receive filter (rule 2) passes only the DBC's own IDs to the codec, and the output
    # IDs stop at rule 4: no frame reaches the codec's unknown-ID check any more (the
    # reference keeps the rule, so one would still show as a mismatch)
    "unknown_id": "the receive filter passes only DBC IDs",
}
COVERED_REASONS = tuple(r for r in codec.REJECT_REASONS + codec.SHELL_REJECT_REASONS if r not in UNREACHABLE_REASONS)
MODE_NAMES = ("INIT", "NORMAL", "DEGRADED", "SAFE_STOP")


def section(out_dir, quick: bool, progress: Progress) -> Section:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = QUICK_FRAMES if quick else FULL_FRAMES
    title = "Front-door fuzzing (CAN receive path)"
    try:
        import hypothesis  # noqa: F401
    except ImportError as exc:
        return Section(title, f"Hypothesis is not installed (`pip install hypothesis`): {exc}\n",
                       [Check("fuzz: runs (needs hypothesis)", False, f"ImportError: {exc}")])
    progress(f"fuzz: {target:,} Hypothesis-generated frames into the runner's receive path")
    r = run(target, progress)
    accepted, rej_total = r["accepted"], r["rejected_total"]
    missing_reasons = [x for x in COVERED_REASONS if not r["rejected"].get(x)]
    missing_reasons += [FILTERED] if not r["filtered"] else []
    missing_ids = [f"0x{i:02X}" for i in sorted(INPUTS) if not r["accepted_ids"].get(f"0x{i:02X}")]
    missing_ids += [f"0x{i:02X} (foreign)" for i in OUTPUTS if not r["foreign_ids"].get(f"0x{i:02X}")]
    missing_modes = [MODE_NAMES[m] for m in range(4) if not r["modes"].get(m)]
    missing_other = [k for k in KINDS if not r["frame_kinds"].get(k)]
    missing_other += [st for st in BUS_STATES if not r["bus_states"].get(st)]
    missing_other += ["ForeignOutput cycle"] if not r["foreign_cycles"] else []
    missing = missing_reasons or missing_ids or missing_modes or missing_other
    checks = [
        Check("fuzz: frames through the receive path", r["frames"] >= target,
              f"{r['frames']:,} >= {target:,} in {r['seconds']:.1f} s ({r['frames_per_s']:,.0f} frames/s)",
              {"frames": r["frames"], "seconds": round(r["seconds"], 2), "workers": r["workers"]}),
        Check("fuzz: no exception (runner, receiver, core)", r["exceptions"] == 0 and r["harness_errors"] == 0,
              f"{r['exceptions']} exceptions, {r['harness_errors']} harness errors",
              {"examples": [e for e in r["examples"] if e["kind"] in ("exception", "harness")][:3]}),
        Check("fuzz: no invariant violation (domains, reference receiver)", r["violations"] == 0,
              f"{r['violations']} violations" + (f" {r['violations_by_kind']}" if r["violations"] else ""),
              {"examples": [e for e in r["examples"] if e["kind"] not in ("exception", "harness")][:3]}),
        Check("fuzz: accounting exact (received = accepted + rejected by reason + filtered)",
              r["accounting_exact"] and r["reference_agrees"],
              f"{r['frames']:,} = {accepted:,} + {rej_total:,} + {r['filtered']:,}; "
              f"per-frame errors {r['accounting_errors']}",
              {"rejected": r["rejected"], "filtered": r["filtered"]}),
        Check("fuzz: coverage (every reachable reject reason and filtered, every input accepted, both output IDs "
              "foreign, every frame kind and bus state, ForeignOutput, every mode)",
              not missing,
              "complete" if not missing else
              f"missing reasons {missing_reasons}, IDs {missing_ids}, modes {missing_modes}, other {missing_other}",
              {"not reachable here": UNREACHABLE_REASONS}),
    ]
    md = [_SECTION_TEXT.format(target=target, mode="quick" if quick else "full", tape=TAPE_BYTES)]
    md.append(md_table(["frames", "accepted", "rejected", "filtered", "exceptions", "violations",
                        "streams (examples)", "cycles", "time (s)", "frames/s", "workers"],
                       [[f"{r['frames']:,}", f"{accepted:,}", f"{rej_total:,}", f"{r['filtered']:,}", r["exceptions"],
                         r["violations"], f"{r['streams']:,}", f"{r['cycles']:,}", f"{r['seconds']:.1f}",
                         f"{r['frames_per_s']:,.0f}", r["workers"]]]))
    md.append("\nRejected frames by reason (the runner's counters; the reference receiver's prediction):\n\n")
    reasons = list(codec.REJECT_REASONS) + list(codec.SHELL_REJECT_REASONS)
    reasons += sorted(k for k in r["rejected"] if k not in reasons)
    md.append(md_table(["reason", "frames", "reference"],
                       [[k + (f" (not reachable here: {UNREACHABLE_REASONS[k]})" if k in UNREACHABLE_REASONS else ""),
                         f"{r['rejected'].get(k, 0):,}", f"{r['expected'].get(k, 0):,}"] for k in reasons]
                       + [[FILTERED, f"{r['filtered']:,}", f"{r['expected'].get(FILTERED, 0):,}"],
                          [ACCEPTED, f"{accepted:,}", f"{r['expected'].get(ACCEPTED, 0):,}"]]))
    md.append("\nFrames by kind (the runner's tally), bus states announced by error frames, frames by generator, "
              "accepted frames by message, foreign frames by ID, cycles by mode "
              f"({r['foreign_cycles']:,} cycles with ForeignOutput set):\n\n")
    md.append(md_table(["frame kind", "frames"], [[k, f"{r['frame_kinds'].get(k, 0):,}"] for k in KINDS]))
    md.append("\n" + md_table(["bus state", "announced"], [[k, f"{r['bus_states'].get(k, 0):,}"] for k in BUS_STATES]))
    md.append("\n" + md_table(["generator", "frames"], [[k, f"{v:,}"] for k, v in sorted(r["kinds"].items())]))
    md.append("\n" + md_table(["message", "accepted"], [[k, f"{v:,}"] for k, v in sorted(r["accepted_ids"].items())]))
    md.append("\n" + md_table(["output ID", "foreign frames"], [[k, f"{v:,}"] for k, v in r["foreign_ids"].items()]))
    md.append("\n" + md_table(["mode", "cycles"], [[MODE_NAMES[m] if 0 <= int(m) < 4 else m, f"{v:,}"]
                                                  for m, v in sorted(r["modes"].items())]))
    if r["examples"]:
        md.append("\nFirst faults found (frame bytes to reproduce):\n\n")
        md.append(md_table(["kind", "what", "frame", "stream"],
                           [[e["kind"], e.get("what", ""), e.get("frame", ""),
                             f"{e.get('table')}/{e.get('topology')}/{e.get('profile')} seed {e.get('hypothesis_seed')} "
                             f"example {e.get('example')} frame {e.get('frame_index')}"] for e in r["examples"]]))
    return Section(title, "".join(md), checks)


_SECTION_TEXT = """\
{target:,} frames ({mode} mode) went through the real receive path: `MonitorRunner.drain()` on an in-memory
python-can bus with the simulated clock, and at every period boundary `MonitorRunner.cycle()`, which steps
the core (`monitor.core.cycle.step`) with the latched reports, returns the cycle's record and sends
BrakeDemand and MonitorStatus. The receive rules, in order, for each frame: (1) it is counted by kind
(classical, 29-bit, FD, remote, error; an error frame also announces a bus state); (2) outside the receive
filter (not an error frame, and 29-bit or an ID other than 0x010, 0x020-0x025, 0x030, 0x040) it is
counted as filtered, not as a reject (live, it never reaches the process); (3) an FD, remote or error
frame is refused (`fd_frame`, `remote_frame`, `error_frame`); (4) a frame on the monitor's own output IDs
0x010 and 0x040 is foreign (`foreign_output`) and sets the ForeignOutput diagnostic in every cycle within
one second (10 periods) of it; (5) the codec: on an input ID every frame counts for the rate policing
before its length and CRC are looked at, and more than 3 frames within one period quarantine the ID for
500 ms after its last excess frame (`rate_exceeded`, the channel's report withdrawn, its alive counter
forgotten); then `wrong_length`, `bad_crc`, `repeated_counter`/`counter_jump`, `out_of_range`, and the
report latched.

**Frames.** One Hypothesis example is one stream: the table (m1, m2), the topology (3oo3, 2oo2), a traffic
profile and a {tape:,}-byte string read as a program of nominal cycles with persistent faults, valid frames
of every DBC message (encoded by the codec; those on the output IDs are foreign), mutated frames (bit flips,
byte changes, truncation, extension up to 64 bytes, counter replay and jump, payload replacement, swapped
IDs, 29-bit, remote, error and FD flags, CRC recomputed or not), fully random frames (11-bit, 29-bit and
out-of-spec IDs, lengths 0..64), hostile frames (CAN FD with valid payloads, remote requests and controller
error frames on the monitored IDs, frames on 0x010/0x040, 29-bit and unmonitored neighbours of the
monitored IDs), signals out of range with a valid CRC, babbling bursts (valid, with broken CRCs or lengths,
or interleaved with FD/remote frames on the same ID), replays, and time steps, cycles and silences. Time
moves as in the runner's loop with every cycle on time: frames arrive between two ticks, and the cycle at a
tick sees what arrived up to it (deadline overruns are outside this part).

**Checks after every frame and cycle.** No exception escapes the runner, and the core's fail-safe never
swallows one. Each frame moves exactly one counter by one (accepted, one reject reason, or filtered) and
the kind tally by one, and frames received = accepted + rejected + filtered per stream. A reference
receiver written from the DBC and the rules above (its own classification, receive filter, CRC-8 and bit
unpacking) predicts every frame's outcome and kind, the bus state, the latched reports and TrainState:
the runner must agree. Every cycle's record agrees with the core's outputs and the reference (TrainState
speed, ForeignOutput), and the frames it sent carry a valid CRC, the demand and the ForeignOutput bit.
Latched reports stay in their domain (status 0..2, distance 0..60000 dm, closing -15000..15000 cm/s,
obstacle 0..2, tick <= now), and so do the core's state (mode, node < table nodes, counters) and outputs
(demand 0..2, reasons < 8192, distance 0..60000 or 65535), with emergency in INIT, SAFE_STOP and while
latched. A stream stops at its first fault.

"""
