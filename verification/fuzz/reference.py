"""The receive path's rules, read a second time: the oracle the fuzzing judges the runner by.

The DBC's IDs and signal layouts in raw units, the receive filter and output IDs, the E2E
CRC-8 (0x2F), bit unpacking, the frame kinds and the bus state an error frame announces, the
rate policing's figures (docs/can.md), and `ReferenceReceiver`, which predicts each frame's
outcome from them. It shares no code with can_bus on purpose, not even a constant: a verdict
is only worth as much as this independent reading (issue 13); tests/test_fuzz.py compares
the two readings.
"""
from __future__ import annotations

from collections import Counter
from typing import Optional

import can

from monitor.core.types import Report, Train


ACCEPTED = "accepted"
FILTERED = "filtered"        # outside the receive filter: never seen live, not a reject


# ----------------------------------------------------------------------------- the DBC, read independently
# Frame IDs and signal layouts as railguard.dbc gives them, in raw units: (name, start bit,
# length, signed, raw minimum, raw maximum); all signals are little-endian (Intel, @1).
BRAKE_DEMAND = 0x10
OBSTACLES = tuple(range(0x20, 0x26))
TRAIN_STATE = 0x30
MONITOR_STATUS = 0x40
MONITOR_TRACK = 0x41
MONITOR_RISK = 0x42
INPUTS = frozenset(OBSTACLES) | {TRAIN_STATE}
_E2E = (("Crc", 0, 8, False, 0, 255), ("Counter", 8, 4, False, 0, 15))
_OBSTACLE = _E2E + (("Status", 12, 2, False, 0, 2), ("ObstacleType", 14, 2, False, 0, 2),
                    ("Distance", 16, 16, False, 0, 60000),        # [0|6000] m at 0.1 m
                    ("ClosingSpeed", 32, 16, True, -15000, 15000),  # [-150|150] m/s at 0.01 m/s
                    ("Module", 48, 2, False, 0, 2), ("Channel", 50, 1, False, 0, 1))
LAYOUT = {
    BRAKE_DEMAND: _E2E + (("Level", 12, 2, False, 0, 2), ("Warning", 14, 1, False, 0, 1),
                          ("Reason", 16, 16, False, 0, 32767), ("Cycle", 32, 32, False, 0, 2**32 - 1)),
    **{fid: _OBSTACLE for fid in OBSTACLES},
    TRAIN_STATE: _E2E + (("TrackCondition", 12, 1, False, 0, 1), ("BrakeStatus", 13, 1, False, 0, 1),
                         ("Speed", 16, 16, False, 0, 12000)),    # [0|120] m/s at 0.01 m/s
    MONITOR_STATUS: _E2E + (("Mode", 12, 2, False, 0, 3), ("Warning", 14, 1, False, 0, 1),
                            ("ForeignOutput", 15, 1, False, 0, 1), ("Node", 16, 10, False, 0, 1023),
                            ("ErrorFlags", 26, 6, False, 0, 63), ("VotedDistance", 32, 16, False, 0, 65535),
                            ("TableHash", 48, 12, False, 0, 4095), ("DeadlineMisses", 60, 4, False, 0, 15)),
    MONITOR_TRACK: _E2E + (("TrackState", 12, 3, False, 0, 5), ("Memory", 15, 1, False, 0, 1),
                           ("TrackDistance", 16, 16, False, 0, 65535),   # [0|6553.5] m at 0.1 m, 65535 no_track
                           ("TrackAge", 32, 16, False, 0, 65535)),       # [0|6553.5] s at 0.1 s
    MONITOR_RISK: _E2E + (("RiskCategory", 12, 3, False, 1, 4), ("Unsecured", 15, 1, False, 0, 1),
                          ("RiskScore", 16, 5, False, 0, 20),
                          ("R1", 21, 10, False, 0, 500),                # [0|50] % at 0.1 %
                          ("R2", 31, 11, False, 0, 1000),               # [0|100] % at 0.1 %
                          ("TableRisk", 42, 20, False, 0, 1000000)),    # ppm
}
# The bits no signal of a message uses: the monitor sends them 0 (MonitorTrack's comment: bits 48-63 reserved, 0).
UNUSED = {fid: ~sum(((1 << length) - 1) << start for _, start, length, *_ in sig) & (2**64 - 1)
          for fid, sig in LAYOUT.items()}
