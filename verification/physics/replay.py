"""Counterexamples that replay (issue 30 item 5): a refuted integer obligation becomes a cosim
scenario that anyone can watch collide.

From the refuted obligation's paths, Z3 is asked for the playable point (a static or oncoming
obstacle, the true speed the measured one plus the speed error, a fresh report) where the
integer curve falls shortest of the real one, doubling the shortfall until it can no more.
The scenario puts the world's train at the declaration's corner there: the guaranteed
deceleration, the whole equivalent build-up as dead time, full traction until the cut-off,
the steepest downhill, the speed under-reported by the whole error; the sensors' range is the
integer curve at that point, so the monitor first sees the obstacle on its emergency curve.
`railguard cosim FILE` plays it (with `--monitor-fmu` for a weakened core's FMU).
"""
from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from types import ModuleType
from typing import Optional

import z3

from monitor.core.config import Config, emergency_bands
from monitor.core.types import MAX_DISTANCE_DM, MAX_SPEED_CMS

from . import symbolic
from .model import Declaration, q, real_curves
from .obligations import Result, refute, value

PLAYABLE_OBSTACLE_CMS = 6000       # an oncoming obstacle of the replay: at most 60 m/s
APPROACH_S = 3                     # the train cruises this long before the obstacle comes into range


def declaration_si(cfg: Config) -> dict:
    """A braking declaration (monitor/declaration.py keys, SI) that converts back to cfg's integers."""
    def dec(x: int, scale: int):
        f = Fraction(x, scale)
        return int(f) if f.denominator == 1 else float(f)
    bands = [[dec(lo, 100), dec(a, 1000)] for lo, a in emergency_bands(cfg)]
    return {"emergency_decel": bands if len(bands) > 1 else bands[0][1],
            "service_decel": dec(cfg.service_decel_mms2, 1000),
            "emergency_buildup_s": dec(cfg.emergency_buildup_ms, 1000),
            "service_buildup_s": dec(cfg.service_buildup_ms, 1000),
            "traction_cutoff_s": dec(cfg.traction_cutoff_ms, 1000), "max_accel": dec(cfg.max_accel_mms2, 1000),
            "speed_error": dec(cfg.speed_error_permille, 1000), "slippery_factor": dec(cfg.slippery_permille, 1000),
            "degraded_factor": dec(cfg.degraded_permille, 1000),
            "max_downhill_gradient": cfg.max_gradient_permille,
            "standstill_margin_m": dec(cfg.standstill_margin_dm, 10)}


def worst_point(cfg: Config, braking: ModuleType, result: Result, oncoming: bool = False,
                limit_m: float = 1024.0) -> Optional[dict]:
    """The playable point (integers: measured speed and closing speed in cm/s, report age 0)
    where the refuted curve falls shortest of the real one, with a static obstacle, or an
    oncoming one; None when no playable point falls short."""
    ctx = result.context
    name, track, brake, service = ctx["curve"], ctx["track"], ctx["brake"], ctx["service"]
    d = Declaration.of(cfg)
    s, c, a = z3.Reals("speed_cms closing_cms age_ms")
    e = Fraction(cfg.speed_error_permille, 1000)
    true_cms = s * q(1 + e)
    w = c - true_cms
    domain = [0 <= s, true_cms <= MAX_SPEED_CMS, a == 0,
              *([0 < w, w <= PLAYABLE_OBSTACLE_CMS] if oncoming else [w == 0])]
    paths = symbolic.explore(braking.curves, {"cfg": cfg, "speed_cms": s, "track": track, "brake": brake,
                                              "closing_cms": c, "age_ms": a, "service": service}, domain)
    real = getattr(real_curves(d, s / 100, c / 100, a / 1000, track, brake, service), name)
    best, k = None, 0.0
    while k <= limit_m:
        found = None
        for p in paths:
            rounded = getattr(p.value, f"{name}_dm") / 10
            # the shipped curve there is at least the real one, and the sensors' range must reach it
            _, model = refute(z3.And(*domain, *p.condition, *p.side, real - rounded > q(Fraction(k).limit_denominator()),
                                     real <= q(Fraction(MAX_DISTANCE_DM, 10)) - 50), 20000)
            if model is not None:
                found = {"speed_cms": int(value(model, s)), "closing_cms": int(value(model, c)), "age_ms": 0,
                         "track": track, "brake": brake, "service": service, "curve": name,
                         "shortfall_m": value(model, real - rounded)}
                break
        if found is None:
            break
        best = found
        k = max(1.0, 2 * k)
    return best


