"""The value tables (VAL_) and units of can_bus/railguard.dbc, as a user of cantools sees them.

Every VAL_ entry is compared with the constant the project encodes it from (monitor/core/types.py,
the codec's module/channel fields, the runner's ErrorFlags bits): changing a constant without the
DBC, or the DBC without the constant, fails here. Then real frames, produced by the project's own
sender in a scenario run on the virtual bus, are decoded with cantools' API and its command line,
and must show the names (e.g. VotedDistance 65535 -> "no_distance").
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import cantools
import pytest
from cantools.database.namedsignalvalue import NamedSignalValue

from can_bus import codec, logfile, scenario, session
from can_bus.clock import SimClock
from can_bus.runner import MonitorRunner
from monitor.core import cycle as core
from monitor.core import types as T
from monitor.core.config import Config

ROOT = Path(__file__).resolve().parents[1]
DBC_PATH = ROOT / "can_bus" / "railguard.dbc"
TABLE = ROOT / "monitor" / "tables" / "m2.table.rgt"

REASON_BITS = (T.R_TABLE, T.R_ENVELOPE, T.R_SYSTEM_ERROR, T.R_LATCH, T.R_INIT, T.R_SAFE_STOP, T.R_STALE,
               T.R_PERCEPTOR, T.R_DEADLINE, T.R_TRAIN_INPUT, T.R_SBI, T.R_WARNING, T.R_DISPUTE, T.R_MEMORY,
               T.R_IMPLAUSIBLE)
TRACK_STATES = (T.TRACK_NONE, T.TRACK_SEEN, T.TRACK_HELD, T.TRACK_CONFIRMING, T.TRACK_FORGOTTEN, T.TRACK_PASSED)


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC_PATH))


def choices(db, message: str, signal: str) -> dict:
    sig = db.get_message_by_name(message).get_signal_by_name(signal)
    return {int(k): str(v) for k, v in (sig.choices or {}).items()}


def obstacle_messages(db) -> list:
    return [db.get_message_by_frame_id(fid) for fid in codec.OBSTACLE_IDS]


class Capture:
    """A bus that keeps what the runner sends."""

    def __init__(self):
        self.sent = []

    def send(self, msg, timeout=None):
        self.sent.append(msg)


def capturing_runner() -> tuple[Capture, MonitorRunner]:
    bus = Capture()
    return bus, MonitorRunner(bus, core.create(Config(), TABLE.read_bytes()), SimClock())


BASE_OUTPUTS = dict(demand=0, reasons=0, distance_dm=T.NO_DISTANCE, node=0, mode=T.NORMAL, module_flags=0,
                    system_error=False, observation=0, cycle=0, error_cycles=0)


def error_flag_bits() -> dict:
    """ErrorFlags as the runner sends it: one frame per cause, decoded by the project's receiver."""
    bus, runner = capturing_runner()
    causes = {f"module_{m + 1}": dict(module_flags=1 << m) for m in range(3)}
    causes |= {"system_error": dict(system_error=True), "stale": dict(reasons=T.R_STALE),
               "perceptor": dict(reasons=T.R_PERCEPTOR), "none": {}}
    out = {}
    for name, change in causes.items():
        runner.send(T.Outputs(**(BASE_OUTPUTS | change)))
        msg = next(m for m in reversed(bus.sent) if m.arbitration_id == codec.MONITOR_STATUS_ID)
        assert msg.arbitration_id == codec.MONITOR_STATUS_ID
        rx = codec.Receiver()
        assert rx.accept(msg.arbitration_id, msg.data, 0) == "MonitorStatus"
        out[rx.status["ErrorFlags"]] = name
    return out


# ----------------------------------------------------------------------------- every VAL_ entry

