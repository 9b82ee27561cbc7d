"""The front-door fuzzing (verification/fuzz/): a quick run through the real runner is
clean, nasty frames land under the right reject reason (or are filtered), the reference
receiver reads the DBC as cantools does and error frames as the runner does, and planted bugs
in the codec, the runner path, the reference's own rule order or the core are caught."""
from __future__ import annotations

import can
import pytest

from can_bus import codec, frames, runner as runner_mod
from can_bus.clock import SimClock
from can_bus.codec import Receiver
from can_bus.runner import MonitorRunner
from monitor.core import cycle as core
from monitor.core.types import EMERGENCY, NORMAL, SERVICE, Report
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
    assert r["frames"] == r["accepted"] + sum(r["rejected"].values()) + r["filtered"]
    assert r["frames"] == sum(r["frame_kinds"].values())
    assert r["accepted"] > 0 and r["filtered"] > 0
    for reason in ("bad_crc", "rate_exceeded", "fd_frame", "remote_frame", "error_frame", "foreign_output"):
        assert r["rejected"].get(reason, 0) > 0, reason
    assert "undecodable" not in r["rejected"] and "unknown_id" not in r["rejected"]
    assert "error_or_remote_frame" not in r["rejected"]          # the old shared reason is gone
    assert r["foreign_cycles"] > 0 and set(r["foreign_ids"]) == {"0x10", "0x40", "0x41", "0x42"}
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
    assert fuzz.MONITORED == set(frames.MONITORED_IDS) and fuzz.OUTPUTS == codec.OUTPUT_IDS == frames.OUTPUT_IDS
    assert fuzz.MONITOR_TRACK == codec.MONITOR_TRACK_ID
    # the rate policing, read from docs/can.md, is the codec's
    assert (fuzz.MAX_FRAMES_PER_WINDOW, fuzz.BABBLE_QUARANTINE_MS) == (codec.MAX_FRAMES_PER_WINDOW,
                                                                       codec.BABBLE_QUARANTINE_MS)
    assert fuzz.KINDS == frames.KINDS and fuzz.BUS_STATES == frames.BUS_STATES
    assert fuzz.FOREIGN_HOLD_CYCLES == runner_mod.FOREIGN_HOLD_CYCLES
    # every reason is either covered by the fuzzing or named as unreachable through this front door
    assert set(fuzz.COVERED_REASONS) | set(fuzz.UNREACHABLE_REASONS) == \
        set(codec.REJECT_REASONS) | set(codec.SHELL_REJECT_REASONS)
    assert "receive_error" in fuzz.UNREACHABLE_REASONS
    assert {"fd_frame", "remote_frame", "error_frame", "foreign_output", "rate_exceeded"} <= set(fuzz.COVERED_REASONS)
    for msg in db.messages:
        assert msg.length == 8 and not msg.is_extended_frame
        ours = {name: rest for name, *rest in fuzz.LAYOUT[msg.frame_id]}
        assert set(ours) == {s.name for s in msg.signals}
        for s in msg.signals:
            start, length, signed, lo, hi = ours[s.name]
            assert (s.start, s.length, s.is_signed, s.byte_order) == (start, length, signed, "little_endian")
            assert round((s.minimum - s.offset) / s.scale) == lo and round((s.maximum - s.offset) / s.scale) == hi
        # the unused bits (MonitorTrack's reserved 48-63 among them): exactly those no signal uses
        used = sum(((1 << s.length) - 1) << s.start for s in msg.signals)
        assert fuzz.UNUSED[msg.frame_id] == ~used & (2**64 - 1)
    assert fuzz.UNUSED[fuzz.MONITOR_TRACK] == 0xFFFF << 48


def test_reference_crc_and_unpacking_agree_with_the_codec():
    assert fuzz.crc8_h2f(b"123456789") == 0xDF        # the AUTOSAR CRC8H2F check value
    sender = codec.Sender()
    signals = {0x20: {"Status": 1, "ObstacleType": 2, "Distance": 60000, "ClosingSpeed": -15000, "Module": 0},
               0x25: {"Status": 2, "Distance": 1, "ClosingSpeed": 15000, "Module": 2, "Channel": 1},
               0x30: {"Speed": 12000, "TrackCondition": 1, "BrakeStatus": 1},
               0x10: {"Level": 2, "Warning": 1, "Reason": 32767, "Cycle": 2**32 - 1},
               0x40: {"Mode": 3, "ForeignOutput": 1, "Node": 1023, "ErrorFlags": 63, "VotedDistance": 65535,
                      "TableHash": 4095, "DeadlineMisses": 15},
               0x41: {"TrackState": 5, "Memory": 1, "TrackDistance": 65535, "TrackAge": 65535},
               0x42: {"RiskCategory": 4, "RiskScore": 20, "R1": 500, "R2": 1000, "TableRisk": 1_000_000}}
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


