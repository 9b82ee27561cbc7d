"""The CAN message set (can_bus/railguard.dbc) and its E2E codec (can_bus/codec.py).

The receive checks are compared against an independent reference written here from the DBC
and the AUTOSAR E2E profile 2 layout (own CRC-8 0x2F, own bit extraction, own counter rule),
so a wrong implementation shows up as a disagreement frame by frame.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cantools
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from can_bus import codec
from can_bus.codec import (
    BRAKE_DEMAND_ID, MONITOR_RISK_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, OBSTACLE_IDS, REJECT_REASONS, TRAIN_STATE_ID, Receiver,
    Sender, encode, report_signals,
)
from monitor.core import cycle as core
from monitor.core.config import Config
from monitor.core.freshness import channel_status
from monitor.core.types import ABSENT, DEGRADED, PRESENT, R_STALE, Inputs, Report, Train

ROOT = Path(__file__).resolve().parents[1]
DBC_PATH = ROOT / "can_bus" / "railguard.dbc"
TABLES = ROOT / "monitor" / "tables"

MESSAGE_NAMES = {
    0x10: "BrakeDemand",
    0x20: "ObstacleReport_M1C1", 0x21: "ObstacleReport_M1C2",
    0x22: "ObstacleReport_M2C1", 0x23: "ObstacleReport_M2C2",
    0x24: "ObstacleReport_M3C1", 0x25: "ObstacleReport_M3C2",
    0x30: "TrainState",
    0x40: "MonitorStatus",
    0x42: "MonitorRisk",
    0x41: "MonitorTrack",
}
KNOWN_IDS = tuple(MESSAGE_NAMES)


# ----------------------------------------------------------------------------- reference

def crc8_h2f(data: bytes) -> int:
    """CRC-8 polynomial 0x2F (AUTOSAR CRC8H2F): init 0xFF, no reflection, xor-out 0xFF."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x2F) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def ref_crc(data: bytes, frame_id: int) -> int:
    """Profile 2: CRC over bytes 1..7 followed by the data ID (low byte of the frame ID)."""
    return crc8_h2f(bytes(data[1:8]) + bytes([frame_id & 0xFF]))


def field(data: bytes, start: int, length: int, signed: bool = False) -> int:
    """A little-endian (Intel) bit field of an 8-byte payload."""
    v = (int.from_bytes(bytes(data), "little") >> start) & ((1 << length) - 1)
    if signed and v >= 1 << (length - 1):
        v -= 1 << length
    return v


