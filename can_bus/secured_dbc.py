"""The DBC of the secured bus (issue 39 item 1): every message of can_bus/railguard.dbc as the
20-byte CAN FD frame of the secured profile (secoc.py), so that a bus tool reading
`railguard_secured.dbc` decodes a secured frame's signals, its freshness value's low bits and
its authenticator. Made from railguard.dbc, never edited by hand:

    python -m can_bus.secured_dbc            # rewrite can_bus/railguard_secured.dbc
    python -m can_bus.secured_dbc --check    # exit 1 if the shipped file is not what it makes
"""
from __future__ import annotations

import argparse
import copy
import sys
from functools import lru_cache
from importlib import resources
from pathlib import Path

import cantools
from cantools.database.can import Bus, Database, Message, Signal
from cantools.database.can.formats.dbc.dbc_attribute import DbcAttribute as Attribute
from cantools.database.can.formats.dbc.dbc_attribute_definition import DbcAttributeDefinition as AttributeDefinition

from . import secoc
from .codec import database

SECURED_DBC_NAME = "railguard_secured.dbc"
ARBITRATION_BAUD, DATA_BAUD = 500_000, 2_000_000     # CAN FD: 500 kbit/s arbitration, 2 Mbit/s data phase


def _secured(msg: Message) -> Message:
    signals = [copy.deepcopy(s) for s in msg.signals]
    signals.append(Signal("FreshnessLow", 8 * secoc.PAYLOAD_BYTES, 8 * secoc.FV_WIRE_BYTES, byte_order="little_endian",
                          comment="The low 32 bits of the sender's 64-bit freshness value for this ID (it never goes "
                                  "back, across restarts too); the receiver rebuilds the full value."))
    signals.append(Signal("Mac", 8 * (secoc.PAYLOAD_BYTES + secoc.FV_WIRE_BYTES), 8 * secoc.MAC_BYTES,
                          byte_order="little_endian",
                          comment="CMAC-AES-128 under the ID owner's key over the frame ID (2 bytes, big-endian), "
                                  "bytes 0..7 and the full freshness value (8 bytes, big-endian), its first 64 bits "
                                  "(as bytes 12..19; read as a little-endian number here)."))
    comment = (msg.comment or "") + (" Secured: a CAN FD frame of 20 bytes, bytes 0..7 the classic frame (E2E), "
                                     "8..11 FreshnessLow, 12..19 Mac (docs/can.md, Authenticated frames).")
    return Message(msg.frame_id, msg.name, secoc.FRAME_LENGTH, signals, comment=comment, senders=msg.senders,
                   is_fd=True, cycle_time=msg.cycle_time)


def make_text() -> str:
    """The secured DBC's text, from the classic one."""
    base = database()
    bus = Bus("railguard", baudrate=ARBITRATION_BAUD, fd_baudrate=DATA_BAUD)
    dbc = copy.deepcopy(base.dbc)
    bus_type = AttributeDefinition("BusType", kind=None, type_name="STRING", default_value="")
    dbc.attribute_definitions["BusType"] = bus_type          # (cantools writes VFrameFormat on a "CAN FD" bus)
    dbc.attributes["BusType"] = Attribute("CAN FD", bus_type)
    db = Database(messages=[_secured(m) for m in base.messages], nodes=base.nodes, buses=[bus],
                  version="railguard secured 1", dbc_specifics=dbc)
    return db.as_dbc_string().replace("\r\n", "\n")


@lru_cache(maxsize=1)
def secured_database() -> cantools.database.can.Database:
    """The shipped secured DBC (parsed once)."""
    text = resources.files("can_bus").joinpath(SECURED_DBC_NAME).read_text(encoding="utf-8")
    return cantools.database.load_string(text, database_format="dbc")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m can_bus.secured_dbc", description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the shipped file differs from what this makes")
    args = ap.parse_args(argv)
    path = Path(__file__).with_name(SECURED_DBC_NAME)
    text = make_text()
    if args.check:
        same = path.exists() and path.read_text(encoding="utf-8") == text
        print(f"{path}: {'up to date' if same else 'differs from railguard.dbc made secured: run python -m can_bus.secured_dbc'}")
        return 0 if same else 1
    path.write_text(text, encoding="utf-8")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