def test_reference_reads_error_frames_as_the_runner():
    """linux/can/error.h: the class bits in the identifier, the controller status in data[1]."""
    classes = (0, 0x001, 0x004, 0x008, 0x040, 0x100, 0x004 | 0x100, 0x044, 0x1FF, 0x20000004, 0x20000040)
    for cls in classes:
        for ctrl in (0x00, 0x01, 0x04, 0x08, 0x10, 0x20, 0x40, 0x14, 0x44, 0x50, 0xFF):
            for data in (bytes([0, ctrl]) + bytes(6), bytes([0, ctrl]), b"", b"\0"):
                m = msg(cls, data, error=True, extended=True)
                assert fuzz.announced_state(m) == frames.bus_state_of(m), (hex(cls), hex(ctrl), data)
    assert fuzz.announced_state(msg(0x040, bytes(8), error=True)) == "bus_off"
    assert fuzz.announced_state(msg(0x004, bytes([0, 0x10]), error=True)) == "error_passive"
    assert fuzz.announced_state(msg(0x001, bytes([0, 0x10]), error=True)) is None    # no CRTL class: no status


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
    h = fuzz.Harness(fuzz.setup_for("m2", "3oo3"), fuzz.Stats())
    yield h
    h.bus.shutdown()


def feed(h, t, m, reason):
    """Feed one frame; the runner must count it under `reason` (and the reference agree)."""
    rx, tally = h.rx, h.tally
    before, accepted, filtered, kinds = dict(rx.rejected), rx.accepted, tally.filtered, sum(tally.kinds.values())
    outcome = h.feed(t, m, "test")
    assert outcome == reason
    assert sum(tally.kinds.values()) == kinds + 1 and h.runner.frames_received == h.frames
    if reason == fuzz.ACCEPTED:
        assert rx.accepted == accepted + 1 and dict(rx.rejected) == before and tally.filtered == filtered
    elif reason == fuzz.FILTERED:
        assert rx.accepted == accepted and dict(rx.rejected) == before and tally.filtered == filtered + 1
    else:
        assert rx.accepted == accepted and tally.filtered == filtered
        assert rx.rejected[reason] == before.get(reason, 0) + 1
        assert sum(rx.rejected.values()) == sum(before.values()) + 1
    assert not h.failed and not h.stats.violations and h.stats.exceptions == 0


