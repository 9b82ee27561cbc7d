"""Any communication step (issue 15): the monitor and train FMUs, built by the project's
builder (conftest fixtures) and loaded by FMPy, accept steps that are not whole multiples
of their fixed step, and give the same results as at their own step.

Monitor: a sampled controller. Cycle k runs at k x 100 ms with the inputs as set before the
step that contains that instant ([t, t + h) contains its start); the outputs at time t are
those of the last cycle before t, so with any steps they must equal, at every
communication point t, the outputs of a 100 ms run at ceil(t / 100 ms) x 100 ms.

Train: the state lives on the 10 ms grid, brake_demand is sampled at the grid instants,
and between grid instants the outputs are the state integrated over the part of the step
(docs/train_fmu.md, "Communication steps"). So on the grid the outputs are bit for bit
those of a 10 ms run; off the grid they lie within what one internal step can change of
the straight line between the two grid states.
"""
from __future__ import annotations

import math
import random

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException

from fmu import cosim
from fmu.driver import close_slave, initialize, open_slave, vr_of
from fmu.scenario import CosimScenario
from fmu.variables import CHANNELS, MONITOR, MONITOR_OUTPUTS, TRAIN

NS = 1_000_000_000
CYCLE_NS = 100_000_000      # the monitor's period
GRID_NS = 10_000_000        # the train's internal step
ERROR = 3                   # fmi2Error == fmi3Error


class Slave:
    """One FMU through FMPy, addressed by variable name; the master's time is kept in
    integer ns so that the communication points are exact."""

    def __init__(self, path, variables, params: dict | None = None, name: str = "steps"):
        self.variables = variables
        self.slave, self.fmi, self.unzip = open_slave(path, name)
        initialize(self.slave, self.fmi, variables, params or {})
        self.t_ns = 0

    def _fn(self, direction: str, kind: str):
        if self.fmi == 3:
            kind = {"Real": "Float64", "Integer": "Int32"}.get(kind, kind)
        return getattr(self.slave, direction + kind)

    def get(self, name: str):
        vr = vr_of(self.variables, name)
        value = self._fn("get", self.variables[vr].type)([vr])[0]
        return bool(value) if self.variables[vr].type == "Boolean" else value

    def set(self, name: str, value) -> None:
        vr = vr_of(self.variables, name)
        self._fn("set", self.variables[vr].type)([vr], [value])

    def step_to(self, end_ns: int) -> None:
        self.slave.doStep(self.t_ns / NS, (end_ns - self.t_ns) / NS)
        self.t_ns = end_ns

    def time(self) -> float:
        return self._fn("get", "Real")([0])[0]

    def close(self) -> None:
        close_slave(self.slave, self.unzip)


def points(step_ns, end_ns: int, extra=()) -> list[int]:
    """Communication points from 0 to end_ns: every `step_ns` (an int, or a list of step
    lengths used in turn) plus the `extra` instants, as FMPy lands on input changes."""
    pts, t, i = {0, end_ns, *[e for e in extra if 0 < e < end_ns]}, 0, 0
    while t < end_ns:
        t += step_ns if isinstance(step_ns, int) else step_ns[i % len(step_ns)]
        i += 1
        if t < end_ns:
            pts.add(t)
    return sorted(pts)


