"""The CAN network in FMI 3.0 co-simulation (issue 42): our bus simulation FMU and frame
player nodes, wired by their FMI-LS-BUS terminals in an fmu-manipulation-toolbox container
and run by FMPy. Judged by the bus's own trace (every transmission's queue, start and end
time) against the bit-timing arithmetic, and by what the nodes received."""
from __future__ import annotations

import csv
import ctypes
import subprocess

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fmu import lsbus_system as S
from fmu.build import C_DIR, CFLAGS, compiler

PERIOD = 0.1
SENSOR_IDS = range(0x20, 0x26)
STEP = 1e-4          # the container's step: deliveries reach the nodes at the next one


def brake_frames(duration: float):
    return [(PERIOD * i, 0x10, 0, bytes([i % 256]) + bytes(7)) for i in range(1, round(duration / PERIOD))]


def sensor_frames(duration: float):
    return [(PERIOD * i, fid, 0, bytes([fid, i % 256]) + bytes(6)) for i in range(1, round(duration / PERIOD))
            for fid in SENSOR_IDS]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    out = tmp_path_factory.mktemp("lsbus")
    monitor = S.build_player(brake_frames(30.0), out, "monitor.fmu")
    sensors = S.build_player(sensor_frames(30.0), out, "sensors.fmu")
    bus = S.build_bus(2, out)
    return out, monitor, sensors, bus


OUTPUTS = [("canbus.fmu", "watch_max_delay", "delay"), ("canbus.fmu", "watch_frames", "bus_brake_frames"),
           ("canbus.fmu", "errors", "errors"), ("canbus.fmu", "frames", "frames"), ("canbus.fmu", "bus_load", "load"),
           ("sensors.fmu", "watch_frames", "brake_frames"), ("sensors.fmu", "rx_frames", "sensors_rx"),
           ("sensors.fmu", "brake", "brake"), ("sensors.fmu", "first_brake", "first_brake"),
           ("monitor.fmu", "rx_frames", "monitor_rx"), ("monitor.fmu", "confirmed", "monitor_confirmed"),
           ("monitor.fmu", "rx_errors", "monitor_errors"), ("canbus.fmu", "config_mismatch", "mismatch")]


def run(fmus, name: str, duration: float = 30.0, **bus):
    from fmpy import simulate_fmu
    out, monitor, sensors, canbus = fmus
    trace = out / f"{name}.csv"
    starts = {("canbus.fmu", "trace_file"): str(trace), **{("canbus.fmu", k): v for k, v in bus.items()}}
    container = S.build_container([S.Node(monitor), S.Node(sensors)], canbus, out / f"{name}.fmu", STEP, starts,
                                  OUTPUTS)
    result = simulate_fmu(str(container), stop_time=duration, step_size=STEP, output_interval=duration / 2,
                          use_event_mode=False, fmi_type="CoSimulation")
    final = {n: result[n][-1] for n in result.dtype.names}
    with open(trace) as fh:
        rows = list(csv.DictReader(fh))
    return final, rows, container


@pytest.fixture(scope="module")
def quiet(fmus):
    return run(fmus, "quiet")


@pytest.fixture(scope="module")
def canbus_c(tmp_path_factory):
    from fmu import canbus_c
    lib = canbus_c.CanBusLib(canbus_c.build(tmp_path_factory.mktemp("canbus")))
    return canbus_c.CanBusC(lib, 2, S.BIT_RATE, S.DATA_BIT_RATE)


def frame_ns(lib, fid: int, data: bytes) -> int:
    from fmu.canbus_c import Frame
    return lib.frame_ns(Frame(fid, data))


def test_every_fmu_validates_in_fmpy_and_the_toolbox_checker(fmus, quiet):
    from fmpy.validation import validate_fmu
    out, monitor, sensors, bus = fmus
    for fmu in (monitor, bus, quiet[2]):
        assert validate_fmu(str(fmu)) == [], fmu.name
        res = subprocess.run(["fmutool", "-input", str(fmu), "-check"], capture_output=True, text=True)
        text = res.stdout + res.stderr
        assert res.returncode == 0 and "No semantic error" in text and "compliant with FMI-3.0" in text, text