DBC_IDS = tuple(sorted(LAYOUT))

# ----------------------------------------------------------------------------- the rules, read independently
# The receive filter (standard frames on these IDs, and every error frame), the monitor's own
# output IDs (live, never received from itself: any frame there is foreign), and the
# ForeignOutput hold: set in every cycle within FOREIGN_HOLD_CYCLES periods of the last
# foreign frame ("within the last second", the DBC's comment on MonitorStatus.ForeignOutput).
MONITORED = frozenset((BRAKE_DEMAND, *OBSTACLES, TRAIN_STATE, MONITOR_STATUS, MONITOR_TRACK, MONITOR_RISK))
OUTPUTS = (BRAKE_DEMAND, MONITOR_STATUS, MONITOR_TRACK, MONITOR_RISK)    # sent every cycle, in this order
FOREIGN_HOLD_CYCLES = 10
# The rate policing (docs/can.md, "an input sender with more than 3 frames within one period:
# quarantined 0.5 s, its channel withdrawn").
MAX_FRAMES_PER_WINDOW = 3
BABBLE_QUARANTINE_MS = 500
# A second sender (docs/can.md, issue 39: "the same alive counter with other content within
# 0.5 s: the ID is refused for 1 s after the last such frame, its channel withdrawn").
SAME_COUNTER_WINDOW_MS = 500
SECOND_SENDER_REFUSAL_MS = 1000
KINDS = ("classical", "extended", "fd", "remote", "error")
SHELL_REASON = {"fd": "fd_frame", "remote": "remote_frame", "error": "error_frame", "classical": "classical_frame"}

# ----------------------------------------------------------------------------- the secured bus (issue 39)
# docs/can.md, "Authenticated frames": a 20-byte CAN FD frame, bytes 0..7 the classic frame,
# 8..11 the low 32 bits of the sender's freshness value (little-endian), 12..19 the first 8
# bytes of AES-CMAC under the ID owner's key over ID (2 bytes, big-endian), bytes 0..7 and the
# full 64-bit freshness value (big-endian); a value is new if above the newest accepted on the
# ID by at most 65,536; a failed authenticator refuses the ID as a second sender does.
SECURED_BYTES, FRESHNESS_LOW_BYTES, AUTHENTICATOR_BYTES = 20, 4, 8
FRESHNESS_AHEAD = 65536
OWNER_OF = {**{fid: f"ch{i}" for i, fid in enumerate(OBSTACLES)}, TRAIN_STATE: "train",
            **{fid: "monitor" for fid in OUTPUTS}}


def authenticator(key: bytes, frame_id: int, payload: bytes, freshness: int) -> bytes:
    from cryptography.hazmat.primitives import cmac
    from cryptography.hazmat.primitives.ciphers import algorithms

    mac = cmac.CMAC(algorithms.AES(key))
    mac.update(frame_id.to_bytes(2, "big") + payload + freshness.to_bytes(8, "big"))
    return mac.finalize()[:AUTHENTICATOR_BYTES]


