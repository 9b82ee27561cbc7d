"""Encode and check the railguard CAN messages (can_bus/railguard.dbc) with E2E protection.

Every message uses the AUTOSAR E2E profile 2 layout: CRC-8 in byte 0 over bytes 1..7 and
the message's data ID (the low byte of its frame ID), alive counter in the low nibble of
byte 1. cantools packs the signals and computes the CRC; the counter check is ours.

`Receiver.accept` never raises: a frame that fails any check is counted by reason and
dropped. The channel it came from then simply stops being refreshed, and the core's
freshness rule ages it into DEGRADED.

A second sender on an ID is a fault, never a race (issue 39 item 2): one sender never sends
two different frames with the same alive counter within CONFLICT_WINDOW_MS, so such a pair
means another node writes the ID (a forger in step with the genuine sender, or one replaying
old frames). The ID is then quarantined for SECOND_SENDER_QUARANTINE_MS after the last
conflict: its latched content is withdrawn and every frame on it refused (`second_sender`),
so an obstacle channel reads as never heard from (DEGRADED: the voter goes to the safe side)
and BrakeDemand as absent (the brake receiver brakes). A frame equal to the last one is a
plain duplicate (`repeated_counter`), harmless.
"""
from __future__ import annotations

from collections import Counter as Tally
from collections import deque
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from typing import Optional

import cantools
from cantools.autosar.end_to_end import apply_profile2_crc, check_profile2_crc

from monitor.core.types import Report, Train

DBC_NAME = "railguard.dbc"
BRAKE_DEMAND_ID = 0x10
OBSTACLE_IDS = tuple(range(0x20, 0x26))     # channel i of module i // 2
TRAIN_STATE_ID = 0x30
MONITOR_STATUS_ID = 0x40
MONITOR_TRACK_ID = 0x41                     # the remembered obstacle, right after MonitorStatus
MONITOR_RISK_ID = 0x42                      # the papers' risk and the table's, right after MonitorTrack
OUTPUT_IDS = (BRAKE_DEMAND_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, MONITOR_RISK_ID)   # what the monitor sends, in order
FRAME_LENGTH = 8
INPUT_IDS = frozenset(OBSTACLE_IDS) | {TRAIN_STATE_ID}   # what the monitor reads (rate-checked)

REJECT_REASONS = ("unknown_id", "wrong_length", "bad_crc", "repeated_counter", "counter_jump",
                  "out_of_range", "rate_exceeded", "second_sender", "undecodable",
                  "stale_freshness", "bad_mac", "no_key")          # the last three: a secured bus only
# refused before the codec sees the frame (can_bus/frames.py, runner.MonitorCore)
SHELL_REJECT_REASONS = ("fd_frame", "classical_frame", "remote_frame", "error_frame", "foreign_output", "receive_error")
BABBLE_QUARANTINE_MS = 500   # a babbling sender is ignored this long after its last excess frame
MAX_FRAMES_PER_WINDOW = 3    # more frames than this from one sender within one period: babbling
CONFLICT_WINDOW_MS = 500     # the same counter with other content this soon: a second sender (a 4-bit
                             # counter at the DBC's 100 ms wraps in 1.6 s, so it is not the sender's wrap)
SECOND_SENDER_QUARANTINE_MS = 1000   # an ID with a second sender is refused this long after the last conflict


@lru_cache(maxsize=1)
def database() -> cantools.database.can.Database:
    """The DBC shipped with the package (parsed once)."""
    text = resources.files("can_bus").joinpath(DBC_NAME).read_text(encoding="utf-8")
    return cantools.database.load_string(text, database_format="dbc")


def data_id(frame_id: int) -> int:
    return frame_id & 0xFF


def encode(frame_id: int, signals: dict, counter: int) -> bytes:
    """Pack signals (raw integer values) with the alive counter, then apply the CRC."""
    msg = database().get_message_by_frame_id(frame_id)
    values = {s.name: 0 for s in msg.signals}
    values.update(signals)
    values["Counter"] = counter & 0xF
    values["Crc"] = 0
    payload = bytearray(msg.encode(values, scaling=False, strict=False, padding=False))
    return bytes(apply_profile2_crc(payload, data_id(frame_id)))


def train_signals(train: Train) -> dict:
    """Raw signals of a TrainState: the core's Train, as the receiver reads it back."""
    return {"Speed": train.speed_cms, "TrackCondition": train.track, "BrakeStatus": train.brake}


