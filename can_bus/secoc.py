"""Secured frames, SecOC style (issue 39 item 1): who sent a frame, and that it is new.

The profile (docs/can.md, "Authenticated frames"): a CAN FD frame of 20 bytes.

    bytes 0..7    the classic frame as today: E2E CRC-8, alive counter, the DBC's signals
    bytes 8..11   the low 32 bits of the sender's 64-bit freshness value for this ID, little-endian
    bytes 12..19  the authenticator: CMAC-AES-128 (`cryptography`) under the sender's key over
                  the frame ID (2 bytes, big-endian), bytes 0..7 and the full freshness value
                  (8 bytes, big-endian), truncated to its first 64 bits

The freshness value counts the sender's frames on the ID and never goes back, across
restarts too (`FreshnessCounter` persists it ahead of use). A receiver accepts a frame only
if its freshness value is newer than the newest it accepted on the ID and at most `WINDOW`
ahead (frames lost, a sender restarted on its next reserved block), and only if the
authenticator verifies under the ID owner's key; it then remembers the value
(`FreshnessWindow`, persisted too, so a recording from an earlier session is refused). 32
bits on the wire are 13.6 years of frames at 10 Hz: the full value is rebuilt as the
smallest one above the newest accepted with those low bits.
"""
from __future__ import annotations

import hmac
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from cryptography.hazmat.primitives import cmac
from cryptography.hazmat.primitives.ciphers import algorithms

PAYLOAD_BYTES = 8
FV_WIRE_BYTES = 4              # the low 32 bits of the freshness value
MAC_BYTES = 8                  # the truncated authenticator, 64 bits
FRAME_LENGTH = PAYLOAD_BYTES + FV_WIRE_BYTES + MAC_BYTES    # 20: a CAN FD length (DLC 11)
FV_MODULUS = 1 << (8 * FV_WIRE_BYTES)
WINDOW = 1 << 16               # a frame may be this many values ahead of the newest accepted
RESERVE = 1 << 12              # a sender persists its counter this far ahead (4,096 frames: ~7 min at 10 Hz)
VERDICTS = ("ok", "wrong_length", "stale_freshness", "bad_mac")


def authenticator(key: bytes, frame_id: int, payload: bytes, fv: int) -> bytes:
    """The truncated CMAC over ID, payload and the full freshness value."""
    c = cmac.CMAC(algorithms.AES(key))
    c.update(frame_id.to_bytes(2, "big") + bytes(payload) + fv.to_bytes(8, "big"))
    return c.finalize()[:MAC_BYTES]


def protect(key: bytes, frame_id: int, payload: bytes, fv: int) -> bytes:
    """The secured frame of an 8-byte classic payload with freshness value `fv`."""
    if len(payload) != PAYLOAD_BYTES:
        raise ValueError(f"a secured frame carries {PAYLOAD_BYTES} payload bytes, not {len(payload)}")
    low = (fv % FV_MODULUS).to_bytes(FV_WIRE_BYTES, "little")
    return bytes(payload) + low + authenticator(key, frame_id, payload, fv)


def rebuild(newest: Optional[int], low: int) -> int:
    """The full freshness value: the smallest value above `newest` (None: nothing accepted
    yet, -1) whose low bits are `low`."""
    base = -1 if newest is None else newest
    cand = (base + 1) - ((base + 1) % FV_MODULUS) + low
    return cand if cand > base else cand + FV_MODULUS


def check(key: bytes, frame_id: int, data: bytes, newest: Optional[int]) -> tuple[str, Optional[int]]:
    """(verdict, freshness value) of a received frame: `ok` with the value to remember, or
    the reason it is refused (the value checked first, then the authenticator, so a stale
    frame costs no CMAC)."""
    if len(data) != FRAME_LENGTH:
        return "wrong_length", None
    low = int.from_bytes(data[PAYLOAD_BYTES:PAYLOAD_BYTES + FV_WIRE_BYTES], "little")
    fv = rebuild(newest, low)
    if fv - (-1 if newest is None else newest) > WINDOW:
        return "stale_freshness", None
    want = authenticator(key, frame_id, data[:PAYLOAD_BYTES], fv)
    if not hmac.compare_digest(want, bytes(data[PAYLOAD_BYTES + FV_WIRE_BYTES:])):
        return "bad_mac", None
    return "ok", fv


def _read_state(path: Optional[Path]) -> dict:
    if path is None or not path.exists():
        return {}
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return {int(k): int(v) for k, v in data.items()}
    except (OSError, ValueError, AttributeError) as exc:
        raise ValueError(f"{path}: not a freshness state file ({exc.__class__.__name__}); "
                         "a damaged state is never guessed: restore it or make a new key set") from None


def _write_state(path: Optional[Path], values: dict) -> None:
    """Write atomically (a crash leaves the old state or the new one, never half of one)."""
    if path is None:
        return
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        json.dump({str(k): v for k, v in sorted(values.items())}, fh)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


@dataclass
class FreshnessCounter:
    """A sender's freshness values per ID, persisted RESERVE ahead of use in `path` (None:
    in memory only, for tests): after a restart it goes on from the reserved value, so it
    never repeats one, whatever the crash."""

    path: Optional[Path] = None
    next: dict = field(default_factory=dict)
    reserved: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.path = None if self.path is None else Path(self.path)
        self.reserved = _read_state(self.path)
        self.next = dict(self.reserved)

    def take(self, frame_id: int) -> int:
        fv = self.next.get(frame_id, 0)
        if fv >= self.reserved.get(frame_id, 0):
            self.reserved[frame_id] = fv + RESERVE
            _write_state(self.path, self.reserved)
        self.next[frame_id] = fv + 1
        return fv


@dataclass
class FreshnessWindow:
    """A receiver's newest accepted freshness value per ID, persisted by `save` (at the end
    of a run and after every `SAVE_EVERY` accepted frames of an ID) in `path` (None: in
    memory). A restart cannot know what it accepted after its last save, so it starts
    `SAVE_EVERY` above the saved value: a frame it may already have taken is refused, and a
    sender that did not restart is refused for at most that many frames (1 s at 10 Hz)."""

    path: Optional[Path] = None
    newest: dict = field(default_factory=dict)
    unsaved: dict = field(default_factory=dict)
    SAVE_EVERY = 10

    def __post_init__(self) -> None:
        self.path = None if self.path is None else Path(self.path)
        self.newest = {k: v + self.SAVE_EVERY for k, v in _read_state(self.path).items()}

    def accept(self, key: bytes, frame_id: int, data: bytes) -> str:
        """Judge a frame; on `ok` remember its freshness value."""
        verdict, fv = check(key, frame_id, data, self.newest.get(frame_id))
        if verdict == "ok":
            self.newest[frame_id] = fv
            self.unsaved[frame_id] = self.unsaved.get(frame_id, 0) + 1
            if self.unsaved[frame_id] >= self.SAVE_EVERY:
                self.save()
        return verdict

    def save(self) -> None:
        _write_state(self.path, self.newest)
        self.unsaved.clear()