def expected_tables(db) -> dict:
    """(message, signal) -> {raw value: name}, each derived from the constant the project sends."""
    lower = [n.lower() for n in T.STATUS_NAMES]
    status = {T.ABSENT: lower[T.ABSENT], T.PRESENT: lower[T.PRESENT], T.DEGRADED: lower[T.DEGRADED]}
    obstacle = {T.STATIC: "static", T.DYNAMIC: "dynamic", T.TRAIN: "train"}
    warning = {int(False): "none", int(True): "warning"}
    exp = {
        ("BrakeDemand", "Level"): {T.MAINTAIN: T.DEMAND_NAMES[T.MAINTAIN], T.SERVICE: T.DEMAND_NAMES[T.SERVICE],
                                   T.EMERGENCY: T.DEMAND_NAMES[T.EMERGENCY]},
        ("BrakeDemand", "Warning"): warning,
        ("BrakeDemand", "Reason"): {0: "none"} | {bit: name for bit, name in zip(REASON_BITS, T.REASON_NAMES)},
        ("TrainState", "TrackCondition"): {T.TRACK_NORMAL: "normal", T.TRACK_SLIPPERY: "slippery"},
        ("TrainState", "BrakeStatus"): {T.BRAKE_NORMAL: "normal", T.BRAKE_DEGRADED: "degraded"},
        ("MonitorStatus", "Mode"): {m: T.MODE_NAMES[m] for m in (T.INIT, T.NORMAL, T.DEGRADED_MODE, T.SAFE_STOP)},
        ("MonitorStatus", "Warning"): warning,
        ("MonitorStatus", "ForeignOutput"): {int(False): "none", int(True): "foreign_sender"},
        ("MonitorStatus", "ErrorFlags"): error_flag_bits(),
        ("MonitorStatus", "VotedDistance"): {T.NO_DISTANCE: "no_distance"},
        ("MonitorTrack", "TrackState"): track_state_names(),
        ("MonitorTrack", "Memory"): {0: "none", 1: T.REASON_NAMES[T.R_MEMORY.bit_length() - 1]},
        ("MonitorTrack", "TrackDistance"): {T.NO_DISTANCE: "no_track"},
        ("MonitorRisk", "RiskCategory"): category_names(),
    }
    for ch, msg in enumerate(obstacle_messages(db)):
        exp[(msg.name, "Status")] = status
        exp[(msg.name, "ObstacleType")] = obstacle
        # the codec's module/channel fields of channel `ch`, named as the message is (ObstacleReport_M1C1 ...)
        fields = codec.report_signals(T.Report(T.ABSENT, 0, 0, T.STATIC, 0), ch)
        exp[(msg.name, "Module")] = {m: f"module_{m + 1}" for m in range(3)}
        exp[(msg.name, "Channel")] = {c: f"channel_{c + 1}" for c in range(2)}
        assert msg.name == f"ObstacleReport_M{fields['Module'] + 1}C{fields['Channel'] + 1}"
    return exp


def category_names() -> dict:
    """RiskCategory as the runner sends the core's categories (monitor.core.risk) and the
    offline estimators name them (seed 001: low, moderate, high, critical)."""
    from monitor.core import risk
    from monitor.offline.risk import RISK_NAMES

    bus, runner = capturing_runner()
    out = {}
    for score in range(risk.MAX_SCORE + 1):
        category = risk.risk_category(score)
        runner.send(T.Outputs(**BASE_OUTPUTS, risk_score=score, risk_category=category))
        rx = codec.Receiver()
        assert rx.accept(codec.MONITOR_RISK_ID, bus.sent[-1].data, 0) == "MonitorRisk"
        assert rx.risk["RiskScore"] == score
        out[rx.risk["RiskCategory"]] = RISK_NAMES[category - 1]
    return out


def track_state_names() -> dict:
    """TrackState as the runner sends it: one frame per core state, decoded by the project's receiver."""
    bus, runner = capturing_runner()
    out = {}
    for state in TRACK_STATES:
        runner.send(T.Outputs(**BASE_OUTPUTS, track_state=state))
        msg = bus.sent[-2]
        assert msg.arbitration_id == codec.MONITOR_TRACK_ID
        rx = codec.Receiver()
        assert rx.accept(msg.arbitration_id, msg.data, 0) == "MonitorTrack"
        out[rx.track["TrackState"]] = T.TRACK_NAMES[state]
    return out


def test_reason_names_and_bits_are_the_cores():
    assert len(REASON_BITS) == len(T.REASON_NAMES)
    assert list(REASON_BITS) == [1 << i for i in range(len(REASON_BITS))]
    sig = cantools.database.load_file(str(DBC_PATH)).get_message_by_name("BrakeDemand").get_signal_by_name("Reason")
    assert sum(REASON_BITS) == sig.maximum      # every bit fits, none beyond the range


def test_every_value_table_matches_the_constants_the_project_sends(db):
    expected = expected_tables(db)
    actual = {(m.name, s.name): choices(db, m.name, s.name) for m in db.messages for s in m.signals if s.choices}
    # no table without a check, no checked signal without its table
    assert set(actual) == set(expected)
    for key, table in expected.items():
        assert actual[key] == table, key