def full_freshness(newest: Optional[int], low: int) -> int:
    """The smallest freshness value above `newest` (-1 if none yet) whose low 32 bits are `low`."""
    floor = -1 if newest is None else newest
    value = ((floor + 1) >> 32 << 32) | low
    return value if value > floor else value + (1 << 32)
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
    2. not an error frame and 29-bit, or an ID outside 0x010, 0x020-0x025, 0x030, 0x040, 0x041 ->
       `filtered` (the receive filter drops it: not a reject);
    3. an error, remote or FD frame -> error_frame, remote_frame, fd_frame;
    4. on the output IDs 0x010, 0x040 or 0x041 -> foreign_output; ForeignOutput is set in every cycle
       within FOREIGN_HOLD_CYCLES periods of it;
    (secured bus: FD frames are the decoded kind, a classical one -> classical_frame; and after
    the rate policing of rule 5, rule 5a: not 20 bytes -> wrong_length, a freshness value not
    new -> stale_freshness, an authenticator that fails -> bad_mac, the ID refused as for a
    second sender; then rule 5 on bytes 0..7)
    5. an ID not in the DBC -> unknown_id; on an input ID (obstacle channels, TrainState) every
       frame counts for the rate, valid or not, before length and CRC: more than
       MAX_FRAMES_PER_WINDOW frames within the window (one period) quarantines the ID until
       BABBLE_QUARANTINE_MS after its last excess frame; while quarantined -> rate_exceeded,
       the channel's report withdrawn and the ID's alive counter forgotten (the next frame
       that passes the CRC resynchronises without a counter check); then not 8 bytes ->
       wrong_length; CRC -> bad_crc; a frame with the alive counter of the ID's previous
       CRC-valid frame, arrived less than SAME_COUNTER_WINDOW_MS after it and not byte for
       byte equal to it, means a second sender: the ID is refused until
       SECOND_SENDER_REFUSAL_MS after the newest such frame -> second_sender, the channel's
       report withdrawn (the counter is not remembered from refused frames); the alive
       counter is remembered from here on whatever follows; equal to the last -> repeated_counter, not last + 1 -> counter_jump; a signal
       outside its DBC range, or a report claiming another (or a missing) channel ->
       out_of_range; otherwise accepted and latched with the arrival tick.
    """

    def __init__(self, channels: int, window_ms: int, keys: Optional[dict] = None) -> None:
        self.channels = channels
        self.window = window_ms
        self.keys = keys                  # sender -> key: a secured bus (rule 5a), None: unsecured
        self.decoded = "classical" if keys is None else "fd"
        self.newest_freshness: dict = {}
        self.reports: list = [None] * channels
        self.train: Optional[Train] = None
        self.train_tick: Optional[int] = None
        self.counter: dict = {}
        self.times: dict = {}
        self.quarantine_until: dict = {}
        self.previous: dict = {}          # ID -> (tick, bytes) of its newest CRC-valid frame
        self.refused_until: dict = {}     # ID -> end of its second-sender refusal
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
        if kind != self.decoded:          # (secured: a classical frame is an unsecured one)
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
            if len(times) > MAX_FRAMES_PER_WINDOW:
                self.quarantine_until[fid] = now + BABBLE_QUARANTINE_MS
            if now < self.quarantine_until.get(fid, now):
                ch = fid - OBSTACLES[0]
                if fid in OBSTACLES and ch < self.channels:
                    self.reports[ch] = None
                self.counter[fid] = None
                return "rate_exceeded"
        if self.keys is not None:
            data, refusal = self.opened(fid, data, now)
            if refusal:
                return refusal
        if len(data) != 8:
            return "wrong_length"
        if e2e_crc(data, fid) != data[0]:
            return "bad_crc"
        before = self.previous.get(fid)
        self.previous[fid] = (now, data)
        if before is not None and now - before[0] < SAME_COUNTER_WINDOW_MS and before[1] != data \
                and before[1][1] & 0xF == data[1] & 0xF:
            self.refused_until[fid] = now + SECOND_SENDER_REFUSAL_MS
        if now < self.refused_until.get(fid, now):
            if fid in OBSTACLES and fid - OBSTACLES[0] < self.channels:
                self.reports[fid - OBSTACLES[0]] = None
            return "second_sender"
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

    def opened(self, fid: int, data: bytes, now: int) -> tuple:
        """Rule 5a, a secured bus: (the 8-byte classic frame, "") or (data, the refusal)."""
        if len(data) != SECURED_BYTES:
            return data, "wrong_length"
        newest = self.newest_freshness.get(fid)
        value = full_freshness(newest, int.from_bytes(data[8:8 + FRESHNESS_LOW_BYTES], "little"))
        if value - (-1 if newest is None else newest) > FRESHNESS_AHEAD:
            return data, "stale_freshness"
        if authenticator(self.keys[OWNER_OF[fid]], fid, data[:8], value) != data[8 + FRESHNESS_LOW_BYTES:]:
            self.refused_until[fid] = now + SECOND_SENDER_REFUSAL_MS
            if fid in OBSTACLES and fid - OBSTACLES[0] < self.channels:
                self.reports[fid - OBSTACLES[0]] = None
            return data, "bad_mac"
        self.newest_freshness[fid] = value
        return data[:8], ""

    def foreign(self, tick: int, period: int) -> bool:
        """Must the cycle at `tick` set the ForeignOutput diagnostic?"""
        return self.foreign_tick is not None and tick - self.foreign_tick <= FOREIGN_HOLD_CYCLES * period
