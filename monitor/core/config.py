"""Monitor configuration, checked once at start-up: a bad value is refused with a message
that names it and says why, before the first cycle runs."""
from __future__ import annotations

from typing import NamedTuple

from .types import EMERGENCY, SERVICE

TOPOLOGIES = {"3oo3": 3, "2oo2": 1}   # name -> number of 2oo2 modules


class ConfigurationError(ValueError):
    """A configuration or table the monitor must not start with."""


class Config(NamedTuple):
    period_ms: int = 100               # cycle period
    timeout_cycles: int = 3            # a report older than this many cycles is stale
    persistence_cycles: int = 3        # a 2oo2 disagreement this long is a perceptor error
    service_decel_mms2: int = 1000     # nominal braking, for alpha1(v)
    emergency_decel_mms2: int = 3000   # emergency braking, for alpha2(v) and the envelope
    reaction_ms: int = 500             # reaction and brake build-up time in the braking distance
    warning_margin_dm: int = 2000      # warning zone length beyond alpha1
    fast_closing_cms: int = 2000       # Model 2: closing speed from which an obstacle is "fast"
    safe_reaction: int = EMERGENCY     # demand on a system error
    topology: str = "3oo3"
    recovery_cycles: int = 10          # error-free cycles before DEGRADED/SAFE_STOP clear
    max_overruns: int = 3              # consecutive deadline overruns leading to SAFE_STOP
    distance_tolerance_dm: int = 100   # 2oo2: two PRESENT distances further apart than this raise the flag

    @property
    def modules(self) -> int:
        return TOPOLOGIES[self.topology]

    @property
    def channels(self) -> int:
        return 2 * self.modules


def check(cfg: Config) -> None:
    """Raise ConfigurationError naming the first value that cannot be used."""
    def need(ok: bool, name: str, why: str) -> None:
        if not ok:
            raise ConfigurationError(f"{name} = {getattr(cfg, name)!r}: {why}")

    for name in cfg._fields:
        value = getattr(cfg, name)
        if name != "topology" and (isinstance(value, bool) or not isinstance(value, int)):
            raise ConfigurationError(f"{name} = {value!r}: must be a whole number")
    need(cfg.topology in TOPOLOGIES, "topology", f"unknown topology; known: {', '.join(TOPOLOGIES)}")
    need(1 <= cfg.period_ms <= 10000, "period_ms", "must be 1..10000 ms")
    need(cfg.timeout_cycles >= 1, "timeout_cycles", "must be at least 1 cycle (0 would make every report stale)")
    need(cfg.persistence_cycles >= 1, "persistence_cycles", "must be at least 1 cycle")
    need(cfg.persistence_cycles <= cfg.timeout_cycles, "persistence_cycles",
         f"must not exceed timeout_cycles ({cfg.timeout_cycles}): a disagreement would outlive the reports it is about")
    need(cfg.service_decel_mms2 > 0, "service_decel_mms2", "a deceleration must be positive (mm/s^2, magnitude)")
    need(cfg.emergency_decel_mms2 > 0, "emergency_decel_mms2", "a deceleration must be positive (mm/s^2, magnitude)")
    need(cfg.emergency_decel_mms2 >= cfg.service_decel_mms2, "emergency_decel_mms2",
         f"must be at least service_decel_mms2 ({cfg.service_decel_mms2})")
    need(cfg.emergency_decel_mms2 <= 20000, "emergency_decel_mms2", "more than 20 m/s^2 is not a train")
    need(0 <= cfg.reaction_ms <= 60000, "reaction_ms", "must be 0..60000 ms")
    need(0 <= cfg.warning_margin_dm <= 60000, "warning_margin_dm", "must be 0..60000 dm")
    need(1 <= cfg.fast_closing_cms <= 15000, "fast_closing_cms", "must be 1..15000 cm/s")
    need(cfg.safe_reaction in (SERVICE, EMERGENCY), "safe_reaction", "must be 1 (service) or 2 (emergency)")
    need(cfg.recovery_cycles >= 1, "recovery_cycles", "must be at least 1 cycle")
    need(cfg.max_overruns >= 1, "max_overruns", "must be at least 1")
    need(0 <= cfg.distance_tolerance_dm <= 60000, "distance_tolerance_dm", "must be 0..60000 dm")


def from_mapping(values: dict) -> Config:
    """A Config from a mapping (e.g. a TOML table); unknown keys are refused."""
    unknown = sorted(set(values) - set(Config._fields))
    if unknown:
        raise ConfigurationError(f"unknown configuration key(s) {', '.join(unknown)}; known: {', '.join(Config._fields)}")
    cfg = Config(**values)
    check(cfg)
    return cfg
