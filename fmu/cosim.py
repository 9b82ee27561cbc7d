"""The closed loop in FMPy: the train-dynamics FMU and the monitor FMU, stepped by a master
loop over FMPy's slave classes.

The train FMU is stepped every `step_s` (10 ms by default); the monitor FMU every 100 ms,
its fixed cycle (a multi-rate master). At a monitor instant the master first hands the
train's sensor and speed outputs to the monitor and steps it. The brake demand reaches
the train `demand_delay_cycles` monitor cycles later (default 1: the demand of the cycle
at t acts from t + 100 ms, as it does on CAN, where the train reads the BrakeDemand frame
the monitor sent in the previous period); 0 gives the Gauss-Seidel loop where it acts at
once. The hot loop calls the FMI functions FMPy bound from the binaries, with
value-reference arrays prepared once.

`Loop` keeps both FMUs open for many runs (a grid); the monitor may also be
`ReferenceMonitor`, the Python twin of the monitor FMU (fmu.reference).
"""
from __future__ import annotations

import csv
import math
import shutil
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from monitor.core.types import EMERGENCY
from monitor.risk_summary import RiskTally, risk_columns

from .driver import FmuCallError, Port, close_slave, do_step_function, initialize, open_slave, vr_of
from .variables import CHANNELS, MONITOR, MONITOR_OUTPUTS, TRAIN

MONITOR_PERIOD_S = 0.1
NO_GAP_M = 1e8          # true_distance at least this: no obstacle on the track (the train FMU gives 1e9)
DEMAND_DELAY_CYCLES = 1


class CosimError(RuntimeError):
    """The co-simulation could not run; the message says which FMU call failed."""


@dataclass
class CosimResult:
    outcome: str          # collision, struck_at_standstill, stopped, running, no_obstacle (margin None
                          # when stopped or running after the obstacle left the track)
    margin_m: float | None
    steps: int
    monitor_cycles: int
    simulated_s: float
    wall_s: float
    rows: list
    columns: list
    first_brake_s: float | None
    max_demand: int
    stop_margin_m: float | None = None    # distance to the obstacle when the train first stood
    impact_speed: float = 0.0             # our speed at the contact (0: none, or we stood)
    train_params: dict = field(default_factory=dict)
    monitor_params: dict = field(default_factory=dict)
    demand_delay_cycles: int = DEMAND_DELAY_CYCLES
    demand_changes: int = 0               # changes of the monitor's demand from its first brake demand on
    receiver_brake: bool = False          # the train's brake receiver braked on the monitor's stopped alive counter
    first_emergency_s: float | None = None   # the monitor's first emergency demand (its cycle's time)

    @property
    def realtime_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else float("inf")

    @property
    def collision(self) -> bool:
        """Contact while our train moved: what the supervision must prevent."""
        return self.outcome == "collision"


def run(monitor_fmu, train_fmu: str | Path, train_params: dict, monitor_params: dict,
        duration_s: float, step_s: float = 0.01, record: bool = True, *,
        demand_delay_cycles: int = DEMAND_DELAY_CYCLES, until_standstill: bool = False,
        monitor_stop_s: float = math.inf) -> CosimResult:
    """Co-simulate and return the trace; raises CosimError if an FMU refuses a call. The
    monitor may be an FMU path (FMI 2.0 or 3.0, read from its model description) or a
    ReferenceMonitor."""
    _check(step_s, demand_delay_cycles)
    with Loop(monitor_fmu, train_fmu) as loop:
        return loop.run(train_params, monitor_params, duration_s, step_s, record,
                        demand_delay_cycles=demand_delay_cycles, until_standstill=until_standstill,
                        monitor_stop_s=monitor_stop_s)


