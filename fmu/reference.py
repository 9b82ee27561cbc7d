"""The monitor FMU's behaviour in Python: FMI-level inputs read into the core's integer
units exactly as fmu/c/monitor/model.c reads them, then the Python core.

The C side must agree with this bit for bit (tests/test_fmu_equivalence.py); it is also
how a co-simulation run can be re-checked without the FMU.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import Inputs, Report, Train

CHANNELS = 6


def read_distance_dm(x: float) -> int:
    """Metres to dm, rounded down (the obstacle is nearer); -1 (refused) if NaN or out of range."""
    if not (0.0 <= x <= 6000.0):
        return -1
    return math.floor(x * 10.0)


def read_closing_cms(x: float) -> int:
    """m/s to cm/s, rounded up (closing faster); 99999 (refused) if NaN or out of range."""
    if not (-150.0 <= x <= 150.0):
        return 99999
    return math.ceil(x * 100.0)


def read_speed_cms(x: float) -> int:
    """Train speed m/s to cm/s, rounded up; -1 (a train-input error) if NaN or out of range."""
    if not (0.0 <= x <= 120.0):
        return -1
    return math.ceil(x * 100.0)


class ChannelInput(NamedTuple):
    status: int = 0
    distance: float = 0.0
    closing_speed: float = 0.0
    type: int = 0
    valid: bool = False


class StepInput(NamedTuple):
    """The FMU's inputs during one communication step."""

    channels: tuple          # CHANNELS ChannelInput
    speed: float = 0.0
    track: int = 0
    brake: int = 0


def config_from_parameters(params: dict, base: Config | None = None) -> Config:
    """A core Config from the FMU's parameter names (topology 3 -> "3oo3", 2 -> "2oo2"); the
    parameters not set keep `base`'s values (the FMU's start values; default Config())."""
    values = dict(params)
    if "topology" in values:
        topo = values.pop("topology")
        values["topology"] = {3: "3oo3", 2: "2oo2"}.get(topo, str(topo))
    return (base or Config())._replace(**values)


class MonitorReference:
    """Steps like the FMU: each cycle latches the channels whose `valid` is set with the
    cycle's tick, then runs the core. `on_cycle(tick, inputs, state_before, state_after,
    outputs)`, if given, sees every cycle (tests measure what a sequence exercised)."""

    def __init__(self, table_bytes: bytes, params: dict | None = None, base: Config | None = None,
                 on_cycle=None):
        self.setup = cycle.create(config_from_parameters(params or {}, base), table_bytes)
        self.state = cycle.initial_state(self.setup)
        self.reports = [None] * CHANNELS
        self.cycles = 0
        self.on_cycle = on_cycle

    def step(self, inp: StepInput, cycles: int = 1) -> list:
        outs = []
        period = self.setup.config.period_ms
        for _ in range(cycles):
            tick = self.cycles * period
            for i, ch in enumerate(inp.channels):
                if ch.valid:
                    self.reports[i] = Report(ch.status, read_distance_dm(ch.distance), read_closing_cms(ch.closing_speed),
                                             ch.type, tick)
            train = Train(read_speed_cms(inp.speed), inp.track, inp.brake)
            inputs, before = Inputs(tuple(self.reports), train), self.state
            self.state, out = cycle.step(self.setup, before, inputs, tick)
            if self.on_cycle is not None:
                self.on_cycle(tick, inputs, before, self.state, out)
            self.cycles += 1
            outs.append(out)
        return outs
