"""What kind of frame arrived, decided in one place for the live runner and the replay.

The live monitor and `railguard replay` must reach the same decisions on the same traffic,
so both hand every frame to `classify` and count it with a `FrameTally`:

- `classical`: an 11-bit data frame; the only kind the receive path decodes.
- `extended`: a 29-bit data frame. The DBC has none: never a report.
- `fd`: a CAN FD frame. The DBC's messages are classical: an FD frame on a monitored ID is
  refused (`fd_frame`), live (the socket is opened with FD frames enabled, so it sees them)
  and in replay alike.
- `remote`: a remote request; refused (`remote_frame`), it carries no data.
- `error`: an error frame from the controller (SocketCAN's CAN_ERR_FLAG); refused
  (`error_frame`) and read for the bus state: error-passive, bus-off, restarted.

`monitored(frame)` is the kernel receive filter written as a function: the runner installs
the same set as CAN_RAW_FILTER on SocketCAN (frames outside it never reach the process)
and applies the function itself on every other interface; replay applies it to the log,
counting what a live monitor would never have seen as `filtered`, not as a reject.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Optional

from .codec import OBSTACLE_IDS, OUTPUT_IDS, TRAIN_STATE_ID

KINDS = ("classical", "extended", "fd", "remote", "error")
# the monitor's own output IDs are monitored too: a frame there is another sender's (foreign_output)
MONITORED_IDS = tuple(sorted((*OBSTACLE_IDS, TRAIN_STATE_ID, *OUTPUT_IDS)))
_MONITORED = frozenset(MONITORED_IDS)

# linux/can/error.h: error class bits in the identifier, controller details in data[1]
CAN_ERR_FLAG = 0x20000000
ERR_CRTL = 0x004
ERR_BUSOFF = 0x040
ERR_RESTARTED = 0x100
CRTL_RX_WARNING, CRTL_TX_WARNING = 0x04, 0x08
CRTL_RX_PASSIVE, CRTL_TX_PASSIVE = 0x10, 0x20
CRTL_ACTIVE = 0x40
BUS_STATES = ("error_active", "error_warning", "error_passive", "bus_off")


def classify(msg) -> str:
    """The frame's kind (one of KINDS) from python-can's flags; error first, as the kernel does."""
    if msg.is_error_frame:
        return "error"
    if msg.is_remote_frame:
        return "remote"
    if msg.is_fd:
        return "fd"
    if msg.is_extended_id:
        return "extended"
    return "classical"


def monitored(msg) -> bool:
    """Would the monitor's receive filter deliver this frame? Error frames always (the
    error filter is separate); data and remote frames on the monitored 11-bit IDs."""
    if msg.is_error_frame:
        return True
    return not msg.is_extended_id and msg.arbitration_id in _MONITORED


def kernel_filters() -> list[dict]:
    """python-can filters equal to `monitored` (11-bit only: extended frames never match)."""
    return [{"can_id": fid, "can_mask": 0x7FF, "extended": False} for fid in MONITORED_IDS]


def bus_state_of(msg) -> Optional[str]:
    """The controller state an error frame announces, or None if it announces none."""
    cls = int(msg.arbitration_id) & 0x1FFFFFFF
    data = bytes(msg.data or b"")
    if cls & ERR_BUSOFF:
        return "bus_off"
    detail = data[1] if cls & ERR_CRTL and len(data) > 1 else 0
    if detail & (CRTL_RX_PASSIVE | CRTL_TX_PASSIVE):
        return "error_passive"
    if detail & (CRTL_RX_WARNING | CRTL_TX_WARNING):
        return "error_warning"
    if cls & ERR_RESTARTED or detail & CRTL_ACTIVE:
        return "error_active"
    return None


@dataclass
class FrameTally:
    """Frames by kind, frames outside the filter, and the controller's bus state.

    `bus_state` is the newest state an error frame announced; `bus_events` counts each
    announcement, so a bus-off that recovered is still visible in the summary."""

    kinds: Counter = field(default_factory=Counter)
    filtered: int = 0
    bus_state: str = "error_active"
    bus_events: Counter = field(default_factory=Counter)

    def count(self, msg) -> str:
        """Count one frame; return its kind."""
        kind = classify(msg)
        self.kinds[kind] += 1
        if kind == "error":
            state = bus_state_of(msg)
            if state is not None:
                self.bus_state = state
                self.bus_events[state] += 1
        return kind