def run_scenario(scen, monitor_fmu, train_fmu: str | Path, step_s: float = 0.01,
                 demand_delay_cycles: int | None = None, record: bool = True) -> CosimResult:
    """A fmu.scenario.CosimScenario: its parameters, duration and demand delay (unless
    `demand_delay_cycles` overrides it, as the CLI's --demand-delay does)."""
    delay = scen.demand_delay_cycles if demand_delay_cycles is None else demand_delay_cycles
    return run(monitor_fmu, train_fmu, scen.train, scen.monitor, scen.duration_s, step_s, record,
               demand_delay_cycles=delay, monitor_stop_s=scen.monitor_stop_s)


def _check(step_s: float, delay: int) -> int:
    """The train steps per monitor cycle; CosimError if the step or the delay cannot be run."""
    ratio = round(MONITOR_PERIOD_S / step_s)
    if ratio < 1 or abs(ratio * step_s - MONITOR_PERIOD_S) > 1e-9:
        raise CosimError(f"step {step_s} s must divide the monitor's 0.1 s period")
    if isinstance(delay, bool) or not isinstance(delay, int) or not 0 <= delay <= 50:
        raise CosimError(f"demand delay {delay!r}: must be 0..50 monitor cycles")
    return ratio


# the signals handed from the train to the monitor, per type, in matching order
_LINK_REAL = [f"ch{i}.{f}" for i in range(1, CHANNELS + 1) for f in ("distance", "closing_speed")] + ["train.speed"]
_LINK_INT = ([f"ch{i}.{f}" for i in range(1, CHANNELS + 1) for f in ("status", "type")]
             + ["train.track_condition", "train.brake_status"])
_LINK_BOOL = [f"ch{i}.valid" for i in range(1, CHANNELS + 1)]
TRAIN_TRACE_REAL = ["true_speed", "train.speed", "position", "acceleration", "true_distance", "brake_decel"]
TRAIN_TRACE_INT = ["brake_level"]
_OUTPUT_NAMES = [v.name for v in MONITOR_OUTPUTS]
MONITOR_TRACE = ["brake_demand", "reasons", "voted_distance_dm", "node", "mode", "module_flags", "observation", "cycle",
                 "error_cycles", "r1_ppm", "r2_ppm", "risk_score", "risk_category", "table_risk_ppm",
                 "warning"]      # the Integer outputs, then the one Boolean
CYCLE_FIELD = MONITOR_TRACE.index("cycle")   # the monitor's alive counter, handed to the train with the demand


class FmuMonitor:
    """The monitor FMU, opened once; `start` (re)initialises it with parameters."""

    def __init__(self, path: str | Path):
        self.slave, self.fmi, self.unzip = open_slave(path, "monitor")
        m_vr = lambda names: [vr_of(MONITOR, n) for n in names]  # noqa: E731
        self.inputs = [Port(self.slave, self.fmi, kind, m_vr(names), "set")
                       for kind, names in (("Real", _LINK_REAL), ("Integer", _LINK_INT), ("Boolean", _LINK_BOOL))]
        self.int_out = Port(self.slave, self.fmi, "Integer", m_vr(MONITOR_TRACE[:-1]), "get")
        self.warn_out = Port(self.slave, self.fmi, "Boolean", m_vr(MONITOR_TRACE[-1:]), "get")
        self._step = do_step_function(self.slave, self.fmi)
        self.started = False

    def start(self, params: dict) -> None:
        if self.started:
            self.slave.reset()
        initialize(self.slave, self.fmi, MONITOR, params)
        self.started = True

    def cycle(self, t: float, train_ports) -> list:
        """Hand the train's link outputs over, run one cycle, return MONITOR_TRACE values."""
        for dst, src in zip(self.inputs, train_ports):
            dst.copy_from(src)
            dst.call()
        if self._step(t, MONITOR_PERIOD_S) > 1:
            raise CosimError(f"monitor doStep at t = {t:.2f} s failed")
        self.int_out.call()
        self.warn_out.call()
        return self.int_out.values[:] + [int(bool(self.warn_out.values[0]))]

    def close(self) -> None:
        _close(self.slave, self.unzip, self.started)