def scenario_text(cfg: Config, point: dict, weak: ModuleType, title: str, table: Path) -> tuple[str, dict]:
    """The cosim scenario of a counterexample point (monitor/scenario.py's language) and its
    figures. The obstacle comes into range on the shipped code's emergency curve, so that the
    shipped monitor brakes at once there and the weakened one later, on its own curve."""
    import json

    from monitor.core import braking as shipped

    args = (cfg, point["speed_cms"], point["track"], point["brake"], point["closing_cms"], 0)
    ebi_shipped, ebi_weak = shipped.curves(*args).ebi_dm / 10, weak.curves(*args).ebi_dm / 10
    e = cfg.speed_error_permille / 1000
    true_speed = min(point["speed_cms"] * (1 + e), MAX_SPEED_CMS) / 100
    obstacle = max(0.0, point["closing_cms"] / 100 - true_speed)
    seen_at = max(1.0, ebi_shipped)
    position = seen_at + (true_speed + obstacle) * APPROACH_S
    worst = min(a for _, a in emergency_bands(cfg)) / 1000 - 9.81 * cfg.max_gradient_permille / 1000
    duration = APPROACH_S + cfg.emergency_buildup_ms / 1000 + cfg.traction_cutoff_ms / 1000 + true_speed / worst + 20
    bands = [[lo / 100, a / 1000] for lo, a in emergency_bands(cfg)]
    lines = [f"description = {json.dumps(title)}", f"duration_s = {duration:.1f}", "demand_delay_cycles = 1",
             f"table = {json.dumps(str(table))}  # the curves alone: the table never asks for braking", "",
             "[train]  # the declaration's corner: guaranteed deceleration, the whole build-up as dead time,",
             "         # full traction until the cut-off, the steepest downhill, the speed under-reported",
             f"speed_mps = {true_speed:.2f}",
             f"emergency_decel_mps2 = {json.dumps(bands if len(bands) > 1 else bands[0][1])}",
             f"service_decel_mps2 = {cfg.service_decel_mms2 / 1000}",
             f"brake_delay_s = {cfg.emergency_buildup_ms / 1000}", "brake_buildup_s = 0.0",
             f"traction_cutoff_s = {cfg.traction_cutoff_ms / 1000}", f"max_traction_mps2 = {cfg.max_accel_mms2 / 1000}",
             f"gradient_permille = {-cfg.max_gradient_permille}", f"speed_error = {e}", "",
             "[[obstacles]]", f"position_m = {position:.1f}", f"speed_mps = {-obstacle:.2f}",
             f"type = \"{'train' if obstacle > 0 else 'static'}\"", "",
             f"[sensors]  # in range on the shipped EBI ({ebi_shipped:.1f} m); the weakened EBI is {ebi_weak:.1f} m",
             f"range_m = {seen_at:.1f}", "noise_sigma_m = 0.0", "", "[braking]"]
    lines += [f"{k} = {json.dumps(v)}" for k, v in declaration_si(cfg).items()]
    return "\n".join(lines) + "\n", {"true_speed_mps": true_speed, "obstacle_speed_mps": obstacle,
                                      "ebi_shipped_m": ebi_shipped, "ebi_weakened_m": ebi_weak}


def write_scenario(cfg: Config, point: dict, weak: ModuleType, title: str, path: Path) -> tuple[Path, dict]:
    """The scenario file and, beside it, the curves-only table it names."""
    from fmu.acceptance import curves_only_table
    from monitor.tables import read

    path.parent.mkdir(parents=True, exist_ok=True)
    table = path.parent / "curves-only.rgt"
    table.write_bytes(curves_only_table(read("m1")))
    text, figures = scenario_text(cfg, point, weak, title, table.resolve())
    path.write_text(text)
    return path, figures


def play(path: Path, monitor_fmu: Path, train_fmu: Path) -> dict:
    """Play the scenario in co-simulation with the real FMUs given."""
    from fmu import cosim, scenario

    res = cosim.run_scenario(scenario.load(str(path)), monitor_fmu, train_fmu, record=False)
    return {"outcome": res.outcome, "margin_m": res.margin_m, "impact_speed": res.impact_speed,
            "first_brake_s": res.first_brake_s, "max_demand": res.max_demand}