def ref_in_range(frame_id: int, data: bytes) -> bool:
    """Every signal inside the range the DBC gives it (raw units)."""
    if frame_id in OBSTACLE_IDS:
        ch = frame_id - 0x20
        return (field(data, 12, 2) <= 2 and field(data, 14, 2) <= 2 and field(data, 16, 16) <= 60000
                and -15000 <= field(data, 32, 16, signed=True) <= 15000
                and field(data, 48, 2) == ch // 2 and field(data, 50, 1) == ch % 2)
    if frame_id == TRAIN_STATE_ID:
        return field(data, 16, 16) <= 12000
    if frame_id == BRAKE_DEMAND_ID:
        return field(data, 12, 2) <= 2 and field(data, 16, 16) <= 32767
    if frame_id == MONITOR_TRACK_ID:
        return field(data, 12, 3) <= 5        # TrackState; Memory, TrackDistance and TrackAge span their bits
    if frame_id == MONITOR_RISK_ID:           # category 1..4, score 0..20, R1 <= 50 %, R2 <= 100 %, <= 10^6 ppm
        return (1 <= field(data, 12, 3) <= 4 and field(data, 16, 5) <= 20 and field(data, 21, 10) <= 500
                and field(data, 31, 11) <= 1000 and field(data, 42, 20) <= 1_000_000)
    return True    # MonitorStatus: every signal spans its full bit width


class RefReceiver:
    """Independent model of the receive rules: id, length, CRC, a second sender, counter (with
    resync), range."""

    def __init__(self) -> None:
        self.counters: dict[int, int] = {}
        self.reports: list = [None] * 6
        self.train = None
        self.accepted = 0
        self.rejected: dict[str, int] = {}
        self.previous: dict[int, tuple] = {}     # ID -> (tick, bytes) of its last CRC-valid frame
        self.refused_until: dict[int, int] = {}  # a second sender: the ID refused until then

    def expect(self, frame_id: int, data: bytes, tick: int):
        """(message name or None, reject reason or None)"""
        if frame_id not in MESSAGE_NAMES:
            return None, "unknown_id"
        if len(data) != 8:
            return None, "wrong_length"
        if data[0] != ref_crc(data, frame_id):
            return None, "bad_crc"
        # issue 39: the counter of the previous CRC-valid frame again, within 0.5 s, other bytes:
        # two senders on the ID; refused (what it latched withdrawn) for 1 s after the last one
        before, self.previous[frame_id] = self.previous.get(frame_id), (tick, data)
        if before is not None and tick - before[0] < 500 and before[1][1] & 0xF == data[1] & 0xF and before[1] != data:
            self.refused_until[frame_id] = tick + 1000
        if tick < self.refused_until.get(frame_id, tick):
            if frame_id in OBSTACLE_IDS:
                self.reports[frame_id - 0x20] = None
            return None, "second_sender"
        c = data[1] & 0xF
        last = self.counters.get(frame_id)
        if last is not None:
            delta = (c - last) & 0xF
            if delta == 0:
                return None, "repeated_counter"
            if delta != 1:
                self.counters[frame_id] = c
                return None, "counter_jump"
        self.counters[frame_id] = c
        if not ref_in_range(frame_id, data):
            return None, "out_of_range"
        if frame_id in OBSTACLE_IDS:
            self.reports[frame_id - 0x20] = Report(field(data, 12, 2), field(data, 16, 16),
                                                   field(data, 32, 16, signed=True), field(data, 14, 2), tick)
        elif frame_id == TRAIN_STATE_ID:
            self.train = Train(field(data, 16, 16), field(data, 12, 1), field(data, 13, 1))
        return MESSAGE_NAMES[frame_id], None

    def feed(self, frame_id: int, data: bytes, tick: int):
        name, reason = self.expect(frame_id, data, tick)
        if reason is None:
            self.accepted += 1
        else:
            self.rejected[reason] = self.rejected.get(reason, 0) + 1
        return name, reason


def test_reference_crc_matches_the_autosar_check_value():
    # the published check value of CRC-8/AUTOSAR ("123456789")
    assert crc8_h2f(b"123456789") == 0xDF


# ----------------------------------------------------------------------------- the DBC

def test_dbc_loads_with_cantools_and_is_the_packaged_one():
    db = cantools.database.load_file(str(DBC_PATH))
    assert {m.frame_id: m.name for m in db.messages} == MESSAGE_NAMES
    packaged = codec.database()
    assert {m.frame_id: m.name for m in packaged.messages} == MESSAGE_NAMES


def test_dbc_ids_are_ordered_by_safety_priority_and_e2e_layout():
    db = cantools.database.load_file(str(DBC_PATH))
    ids = {m.name: m.frame_id for m in db.messages}
    # the brake demand wins arbitration against everything else
    assert ids["BrakeDemand"] == min(ids.values())
    assert all(v > ids["BrakeDemand"] for k, v in ids.items() if k != "BrakeDemand")
    assert (codec.BRAKE_DEMAND_ID, codec.TRAIN_STATE_ID, codec.MONITOR_STATUS_ID, codec.MONITOR_TRACK_ID) == (
        ids["BrakeDemand"], ids["TrainState"], ids["MonitorStatus"], ids["MonitorTrack"])
    # the monitor's outputs in the order it sends them; the track right after the status, then the risk
    assert codec.OUTPUT_IDS == (ids["BrakeDemand"], ids["MonitorStatus"], ids["MonitorTrack"], ids["MonitorRisk"])
    assert codec.MONITOR_RISK_ID == ids["MonitorRisk"]
    assert codec.OBSTACLE_IDS == tuple(ids[f"ObstacleReport_M{m}C{c}"] for m in (1, 2, 3) for c in (1, 2))
    # data IDs (low byte of the frame ID) are distinct, so a frame cannot pass as another
    assert len({codec.data_id(i) for i in ids.values()}) == len(ids)
    for msg in db.messages:
        assert msg.length == 8, msg.name
        assert not msg.is_extended_frame, msg.name
        sig = {s.name: s for s in msg.signals}
        assert (sig["Crc"].start, sig["Crc"].length, sig["Crc"].is_signed) == (0, 8, False), msg.name
        assert (sig["Counter"].start, sig["Counter"].length, sig["Counter"].is_signed) == (8, 4, False), msg.name
        assert sig["Crc"].byte_order == "little_endian" and sig["Counter"].byte_order == "little_endian"
        # no signal overlaps the CRC or the counter, and none overlaps another
        used: set[int] = set()
        for s in msg.signals:
            bits = set(range(s.start, s.start + s.length))
            assert not (bits & used), (msg.name, s.name)
            assert max(bits) < 64
            used |= bits


def test_cantools_dump_lists_every_message():
    proc = subprocess.run([sys.executable, "-m", "cantools", "dump", str(DBC_PATH)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    for name in MESSAGE_NAMES.values():
        assert name in proc.stdout, name


# ----------------------------------------------------------------------------- encode / round trip

reports = st.builds(
    Report,
    status=st.integers(0, 2),
    distance_dm=st.integers(0, 60000),
    closing_cms=st.integers(-15000, 15000),
    obstacle=st.integers(0, 2),
    tick=st.just(0),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 5), reports, st.integers(0, 2**40)), min_size=1, max_size=20))
