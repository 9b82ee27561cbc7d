"""The front-door fuzzing (verification/fuzz.py): a quick run through the real runner is
clean, nasty frames land under the right reject reason, the reference receiver reads the
DBC as cantools does, and planted bugs in the codec, the runner path or the core are caught."""
from __future__ import annotations

import can
import pytest

from can_bus import codec
from can_bus.clock import SimClock
from can_bus.codec import Receiver
from can_bus.runner import MonitorRunner
from monitor.core import cycle as core
from monitor.core.types import Report
from verification import fuzz
from verification.report import Section


def quiet(_: str) -> None:
    pass


# ----------------------------------------------------------------------------- the whole thing

def test_quick_section_passes_with_exact_accounting(tmp_path):
    sec = fuzz.section(tmp_path, True, quiet)
    assert isinstance(sec, Section)
    failed = [c.line() for c in sec.checks if not c.passed]
    assert not failed, failed
    names = " ".join(c.name for c in sec.checks)
    for word in ("frames", "exception", "violation", "accounting", "coverage"):
        assert word in names
    assert "rate_exceeded" in sec.markdown and "| accepted |" in sec.markdown


def test_quick_run_figures():
    r = fuzz.run(8000, quiet, seed=5, workers=1)
    assert r["frames"] >= 8000
    assert r["exceptions"] == 0 and r["violations"] == 0 and r["harness_errors"] == 0
    assert r["accounting_exact"] and r["reference_agrees"]
    assert r["frames"] == r["accepted"] + sum(r["rejected"].values())
    assert r["accepted"] > 0 and r["rejected"].get("bad_crc", 0) > 0 and r["rejected"].get("unknown_id", 0) > 0
    assert "undecodable" not in r["rejected"]
    assert r["cycles"] > 0 and r["frames_per_s"] > 0
    # the same seed gives the same frames
    again = fuzz.run(8000, quiet, seed=5, workers=1)
    assert (again["accepted"], again["rejected"], again["kinds"]) == (r["accepted"], r["rejected"], r["kinds"])


# ----------------------------------------------------------------------------- the reference receiver

def test_reference_layout_is_the_dbc():
    db = codec.database()
    assert set(fuzz.LAYOUT) == {m.frame_id for m in db.messages}
    assert fuzz.OBSTACLES == codec.OBSTACLE_IDS and fuzz.TRAIN_STATE == codec.TRAIN_STATE_ID
    assert fuzz.INPUTS == codec.INPUT_IDS
    for msg in db.messages:
        assert msg.length == 8 and not msg.is_extended_frame
        ours = {name: rest for name, *rest in fuzz.LAYOUT[msg.frame_id]}
        assert set(ours) == {s.name for s in msg.signals}
        for s in msg.signals:
            start, length, signed, lo, hi = ours[s.name]
            assert (s.start, s.length, s.is_signed, s.byte_order) == (start, length, signed, "little_endian")
            assert round((s.minimum - s.offset) / s.scale) == lo and round((s.maximum - s.offset) / s.scale) == hi


def test_reference_crc_and_unpacking_agree_with_the_codec():
    assert fuzz.crc8_h2f(b"123456789") == 0xDF        # the AUTOSAR CRC8H2F check value
    sender = codec.Sender()
    signals = {0x20: {"Status": 1, "ObstacleType": 2, "Distance": 60000, "ClosingSpeed": -15000, "Module": 0},
               0x25: {"Status": 2, "Distance": 1, "ClosingSpeed": 15000, "Module": 2, "Channel": 1},
               0x30: {"Speed": 12000, "TrackCondition": 1, "BrakeStatus": 1},
               0x10: {"Level": 2, "Warning": 1, "Reason": 8191, "Cycle": 2**32 - 1},
               0x40: {"Mode": 3, "Node": 1023, "ErrorFlags": 63, "VotedDistance": 65535, "TableHash": 4095,
                      "DeadlineMisses": 15}}
    for _ in range(17):
        for fid, sig in signals.items():
            data = sender.frame(fid, sig)
            assert fuzz.e2e_crc(data, fid) == data[0]
            values = fuzz.unpack(fid, data)
            assert values["Counter"] == sender.counters[fid]
            assert all(values[k] == v for k, v in sig.items())
            decoded = codec.database().get_message_by_frame_id(fid).decode(data, decode_choices=False, scaling=False)
            assert values == decoded
            bad = bytes([data[0] ^ 0x01]) + data[1:]
            assert fuzz.e2e_crc(bad, fid) != bad[0]