def test_every_named_value_is_inside_the_signal_range(db):
    for msg in db.messages:
        for sig in msg.signals:
            for raw in (sig.choices or {}):
                assert 0 <= raw < 1 << sig.length, (msg.name, sig.name, raw)
                if sig.name not in ("VotedDistance", "TrackDistance"):     # 65535: the "no" code at the top
                    assert sig.minimum <= raw * sig.scale + sig.offset <= sig.maximum, (msg.name, sig.name, raw)


def test_obstacle_distance_has_no_no_distance_code(db):
    """A sensor report has no 'no distance' value: 65535 is refused, absence is Status absent."""
    for ch, msg in enumerate(obstacle_messages(db)):
        assert not msg.get_signal_by_name("Distance").choices
        signals = codec.report_signals(T.Report(T.ABSENT, T.MAX_DISTANCE_DM, 0, T.STATIC, 0), ch)
        rx = codec.Receiver()
        assert rx.accept(msg.frame_id, codec.encode(msg.frame_id, signals, 0), 0) == msg.name
        signals["Distance"] = T.NO_DISTANCE
        assert rx.accept(msg.frame_id, codec.encode(msg.frame_id, signals, 1), 0) is None
        assert rx.rejected["out_of_range"] == 1


# ----------------------------------------------------------------------------- units

def test_every_physical_signal_has_its_unit(db):
    """The DBC's physical units are the core's integer units (DESIGN.md section 4) scaled."""
    units = {"Distance": ("m", 0.1), "ClosingSpeed": ("m/s", 0.01), "Speed": ("m/s", 0.01),
             "VotedDistance": ("m", 0.1), "TrackDistance": ("m", 0.1), "TrackAge": ("s", 0.1),
             "R1": ("%", 0.1), "R2": ("%", 0.1), "TableRisk": ("ppm", 1)}
    for msg in db.messages:
        for sig in msg.signals:
            if sig.name in units:
                assert (sig.unit, sig.scale, sig.offset) == (*units[sig.name], 0), (msg.name, sig.name)
            else:
                # counters, enumerations, bit fields, CRC: raw integers without a unit
                assert (sig.scale, sig.offset) == (1, 0) and not sig.unit, (msg.name, sig.name)


# ----------------------------------------------------------------------------- MonitorTrack as sent

def held_track_frames(**change) -> list:
    """The frames one cycle sends for a track held 3.7 s at 123.4 m, the curves on it."""
    bus, runner = capturing_runner()
    runner.send(T.Outputs(**(BASE_OUTPUTS | dict(demand=T.EMERGENCY, reasons=T.R_MEMORY | T.R_LATCH,
                                                  track_dm=1234, track_cycles=37, track_state=T.TRACK_HELD)
                             | change)))
    return bus.sent


def test_the_runner_sends_the_track_right_after_the_status(db):
    sent = held_track_frames()
    assert [m.arbitration_id for m in sent] == [codec.BRAKE_DEMAND_ID, codec.MONITOR_STATUS_ID, codec.MONITOR_TRACK_ID,
                                                codec.MONITOR_RISK_ID]
    rx = codec.Receiver()
    assert [rx.accept(m.arbitration_id, m.data, 0) for m in sent] == ["BrakeDemand", "MonitorStatus", "MonitorTrack",
                                                                       "MonitorRisk"]
    assert rx.track["TrackState"] == T.TRACK_HELD and rx.track["Memory"] == 1
    assert rx.track["TrackDistance"] == 1234 and rx.track["TrackAge"] == 37         # 37 cycles of 100 ms
    named = db.decode_message(codec.MONITOR_TRACK_ID, bytes(sent[2].data), decode_choices=True)
    assert (str(named["TrackState"]), str(named["Memory"])) == ("held", "memory")
    assert named["TrackDistance"] == pytest.approx(123.4) and named["TrackAge"] == pytest.approx(3.7)
    # the reason bits name memory and the hold
    assert str(db.decode_message(codec.BRAKE_DEMAND_ID, bytes(sent[0].data))["Reason"]) == str(T.R_MEMORY | T.R_LATCH)
    assert str(db.decode_message(codec.BRAKE_DEMAND_ID, bytes(held_track_frames(reasons=T.R_MEMORY)[0].data))
               ["Reason"]) == "memory"


