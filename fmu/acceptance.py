"""Closed-loop acceptance of the braking curves (issue 11, Deliver 6): the train FMU is the
world and brakes as badly as the braking declaration allows, corners included (a train
pulling at full traction until the brake demand among them), its sensors erring at the
declared accuracy's worst (the obstacle reported farther and closing slower than it is); the monitor supervises it with
the curves of that declaration; the demand reaches the train one monitor cycle late; the
obstacle is first read one cycle's travel inside EBI, at the speed the train has then (the
sampling period's worst case, which the supervised EBI counts: the cycle before, it was out
of range and at least EBI away). Required: no collision (contact while our train moves), and
inside the declaration every stop `standstill_margin` short, as the physics proof says.

`grid_cases` builds the grid, `run_cases` runs it through a `fmu.cosim.Loop`,
`beyond_cases` builds the sweep outside the declaration, and `python -m fmu.acceptance`
writes docs/supervision_grid.png and prints the tables of docs/supervision_grid.md.
"""
from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace

from monitor.core.braking import curves
from monitor.core.config import Config
from monitor.declaration import apply, fields

from .reference import read_closing_cms, read_speed_cms

SPEEDS_MPS = (10.0, 20.0, 30.0, 40.0)
OBSTACLE_SPEEDS_MPS = (0.0, -5.0, -10.0)       # along the track: 0 static, negative oncoming
NOMINAL_DECEL = 3.0                            # the papers' train: nominal emergency braking, m/s^2
NOMINAL_SERVICE = 1.0
UPHILL = 10.0                                  # per mille: the uphill corner of the grid
APPROACH_S = 2.0                               # the obstacle enters sensor range this long after t = 0
PERIOD_S = 0.1
PULL_ABOVE_MPS = 5.0                           # a pulling train's cruising speed above any it reaches
MAX_RUN_S = 300.0     # room to stop even if a revocable emergency is released and the train rides the curves down


def approach_accel(max_traction: float, gradient_permille: float, pulling: bool) -> float:
    """The train FMU's acceleration before a brake demand: full traction when pulling, plus
    the downhill pull it coasts with (its cruise controller has no brake); uphill and level
    it holds its speed."""
    downhill = -gradient_permille * 9.81e-3 if gradient_permille < 0 else 0.0
    return (max_traction if pulling else 0.0) + downhill


def approach(speed: float, accel: float, seconds: float) -> tuple[float, float]:
    """(start speed, distance run) of a train that accelerates at `accel` for `seconds` to
    reach `speed`: a scenario starts it slower, so that it meets the obstacle at `speed`."""
    start = max(0.0, speed - accel * seconds)
    return start, start * seconds + accel * seconds ** 2 / 2


def cruise_speed(speed: float, pulling: bool) -> float:
    """The train FMU's cruise_speed: above any speed a pulling train reaches (so it pulls at
    full traction all along), else -1 (it cruises at its initial speed)."""
    return min(120.0, speed + PULL_ABOVE_MPS) if pulling else -1.0


