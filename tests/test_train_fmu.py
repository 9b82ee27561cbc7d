"""The train FMU as the world the braking declaration must cover (issue 11): emergency
deceleration by speed band, traction held after a demand, a speed reported low, slippery
and degraded reports with the deceleration they cost, and contact with an oncoming obstacle
told apart from a collision while our train moves. Driven through FMPy, step by step."""
from __future__ import annotations

import shutil

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import defaultCallbacks

from fmu.driver import initialize, vr_of
from fmu.variables import TRAIN


class Train:
    """The train FMU, its log kept; `run` holds a brake demand (obeyed at once after a 0)."""

    def __init__(self, path):
        md = read_model_description(str(path))
        self.unzip = extract(str(path))
        self.log = []
        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=self.unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName="train")
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: self.log.append(msg.decode()))
        self._callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self._callbacks.freeMemory = defaultCallbacks.freeMemory
        self.slave.instantiate(callbacks=self._callbacks)
        self.t = 0.0

    def start(self, params: dict) -> "Train":
        initialize(self.slave, 2, TRAIN, params)
        return self

    def get(self, name: str):
        vr = vr_of(TRAIN, name)
        kind = TRAIN[vr].type
        return {"Real": self.slave.getReal, "Integer": self.slave.getInteger, "Boolean": self.slave.getBoolean}[kind]([vr])[0]

    def run(self, demand: int, seconds: float, h: float = 0.01, watch: tuple = ("true_speed",)) -> list:
        """Step with `demand` for `seconds`; the watched outputs after every step. The harness
        is the monitor: its alive counter (`monitor_cycle`) moves every 100 ms."""
        rows = []
        for _ in range(round(seconds / h)):
            self.slave.setInteger([vr_of(TRAIN, "brake_demand"), vr_of(TRAIN, "monitor_cycle")],
                                  [demand, int(self.t * 10 + 1e-9) + 1])
            self.slave.doStep(self.t, h)
            self.t = round(self.t + h, 9)
            rows.append(tuple(self.get(n) for n in watch))
        return rows

    def close(self) -> None:
        self.slave.freeInstance()
        shutil.rmtree(self.unzip, ignore_errors=True)


@pytest.fixture
def train(train_fmu):
    made = []

    def make(**params):
        t = Train(train_fmu)
        made.append(t)
        return t.start({k.replace("__", "."): v for k, v in params.items()})

    yield make
    for t in made:
        t.close()


NO_DRAG = dict(davis_a=0.0, davis_b=0.0, davis_c=0.0, obstacle__present=False)


def decel_at(train, speed: float, **params) -> float:
    """The steady emergency deceleration at `speed` (no dead time, no ramp, no drag)."""
    t = train(initial_speed=speed, brake_delay=0.0, brake_buildup=0.0, **NO_DRAG, **params)
    t.run(0, 0.01)
    (v0,), (v1,) = t.run(2, 0.02)
    return (v0 - v1) / 0.01


def test_emergency_deceleration_follows_the_speed_bands(train):
    bands = dict(emergency_decel=2.4, emergency_band2_speed=30.0, emergency_band2_decel=2.2,
                 emergency_band3_speed=38.0, emergency_band3_decel=2.0)
    assert decel_at(train, 20.0, **bands) == pytest.approx(2.4)
    assert decel_at(train, 34.0, **bands) == pytest.approx(2.2)
    assert decel_at(train, 40.0, **bands) == pytest.approx(2.0)
    assert decel_at(train, 40.0) == pytest.approx(3.0)                 # default: one band, 3 m/s^2


def test_a_built_brake_follows_the_band_change_at_once(train):
    """Braking through 30 m/s, the deceleration jumps from band 2 to band 1 within one
    step (the ramp is only the build-up), so the world never brakes below its bands."""
    t = train(initial_speed=31.0, brake_delay=0.0, brake_buildup=0.5, emergency_decel=2.4,
              emergency_band2_speed=30.0, emergency_band2_decel=2.2, **NO_DRAG)
    t.run(0, 0.01)
    rows = t.run(2, 3.0, watch=("true_speed", "brake_decel"))
    # (speed at the start of a step, deceleration in that step), once built up (0.5 s)
    steps = [(v, d) for (v, _), (_, d) in zip(rows[50:], rows[51:])]
    above = [d for v, d in steps if v >= 30.0]
    below = [d for v, d in steps if v < 30.0]
    assert above and below
    assert above == [pytest.approx(2.2)] * len(above) and below == [pytest.approx(2.4)] * len(below)


