"""The brake controller's side of BrakeDemand (issue 39 item 3): the reference receiver.

What the brakes do with the monitor's frames, so that nobody but the monitor lowers a brake
and silence brakes. A valid frame (E2E CRC and alive counter, the codec's `Receiver`) gives
its level. Emergency, whatever the last valid frame said:

- `power_up`: no valid frame yet since the receiver started;
- `timeout`: the newest valid frame is TIMEOUT_PERIODS periods old (a monitor that crashed,
  hangs or went bus-off): the supervision's timing contract counts these periods
  (braking.SUPERVISED_PERIODS = 1 for the last frame's way + TIMEOUT_PERIODS);
- `second_sender`: BrakeDemand has a second sender (a frame repeating the counter with other
  content: a forger in step with the monitor, or one replaying its old frames; codec.py);
- `invalid_level`: the newest BrakeDemand with a correct CRC carried a level the DBC does
  not know (3).

An emergency the receiver raised for a failure (all but `power_up`) is held until the train
stands (speed 0) and a valid, uncontested frame has come since: the brakes are never
released under way on the word of a bus that just failed. `power_up` ends with the first
valid frame (a brake controller powers up with the train standing; a log or a
co-simulation that starts under way finds it already running: the train FMU's hand-over).
`causes` counts the periods each cause held the brakes.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Optional

from monitor.core.types import EMERGENCY

from .codec import BRAKE_DEMAND_ID, Receiver

TIMEOUT_PERIODS = 3          # the newest valid BrakeDemand counts for less than this many periods (300 ms at 100 ms)
CAUSES = ("power_up", "timeout", "second_sender", "invalid_level")


@dataclass
class BrakeReceiver:
    """Reads the level the brakes apply from a codec `Receiver` that drains the bus."""

    period_ms: int = 100
    latched: Optional[str] = None         # the cause of an emergency held to standstill, None if none
    causes: Counter = field(default_factory=Counter)
    heard: bool = False                   # a valid BrakeDemand has come since power-up
    silent_ms: Optional[int] = None       # at the first timeout: time since the last valid frame

    def fault(self, rx: Receiver, tick: int) -> Optional[str]:
        """What makes the bus's word void at `tick`, None if a valid fresh frame stands."""
        d = rx.demand
        if rx.contested(BRAKE_DEMAND_ID, tick):
            return "second_sender"
        if d is None:
            return "timeout" if self.heard else "power_up"
        self.heard = True
        if rx.demand_invalid is not None and rx.demand_invalid >= d["tick"]:
            return "invalid_level"
        if tick - d["tick"] >= TIMEOUT_PERIODS * self.period_ms:
            if self.silent_ms is None:
                self.silent_ms = tick - d["tick"]
            return "timeout"
        return None

    def level(self, rx: Receiver, tick: int, speed_mps: float) -> int:
        """The level the brakes apply now (0 none, 1 service, 2 emergency)."""
        cause = self.fault(rx, tick)
        if cause == "power_up":                  # not held: the first valid frame ends it
            self.causes[cause] += 1
            return EMERGENCY
        if cause is not None:
            self.latched = cause
        elif self.latched is not None and speed_mps == 0.0:
            self.latched = None
        if self.latched is not None:
            self.causes[self.latched] += 1
            return EMERGENCY
        return int(rx.demand["Level"])

    def summary(self) -> dict:
        """Periods the receiver held the brakes, by cause (only the causes that occurred)."""
        return {c: self.causes[c] for c in CAUSES if self.causes[c]}
