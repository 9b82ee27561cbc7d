"""Closed-loop acceptance of the braking curves (issue 11, Deliver 6), in FMPy with the real
FMUs: the train FMU brakes as badly as the shipped declaration allows (corners included),
the monitor FMU supervises it, the demand reaches the train one monitor cycle late, and
the obstacle is first read one cycle's travel inside EBI (the sampling period's worst case),
the train pulling at full traction until the demand in the hardest corner. No run may
collide, and every stop keeps the standstill margin, as the physics proof says; the same grid must collide against the old nominal envelope,
against a declaration that promises more than the train brakes, and with a train a little
worse than declared. The results and the figure are in docs/supervision_grid.md."""
from __future__ import annotations

import math
from dataclasses import replace

import pytest

from fmu import acceptance as acc
from fmu import cosim
from monitor.core.braking import curves
from monitor.core.config import Config
from monitor.declaration import apply, shipped
from monitor.tables import read

VALUES = shipped()
CFG = apply(Config(), VALUES)
PARAMS = acc.monitor_params(VALUES)


@pytest.fixture(scope="module")
def curves_loop(fmu_dir, train_fmu):
    """The monitor FMU with a table that never brakes: the supervision curves alone, the
    floor every table can only raise."""
    from fmu.build import build_monitor

    path = build_monitor(acc.curves_only_table(read("m1")), 2, fmu_dir, "railguard-monitor-curves-only.fmu")
    with cosim.Loop(path, train_fmu) as loop:
        yield loop


def hardest_cases(world=None) -> list:
    """The grid's hardest train (or `world`) at every speed against every obstacle."""
    return acc.cases(CFG, [world or acc.hardest_world(VALUES)])


def test_the_grid_spans_the_declaration_and_its_corners():
    worlds = acc.grid_worlds(VALUES)
    assert len(acc.grid_cases(VALUES)) == len(worlds) * 4 * 3 == 2592
    assert {w.buildup_s for w in worlds} == {VALUES["emergency_buildup_s"]}          # dead + ramp / 2 at the limit
    assert {(w.dead_s, w.ramp_s) for w in worlds} == {(1.0, 0.0), (0.0, 2.0), (0.5, 1.0)}
    assert {w.bands for w in worlds} == {((0.0, 2.4), (30.0, 2.2)), ((0.0, 3.0),)}     # guaranteed .. nominal
    assert {w.gradient for w in worlds} == {-20.0, 0.0, 10.0}
    assert {w.traction_s for w in worlds} == {0.8, 0.0} and {w.max_traction for w in worlds} == {0.5}
    assert {(w.traction_s, w.pulling) for w in worlds} == {(0.8, True), (0.0, False)}
    assert {w.speed_error for w in worlds} == {0.02, 0.0}
    assert {(w.track, w.brake) for w in worlds} == {(0, 0), (1, 0), (0, 1)}
    assert {(w.slippery_factor, w.degraded_factor) for w in worlds} == {(0.7, 0.8)}
    assert acc.hardest_world(VALUES) in worlds


@pytest.mark.parametrize("speed, obstacle", [(10.0, 0.0), (40.0, -10.0)])
def test_the_obstacle_is_first_read_one_cycle_inside_ebi_at_the_grid_speed(speed, obstacle):
    """The sampling period's worst case: one cycle before, the obstacle was at EBI, out of
    range; the pulling train starts slower so that it reads the obstacle at the grid's speed.
    The sensors at the error budget's corner: every reading reports the obstacle 50 m farther
    and closing 1 m/s slower than it is, so it is first read (truly) 50 m inside the EBI the
    monitor computes from that reading."""
    world = acc.hardest_world(VALUES)
    assert (world.distance_bias, world.closing_bias) == (50.0, -1.0)
    case = acc.cases(CFG, [world], [speed], [obstacle])[0]
    measured = math.ceil(speed / 1.02 * 100)                   # train.speed read in cm/s, rounded up
    ebi = curves(CFG, measured, 0, 0, round((speed - obstacle - 1.0) * 100), 0).ebi_dm / 10
    assert case.visible_m == pytest.approx(ebi - 50.0 - (speed - obstacle) * 0.1, abs=0.11)
    p = case.train_params()
    assert p["sensor.range"] == case.visible_m and p["obstacle.speed"] == obstacle
    assert (p["sensor.distance_bias"], p["sensor.closing_bias"], p["sensor.noise_sigma"]) == (50.0, -1.0, 0.0)
    pull = 0.5 + 20 * 9.81e-3                                  # full traction and the steepest downhill
    assert p["initial_speed"] == pytest.approx(speed - pull * acc.APPROACH_S)
    assert p["cruise_speed"] > speed                           # it pulls all the way to the reading
    start, t = p["initial_speed"], acc.APPROACH_S
    assert p["obstacle.position"] == pytest.approx(case.visible_m + start * t + pull * t * t / 2 - obstacle * t)