@pytest.mark.parametrize("track, brake, factor", [(0, 0, 1.0), (1, 0, 0.7), (0, 1, 0.8), (1, 1, 0.56)])
def test_reported_conditions_cost_their_factor_and_are_reported(train, track, brake, factor):
    params = dict(track_condition=track, brake_status=brake, slippery_factor=0.7, degraded_factor=0.8)
    assert decel_at(train, 20.0, **params) == pytest.approx(3.0 * factor)
    t = train(**params)
    assert (t.get("train.track_condition"), t.get("train.brake_status")) == (track, brake)


def test_traction_is_held_for_traction_cutoff_after_the_demand(train):
    """traction_cutoff 0.8 s: full traction (max_traction) for 0.8 s after the demand,
    although the brakes apply after 0.2 s; the default cuts traction when they apply."""
    held = train(initial_speed=20.0, traction_cutoff=0.8, max_traction=0.5, brake_delay=0.2, brake_buildup=0.0,
                 emergency_decel=3.0, **NO_DRAG)
    held.run(0, 0.01)
    acc = [a for (a,) in held.run(2, 1.2, watch=("acceleration",))]
    assert acc[:20] == [pytest.approx(0.5)] * 20                        # dead time: traction only
    assert acc[20:80] == [pytest.approx(0.5 - 3.0)] * 60                # brakes against held traction
    assert acc[80:] == [pytest.approx(-3.0)] * 40                       # traction cut at 0.8 s
    cut = train(initial_speed=20.0, brake_delay=0.2, brake_buildup=0.0, emergency_decel=3.0, **NO_DRAG)
    cut.run(0, 0.01)
    acc = [a for (a,) in cut.run(2, 0.5, watch=("acceleration",))]
    assert acc[:20] == [pytest.approx(0.0)] * 20 and acc[20:] == [pytest.approx(-3.0)] * 30


def test_a_cruising_speed_above_the_start_speed_pulls_at_full_traction_until_the_demand(train):
    """cruise_speed 25 m/s from 20 m/s: max_traction (0.5 m/s^2) until the demand, then held
    for traction_cutoff as ever (the declaration's worst train: accelerating when the brake
    is demanded); the default (-1) cruises at initial_speed, and the check refuses > 120."""
    pull = train(initial_speed=20.0, cruise_speed=25.0, traction_cutoff=0.8, max_traction=0.5, brake_delay=0.2,
                 brake_buildup=0.0, emergency_decel=3.0, **NO_DRAG)
    acc = [a for (a,) in pull.run(0, 2.0, watch=("acceleration",))]
    assert acc[1:] == [pytest.approx(0.5)] * 199                        # pulls, far from 25 m/s
    assert pull.get("true_speed") == pytest.approx(21.0, abs=0.01)
    acc = [a for (a,) in pull.run(2, 1.0, watch=("acceleration",))]
    assert acc[:20] == [pytest.approx(0.5)] * 20 and acc[20:80] == [pytest.approx(0.5 - 3.0)] * 60
    assert acc[80:] == [pytest.approx(-3.0)] * 20
    cruise = train(initial_speed=20.0, max_traction=0.5, **NO_DRAG)
    cruise.run(0, 2.0)
    assert cruise.get("true_speed") == pytest.approx(20.0)
    with pytest.raises(FMICallException):
        train(initial_speed=20.0, cruise_speed=130.0)


def test_the_reported_speed_is_low_by_speed_error_of_itself(train):
    t = train(initial_speed=40.0, speed_error=0.02)
    t.run(0, 0.5)
    assert t.get("true_speed") == pytest.approx(40.0)
    assert t.get("train.speed") * 1.02 == pytest.approx(40.0)


