"""Issue 39 item 1 on the bus: every node signs what it sends under its own key and checks
what it reads under the ID owner's key (can_bus/security.py); `railguard run` is secured by
default (a test key set on the in-process bus), an unsecured bus is an explicit option that
is announced; forged and replayed frames are refused and never lower a brake."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import can
import pytest

from can_bus import keys, logfile, secoc
from can_bus import scenario as scenarios
from can_bus import session
from can_bus.codec import (BRAKE_DEMAND_ID, MONITOR_RISK_ID, OBSTACLE_IDS, Receiver, Sender, database,
                           report_signals)
from can_bus.hostile import Hostile
from can_bus.secured_dbc import secured_database
from can_bus.security import Security, for_node, made_test_keys
from monitor.core import cycle as core
from monitor.core.config import Config
from monitor.core.types import ABSENT, PRESENT, Report
from monitor.tables import read

SETUP = core.create(Config(), read("m2"))


def railguard(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "railguard", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="module")
def secured_run(tmp_path_factory):
    """`railguard run --json` as a user types it: the default bus, secured with test keys."""
    out = tmp_path_factory.mktemp("secured")
    r = railguard("run", "--out", str(out), "--json", "--no-plot", cwd=out)
    assert r.returncode == 0, r.stderr
    return out, json.loads(r.stdout)


def test_run_is_secured_by_default_and_its_frames_verify(secured_run):
    """Every frame on the bus is a 20-byte CAN FD frame; the secured DBC decodes it and its
    authenticator verifies under its owner's key; the train stops as on the unsecured bus."""
    out, summary = secured_run
    assert summary["bus_security"].startswith("secured") and "TEST keys" in summary["bus_security"]
    assert summary["outcome"] == "stopped" and summary["rejects"] == {} and summary["attack"] is None
    ks = keys.load(out / "test-keys")
    assert ks.test
    frames = [f.msg for f in logfile.read(out / "run-static-obstacle.log")]
    assert frames and all(m.is_fd and len(m.data) == secoc.FRAME_LENGTH for m in frames)
    newest: dict = {}
    for m in frames:
        verdict, fv = secoc.check(ks.key_for(m.arbitration_id), m.arbitration_id, bytes(m.data),
                                  newest.get(m.arbitration_id))
        assert verdict == "ok", (hex(m.arbitration_id), verdict)
        newest[m.arbitration_id] = fv
    brake = next(m for m in frames if m.arbitration_id == BRAKE_DEMAND_ID)
    decoded = secured_database().get_message_by_frame_id(BRAKE_DEMAND_ID).decode(bytes(brake.data))
    assert decoded["Mac"] == int.from_bytes(bytes(brake.data)[12:20], "little")
    risk = [m for m in frames if m.arbitration_id == MONITOR_RISK_ID]
    assert all(database().decode_message(MONITOR_RISK_ID, bytes(m.data[:8]))["Unsecured"] == 0 for m in risk)