# ----------------------------------------------------------------------------- nasty frames, one by one

def msg(fid, data, *, extended=False, remote=False, error=False, fd=False):
    return can.Message(arbitration_id=fid, data=data, is_extended_id=extended, is_remote_frame=remote,
                       is_error_frame=error, is_fd=fd, check=False)


def obstacle(counter, ch=0, **over):
    sig = {"Status": 1, "ObstacleType": 0, "Distance": 1234, "ClosingSpeed": 50, "Module": ch // 2, "Channel": ch % 2}
    sig.update(over)
    return codec.encode(0x20 + ch, sig, counter)


def train(counter, speed=500):
    return codec.encode(0x30, {"Speed": speed, "TrackCondition": 0, "BrakeStatus": 0}, counter)


@pytest.fixture
def harness():
    return fuzz.Harness(fuzz.setup_for("m2", "3oo3"), fuzz.Stats())


def feed(h, t, m, reason):
    """Feed one frame; the receiver must count it under `reason` (and the reference agree)."""
    rx = h.rx
    before, accepted = dict(rx.rejected), rx.accepted
    outcome = h.feed(t, m, "test")
    assert outcome == reason
    if reason == fuzz.ACCEPTED:
        assert rx.accepted == accepted + 1 and dict(rx.rejected) == before
    else:
        assert rx.accepted == accepted
        assert rx.rejected[reason] == before.get(reason, 0) + 1
        assert sum(rx.rejected.values()) == sum(before.values()) + 1
    assert not h.failed and not h.stats.violations and h.stats.exceptions == 0


def test_nasty_frames_are_rejected_under_the_right_reason(harness):
    h = harness
    good = obstacle(0)
    feed(h, 0, msg(0x20, good), "accepted")
    assert h.rx.reports[0] == Report(1, 1234, 50, 0, 0)
    feed(h, 5, msg(0x20, bytes([good[0] ^ 0x5A]) + good[1:]), "bad_crc")                    # wrong CRC
    feed(h, 6, msg(0x20, good[:3] + bytes([good[3] ^ 0x10]) + good[4:]), "bad_crc")           # a bit flipped
    feed(h, 7, msg(0x20, good[:7]), "wrong_length")                                             # truncated
    feed(h, 8, msg(0x20, good + b"\0"), "wrong_length")                                         # extended
    feed(h, 9, msg(0x20, good + bytes(56), fd=True), "wrong_length")                           # CAN FD, 64 bytes
    feed(h, 10, msg(0x123, good), "unknown_id")                                                 # not in the DBC
    feed(h, 11, msg(0x20, good, extended=True), "unknown_id")                                   # 29-bit
    feed(h, 12, msg(0x820, good), "unknown_id")                                                 # out-of-spec 11-bit
    feed(h, 13, msg(0x20, good, remote=True), "error_or_remote_frame")                          # remote frame
    feed(h, 14, msg(0, b"", error=True), "error_or_remote_frame")                               # error frame
    feed(h, 150, msg(0x20, good), "repeated_counter")                                           # replay
    feed(h, 260, msg(0x20, obstacle(3)), "counter_jump")                                        # jump 0 -> 3
    feed(h, 370, msg(0x20, obstacle(4, Distance=60001)), "out_of_range")                      # 6000.1 m
    feed(h, 480, msg(0x20, obstacle(5, Status=3)), "out_of_range")                              # no such status
    feed(h, 590, msg(0x20, obstacle(6, ClosingSpeed=-15001)), "out_of_range")                 # -150.01 m/s
    feed(h, 700, msg(0x20, obstacle(7, Module=1)), "out_of_range")                              # another module's
    feed(h, 800, msg(0x21, obstacle(0, ch=0)), "bad_crc")                                       # ID swapped
    feed(h, 810, msg(0x30, train(0, speed=12001)), "out_of_range")                              # 120.01 m/s
    assert h.rx.reports[0] == Report(1, 1234, 50, 0, 0) and h.rx.train is None   # nothing bad latched
    feed(h, 900, msg(0x20, obstacle(8, Distance=777)), "accepted")
    assert h.rx.reports[0] == Report(1, 777, 50, 0, 900)
    assert h.cycles == 9                                       # ticks 0..800 ran between the frames


def test_babbling_burst_is_refused_and_quarantined(harness):
    h = harness
    for i, t in enumerate((1000, 1010, 1020)):
        feed(h, t, msg(0x21, obstacle(i, ch=1)), "accepted")
    assert h.rx.reports[1] is not None
    feed(h, 1030, msg(0x21, obstacle(3, ch=1)), "rate_exceeded")          # 4 frames in one period
    assert h.rx.reports[1] is None                                         # its report withdrawn
    feed(h, 1300, msg(0x21, obstacle(4, ch=1)), "rate_exceeded")          # quarantined until 1530
    feed(h, 1600, msg(0x21, obstacle(5, ch=1)), "accepted")               # heard again, counter in step
    # TrainState babbling: the fourth frame within 100 ms is refused
    for i, t in enumerate((2000, 2001, 2002)):
        feed(h, t, msg(0x30, train(i)), "accepted")
    feed(h, 2003, msg(0x30, train(3)), "rate_exceeded")
    h.finish()
    assert h.frames == h.rx.accepted + h.rx.rejected_total == h.runner.frames_received


# ----------------------------------------------------------------------------- planted bugs are caught

def planted_run(frames=5000, seed=2):
    return fuzz.run(frames, quiet, seed=seed, workers=1)


def test_planted_bug_crc_check_skipped_is_caught(monkeypatch):
    monkeypatch.setattr(codec, "check_profile2_crc", lambda data, data_id: True)
    r = planted_run()
    assert r["violations"] > 0 and r["violations_by_kind"].get("reason", 0) > 0
    ex = next(e for e in r["examples"] if e["kind"] == "reason")
    assert ex["expected"] == "bad_crc"
    data = bytes.fromhex(ex["frame"]["data"])
    assert len(data) == 8 and fuzz.e2e_crc(data, int(ex["frame"]["id"], 16)) != data[0]
    # the recorded stream replays to the same fault at the same frame
    stats = fuzz.Stats()
    fuzz.run_stream(ex["table"], ex["topology"], ex["profile"], bytes.fromhex(ex["tape"]), stats,
                    budget=fuzz.STREAM_FRAMES)
    assert stats.examples[0]["frame"] == ex["frame"] and stats.examples[0]["frame_index"] == ex["frame_index"]


def test_planted_exception_inside_the_codec_is_caught(monkeypatch):
    real = Receiver._accept

    def flaky(self, frame_id, data, tick):
        if len(data) == 8 and data[2] == 0x42:
            raise ValueError("planted")
        return real(self, frame_id, data, tick)

    monkeypatch.setattr(Receiver, "_accept", flaky)
    r = planted_run()
    # the receiver swallows it as 'undecodable': counted, but not what the frame deserved
    assert r["violations_by_kind"].get("reason", 0) > 0
    assert any("undecodable" in e["what"] for e in r["examples"])


def test_planted_exception_escaping_the_receiver_is_caught(monkeypatch):
    real = Receiver.accept

    def raising(self, frame_id, data, tick, extended=False):
        if len(data) == 0:
            raise RuntimeError("planted")
        return real(self, frame_id, data, tick, extended)

    monkeypatch.setattr(Receiver, "accept", raising)
    r = planted_run()
    assert r["exceptions"] > 0
    assert any(e["kind"] == "exception" and "planted" in e["what"] for e in r["examples"])


def test_planted_uncounted_rejection_is_caught(monkeypatch):
    real = Receiver.accept

    def dropping(self, frame_id, data, tick, extended=False):
        if len(data) not in (8,) and not extended:
            return None                       # dropped without counting
        return real(self, frame_id, data, tick, extended)

    monkeypatch.setattr(Receiver, "accept", dropping)
    r = planted_run()
    assert r["accounting_errors"] > 0 and not r["accounting_exact"]
    assert r["violations_by_kind"].get("accounting", 0) > 0


def test_planted_value_outside_its_domain_is_caught(monkeypatch):
    monkeypatch.setattr(codec, "Report", lambda s, d, c, o, t: Report(s + 3, d, c, o, t))
    r = planted_run()
    assert r["violations_by_kind"].get("domain", 0) > 0
    assert any("outside its domain" in e["what"] for e in r["examples"])


def test_planted_exception_swallowed_by_the_core_fail_safe_is_caught(monkeypatch):
    real = core._step

    def failing(setup, state, inputs, tick):
        if state.cycle == 7:
            raise ZeroDivisionError("planted")
        return real(setup, state, inputs, tick)

    monkeypatch.setattr(core, "_step", failing)
    r = planted_run(frames=3000)
    assert r["exceptions"] > 0
    assert any("fail-safe" in e["what"] and "planted" in e["what"] for e in r["examples"])


def test_planted_core_state_outside_its_domain_is_caught(monkeypatch):
    real = core.step

    def bad_node(setup, state, inputs, tick):
        new, out = real(setup, state, inputs, tick)
        if new.cycle == 20:
            new = new._replace(node=setup.table.nodes)
            out = out._replace(node=setup.table.nodes)
        return new, out

    monkeypatch.setattr(core, "step", bad_node)
    r = planted_run(frames=3000)
    assert r["violations_by_kind"].get("domain", 0) > 0
    assert any("node" in e["what"] for e in r["examples"])


# ----------------------------------------------------------------------------- found while fuzzing

class HandClock(SimClock):
    """A clock the runner treats as real time (not simulated) that moves only when the test says so."""

    simulated = False


class SlowBus(fuzz.FrontDoorBus):
    """Waiting for a frame lasts until the runner's next tick; a send can be made slow."""

    def __init__(self, clock: HandClock) -> None:
        super().__init__()
        self.clock = clock
        self.runner = None
        self.send_ms = 0

    def _recv_internal(self, timeout):
        if not self.pending and timeout:
            self.clock.sleep_until_ms(self.runner.next_tick)
        return super()._recv_internal(timeout)

    def send(self, msg, timeout=None) -> None:
        self.clock.sleep_until_ms(self.clock.now_ms() + self.send_ms)
        super().send(msg)


def test_one_deadline_overrun_keeps_latched_ticks_within_now():
    clock = HandClock()
    bus = SlowBus(clock)
    runner = MonitorRunner(bus, fuzz.setup_for("m2", "3oo3"), clock)
    bus.runner = runner
    sender = codec.Sender()
    late = []
    try:
        for k in range(14):
            for ch in range(6):     # every channel: no obstacle; the train at standstill
                data = sender.frame(0x20 + ch, {"Status": 0, "Module": ch // 2, "Channel": ch % 2})
                bus.pending.append(msg(0x20 + ch, data))
            bus.pending.append(msg(0x30, sender.frame(0x30, {"Speed": 0})))
            bus.send_ms = 80 if k == 10 else 0     # cycle 10 ends 60 ms after its deadline: one overrun
            runner.run(cycles=1)
            rec = runner.records[-1]
            late += [(rec.tick, r.tick) for r in runner.receiver.reports if r is not None and r.tick > rec.tick]
    finally:
        bus.shutdown()
    assert runner.deadline_misses == 1 and runner.overruns == 0
    assert late == []     # before the fix: [(1100, 1160)] * 6, and that cycle demanded emergency
