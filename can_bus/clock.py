"""Where time comes from for the shells: the wall clock on a real bus, a simulated clock
when the monitor and the player share an in-process bus and should run as fast as the
CPU allows. The core never sees either: it gets integer ticks."""
from __future__ import annotations

import math
import time


class WallClock:
    """Milliseconds since construction, from the monotonic clock; sleeping really sleeps."""

    simulated = False

    def __init__(self) -> None:
        self._t0 = time.monotonic_ns()
        self._wall0 = time.time()

    def tick_of_stamp(self, stamp) -> int | None:
        """The tick of a frame's receive timestamp (python-can: seconds of the epoch, from the
        kernel on SocketCAN), rounded down: a frame that waited in a queue is that much older."""
        if not stamp:
            return None
        return math.floor((stamp - self._wall0) * 1000)

    def now_ms(self) -> int:
        return (time.monotonic_ns() - self._t0) // 1_000_000

    def now_s(self) -> float:
        return (time.monotonic_ns() - self._t0) / 1e9

    def sleep_until_ms(self, tick: int) -> None:
        delay = tick / 1000 - self.now_s()
        if delay > 0:
            time.sleep(delay)


class SimClock:
    """A clock that only moves when told to: runs are deterministic and take no wall time."""

    simulated = True

    def __init__(self) -> None:
        self._ms = 0

    def now_ms(self) -> int:
        return self._ms

    def tick_of_stamp(self, stamp) -> None:
        """Bus timestamps are wall time, not simulated time: the arrival tick alone counts."""
        return None

    def now_s(self) -> float:
        return self._ms / 1000

    def sleep_until_ms(self, tick: int) -> None:
        if tick > self._ms:
            self._ms = tick
