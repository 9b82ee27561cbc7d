"""The CAN bus model in C (fmu/c/lsbus/, issue 42) as a shared library with a ctypes face: the
same code the FMI-LS-BUS bus-simulation FMU calls, for the tests (tests/test_canbus.py) and for
Python tooling that wants the arbitration a real bus has (vcan0 has none: a flood at 0x000 looks
harmless there, while on a real bus it starves BrakeDemand 0x010)."""
from __future__ import annotations

import ctypes
import subprocess
from dataclasses import dataclass
from pathlib import Path

from .build import C_DIR, CFLAGS, BuildError, compiler

LSBUS_DIR = C_DIR / "lsbus"
DELIVERED, BUS_ERROR, DROPPED = 1, 2, 3
KINDS = {DELIVERED: "delivered", BUS_ERROR: "bus_error", DROPPED: "dropped"}
EFF = 0x80000000            # marks an extended ID in stats and error_next (RG_CANBUS_EFF)
INT64_MAX = 2**63 - 1


def build(out_dir: Path) -> Path:
    """Compile rg_canbus.c into `out_dir`/librg_canbus.so (warnings are errors)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    output = out_dir / "librg_canbus.so"
    cmd = [compiler(), *CFLAGS, "-shared", f"-I{LSBUS_DIR}", str(LSBUS_DIR / "rg_canbus.c"), "-o", str(output)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BuildError(f"compiling {output.name} failed:\n{res.stderr.strip()}")
    return output


class _Frame(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("ide", ctypes.c_uint8), ("fd", ctypes.c_uint8), ("brs", ctypes.c_uint8),
                ("len", ctypes.c_uint8), ("data", ctypes.c_uint8 * 64)]


class _Event(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_int32), ("node", ctypes.c_int32), ("frame", _Frame),
                ("queued_ns", ctypes.c_int64), ("start_ns", ctypes.c_int64), ("end_ns", ctypes.c_int64)]


class _Stats(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("frames", ctypes.c_int64), ("errors", ctypes.c_int64),
                ("dropped", ctypes.c_int64), ("max_delay_ns", ctypes.c_int64), ("sum_delay_ns", ctypes.c_int64)]


@dataclass(frozen=True)
class Frame:
    id: int
    data: bytes = b""
    ide: bool = False
    fd: bool = False
    brs: bool = False


@dataclass(frozen=True)
class Event:
    kind: str
    node: int
    frame: Frame
    queued_ns: int
    start_ns: int
    end_ns: int


@dataclass(frozen=True)
class IdStats:
    id: int
    frames: int
    errors: int
    dropped: int
    max_delay_ns: int
    sum_delay_ns: int


def _c_frame(f: Frame) -> _Frame:
    if len(f.data) > 64:
        raise ValueError("a CAN FD frame carries at most 64 bytes")
    c = _Frame(f.id, int(f.ide), int(f.fd), int(f.brs), len(f.data))
    ctypes.memmove(c.data, bytes(f.data), len(f.data))
    return c


def _py_frame(c: _Frame) -> Frame:
    return Frame(c.id, bytes(c.data[:c.len]), bool(c.ide), bool(c.fd), bool(c.brs))


class CanBusLib:
    """The loaded library: argument types set once, layouts checked against the C sizes."""

    def __init__(self, library: Path) -> None:
        lib = ctypes.CDLL(str(library))
        vp, i32, i64 = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64
        fp, i32p = ctypes.POINTER(_Frame), ctypes.POINTER(ctypes.c_int32)
        sig = {
            "rg_canbus_init": ([vp, i32, i64, i64], None),
            "rg_canbus_submit": ([vp, i32, fp, i64], i32),
            "rg_canbus_flood": ([vp, i32, ctypes.c_uint32, i64, i64], None),
            "rg_canbus_error_next": ([vp, ctypes.c_uint32, i32], None),
            "rg_canbus_next_ns": ([vp], i64),
            "rg_canbus_advance": ([vp, i64, ctypes.POINTER(_Event), i32], i32),
            "rg_canbus_frame_bits": ([fp, i32p, i32p], i32),
            "rg_canbus_frame_wire": ([fp, ctypes.POINTER(ctypes.c_uint8), i32], i32),
            "rg_canbus_frame_ns": ([vp, fp], i64),
            "rg_canbus_stats": ([vp, i32p], ctypes.POINTER(_Stats)),
            "rg_canbus_busy_ns": ([vp], i64),
            "rg_canbus_pending": ([vp, i32], i32),
            "rg_canbus_sizeof": ([i32], i32),
        }
        for name, (args, res) in sig.items():
            getattr(lib, name).argtypes = args
            getattr(lib, name).restype = res
        for which, struct in ((1, _Event), (2, _Stats), (3, _Frame)):
            if lib.rg_canbus_sizeof(which) != ctypes.sizeof(struct):
                raise BuildError(f"rg_canbus layout {which}: C {lib.rg_canbus_sizeof(which)} bytes, "
                                 f"ctypes {ctypes.sizeof(struct)}")
        self.lib = lib
        self.bus_size = lib.rg_canbus_sizeof(0)

    def frame_bits(self, f: Frame) -> tuple[int, int]:
        """(nominal bits, data-rate bits) from SOF to the end of EOF; ValueError if invalid."""
        nom, dat = ctypes.c_int32(), ctypes.c_int32()
        c = _c_frame(f)
        if self.lib.rg_canbus_frame_bits(ctypes.byref(c), ctypes.byref(nom), ctypes.byref(dat)) < 0:
            raise ValueError(f"not a valid frame: {f}")
        return nom.value, dat.value

    def frame_wire(self, f: Frame) -> list[int]:
        """The bits on the wire, SOF to the end of EOF (0 dominant, the ACK slot acknowledged)."""
        c = _c_frame(f)
        out = (ctypes.c_uint8 * 768)()
        n = self.lib.rg_canbus_frame_wire(ctypes.byref(c), out, len(out))
        if n < 0:
            raise ValueError(f"not a valid frame: {f}")
        return list(out[:n])

    def bus(self, nodes: int, nominal_bps: int = 500_000, data_bps: int = 2_000_000) -> "CanBusC":
        return CanBusC(self, nodes, nominal_bps, data_bps)


class CanBusC:
    """One bus (its state in a ctypes buffer owned by this object)."""

    def __init__(self, lib: CanBusLib, nodes: int, nominal_bps: int, data_bps: int) -> None:
        self._c = lib.lib
        self._mem = (ctypes.c_int64 * (lib.bus_size // 8 + 1))()     # 8-byte aligned
        self._p = ctypes.cast(self._mem, ctypes.c_void_p)
        self._c.rg_canbus_init(self._p, nodes, nominal_bps, data_bps)

    def submit(self, node: int, frame: Frame, now_ns: int) -> bool:
        c = _c_frame(frame)
        return self._c.rg_canbus_submit(self._p, node, ctypes.byref(c), now_ns) == 0

    def flood(self, node: int, frame_id: int, from_ns: int, until_ns: int) -> None:
        self._c.rg_canbus_flood(self._p, node, frame_id, from_ns, until_ns)

    def error_next(self, frame_id: int, count: int) -> None:
        self._c.rg_canbus_error_next(self._p, frame_id, count)

    def next_ns(self) -> int:
        return self._c.rg_canbus_next_ns(self._p)

    def advance(self, now_ns: int, max_events: int = 64) -> list[Event]:
        buf = (_Event * max_events)()
        n = self._c.rg_canbus_advance(self._p, now_ns, buf, max_events)
        return [Event(KINDS[e.kind], e.node, _py_frame(e.frame), e.queued_ns, e.start_ns, e.end_ns) for e in buf[:n]]

    def run(self, until_ns: int) -> list[Event]:
        """Every event up to until_ns (advance until nothing more is due by then)."""
        events: list[Event] = []
        while True:
            batch = self.advance(until_ns)
            events += batch
            if len(batch) < 64:
                return events

    def frame_ns(self, frame: Frame) -> int:
        c = _c_frame(frame)
        return self._c.rg_canbus_frame_ns(self._p, ctypes.byref(c))

    def stats(self) -> dict[int, IdStats]:
        count = ctypes.c_int32()
        p = self._c.rg_canbus_stats(self._p, ctypes.byref(count))
        return {p[i].id: IdStats(p[i].id, p[i].frames, p[i].errors, p[i].dropped, p[i].max_delay_ns,
                                 p[i].sum_delay_ns) for i in range(count.value)}

    def busy_ns(self) -> int:
        return self._c.rg_canbus_busy_ns(self._p)

    def pending(self, node: int) -> int:
        return self._c.rg_canbus_pending(self._p, node)