def test_frames_cross_the_bus_in_id_order_with_their_bit_times(quiet, canbus_c):
    final, rows, _ = quiet
    cycle = [r for r in rows if abs(float(r["queued_s"]) - 1.0) < 1e-9]
    assert [int(r["id"], 16) for r in cycle] == [0x10, *SENSOR_IDS]       # arbitration: lowest ID first
    assert float(cycle[0]["start_s"]) == pytest.approx(1.0, abs=1e-12)
    for prev, row in zip(cycle, cycle[1:]):                               # back to back, 3 bits of intermission
        assert float(row["start_s"]) == pytest.approx(float(prev["end_s"]) + 3 / S.BIT_RATE, abs=1e-9)
    for row in cycle:
        ns = frame_ns(canbus_c, int(row["id"], 16), bytes.fromhex(row["data"]))
        assert float(row["end_s"]) - float(row["start_s"]) == pytest.approx(ns / 1e9, abs=1e-9)
    assert 0.2e-3 < ns / 1e9 < 0.28e-3                                     # about 0.25 ms for 8 bytes at 500k


def test_every_node_receives_what_the_others_sent_and_a_confirmation_of_its_own(quiet):
    final, rows, _ = quiet
    cycles = 299
    assert final["frames"] == cycles * 7 and final["bus_brake_frames"] == cycles
    assert final["brake_frames"] == cycles and final["sensors_rx"] == cycles        # the sensors hear BrakeDemand
    assert final["monitor_rx"] == cycles * 6 and final["monitor_confirmed"] == cycles
    assert not final["brake"] and final["first_brake"] == -1.0
    assert final["delay"] < 1e-9                                           # BrakeDemand never waited
    assert final["mismatch"] == 0 and final["errors"] == 0


def test_a_flood_at_0x000_starves_brake_demand_and_the_receiver_brakes(fmus, quiet):
    final, rows, _ = run(fmus, "flood", flood_id=0, flood_start=20.0, flood_stop=21.0)
    brake = [r for r in rows if r["id"] == "0x010"]
    before = [r for r in brake if float(r["end_s"]) < 20.0][-1]
    waited = [r for r in brake if float(r["queued_s"]) >= 20.0][0]
    assert float(waited["queued_s"]) == pytest.approx(20.0)
    assert float(waited["start_s"]) >= 21.0                                # nothing before the flood ends
    assert final["delay"] == pytest.approx(float(waited["start_s"]) - 20.0) and final["delay"] >= 1.0
    # the receiver's 300 ms timeout runs from the last BrakeDemand it got; it acts at the next step
    assert final["brake"]
    assert float(before["end_s"]) + 0.3 <= final["first_brake"] <= float(before["end_s"]) + 0.3 + 2 * STEP
    floods = [r for r in rows if r["id"] == "0x000"]
    assert floods and all(20.0 <= float(r["start_s"]) < 21.0 for r in floods)
    assert final["load"] > quiet[0]["load"] + 0.9 / 30                    # one second of a busy bus


def test_a_flood_at_0x7ff_costs_brake_demand_at_most_one_frame(fmus, canbus_c):
    final, rows, _ = run(fmus, "flood_low", flood_id=0x7FF, flood_start=20.0, flood_stop=21.0)
    assert not final["brake"]
    assert 0 < final["delay"] <= (frame_ns(canbus_c, 0x7FF, bytes(8)) + 3 * 2000) / 1e9


def test_an_error_frame_delays_the_frame_which_is_sent_again(fmus, canbus_c):
    final, rows, _ = run(fmus, "errors", error_id=0x10, error_count=2)
    assert final["errors"] == 2 and final["monitor_errors"] == 2
    first = [r for r in rows if r["id"] == "0x010"][:3]
    assert [r["kind"] for r in first] == ["bus_error", "bus_error", "delivered"]
    assert first[2]["queued_s"] == first[0]["queued_s"]                  # the same frame, retransmitted
    assert final["bus_brake_frames"] == 299


# ---- the Bus Operation codec (rg_lsbus.c), by itself ----------------------------------

@pytest.fixture(scope="module")
def ops(tmp_path_factory):
    lib_path = tmp_path_factory.mktemp("ops") / "librg_lsbus.so"
    src = C_DIR / "lsbus" / "rg_lsbus.c"
    subprocess.run([compiler(), *CFLAGS, "-shared", f"-I{src.parent}", str(src), "-o", str(lib_path)], check=True)
    lib = ctypes.CDLL(str(lib_path))
    return lib


class Op(ctypes.Structure):
    _fields_ = [("op", ctypes.c_uint32), ("id", ctypes.c_uint32), ("ide", ctypes.c_uint8), ("rtr", ctypes.c_uint8),
                ("brs", ctypes.c_uint8), ("esi", ctypes.c_uint8), ("length", ctypes.c_uint16),
                ("data", ctypes.c_uint8 * 64), ("error_code", ctypes.c_uint8), ("error_flag", ctypes.c_uint8),
                ("is_sender", ctypes.c_uint8), ("kind", ctypes.c_uint8), ("value", ctypes.c_uint32)]