def test_no_collision_in_the_grid(curves_loop):
    """2592 runs: every train within the declaration stops `standstill_margin` (5 m) before
    every obstacle, as the physics proof says, with the monitor running (measured: 9.66 m at
    least) and with it stalled at the first reading, the brakes' receiver braking at its
    timeout (issue 40 item 3; measured 8.23 m at least; the curves of before, which counted
    two periods, not four, stopped 31 of these runs inside the margin, 2.69 m at worst)."""
    outcomes, _ = acc.run_cases(curves_loop, PARAMS, acc.grid_cases(VALUES))
    s = acc.summary(outcomes)
    bad = [(o.case.world.label(), o.case.speed, o.case.obstacle_speed, o.outcome, o.impact_speed)
           for o in outcomes if o.outcome != "stopped"]
    assert s["collisions"] == 0 and not bad, bad[:5]
    assert VALUES["standstill_margin_m"] <= s["min_margin_m"] < VALUES["standstill_margin_m"] + 6.0
    stalled, _ = acc.run_cases(curves_loop, PARAMS, acc.grid_cases(VALUES), stalled=True)
    t = acc.summary(stalled)
    assert t["collisions"] == 0 and all(o.outcome == "stopped" for o in stalled)
    assert VALUES["standstill_margin_m"] <= t["min_margin_m"] < s["min_margin_m"]      # the stall costs margin
    assert all(o.first_brake_s is None for o in stalled)            # no monitor demand: the receiver braked
    assert all(o.first_brake_s is not None and o.first_brake_s >= acc.APPROACH_S - 0.11 for o in outcomes)
    chatter = [(o.case.world.label(), o.case.speed, o.case.obstacle_speed, o.demand_changes)
               for o in outcomes if o.demand_changes > 2]
    assert not chatter, chatter[:5]                      # issue 29: a clean stop, at most 2 demand changes


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_the_shipped_tables_keep_the_hardest_trains_safe(table, monitor_fmus, train_fmu):
    """The tables only add braking: with m1 or m2 in the loop, the whole grid (2592 runs,
    slippery and degraded included) stays free of collisions too, and every encounter ends
    with at most 2 demand changes (issue 29 item 6; measured: 1296 runs with 1, 1296 with 2)."""
    with cosim.Loop(monitor_fmus[(table, 2)], train_fmu) as loop:
        outcomes, _ = acc.run_cases(loop, PARAMS, acc.grid_cases(VALUES))
    assert len(outcomes) == 2592
    assert acc.summary(outcomes)["collisions"] == 0
    chatter = [(o.case.world.label(), o.case.speed, o.case.obstacle_speed, o.demand_changes)
               for o in outcomes if o.demand_changes > 2]
    assert not chatter, chatter[:5]                      # issue 29 item 6: the table's hold


@pytest.mark.parametrize("table", ["m1", "m2"])
@pytest.mark.parametrize("speed, decel", [(40.0, 3.0), (30.0, 1.5)])
def test_the_table_ends_a_slippery_encounter_in_a_clean_stop(table, speed, decel, monitor_fmus, train_fmu):
    """Issue 29 item 6, as the assessor tried it: guaranteed 1.5 m/s^2 with 2.5 s build-up
    declared, slippery track reported, a static obstacle first seen 1,700 m ahead, the train
    braking at `decel` (the m2 table used to toggle service/none 118 times at 40 m/s and
    creep on at 0.2 m/s): now at most 2 demand changes and a stop before the obstacle."""
    values = {**VALUES, "emergency_decel": 1.5, "service_decel": 0.8, "emergency_buildup_s": 2.5}
    world = acc.World(((0.0, decel),), 0.8 * decel / 1.5, 2.5, 0.0, 0.0, 0.0, 0.0, 0.5, track=1)
    case = acc.Case(world, speed, 0.0, 1700.0)
    with cosim.Loop(monitor_fmus[(table, 2)], train_fmu) as loop:
        [o], _ = acc.run_cases(loop, acc.monitor_params(values), [case])
    assert o.outcome == "stopped" and o.stop_margin_m > 0
    assert o.demand_changes <= 2, o.demand_changes


