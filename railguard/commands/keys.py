"""`railguard keys`: make and inspect the key sets of authenticated frames (issue 39)."""
from __future__ import annotations

import argparse

from .. import output


def _summary(folder, info: dict) -> dict:
    return {"folder": str(folder), "test": info["test"], "created": info.get("created"),
            "senders": dict(info["senders"]),
            "note": "TEST KEYS: for simulation and tests only, never a real bus" if info["test"] else
                    "keep every <sender>.key on its node only (0600); the monitor holds the keys it verifies"}


def new(args: argparse.Namespace) -> int:
    from can_bus import keys

    ks = keys.new_set(args.folder, test=args.test)
    output.summary(_summary(ks.folder, ks.manifest), args.json)
    return 0


def show(args: argparse.Namespace) -> int:
    from can_bus import keys

    ks = keys.load(args.folder)                  # every key checked: permissions, length, fingerprint
    output.summary(_summary(ks.folder, ks.manifest), args.json)
    return 0


def register(sub) -> None:
    k = sub.add_parser(
        "keys",
        help="make or check a key set for authenticated CAN frames (one key per sender)",
        description="A key set is a folder with one AES-128 key per sender (ch0..ch5: the six obstacle channels, "
                    "train: TrainState, monitor: the monitor's outputs), each readable by its owner only, and a "
                    "manifest (keyset.toml) with their fingerprints. A sensor's key cannot sign another channel's "
                    "frames nor the monitor's. `new` makes one (never overwrites), `show` checks one and lists its "
                    "senders. Test sets are marked as such (--test). docs/can.md, \"Authenticated frames\".",
    )
    ks = k.add_subparsers(dest="keys_command", metavar="{new,show}", required=True)
    n = ks.add_parser("new", help="make a key set in a new (or empty) folder",
                      description="Make a key set in FOLDER (created with mode 0700; an existing non-empty folder is "
                                  "refused): one random 16-byte key per sender in <sender>.key (0600) and keyset.toml.")
    n.add_argument("folder", metavar="FOLDER")
    n.add_argument("--test", action="store_true", help="mark the set as test keys (simulation and tests only)")
    n.add_argument("--json", action="store_true", help="print the summary as JSON")
    n.set_defaults(func=new)
    s = ks.add_parser("show", help="check a key set and list its senders and fingerprints",
                      description="Load every key of the set in FOLDER, checking permissions (owner only), length and "
                                  "the manifest's fingerprints; print the senders and fingerprints (never a key).")
    s.add_argument("folder", metavar="FOLDER")
    s.add_argument("--json", action="store_true", help="print the summary as JSON")
    s.set_defaults(func=show)