def test_round_trip_latches_exactly_the_report(items):
    sender, rx = Sender(), Receiver()
    expected = [None] * 6
    sent_per_id: dict[int, int] = {}
    for n, (ch, rep, tick) in enumerate(items, start=1):
        fid = OBSTACLE_IDS[ch]
        data = sender.frame(fid, report_signals(rep, ch))
        assert len(data) == 8
        # the E2E layout, checked independently of cantools
        assert data[0] == ref_crc(data, fid)
        assert data[1] & 0xF == sent_per_id.get(fid, 0) % 16
        sent_per_id[fid] = sent_per_id.get(fid, 0) + 1
        assert field(data, 48, 2) == ch // 2 and field(data, 50, 1) == ch % 2
        assert rx.accept(fid, data, tick) == MESSAGE_NAMES[fid]
        expected[ch] = rep._replace(tick=tick)
        assert rx.reports == expected
        assert rx.accepted == n and rx.rejected_total == 0


@settings(max_examples=100, deadline=None)
@given(speed=st.integers(0, 12000), track=st.integers(0, 1), brake=st.integers(0, 1),
       level=st.integers(0, 2), reason=st.integers(0, 32767), cyc=st.integers(0, 2**32 - 1),
       mode=st.integers(0, 3), misses=st.integers(0, 15), dist=st.integers(0, 65535),
       t_state=st.integers(0, 5), memory=st.integers(0, 1), t_dist=st.integers(0, 65535), age=st.integers(0, 65535))
