"""Counterexamples that replay (issue 30 item 5): a refuted integer obligation becomes a cosim
scenario that anyone can watch collide.

From the refuted obligation's paths, Z3 is asked for the playable point (a static or oncoming
obstacle, the true speed the measured one plus the speed error, a fresh report) where the
integer curve falls shortest of the real one, doubling the shortfall until it can no more.
The scenario puts the world's train at the declaration's corner there: the guaranteed
deceleration, the whole equivalent build-up as dead time, full traction until the cut-off,
the steepest downhill, the speed under-reported by the whole error; and the sensors at the
error budget's (`sensor_corner`): the obstacle reported the whole distance accuracy farther
and closing the whole closing accuracy slower than it is. The sensors' range puts
the first reading one cycle's travel inside the shipped EBI: the obstacle came into range
just after a reading, one cycle after the last reading that found it beyond EBI. With the
cycle from a reading to the demand at the train, these are the two periods the supervised
EBI counts, so the shipped monitor meets its curve's worst case there exactly.
`railguard cosim FILE` plays it (with `--monitor-fmu` for a weakened core's FMU).

Why a replay needs speed, and a declaration with a perfect speedometer. Two monitors that
first read the obstacle at the same distance differ little: inside the weakened EBI both
demand the emergency at once; between the two EBIs the weakened one demands the service brake
(the point is inside its SBI) and the emergency two cycles later, when it holds the brake
inside SBI. A replay collides when that lateness exceeds the standstill margin and the slack
the curve has at that point, which is why `worst_point` takes the fastest point. The largest slack is
the speed error, counted twice by design: the train's travel at the highest true speed
(v_max) and the obstacle's at the closing speed less the lowest true speed (v_min), which no
single world realises (a static obstacle seen by a train whose speed is under-reported by 2 %
leaves about 80 m at 69 m/s, measured in this tool's first replays: the obstacle's 2.7 m/s
counted over a 33 s stop). `replay_declaration`
therefore plays every weakening that does not concern the speed error on the declaration with
speed error 0, on which the proof fails too.
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


def replay_declaration(cfg: Config, weakening_name: str) -> Config:
    """The declaration a weakening's counterexample is replayed on: `cfg` with speed error 0,
    except for the weakening of the speed error itself (see the module doc)."""
    return cfg if weakening_name == "speed-error-ignored" else cfg._replace(speed_error_permille=0)


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


SPEED_FLOORS_CMS = (11000, 9000, 7000, 5000, 3000, 0)   # tried fastest first (worst_point)
SHORTFALLS_M = (1024, 256, 64, 16, 4, 0)                # an oncoming obstacle: the largest shortfall first


def worst_point(cfg: Config, braking: ModuleType, result: Result, oncoming: bool = False) -> Optional[dict]:
    """The playable point (integers: measured speed and closing speed in cm/s, report age 0)
    with a static obstacle (the fastest train) or an oncoming one (the largest shortfall),
    where the refuted curve falls short of the real one by more than a cycle's travel and a
    metre: there the weakened monitor first reads the obstacle outside its own EBI
    (scenario_text), and a cycle's lateness grows with the speed while the standstill margin
    does not. None when no playable point falls so short."""
    from fmu.acceptance import sensor_corner

    ctx = result.context
    name, track, brake, service = ctx["curve"], ctx["track"], ctx["brake"], ctx["service"]
    d = Declaration.of(cfg)
    s, c, a = z3.Reals("speed_cms closing_cms age_ms")
    e = Fraction(cfg.speed_error_permille, 1000)
    true_cms = s * q(1 + e)
    # the obstacle's true speed when the sensors report its closing speed at their corner
    w = c - round(sensor_corner(cfg)[1] * 100) - true_cms
    domain = [0 <= s, true_cms <= MAX_SPEED_CMS, a == 0,
              *([0 < w, w <= PLAYABLE_OBSTACLE_CMS] if oncoming else [w == 0])]
    paths = symbolic.explore(braking.curves, {"cfg": cfg, "speed_cms": s, "track": track, "brake": brake,
                                              "closing_cms": c, "age_ms": a, "service": service}, domain)
    real = getattr(real_curves(d, s / 100, c / 100, a / 1000, track, brake, service), name)
    late = c / 100 * q(Fraction(cfg.period_ms, 1000)) + 1          # a cycle's travel and a metre, in m
    # static: the fastest train; oncoming: the largest shortfall (the obstacle's own travel)
    floors = [(0, k) for k in SHORTFALLS_M] if oncoming else [(f, 0) for f in SPEED_FLOORS_CMS]
    for floor, shortfall in floors:
        for p in paths:
            rounded = getattr(p.value, f"{name}_dm") / 10
            # the sensors' range must reach the shipped curve there
            _, model = refute(z3.And(*domain, s >= floor, *p.condition, *p.side, real - rounded > late,
                                     real - rounded > shortfall, real <= q(Fraction(MAX_DISTANCE_DM, 10)) - 50),
                              20000)
            if model is not None:
                return {"speed_cms": int(value(model, s)), "closing_cms": int(value(model, c)), "age_ms": 0,
                        "track": track, "brake": brake, "service": service, "curve": name,
                        "shortfall_m": value(model, real - rounded)}
    return None


# The replays try the pulling train first, then the cruising one: a weakened monitor is one or
# two cycles late (it escalates at its EBI, or inside its SBI once it holds the service brake),
# and the train's acceleration moves its EBI between readings, which decides which.
PULLING = (True, False)
SIGHTING_INSIDE_M = 0.1    # the first reading this far inside the shipped EBI: the sensors' dm rounding


def scenario_text(cfg: Config, point: dict, weak: ModuleType, title: str, table: Path,
                  pulling: bool = True, stall_s: Optional[float] = None) -> tuple[str, dict]:
    """The cosim scenario of a counterexample point (monitor/scenario.py's language) and its
    figures. The obstacle comes into range one cycle's travel inside the shipped code's
    emergency curve, so that the shipped monitor brakes at once there and the weakened one at
    least a cycle later. `pulling`: the train pulls at full traction until the demand (the
    declaration's worst train), else it cruises; both are inside the declaration, and which
    one makes the weakened monitor later depends on where its curve lies (PULLING).
    `stall_s`: the monitor stalls from then on (a hang, a crash: the master no longer steps
    it); the caller gives the cycle at which the weakened monitor first demands when it runs,
    so that the brakes' receiver brakes at its timeout, the timing contract's worst (4
    periods after the weakened monitor's last cycle outside its own EBI), while the shipped
    monitor braked at the first reading."""
    import json

    from fmu.acceptance import approach, approach_accel, cruise_speed, sensor_corner
    from monitor.core import braking as shipped

    args = (cfg, point["speed_cms"], point["track"], point["brake"], point["closing_cms"], 0)
    ebi_shipped, ebi_weak = shipped.curves(*args).ebi_dm / 10, weak.curves(*args).ebi_dm / 10
    e = cfg.speed_error_permille / 1000
    true_speed = min(point["speed_cms"] * (1 + e), MAX_SPEED_CMS) / 100
    bias_m, bias_mps = sensor_corner(cfg)
    obstacle = max(0.0, point["closing_cms"] / 100 - bias_mps - true_speed)
    # pulling: full traction downhill until the demand (the cruising speed is above any it
    # reaches); cruising: downhill, it coasts. It starts slower either way, so that its speed
    # at the first reading is the point's
    pull = approach_accel(cfg.max_accel_mms2 / 1000, -cfg.max_gradient_permille, pulling)
    start_speed, run = approach(true_speed, pull, APPROACH_S)
    cruise = cruise_speed(true_speed, pulling)
    # one cycle's travel inside the shipped EBI: the obstacle came into range just after a
    # reading, a cycle after the last reading that found it beyond EBI (the sampling period)
    # (the reading reports it the distance bias farther than it is)
    seen_at = max(1.0, ebi_shipped - bias_m - (true_speed + obstacle) * cfg.period_ms / 1000 - SIGHTING_INSIDE_M)
    position = seen_at + run + obstacle * APPROACH_S
    worst = min(a for _, a in emergency_bands(cfg)) / 1000 - 9.81 * cfg.max_gradient_permille / 1000
    duration = APPROACH_S + cfg.emergency_buildup_ms / 1000 + cfg.traction_cutoff_ms / 1000 + true_speed / worst + 20
    lines = [f"description = {json.dumps(title)}", f"duration_s = {duration:.1f}", "demand_delay_cycles = 1",
             f"table = {json.dumps(str(table))}  # the curves alone: the table never asks for braking", "",
             *corner_train(cfg, start_speed, cruise, pulling,
                           f"{true_speed:.2f} m/s at the first reading, {APPROACH_S} s later"), "",
             "[[obstacles]]", f"position_m = {position:.4f}", f"speed_mps = {-obstacle:.2f}",
             f"type = \"{'train' if obstacle > 0 else 'static'}\"", "",
             f"[sensors]  # first reading a cycle's travel inside the shipped EBI ({ebi_shipped:.1f} m), outside "
             f"the weakened EBI ({ebi_weak:.1f} m)",
             f"range_m = {seen_at + 0.05:.2f}", "noise_sigma_m = 0.0", *sensor_lines(cfg), "", "[braking]"]
    lines += [f"{k} = {json.dumps(v)}" for k, v in declaration_si(cfg).items()]
    if stall_s is not None:
        lines += ["", "[[faults]]  # the monitor stalls where the weakened one first demands", 'kind = "monitor_stop"',
                  f"start_s = {stall_s:.1f}"]
    return "\n".join(lines) + "\n", {"true_speed_mps": true_speed, "obstacle_speed_mps": obstacle,
                                      "ebi_shipped_m": ebi_shipped, "ebi_weakened_m": ebi_weak}


def sensor_lines(cfg: Config) -> list[str]:
    """The [sensors] keys of fmu.acceptance.sensor_corner, for a replay's scenario."""
    from fmu.acceptance import sensor_corner

    bias_m, bias_mps = sensor_corner(cfg)
    return [f"distance_bias_m = {bias_m}  # the sensors at their declared accuracy's worst: farther,",
            f"closing_bias_mps = {bias_mps}  # and closing slower than it is"]


def corner_train(cfg: Config, start_speed: float, cruise: float, pulling: bool, when: str) -> list[str]:
    """The scenario's [train] at the declaration's corner: guaranteed deceleration, the whole
    build-up as dead time, full traction until the cut-off, the steepest downhill, the speed
    under-reported by the whole error."""
    import json

    bands = [[lo / 100, a / 1000] for lo, a in emergency_bands(cfg)]
    return ["[train]  # the declaration's corner: guaranteed deceleration, the whole build-up as dead time,",
            "         # full traction until the cut-off, the steepest downhill, the speed under-reported",
            f"speed_mps = {start_speed:.4f}  # {when}",
            f"cruise_speed_mps = {cruise:.2f}  # " + ("above every speed it reaches: full traction until the demand"
                                                     if pulling else "cruising, coasting downhill"),
            f"emergency_decel_mps2 = {json.dumps(bands if len(bands) > 1 else bands[0][1])}",
            f"service_decel_mps2 = {cfg.service_decel_mms2 / 1000}",
            f"brake_delay_s = {cfg.emergency_buildup_ms / 1000}", "brake_buildup_s = 0.0",
            f"traction_cutoff_s = {cfg.traction_cutoff_ms / 1000}", f"max_traction_mps2 = {cfg.max_accel_mms2 / 1000}",
            f"gradient_permille = {-cfg.max_gradient_permille}", f"speed_error = {cfg.speed_error_permille / 1000}"]


# A memory weakening's replay (issue 40 item 2): an oncoming train seen once, far beyond the
# shipped warning curve, then every channel blind (fresh ABSENT, beyond the declared sensor
# range: no evidence that it is gone) while the remembered obstacle closes in; the sensors see
# again only after the shipped monitor stands. What the memory predicts is all that brakes.
MEMORY_REPLAY = {"train_mps": 30.0, "obstacle_mps": 25.0, "beyond_warning_m": 600.0, "approach_s": 3.0,
                 "blind_after_s": 0.2, "blind_s": 16.0}


def memory_scenario_text(cfg: Config, title: str, table: Path) -> tuple[str, dict]:
    """The scenario (MEMORY_REPLAY) and its figures, on `cfg` (replay_declaration's)."""
    import json

    from monitor.core import braking as shipped

    m = MEMORY_REPLAY
    v, w = m["train_mps"], m["obstacle_mps"]
    c = shipped.curves(cfg, round(v * 100), 0, 0, round((v + w) * 100), 0)
    seen_at = c.warning_dm / 10 + m["beyond_warning_m"]
    blind_from = m["approach_s"] + m["blind_after_s"]
    lines = [f"description = {json.dumps(title)}", "duration_s = 80.0", "demand_delay_cycles = 1",
             f"table = {json.dumps(str(table))}  # the curves alone: the table never asks for braking", "",
             *corner_train(cfg, v, v + 20, True, "pulling until the demand"), "",
             "[[obstacles]]", f"position_m = {seen_at + (v + w) * m['approach_s']:.2f}", f"speed_mps = {-w}",
             'type = "train"', "", f"[sensors]  # first seen {m['beyond_warning_m']:.0f} m beyond the shipped warning "
             f"curve ({c.warning_dm / 10:.1f} m; EBI {c.ebi_dm / 10:.1f} m)", f"range_m = {seen_at:.2f}",
             "noise_sigma_m = 0.0", *sensor_lines(cfg), "", "[[faults]]", 'kind = "blind"', f"start_s = {blind_from}",
             f"end_s = {blind_from + m['blind_s']}", "", "[braking]"]
    lines += [f"{k} = {json.dumps(x)}" for k, x in declaration_si(cfg).items()]
    figures = {"true_speed_mps": v, "obstacle_speed_mps": w, "ebi_shipped_m": c.ebi_dm / 10,
               "ebi_weakened_m": c.ebi_dm / 10, "seen_at_m": seen_at, "blind_s": m["blind_s"]}
    return "\n".join(lines) + "\n", figures


def write_scenario(cfg: Config, point: dict, weak: ModuleType, title: str, path: Path,
                   pulling: bool = True, stall_s: Optional[float] = None) -> tuple[Path, dict]:
    """The scenario file and, beside it, the curves-only table it names."""
    from fmu.acceptance import curves_only_table
    from monitor.tables import read

    path.parent.mkdir(parents=True, exist_ok=True)
    table = path.parent / "curves-only.rgt"
    table.write_bytes(curves_only_table(read("m1")))
    text, figures = scenario_text(cfg, point, weak, title, table.resolve(), pulling, stall_s)
    path.write_text(text)
    return path, figures


def play(path: Path, monitor_fmu: Path, train_fmu: Path) -> dict:
    """Play the scenario in co-simulation with the real FMUs given."""
    from fmu import cosim, scenario

    res = cosim.run_scenario(scenario.load(str(path)), monitor_fmu, train_fmu, record=False)
    return {"outcome": res.outcome, "margin_m": res.margin_m, "impact_speed": res.impact_speed,
            "first_brake_s": res.first_brake_s, "first_emergency_s": res.first_emergency_s,
            "max_demand": res.max_demand}