@dataclass(frozen=True)
class World:
    """One way the real train brakes (the train FMU's parameters the declaration bounds)."""

    bands: tuple                # ((from_speed_m_s, emergency_decel_m_s2), ...), first from 0
    service_decel: float
    dead_s: float               # brake dead time
    ramp_s: float               # linear brake build-up after it
    gradient: float             # per mille, positive uphill
    traction_s: float           # full traction this long after a brake demand
    speed_error: float          # the train reports true speed / (1 + speed_error)
    max_traction: float
    track: int = 0              # reported slippery track, with the decelerations x slippery_factor
    brake: int = 0              # reported degraded brakes, with the decelerations x degraded_factor
    slippery_factor: float = 1.0
    degraded_factor: float = 1.0
    pulling: bool = False       # full traction until the demand (the train FMU's cruise_speed above its speed)
    distance_bias: float = 0.0  # m: the sensors report the obstacle this much farther than it is
    closing_bias: float = 0.0   # m/s: and closing this much faster (negative: slower)

    @property
    def buildup_s(self) -> float:
        """Equivalent build-up: dead time + half the ramp (the declaration's convention)."""
        return self.dead_s + self.ramp_s / 2

    @property
    def worst_decel(self) -> float:
        """The weakest emergency deceleration the train achieves (any band, conditions)."""
        factor = (self.slippery_factor if self.track else 1.0) * (self.degraded_factor if self.brake else 1.0)
        return min(a for _, a in self.bands) * factor

    def params(self) -> dict:
        """Train FMU parameters (no running resistance: the declaration does not count it)."""
        p = {"emergency_decel": self.bands[0][1], "service_decel": self.service_decel,
             "brake_delay": self.dead_s, "brake_buildup": self.ramp_s, "gradient": self.gradient,
             "traction_cutoff": self.traction_s, "speed_error": self.speed_error, "max_traction": self.max_traction,
             "track_condition": self.track, "brake_status": self.brake, "slippery_factor": self.slippery_factor,
             "degraded_factor": self.degraded_factor, "davis_a": 0.0, "davis_b": 0.0, "davis_c": 0.0,
             "sensor.distance_bias": self.distance_bias, "sensor.closing_bias": self.closing_bias,
             "sensor.noise_sigma": 0.0}      # (the bias is the accuracy's corner: noise on it would leave the budget)
        for i, (speed, decel) in enumerate(self.bands[1:], start=2):
            p[f"emergency_band{i}_speed"], p[f"emergency_band{i}_decel"] = speed, decel
        return p

    def label(self) -> str:
        bands = "/".join(f"{a:g}" for _, a in self.bands)
        cond = {(0, 0): "normal", (1, 0): "slippery", (0, 1): "degraded", (1, 1): "slippery+degraded"}[
            (self.track, self.brake)]
        return (f"decel {bands}, dead {self.dead_s:g} s + ramp {self.ramp_s:g} s, gradient {self.gradient:+g}, "
                f"{'pulling, ' if self.pulling else ''}traction {self.traction_s:g} s, speed error {self.speed_error:g}, "
                f"{cond}")

    def approach_accel(self) -> float:
        """The train's acceleration before the demand (approach_accel)."""
        return approach_accel(self.max_traction, self.gradient, self.pulling)


@dataclass(frozen=True)
class Case:
    world: World
    speed: float                # the true speed at the first reading, m/s
    obstacle_speed: float       # m/s along the track
    visible_m: float            # sensor range: the obstacle is first seen this far ahead

    def train_params(self) -> dict:
        """The train starts slower by what it gains before the first reading (approach_accel),
        so that it reads the obstacle at `speed`, `visible_m` ahead, APPROACH_S after t = 0."""
        start, travel = approach(self.speed, self.world.approach_accel(), APPROACH_S)
        return {**self.world.params(), "initial_speed": start, "obstacle.present": True,
                "cruise_speed": cruise_speed(self.speed, self.world.pulling),
                "obstacle.position": self.visible_m + travel - self.obstacle_speed * APPROACH_S,
                "obstacle.speed": self.obstacle_speed,
                "obstacle.type": 0 if self.obstacle_speed == 0 else 2, "sensor.range": self.visible_m}


@dataclass(frozen=True)
class Outcome:
    case: Case
    outcome: str
    stop_margin_m: float | None
    impact_speed: float
    first_brake_s: float | None
    demand_changes: int = 0     # from the first brake demand on (the first brake itself counts)

    @property
    def collision(self) -> bool:
        return self.outcome == "collision"

    def signed_margin_m(self) -> float:
        """Stop margin; for a collision, minus the distance the train would still have
        needed at its impact speed with its weakest deceleration (how far it overran)."""
        if not self.collision:
            return self.stop_margin_m if self.stop_margin_m is not None else math.inf
        w = self.case.world
        return -self.impact_speed ** 2 / (2 * max(w.worst_decel + w.gradient * 9.81e-3, 0.05))