def test_round_trip_other_messages(speed, track, brake, level, reason, cyc, mode, misses, dist, t_state, memory,
                                   t_dist, age):
    sender, rx = Sender(), Receiver()
    data = sender.frame(TRAIN_STATE_ID, {"Speed": speed, "TrackCondition": track, "BrakeStatus": brake})
    assert rx.accept(TRAIN_STATE_ID, data, 7) == "TrainState"
    assert rx.train == Train(speed, track, brake) and rx.train_tick == 7
    data = sender.frame(BRAKE_DEMAND_ID, {"Level": level, "Reason": reason, "Cycle": cyc})
    assert rx.accept(BRAKE_DEMAND_ID, data, 8) == "BrakeDemand"
    assert (rx.demand["Level"], rx.demand["Reason"], rx.demand["Cycle"], rx.demand["tick"]) == (level, reason, cyc, 8)
    data = sender.frame(MONITOR_STATUS_ID, {"Mode": mode, "DeadlineMisses": misses, "VotedDistance": dist})
    assert rx.accept(MONITOR_STATUS_ID, data, 9) == "MonitorStatus"
    assert (rx.status["Mode"], rx.status["DeadlineMisses"], rx.status["VotedDistance"]) == (mode, misses, dist)
    data = sender.frame(MONITOR_TRACK_ID, {"TrackState": t_state, "Memory": memory, "TrackDistance": t_dist,
                                           "TrackAge": age})
    assert data[0] == ref_crc(data, MONITOR_TRACK_ID)
    assert (field(data, 12, 3), field(data, 15, 1), field(data, 16, 16), field(data, 32, 16), field(data, 48, 16)) == (
        t_state, memory, t_dist, age, 0)                       # bits 48-63 reserved: zero
    assert rx.accept(MONITOR_TRACK_ID, data, 10) == "MonitorTrack"
    assert (rx.track["TrackState"], rx.track["Memory"], rx.track["TrackDistance"], rx.track["TrackAge"],
            rx.track["tick"]) == (t_state, memory, t_dist, age, 10)
    assert rx.rejected_total == 0


def test_track_state_beyond_the_table_is_out_of_range():
    rx = Receiver()
    assert rx.accept(MONITOR_TRACK_ID, encode(MONITOR_TRACK_ID, {"TrackState": 5}, 0), 1) == "MonitorTrack"
    assert rx.accept(MONITOR_TRACK_ID, encode(MONITOR_TRACK_ID, {"TrackState": 6}, 1), 2) is None
    assert rx.rejected["out_of_range"] == 1 and rx.track["TrackState"] == 5


def test_sender_counter_wraps_modulo_16_and_receiver_follows():
    sender, rx = Sender(), Receiver()
    rep = Report(PRESENT, 1234, 56, 0, 0)
    for i in range(40):
        data = sender.frame(0x22, report_signals(rep, 2))
        assert data[1] & 0xF == i % 16
        assert rx.accept(0x22, data, i) == "ObstacleReport_M2C1"
    assert rx.accepted == 40 and rx.rejected_total == 0


# ----------------------------------------------------------------------------- rejections

GOOD = Report(PRESENT, 4321, -250, 1, 0)


def primed(ch: int = 0):
    """A receiver that has latched one valid report of channel ch at tick 100, and its sender."""
    sender, rx = Sender(), Receiver()
    data = sender.frame(OBSTACLE_IDS[ch], report_signals(GOOD, ch))
    assert rx.accept(OBSTACLE_IDS[ch], data, 100) is not None
    return sender, rx


def assert_dropped(rx: Receiver, reason: str, count: int = 1, ch: int = 0) -> None:
    assert rx.rejected[reason] == count, dict(rx.rejected)
    assert rx.rejected_total == count, dict(rx.rejected)
    assert rx.reports[ch] == GOOD._replace(tick=100)
    assert all(r is None for i, r in enumerate(rx.reports) if i != ch)