def test_nasty_frames_are_rejected_under_the_right_reason(harness):
    h = harness
    good = obstacle(0)
    feed(h, 0, msg(0x20, good), "accepted")
    assert h.rx.reports[0] == Report(1, 1234, 50, 0, 0)
    # refused or dropped before the codec (and so not counted by 0x020's rate policing: four
    # frames on it within 10 ms here, yet the next frame meets the CRC check, not the policing)
    feed(h, 1, msg(0x20, good, remote=True), "remote_frame")                                  # remote request
    feed(h, 2, msg(0x20, good, fd=True), "fd_frame")                                          # CAN FD, valid payload
    feed(h, 3, msg(0x20, good + bytes(56), fd=True), "fd_frame")                              # CAN FD, 64 bytes
    feed(h, 4, msg(0, b"", error=True), "error_frame")                                        # error frame
    feed(h, 5, msg(0x20, good, remote=True, fd=True, error=True), "error_frame")              # error first
    feed(h, 6, msg(0x20, good, extended=True), "filtered")                                    # 29-bit
    feed(h, 7, msg(0x20, good, extended=True, fd=True), "filtered")                           # 29-bit FD
    feed(h, 8, msg(0x123, good), "filtered")                                                  # not monitored
    feed(h, 9, msg(0x820, good), "filtered")                                                  # out-of-spec 11-bit
    feed(h, 10, msg(0x10, codec.encode(0x10, {"Level": 0}, 0)), "foreign_output")            # our BrakeDemand ID
    feed(h, 11, msg(0x40, b"\0"), "foreign_output")                                           # our status ID, junk
    assert dict(h.tally.kinds) == {"classical": 5, "remote": 1, "fd": 3, "error": 2, "extended": 1}  # 29-bit FD: fd
    assert h.tally.filtered == 4
    # the codec's checks: one frame on 0x020 every 50 ms (never more than 3 within a period)
    feed(h, 50, msg(0x20, bytes([good[0] ^ 0x5A]) + good[1:]), "bad_crc")                    # wrong CRC
    feed(h, 100, msg(0x20, good[:3] + bytes([good[3] ^ 0x10]) + good[4:]), "bad_crc")        # a bit flipped
    feed(h, 150, msg(0x20, good[:7]), "wrong_length")                                          # truncated
    feed(h, 200, msg(0x20, good + b"\0"), "wrong_length")                                      # extended
    feed(h, 250, msg(0x20, good), "repeated_counter")                                          # replay
    feed(h, 300, msg(0x20, obstacle(3)), "counter_jump")                                       # jump 0 -> 3
    feed(h, 350, msg(0x20, obstacle(4, Distance=60001)), "out_of_range")                     # 6000.1 m
    feed(h, 400, msg(0x20, obstacle(5, Status=3)), "out_of_range")                             # no such status
    feed(h, 450, msg(0x20, obstacle(6, ClosingSpeed=-15001)), "out_of_range")                # -150.01 m/s
    feed(h, 500, msg(0x20, obstacle(7, Module=1)), "out_of_range")                             # another module's
    feed(h, 510, msg(0x21, obstacle(0, ch=0)), "bad_crc")                                      # ID swapped
    feed(h, 520, msg(0x30, train(0, speed=12001)), "out_of_range")                             # 120.01 m/s
    assert h.rx.reports[0] == Report(1, 1234, 50, 0, 0) and h.rx.train is None   # nothing bad latched
    feed(h, 600, msg(0x20, obstacle(8, Distance=777)), "accepted")
    assert h.rx.reports[0] == Report(1, 777, 50, 0, 600)
    assert h.cycles == 6                                       # ticks 0..500 ran between the frames
    assert "unknown_id" not in h.rx.rejected                   # the receive filter leaves the codec none


def test_foreign_frame_sets_the_diagnostic_for_one_second(harness):
    h = harness
    feed(h, 250, msg(0x10, codec.encode(0x10, {"Level": 2}, 3)), "foreign_output")
    flagged, sent = [], []
    for _ in range(15):
        h.cycle()
        rec = h.runner.records[-1]
        flagged.append(rec.foreign_output)
        sent.append(fuzz.unpack(0x40, bytes(h.bus.last_sent[0x40].data))["ForeignOutput"])
    ticks = [r.tick for r in h.runner.records[-15:]]
    assert ticks[0] == 300 and [t for t, f in zip(ticks, flagged) if f] == list(range(300, 1300, 100))  # 10 cycles
    assert sent == [int(f) for f in flagged]                   # the MonitorStatus frame carries it
    # a second foreign frame (on MonitorStatus) holds it again; the record is what cycle() returns
    feed(h, 1750, msg(0x40, bytes(8)), "foreign_output")
    rec = h.runner.cycle()
    assert rec is h.runner.records[-1] and rec.tick == 1800 and rec.foreign_output
    assert rec.demand == h.runner.outputs.demand