def ceil_div(a: int, b: int) -> int:
    return -(-a // b)


# ---- the monitor -----------------------------------------------------------------------------

MONITOR_NAMES = [v.name for v in MONITOR_OUTPUTS]


def monitor_script(seed: int, end_ns: int) -> list[tuple[int, dict]]:
    """Scripted monitor inputs: (time in ns, values set from then on). Changes fall on and
    between cycle instants (0.35 s among them): an obstacle approaching, a channel that
    goes stale and one that disputes, the speed, the track condition."""
    rng = random.Random(seed)
    base = {"train.speed": 20.0}
    for c in range(1, CHANNELS + 1):
        base.update({f"ch{c}.status": 0, f"ch{c}.distance": 0.0, f"ch{c}.closing_speed": 0.0,
                     f"ch{c}.type": 0, f"ch{c}.valid": True})
    events = [(0, dict(base))]
    times = sorted({350_000_000, 100_000_000, 1_000_000_000}
                   | {rng.randrange(1, end_ns // 1_000_000) * 1_000_000 for _ in range(30)})
    distance = 260.0
    for k, t in enumerate(times):
        distance = max(5.0, distance - rng.uniform(2.0, 25.0))
        values = {}
        for c in range(1, CHANNELS + 1):
            seen = distance <= 250.0
            values.update({f"ch{c}.status": 1 if seen else 0, f"ch{c}.distance": distance if seen else 0.0,
                           f"ch{c}.closing_speed": 18.5 if seen else 0.0, f"ch{c}.type": 0, f"ch{c}.valid": True})
        if k % 7 == 3:
            values["ch3.valid"] = False            # stale: keeps its last report, ages
        if k % 5 == 2:
            values["ch5.distance"] = distance + 40.0   # disputes the obstacle
        values["train.speed"] = rng.choice([20.0, 19.5, 0.0 if k > 25 else 18.0])
        values["train.track_condition"] = 1 if k % 9 == 4 else 0
        events.append((t, values))
    return events


def inputs_at(events, t_ns: int) -> dict:
    values = {}
    for t, v in events:
        if t <= t_ns:
            values.update(v)
    return values


def run_monitor(path, events, pts: list[int]) -> list[tuple[int, tuple]]:
    """Step the monitor through the communication points `pts`, setting at each point the
    inputs in effect there; (t_ns, outputs) after every step."""
    fmu = Slave(path, MONITOR)
    try:
        rows = [(0, tuple(fmu.get(n) for n in MONITOR_NAMES))]
        for t0, t1 in zip(pts, pts[1:]):
            for name, value in inputs_at(events, t0).items():
                fmu.set(name, value)
            fmu.step_to(t1)
            assert fmu.time() == pytest.approx(t1 / NS, abs=1e-12)
            rows.append((t1, tuple(fmu.get(n) for n in MONITOR_NAMES)))
        return rows
    finally:
        fmu.close()


STEPS = {"10ms": 10_000_000, "0.25s": 250_000_000, "0.037s": 37_000_000, "1ms": 1_000_000, "random": None}


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("case", list(STEPS))
def test_monitor_gives_the_100ms_outputs_at_any_step(case, fmi, monitor_fmus):
    """At every communication point t the outputs equal those of the 100 ms run at the
    next cycle instant at or after t: the same at the cycle instants, held in between; an
    input changed between two cycles is sampled at the next cycle instant."""
    path = monitor_fmus[("m1", fmi)]
    end_ns = 1_500_000_000 if case == "1ms" else 6_000_000_000
    events = monitor_script(15, end_ns)
    change_times = [t for t, _ in events]
    reference = dict(run_monitor(path, events, points(CYCLE_NS, end_ns)))
    if case == "random":
        rng = random.Random(2024)
        step = [rng.randrange(1_000_000, 180_000_000) for _ in range(97)]   # 1 ms .. 180 ms, in ns
    else:
        step = STEPS[case]
    # like FMPy, the master lands on every input change
    rows = run_monitor(path, events, points(step, end_ns, change_times))
    assert len(rows) > end_ns // max(step if isinstance(step, int) else min(step), CYCLE_NS)
    off_grid = 0
    for t, outputs in rows:
        k = ceil_div(t, CYCLE_NS)
        assert outputs == reference[k * CYCLE_NS], (case, t, k)
        off_grid += t % CYCLE_NS != 0
    assert off_grid > 0
    # the scenario is not trivial: it brakes, and the stale/disputing channels show
    demands = {out[MONITOR_NAMES.index("brake_demand")] for out in reference.values()}
    assert len(demands) >= 2


@pytest.mark.parametrize("fmi", [2, 3])
def test_an_input_set_between_cycles_is_sampled_at_the_next_cycle(fmi, monitor_fmus):
    """ch1..6 report an obstacle at 0.35 s (between cycles 3 and 4): cycle 3 (at 0.3 s)
    does not see it, cycle 4 (at 0.4 s) does; with 50 ms steps the outputs after 0.4 s
    and after 0.45 s are the same (they hold)."""
    fmu = Slave(monitor_fmus[("m1", fmi)], MONITOR)
    try:
        fmu.set("train.speed", 20.0)
        for c in range(1, CHANNELS + 1):
            fmu.set(f"ch{c}.valid", True)
        voted = []
        for k in range(12):
            t = k * 50_000_000
            if t == 350_000_000:
                for c in range(1, CHANNELS + 1):
                    fmu.set(f"ch{c}.status", 1)
                    fmu.set(f"ch{c}.distance", 150.0)
            fmu.step_to(t + 50_000_000)
            voted.append((fmu.t_ns, fmu.get("voted_distance_dm"), fmu.get("cycle")))
        by_time = {t: (d, c) for t, d, c in voted}
        assert by_time[400_000_000][0] == by_time[350_000_000][0] != 1500   # cycle 3 saw no obstacle
        assert by_time[450_000_000][0] == 1500 == by_time[500_000_000][0]   # cycle 4 at 0.4 s did
        assert by_time[400_000_000][1] == by_time[350_000_000][1]           # nothing ran in [0.35, 0.4)
    finally:
        fmu.close()


@pytest.mark.parametrize("fmi", [2, 3])
def test_a_step_of_50ms_is_accepted(fmi, monitor_fmus):
    """Refused before issue 15: a 0.05 s step (and 0.15 s) now runs the cycles inside it."""
    fmu = Slave(monitor_fmus[("m1", fmi)], MONITOR)
    try:
        fmu.step_to(100_000_000)
        cycle = fmu.get("cycle")
        fmu.slave.doStep(0.1, 0.05)          # [0.1, 0.15): the cycle at 0.1 s
        fmu.t_ns = 150_000_000
        assert fmu.get("cycle") == cycle + 1
        fmu.slave.doStep(0.15, 0.15)         # [0.15, 0.3): the cycle at 0.2 s
        fmu.t_ns = 300_000_000
        assert fmu.get("cycle") == cycle + 2
        assert fmu.time() == 0.3
    finally:
        fmu.close()


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("h", [0.0, -0.1, math.nan])
def test_a_step_that_is_not_positive_is_still_refused(h, fmi, monitor_fmus):
    """FMI 2.0 and 3.0 both require communicationStepSize > 0.0."""
    fmu = Slave(monitor_fmus[("m1", fmi)], MONITOR)
    try:
        fmu.step_to(100_000_000)
        with pytest.raises(FMICallException) as exc:
            fmu.slave.doStep(0.1, h)
        assert exc.value.status == ERROR
    finally:
        fmu.close()


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_simulate_lands_on_a_stop_time_off_the_grid(fmi, monitor_fmus):
    """fmusim's `--stop-time 10.05 --output-interval 0.1` case through FMPy: the last step
    is 50 ms (shortened to the stop time) and accepted; it runs the cycle at 10.0 s."""
    res = simulate_fmu(str(monitor_fmus[("m1", fmi)]), output_interval=0.1, stop_time=10.05,
                       output=["cycle", "brake_demand"])
    assert res["time"][-1] == pytest.approx(10.05)
    assert res["time"][-2] == pytest.approx(10.0)
    # cycle k runs at k x 0.1 s: 100 cycles (0 .. 9.9 s) before 10.0 s, the 101st in the last step
    cycles = res["cycle"]
    assert cycles[-1] == cycles[-2] + 1
    assert list(np.diff(cycles[:-1])) == [1] * (len(cycles) - 2)


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmpy_input_event_between_cycles(fmi, monitor_fmus):
    """FMPy shortens a step to land on an input change (0.35 s here); the change is sampled
    at the cycle at 0.4 s, as in a 100 ms run that sets it at 0.4 s."""
    names = [f"ch{c}.{f}" for c in range(1, CHANNELS + 1) for f in ("status", "valid")]
    dtype = [("time", np.float64)] + [(n, np.int32 if n.endswith("status") else np.bool_) for n in names]
    signal = np.array([(0.0, *([0, True] * CHANNELS)), (0.35, *([1, True] * CHANNELS))], dtype=dtype)
    shifted = signal.copy()
    shifted["time"][1] = 0.4
    path = str(monitor_fmus[("m1", fmi)])
    a = simulate_fmu(path, output_interval=0.1, stop_time=1.0, input=signal, output=MONITOR_NAMES)
    b = simulate_fmu(path, output_interval=0.1, stop_time=1.0, input=shifted, output=MONITOR_NAMES)
    assert any(abs(t - 0.35) < 1e-9 for t in a["time"])          # FMPy did land on the change
    on_grid = [i for i, t in enumerate(a["time"]) if abs(t * 10 - round(t * 10)) < 1e-9]
    assert len(on_grid) == len(b)
    for name in MONITOR_NAMES:
        assert list(a[name][on_grid]) == list(b[name]), name
    assert len(set(b["observation"])) > 1          # the change did something


def test_a_step_past_stop_time_is_still_refused(monitor_fmus):
    fmu = Slave(monitor_fmus[("m1", 2)], MONITOR)
    try:
        fmu.slave.reset()
        fmu.slave.setupExperiment(startTime=0.0, stopTime=0.25)
        fmu.slave.enterInitializationMode()
        fmu.slave.exitInitializationMode()
        fmu.slave.doStep(0.0, 0.25)                 # to the stop time exactly: fine
        with pytest.raises(FMICallException):
            fmu.slave.doStep(0.25, 0.01)
    finally:
        fmu.close()


# ---- the train -------------------------------------------------------------------------------

TRAIN_REAL = ["true_speed", "position", "true_distance", "brake_decel", "train.speed"]
TRAIN_EXACT = ["brake_level"] + [f"ch{c}.{f}" for c in (1, 4) for f in ("status", "distance", "valid")]
A_MAX = 4.0      # m/s^2: above every acceleration of this run (3 m/s^2 emergency + resistance)
RAMP = 3.0 / 0.5  # m/s^3: the brake build-up rate (emergency deceleration / build-up time)
DEMAND_AT = 3_005_000_000    # the emergency demand arrives between two grid instants


def run_train(path, pts: list[int], params: dict | None = None) -> dict:
    fmu = Slave(path, TRAIN, {"sensor.noise_sigma": 0.3, "fault.kind": 1, "fault.channel": 4,
                              "fault.start": 2.0, "fault.end": 2.555, **(params or {})})
    try:
        rows = {0: tuple(fmu.get(n) for n in TRAIN_REAL + TRAIN_EXACT)}
        for t0, t1 in zip(pts, pts[1:]):
            fmu.set("brake_demand", 2 if t0 >= DEMAND_AT else 0)
            fmu.set("monitor_cycle", t0 // 100_000_000 + 1)    # the harness is the monitor: alive every 100 ms
            fmu.step_to(t1)
            rows[t1] = tuple(fmu.get(n) for n in TRAIN_REAL + TRAIN_EXACT)
        return rows
    finally:
        fmu.close()


TRAIN_STEPS = {"3ms": 3_000_000, "25ms": 25_000_000, "37ms": 37_000_000, "100ms": 100_000_000, "random": None}


@pytest.mark.parametrize("case", list(TRAIN_STEPS))
def test_train_agrees_with_10ms_stepping(case, train_fmu):
    """On the 10 ms grid: bit for bit the 10 ms run (the state is on the grid and the demand
    is sampled at grid instants, also when it changes between them, at 3.005 s). Between
    grid instants: the same equations over the part of the step, which differs from the
    straight line between the two grid states by less than one step's change of the
    acceleration can make: speed by A_MAX x 10 ms, position by A_MAX x (10 ms)^2, the brake
    deceleration by the ramp over one step. Sensors hold between grid samples; chN.valid
    switches at the fault's own times (2.0 s, 2.555 s)."""
    end_ns = 12_000_000_000
    ref = run_train(train_fmu, points(GRID_NS, end_ns, [DEMAND_AT]))
    if case == "random":
        rng = random.Random(7)
        step = [rng.randrange(500_000, 60_000_000) for _ in range(101)]
    else:
        step = TRAIN_STEPS[case]
    rows = run_train(train_fmu, points(step, end_ns, [DEMAND_AT]))
    n_real = len(TRAIN_REAL)
    on, off = 0, 0
    for t, out in rows.items():
        lo = (t // GRID_NS) * GRID_NS
        if t == lo:
            on += 1
            assert out == ref[t], (case, t)
            continue
        off += 1
        a, b, w = ref[lo], ref[lo + GRID_NS], (t - lo) / GRID_NS
        line = [a[i] + w * (b[i] - a[i]) for i in range(n_real)]
        speed, position, distance, decel, reported = out[:n_real]
        assert abs(speed - line[0]) <= A_MAX * 0.01, (case, t)
        assert abs(position - line[1]) <= A_MAX * 0.01 ** 2, (case, t)
        assert abs(distance - line[2]) <= A_MAX * 0.01 ** 2, (case, t)
        assert abs(decel - line[3]) <= RAMP * 0.01, (case, t)
        assert min(a[0], b[0]) - 1e-12 <= speed <= max(a[0], b[0]) + A_MAX * 0.01
        assert out[n_real] == b[n_real]                 # brake level: the one of the step
        sensors = list(out[n_real + 1:])
        expected = list(a[n_real + 1:])                 # held since the last grid sample
        for i, name in enumerate(TRAIN_EXACT[1:]):
            if name.endswith("valid") and name.startswith("ch4"):
                expected[i] = not (2.0 <= t / NS < 2.555)
        assert sensors == expected, (case, t)
    assert on > 0 and (off > 0 or case == "100ms")
    # the run brakes to a stop before the obstacle
    assert rows[end_ns][0] == 0.0 and rows[end_ns][2] > 0.0


def test_train_fmu_time_is_exact_at_any_step(train_fmu):
    """The FMU time is whole ns: after 1000 steps of 1 ms it is exactly 1.0 s, and after
    3 x 0.1 s it reads 0.3, not 0.30000000000000004."""
    fmu = Slave(train_fmu, TRAIN)
    try:
        t = 0.0
        for _ in range(1000):
            fmu.slave.doStep(t, 0.001)
            t += 0.001                      # the master's own sum drifts; the FMU's does not
        assert fmu.time() == 1.0
        fmu.t_ns = NS
        for k in range(3):
            fmu.step_to(NS + (k + 1) * 100_000_000)
        assert fmu.time() == 1.3
    finally:
        fmu.close()


# ---- the closed loop -------------------------------------------------------------------------

def closed_loop(monitor_path, train_path, scen: CosimScenario, step_ns: int, demand_every_cycle: bool):
    """Both FMUs stepped together at `step_ns` (Jacobi: the outputs at t go to the other FMU
    before both step from t). With `demand_every_cycle` the monitor's demand reaches the
    train only at cycle instants, as cosim's CAN frame (one cycle late); otherwise at every
    communication point. (train rows at every step, outcome, margin)."""
    mon = Slave(monitor_path, MONITOR, scen.monitor, "monitor")
    train = Slave(train_path, TRAIN, scen.train, "train")
    links = [v.name for v in MONITOR if v.causality == "input"]
    try:
        rows = []
        end_ns = round(scen.duration_s * NS)
        for t in range(0, end_ns, step_ns):
            for name in links:
                mon.set(name, train.get(name))
            if not demand_every_cycle or t % CYCLE_NS == 0:
                train.set("brake_demand", mon.get("brake_demand"))
                train.set("monitor_cycle", mon.get("cycle"))
            mon.step_to(t + step_ns)
            train.step_to(t + step_ns)
            rows.append(tuple(train.get(n) for n in cosim.TRAIN_TRACE_REAL))
        speed, distance = train.get("true_speed"), train.get("true_distance")
        outcome = "collision" if train.get("collided") else ("stopped" if speed == 0.0 else "running")
        return rows, outcome, distance
    finally:
        mon.close()
        train.close()


def test_closed_loop_at_10ms_macro_step(monitor_fmus, train_fmu):
    """Train FMU + monitor FMU, both at a 10 ms macro step. (1) With the demand handed over
    at cycle instants the run is bit for bit cosim.run_scenario's (train at 10 ms, monitor at
    100 ms, demand one cycle late). (2) With the demand handed over every 10 ms the outcome
    is the same (stopped), the margin between those of the demand one cycle late and at once."""
    scen = CosimScenario(name="steps", duration_s=30.0, train={"initial_speed": 25.0, "obstacle.position": 560.0},
                         monitor={}, demand_delay_cycles=1)
    mon = monitor_fmus[("m1", 2)]
    late = cosim.run_scenario(scen, mon, train_fmu, step_s=0.01)
    at_once = cosim.run_scenario(scen, mon, train_fmu, step_s=0.01, demand_delay_cycles=0)
    assert late.outcome == at_once.outcome == "stopped"
    c = {name: i for i, name in enumerate(late.columns)}
    expected = [tuple(r[c[n]] for n in cosim.TRAIN_TRACE_REAL) for r in late.rows]
    rows, outcome, margin = closed_loop(mon, train_fmu, scen, GRID_NS, demand_every_cycle=True)
    assert rows == expected and outcome == late.outcome and margin == late.margin_m
    rows, outcome, margin = closed_loop(mon, train_fmu, scen, GRID_NS, demand_every_cycle=False)
    assert outcome == "stopped"
    assert late.margin_m - 0.05 <= margin <= at_once.margin_m + 0.05
