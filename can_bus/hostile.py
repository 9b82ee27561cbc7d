"""A hostile node on the bus (issue 39): a second sender that knows the DBC and the public
E2E profile, sniffs the bus and forges frames in step with the genuine senders.

`forge_absent`: before channel ch's genuine ObstacleReport, the same ID with "absent", a
valid CRC and the counter the genuine frame is about to carry, so a receiver that keeps
whichever valid frame comes first believes the forger. `forge_brake_none`: BrakeDemand
"none" with the monitor's next counter and cycle, before the monitor's own frame. The node
has its own bus connection (another node on the wire), so everyone else receives it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import can

from monitor.core.types import ABSENT, Report

from .codec import BRAKE_DEMAND_ID, OBSTACLE_IDS, encode, report_signals

HOSTILE_KINDS = ("forge_absent", "forge_brake_none")


@dataclass
class Hostile:
    bus: can.BusABC
    sent: dict = field(default_factory=dict)      # forged frames by kind
    brake_counter: int = -1                       # the newest BrakeDemand counter seen on the bus
    brake_cycle: int = 0                          # and its Cycle signal

    def sniff(self, msg: can.Message) -> None:
        """Learn the monitor's BrakeDemand counter and cycle from a frame seen on the bus."""
        if msg.arbitration_id == BRAKE_DEMAND_ID and len(msg.data) == 8:
            self.brake_counter = msg.data[1] & 0xF
            self.brake_cycle = int.from_bytes(bytes(msg.data[4:8]), "little")

    def _send(self, kind: str, frame_id: int, data: bytes) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False))
            self.sent[kind] = self.sent.get(kind, 0) + 1
        except can.CanError:
            pass

    def forge_absent(self, ch: int, genuine_next_counter: int) -> None:
        self._send("forge_absent", OBSTACLE_IDS[ch],
                   encode(OBSTACLE_IDS[ch], report_signals(Report(ABSENT, 0, 0, 0, 0), ch), genuine_next_counter))

    def forge_brake_none(self) -> None:
        if self.brake_counter < 0:
            return
        self._send("forge_brake_none", BRAKE_DEMAND_ID,
                   encode(BRAKE_DEMAND_ID, {"Level": 0, "Warning": 0, "Reason": 0,
                                            "Cycle": (self.brake_cycle + 1) & 0xFFFFFFFF}, self.brake_counter + 1))