def test_collision_while_moving_has_the_impact_speed(train):
    """No braking into a static obstacle 50 m ahead at 20 m/s: contact at 20 m/s."""
    t = train(initial_speed=20.0, obstacle__position=50.0, **{k: v for k, v in NO_DRAG.items() if k != "obstacle__present"})
    t.run(0, 3.0)
    assert t.get("collided") and t.get("impact_speed") == pytest.approx(20.0)


def test_contact_while_braking_has_the_speed_at_the_contact(train):
    """Braking at 3 m/s^2 from 20 m/s with the obstacle 60 m ahead (66.7 m needed): the
    speed at contact is sqrt(400 - 2 * 3 * 60) = 6.32 m/s, resolved within the step."""
    t = train(initial_speed=20.0, obstacle__position=60.0, brake_delay=0.0, brake_buildup=0.0, davis_a=0.0, davis_b=0.0,
              davis_c=0.0)
    t.run(0, 0.01)
    t.run(2, 10.0)
    assert t.get("collided") and t.get("impact_speed") == pytest.approx((400 - 2 * 3 * 59.8) ** 0.5, abs=0.02)


def test_an_oncoming_obstacle_reaching_a_standing_train_is_not_our_collision(train):
    t = train(initial_speed=20.0, obstacle__position=300.0, obstacle__speed=-10.0, brake_delay=0.0, brake_buildup=0.0)
    t.run(0, 0.01)
    t.run(2, 8.0)                                     # stands after ~7 s, 70 m travelled; obstacle at ~220 m
    assert t.get("true_speed") == 0.0 and not t.get("collided")
    t.run(2, 20.0)
    assert t.get("collided") and t.get("impact_speed") == 0.0


CHANNELS = [f"ch{c}.status" for c in range(1, 7)]


def test_an_obstacle_that_left_the_track_is_neither_seen_nor_reached(train):
    """obstacle.leave_time (issue 29 item 4): a vehicle 60 m ahead leaves the track at 1 s.
    Before, every channel sees it; from the first sample at 1 s on, every channel reports
    ABSENT and true_distance is 1e9 (no obstacle); the train, not braking at 20 m/s, runs
    through where it stood (60 m, at 3 s) without contact. Without leave_time it collides."""
    params = dict(initial_speed=20.0, obstacle__position=60.0, sensor__noise_sigma=0.0, davis_a=0.0, davis_b=0.0,
                  davis_c=0.0, max_traction=0.0)
    t = train(obstacle__leave_time=1.0, **params)
    assert t.get("obstacle.leave_time") == 1.0
    rows = t.run(0, 5.0, watch=("true_distance", "collided", *CHANNELS))
    times = [round(0.01 * (i + 1), 2) for i in range(len(rows))]
    before = [r for ti, r in zip(times, rows) if ti < 1.0]
    after = [r for ti, r in zip(times, rows) if ti >= 1.0]
    assert all(0 < r[0] < 60.0 and r[2:] == (1,) * 6 for r in before)
    assert all(r[0] == 1e9 and not r[1] and r[2:] == (0,) * 6 for r in after)
    assert t.get("position") == pytest.approx(100.0) and t.get("impact_speed") == 0.0
    stays = train(**params)
    stays.run(0, 5.0)
    assert stays.get("obstacle.leave_time") == 1e9                    # the default: never
    assert stays.get("collided") and stays.get("impact_speed") == pytest.approx(20.0)


@pytest.mark.parametrize("params, name", [
    ({"emergency_band3_speed": 30.0}, "emergency_band3_speed"),
    ({"emergency_band2_speed": 30.0, "emergency_band2_decel": 0.5}, "emergency_band2_decel"),
    ({"slippery_factor": 0.0}, "slippery_factor"),
    ({"degraded_factor": 1.5}, "degraded_factor"),
    ({"speed_error": 0.6}, "speed_error"),
    ({"traction_cutoff": 31.0}, "traction_cutoff"),
    ({"obstacle.leave_time": -1.0}, "obstacle.leave_time"),
])
def test_bad_world_parameters_are_refused_by_name(train_fmu, params, name):
    t = Train(train_fmu)
    try:
        with pytest.raises(FMICallException):
            t.start(params)
        assert any(f"{name} = " in line for line in t.log), t.log
    finally:
        t.close()