def report_signals(report: Report, channel: int) -> dict:
    """Raw signals of an ObstacleReport: the core's units are the DBC's raw units."""
    return {
        "Status": report.status, "ObstacleType": report.obstacle, "Distance": report.distance_dm,
        "ClosingSpeed": report.closing_cms, "Module": channel // 2, "Channel": channel % 2,
    }


@dataclass
class SenderState:
    counter: Optional[int] = None
    recent: deque = field(default_factory=lambda: deque(maxlen=MAX_FRAMES_PER_WINDOW + 1))  # its newest ticks
    quarantine_until: Optional[int] = None   # babbling: its frames are refused until this tick
    last: Optional[tuple] = None             # (tick, bytes) of the newest frame that passed the CRC
    contested_until: Optional[int] = None    # a second sender: its frames are refused until this tick


@dataclass
class Receiver:
    """Checks incoming frames and latches the newest valid report per channel.

    `reports[i]` is the newest valid report of channel i with the tick it arrived, None until
    the first; `train` the newest valid TrainState. `rejected` counts drops by reason.

    Babbling: an input sender (obstacle channel or TrainState) with more than
    MAX_FRAMES_PER_WINDOW frames within `rate_window_ms` (the runner and the replay set one
    cycle period; 0, the default, switches the check off) is quarantined for
    BABBLE_QUARANTINE_MS after its last excess frame: its frames are refused and, for an
    obstacle channel, its latched report is withdrawn, so the core sees the channel as
    DEGRADED (never heard from) and brakes to the safe side. Ordinary jitter (two frames
    of one period close together) stays well under the limit. The policing counts every
    frame on the ID, valid or not, and comes before the length, CRC and decoding, in
    constant time per frame: a flood costs the receive path a dictionary lookup per frame.
    """

    channels: int = 6
    rate_window_ms: int = 0
    reports: list = field(default_factory=list)
    train: Optional[Train] = None
    train_tick: Optional[int] = None
    demand: Optional[dict] = None          # newest BrakeDemand (for the player and replay)
    demand_invalid: Optional[int] = None   # tick of the newest BrakeDemand refused for its content (a level 3)
    status: Optional[dict] = None          # newest MonitorStatus
    track: Optional[dict] = None           # newest MonitorTrack
    risk: Optional[dict] = None            # newest MonitorRisk
    accepted: int = 0
    rejected: Tally = field(default_factory=Tally)
    senders: dict = field(default_factory=dict)
    security: Optional[object] = None      # a security.Security: a secured bus (None: E2E only)

    def __post_init__(self) -> None:
        if not self.reports:
            self.reports = [None] * self.channels

    @property
    def rejected_total(self) -> int:
        return sum(self.rejected.values())

    def _reject(self, reason: str) -> None:
        self.rejected[reason] += 1

    def accept(self, frame_id, data, tick: int, extended: bool = False) -> Optional[str]:
        """Check one frame; on success latch its content and return the message name,
        otherwise count the reason and return None. Never raises. The DBC has only
        11-bit identifiers, so an extended (29-bit) frame is an unknown ID."""
        if extended:
            self._reject("unknown_id")
            return None
        try:
            return self._accept(int(frame_id), bytes(data), tick)
        except Exception:  # noqa: BLE001 - whatever the bytes, the receive path must go on
            self._reject("undecodable")
            return None

    def _withdraw(self, frame_id: int) -> None:
        """Forget what the ID's frames latched: the channel reads as never heard from, the
        BrakeDemand as absent."""
        if frame_id in OBSTACLE_IDS and frame_id - OBSTACLE_IDS[0] < self.channels:
            self.reports[frame_id - OBSTACLE_IDS[0]] = None
        elif frame_id == BRAKE_DEMAND_ID:
            self.demand = None

    def _babbling(self, frame_id: int, state: SenderState, tick: int) -> bool:
        """Count this frame against its sender; True while the sender is quarantined."""
        state.recent.append(tick)
        excess = len(state.recent) > MAX_FRAMES_PER_WINDOW and 0 <= tick - state.recent[0] < self.rate_window_ms
        if excess:
            state.quarantine_until = tick + BABBLE_QUARANTINE_MS
        if excess or (state.quarantine_until is not None and tick < state.quarantine_until):
            self._withdraw(frame_id)
            return True
        return False

    def _second_sender(self, frame_id: int, state: SenderState, data: bytes, tick: int) -> bool:
        """Judge a frame that passed the CRC for a second sender on its ID; True while the ID
        is contested (its frames are refused). Every such frame is remembered, refused or
        not, so a forger that keeps going keeps the ID contested."""
        last, state.last = state.last, (tick, data)
        if (last is not None and 0 <= tick - last[0] < CONFLICT_WINDOW_MS and data[1] & 0xF == last[1][1] & 0xF
                and data != last[1]):
            state.contested_until = tick + SECOND_SENDER_QUARANTINE_MS
        if state.contested_until is not None and tick < state.contested_until:
            self._withdraw(frame_id)
            return True
        return False

    def _contest(self, frame_id: int, state: SenderState, tick: int) -> None:
        """A frame that fails its authenticator (secured bus): another node writes the ID, a
        second sender as surely as a conflicting counter is. The ID is quarantined as
        `_second_sender` does; the frame itself is counted as `bad_mac`."""
        state.contested_until = tick + SECOND_SENDER_QUARANTINE_MS
        self._withdraw(frame_id)

    def contested(self, frame_id: int, tick: int) -> bool:
        """Whether `frame_id` has a second sender (its quarantine runs at `tick`)."""
        state = self.senders.get(frame_id)
        return state is not None and state.contested_until is not None and tick < state.contested_until

    def _accept(self, frame_id: int, data: bytes, tick: int) -> Optional[str]:
        db = database()
        try:
            msg = db.get_message_by_frame_id(frame_id)
        except KeyError:
            self._reject("unknown_id")
            return None
        state = self.senders.setdefault(frame_id, SenderState())
        if self.rate_window_ms > 0 and frame_id in INPUT_IDS and self._babbling(frame_id, state, tick):
            state.counter = None                 # the stream is broken: resynchronise afterwards
            self._reject("rate_exceeded")
            return None
        if self.security is not None:
            verdict, data = self.security.open(frame_id, data)
            if verdict != "ok":
                if verdict == "bad_mac":          # a node without the owner's key writes the ID
                    self._contest(frame_id, state, tick)
                self._reject(verdict)
                return None
        if len(data) != FRAME_LENGTH:
            self._reject("wrong_length")
            return None
        if not check_profile2_crc(data, data_id(frame_id)):
            self._reject("bad_crc")
            return None
        if self._second_sender(frame_id, state, data, tick):
            self._reject("second_sender")
            return None
        counter = data[1] & 0xF
        if state.counter is not None:
            delta = (counter - state.counter) & 0xF
            if delta == 0:
                self._reject("repeated_counter")
                return None
            if delta != 1:
                state.counter = counter          # resynchronise on the next frame
                self._reject("counter_jump")
                return None
        state.counter = counter
        raw = msg.decode(data, decode_choices=False, scaling=False)
        for sig in msg.signals:
            lo, hi = sig.minimum, sig.maximum
            value = raw[sig.name] * sig.scale + sig.offset
            if (lo is not None and value < lo - 1e-9) or (hi is not None and value > hi + 1e-9):
                if frame_id == BRAKE_DEMAND_ID:
                    self.demand_invalid = tick
                self._reject("out_of_range")
                return None
        self.accepted += 1
        if frame_id in OBSTACLE_IDS:
            ch = frame_id - OBSTACLE_IDS[0]
            if ch < self.channels and raw["Module"] == ch // 2 and raw["Channel"] == ch % 2:
                self.reports[ch] = Report(raw["Status"], raw["Distance"], raw["ClosingSpeed"],
                                          raw["ObstacleType"], tick)
            else:
                self.accepted -= 1
                self._reject("out_of_range")     # a report claiming another module/channel
                return None
        elif frame_id == TRAIN_STATE_ID:
            self.train = Train(raw["Speed"], raw["TrackCondition"], raw["BrakeStatus"])
            self.train_tick = tick
        elif frame_id == BRAKE_DEMAND_ID:
            self.demand = dict(raw, tick=tick)
        elif frame_id == MONITOR_STATUS_ID:
            self.status = dict(raw, tick=tick)
        elif frame_id == MONITOR_TRACK_ID:
            self.track = dict(raw, tick=tick)
        elif frame_id == MONITOR_RISK_ID:
            self.risk = dict(raw, tick=tick)
        return msg.name


class Sender:
    """Keeps one alive counter per frame ID and encodes frames in order; with a `security`
    (security.Security) each frame is sealed: a secured CAN FD frame under the ID's key."""

    def __init__(self, security=None) -> None:
        self.counters: dict[int, int] = {}
        self.security = security

    def frame(self, frame_id: int, signals: dict) -> bytes:
        c = (self.counters.get(frame_id, -1) + 1) & 0xF
        self.counters[frame_id] = c
        data = encode(frame_id, signals, c)
        return data if self.security is None else self.security.seal(frame_id, data)
