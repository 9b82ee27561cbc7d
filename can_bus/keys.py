"""Authentication keys, one per sender (issue 39 item 1): a sensor's key cannot sign another
channel's frames, nor the monitor's.

A key set is a folder: one file per sender (`ch0.key` .. `ch5.key` for the six obstacle
channels, `train.key` for TrainState, `monitor.key` for the monitor's outputs), each 16
random bytes as 32 hex digits, readable by its owner only (0600, the folder 0700), and a
manifest `keyset.toml` naming the senders with each key's fingerprint (the first 8 bytes of
its SHA-256, never the key) and whether the set is a test set. A node loads the keys it
needs; every load checks the permissions and the fingerprints, and refuses in one line.
Test sets say so in their manifest and in every summary that uses them; they are never a
default for a real bus.
"""
from __future__ import annotations

import hashlib
import os
import secrets
import stat
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Iterable, Optional

from .codec import BRAKE_DEMAND_ID, MONITOR_RISK_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, OBSTACLE_IDS, TRAIN_STATE_ID

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

KEY_BYTES = 16                 # AES-128
MANIFEST = "keyset.toml"
FORMAT = 1
SENDERS = tuple(f"ch{i}" for i in range(len(OBSTACLE_IDS))) + ("train", "monitor")
OWNER = {**{fid: f"ch{i}" for i, fid in enumerate(OBSTACLE_IDS)}, TRAIN_STATE_ID: "train",
         **{fid: "monitor" for fid in (BRAKE_DEMAND_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, MONITOR_RISK_ID)}}


class KeyFileError(ValueError):
    """A key set that cannot be made or used; the message names the file and says why."""


def fingerprint(key: bytes) -> str:
    return hashlib.sha256(key).hexdigest()[:16]


@dataclass(frozen=True)
class KeySet:
    folder: Path
    keys: dict               # sender -> key bytes (only the senders loaded)
    test: bool
    manifest: dict           # keyset.toml as read (format, test, created, senders -> fingerprints)

    def key_for(self, frame_id: int) -> bytes:
        """The key of the ID's owner (KeyFileError if the set does not hold it)."""
        owner = OWNER.get(frame_id)
        if owner is None:
            raise KeyFileError(f"frame ID 0x{frame_id:03X} has no owner in the key set")
        if owner not in self.keys:
            raise KeyFileError(f"{self.folder}: the key of {owner} (ID 0x{frame_id:03X}) was not loaded")
        return self.keys[owner]


def new_set(folder: str | Path, *, test: bool = False) -> KeySet:
    """Make a key set in `folder` (created 0700; refused if it already holds files)."""
    folder = Path(folder)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise KeyFileError(f"{folder}: exists and is not an empty folder; keys are never overwritten")
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    keys = {s: secrets.token_bytes(KEY_BYTES) for s in SENDERS}
    for sender, key in keys.items():
        path = folder / f"{sender}.key"
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="ascii") as fh:
            fh.write(key.hex() + "\n")
    info = {"format": FORMAT, "test": test, "created": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "senders": {s: fingerprint(k) for s, k in keys.items()}}
    lines = [f"format = {FORMAT}", f"test = {'true' if test else 'false'}", f'created = "{info["created"]}"',
             "# fingerprint = the first 8 bytes of the key's SHA-256 (the key itself is in <sender>.key)",
             "[senders]"] + [f'{s} = "{f}"' for s, f in info["senders"].items()]
    fd = os.open(folder / MANIFEST, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as fh:
        fh.write("\n".join(lines) + "\n")
    return KeySet(folder, keys, test, info)


def manifest(folder: str | Path) -> dict:
    """The manifest of a key set (format, test, created, senders and fingerprints)."""
    path = Path(folder) / MANIFEST
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise KeyFileError(f"{path}: no key set here (railguard keys new {folder} makes one)") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise KeyFileError(f"{path}: not a key set manifest ({exc})") from None
    if data.get("format") != FORMAT or not isinstance(data.get("senders"), dict) or not isinstance(data.get("test"), bool):
        raise KeyFileError(f"{path}: not a format-{FORMAT} key set manifest (format, test and [senders] expected)")
    unknown = sorted(set(data["senders"]) - set(SENDERS))
    if unknown:
        raise KeyFileError(f"{path}: unknown senders {', '.join(unknown)} (known: {', '.join(SENDERS)})")
    return data


def load(folder: str | Path, senders: Optional[Iterable[str]] = None) -> KeySet:
    """The keys of `senders` (default: all) from a key set, each checked: owner-only
    permissions, 16 bytes, the manifest's fingerprint."""
    folder = Path(folder)
    info = manifest(folder)
    wanted = tuple(SENDERS if senders is None else senders)
    keys = {}
    for sender in wanted:
        if sender not in info["senders"]:
            raise KeyFileError(f"{folder / MANIFEST}: no key for {sender}")
        path = folder / f"{sender}.key"
        try:
            mode = path.stat().st_mode
            text = path.read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError) as exc:
            raise KeyFileError(f"{path}: cannot be read ({exc.__class__.__name__})") from None
        if mode & (stat.S_IRWXG | stat.S_IRWXO):
            raise KeyFileError(f"{path}: readable by others (mode {stat.S_IMODE(mode):o}); chmod 600 {path}")
        try:
            key = bytes.fromhex(text)
        except ValueError:
            key = b""
        if len(key) != KEY_BYTES:
            raise KeyFileError(f"{path}: not {KEY_BYTES} bytes as {2 * KEY_BYTES} hex digits")
        if fingerprint(key) != info["senders"][sender]:
            raise KeyFileError(f"{path}: its fingerprint is not the manifest's (a key from another set?)")
        keys[sender] = key
    return KeySet(folder, keys, info["test"], info)