def test_every_bit_flip_is_a_bad_crc_and_dropped():
    sender, rx = primed()
    other = Report(ABSENT, 0, 0, 0, 0)
    data = sender.frame(0x20, report_signals(other, 0))
    for bit in range(64):
        bad = bytearray(data)
        bad[bit // 8] ^= 1 << (bit % 8)
        assert rx.accept(0x20, bytes(bad), 200 + bit) is None, bit
    assert_dropped(rx, "bad_crc", 64)
    # the unflipped frame still passes: a CRC failure does not advance the counter
    assert rx.accept(0x20, data, 999) == "ObstacleReport_M1C1"
    assert rx.reports[0] == other._replace(tick=999)


def test_crc_uses_the_data_id_of_the_frame():
    """A valid frame of channel 1 moved onto channel 2's ID fails the CRC (different data ID)."""
    sender, rx = primed()
    data = Sender().frame(0x21, report_signals(Report(PRESENT, 10, 0, 0, 0), 1))
    assert rx.accept(0x20, data, 200) is None
    assert_dropped(rx, "bad_crc")


def test_repeated_frame_is_rejected():
    sender, rx = Sender(), Receiver()
    data = sender.frame(0x20, report_signals(GOOD, 0))
    assert rx.accept(0x20, data, 100) == "ObstacleReport_M1C1"
    assert rx.accept(0x20, data, 200) is None
    assert_dropped(rx, "repeated_counter")   # the latched tick stays 100


def test_counter_jump_is_rejected_then_resynchronises():
    sender, rx = primed()
    newer = Report(PRESENT, 100, 10, 0, 0)
    sender.counters[0x20] += 3                     # skip counters 1, 2, 3
    jumped = sender.frame(0x20, report_signals(newer, 0))
    assert jumped[1] & 0xF == 4
    assert rx.accept(0x20, jumped, 200) is None
    assert_dropped(rx, "counter_jump")
    nxt = sender.frame(0x20, report_signals(newer, 0))
    assert rx.accept(0x20, nxt, 300) == "ObstacleReport_M1C1"
    assert rx.reports[0] == newer._replace(tick=300)
    assert rx.rejected_total == 1


def test_counter_going_backwards_is_a_jump():
    sender, rx = primed()
    sender.frame(0x20, report_signals(GOOD, 0))
    sender.counters[0x20] = 14                     # next frame carries 15 = -1 after 0
    back = sender.frame(0x20, report_signals(GOOD, 0))
    assert rx.accept(0x20, back, 200) is None
    assert_dropped(rx, "counter_jump")


def test_counters_are_per_frame_id():
    sender, rx = primed(0)
    # channel 1's first frame has counter 0 like channel 0's: not a repetition
    data = sender.frame(0x21, report_signals(GOOD, 1))
    assert data[1] & 0xF == 0
    assert rx.accept(0x21, data, 150) == "ObstacleReport_M1C2"
    assert rx.rejected_total == 0


@pytest.mark.parametrize("length", [0, 1, 7, 9, 64])
def test_wrong_length_is_rejected(length):
    sender, rx = primed()
    data = sender.frame(0x20, report_signals(Report(ABSENT, 0, 0, 0, 0), 0))
    bad = (data + bytes(64))[:length]
    assert rx.accept(0x20, bad, 200) is None
    assert_dropped(rx, "wrong_length")


@pytest.mark.parametrize("frame_id", [0x0, 0x11, 0x1F, 0x26, 0x31, 0x43, 0x7FF, 0x120])
def test_unknown_id_is_rejected(frame_id):
    sender, rx = primed()
    data = encode(0x20, report_signals(GOOD, 0), 1)
    assert rx.accept(frame_id, data, 200) is None
    assert_dropped(rx, "unknown_id")


@pytest.mark.parametrize("signals", [
    {"Status": 3},
    {"ObstacleType": 3},
    {"Distance": 60001},
    {"Distance": 65535},
    {"ClosingSpeed": 15001},
    {"ClosingSpeed": -15001},
    {"Module": 2},             # a report on M1C1's ID claiming module 3
    {"Module": 3},
    {"Channel": 1},            # ... claiming channel 2
], ids=lambda s: ",".join(f"{k}={v}" for k, v in s.items()))
def test_out_of_range_with_correct_crc_is_rejected(signals):
    sender, rx = primed()
    values = dict(report_signals(Report(PRESENT, 500, 0, 0, 0), 0), **signals)
    data = encode(0x20, values, 1)
    assert data[0] == ref_crc(data, 0x20)           # the CRC is right: only the range is wrong
    assert rx.accept(0x20, data, 200) is None
    assert_dropped(rx, "out_of_range")


def test_out_of_range_train_and_demand_are_rejected():
    rx = Receiver()
    assert rx.accept(TRAIN_STATE_ID, encode(TRAIN_STATE_ID, {"Speed": 12001}, 0), 1) is None
    assert rx.train is None and rx.train_tick is None
    assert rx.accept(BRAKE_DEMAND_ID, encode(BRAKE_DEMAND_ID, {"Level": 3}, 0), 1) is None
    assert rx.accept(BRAKE_DEMAND_ID, encode(BRAKE_DEMAND_ID, {"Reason": 32768}, 1), 1) is None
    assert rx.demand is None
    assert rx.rejected["out_of_range"] == 3 and rx.accepted == 0


def test_boundary_values_are_accepted():
    rx = Receiver()
    for i, (status, dist, closing, obs) in enumerate([(2, 60000, 15000, 2), (0, 0, -15000, 0)]):
        rep = Report(status, dist, closing, obs, 0)
        assert rx.accept(0x25, encode(0x25, report_signals(rep, 5), i), i) == "ObstacleReport_M3C2"
        assert rx.reports[5] == rep._replace(tick=i)
    assert rx.accept(TRAIN_STATE_ID, encode(TRAIN_STATE_ID, {"Speed": 12000}, 0), 5) == "TrainState"
    assert rx.rejected_total == 0


def test_a_report_claiming_another_channel_of_a_smaller_topology():
    """With the 2oo2 topology (two channels) a report of module 2 is not latched anywhere."""
    rx = Receiver(channels=2)
    assert len(rx.reports) == 2
    assert rx.accept(0x22, encode(0x22, report_signals(GOOD, 2), 0), 1) is None
    assert rx.reports == [None, None] and rx.rejected["out_of_range"] == 1 and rx.accepted == 0


@pytest.mark.parametrize("frame_id,data", [
    (None, bytes(8)), ("abc", bytes(8)), (0x20, None), (0x20, "not bytes"), (0x20, 12.5), (object(), b""),
])
def test_accept_never_raises_on_garbage_arguments(frame_id, data):
    rx = Receiver()
    assert rx.accept(frame_id, data, 0) is None
    assert rx.rejected_total == 1 and rx.accepted == 0
    assert set(rx.rejected) <= set(REJECT_REASONS)


# ----------------------------------------------------------------------------- fuzzing

def _signal_strategy(frame_id: int):
    """Raw signal values: mostly in range, sometimes anything the bit width holds."""
    def val(lo, hi, full_lo, full_hi):
        return st.one_of(st.integers(lo, hi), st.integers(lo, hi), st.integers(full_lo, full_hi))

    if frame_id in OBSTACLE_IDS:
        ch = frame_id - 0x20
        return st.fixed_dictionaries({
            "Status": val(0, 2, 0, 3), "ObstacleType": val(0, 2, 0, 3), "Distance": val(0, 60000, 0, 65535),
            "ClosingSpeed": val(-15000, 15000, -32768, 32767), "Module": val(ch // 2, ch // 2, 0, 3),
            "Channel": val(ch % 2, ch % 2, 0, 1)})
    if frame_id == TRAIN_STATE_ID:
        return st.fixed_dictionaries({"Speed": val(0, 12000, 0, 65535), "TrackCondition": st.integers(0, 1),
                                      "BrakeStatus": st.integers(0, 1)})
    if frame_id == BRAKE_DEMAND_ID:
        return st.fixed_dictionaries({"Level": val(0, 2, 0, 3), "Reason": val(0, 32767, 0, 65535), "Warning": st.integers(0, 1),
                                      "Cycle": st.integers(0, 2**32 - 1)})
    if frame_id == MONITOR_TRACK_ID:
        return st.fixed_dictionaries({"TrackState": val(0, 5, 0, 7), "Memory": st.integers(0, 1),
                                      "TrackDistance": st.integers(0, 65535), "TrackAge": st.integers(0, 65535)})
    if frame_id == MONITOR_RISK_ID:
        return st.fixed_dictionaries({"RiskCategory": val(1, 4, 0, 7), "RiskScore": val(0, 20, 0, 31),
                                      "R1": val(0, 500, 0, 1023), "R2": val(0, 1000, 0, 2047),
                                      "TableRisk": val(0, 1_000_000, 0, 2**20 - 1)})
    return st.fixed_dictionaries({"Mode": st.integers(0, 3), "Node": st.integers(0, 1023),
                                  "ErrorFlags": st.integers(0, 63), "VotedDistance": st.integers(0, 65535),
                                  "TableHash": st.integers(0, 4095), "DeadlineMisses": st.integers(0, 15)})


MUTATIONS = ("none", "none", "bitflip", "truncate", "extend", "counter_set", "counter_set_fixed_crc",
             "skip", "repeat", "random_payload_fixed_crc")


@st.composite
def frame_ops(draw):
    kind = draw(st.sampled_from(("raw", "valid", "valid", "valid")))
    if kind == "raw":
        fid = draw(st.one_of(st.sampled_from(KNOWN_IDS), st.integers(0, 0x7FF)))
        return ("raw", fid, draw(st.binary(min_size=0, max_size=64)))
    fid = draw(st.sampled_from(KNOWN_IDS))
    return ("valid", fid, draw(_signal_strategy(fid)), draw(st.sampled_from(MUTATIONS)),
            draw(st.integers(0, 63)), draw(st.integers(0, 15)), draw(st.binary(min_size=7, max_size=7)))


def _with_crc(frame_id: int, data: bytes) -> bytes:
    data = bytearray(data)
    data[0] = ref_crc(data, frame_id)
    return bytes(data)


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(frame_ops(), min_size=1, max_size=40))
def test_fuzzed_frame_sequences_agree_with_the_reference(ops):
    rx, ref, sender = Receiver(), RefReceiver(), Sender()
    last: dict[int, bytes] = {}
    names = set(MESSAGE_NAMES.values())
    for n, op in enumerate(ops, start=1):
        if op[0] == "raw":
            _, fid, data = op
        else:
            _, fid, signals, mutation, pos, value, payload = op
            if mutation == "skip":
                sender.counters[fid] = (sender.counters.get(fid, -1) + 1 + value) & 0xF
            data = bytearray(sender.frame(fid, signals))
            if mutation == "bitflip":
                data[pos // 8] ^= 1 << (pos % 8)
            elif mutation == "truncate":
                data = data[: pos % 8]
            elif mutation == "extend":
                data = data + bytes(1 + pos % 8)
            elif mutation == "counter_set":
                data[1] = (data[1] & 0xF0) | value
            elif mutation == "counter_set_fixed_crc":
                data[1] = (data[1] & 0xF0) | value
                data = bytearray(_with_crc(fid, data))
            elif mutation == "repeat" and fid in last:
                data = bytearray(last[fid])
            elif mutation == "random_payload_fixed_crc":
                data = bytearray(_with_crc(fid, bytes(1) + payload))
            data = bytes(data)
            last[fid] = data
        tick = 10 * n
        before = (rx.accepted, rx.rejected_total)
        got = rx.accept(fid, data, tick)
        want, reason = ref.feed(fid, data, tick)
        assert got is None or got in names
        assert got == want, (hex(fid), data.hex(), reason, dict(rx.rejected))
        # exactly one of the two counters moved, by one
        if got is None:
            assert (rx.accepted, rx.rejected_total) == (before[0], before[1] + 1)
            assert rx.rejected[reason] == ref.rejected[reason], (reason, dict(rx.rejected))
        else:
            assert (rx.accepted, rx.rejected_total) == (before[0] + 1, before[1])
        assert rx.accepted + rx.rejected_total == n
        assert set(rx.rejected) <= set(REJECT_REASONS)
        assert dict(rx.rejected) == ref.rejected
        assert rx.reports == ref.reports
        assert rx.train == ref.train


@settings(max_examples=500, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 0x7FF), st.binary(min_size=0, max_size=64)), min_size=1, max_size=30))
def test_arbitrary_frames_never_raise_and_are_all_counted(frames):
    rx = Receiver()
    names = set(MESSAGE_NAMES.values())
    for n, (fid, data) in enumerate(frames, start=1):
        got = rx.accept(fid, data, n)
        assert got is None or got == MESSAGE_NAMES.get(fid)
        assert got is None or got in names
        assert rx.accepted + rx.rejected_total == n
        assert set(rx.rejected) <= set(REJECT_REASONS)
        if fid not in MESSAGE_NAMES:
            assert got is None
        if len(data) != 8:
            assert got is None


