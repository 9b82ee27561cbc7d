"""The campaign's world train (verification/world_train.py): the Python twin equals the train
FMU in FMPy step by step, corner trains sit exactly on the declaration's limits, trains drawn
inside it never brake worse, and world-train files are read with errors that name the file."""
from __future__ import annotations

import random

import pytest

from monitor.core.config import Config
from test_train_fmu import Train
from verification import world_train as wt

WORLDS = {
    "declared corner, dead time": wt.corners(Config())[0],
    "declared corner, ramp": wt.corners(Config())[1],
    "bands, drag, uphill": wt.WorldTrain(emergency_decel=((0.0, 2.8), (15.0, 2.1), (30.0, 1.7)), service_decel=0.9,
                                         brake_delay=0.33, brake_buildup=1.2, traction_cutoff=-1.0, gradient=12.0,
                                         davis_a=6000.0, davis_b=100.0, davis_c=8.0),
    "weak, traction held": wt.WorldTrain(emergency_decel=((0.0, 1.0),), service_decel=0.5, brake_delay=1.5,
                                         brake_buildup=0.0, traction_cutoff=1.3, max_traction=0.7, gradient=-25.0),
}
# (demand, seconds): released once at the start (the FMU obeys at once after a 0), then braking
# that starts, changes level, is released and comes back, down to standstill
DEMANDS = [(0, 0.5), (1, 1.7), (0, 0.8), (2, 2.35), (1, 0.6), (2, 50.0)]


@pytest.mark.parametrize("name", list(WORLDS))
def test_the_twin_equals_the_train_fmu_step_by_step(train_fmu, name):
    world = WORLDS[name]
    fmu = Train(train_fmu).start(dict(world.fmu_parameters(), initial_speed=33.0, **{"obstacle.present": False}))
    twin = wt.TrainTwin(world, 33.0)
    worst = 0.0
    try:
        for demand, seconds in DEMANDS:
            rows = fmu.run(demand, seconds, watch=("true_speed", "position", "train.speed"))
            for speed, position, reported in rows:
                twin.step(demand)
                worst = max(worst, abs(speed - twin.speed), abs(position - twin.position),
                            abs(reported - twin.measured_speed()))
    finally:
        fmu.close()
    assert twin.speed == 0.0 and twin.position > 100.0      # the run reached standstill under braking
    assert worst <= 1e-9, worst


def test_corners_are_the_declarations_limits():
    cfg = Config()
    dead, ramp = wt.corners(cfg)
    assert dead.emergency_decel == ((0.0, 2.4), (30.0, 2.2)) and dead.service_decel == 0.8
    assert dead.equivalent_buildup_s() == ramp.equivalent_buildup_s() == 1.0 and ramp.brake_buildup == 1.0
    assert dead.gradient == -20.0 and dead.traction_cutoff == 0.8 and dead.max_traction == 0.5
    assert dead.speed_error == 0.02


def test_trains_drawn_inside_the_declaration_never_brake_worse():
    cfg = Config()
    worst = wt.corners(cfg)[0]
    rng = random.Random(7)
    for _ in range(300):
        w = wt.within(cfg, rng)
        assert all(a >= b for (_, a), (_, b) in zip(w.emergency_decel, worst.emergency_decel))
        assert worst.service_decel <= w.service_decel <= w.emergency_decel[0][1]
        assert w.equivalent_buildup_s() <= worst.equivalent_buildup_s() + 1e-9
        assert worst.gradient <= w.gradient <= 0.0 and 0.0 <= w.speed_error <= worst.speed_error
        assert w.traction_cutoff <= worst.traction_cutoff and w.max_traction <= worst.max_traction
        assert 0.0 <= w.sensor_latency_s <= 0.01 and 0.0 <= w.output_latency_s <= 0.01
    drawn = [wt.for_run(cfg, f"k{i}") for i in range(400)]
    assert drawn == [wt.for_run(cfg, f"k{i}") for i in range(400)]          # a run's train follows from its key
    corner_share = sum(d in wt.corners(cfg) for d in drawn) / len(drawn)
    assert 0.15 < corner_share < 0.35 and worst in drawn and wt.corners(cfg)[1] in drawn


