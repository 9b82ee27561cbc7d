"""Monitor configuration, checked once at start-up: a bad value is refused with a message
that names it and says why, before the first cycle runs.

The train's braking declaration (docs/supervision.md) lives here in integer units: the
guaranteed decelerations (already reduced by the operator's confidence factor), build-up
and traction cut-off times, speed error, adhesion factors, gradient and standstill margin.
`monitor.declaration` reads it from a TOML file in SI units.
"""
from __future__ import annotations

from typing import NamedTuple

from .types import EMERGENCY, MAX_SPEED_CMS, SERVICE

TOPOLOGIES = {"3oo3": 3, "2oo2": 1}   # name -> number of 2oo2 modules
RELEASE_AT_STANDSTILL, RELEASE_REVOCABLE = 0, 1
MIN_GUARANTEED_DECEL_MMS2 = 100       # below this (worst case) the train cannot be said to stop


class ConfigurationError(ValueError):
    """A configuration or table the monitor must not start with."""


class Config(NamedTuple):
    period_ms: int = 100               # cycle period
    timeout_cycles: int = 3            # a report older than this many cycles is stale
    persistence_cycles: int = 10       # a 2oo2 disagreement this long is a perceptor error
    # --- the train's braking declaration (guaranteed values; docs/supervision.md)
    emergency_decel_mms2: int = 2400   # guaranteed emergency deceleration from 0 (speed band 1)
    emergency_band2_cms: int = 3000    # band 2 starts at this speed (0: no band 2)
    emergency_band2_mms2: int = 2200   # guaranteed emergency deceleration in band 2
    emergency_band3_cms: int = 0       # band 3 starts at this speed (0: no band 3)
    emergency_band3_mms2: int = 0      # guaranteed emergency deceleration in band 3
    service_decel_mms2: int = 800      # guaranteed service deceleration
    emergency_buildup_ms: int = 1000   # equivalent emergency brake build-up (dead time + half ramp)
    service_buildup_ms: int = 2000     # equivalent service brake build-up
    traction_cutoff_ms: int = 800      # traction may still accelerate the train this long
    max_accel_mms2: int = 500          # the train's largest acceleration under traction
    speed_error_permille: int = 20     # speed measurement error, fraction of the speed
    slippery_permille: int = 700       # deceleration factor while the train reports a slippery track
    degraded_permille: int = 800       # deceleration factor while the train reports degraded brakes
    max_gradient_permille: int = 20    # steepest downhill gradient of the line
    standstill_margin_dm: int = 50     # stop this far before the obstacle
    # --- supervision and response
    warning_ms: int = 2000             # the warning curve leads SBI by this time
    emergency_release: int = RELEASE_REVOCABLE  # 1: revocable when the cause is gone; 0: at standstill
    release_confirm_cycles: int = 5    # cycles without an emergency cause before a revocable release
    # --- Model 2 observation and voting
    warning_margin_dm: int = 10000     # table zones: warning zone length beyond alpha1
    fast_closing_cms: int = 2000       # Model 2: closing speed from which an obstacle is "fast"
    safe_reaction: int = EMERGENCY     # demand on a system error with a degraded channel
    topology: str = "3oo3"
    recovery_cycles: int = 10          # error-free cycles before DEGRADED/SAFE_STOP clear
    max_overruns: int = 3              # consecutive deadline overruns leading to SAFE_STOP
    distance_tolerance_dm: int = 100   # 2oo2: two PRESENT distances further apart than this raise the flag
    # --- obstacle memory (monitor/core/memory.py, docs/supervision.md section 5)
    forget_ms: int = 7500              # fresh unanimous ABSENT this long forgets a remembered obstacle (the trade-off: docs/supervision.md 5)
    sensor_range_dm: int = 4000        # the sensors' declared range: absence counts as evidence only inside it
    forget_single_ms: int = 1000       # the same for an obstacle only one module ever saw (issue 38: its ghosts)
    # --- the sensors' declared accuracy (guaranteed): counted by the supervised curves and the
    #     memory (the error budget, docs/supervision.md 2.6) and by plausibility (plausibility.py)
    distance_accuracy_dm: int = 500    # a reported distance is within this of the truth (5 sigma of the papers' 10 m noise)
    closing_accuracy_cms: int = 100    # a reported closing speed is within this of the truth
    plausibility_ms: int = 30000       # an implausible channel is believed again after this long of plausible reports

    @property
    def modules(self) -> int:
        return TOPOLOGIES[self.topology]

    @property
    def channels(self) -> int:
        return 2 * self.modules