def test_track_age_saturates_and_no_track_is_named(db):
    sent = held_track_frames(track_cycles=10**7)
    assert db.decode_message(codec.MONITOR_TRACK_ID, bytes(sent[2].data))["TrackAge"] == pytest.approx(6553.5)
    sent = held_track_frames(track_dm=T.NO_DISTANCE, track_cycles=0, track_state=T.TRACK_FORGOTTEN, reasons=0)
    named = db.decode_message(codec.MONITOR_TRACK_ID, bytes(sent[2].data))
    assert (str(named["TrackState"]), str(named["TrackDistance"]), str(named["Memory"])) == (
        "forgotten", "no_track", "none")
    assert named["TrackDistance"].value == 65535


def test_the_track_age_is_a_time_at_any_period():
    from can_bus.runner import track_age

    assert [track_age(c, 100) for c in (0, 1, 37)] == [0, 1, 37]
    assert [track_age(c, 50) for c in (1, 2, 3)] == [1, 1, 2]          # 0.05 s rounds to 0.1 s, 0.15 s to 0.2 s
    assert track_age(7, 250) == 18 and track_age(10**9, 1000) == 65535


def test_the_final_emergency_says_no_track(db):
    bus, runner = capturing_runner()
    runner.send_final_emergency()
    assert [m.arbitration_id for m in bus.sent] == [codec.BRAKE_DEMAND_ID, codec.MONITOR_STATUS_ID,
                                                    codec.MONITOR_TRACK_ID, codec.MONITOR_RISK_ID]
    named = db.decode_message(codec.MONITOR_TRACK_ID, bytes(bus.sent[2].data))
    assert (str(named["TrackState"]), str(named["TrackDistance"])) == ("none", "no_track")
    risk = db.decode_message(codec.MONITOR_RISK_ID, bytes(bus.sent[3].data))     # nothing known: the worst
    assert (str(risk["RiskCategory"]), risk["R1"], risk["R2"], risk["TableRisk"]) == ("critical", 50, 100, 1_000_000)


def test_cantools_decodes_the_risk_with_its_units(db):
    """A HIL engineer's view of MonitorRisk: cantools names every signal with its unit and the
    category with its name; R1 and R2 are the core's ppm rounded up to 0.1 %."""
    bus, runner = capturing_runner()
    runner.send(T.Outputs(**(BASE_OUTPUTS | dict(r1_ppm=6_693, r2_ppm=500_001, risk_score=13, risk_category=3,
                                                 table_risk_ppm=23_141))))
    msg = db.get_message_by_frame_id(codec.MONITOR_RISK_ID)
    named = db.decode_message(codec.MONITOR_RISK_ID, bytes(bus.sent[3].data))
    assert named["R1"] == pytest.approx(0.7) and named["R2"] == pytest.approx(50.1)
    assert (str(named["RiskCategory"]), named["RiskScore"], named["TableRisk"]) == ("high", 13, 23_141)
    assert {s.name: s.unit for s in msg.signals if s.unit} == {"R1": "%", "R2": "%", "TableRisk": "ppm"}


# ----------------------------------------------------------------------------- as a user decodes

@pytest.fixture(scope="module")
def bus_log(tmp_path_factory) -> Path:
    """A candump log of a scenario run on the virtual bus: every frame from the project's sender."""
    out = tmp_path_factory.mktemp("dbc-values")
    setup = core.create(Config(), TABLE.read_bytes())
    result = session.run_virtual(setup, scenario.load("fault-cascade"), out, plot=False)
    return Path(result.summary["log"])


@pytest.fixture(scope="module")
def service_log(tmp_path_factory) -> Path:
    """The default scenario's log: the shipped m2 table brakes with service there (issue 41's
    table never asks for service in fault-cascade, where the faults answer first)."""
    out = tmp_path_factory.mktemp("dbc-service")
    setup = core.create(Config(), TABLE.read_bytes())
    return Path(session.run_virtual(setup, scenario.load("static-obstacle"), out, plot=False).summary["log"])


