"""The train's braking declaration: a TOML file in SI units, read into the integer fields
of the monitor's Config (monitor.core.config), every value rounded to the safe side.

Keys (docs/supervision.md gives each one's meaning and the shipped train's sources):
    emergency_decel        m/s^2, guaranteed; a number, or [[from_speed_m_s, decel], ...]
                           (up to 3 bands, the first from 0 m/s)
    service_decel          m/s^2, guaranteed
    emergency_buildup_s    equivalent dead time + build-up of the emergency brake
    service_buildup_s      the same for the service brake
    traction_cutoff_s      traction may still accelerate the train this long
    max_accel              m/s^2 under full traction
    speed_error            fraction of the measured speed (0.02: 2 %)
    slippery_factor        multiplies the decelerations while a slippery track is reported
    degraded_factor        multiplies the decelerations while degraded brakes are reported
    max_downhill_gradient  per mille, the steepest downhill of the line
    standstill_margin_m    stop this far before the obstacle
and, optional (absent: the monitor's configured sensors, 50 m and 1 m/s by default), the
sensors' guaranteed accuracy, which the supervised curves and the memory count (the error
budget, docs/supervision.md 2.6):
    distance_accuracy_m    a reported distance is within this of the true one
    closing_accuracy_mps   a reported closing speed is within this of the true one
"""
from __future__ import annotations

import math
from importlib import resources
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from monitor.core.config import Config, ConfigurationError, check

SHIPPED = "papers-train"
KEYS = ("emergency_decel", "service_decel", "emergency_buildup_s", "service_buildup_s", "traction_cutoff_s",
        "max_accel", "speed_error", "slippery_factor", "degraded_factor", "max_downhill_gradient",
        "standstill_margin_m")
OPTIONAL = ("distance_accuracy_m", "closing_accuracy_mps")     # the sensors': absent, the configured ones


class DeclarationError(ValueError):
    """A braking declaration that cannot be used; the message names the file and the key."""


def _number(where: str, key: str, value, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DeclarationError(f"{where}: {key} = {value!r}: must be a number")
    if not lo <= value <= hi:
        raise DeclarationError(f"{where}: {key} = {value!r}: must be {lo:g}..{hi:g}")
    return float(value)


def _down(x: float, scale: int) -> int:
    """x * scale rounded down (decelerations, factors: weaker is the safe side)."""
    return math.floor(round(x * scale, 6))


def _up(x: float, scale: int) -> int:
    """x * scale rounded up (times, errors, gradients, margins: longer is the safe side)."""
    return math.ceil(round(x * scale, 6))


def _bands(where: str, value) -> list[tuple[int, int]]:
    if not isinstance(value, list):
        return [(0, _down(_number(where, "emergency_decel", value, 0.001, 20.0), 1000))]
    if not 1 <= len(value) <= 3:
        raise DeclarationError(f"{where}: emergency_decel: give 1 to 3 bands [[from_speed_m_s, decel], ...]")
    bands = []
    for i, band in enumerate(value):
        key = f"emergency_decel[{i}]"
        if not isinstance(band, list) or len(band) != 2:
            raise DeclarationError(f"{where}: {key} = {band!r}: a band is [from_speed_m_s, decel_m_s2]")
        speed = _number(where, key + " speed", band[0], 0.0, 120.0)
        decel = _number(where, key + " deceleration", band[1], 0.001, 20.0)
        bands.append((_up(speed, 100), _down(decel, 1000)))
    if bands[0][0] != 0:
        raise DeclarationError(f"{where}: emergency_decel: the first band must start at 0 m/s")
    for (a, _), (b, _) in zip(bands, bands[1:]):
        if b <= a:
            raise DeclarationError(f"{where}: emergency_decel: band speeds must increase")
    return bands


def fields(values: dict, where: str = "braking declaration") -> dict:
    """The Config fields of a declaration mapping (all keys required); unknown keys refused."""
    unknown = sorted(set(values) - set(KEYS) - set(OPTIONAL))
    if unknown:
        raise DeclarationError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(KEYS + OPTIONAL)}")
    missing = [k for k in KEYS if k not in values]
    if missing:
        raise DeclarationError(f"{where}: missing key(s) {', '.join(missing)}")
    bands = _bands(where, values["emergency_decel"])
    out = {"emergency_decel_mms2": bands[0][1], "emergency_band2_cms": 0, "emergency_band2_mms2": 0,
           "emergency_band3_cms": 0, "emergency_band3_mms2": 0}
    for i, (speed, decel) in enumerate(bands[1:], start=2):
        out[f"emergency_band{i}_cms"], out[f"emergency_band{i}_mms2"] = speed, decel
    out["service_decel_mms2"] = _down(_number(where, "service_decel", values["service_decel"], 0.001, 20.0), 1000)
    for key, field in (("emergency_buildup_s", "emergency_buildup_ms"), ("service_buildup_s", "service_buildup_ms"),
                       ("traction_cutoff_s", "traction_cutoff_ms")):
        out[field] = _up(_number(where, key, values[key], 0.0, 30.0), 1000)
    out["max_accel_mms2"] = _up(_number(where, "max_accel", values["max_accel"], 0.0, 5.0), 1000)
    out["speed_error_permille"] = _up(_number(where, "speed_error", values["speed_error"], 0.0, 0.5), 1000)
    for key, field in (("slippery_factor", "slippery_permille"), ("degraded_factor", "degraded_permille")):
        out[field] = _down(_number(where, key, values[key], 0.001, 1.0), 1000)
    out["max_gradient_permille"] = _up(_number(where, "max_downhill_gradient", values["max_downhill_gradient"], 0.0, 60.0), 1)
    out["standstill_margin_dm"] = _up(_number(where, "standstill_margin_m", values["standstill_margin_m"], 0.0, 1000.0), 10)
    if "distance_accuracy_m" in values:        # errors round up: a larger error is the safe side
        out["distance_accuracy_dm"] = _up(_number(where, "distance_accuracy_m", values["distance_accuracy_m"], 0.0, 6000.0), 10)
    if "closing_accuracy_mps" in values:
        out["closing_accuracy_cms"] = _up(_number(where, "closing_accuracy_mps", values["closing_accuracy_mps"], 0.0, 150.0), 100)
    return out


def apply(cfg: Config, values: dict, where: str = "braking declaration") -> Config:
    """`cfg` with the declaration's values, checked together (e.g. the worst-case
    deceleration on the steepest downhill must stay positive)."""
    new = cfg._replace(**fields(values, where))
    try:
        check(new)
    except ConfigurationError as exc:
        raise DeclarationError(f"{where}: {exc}") from None
    return new


def load(path: str | Path) -> dict:
    """The mapping of a declaration file (a `[braking]` table, if there is one, or the top
    level); DeclarationError naming the file (and the line, for TOML syntax) otherwise."""
    from monitor.offline.params import ConfigError, read_toml

    try:
        data = read_toml(path)
    except ConfigError as exc:
        raise DeclarationError(f"{exc} (braking declaration)") from None
    return data.get("braking", data) if isinstance(data.get("braking"), dict) else data


def shipped() -> dict:
    """The declaration of the papers' train (monitor/trains/papers-train.toml)."""
    text = resources.files("monitor.trains").joinpath(f"{SHIPPED}.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)["braking"]


def config_with(cfg: Config, path: str | Path | None) -> Config:
    """`cfg` with the declaration in `path` (None: unchanged)."""
    if path is None:
        return cfg
    return apply(cfg, load(path), str(path))
