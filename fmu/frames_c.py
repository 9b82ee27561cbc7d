"""The frame layer in C (fmu/c/frames/, issue 42) as a shared library with a ctypes face: what
the network FMUs will read and write on the bus, held to can_bus/codec.py, runner.py,
security.py and brake_receiver.py by tests/test_frames_c.py.

The signals' packing is generated at build time from can_bus/railguard.dbc by cantools'
C generator (rg_dbc.c, rg_dbc.h), so the DBC stays the one source of truth; libcrypto
(OpenSSL 3) provides AES-CMAC for secured frames (`apt-get install libssl-dev`).
"""
from __future__ import annotations

import ctypes
import subprocess
import sys
from importlib import resources
from pathlib import Path
from typing import Optional

from .build import C_DIR, CFLAGS, BuildError, compiler

FRAMES_DIR = C_DIR / "frames"
SOURCES = [FRAMES_DIR / "rg_frames_rx.c", FRAMES_DIR / "rg_frames_tx.c", C_DIR / "secoc" / "rg_secoc.c"]
DBC_MODULE = "rg_dbc"

# rg_frames.h's verdicts, in order: codec.REJECT_REASONS then codec.SHELL_REJECT_REASONS
VERDICTS = ("accepted", "unknown_id", "wrong_length", "bad_crc", "repeated_counter", "counter_jump", "out_of_range",
            "rate_exceeded", "second_sender", "undecodable", "stale_freshness", "bad_mac", "no_key", "fd_frame",
            "classical_frame", "remote_frame", "error_frame", "foreign_output", "receive_error", "filtered")
CAUSES = ("power_up", "timeout", "second_sender", "invalid_level")
MESSAGE_IDS = (0x10, 0x20, 0x21, 0x22, 0x23, 0x24, 0x25, 0x30, 0x40, 0x41, 0x42)
KEY_OWNERS = tuple(f"ch{i}" for i in range(6)) + ("train", "monitor")     # keys.SENDERS
FLAG_EXTENDED, FLAG_FD, FLAG_REMOTE, FLAG_ERROR = 1, 2, 4, 8
SNAPSHOT = 6 * 6 + 5 + 6 + 2 + 10 + 6 + 8 + 1 + (len(VERDICTS) - 2) + 4 * len(MESSAGE_IDS)