def test_stops_within_is_the_twins_own_stopping_distance():
    twin = wt.TrainTwin(wt.corners(Config())[0], 30.0)
    probe = twin.copy()
    while probe.speed > 0.0:
        probe.step(2)
    distance = probe.position
    assert twin.position == 0.0 and twin.speed == 30.0                   # the copy left the twin alone
    assert twin.stops_within(distance + 0.01) and not twin.stops_within(distance - 0.01)
    assert not twin.stops_within(distance + 1.0, after_s=0.1) and twin.stops_within(distance + 3.5, after_s=0.1)
    assert 200.0 < distance < 260.0        # 30 m/s, 1 s dead time with traction, 2.2 - 0.196 m/s^2


def test_world_train_files(tmp_path):
    good = tmp_path / "weak.toml"
    good.write_text("[world_train]\nemergency_decel = 1.0\nbrake_delay = 1.5\nbrake_buildup = 0.0\nservice_decel = 0.5\n")
    w = wt.load(good)
    assert w.emergency_decel == ((0.0, 1.0),) and w.brake_delay == 1.5 and w.davis_a == 0.0
    for text, words in (("emergency_decel = 1.0\nbogus = 3\n", "unknown key(s) bogus"),
                        ("brake_delay = -1\n", "brake_delay = -1"),
                        ("emergency_decel = [[5.0, 2.0]]\n", "bands start at 0 m/s"),
                        ("emergency_decel = 1.0\nservice_decel = 2.0\n", "service_decel = 2"),
                        ("brake_delay = \n", "")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(wt.WorldTrainError) as err:
            wt.load(bad)
        assert str(bad) in str(err.value) and words in str(err.value)


def test_broken_bounds_names_each_declared_bound_a_world_train_breaks():
    """Issue 30 item 8: the world train against the declaration, key by key (the physics
    model's reading of it); corners and draws inside break nothing, every worse value is named."""
    cfg = Config()
    assert all(wt.broken_bounds(c, cfg) == [] for c in wt.corners(cfg))
    assert not any(wt.broken_bounds(wt.within(cfg, random.Random(i)), cfg) for i in range(200))
    corner = wt.corners(cfg)[0]
    worse = {
        "emergency_decel": dict(emergency_decel=((0.0, 2.4), (30.0, 2.1))),     # band 2 a little weak only
        "service_decel": dict(service_decel=0.79),
        "emergency_buildup_s": dict(brake_delay=0.6, brake_buildup=0.9),         # 0.6 + 0.45 = 1.05 s
        "traction_cutoff_s": dict(traction_cutoff=0.9),
        "max_accel": dict(max_traction=0.6),
        "max_downhill_gradient": dict(gradient=-21.0),
        "speed_error": dict(speed_error=0.03),
    }
    for key, change in worse.items():
        broken = wt.broken_bounds(wt.replace(corner, **change), cfg)
        assert [b.split(":")[0] for b in broken] == [key], (key, broken)
    assert wt.broken_bounds(wt.replace(corner, gradient=30.0, speed_error=0.0), cfg) == []   # uphill, exact: better


def test_a_collision_beyond_the_declaration_is_told_apart_from_an_unavoidable_one():
    """A train braking 1.0 m/s^2 after 2.0 s cannot stop for the crossing vehicle once it is in
    range (the world calls it unavoidable); a train at the declaration's corner could have."""
    from verification import campaign as cp

    awful = wt.WorldTrain(emergency_decel=((0.0, 1.0),), service_decel=0.5, brake_delay=2.0, brake_buildup=0.0)
    res = cp.simulate(cp.RunSpec((), "crossing-500m-30", 0, "m2"), world=awful)
    assert res["collision"] and res["unavoidable"] and res["beyond_declaration"] and not res["unsafe"]
    inside = cp.simulate(cp.RunSpec((), "crossing-500m-30", 0, "m2"), world=wt.corners(Config())[0])
    assert not inside["collision"] and not inside["beyond_declaration"]