def test_babbling_burst_is_refused_and_quarantined(harness):
    h = harness
    for i, t in enumerate((1000, 1010, 1020)):
        feed(h, t, msg(0x21, obstacle(i, ch=1)), "accepted")
    assert h.rx.reports[1] is not None
    feed(h, 1030, msg(0x21, obstacle(3, ch=1)), "rate_exceeded")          # 4 frames in one period
    assert h.rx.reports[1] is None                                         # its report withdrawn
    feed(h, 1300, msg(0x21, obstacle(4, ch=1)), "rate_exceeded")          # quarantined until 1530
    assert h.rx.reports[1] is None
    feed(h, 1600, msg(0x21, obstacle(9, ch=1)), "accepted")               # counter forgotten: resynchronised
    feed(h, 1700, msg(0x21, obstacle(11, ch=1)), "counter_jump")          # and checked again from 9
    # invalid frames count too, before their CRC is looked at
    bad = obstacle(0, ch=2)
    bad = bytes([bad[0] ^ 1]) + bad[1:]
    for t in (2000, 2010, 2020):
        feed(h, t, msg(0x22, bad), "bad_crc")
    feed(h, 2030, msg(0x22, obstacle(0, ch=2)), "rate_exceeded")
    feed(h, 2040, msg(0x22, bad), "rate_exceeded")                         # a bad frame, refused by the policing
    feed(h, 2050, msg(0x22, obstacle(0, ch=2)[:5]), "rate_exceeded")       # so is a short one
    # FD and remote frames on an input ID are refused before the policing: they do not count
    for t in (3000, 3001, 3002, 3003):
        feed(h, t, msg(0x23, obstacle(0, ch=3), fd=True), "fd_frame")
        feed(h, t, msg(0x23, b"", remote=True), "remote_frame")
    for i, t in enumerate((3010, 3020, 3030)):
        feed(h, t, msg(0x23, obstacle(i, ch=3)), "accepted")
    # TrainState babbling: the fourth frame within 100 ms is refused
    for i, t in enumerate((4000, 4001, 4002)):
        feed(h, t, msg(0x30, train(i)), "accepted")
    feed(h, 4003, msg(0x30, train(3)), "rate_exceeded")
    h.finish()
    assert h.frames == h.rx.accepted + h.rx.rejected_total + h.tally.filtered == h.runner.frames_received
    assert not h.failed


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
                    budget=fuzz.STREAM_FRAMES, secured=ex["bus"] == "secured")
    assert stats.examples[0]["frame"] == ex["frame"] and stats.examples[0]["frame_index"] == ex["frame_index"]


def test_planted_bad_mac_without_quarantine_is_caught(monkeypatch):
    """Issue 39, the secured streams: a frame that fails its authenticator refused, but the
    ID not quarantined (its report kept, the next genuine frame taken)."""
    monkeypatch.setattr(Receiver, "_contest", lambda self, frame_id, state, tick: None)
    r = planted_run()
    assert r["violations"] > 0
    assert any(e["bus"] == "secured" for e in r["examples"] if e["kind"] in ("reason", "latched"))


def test_planted_freshness_window_skipped_is_caught(monkeypatch):
    """Issue 39: a receiver that takes any freshness value (no window): a replayed secured
    frame is then judged by its authenticator, which fails, instead of refused as stale."""
    from can_bus import secoc

    monkeypatch.setattr(secoc, "WINDOW", 1 << 70)
    r = planted_run()
    assert any(e["kind"] == "reason" and e["expected"] == "stale_freshness" for e in r["examples"]), r["examples"][:2]


def test_the_secured_streams_reach_every_refusal_of_the_secured_bus():
    r = fuzz.run(6000, quiet, seed=5, workers=1)
    assert r["violations"] == 0 and r["exceptions"] == 0 and r["reference_agrees"]
    assert all(r["rejected"].get(k, 0) > 0 for k in ("bad_mac", "stale_freshness", "classical_frame")), r["rejected"]
    assert any(k.endswith("/secured") for k in r["stream_kinds"]) and any(k.endswith("/unsecured") for k in r["stream_kinds"])


def test_planted_crc_before_rate_policing_is_caught(monkeypatch):
    """The old order: a frame with a broken CRC refused before the policing counts it."""
    real = Receiver._accept

    def crc_first(self, frame_id, data, tick):
        if (frame_id in codec.INPUT_IDS and len(data) == 8
                and not codec.check_profile2_crc(data, codec.data_id(frame_id))):
            self._reject("bad_crc")
            return None
        return real(self, frame_id, data, tick)

    monkeypatch.setattr(Receiver, "_accept", crc_first)
    r = planted_run()
    assert r["violations_by_kind"].get("reason", 0) > 0 and not r["reference_agrees"]
    assert any(e["kind"] == "reason" and e["expected"] == "rate_exceeded" and "'bad_crc': 1" in e["what"]
               for e in r["examples"])


def test_reference_with_crc_before_rate_policing_disagrees(monkeypatch):
    """The comparison is sensitive to the rule order: the reference itself with the CRC
    checked before the policing (a scratch copy, the runner untouched) is caught."""

    class CrcFirst(fuzz.ReferenceReceiver):
        def check(self, fid, data, now):
            if len(data) != 8:
                return "wrong_length"
            if fuzz.e2e_crc(data, fid) != data[0]:
                return "bad_crc"
            return super().check(fid, data, now)

    monkeypatch.setattr(fuzz.harness, "ReferenceReceiver", CrcFirst)   # where the harness looks it up
    r = planted_run()
    assert r["violations_by_kind"].get("reason", 0) > 0 and not r["reference_agrees"]