def declared_bands(values: dict) -> tuple:
    raw = values["emergency_decel"]
    return ((0.0, float(raw)),) if not isinstance(raw, list) else tuple((float(s), float(a)) for s, a in raw)


def sensor_corner(cfg: Config) -> tuple[float, float]:
    """(distance bias m, closing bias m/s) of sensors at their declared accuracy's worst (the
    error budget's corner): every reading reports the obstacle the whole distance accuracy
    farther and closing the whole closing accuracy slower than it is."""
    return cfg.distance_accuracy_dm / 10, -cfg.closing_accuracy_cms / 100


def first_visible_m(cfg: Config, speed: float, obstacle_speed: float, world: World) -> float:
    """Where the curves say a brake must start (EBI as the monitor computes it from what
    the train and the sensors report), less one cycle of travel at the closing speed: the
    first reading comes one cycle after the last one that found the obstacle beyond EBI."""
    closing = speed - obstacle_speed
    measured = read_speed_cms(speed / (1.0 + world.speed_error))
    ebi = curves(cfg, measured, world.track, world.brake, read_closing_cms(closing + world.closing_bias), 0).ebi_dm / 10
    return ebi - world.distance_bias - closing * PERIOD_S


def grid_worlds(values: dict) -> list[World]:
    """The trains within the declaration `values` (SI keys), corners included: actual
    deceleration at the guaranteed band values and at nominal; dead time and ramp whose
    equivalent build-up is the declared one (all dead time, all ramp, half each);
    steepest downhill, level, uphill; pulling at full traction until the demand and held
    for traction_cutoff_s after it, or cruising and cut at once; the speed reported low by
    speed_error or exact; normal, slippery (deceleration x slippery_factor) or degraded
    (x degraded_factor) reported; the sensors at the error budget's corner (sensor_corner)."""
    bias, closing_bias = sensor_corner(apply(Config(), values))
    t_be = values["emergency_buildup_s"]
    decels = ((declared_bands(values), float(values["service_decel"])), (((0.0, NOMINAL_DECEL),), NOMINAL_SERVICE))
    timings = ((t_be, 0.0), (0.0, 2 * t_be), (t_be / 2, t_be))
    gradients = (-float(values["max_downhill_gradient"]), 0.0, UPHILL)
    conditions = ((0, 0), (1, 0), (0, 1))
    worlds = []
    for (bands, service), (dead, ramp), grad, traction, err, (track, brake) in itertools.product(
            decels, timings, gradients, (float(values["traction_cutoff_s"]), 0.0),
            (float(values["speed_error"]), 0.0), conditions):
        worlds.append(World(bands, service, dead, ramp, grad, traction, err, float(values["max_accel"]), track, brake,
                            float(values["slippery_factor"]), float(values["degraded_factor"]), pulling=traction > 0,
                            distance_bias=bias, closing_bias=closing_bias))
    return worlds


def cases(cfg: Config, worlds, speeds=SPEEDS_MPS, obstacle_speeds=OBSTACLE_SPEEDS_MPS) -> list[Case]:
    """Every world at every speed against every obstacle, first visible as the curves of
    `cfg` (the declaration the grid is built from) say."""
    return [Case(w, v, u, first_visible_m(cfg, v, u, w)) for w in worlds for v in speeds for u in obstacle_speeds]


def grid_cases(values: dict) -> list[Case]:
    """The acceptance grid of the declaration `values`."""
    return cases(apply(Config(), values), grid_worlds(values))


def monitor_params(values: dict) -> dict:
    """The monitor FMU's parameters for a declaration (names of monitor/core/config.py)."""
    return fields(values)