DECLARATION_FIELDS = ("emergency_decel_mms2", "emergency_band2_cms", "emergency_band2_mms2", "emergency_band3_cms",
                      "emergency_band3_mms2", "service_decel_mms2", "emergency_buildup_ms", "service_buildup_ms",
                      "traction_cutoff_ms", "max_accel_mms2", "speed_error_permille", "slippery_permille",
                      "degraded_permille", "max_gradient_permille", "standstill_margin_dm", "distance_accuracy_dm",
                      "closing_accuracy_cms")


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
    need(cfg.timeout_cycles * cfg.period_ms <= 60000, "timeout_cycles",
         f"a report may be at most 60 s old (timeout_cycles x period_ms = {cfg.timeout_cycles * cfg.period_ms} ms)")
    need(1 <= cfg.persistence_cycles <= 1000, "persistence_cycles", "must be 1..1000 cycles")
    for name in ("emergency_decel_mms2", "service_decel_mms2"):
        need(1 <= getattr(cfg, name) <= 20000, name, "a deceleration must be 1..20000 mm/s^2 (magnitude)")
    need(0 <= cfg.emergency_band2_cms <= MAX_SPEED_CMS, "emergency_band2_cms", f"must be 0 (no band) or a speed up to {MAX_SPEED_CMS} cm/s")
    need(0 <= cfg.emergency_band3_cms <= MAX_SPEED_CMS, "emergency_band3_cms", f"must be 0 (no band) or a speed up to {MAX_SPEED_CMS} cm/s")
    need(cfg.emergency_band3_cms == 0 or cfg.emergency_band3_cms > cfg.emergency_band2_cms > 0, "emergency_band3_cms",
         f"band 3 needs band 2 and must start above it ({cfg.emergency_band2_cms} cm/s)")
    for band in (2, 3):
        if getattr(cfg, f"emergency_band{band}_cms"):
            name = f"emergency_band{band}_mms2"
            need(1 <= getattr(cfg, name) <= 20000, name, "a deceleration must be 1..20000 mm/s^2 (magnitude)")
    # the equivalent build-up covers a linear ramp only if the guaranteed deceleration never
    # rises with speed (issue 40 item 4: verification/physics/buildup.py refutes it otherwise)
    for band, below in ((2, cfg.emergency_decel_mms2), (3, cfg.emergency_band2_mms2)):
        if getattr(cfg, f"emergency_band{band}_cms"):
            name = f"emergency_band{band}_mms2"
            need(getattr(cfg, name) <= below, name, f"must not exceed the band below it ({below} mm/s^2): the "
                 "guaranteed deceleration may only fall with speed (the build-up proof, docs/proof.md)")
    need(cfg.service_decel_mms2 <= min(a for _, a in emergency_bands(cfg)), "service_decel_mms2",
         "must not exceed the guaranteed emergency deceleration of any speed band")
    for name in ("emergency_buildup_ms", "service_buildup_ms", "traction_cutoff_ms"):
        need(0 <= getattr(cfg, name) <= 30000, name, "must be 0..30000 ms")
    need(0 <= cfg.max_accel_mms2 <= 5000, "max_accel_mms2", "must be 0..5000 mm/s^2")
    need(0 <= cfg.speed_error_permille <= 500, "speed_error_permille", "must be 0..500 (per mille of the speed)")
    for name in ("slippery_permille", "degraded_permille"):
        need(1 <= getattr(cfg, name) <= 1000, name, "a deceleration factor must be 1..1000 per mille (adverse conditions never brake better)")
    need(0 <= cfg.max_gradient_permille <= 60, "max_gradient_permille", "must be 0..60 per mille (downhill)")
    need(0 <= cfg.standstill_margin_dm <= 10000, "standstill_margin_dm", "must be 0..10000 dm")
    worst = min(a for _, a in emergency_bands(cfg)) * cfg.slippery_permille * cfg.degraded_permille // 1000000
    need(worst - gradient_accel_mms2(cfg.max_gradient_permille) >= MIN_GUARANTEED_DECEL_MMS2, "max_gradient_permille",
         f"on this downhill with slippery track and degraded brakes the guaranteed deceleration is "
         f"{worst - gradient_accel_mms2(cfg.max_gradient_permille)} mm/s^2, below {MIN_GUARANTEED_DECEL_MMS2}: the train cannot be said to stop")
    worst_service = cfg.service_decel_mms2 * cfg.slippery_permille * cfg.degraded_permille // 1000000
    need(worst_service - gradient_accel_mms2(cfg.max_gradient_permille) >= MIN_GUARANTEED_DECEL_MMS2, "service_decel_mms2",
         "too weak to stop the train on the steepest downhill with slippery track and degraded brakes")
    need(0 <= cfg.warning_ms <= 60000, "warning_ms", "must be 0..60000 ms")
    need(cfg.emergency_release in (RELEASE_AT_STANDSTILL, RELEASE_REVOCABLE), "emergency_release",
         "must be 0 (held to standstill) or 1 (revocable when its cause is gone)")
    need(1 <= cfg.release_confirm_cycles <= 1000, "release_confirm_cycles", "must be 1..1000 cycles")
    need(0 <= cfg.warning_margin_dm <= 60000, "warning_margin_dm", "must be 0..60000 dm")
    need(1 <= cfg.fast_closing_cms <= 15000, "fast_closing_cms", "must be 1..15000 cm/s")
    need(cfg.safe_reaction in (SERVICE, EMERGENCY), "safe_reaction", "must be 1 (service) or 2 (emergency)")
    need(1 <= cfg.recovery_cycles <= 100000, "recovery_cycles", "must be 1..100000 cycles")
    need(1 <= cfg.max_overruns <= 1000, "max_overruns", "must be 1..1000")
    need(0 <= cfg.distance_tolerance_dm <= 60000, "distance_tolerance_dm", "must be 0..60000 dm")
    need(1 <= cfg.forget_ms <= 600000, "forget_ms", "must be 1..600000 ms (10 min; rounded up to whole cycles)")
    need(1 <= cfg.sensor_range_dm <= 60000, "sensor_range_dm", "must be 1..60000 dm")
    need(1 <= cfg.forget_single_ms <= 600000, "forget_single_ms", "must be 1..600000 ms (at most forget_ms counts; rounded up to whole cycles)")
    need(0 <= cfg.distance_accuracy_dm <= 60000, "distance_accuracy_dm", "must be 0..60000 dm")
    need(0 <= cfg.closing_accuracy_cms <= 15000, "closing_accuracy_cms", "must be 0..15000 cm/s")
    need(1 <= cfg.plausibility_ms <= 60000, "plausibility_ms", "must be 1..60000 ms")


