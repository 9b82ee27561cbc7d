"""A hostile node on the bus (issue 39): a second sender that knows the DBC and the public
E2E profile, sniffs the bus and forges frames in step with the genuine senders.

`forge_absent`: before channel ch's genuine ObstacleReport, the same ID with "absent", a
valid CRC and the counter the genuine frame is about to carry, so a receiver that keeps
whichever valid frame comes first believes the forger. `forge_brake_none`: BrakeDemand
"none" with the monitor's next counter and cycle, before the monitor's own frame.
`replay_absent` / `replay_brake_none`: no forging at all. The node records the frames it
sees on the bus ("absent" reports and "none" demands, one per alive counter value), then
sends them back byte for byte, each when its counter value is due, just before the genuine
frame. The node has its own bus connection (another node on the wire), so everyone else
receives it.

On a secured bus (`secured=True`) the node knows the profile but holds no owner's key: it
sends secured CAN FD frames with the freshness value after the newest it saw on the ID and an
authenticator under a key of its own (`key`), and its replays are the secured frames byte for
byte. `forge_absent_stolen_key` is `forge_absent` by a node that holds channel 0's sensor key
(a sensor node taken over): its frames on the other channels' IDs carry a real sensor's
authenticator, under the wrong key.
"""
from __future__ import annotations

import secrets
from dataclasses import dataclass, field

import can

from monitor.core.types import ABSENT, Report

from . import secoc
from .codec import BRAKE_DEMAND_ID, OBSTACLE_IDS, encode, report_signals
from .keys import KEY_BYTES

HOSTILE_KINDS = ("forge_absent", "forge_brake_none", "replay_absent", "replay_brake_none", "forge_absent_stolen_key")
STOLEN_KEY_OF = "ch0"          # forge_absent_stolen_key: the node holds channel 0's sensor key


@dataclass
class Hostile:
    bus: can.BusABC
    sent: dict = field(default_factory=dict)      # forged frames by kind
    brake_counter: int = -1                       # the newest BrakeDemand counter seen on the bus
    brake_cycle: int = 0                          # and its Cycle signal
    recorded: dict = field(default_factory=dict)  # (ID, counter) -> the first "absent" / "none" frame seen
    secured: bool = False                         # a secured bus: it forges secured frames (module doc)
    key: bytes = field(default_factory=lambda: secrets.token_bytes(KEY_BYTES))   # never an owner's
    freshness: dict = field(default_factory=dict)  # ID -> the low freshness bits of the newest frame seen

    def listen(self) -> None:
        """Read what the node's own connection received (every other node's frames)."""
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            if not (msg.is_error_frame or msg.is_remote_frame):
                self.sniff(msg)

    def sniff(self, msg: can.Message) -> None:
        """Learn the monitor's BrakeDemand counter and cycle from a frame seen on the bus, and
        record "absent" reports and "none" demands (status / level 0) for a replay."""
        fid, frame = msg.arbitration_id, bytes(msg.data)
        if len(frame) != (secoc.FRAME_LENGTH if self.secured else 8):
            return
        data = frame[:8]
        if self.secured:
            self.freshness[fid] = int.from_bytes(frame[8:8 + secoc.FV_WIRE_BYTES], "little")
        if fid == BRAKE_DEMAND_ID:
            self.brake_counter = data[1] & 0xF
            self.brake_cycle = int.from_bytes(data[4:8], "little")
        if (fid == BRAKE_DEMAND_ID or fid in OBSTACLE_IDS) and (data[1] >> 4) & 0x3 == 0:
            self.recorded.setdefault((fid, data[1] & 0xF), frame)

    def replay(self, kind: str, frame_id: int, counter: int) -> None:
        """Send the recorded frame of `frame_id` with alive counter `counter`, if there is one."""
        data = self.recorded.get((frame_id, counter & 0xF))
        if data is not None:
            self._send(kind, frame_id, data)

    def _forged(self, frame_id: int, payload: bytes) -> bytes:
        """What the node sends for a payload it made up: as is on an unsecured bus, else a
        secured frame with the next freshness value and its own key's authenticator."""
        if not self.secured:
            return payload
        return secoc.protect(self.key, frame_id, payload, self.freshness.get(frame_id, -1) + 1)

    def _send(self, kind: str, frame_id: int, data: bytes) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False, is_fd=len(data) > 8))
            self.sent[kind] = self.sent.get(kind, 0) + 1
        except can.CanError:
            pass

    def forge_absent(self, ch: int, genuine_next_counter: int, kind: str = "forge_absent") -> None:
        fid = OBSTACLE_IDS[ch]
        self._send(kind, fid,
                   self._forged(fid, encode(fid, report_signals(Report(ABSENT, 0, 0, 0, 0), ch), genuine_next_counter)))

    def forge_brake_none(self) -> None:
        if self.brake_counter < 0:
            return
        self._send("forge_brake_none", BRAKE_DEMAND_ID, self._forged(BRAKE_DEMAND_ID, encode(
            BRAKE_DEMAND_ID, {"Level": 0, "Warning": 0, "Reason": 0, "Cycle": (self.brake_cycle + 1) & 0xFFFFFFFF},
            self.brake_counter + 1)))