def _close(slave, unzip, started: bool) -> None:
    """Free an FMU; terminate it first only if it was initialised (FMI forbids it before)."""
    if started:
        close_slave(slave, unzip)
    else:
        try:
            slave.freeInstance()
        finally:
            shutil.rmtree(unzip, ignore_errors=True)


class ReferenceMonitor:
    """fmu.reference.MonitorReference (the Python twin of the monitor FMU) behind the same
    interface as FmuMonitor: the same loop without the monitor FMU."""

    def __init__(self, table_bytes: bytes):
        self.table = table_bytes
        self.ref = None
        self._fields = [_OUTPUT_NAMES.index(n) for n in MONITOR_TRACE]

    def start(self, params: dict) -> None:
        from .reference import MonitorReference

        try:
            self.ref = MonitorReference(self.table, params)
        except (ValueError, TypeError) as exc:         # ConfigurationError, unknown names
            raise CosimError(f"initialisation refused: {exc}") from None

    def cycle(self, t: float, train_ports) -> list:
        from .reference import ChannelInput, StepInput

        real, ints, bools = (p.values for p in train_ports)
        chans = tuple(ChannelInput(ints[2 * i], real[2 * i], real[2 * i + 1], ints[2 * i + 1], bool(bools[i]))
                      for i in range(CHANNELS))
        out = self.ref.step(StepInput(chans, real[2 * CHANNELS], ints[2 * CHANNELS], ints[2 * CHANNELS + 1]))[0]
        return [int(out[i]) for i in self._fields]

    def close(self) -> None:
        self.ref = None