def walk(lib, data: bytes):
    buf = ctypes.create_string_buffer(data, len(data))
    offset = ctypes.c_size_t(0)
    op = Op()
    out = []
    while True:
        r = lib.rg_lsbus_next(buf, ctypes.c_size_t(len(data)), ctypes.byref(offset), ctypes.byref(op))
        if r != 1:
            return out, r, offset.value
        out.append((op.op, op.id, op.length, bytes(op.data[:op.length])))


def transmit_bytes(fid: int, data: bytes, fd: bool) -> bytes:
    """The CAN (FD) Transmit operation written from the standard's table, independently of rg_lsbus.c."""
    le = lambda v, n: v.to_bytes(n, "little")                                            # noqa: E731
    if fd:
        return le(0x11, 4) + le(17 + len(data), 4) + le(fid, 4) + b"\x00\x01\x00" + le(len(data), 2) + data
    return le(0x10, 4) + le(16 + len(data), 4) + le(fid, 4) + b"\x00\x00" + le(len(data), 2) + data


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 0x7FF), st.sampled_from([0, 1, 8, 12, 20, 64]), st.booleans()), max_size=6))
def test_operations_written_from_the_standard_are_read_back(ops, frames):
    frames = [(fid, n, fd or n > 8) for fid, n, fd in frames]
    stream = b"".join(transmit_bytes(fid, bytes(range(n)), fd) for fid, n, fd in frames)
    got, r, offset = walk(ops, stream)
    assert r == 0 and offset == len(stream)
    assert got == [(0x11 if fd else 0x10, fid, n, bytes(range(n))) for fid, n, fd in frames]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=80))
def test_garbage_never_reads_past_its_buffer(ops, junk):
    got, r, offset = walk(ops, junk)
    assert r in (0, -1) and offset <= len(junk)
    if r == 0:
        assert offset == len(junk)


def test_a_length_that_lies_is_refused(ops):
    good = transmit_bytes(0x10, bytes(8), False)
    assert walk(ops, good)[1] == 0
    for bad in (good[:4] + (100).to_bytes(4, "little") + good[8:],      # longer than the buffer
                good[:4] + (8).to_bytes(4, "little") + good[8:],        # shorter than a transmit
                good[:14] + (9).to_bytes(2, "little") + good[16:]):     # 9 data bytes: not a classic length
        got, r, _ = walk(ops, bad)
        assert r == -1 and got == []


def test_terminals_mime_types_and_manifest_are_the_standards(fmus):
    """FMI-LS-BUS (Network Abstraction): one network terminal per bus with the transceiver
    matching rule and its four members, binaries of the CAN MIME type, the manifest saying
    which FMU is the bus simulation."""
    import xml.etree.ElementTree as ET
    import zipfile
    out, monitor, sensors, bus = fmus
    for fmu, terminals, is_bus in ((monitor, ["CAN"], "false"), (bus, ["Node1", "Node2"], "true")):
        with zipfile.ZipFile(fmu) as z:
            md = ET.fromstring(z.read("modelDescription.xml"))
            ti = ET.fromstring(z.read("terminalsAndIcons/terminalsAndIcons.xml"))
            manifest = ET.fromstring(z.read("extra/org.fmi-standard.fmi-ls-bus/fmi-ls-manifest.xml"))
        binaries = md.findall("ModelVariables/Binary")
        assert binaries and {b.get("mimeType") for b in binaries} == {
            'application/org.fmi-standard.fmi-ls-bus.can; version="1.0.0"'}
        found = ti.findall("Terminals/Terminal")
        assert [t.get("name") for t in found] == terminals
        for t in found:
            assert t.get("terminalKind") == "org.fmi-ls-bus.network-terminal"
            assert t.get("matchingRule") == "org.fmi-ls-bus.transceiver"
            assert sorted(m.get("memberName") for m in t) == ["Rx_Clock", "Rx_Data", "Tx_Clock", "Tx_Data"]
        ns = "{http://fmi-standard.org/fmi-ls-manifest}"
        assert manifest.get(f"{ns}fmi-ls-name") == "org.fmi-standard.fmi-ls-bus"
        assert manifest.get("isBusSimulationFMU") == is_bus
        clocks = {c.get("name"): c for c in md.findall("ModelVariables/Clock")}
        assert all(c.get("intervalVariability") == "triggered" for c in clocks.values())