BLIND_AFTER_S = (0.3, 2.0, 5.0)         # after the first brake demand
BLIND_FOR_S = (1.0, 3.0, 7.0)           # every one shorter than forget_ms (7.5 s)


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_every_blindness_shorter_than_the_forgetting_time_ends_in_a_stop(table, monitor_fmus, train_fmu):
    """Issue 29 acceptance: every channel blind (the train FMU's `blind` fault), beginning
    after the obstacle was voted and lasting less than the forgetting time, at every speed of
    the grid, for the grid's hardest train, against static and oncoming obstacles: the train
    stops before the obstacle (before the obstacle memory, half such runs collided)."""
    from fmu.scenario import FAULT_KINDS

    blind = FAULT_KINDS.index("blind")
    outcomes = []
    with cosim.Loop(monitor_fmus[(table, 2)], train_fmu) as loop:
        for case in hardest_cases():
            calm = loop.run(case.train_params(), PARAMS, acc.MAX_RUN_S, record=False, until_standstill=True)
            for after in BLIND_AFTER_S:
                for length in BLIND_FOR_S:
                    start = calm.first_brake_s + after
                    params = {**case.train_params(), "fault.kind": blind, "fault.start": start,
                              "fault.end": start + length}
                    res = loop.run(params, PARAMS, acc.MAX_RUN_S, record=False, until_standstill=True)
                    outcomes.append((case.speed, case.obstacle_speed, after, length, res.outcome))
    bad = [o for o in outcomes if o[-1] != "stopped"]
    assert len(outcomes) == 4 * 3 * 9 and not bad, bad[:5]


def test_the_grid_collides_against_the_old_nominal_envelope(curves_loop):
    """The envelope before issue 11 (3 m/s^2, 0.5 s, nothing else) lets every one of the
    hardest trains hit the obstacle."""
    outcomes, _ = acc.run_cases(curves_loop, acc.monitor_params(acc.nominal_envelope()), hardest_cases())
    assert all(o.collision for o in outcomes)
    assert max(o.impact_speed for o in outcomes) > 10


def test_the_grid_collides_when_the_declaration_promises_more_than_the_train_brakes(curves_loop):
    """Declared 3.0 m/s^2 for a train that brakes at the guaranteed 2.4 / 2.2."""
    promised = acc.monitor_params({**VALUES, "emergency_decel": acc.NOMINAL_DECEL})
    outcomes, _ = acc.run_cases(curves_loop, promised, hardest_cases())
    assert sum(o.collision for o in outcomes) >= 6


@pytest.mark.parametrize("worse", [{"factor": 0.9}, {"dead_s": 1.75}])
def test_a_train_a_little_worse_than_declared_collides(curves_loop, worse):
    """10 % less deceleration, or 0.75 s more dead time, than declared, at the timing
    contract's worst (the monitor stalled at the first reading, the receiver's timeout):
    collisions in at least 9 of the 12 hardest cases."""
    hard = acc.hardest_world(VALUES)
    if "factor" in worse:
        world = replace(hard, bands=tuple((s, a * worse["factor"]) for s, a in hard.bands))
    else:
        world = replace(hard, dead_s=worse["dead_s"])
    outcomes, _ = acc.run_cases(curves_loop, PARAMS, hardest_cases(world), stalled=True)
    assert sum(o.collision for o in outcomes) >= 9          # of 12


def test_sensors_a_little_worse_than_declared_use_up_the_margin(curves_loop):
    """The error budget is tight where the stop is short (issue 40 item 3): the hardest train,
    placed by the declared corner, its sensors reporting the obstacle 15 m beyond the declared
    50 m, stops inside the 5 m margin at 10 m/s (measured 2.8 m); 20 m beyond, it collides.
    At the declared accuracy the same runs keep 9.66 m."""
    hard = acc.hardest_world(VALUES)

    def margins(extra_m: float) -> list:
        worse = replace(hard, distance_bias=hard.distance_bias + extra_m)
        outcomes, _ = acc.run_cases(curves_loop, PARAMS, [replace(c, world=worse) for c in hardest_cases()])
        return [o.signed_margin_m() for o in outcomes]
    assert min(margins(0.0)) >= VALUES["standstill_margin_m"]
    assert min(margins(15.0)) < VALUES["standstill_margin_m"]
    assert min(margins(20.0)) < 0                              # a collision


def test_the_grid_and_the_proof_agree_on_which_trains_are_inside_the_declaration():
    """Issue 30: the physics proof holds for every train inside the declaration (broken_bounds
    == [], the model's reading of it); every grid world is such a train (and the grid has no
    collision: test_no_collision_in_the_grid), and the worlds that collide break a bound."""
    from verification import world_train as wt

    def as_world_train(w: acc.World) -> wt.WorldTrain:
        return wt.WorldTrain(emergency_decel=w.bands, service_decel=w.service_decel, brake_delay=w.dead_s,
                             brake_buildup=w.ramp_s, traction_cutoff=w.traction_s, max_traction=w.max_traction,
                             gradient=w.gradient, speed_error=w.speed_error)

    cfg = apply(Config(), VALUES)
    assert all(wt.broken_bounds(as_world_train(w), cfg) == [] for w in acc.grid_worlds(VALUES))
    hard = acc.hardest_world(VALUES)
    for worse in (replace(hard, bands=tuple((s, a * 0.9) for s, a in hard.bands)), replace(hard, dead_s=1.75)):
        assert wt.broken_bounds(as_world_train(worse), cfg)
