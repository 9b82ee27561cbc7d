"""A node's part in the secured bus (issue 39 item 1): it signs what it sends under its own
keys and opens what it reads under the key of the ID's owner, each ID's freshness kept across
restarts.

A `Security` belongs to one node (the monitor, the scenario player's sensors and train, the
brake receiver), holds the keys that node has (`keys.load(folder, senders)`), and keeps its
freshness state in `<key set>/freshness/<node>.tx.json` (the values it signs with, reserved
ahead of use) and `<node>.rx.json` (the newest it accepted per ID): so a frame recorded in an
earlier session is refused, and a restarted sender never repeats a value. `state=False`
keeps the freshness in memory (a replay of a log reproduces its own session, tests).

On the wire a secured frame is a CAN FD frame of `secoc.FRAME_LENGTH` bytes (secoc.py). A
node without a `Security` is unsecured: classical 8-byte frames, E2E only, which every
summary, MonitorStatus and plot announces (UNSECURED).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Optional

from . import keys, secoc

FRESHNESS_DIR = "freshness"
# the verdicts of `open` that are refusals, as the codec counts them
REFUSALS = ("wrong_length", "stale_freshness", "bad_mac", "no_key")


@dataclass
class Security:
    """Signs (`seal`) and opens (`open`) frames for one node."""

    keyset: keys.KeySet
    node: str
    state: bool = True
    tx: secoc.FreshnessCounter = field(init=False)
    rx: secoc.FreshnessWindow = field(init=False)

    def __post_init__(self) -> None:
        folder = None
        if self.state:
            folder = Path(self.keyset.folder) / FRESHNESS_DIR
            folder.mkdir(mode=0o700, exist_ok=True)
        self.tx = secoc.FreshnessCounter(None if folder is None else folder / f"{self.node}.tx.json")
        self.rx = secoc.FreshnessWindow(None if folder is None else folder / f"{self.node}.rx.json")

    @property
    def test(self) -> bool:
        return self.keyset.test

    def seal(self, frame_id: int, payload: bytes) -> bytes:
        """The secured frame of an 8-byte payload on `frame_id`, under the ID owner's key
        (KeyFileError if this node does not hold it: a node signs only its own IDs)."""
        return secoc.protect(self.keyset.key_for(frame_id), frame_id, payload, self.tx.take(frame_id))

    def open(self, frame_id: int, data: bytes) -> tuple[str, Optional[bytes]]:
        """(`ok`, the 8-byte payload) of a frame that is new and verifies under its owner's
        key, else (the reason, None): wrong_length, stale_freshness, bad_mac, or no_key (this
        node holds no key for the ID: it cannot judge the frame, so it never takes it)."""
        try:
            key = self.keyset.key_for(frame_id)
        except keys.KeyFileError:
            return "no_key", None
        verdict = self.rx.accept(key, frame_id, data)
        return (verdict, bytes(data[:secoc.PAYLOAD_BYTES])) if verdict == "ok" else (verdict, None)

    def save(self) -> None:
        """Write the receive windows (at the end of a run; they are also written as they go)."""
        self.rx.save()

    def describe(self) -> str:
        """One line for summaries: the key set and whether it is a test set."""
        kind = "TEST keys (simulation and tests only)" if self.test else "keys"
        return f"secured (CMAC-AES-128, {secoc.MAC_BYTES * 8}-bit MAC, CAN FD {secoc.FRAME_LENGTH} bytes; {kind} {self.keyset.folder})"


UNSECURED = "UNSECURED (E2E only: any node on the bus can forge or replay frames)"


def describe(security: Optional[Security]) -> str:
    return UNSECURED if security is None else security.describe()


def for_node(folder: str | Path, node: str, senders: Iterable[str], state: bool = True) -> Security:
    """The Security of `node`, holding the keys of `senders` from the key set in `folder`."""
    return Security(keys.load(folder, senders), node, state)


def made_test_keys(folder: str | Path) -> Path:
    """A test key set in `folder`, made on first use (the simulated bus's default)."""
    folder = Path(folder)
    if not (folder / keys.MANIFEST).exists():
        keys.new_set(folder, test=True)
    return folder