def generate_dbc_source(out_dir: Path) -> None:
    """rg_dbc.c and rg_dbc.h from the shipped DBC, by cantools' C generator (integers only)."""
    dbc = Path(str(resources.files("can_bus").joinpath("railguard.dbc")))
    cmd = [sys.executable, "-m", "cantools", "generate_c_source", str(dbc), "--no-floating-point-numbers",
           "--database-name", DBC_MODULE, "-o", str(out_dir)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BuildError(f"cantools generate_c_source failed:\n{res.stderr.strip()}")


def build(out_dir: Path) -> Path:
    """Generate the packing code and compile the frame layer into `out_dir`/librg_frames.so."""
    out_dir.mkdir(parents=True, exist_ok=True)
    generate_dbc_source(out_dir)
    output = out_dir / "librg_frames.so"
    cmd = [compiler(), *CFLAGS, "-shared", f"-I{FRAMES_DIR}", f"-I{C_DIR / 'secoc'}", f"-I{C_DIR / 'core'}",
           f"-I{out_dir}", *map(str, SOURCES), str(out_dir / f"{DBC_MODULE}.c"), "-o", str(output), "-lcrypto"]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise BuildError(f"compiling {output.name} failed (libcrypto: apt-get install libssl-dev):\n{res.stderr.strip()}")
    return output


class Frame(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("data", ctypes.c_uint8 * 20), ("length", ctypes.c_int32),
                ("is_fd", ctypes.c_int32)]

    def bytes(self) -> bytes:
        return bytes(self.data[:self.length])


class KeySet(ctypes.Structure):
    _fields_ = [("key", (ctypes.c_uint8 * 16) * 8), ("have", ctypes.c_int32 * 8)]


class Report(ctypes.Structure):
    _fields_ = [("heard", ctypes.c_int32), ("status", ctypes.c_int32), ("distance_dm", ctypes.c_int32),
                ("closing_cms", ctypes.c_int32), ("obstacle", ctypes.c_int32), ("tick", ctypes.c_int64)]


class TrainC(ctypes.Structure):
    _fields_ = [("speed_cms", ctypes.c_int32), ("track", ctypes.c_int32), ("brake", ctypes.c_int32)]


class InputsC(ctypes.Structure):
    _fields_ = [("reports", Report * 6), ("train", TrainC), ("overruns", ctypes.c_int32)]


OUTPUT_FIELDS = ("demand", "reasons", "distance_dm", "node", "mode", "module_flags", "system_error", "observation",
                 "cycle", "error_cycles", "warning", "track_dm", "track_cycles", "track_state", "r1_ppm", "r2_ppm",
                 "risk_score", "risk_category", "table_risk_ppm")


class OutputsC(ctypes.Structure):
    _fields_ = [(name, ctypes.c_int32) for name in OUTPUT_FIELDS]


def keyset(keys: Optional[dict]):
    """The C key set of `keys` (sender -> 16 bytes, keys.KeySet.keys); None: an unsecured node."""
    if keys is None:
        return None
    ks = KeySet()
    for i, owner in enumerate(KEY_OWNERS):
        if owner in keys:
            ctypes.memmove(ks.key[i], keys[owner], 16)
            ks.have[i] = 1
    return ks


class FramesC:
    """The C functions, called through ctypes; state structs are opaque buffers."""

    def __init__(self, library: Path) -> None:
        lib = ctypes.CDLL(str(library))
        vp, i32, i64, u32, sz = ctypes.c_void_p, ctypes.c_int32, ctypes.c_int64, ctypes.c_uint32, ctypes.c_size_t
        lib.rg_frames_sizeof.argtypes, lib.rg_frames_sizeof.restype = [i32], sz
        lib.rg_frames_crc.argtypes, lib.rg_frames_crc.restype = [ctypes.c_char_p, u32], ctypes.c_uint8
        lib.rg_receiver_init.argtypes = [vp, i32, i32, ctypes.POINTER(KeySet)]
        lib.rg_receiver_accept.argtypes = [vp, u32, i32, ctypes.c_char_p, sz, i64]
        lib.rg_receiver_accept.restype = i32
        lib.rg_receiver_snapshot.argtypes = [vp, ctypes.POINTER(i64), sz]
        lib.rg_receiver_snapshot.restype = i32
        lib.rg_monitor_rx_init.argtypes = [vp, i32, i32, i32, ctypes.POINTER(KeySet)]
        lib.rg_monitor_ingest.argtypes = [vp, u32, u32, ctypes.c_char_p, sz, i64]
        lib.rg_monitor_ingest.restype = i32
        lib.rg_monitor_inputs.argtypes = [vp, i64, i32, ctypes.POINTER(InputsC), ctypes.POINTER(i32)]
        lib.rg_sender_init.argtypes = [vp, ctypes.POINTER(KeySet)]
        lib.rg_sender_frame.argtypes = [vp, u32, ctypes.c_char_p, ctypes.POINTER(Frame)]
        lib.rg_monitor_send.argtypes = [vp, ctypes.POINTER(OutputsC), i32, i32, i32, i32, i32, ctypes.POINTER(Frame)]
        lib.rg_send_report.argtypes = [vp, i32, i32, i32, i32, i32, ctypes.POINTER(Frame)]
        lib.rg_send_train.argtypes = [vp, i32, i32, i32, ctypes.POINTER(Frame)]
        lib.rg_brake_init.argtypes = [vp, i32]
        lib.rg_brake_level.argtypes = [vp, vp, i64, i32]
        lib.rg_brake_level.restype = i32
        self.lib = lib

    def _buffer(self, which: int):
        return ctypes.create_string_buffer(self.lib.rg_frames_sizeof(which))

    # ---- receive
    def receiver(self, channels: int = 6, rate_window_ms: int = 0, keys: Optional[dict] = None):
        rx = self._buffer(0)
        ks = keyset(keys)
        self.lib.rg_receiver_init(rx, channels, rate_window_ms, None if ks is None else ctypes.byref(ks))
        return rx

    def accept(self, rx, frame_id: int, data: bytes, tick: int, extended: bool = False) -> str:
        return VERDICTS[self.lib.rg_receiver_accept(rx, frame_id, int(extended), bytes(data), len(data), tick)]

    def snapshot(self, rx) -> list:
        out = (ctypes.c_int64 * SNAPSHOT)()
        assert self.lib.rg_receiver_snapshot(rx, out, SNAPSHOT) == SNAPSHOT
        return list(out)

    def monitor(self, channels: int, period_ms: int, timeout_cycles: int, keys: Optional[dict] = None):
        m = self._buffer(1)
        ks = keyset(keys)
        self.lib.rg_monitor_rx_init(m, channels, period_ms, timeout_cycles, None if ks is None else ctypes.byref(ks))
        return m

    def ingest(self, m, frame_id: int, flags: int, data: bytes, tick: int) -> str:
        return VERDICTS[self.lib.rg_monitor_ingest(m, frame_id, flags, bytes(data), len(data), tick)]

    def inputs(self, m, tick: int, overruns: int = 0) -> tuple[InputsC, bool]:
        inp, foreign = InputsC(), ctypes.c_int32(0)
        self.lib.rg_monitor_inputs(m, tick, overruns, ctypes.byref(inp), ctypes.byref(foreign))
        return inp, bool(foreign.value)

    # ---- send
    def sender(self, keys: Optional[dict] = None):
        s = self._buffer(2)
        ks = keyset(keys)
        self.lib.rg_sender_init(s, None if ks is None else ctypes.byref(ks))
        return s

    def monitor_send(self, s, out: OutputsC, foreign: bool, table_hash: int, misses: int, period_ms: int,
                     withhold_demand: bool = False) -> list:
        frames = (Frame * 4)()
        n = self.lib.rg_monitor_send(s, ctypes.byref(out), int(foreign), table_hash, misses, period_ms,
                                     int(withhold_demand), frames)
        if n < 0:
            raise RuntimeError("rg_monitor_send failed")
        return [(f.id, f.bytes(), bool(f.is_fd)) for f in frames[:n]]

    def report(self, s, channel: int, status: int, distance_dm: int, closing_cms: int, obstacle: int) -> bytes:
        f = Frame()
        if self.lib.rg_send_report(s, channel, status, distance_dm, closing_cms, obstacle, ctypes.byref(f)) != 0:
            raise RuntimeError("rg_send_report failed")
        return f.bytes()

    def train(self, s, speed_cms: int, track: int, brake: int) -> bytes:
        f = Frame()
        if self.lib.rg_send_train(s, speed_cms, track, brake, ctypes.byref(f)) != 0:
            raise RuntimeError("rg_send_train failed")
        return f.bytes()

    # ---- the brakes
    def brakes(self, period_ms: int = 100):
        b = self._buffer(3)
        self.lib.rg_brake_init(b, period_ms)
        return b

    def brake_level(self, b, rx, tick: int, standing: bool) -> int:
        return self.lib.rg_brake_level(b, rx, tick, int(standing))