def test_an_unsecured_run_says_so_in_the_summary_and_in_monitor_risk(tmp_path):
    r = railguard("run", "--unsecured", "--out", str(tmp_path), "--json", "--no-plot", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["bus_security"].startswith("UNSECURED") and summary["outcome"] == "stopped"
    frames = [f.msg for f in logfile.read(tmp_path / "run-static-obstacle.log")]
    assert all(not m.is_fd and len(m.data) == 8 for m in frames)
    risk = [m for m in frames if m.arbitration_id == MONITOR_RISK_ID]
    assert risk and all(database().decode_message(MONITOR_RISK_ID, bytes(m.data))["Unsecured"] == 1 for m in risk)


def test_a_real_bus_is_never_secured_by_test_keys_unasked(tmp_path):
    """Without --keys or --unsecured a real bus is refused before it is opened: one line, exit 2."""
    r = railguard("run", "--interface", "socketcan", "--channel", "vcan0", "--out", str(tmp_path), cwd=tmp_path)
    assert r.returncode == 2 and "--keys DIR" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_replay_of_a_secured_log_verifies_every_frame_and_agrees(secured_run):
    out, _ = secured_run
    log = str(out / "run-static-obstacle.log")
    r = railguard("replay", log, "--keys", str(out / "test-keys"), "--json", "--no-plot", cwd=out)
    assert r.returncode == 0, r.stderr
    stats = json.loads(r.stdout)
    assert stats["rejected"] == {} and stats["agreement_with_recorded"] > 0.99
    assert stats["bus_security"].startswith("secured")
    plain = json.loads(railguard("replay", log, "--json", "--no-plot", cwd=out).stdout)
    assert plain["accepted"] == 0 and plain["rejected"]["fd_frame"] == plain["frames"] and "--keys" in plain["note"]


def test_a_recording_from_an_earlier_session_is_refused(secured_run):
    """The monitor's receive windows persist (test-keys/freshness): a node that sends the
    first run's frames again, byte for byte, in a later session is refused on every one."""
    out, _ = secured_run
    later = for_node(out / "test-keys", "monitor", keys.SENDERS)          # the next session's monitor
    rx = Receiver(security=later)
    inputs = [f.msg for f in logfile.read(out / "run-static-obstacle.log") if f.msg.arbitration_id in OBSTACLE_IDS]
    for i, m in enumerate(inputs):
        rx.accept(m.arbitration_id, bytes(m.data), 1000 * i)
    assert rx.accepted == 0 and rx.rejected["stale_freshness"] == len(inputs)
    assert rx.reports == [None] * 6


def _secured_pair(tmp_path, receiver_senders=keys.SENDERS):
    folder = made_test_keys(tmp_path / "keys")
    return for_node(folder, "sensors", keys.SENDERS, state=False), for_node(folder, "monitor", receiver_senders,
                                                                             state=False)


def test_one_sensor_s_key_cannot_sign_another_channel_nor_the_monitor(tmp_path):
    """A node holding channel 0's key forges channel 1's report: refused (bad_mac) and the
    ID quarantined as a second sender, so channel 1 reads as never heard (DEGRADED: the voter
    goes to the safe side). A Security holding only sensor keys cannot seal BrakeDemand."""
    sensors, monitor = _secured_pair(tmp_path)
    rx = Receiver(security=monitor)
    genuine = Sender(sensors)
    seen = Report(PRESENT, 3000, 1500, 0, 0)
    for ch in range(6):
        assert rx.accept(OBSTACLE_IDS[ch], genuine.frame(OBSTACLE_IDS[ch], report_signals(seen, ch)), 0)
    bus = can.Bus(interface="virtual", channel="forge", receive_own_messages=True)
    try:
        thief = Hostile(bus, secured=True, key=sensors.keyset.keys["ch0"])
        thief.freshness[OBSTACLE_IDS[1]] = 0
        thief.forge_absent(1, 1)
        forged = bus.recv(timeout=1)
    finally:
        bus.shutdown()
    assert rx.accept(forged.arbitration_id, bytes(forged.data), 50) is None
    assert rx.rejected["bad_mac"] == 1 and rx.reports[1] is None and rx.reports[0] is not None
    later = genuine.frame(OBSTACLE_IDS[1], report_signals(seen, 1))
    assert rx.accept(OBSTACLE_IDS[1], later, 100) is None and rx.rejected["second_sender"] == 1
    only_sensors = for_node(tmp_path / "keys", "s0", [f"ch{i}" for i in range(6)], state=False)
    with pytest.raises(keys.KeyFileError):
        only_sensors.seal(BRAKE_DEMAND_ID, bytes(8))


def test_a_classical_frame_on_a_secured_bus_is_refused_as_such(tmp_path):
    """An unsecured (classical) frame reaches the receive path of a secured monitor: refused
    before decoding, counted as classical_frame."""
    from can_bus.runner import MonitorCore

    _, monitor = _secured_pair(tmp_path)
    mon = MonitorCore(SETUP, security=monitor)
    data = Sender().frame(OBSTACLE_IDS[0], report_signals(Report(ABSENT, 0, 0, 0, 0), 0))
    assert mon.ingest(can.Message(arbitration_id=OBSTACLE_IDS[0], data=data, is_extended_id=False), 0) is None
    assert mon.rejected["classical_frame"] == 1 and mon.receiver.reports[0] is None


HOSTILE = {"hostile-forged-absent": ("rejects", "bad_mac"),
           "hostile-forged-brake-none": ("brake_receiver", "second_sender"),
           "hostile-replay-absent": ("rejects", "stale_freshness"),
           "hostile-replay-brake-none": ("hostile_frames", "replay_brake_none"),
           "hostile-stolen-key": ("rejects", "bad_mac")}     # channel 0's key on channels 1-5


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_every_hostile_node_fails_on_a_secured_bus(name, tmp_path):
    """The four attacks of issue 39 (forged absent on every channel in step, forged BrakeDemand
    none, their replays) and a sensor's key used on the other channels, on the secured bus:
    the train stops and the summary names the refusal. (A forged frame is refused for its authenticator, a replayed one for its
    freshness; the brake receiver brakes on a forger's frames.)"""
    where, what = HOSTILE[name]
    r = session.run_virtual(SETUP, scenarios.load(name), tmp_path / "out", plot=False, keys=made_test_keys(tmp_path / "k"))
    s = r.summary
    assert s["outcome"] == "stopped", s
    assert s[where].get(what, 0) > 0, (where, s[where])
    assert s["hostile_frames"], s
    if where != "hostile_frames":             # named in the summary (and the plot's title)
        assert s["attack"] and what.replace("_", " ") in s["attack"].replace("_", " "), s["attack"]


def test_the_secured_dbc_is_the_classic_one_made_secured():
    r = subprocess.run([sys.executable, "-m", "can_bus.secured_dbc", "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout
    m = secured_database().get_message_by_frame_id(OBSTACLE_IDS[0])
    assert m.is_fd and m.length == secoc.FRAME_LENGTH
    assert [s.name for s in m.signals][-2:] == ["FreshnessLow", "Mac"]


def test_security_refuses_what_it_cannot_judge(tmp_path):
    """A node without the ID owner's key never takes the frame (no_key); a truncated frame
    is wrong_length; the same frame twice is stale."""
    sensors, _ = _secured_pair(tmp_path)
    brakes = Security(keys.load(tmp_path / "keys", ["monitor"]), "brakes", state=False)
    frame = sensors.seal(OBSTACLE_IDS[2], bytes(8))
    assert brakes.open(OBSTACLE_IDS[2], frame) == ("no_key", None)
    monitor = Security(keys.load(tmp_path / "keys", ["ch2"]), "m", state=False)
    assert monitor.open(OBSTACLE_IDS[2], frame[:16])[0] == "wrong_length"
    assert monitor.open(OBSTACLE_IDS[2], frame) == ("ok", bytes(8))
    assert monitor.open(OBSTACLE_IDS[2], frame)[0] == "stale_freshness"


def test_a_reordered_or_corrupted_secured_frame_is_refused(tmp_path):
    """EN 50159 resequencing and corruption on the secured bus: of two frames of one ID, the
    older one after the newer is stale; any bit changed in ID, payload or freshness value
    fails the authenticator."""
    sensors, monitor = _secured_pair(tmp_path)
    fid = OBSTACLE_IDS[4]
    older, newer = (Sender(sensors).frame(fid, report_signals(Report(ABSENT, 0, 0, 0, 0), 4)) for _ in range(2))
    assert monitor.open(fid, newer)[0] == "ok"
    assert monitor.open(fid, older)[0] == "stale_freshness"
    fresh = sensors.seal(fid, bytes(8))
    for byte in (0, 7, 8, 12, 19):
        bad = bytearray(fresh)
        bad[byte] ^= 0x01
        assert monitor.open(fid, bytes(bad))[0] in ("bad_mac", "stale_freshness"), byte
    assert monitor.open(OBSTACLE_IDS[5], fresh)[0] == "bad_mac"          # the same bytes on another ID
    assert monitor.open(fid, fresh)[0] == "ok"


def test_an_earlier_session_s_frames_replayed_live_are_refused_and_the_train_stops(tmp_path):
    """Issue 39 item 4: a hostile node holding a recording of an earlier session (the same key
    set, so every authenticator in it is genuine) sends its "absent" reports back in the next
    session, each when its counter value is due: every one is refused for its freshness (the
    monitor's windows persisted), the genuine reports are taken, the train stops."""
    from can_bus.player import Player

    folder = made_test_keys(tmp_path / "keys")
    first = session.run_virtual(SETUP, scenarios.load("static-obstacle"), tmp_path / "a", plot=False, keys=folder)
    recorded = [f.msg for f in logfile.read(first.summary["log"])]

    class Recorded(Player):
        def join_hostile(self, bus):
            super().join_hostile(bus)
            for msg in recorded:              # the earlier session's frames come first in its memory
                self.hostile.sniff(msg)

    second = session.run_virtual(SETUP, scenarios.load("hostile-replay-absent"), tmp_path / "b", plot=False,
                                 keys=folder, player=Recorded)
    s = second.summary
    assert s["hostile_frames"]["replay_absent"] > 1000, s["hostile_frames"]
    assert s["rejects"].get("stale_freshness", 0) >= s["hostile_frames"]["replay_absent"] - 12, s["rejects"]
    assert s["outcome"] == "stopped" and "bad_mac" not in s["rejects"], s


@pytest.mark.parametrize("name", ["hostile-forged-absent", "hostile-forged-brake-none"])
def test_a_secured_attack_log_replays_to_the_same_decisions(name, tmp_path):
    """Replayed with its key set, the log of an attack on the secured bus gives the live
    decisions and names the refusals (issue 39 acceptance: live and in replay)."""
    from can_bus.replay import Replay

    folder = made_test_keys(tmp_path / "keys")
    live = session.run_virtual(SETUP, scenarios.load(name), tmp_path / "out", plot=False, keys=folder)
    rp = Replay(SETUP, keys=folder, source=name)
    decisions = list(rp.run(logfile.read(live.summary["log"])))
    stats = rp.stats.as_dict()
    assert decisions and stats["agreement_with_recorded"] > 0.99, stats
    if name == "hostile-forged-absent":
        assert stats["rejected"]["bad_mac"] == live.summary["rejects"]["bad_mac"]
    else:
        assert stats["brake_receiver"].get("second_sender", 0) > 0, stats
