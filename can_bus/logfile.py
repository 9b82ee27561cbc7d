"""Read a recorded bus log as a stream of frames with their line numbers.

candump `-L` logs (`.log`), the format the runner and can-utils write, are parsed here line
by line: python-can's reader stops at the first bad line with no line number ("not enough
values to unpack"), takes `(nan)` as a timestamp, and turns every error frame other than
a bus error into an extended data frame, losing the bus-off it announces. Every other
format python-can reads (.asc, .blf, .csv, .mf4, .trc) goes through `can.LogReader`, with
the frame's position in place of a line number.

Nothing is read ahead: memory stays constant whatever the log's length. Any line that is
not a frame (garbage, binary data, a timestamp that is NaN, infinite or not a number, a
malformed identifier or payload) raises `LogError` naming the file and the line.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import can

CAN_ERR_FLAG = 0x20000000
CAN_EFF_MASK = 0x1FFFFFFF
FD_LENGTHS = frozenset((0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64))
_LINE = re.compile(r"\((?P<ts>[^()\s]*)\)\s+(?P<iface>\S+)\s+(?P<frame>\S+)(?:\s+(?P<dir>[RrTt]))?")
_HEX = re.compile(r"[0-9A-Fa-f]*")


class LogError(ValueError):
    """A log that cannot be replayed; the message is one line naming file and line."""


@dataclass(frozen=True)
class LogFrame:
    line: int            # line in the file (candump), else the frame's position (1-based)
    timestamp: float     # seconds, as recorded
    msg: can.Message


def read(path: str | Path) -> Iterator[LogFrame]:
    """Frames of the log in file order; raises LogError for a file that is not a CAN log."""
    p = Path(path)
    if not p.exists():
        raise LogError(f"{p}: no such file")
    if not p.is_file():
        raise LogError(f"{p}: not a file")
    if p.suffix.lower() == ".log":
        return _candump(p)
    return _python_can(p)


def _candump(p: Path) -> Iterator[LogFrame]:
    with p.open("rb") as f:
        for n, raw in enumerate(f, 1):
            try:
                text = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise LogError(f"{p}:{n}: not a candump line (binary data?)") from None
            if not text:
                continue
            yield parse_line(text, p, n)


def parse_line(text: str, p: Path | str, n: int) -> LogFrame:
    """One candump -L line: `(SECONDS) IFACE ID#DATA`, `ID#R[LEN]`, `ID##FLAGSDATA` (FD);
    an ID with CAN_ERR_FLAG (0x20000000) is an error frame."""
    m = _LINE.fullmatch(text)
    if m is None:
        shown = text if len(text) <= 60 else text[:57] + "..."
        raise LogError(f"{p}:{n}: not a candump line: {shown!r} (expected '(SECONDS) IFACE ID#DATA')")
    try:
        ts = float(m["ts"])
    except ValueError:
        raise LogError(f"{p}:{n}: timestamp {m['ts']!r} is not a number") from None
    if not math.isfinite(ts):
        raise LogError(f"{p}:{n}: timestamp {m['ts']!r} is not a finite number")
    ident, sep, payload = m["frame"].partition("#")
    if not sep or not ident or len(ident) not in (3, 8) or not _HEX.fullmatch(ident):
        raise LogError(f"{p}:{n}: identifier {ident!r} is not 3 or 8 hex digits followed by '#'")
    can_id = int(ident, 16)
    extended = len(ident) == 8
    if extended and can_id & ~(CAN_EFF_MASK | CAN_ERR_FLAG):
        raise LogError(f"{p}:{n}: identifier {ident} has flags other than the error flag")
    if extended and can_id & CAN_ERR_FLAG:
        data = _hex(payload, p, n, 8)
        msg = can.Message(timestamp=ts, arbitration_id=can_id & CAN_EFF_MASK, is_error_frame=True,
                          is_extended_id=False, data=data, dlc=len(data), channel=m["iface"])
        return LogFrame(n, ts, msg)
    if not extended and can_id > 0x7FF:
        raise LogError(f"{p}:{n}: identifier {ident} does not fit 11 bits")
    if payload[:1] == "#":                                  # CAN FD: '##' + flags nibble + data
        if len(payload) < 2 or payload[1] not in "0123456789abcdefABCDEF":
            raise LogError(f"{p}:{n}: CAN FD frame without its flags digit")
        data = _hex(payload[2:], p, n, 64)
        if len(data) not in FD_LENGTHS:
            raise LogError(f"{p}:{n}: CAN FD payload of {len(data)} bytes is not a valid FD length")
        flags = int(payload[1], 16)
        msg = can.Message(timestamp=ts, arbitration_id=can_id, is_extended_id=extended, is_fd=True,
                          bitrate_switch=bool(flags & 1), error_state_indicator=bool(flags & 2),
                          data=data, dlc=len(data), channel=m["iface"])
    elif payload[:1] in ("R", "r"):                         # remote request, optional length digit
        rest = payload[1:]
        if rest and not (rest.isdigit() and int(rest) <= 8):
            raise LogError(f"{p}:{n}: remote frame length {rest!r} is not 0-8")
        msg = can.Message(timestamp=ts, arbitration_id=can_id, is_extended_id=extended, is_remote_frame=True,
                          dlc=int(rest or 0), channel=m["iface"])
    else:
        data = _hex(payload.split("_", 1)[0], p, n, 8)     # '_D' is candump's len8_dlc suffix
        msg = can.Message(timestamp=ts, arbitration_id=can_id, is_extended_id=extended, data=data,
                          dlc=len(data), channel=m["iface"])
    return LogFrame(n, ts, msg)


def _hex(text: str, p, n: int, limit: int) -> bytes:
    if len(text) % 2 or not _HEX.fullmatch(text):
        raise LogError(f"{p}:{n}: payload {text[:40]!r} is not whole bytes of hex digits")
    if len(text) // 2 > limit:
        raise LogError(f"{p}:{n}: payload of {len(text) // 2} bytes is longer than {limit}")
    return bytes.fromhex(text)


def _python_can(p: Path) -> Iterator[LogFrame]:
    try:
        reader = can.LogReader(str(p))
    except ValueError as exc:
        raise LogError(f"{p}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file, said in one line
        raise LogError(f"{p}: cannot read as a CAN log: {type(exc).__name__}: {exc}") from None
    return _frames_of(reader, p)


def _frames_of(reader, p: Path) -> Iterator[LogFrame]:
    it = iter(reader)
    n = 0
    try:
        while True:
            try:
                msg = next(it)
            except StopIteration:
                return
            except Exception as exc:  # noqa: BLE001
                raise LogError(f"{p}: frame {n + 1}: cannot read: {type(exc).__name__}: {exc}") from None
            n += 1
            ts = msg.timestamp
            if not isinstance(ts, (int, float)) or not math.isfinite(ts):
                raise LogError(f"{p}: frame {n}: timestamp {ts!r} is not a finite number")
            yield LogFrame(n, float(ts), msg)
    finally:
        stop = getattr(reader, "stop", None)
        if stop is not None:
            stop()


def format_line(msg: can.Message, timestamp: float, iface: str = "vcan0") -> str:
    """The candump -L line of a frame (the inverse of parse_line); error frames keep their class."""
    if msg.is_error_frame:
        data = bytes(msg.data or b"").ljust(8, b"\0")
        return f"({timestamp:.6f}) {iface} {CAN_ERR_FLAG | (msg.arbitration_id & CAN_EFF_MASK):08X}#{data.hex().upper()}"
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_remote_frame:
        body = "R" + (str(msg.dlc) if msg.dlc else "")
    elif msg.is_fd:
        body = f"#{int(msg.bitrate_switch) | int(msg.error_state_indicator) << 1:X}{bytes(msg.data).hex().upper()}"
    else:
        body = bytes(msg.data).hex().upper()
    return f"({timestamp:.6f}) {iface} {ident}#{body}"


class CandumpWriter:
    """Writes frames as a candump -L log, one line each, flushed by the OS as it likes."""

    def __init__(self, path: str | Path, iface: str = "vcan0") -> None:
        self.file = open(path, "w", encoding="ascii")  # noqa: SIM115 - closed by stop()
        self.iface = iface

    def write(self, msg: can.Message, timestamp: float) -> None:
        self.file.write(format_line(msg, timestamp, self.iface) + "\n")

    def stop(self) -> None:
        self.file.close()