def test_planted_receive_filter_skipped_is_caught(monkeypatch):
    monkeypatch.setattr(frames, "monitored", lambda m: True)
    r = planted_run()
    assert r["violations_by_kind"].get("reason", 0) > 0
    assert any(e["expected"] == fuzz.FILTERED for e in r["examples"] if e["kind"] == "reason")


def test_planted_fd_frame_decoded_is_caught(monkeypatch):
    real = frames.classify
    monkeypatch.setattr(frames, "classify", lambda m: "classical" if real(m) == "fd" else real(m))
    r = planted_run()
    assert r["violations_by_kind"].get("reason", 0) > 0
    assert any(e["expected"] == "fd_frame" for e in r["examples"] if e["kind"] == "reason")


def test_planted_short_foreign_output_hold_is_caught(monkeypatch):
    monkeypatch.setattr(runner_mod, "FOREIGN_HOLD_CYCLES", runner_mod.FOREIGN_HOLD_CYCLES - 1)
    r = planted_run()
    assert r["violations_by_kind"].get("cycle", 0) > 0
    assert any("ForeignOutput" in e["what"] for e in r["examples"])


def test_planted_counter_kept_across_quarantine_is_caught(monkeypatch):
    class Sticky(codec.SenderState):
        def __setattr__(self, name, value):
            if name == "counter" and value is None and getattr(self, "counter", None) is not None:
                return                            # the alive counter survives the quarantine
            super().__setattr__(name, value)

    monkeypatch.setattr(codec, "SenderState", Sticky)
    r = planted_run()
    assert r["violations_by_kind"].get("reason", 0) > 0
    assert any(e["expected"] == fuzz.ACCEPTED and "counter_jump" in e["what"] for e in r["examples"])


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


def node_beyond_the_table(setup, new, out):
    if new.cycle == 20:
        return new._replace(node=setup.table.nodes), out._replace(node=setup.table.nodes)
    return new, out


def demand_below_the_level_held(setup, new, out):
    if new.held == EMERGENCY and new.mode == NORMAL:
        return new, out._replace(demand=SERVICE)      # an emergency held, a service demand sent
    return new, out


def track_never_ages(setup, new, out):
    aged = tuple(t._replace(cycles=0) for t in new.tracks)                # a track held unseen stays 0 cycles old
    return new._replace(tracks=aged), out._replace(track_cycles=0)


@pytest.mark.parametrize("change, what", [(node_beyond_the_table, "node"),
                                          (demand_below_the_level_held, "below the level held 2"),
                                          (track_never_ages, "track cycles")], ids=["node", "held", "track"])
def test_planted_core_state_outside_its_domain_is_caught(monkeypatch, change, what):
    """core.step with `change(setup, state, outputs) -> (state, outputs)` applied to its result."""
    real = core.step
    monkeypatch.setattr(core, "step", lambda setup, state, inputs, tick: change(setup, *real(setup, state, inputs,
                                                                                              tick)))
    r = planted_run(frames=3000)
    assert r["violations_by_kind"].get("domain", 0) > 0
    assert any(what in e["what"] for e in r["examples"])


def test_planted_monitor_track_without_the_memory_bit_is_caught(monkeypatch):
    monkeypatch.setattr(runner_mod, "R_MEMORY", 0)     # the runner's MonitorTrack.Memory always 0
    r = planted_run(frames=3000)
    assert r["violations_by_kind"].get("cycle", 0) > 0
    assert any("sent MonitorTrack" in e["what"] for e in r["examples"])


# ----------------------------------------------------------------------------- found while fuzzing

class HandClock(SimClock):
    """A clock the runner treats as real time (not simulated) that moves only when the test says so."""

    simulated = False


class SlowBus(fuzz.FrontDoorBus):
    """Waiting for a frame lasts until the runner's next tick; a cycle's sends can be made slow
    (`send_ms` in all, spent on its first frame, BrakeDemand, whatever the number of frames)."""

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
        if msg.arbitration_id == codec.BRAKE_DEMAND_ID:
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
            bus.send_ms = 160 if k == 10 else 0    # cycle 10 ends 60 ms after its deadline: one overrun
            runner.run(cycles=1)
            rec = runner.records[-1]
            late += [(rec.tick, r.tick) for r in runner.receiver.reports if r is not None and r.tick > rec.tick]
    finally:
        bus.shutdown()
    assert runner.deadline_misses == 1 and runner.overruns == 0
    assert late == []     # before the fix: [(1100, 1160)] * 6, and that cycle demanded emergency