def run_cases(loop, params: dict, todo, stalled: bool = False) -> tuple[list[Outcome], float]:
    """(outcomes, wall seconds) of `todo` through `loop` (a fmu.cosim.Loop) with monitor
    parameters `params`; each run ends when the train stands (or hits). `stalled`: the
    monitor stops at the first reading (no longer stepped: a hang, a crash), so that its
    last cycle is the one that found the obstacle beyond EBI and the train's brake receiver
    brakes at its timeout, the supervision's timing contract at its worst (4 periods)."""
    out = []
    t0 = time.perf_counter()
    stop = APPROACH_S if stalled else math.inf
    for case in todo:
        res = loop.run(case.train_params(), params, MAX_RUN_S, record=False, until_standstill=True,
                       monitor_stop_s=stop)
        out.append(Outcome(case, res.outcome, res.stop_margin_m, res.impact_speed, res.first_brake_s,
                           res.demand_changes))
    return out, time.perf_counter() - t0


def curves_only_table(table_bytes: bytes) -> bytes:
    """A table of the same model that never asks for braking: the supervision curves
    alone, the floor the issue asks for (a table can only raise the demand)."""
    from monitor.core.table import decode, encode

    t = decode(table_bytes)
    header = {k: v for k, v in t.header.items() if k not in ("nodes", "index_bytes", "format_version", "start")}
    header["solver"] = "none: maintain at every node (supervision curves alone)"
    return encode(header, [0], [[0] * len(t.observations)])


# ------------------------------------------------------------------ outside the declaration

DECEL_FACTORS = (1.0, 0.98, 0.96, 0.94, 0.92, 0.9, 0.85, 0.8, 0.7, 0.6)
BUILDUP_S = (1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.75, 2.0, 2.5, 3.0)


def hardest_world(values: dict) -> World:
    """The grid's hardest corner: guaranteed decelerations, all dead time, steepest
    downhill, pulling until the demand and traction held, speed reported low, normal
    conditions, the sensors at the error budget's corner."""
    bias, closing_bias = sensor_corner(apply(Config(), values))
    return World(declared_bands(values), float(values["service_decel"]), float(values["emergency_buildup_s"]), 0.0,
                 -float(values["max_downhill_gradient"]), float(values["traction_cutoff_s"]),
                 float(values["speed_error"]), float(values["max_accel"]), 0, 0,
                 float(values["slippery_factor"]), float(values["degraded_factor"]), pulling=True,
                 distance_bias=bias, closing_bias=closing_bias)


def beyond_cases(values: dict) -> dict:
    """{("decel", factor) | ("buildup", seconds): cases}: the hardest world made worse
    than declared in one way, the obstacle placed as in the grid (by the declaration's
    curves, which do not know the train is worse)."""
    cfg = apply(Config(), values)
    base = hardest_world(values)
    out = {}
    for f in DECEL_FACTORS:
        w = replace(base, bands=tuple((s, a * f) for s, a in base.bands), service_decel=base.service_decel * f)
        out[("decel", f)] = cases(cfg, [w])
    for t in BUILDUP_S:
        out[("buildup", t)] = cases(cfg, [replace(base, dead_s=t)])
    return out


def summary(outcomes) -> dict:
    """Runs, collisions, smallest stop margin (and its case) over outcomes."""
    safe = [o for o in outcomes if not o.collision]
    worst = min(outcomes, key=lambda o: o.signed_margin_m())
    return {"runs": len(outcomes), "collisions": len(outcomes) - len(safe),
            "min_margin_m": worst.signed_margin_m(), "worst": worst,
            "max_impact_mps": max((o.impact_speed for o in outcomes if o.collision), default=0.0)}


# ------------------------------------------------------------------ the docs figure and tables

