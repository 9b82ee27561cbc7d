"""The fuzzing's figures: `Stats` counts frames, outcomes, faults and cycles of one or more
streams and adds up the workers' results (`merge`); the first few faults are kept with the
frame that caused them (`describe`), so that a failure can be put on a bus again.
"""
from __future__ import annotations

from collections import Counter

import can


MAX_EXAMPLES_KEPT = 8        # violation/exception records kept in the result


class Stats:
    """Figures of one or more streams; `merge` adds another's `as_dict()`."""

    def __init__(self) -> None:
        self.frames = 0
        self.accepted = 0                 # the receiver's own count
        self.rejected: Counter = Counter()  # the receiver's own counts by reason
        self.filtered = 0                   # the runner's count of frames outside the receive filter
        self.frame_kinds: Counter = Counter()  # the runner's tally of frames by kind
        self.bus_states: Counter = Counter()   # bus states announced by error frames (the runner's tally)
        self.foreign_ids: Counter = Counter()  # foreign_output frames by ID
        self.foreign_cycles = 0                # cycles with the ForeignOutput diagnostic set
        self.expected: Counter = Counter()  # the reference receiver's outcomes
        self.kinds: Counter = Counter()     # frames by generator kind
        self.accepted_ids: Counter = Counter()
        self.exceptions = 0
        self.harness_errors = 0
        self.violations: Counter = Counter()
        self.accounting_errors = 0
        self.examples: list = []
        self.streams = 0
        self.stream_kinds: Counter = Counter()   # streams by "table/topology/profile"
        self.cycles = 0
        self.modes: Counter = Counter()
        self.demands: Counter = Counter()
        self.seconds = 0.0

    def faults(self) -> int:
        return self.exceptions + self.harness_errors + sum(self.violations.values())

    def record(self, kind: str, detail: dict) -> None:
        if len(self.examples) < MAX_EXAMPLES_KEPT:
            self.examples.append(dict(kind=kind, **detail))

    def as_dict(self) -> dict:
        return {
            "frames": self.frames, "accepted": self.accepted, "rejected": dict(self.rejected),
            "filtered": self.filtered, "frame_kinds": dict(self.frame_kinds), "bus_states": dict(self.bus_states),
            "foreign_ids": {f"0x{k:02X}": v for k, v in sorted(self.foreign_ids.items())},
            "foreign_cycles": self.foreign_cycles,
            "expected": dict(self.expected), "kinds": dict(self.kinds),
            "accepted_ids": {f"0x{k:02X}": v for k, v in sorted(self.accepted_ids.items())},
            "exceptions": self.exceptions, "harness_errors": self.harness_errors,
            "violations": sum(self.violations.values()), "violations_by_kind": dict(self.violations),
            "accounting_errors": self.accounting_errors, "examples": list(self.examples),
            "streams": self.streams, "stream_kinds": dict(self.stream_kinds), "cycles": self.cycles,
            "modes": dict(self.modes),
            "demands": dict(self.demands), "seconds": self.seconds,
        }

    def merge(self, d: dict) -> None:
        self.frames += d["frames"]
        self.accepted += d["accepted"]
        self.rejected.update(d["rejected"])
        self.filtered += d["filtered"]
        self.frame_kinds.update(d["frame_kinds"])
        self.bus_states.update(d["bus_states"])
        self.foreign_ids.update({int(k, 16): v for k, v in d["foreign_ids"].items()})
        self.foreign_cycles += d["foreign_cycles"]
        self.expected.update(d["expected"])
        self.kinds.update(d["kinds"])
        self.accepted_ids.update({int(k, 16): v for k, v in d["accepted_ids"].items()})
        self.exceptions += d["exceptions"]
        self.harness_errors += d["harness_errors"]
        self.violations.update(d["violations_by_kind"])
        self.accounting_errors += d["accounting_errors"]
        for e in d["examples"]:
            if len(self.examples) < MAX_EXAMPLES_KEPT:
                self.examples.append(e)
        self.streams += d["streams"]
        self.stream_kinds.update(d["stream_kinds"])
        self.cycles += d["cycles"]
        self.modes.update(d["modes"])
        self.demands.update(d["demands"])


def describe(msg: can.Message) -> dict:
    """A frame as the report shows it: enough to put it on a bus again."""
    return {"id": f"0x{msg.arbitration_id:X}", "extended": bool(msg.is_extended_id),
            "remote": bool(msg.is_remote_frame), "error": bool(msg.is_error_frame), "fd": bool(msg.is_fd),
            "dlc": msg.dlc, "data": bytes(msg.data).hex()}