class Loop:
    """The train FMU and a monitor, opened once and run as often as wanted (each run
    re-initialises both: fmiReset on the FMUs)."""

    def __init__(self, monitor, train_fmu: str | Path):
        from fmpy.fmi1 import FMICallException

        self.monitor = None
        self.train = None
        try:
            self.train = open_slave(train_fmu, "train")
            self.monitor = FmuMonitor(monitor) if isinstance(monitor, (str, Path)) else monitor
        except FMICallException as exc:
            self.close()
            raise CosimError(f"cannot open an FMU: {exc}") from None
        slave = self.train[0]
        t_vr = lambda names: [vr_of(TRAIN, n) for n in names]  # noqa: E731
        self.links = [Port(slave, 2, kind, t_vr(names), "get")
                      for kind, names in (("Real", _LINK_REAL), ("Integer", _LINK_INT), ("Boolean", _LINK_BOOL))]
        self.t_in = Port(slave, 2, "Integer", t_vr(["brake_demand", "monitor_cycle"]), "set")
        self.t_real = Port(slave, 2, "Real", t_vr(TRAIN_TRACE_REAL), "get")
        self.t_int = Port(slave, 2, "Integer", t_vr(TRAIN_TRACE_INT), "get")
        self.t_end = Port(slave, 2, "Real", t_vr(["impact_speed"]), "get")
        self.t_collided = Port(slave, 2, "Boolean", t_vr(["collided", "receiver_brake"]), "get")
        self.do_train = do_step_function(slave, 2)
        self.runs = 0

    def __enter__(self) -> "Loop":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self.train is not None:
            _close(self.train[0], self.train[2], self.runs > 0)
            self.train = None
        if self.monitor is not None:
            self.monitor.close()
            self.monitor = None

    def start(self, train_params: dict, monitor_params: dict) -> None:
        from fmpy.fmi1 import FMICallException

        try:
            if self.runs:
                self.train[0].reset()
            initialize(self.train[0], 2, TRAIN, train_params)
            self.monitor.start(monitor_params)
        except FMICallException as exc:
            raise CosimError(f"initialisation refused: {exc}") from None
        except KeyError as exc:            # a parameter the FMU does not have
            raise CosimError(f"initialisation refused: {exc.args[0]}") from None
        self.runs += 1

    def run(self, train_params: dict, monitor_params: dict, duration_s: float, step_s: float = 0.01,
            record: bool = True, *, demand_delay_cycles: int = DEMAND_DELAY_CYCLES,
            until_standstill: bool = False, monitor_stop_s: float = math.inf) -> CosimResult:
        """One run from t = 0. With `until_standstill` it ends when the train first stands
        after moving (or collides): enough to know the stop margin. From `monitor_stop_s` on
        the monitor is no longer stepped (a monitor FMU that froze or crashed): its demand and
        its alive counter stay as they were, and the train's brake receiver must notice."""
        ratio = _check(step_s, demand_delay_cycles)
        self.start(train_params, monitor_params)
        try:
            res = self._loop(duration_s, step_s, ratio, record, demand_delay_cycles, until_standstill,
                             bool(train_params.get("obstacle.present", True)), monitor_stop_s)
        except FmuCallError as exc:
            raise CosimError(str(exc)) from None
        res.train_params, res.monitor_params = dict(train_params), dict(monitor_params)
        res.demand_delay_cycles = demand_delay_cycles
        return res

    def _loop(self, duration_s: float, step_s: float, ratio: int, record: bool, delay: int,
              until_standstill: bool, obstacle: bool, monitor_stop_s: float = math.inf) -> CosimResult:
        links, monitor, t_in = self.links, self.monitor, self.t_in
        do_train = self.do_train
        n_steps = int(round(duration_s / step_s))
        pending: deque = deque()      # demands computed but not yet delivered to the train
        train_rows, monitor_rows, delivered = [], [], []
        first_brake = first_emergency = stop_margin = None
        max_demand = changes = last = 0
        real_values, int_values = self.t_real.values, self.t_int.values
        get_real, get_int = self.t_real.call, self.t_int.call
        speed_i, dist_i = TRAIN_TRACE_REAL.index("true_speed"), TRAIN_TRACE_REAL.index("true_distance")
        moved = receiver_brake = False
        k = 0
        t0 = time.perf_counter()
        for k in range(n_steps):
            t = k * step_s
            if k % ratio == 0:
                if t < monitor_stop_s - 1e-9 or not monitor_rows:
                    for src in links:
                        src.call()
                    outs = monitor.cycle(t, links)
                # else: the monitor no longer runs (the scenario's monitor_stop): its outputs freeze
                monitor_rows.append(outs)
                demand = outs[0]
                frame = (demand, outs[CYCLE_FIELD])        # the demand travels with the alive counter
                if not pending:
                    pending.extend([frame] * delay)    # before the first demand arrives: the first one
                pending.append(frame)
                t_in.values[0], t_in.values[1] = pending.popleft()
                t_in.call()
                delivered.append(t_in.values[0])
                if demand > max_demand:
                    max_demand = demand
                if demand and first_brake is None:
                    first_brake = round(t, 6)
                if demand == EMERGENCY and first_emergency is None:
                    first_emergency = round(t, 6)
                if demand != last and first_brake is not None:
                    changes += 1
                last = demand
            if do_train(t, step_s) > 1:
                raise CosimError(f"train doStep at t = {t:.2f} s failed")
            get_real()
            if record:
                get_int()
                train_rows.append(real_values[:] + int_values[:])
            if k % ratio == 0 and not receiver_brake:
                self.t_collided.call()
                receiver_brake = bool(self.t_collided.values[1])
            speed = real_values[speed_i]
            if speed > 0.0:
                moved = True
            elif moved and stop_margin is None:
                stop_margin = float(real_values[dist_i])
                if until_standstill:
                    break
        steps = k + 1 if n_steps else 0
        wall = time.perf_counter() - t0
        self.t_real.call()
        self.t_end.call()
        self.t_collided.call()
        speed, distance = self.t_real.values[speed_i], self.t_real.values[dist_i]
        if stop_margin is not None and stop_margin >= NO_GAP_M:
            stop_margin = None                     # it stood with no obstacle on the track
        impact = float(self.t_end.values[0])
        if self.t_collided.values[0]:
            outcome, margin = ("collision" if impact > 0.0 else "struck_at_standstill"), 0.0
            stop_margin = None if impact > 0.0 else stop_margin
        elif not obstacle:
            outcome, margin = "no_obstacle", None
        else:
            gap = float(distance) if distance < NO_GAP_M else None      # None: it has left the track
            outcome, margin = ("stopped" if speed == 0.0 else "running"), gap
        columns = ["time_s", *TRAIN_TRACE_REAL, *TRAIN_TRACE_INT, "demand_in", *MONITOR_TRACE]
        rows = [(round((i + 1) * step_s, 6), *train_rows[i], delivered[i // ratio], *monitor_rows[i // ratio])
                for i in range(len(train_rows))]
        return CosimResult(outcome, margin, steps, len(monitor_rows), steps * step_s, wall, rows, columns,
                           first_brake, max_demand, stop_margin, impact, demand_changes=changes,
                           receiver_brake=receiver_brake or bool(self.t_collided.values[1]),
                           first_emergency_s=first_emergency)


def write_csv(result: CosimResult, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(result.columns)
        w.writerows(result.rows)
    return path


def speed_distance(result: CosimResult):
    """The run's speed-distance picture (monitor.plot.SpeedDistance): the curves for its
    obstacle under the monitor's configuration and the train's reported conditions."""
    from monitor.plot import SpeedDistance

    from .reference import config_from_parameters

    c = {name: i for i, name in enumerate(result.columns)}
    tp = result.train_params
    obstacle = bool(tp.get("obstacle.present", True))
    rows = [r for r in result.rows if r[c["true_distance"]] < NO_GAP_M] if obstacle else result.rows
    return SpeedDistance(
        config=config_from_parameters(result.monitor_params),
        distance_m=[r[c["true_distance"]] for r in rows] if obstacle else None,
        position_m=[r[c["position"]] for r in rows],
        speed_mps=[r[c["true_speed"]] for r in rows],
        demand=[r[c["brake_demand"]] for r in rows], warning=[bool(r[c["warning"]]) for r in rows],
        obstacle_speed_mps=float(tp.get("obstacle.speed", 0.0)),
        track=int(tp.get("track_condition", 0)), brake=int(tp.get("brake_status", 0)),
        visible_m=float(tp.get("sensor.range", 400.0)) if obstacle else None)


def plot(result: CosimResult, path: Path, title: str) -> Path:
    from monitor.plot import plot_run

    c = {name: i for i, name in enumerate(result.columns)}
    t = [r[0] for r in result.rows]
    dist = [r[c["true_distance"]] if r[c["true_distance"]] < NO_GAP_M else None for r in result.rows]
    voted = [None if r[c["voted_distance_dm"]] == 65535 else r[c["voted_distance_dm"]] / 10 for r in result.rows]
    return plot_run(path, title, t, [r[c["true_speed"]] for r in result.rows], dist, voted,
                    [r[c["brake_demand"]] for r in result.rows], [r[c["mode"]] for r in result.rows],
                    speed_distance=speed_distance(result), risk=risk_of(result))


def risk_summary(result: CosimResult) -> dict:
    """The run's risk as `railguard run` and `replay` summarise it (monitor.risk_summary):
    peaks, and the time in each seed 001 category (rows are communication steps)."""
    c = {name: i for i, name in enumerate(result.columns)}
    tally = RiskTally(round(1000 * result.simulated_s / len(result.rows)) if result.rows else 0)
    for r in result.rows:
        tally.add_values(*(int(r[c[key]]) for key in ("r1_ppm", "r2_ppm", "table_risk_ppm", "risk_category")))
    return tally.as_dict()


def risk_of(result: CosimResult) -> dict:
    """monitor.plot.draw_risk's columns from the monitor FMU's risk outputs."""
    c = {name: i for i, name in enumerate(result.columns)}
    return risk_columns(*([r[c[key]] for r in result.rows] for key in ("r1_ppm", "r2_ppm", "table_risk_ppm",
                                                                        "risk_category")))["risk"]