# ----------------------------------------------------------------------------- ageing in the core

def test_a_channel_with_only_rejected_frames_ages_into_degraded():
    setup = core.create(Config(), (TABLES / "m2.table.rgt").read_bytes())
    timeout = setup.timeout_ticks
    assert timeout == 300
    period = setup.config.period_ms
    sender, rx = Sender(), Receiver()
    absent = Report(ABSENT, 0, 0, 0, 0)
    state = core.initial_state(setup)
    last_good = 500
    statuses, stale_bits = {}, {}
    for tick in range(0, 1500, period):
        # every other channel and the train stay healthy
        for ch in range(1, 6):
            assert rx.accept(OBSTACLE_IDS[ch], sender.frame(OBSTACLE_IDS[ch], report_signals(absent, ch)), tick)
        assert rx.accept(TRAIN_STATE_ID, sender.frame(TRAIN_STATE_ID, {"Speed": 0}), tick)
        data = bytearray(sender.frame(0x20, report_signals(absent, 0)))
        if tick > last_good:
            data[3] ^= 0x10                           # corrupted from here on
            assert rx.accept(0x20, bytes(data), tick) is None
        else:
            assert rx.accept(0x20, bytes(data), tick) == "ObstacleReport_M1C1"
        assert rx.reports[0].tick == min(tick, last_good)
        statuses[tick] = channel_status(rx.reports[0], tick, timeout)
        state, out = core.step(setup, state, Inputs(tuple(rx.reports), rx.train, 0), tick)
        stale_bits[tick] = bool(out.reasons & R_STALE)
    assert rx.rejected["bad_crc"] == len([t for t in statuses if t > last_good])
    for tick, status in statuses.items():
        if tick <= last_good + timeout:
            assert status == ABSENT, tick
            assert not stale_bits[tick], tick
        else:
            assert status == DEGRADED, tick
            assert stale_bits[tick], tick