def test_cantools_decodes_real_frames_to_names(db, bus_log, service_log):
    seen: dict[tuple, set] = {}
    no_distance = 0
    for f in logfile.read(bus_log):
        fid, data = f.msg.arbitration_id, bytes(f.msg.data)
        named = db.decode_message(fid, data, decode_choices=True)
        raw = db.decode_message(fid, data, decode_choices=False, scaling=False)
        msg = db.get_message_by_frame_id(fid)
        for name, value in named.items():
            if isinstance(value, NamedSignalValue):
                # the name stands for exactly the raw value on the bus
                assert value.value == raw[name] and value.name == choices(db, msg.name, name)[raw[name]]
                seen.setdefault((msg.name, name), set()).add(value.name)
            else:
                assert raw[name] not in choices(db, msg.name, name), (msg.name, name, raw[name])
        if fid == codec.MONITOR_STATUS_ID and raw["VotedDistance"] == T.NO_DISTANCE:
            v = named["VotedDistance"]
            assert isinstance(v, NamedSignalValue) and v.name == "no_distance" and v.value == 65535
            no_distance += 1
    assert no_distance > 0
    demands = [db.decode_message(f.msg.arbitration_id, bytes(f.msg.data))
               for f in logfile.read(service_log) if f.msg.arbitration_id == codec.BRAKE_DEMAND_ID]
    levels = {getattr(d["Level"], "name", d["Level"]) for d in demands}
    reasons = {getattr(d["Reason"], "name", d["Reason"]) for d in demands}
    assert seen[("BrakeDemand", "Level")] | levels == {"none", "service", "emergency"} and "service" in levels
    assert {"NORMAL", "SAFE_STOP"} <= seen[("MonitorStatus", "Mode")]
    assert {"none", "safe_stop"} <= seen[("BrakeDemand", "Reason")] and "table" in reasons
    assert {"absent", "present"} <= seen[("ObstacleReport_M1C1", "Status")]
    assert {"none", "seen"} <= seen[("MonitorTrack", "TrackState")]
    assert seen[("MonitorTrack", "TrackDistance")] == {"no_track"}
    for ch, msg in enumerate(obstacle_messages(db)):
        assert seen[(msg.name, "Module")] == {f"module_{ch // 2 + 1}"}
        assert seen[(msg.name, "Channel")] == {f"channel_{ch % 2 + 1}"}


def test_cantools_command_line_decodes_a_candump_log(bus_log):
    lines = bus_log.read_text(encoding="ascii").splitlines()
    status = [ln for ln in lines if " 040#" in ln][:5]
    demand = [ln for ln in lines if " 010#" in ln]
    track = [ln for ln in lines if " 041#" in ln]
    seen = next(ln for ln in track if codec.database().decode_message(
        codec.MONITOR_TRACK_ID, bytes.fromhex(ln.split("#")[1]), decode_choices=False)["TrackState"] == T.TRACK_SEEN)
    held = f"(0.000000) vcan0 041#{bytes(held_track_frames()[2].data).hex().upper()}"     # as the runner sends it
    tracks = [track[0], seen, held]
    picked = status + tracks + [next(ln for ln in demand if codec.database().decode_message(
        codec.BRAKE_DEMAND_ID, bytes.fromhex(ln.split("#")[1]), decode_choices=False)["Level"] == T.EMERGENCY)]
    proc = subprocess.run([sys.executable, "-m", "cantools", "decode", "--single-line", str(DBC_PATH)],
                          input="\n".join(picked) + "\n", capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.splitlines()
    assert len(out) == len(picked)
    assert all("MonitorStatus(" in ln and "VotedDistance: no_distance" in ln for ln in out[:len(status)])
    none, seen, held = out[len(status):len(status) + 3]
    assert all("MonitorTrack(" in ln for ln in (none, seen, held))
    assert "TrackState: none" in none and "TrackDistance: no_track" in none and "TrackAge: 0.0 s" in none
    assert "TrackState: seen" in seen and re.search(r"TrackDistance: [0-9.]+ m\b", seen) and "TrackAge: 0.0 s" in seen
    assert "TrackState: held" in held and "Memory: memory" in held and "TrackDistance: 123.4 m" in held
    assert "TrackAge: 3.7 s" in held
    assert "Level: emergency" in out[-1]


def test_cantools_dump_lists_the_value_tables():
    proc = subprocess.run([sys.executable, "-m", "cantools", "dump", str(DBC_PATH)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    for text in ("65535 no_distance", "4096 dispute", "8192 memory", "2 emergency", "3 SAFE_STOP", "32 perceptor",
                 "MonitorTrack", "0x41", "65535 no_track", "2 held", "3 confirming", "4 forgotten", "5 passed"):
        assert text in proc.stdout, text