def nominal_envelope() -> dict:
    """The old hard envelope as a declaration: nominal 3 m/s^2, 0.5 s, nothing else
    (issue 11's starting point); the grid must collide against it."""
    return {"emergency_decel": NOMINAL_DECEL, "service_decel": NOMINAL_SERVICE, "emergency_buildup_s": 0.5,
            "service_buildup_s": 0.5, "traction_cutoff_s": 0.0, "max_accel": 0.0, "speed_error": 0.0,
            "slippery_factor": 1.0, "degraded_factor": 1.0, "max_downhill_gradient": 0, "standstill_margin_m": 0.0}


def _worst_by_speed(outcomes) -> dict:
    """{speed: (smallest stop margin if no run at that speed collides else None, largest impact speed)}."""
    out = {}
    for v in sorted({o.case.speed for o in outcomes}):
        runs = [o for o in outcomes if o.case.speed == v]
        hit = [o.impact_speed for o in runs if o.collision]
        out[v] = (None if hit else min(o.stop_margin_m for o in runs), max(hit, default=0.0))
    return out


def figure(beyond: dict, path, decel0: float) -> None:
    """Stop margin (top) and impact speed (bottom) against the actual deceleration (left)
    and the brake dead time (right) beyond the declared values, one line per speed, the
    worst obstacle at each point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(13, 8), constrained_layout=True, sharex="col")
    panels = (("decel", 0, lambda f: decel0 * f,
               f"actual emergency deceleration below 30 m/s (m/s$^2$); declared {decel0:g} (above 30 m/s: the same factor)"),
              ("buildup", 1, lambda t: t, "actual brake dead time, no ramp (s); declared equivalent build-up 1 s"))
    for kind, col, xval, xlabel in panels:
        keys = sorted((k for k in beyond if k[0] == kind), key=lambda k: xval(k[1]))
        xs = [xval(k[1]) for k in keys]
        per = [_worst_by_speed(beyond[k]) for k in keys]
        top, bottom = axes[0][col], axes[1][col]
        for i, v in enumerate(SPEEDS_MPS):
            top.plot(xs, [float("nan") if p[v][0] is None else p[v][0] for p in per], "o-", color=f"C{i}", label=f"{v:g} m/s")
            bottom.plot(xs, [p[v][1] for p in per], "o-", color=f"C{i}", label=f"{v:g} m/s")
        for ax in (top, bottom):
            ax.axvline(xval(1.0), color="gray", ls="--", lw=1)
            ax.grid(alpha=0.3)
            ax.set_ylim(bottom=0)
        top.annotate("declared", (xval(1.0), 0.95), xycoords=("data", "axes fraction"), xytext=(4, 0),
                     textcoords="offset points", fontsize=8, color="gray")
        bottom.set_xlabel(xlabel, fontsize=9)
        if kind == "decel":
            bottom.invert_xaxis()
    axes[0][0].set_ylabel("smallest stop margin (m);\nthe line ends where a run collides")
    axes[1][0].set_ylabel("largest impact speed (m/s); 0: no collision")
    axes[0][0].legend(title="initial speed", fontsize=8)
    fig.suptitle("Outside the declaration: the grid's hardest corner (all dead time, 20 per mille downhill, traction "
                 "held 0.8 s, speed reported 2 % low) made worse in one way;\nworst of a static, a 5 m/s and a 10 m/s "
                 "oncoming obstacle, first seen where the declared curves say; emergency held to standstill", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def beyond_table(held: dict, revocable: dict) -> str:
    """Markdown: per setting, the collisions (emergency held to standstill, and revocable
    as shipped), the speeds they happen at, the smallest stop margin, the worst impact."""
    rows = ["| train worse than declared | collisions, held (of 12) | at speeds (m/s) "
            "| smallest stop margin of the runs that stop, held (m) | largest impact speed, held (m/s) "
            "| collisions, revocable (of 12) |", "|---|---|---|---|---|---|"]
    for key in sorted(held, key=lambda k: (k[0] != "decel", -k[1] if k[0] == "decel" else k[1])):
        outs = held[key]
        hit = sorted({o.case.speed for o in outs if o.collision})
        stops = [o.stop_margin_m for o in outs if not o.collision]
        what = f"emergency deceleration x {key[1]:g}" if key[0] == "decel" else f"dead time {key[1]:g} s"
        rows.append(f"| {what} | {sum(o.collision for o in outs)} | {', '.join(f'{v:g}' for v in hit) or '-'} | "
                    f"{f'{min(stops):.2f}' if stops else '-'} | "
                    f"{max((o.impact_speed for o in outs if o.collision), default=0.0):.2f} | "
                    f"{sum(o.collision for o in revocable[key])} |")
    return "\n".join(rows)


def _grid_line(name: str, outcomes, wall: float) -> str:
    s = summary(outcomes)
    w = s["worst"]
    worst = (f"smallest stop margin {s['min_margin_m']:.2f} m" if not s["collisions"]
             else f"impact up to {s['max_impact_mps']:.1f} m/s")
    return (f"{name}: {s['runs']} runs, {s['collisions']} collisions, {worst} ({w.case.world.label()}; "
            f"{w.case.speed:g} m/s, obstacle {w.case.obstacle_speed:g} m/s), {wall:.1f} s")


def main(argv=None) -> int:
    """Run the grid (and the declarations it must reject) and the sweep outside the
    declaration with the monitor FMU (built here) or, with --reference, its Python twin;
    write the figure and print the results and the Markdown table."""
    import argparse
    import tempfile
    from pathlib import Path

    from monitor.declaration import shipped
    from monitor.tables import read

    from . import build, cosim

    ap = argparse.ArgumentParser(prog="python -m fmu.acceptance", description=main.__doc__)
    ap.add_argument("--out", default="docs", help="folder for supervision_grid.png (default: docs)")
    ap.add_argument("--reference", action="store_true", help="use fmu.reference (the Python twin), not the monitor FMU")
    ap.add_argument("--tables", default="none,m1,m2",
                    help="policy tables to run the grid with: none (the curves alone), m1, m2 (default: %(default)s)")
    args = ap.parse_args(argv)
    values = shipped()
    params = monitor_params(values)
    grid = grid_cases(values)
    with tempfile.TemporaryDirectory(prefix="railguard-grid-") as tmp:
        train = build.build_train(tmp)
        for name in args.tables.split(","):
            table = curves_only_table(read("m1")) if name == "none" else read(name)
            monitor = cosim.ReferenceMonitor(table) if args.reference else build.build_monitor(table, 2, tmp, f"{name}.fmu")
            with cosim.Loop(monitor, train) as loop:
                outcomes, wall = run_cases(loop, params, grid)
                print(_grid_line(f"grid, table {name}", outcomes, wall), flush=True)
                if name != "none":
                    continue
                worst = summary(outcomes)["worst"].case
                example = loop.run(worst.train_params(), params, MAX_RUN_S, until_standstill=True)
                example.rows = [r for r in example.rows if r[0] >= APPROACH_S - 1.0]
                cosim.plot(example, Path(args.out) / "supervision_grid_example.png",
                           f"The grid's smallest stop margin: {worst.speed:g} m/s, obstacle {worst.obstacle_speed:g} m/s; "
                           f"{worst.world.label()}")
                for label, vals in (("nominal envelope (3 m/s^2, 0.5 s)", nominal_envelope()),
                                    ("guaranteed 3.0 m/s^2 declared", {**values, "emergency_decel": NOMINAL_DECEL})):
                    print(_grid_line(f"grid against {label}", *run_cases(loop, monitor_params(vals), grid)), flush=True)
                sweep = beyond_cases(values)
                held = {k: run_cases(loop, {**params, "emergency_release": 0}, v)[0] for k, v in sweep.items()}
                revocable = {k: run_cases(loop, params, v)[0] for k, v in sweep.items()}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    figure(held, out / "supervision_grid.png", declared_bands(values)[0][1])
    print(beyond_table(held, revocable))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
