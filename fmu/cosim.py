"""The closed loop in FMPy: the train-dynamics FMU and the monitor FMU, stepped by a master
loop over FMPy's slave classes.

The train FMU is stepped every `step_s` (10 ms by default); the monitor FMU every 100 ms,
its fixed cycle (a multi-rate master). At a monitor instant the master first hands the
train's sensor and speed outputs to the monitor and steps it, then hands its brake demand
to the train for the next 100 ms (Gauss-Seidel: the demand of the cycle at t acts from t,
as a monitor whose cycle ends well inside its period would). The hot loop calls the FMI
functions FMPy bound from the binaries, with value-reference arrays prepared once.
"""
from __future__ import annotations

import csv
import time
from dataclasses import dataclass
from pathlib import Path

from .driver import FmuCallError, Port, close_slave, do_step_function, initialize, open_slave, vr_of
from .variables import CHANNELS, MONITOR, TRAIN

MONITOR_PERIOD_S = 0.1


class CosimError(RuntimeError):
    """The co-simulation could not run; the message says which FMU call failed."""


@dataclass
class CosimResult:
    outcome: str
    margin_m: float | None
    steps: int
    monitor_cycles: int
    simulated_s: float
    wall_s: float
    rows: list
    columns: list
    first_brake_s: float | None
    max_demand: int

    @property
    def realtime_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else float("inf")


def run(monitor_fmu: str | Path, train_fmu: str | Path, train_params: dict, monitor_params: dict,
        duration_s: float, step_s: float = 0.01, record: bool = True) -> CosimResult:
    """Co-simulate and return the trace; raises CosimError if an FMU refuses a call. The
    monitor FMU may be FMI 2.0 or 3.0 (read from its model description)."""
    from fmpy.fmi1 import FMICallException

    ratio = round(MONITOR_PERIOD_S / step_s)
    if ratio < 1 or abs(ratio * step_s - MONITOR_PERIOD_S) > 1e-9:
        raise CosimError(f"step {step_s} s must divide the monitor's 0.1 s period")
    opened = []
    try:
        try:
            train = open_slave(train_fmu, "train")
            opened.append(train)
            monitor = open_slave(monitor_fmu, "monitor")
            opened.append(monitor)
            initialize(train[0], 2, TRAIN, train_params)
            initialize(monitor[0], monitor[1], MONITOR, monitor_params)
        except FMICallException as exc:
            raise CosimError(f"initialisation refused: {exc}") from None
        try:
            return _loop(train[0], monitor[0], monitor[1], train_params, duration_s, step_s, ratio, record)
        except FmuCallError as exc:
            raise CosimError(str(exc)) from None
    finally:
        for slave, _, unzip in opened:
            close_slave(slave, unzip)


# the signals handed from the train to the monitor, per type, in matching order
_LINK_REAL = [f"ch{i}.{f}" for i in range(1, CHANNELS + 1) for f in ("distance", "closing_speed")] + ["train.speed"]
_LINK_INT = ([f"ch{i}.{f}" for i in range(1, CHANNELS + 1) for f in ("status", "type")]
             + ["train.track_condition", "train.brake_status"])
_LINK_BOOL = [f"ch{i}.valid" for i in range(1, CHANNELS + 1)]
TRAIN_TRACE_REAL = ["train.speed", "position", "acceleration", "true_distance"]
TRAIN_TRACE_INT = ["brake_level"]
MONITOR_TRACE = ["brake_demand", "reasons", "voted_distance_dm", "node", "mode", "module_flags", "observation",
                 "cycle", "error_cycles"]


def _loop(train, monitor, mfmi: int, train_params: dict, duration_s: float, step_s: float, ratio: int,
          record: bool) -> CosimResult:
    t_vr = lambda names: [vr_of(TRAIN, n) for n in names]  # noqa: E731
    m_vr = lambda names: [vr_of(MONITOR, n) for n in names]  # noqa: E731
    links = [(Port(train, 2, kind, t_vr(names), "get"), Port(monitor, mfmi, kind, m_vr(names), "set"))
             for kind, names in (("Real", _LINK_REAL), ("Integer", _LINK_INT), ("Boolean", _LINK_BOOL))]
    m_out = Port(monitor, mfmi, "Integer", m_vr(MONITOR_TRACE), "get")
    t_in = Port(train, 2, "Integer", t_vr(["brake_demand"]), "set")
    t_real = Port(train, 2, "Real", t_vr(TRAIN_TRACE_REAL), "get")
    t_int = Port(train, 2, "Integer", t_vr(TRAIN_TRACE_INT), "get")
    t_collided = Port(train, 2, "Boolean", t_vr(["collided"]), "get")
    do_train = do_step_function(train, 2)
    do_monitor = do_step_function(monitor, mfmi)
    n_steps = int(round(duration_s / step_s))
    m_steps = 0
    train_rows = []           # per train step: the train's Real and Integer outputs
    monitor_rows = []         # per monitor cycle: the monitor's outputs
    first_brake = None
    max_demand = 0
    demand_index = MONITOR_TRACE.index("brake_demand")
    real_values, int_values = t_real.values, t_int.values
    get_real, get_int, append = t_real.call, t_int.call, train_rows.append
    t0 = time.perf_counter()
    for k in range(n_steps):
        t = k * step_s
        if k % ratio == 0:
            for src, dst in links:
                src.call()
                dst.copy_from(src)
                dst.call()
            if do_monitor(t, MONITOR_PERIOD_S) > 1:
                raise CosimError(f"monitor doStep at t = {t:.2f} s failed")
            m_steps += 1
            m_out.call()
            outs = m_out.values[:]
            monitor_rows.append(outs)
            demand = outs[demand_index]
            t_in.values[0] = demand
            t_in.call()
            if demand > max_demand:
                max_demand = demand
            if demand and first_brake is None:
                first_brake = round(t, 6)
        if do_train(t, step_s) > 1:
            raise CosimError(f"train doStep at t = {t:.2f} s failed")
        if record:
            get_real()
            get_int()
            append(real_values[:] + int_values[:])
    wall = time.perf_counter() - t0
    t_real.call()
    t_collided.call()
    speed, _, _, distance = t_real.values
    present = bool(train_params.get("obstacle.present", True))
    if t_collided.values[0]:
        outcome, margin = "collision", 0.0
    elif not present:
        outcome, margin = "no_obstacle", None
    elif speed == 0.0:
        outcome, margin = "stopped", float(distance)
    else:
        outcome, margin = "running", float(distance)
    columns = ["time_s", *TRAIN_TRACE_REAL, *TRAIN_TRACE_INT, *MONITOR_TRACE]
    rows = [(round((k + 1) * step_s, 6), *train_rows[k], *monitor_rows[k // ratio]) for k in range(len(train_rows))]
    return CosimResult(outcome, margin, n_steps, m_steps, n_steps * step_s, wall, rows, columns, first_brake, max_demand)


def write_csv(result: CosimResult, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(result.columns)
        w.writerows(result.rows)
    return path


def plot(result: CosimResult, path: Path, title: str) -> Path:
    from can_bus.plot import plot_run

    c = {name: i for i, name in enumerate(result.columns)}
    t = [r[0] for r in result.rows]
    dist = [r[c["true_distance"]] if r[c["true_distance"]] < 1e8 else None for r in result.rows]
    voted = [None if r[c["voted_distance_dm"]] == 65535 else r[c["voted_distance_dm"]] / 10 for r in result.rows]
    return plot_run(path, title, t, [r[c["train.speed"]] for r in result.rows], dist, voted,
                    [r[c["brake_demand"]] for r in result.rows], [r[c["mode"]] for r in result.rows])