def test_babbling_sender_is_quarantined_and_its_report_withdrawn():
    """A sender with more than 3 frames in one 100 ms window is babbling: its frames are
    refused, its latched report is withdrawn (the core then sees the channel DEGRADED), and
    it is heard again only after BABBLE_QUARANTINE_MS of normal pace. Jitter is tolerated."""
    from can_bus.codec import BABBLE_QUARANTINE_MS

    rx = Receiver(rate_window_ms=100)
    tx = Sender()
    rep = Report(PRESENT, 1234, 0, 0, 0)
    # jitter: two frames 5 ms apart, then the usual pace: all accepted
    for tick in (-300, -205, -200, -100):
        assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), tick) == "ObstacleReport_M2C1"
    assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), 0) == "ObstacleReport_M2C1"
    assert rx.reports[2] is not None
    assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), 10) == "ObstacleReport_M2C1"
    assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), 20) == "ObstacleReport_M2C1"
    for tick in range(30, 200, 10):                      # the 4th frame within 100 ms: babbling
        assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), tick) is None
    assert rx.reports[2] is None
    assert rx.rejected["rate_exceeded"] == 17 and rx.rejected_total == 17
    last = 190
    assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), last + 100) is None    # still quarantined
    back = last + 100 + BABBLE_QUARANTINE_MS
    assert rx.accept(0x22, tx.frame(0x22, report_signals(rep, 2)), back) == "ObstacleReport_M2C1"
    assert rx.reports[2].tick == back
    # other senders were never affected, and the monitor's own messages are not rate-checked
    assert rx.accept(0x23, tx.frame(0x23, report_signals(rep, 3)), 15) == "ObstacleReport_M2C2"
    assert rx.accept(0x10, tx.frame(0x10, {"Level": 2}), 15) == "BrakeDemand"
    assert rx.accept(0x10, tx.frame(0x10, {"Level": 2}), 16) == "BrakeDemand"