def forget_cycles(cfg: Config, single: bool = False) -> int:
    """Cycles of evidence that make `forget_ms` (`single`: `forget_single_ms`, for an obstacle
    only one module ever saw, never longer than `forget_ms`), rounded up (never forget early)."""
    ms = min(cfg.forget_single_ms, cfg.forget_ms) if single else cfg.forget_ms
    return -(-ms // cfg.period_ms)


def track_accel_mms2(cfg: Config) -> int:
    """What the train may gain per second, traction plus the steepest downhill (rounded up):
    the acceleration a remembered obstacle is moved with (memory.near_travel)."""
    return cfg.max_accel_mms2 + gradient_accel_mms2(cfg.max_gradient_permille)


def emergency_bands(cfg: Config) -> tuple:
    """((from_cms, decel_mms2), ...) of the emergency brake, lowest speed first."""
    bands = [(0, cfg.emergency_decel_mms2)]
    if cfg.emergency_band2_cms:
        bands.append((cfg.emergency_band2_cms, cfg.emergency_band2_mms2))
        if cfg.emergency_band3_cms:
            bands.append((cfg.emergency_band3_cms, cfg.emergency_band3_mms2))
    return tuple(bands)


def gradient_accel_mms2(gradient_permille: int) -> int:
    """g * gradient in mm/s^2, rounded up (g = 9.81 m/s^2; downhill adds this much).

    pre: 0 <= gradient_permille <= 60
    post: __return__ * 1000 >= 9810 * gradient_permille
    post: (__return__ - 1) * 1000 < 9810 * gradient_permille or __return__ == 0
    """
    return -(-9810 * gradient_permille // 1000)


def from_mapping(values: dict) -> Config:
    """A Config from a mapping (e.g. a TOML table); unknown keys are refused."""
    unknown = sorted(set(values) - set(Config._fields))
    if unknown:
        raise ConfigurationError(f"unknown configuration key(s) {', '.join(unknown)}; known: {', '.join(Config._fields)}")
    cfg = Config(**values)
    check(cfg)
    return cfg
