"""The obstacle memory's exact boundaries (issue 29 item 7: mutation testing of the new code).

Mutation testing (`python -m verification.mutation --scope memory.py envelope.py:hold
envelope.py:keep_held envelope.py:table_hold cycle.py:163-209 ...`) found behaviours of the
obstacle memory, the holds and the new parts of the cycle that tests/test_core_memory.py
let change unnoticed, mostly because its expectations were computed with the core's own
constants and helpers (UNITS_PER_DM, near_travel) or allowed a tolerance: the unit of a
position, the rounding of the prediction, the sensor range and the passed position at
exactly their edges, the remembered obstacle's own speed and the train's share of a closing
speed, the warning of the remembered and of the voted obstacle, what is kept of a forgotten
track, when an obstacle in sight keeps what is held, and the defaults. Each test pins one
such behaviour with values written out (positions in 1e-5 m, the unit of cm/s x ms) or
computed here from the braking curves, which these mutants leave alone; everything runs
through the real core: memory.py's functions directly against their documented contracts,
and whole cycles through `create`/`step`.
"""
from __future__ import annotations

import pytest

from monitor.core.braking import curves, ebi_dm
from monitor.core.config import Config, forget_cycles
from monitor.core.cycle import initial_state, step
from monitor.core.memory import UNITS_PER_DM, accel_run, far_travel, forget, near_travel, observe
from monitor.core.types import (
    ABSENT, DEGRADED, EMERGENCY, INIT, MAINTAIN, NO_DISTANCE, NORMAL, PRESENT, R_DISPUTE, R_LATCH, R_MEMORY, SERVICE,
    STATIC, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_NONE, TRACK_PASSED, TRACK_SEEN, Inputs, Report, State,
    Train,
)
from tests.test_core_cycle import M1, M2, clear, maintain_only, normal_driver, present, with_channel

U = 10000                 # 1e-5 m per dm (memory.UNITS_PER_DM), written out
V = 3000                  # 30 m/s
# the default declaration: speed error 20 per mille, traction 500 + 20 per mille downhill
# (9810 * 20 / 1000 = 196.2, rounded up to 197) = 697 mm/s^2
ERR, ACCEL = 20, 697
# the sensors' default accuracy, counted by the memory (the error budget): a remembered
# obstacle closes 100 cm/s faster than its own speed (10,000 units a period), and may lie
# 500 dm (5,000,000 units) farther than reported (what "passed" and "in range" read)
CLOSING_ACC, DISTANCE_ACC = 100, 500
# a declaration whose prediction is exact to the unit: no speed error, 198 mm/s^2 of
# traction on the level: a T^2 / 2 = 198 * 100^2 / 20000 = 99 units per cycle
EXACT = dict(speed_error_permille=0, max_accel_mms2=198, max_gradient_permille=0)


def travel(speed: int, obstacle: int, err: int = ERR, accel: int = ACCEL, period: int = 100) -> int:
    """What the gap can shrink in one period, worst case, computed here: the speed plus its
    error rounded up, a T^2 / 2 rounded up, the obstacle's own speed."""
    v_max = -(-speed * (1000 + err) // 1000)
    return v_max * period + -(-accel * period * period // 20000) + obstacle * period


# --------------------------------------------------------------------------- memory.py, directly


def test_accel_run_is_a_t2_over_2_in_1e5_m_rounded_up():
    """mm/s^2 x ms^2 / 20000 = 1e-5 m, rounded up: exactly 250 units for 500 mm/s^2 over
    100 ms, 1 for the least acceleration over 1 ms, and the exact quotient when it is one."""
    assert accel_run(0, 100) == 0
    assert accel_run(500, 100) == 250
    assert accel_run(697, 100) == 349          # 348.5 rounded up
    assert accel_run(198, 100) == 99
    assert accel_run(1, 1) == 1
    assert accel_run(401, 1000) == 20050       # 401e6 / 20000 exactly (/ 20001 would give 20049)


def test_near_travel_is_the_speed_plus_its_error_rounded_up_plus_acceleration_plus_the_obstacle():
    assert near_travel(0, 0, 0, 0, 100) == 0
    assert near_travel(1, 1, 0, 0, 1) == 2                          # 1.001 cm/s rounded up to 2
    assert near_travel(12000, 500, 0, 0, 100) == 1800000            # 18000 cm/s for 100 ms
    assert near_travel(1000, 20, 500, 300, 100) == 102000 + 250 + 30000
    assert near_travel(V, ERR, ACCEL, 60, 100) == 306000 + 349 + 6000


def test_far_travel_is_the_speed_less_its_error_rounded_down_less_acceleration_never_below_0():
    assert far_travel(12000, 0, 0, 100) == 1200000
    assert far_travel(1000, 20, 500, 100) == 98000 - 250
    assert far_travel(1, 0, 198, 100) == 1                          # 100 - 99: the least positive run
    assert far_travel(1, 0, 500, 100) == 0                          # 100 - 250 < 0: nothing
    assert far_travel(0, 0, 0, 100) == 0
    assert far_travel(0, 20, 697, 100) == 0


def test_observe_keeps_positions_in_1e5_m_and_the_obstacle_s_own_speed_from_1_cms():
    # confirmed: 300 dm is 3,000,000 units; an obstacle closing at 1 cm/s keeps its 1 cm/s;
    # the sighting's age comes back, to be counted once when the position is moved
    assert observe(5000000, 5000000, 0, 300, 1, 40, True, True) == (3000000, 3000000, 1, 40)
    assert observe(-1, -1, 0, 300, 0, 40, True, True) == (3000000, 3000000, 0, 40)
    assert observe(-1, -1, 0, 300, -5, 40, True, True) == (3000000, 3000000, 0, 40)    # receding: taken to stop
    # disputed without a track and no module sees it with both channels: nothing is
    # remembered, not even a speed or an age
    assert observe(-1, -1, 0, 100, 50, 7, False, False) == (-1, -1, 0, 0)
    # disputed without a track, one module sees it with both channels: remembered as a
    # confirmed sighting would be (issue 38 item 1), receding taken to stop
    assert observe(-1, -1, 0, 100, 50, 7, False, True) == (1000000, 1000000, 50, 7)
    assert observe(-1, -1, 0, 100, -5, 7, False, True) == (1000000, 1000000, 0, 7)
    # disputed exactly at the remembered position: the track takes the sighting (its age, and
    # its far end, which the train's least travel had moved)
    assert observe(3000000, 3000050, 20, 300, 0, 300, False, False) == (3000000, 3000000, 20, 300)
    # disputed and farther, with or without a module's sighting: kept, the faster closing
    # speed of the two, and no age (the kept position's age was counted when it was moved)
    assert observe(3000000, 3000050, 20, 301, 30, 300, False, False) == (3000000, 3000050, 30, 0)
    assert observe(3000000, 3000050, 20, 301, 10, 300, False, True) == (3000000, 3000050, 20, 0)
    # a module's sighting where the track can be (near < d <= far, far included) takes the
    # position; one channel's does not
    assert observe(3000000, 3010000, 20, 301, 10, 300, False, True) == (3010000, 3010000, 20, 300)
    assert observe(3000000, 3010000, 20, 301, 10, 300, False, False) == (3000000, 3010000, 20, 0)


def test_forget_leaves_no_evidence_count_behind_when_the_track_goes():
    assert forget(3, True, True, True, 5) == (0, TRACK_PASSED)
    assert forget(4, True, True, False, 5) == (0, TRACK_FORGOTTEN)
    assert forget(3, True, True, False, 5) == (4, TRACK_CONFIRMING)
    assert forget(3, False, True, False, 5) == (0, TRACK_HELD)


# --------------------------------------------------------------------------- through the cycle


def test_a_static_obstacle_is_remembered_with_the_train_s_speed_error_as_its_own_speed():
    """The train's share of a closing speed is its speed less the speed error (3000 cm/s
    reads 2940 at 20 per mille), so a static obstacle reported closing at the train's 3000
    cm/s is remembered closing at 60 cm/s of its own; the prediction, with the closing
    accuracy (100 cm/s) on top, moves it 322,349 units (32.2 dm) a cycle at 30 m/s."""
    d = normal_driver(Config())
    out = d.cycle(present(d.tick, 3000, closing=V), V)
    assert out.track_state == TRACK_SEEN and out.track_dm == 3000
    assert d.state.track_closing == 60
    assert travel(V, 60 + CLOSING_ACC) == 322349
    assert d.state.track_near == 3000 * U - 322349 and d.state.track_far == 3000 * U
    out = d.clear(V)
    assert out.track_dm == 2967 and out.track_state == TRACK_CONFIRMING        # 2967.77 dm, rounded down
    assert d.state.track_near == 3000 * U - 2 * 322349
    assert d.state.track_far == 3000 * U - (2940 * 100 - 349)                  # the train's least travel


def test_a_remembered_position_is_predicted_to_the_unit():
    """No speed error, 198 mm/s^2 on the level, 99 cm/s, a static obstacle 2 dm ahead: the
    worst case moves it 9900 + 99 + 10,000 (the closing accuracy, 100 cm/s) units in a
    cycle, so 1 unit of the 20,000 remains; an obstacle at 0 dm stays at 0 (never below)."""
    d = normal_driver(Config(**EXACT))
    out = d.cycle(present(d.tick, 2, closing=99), 99)
    assert out.track_dm == 2 and d.state.track_closing == 0
    assert d.state.track_near == 1
    d = normal_driver(Config())
    out = d.cycle(present(d.tick, 0, closing=V), V)
    assert out.track_dm == 0 and d.state.track_near == 0


def test_absence_counts_as_evidence_exactly_up_to_the_declared_sensor_range():
    """The defaults (sensor_range_dm = 4000, distance accuracy 500 dm): a standing train's
    remembered obstacle at exactly 350.0 m, which may lie at 400.0 m, is inside the range
    (evidence counts: confirming), at 350.1 m it is not (held)."""
    cfg = Config()
    assert (cfg.sensor_range_dm, cfg.distance_accuracy_dm) == (4000, DISTANCE_ACC)
    d = normal_driver(cfg)
    d.present(3500, 0)
    out = d.clear(0)
    assert out.track_state == TRACK_CONFIRMING and d.state.track_far == 3500 * U and d.state.track_absent == 1
    d = normal_driver(cfg)
    d.present(3501, 0)
    out = d.clear(0)
    assert out.track_state == TRACK_HELD and d.state.track_far == 3501 * U and d.state.track_absent == 0


def test_passed_is_beyond_the_remembered_position_by_at_least_one_unit():
    """Passed is beyond the remembered position plus the distance accuracy (500 dm: the
    obstacle may lie that much farther) by at least one unit. An obstacle at 0 dm and a
    standing train: the least travel is 0, not passed (evidence counts). An obstacle at
    9.5 m, then 99 cycles at 6.02 m/s (no speed error, 99 units explained by acceleration:
    60,101 units each, 5,949,999 in all) leave it 1 unit short of its 50 m of accuracy behind
    the train; a least travel of exactly 1 unit (1 cm/s) reaches that, not passed, and one
    more unit passes it."""
    d = normal_driver(Config())
    d.present(0, 0)
    out = d.clear(0)
    assert out.track_state == TRACK_CONFIRMING and d.state.track_far == 0
    d = normal_driver(Config(**EXACT, forget_ms=60000))          # (absence forgets nothing meanwhile)
    d.present(95, 0)
    for k in range(99):
        out = d.clear(602)
        assert out.track_state == TRACK_CONFIRMING, k
    assert d.state.track_far == 95 * U - 99 * 60101 == -DISTANCE_ACC * U + 1
    out = d.clear(1)
    assert out.track_state == TRACK_CONFIRMING and d.state.track_far == -DISTANCE_ACC * U
    out = d.clear(1)
    assert out.track_state == TRACK_PASSED and out.track_dm == 65535


def test_an_invalid_train_state_moves_nothing_towards_passed():
    """The train state is read to the safe side for the curves (top speed), but what
    "passed" is judged on is the least travel: an invalid speed is taken as none at all,
    not even 1 cm/s (here, with no speed error and no acceleration, 1 cm/s would pass an
    obstacle at 0 dm in one cycle)."""
    d = normal_driver(Config(speed_error_permille=0, max_accel_mms2=0, max_gradient_permille=0))
    d.present(0, 0)
    for _ in range(3):
        out = d.cycle(clear(d.tick), train=Train(-1))
        assert out.track_state == TRACK_CONFIRMING and d.state.track_far == 0


def test_a_report_s_age_is_counted_once_and_a_forgotten_or_passed_track_leaves_no_speed_behind():
    """An oncoming obstacle (its own 2000 cm/s) from a report 100 ms old: the remembered
    position is moved by the period and the age (200 ms of its closing, at the sighting's
    speed), once; the next cycle moves it by one period. Forgotten after one cycle of
    evidence (forget_ms = 100): the state keeps no closing speed."""
    d = normal_driver(Config(forget_ms=100))
    reports = tuple(Report(PRESENT, 1000, 2000, STATIC, d.tick - 100) for _ in range(6))
    d.cycle(reports, 0)
    assert d.state.track_closing == 2000
    assert d.state.track_near == 1000 * U - travel(0, 2000 + CLOSING_ACC, period=200)
    out = d.clear(0)
    assert out.track_state == TRACK_FORGOTTEN
    assert (d.state.track_near, d.state.track_far, d.state.track_closing) == (-1, -1, 0)
    # (sensors declared exact in distance: passed after a least travel of 1 unit)
    d = normal_driver(Config(**EXACT, distance_accuracy_dm=0))
    d.cycle(tuple(Report(PRESENT, 0, 500, STATIC, d.tick - 100) for _ in range(6)), 1)
    assert d.state.track_closing == 499
    assert d.clear(1).track_state == TRACK_PASSED
    assert (d.state.track_near, d.state.track_far, d.state.track_closing) == (-1, -1, 0)
    d = normal_driver(Config())
    d.cycle(tuple(Report(PRESENT, 3000, V, STATIC, d.tick - 200) for _ in range(6)), V)
    first = 3000 * U - d.state.track_near
    assert first == travel(V, 60 + CLOSING_ACC, period=300)   # the period and the 200 ms age, at 30 m/s
    d.cycle(clear(d.tick), 1000)                               # braked to 10 m/s: one period at that speed
    assert 3000 * U - d.state.track_near == first + travel(1000, 60 + CLOSING_ACC)


def test_the_remembered_obstacle_is_supervised_with_its_own_speed_plus_the_train_s():
    """An oncoming obstacle (reported closing at 5000 cm/s, the train at 3000: 2060 cm/s of
    its own) seen just beyond EBI (service), then every channel blind: its curves use the
    closing speed 2060 + 2940 = 5000 again, and one cycle's prediction (with the closing
    accuracy: 2160 cm/s of its own) takes it inside EBI: emergency on the remembered obstacle
    alone."""
    cfg = Config()
    c = curves(cfg, V, 0, 0, 5000, 0)
    first = c.ebi_dm + 40
    d = normal_driver(cfg, maintain_only(M1))   # the curves' answer, not the table's
    out = d.cycle(present(d.tick, first, closing=5000), V)
    assert out.demand == SERVICE and d.state.track_closing == 2060
    out = d.clear(V)
    t_dm = (first * U - travel(V, 2060 + CLOSING_ACC)) // U
    assert out.track_dm == t_dm and t_dm <= c.ebi_dm
    assert out.demand == EMERGENCY and out.reasons & R_MEMORY


def test_a_blind_remembered_obstacle_inside_its_warning_curve_warns():
    """Every channel blind, the remembered obstacle exactly on its warning curve (beyond
    SBI): no demand, but the warning."""
    cfg = Config()
    c = curves(cfg, V, 0, 0, V, 0)                 # 60 cm/s of its own + the train's 2940
    first = c.warning_dm + 33                      # one cycle's prediction: 32.2 dm (closing accuracy included)
    d = normal_driver(cfg, maintain_only(M1))   # the curves' answer, not the table's
    out = d.cycle(present(d.tick, first, closing=V), V)
    assert not out.warning
    out = d.clear(V)
    assert out.track_dm == c.warning_dm > c.sbi_dm
    assert out.warning and out.demand == MAINTAIN and out.reasons & R_MEMORY


def test_the_voted_obstacle_warns_even_when_the_nearer_remembered_one_does_not():
    """A picture with a stale channel (a system error, not a dispute: no forced warning)
    whose obstacle is farther than the remembered one, from reports 300 ms old (the
    timeout: still fresh), is inside its own warning curve; the remembered obstacle, from a
    fresh report, is just beyond its own: the voted obstacle's warning counts."""
    cfg = Config()
    remembered = curves(cfg, V, 0, 0, V, 0)
    voted = curves(cfg, V, 0, 0, V, 300)
    d = normal_driver(cfg)
    d.cycle(present(d.tick, remembered.warning_dm + 34, closing=V), V)       # one cycle's prediction: 32.2 dm
    old = tuple(Report(PRESENT, voted.warning_dm, V, STATIC, d.tick - 300) for _ in range(6))
    out = d.cycle(with_channel(old, 5, Report(DEGRADED, 0, 0, STATIC, d.tick)), V)
    assert out.distance_dm == voted.warning_dm and out.track_dm == remembered.warning_dm + 1
    assert out.system_error and out.reasons & R_MEMORY
    assert out.warning


def test_a_state_without_agreement_counts_starts_them_at_0():
    """A State built without the per-module agreement counts (nine fields, as the exhaustive
    table tests build them) starts them at 0: one calm cycle makes them 1, which does not yet
    clear a disagreement count with persistence_cycles = 2."""
    cfg = Config(persistence_cycles=2)
    d = normal_driver(cfg)
    state = State(NORMAL, d.state.node, MAINTAIN, d.setup.all_seen, (1, 1, 1), 0, 0, 0, 0)
    state, _ = step(d.setup, state, Inputs(clear(d.tick), Train(0)), d.tick)
    assert state.agree == (1, 1, 1) and state.disagree == (1, 1, 1)


def test_the_initial_state_remembers_nothing():
    d = normal_driver(Config())
    start = d.setup.table.start
    assert tuple(initial_state(d.setup)) == (INIT, start, MAINTAIN, 0, (0, 0, 0), 0, 0, 0, 0, (0, 0, 0),
                                             0, ((-1, -1, 0, 0, 0, False),) * 3, False, ((-1, 0, 0, 0, 0, 0, 0),) * 6)


def test_the_memory_defaults_are_the_documented_ones():
    """docs/core.md: forget_ms 7500 (75 cycles of 100 ms), sensor_range_dm 4000."""
    cfg = Config()
    assert (cfg.forget_ms, cfg.sensor_range_dm) == (7500, 4000)
    assert forget_cycles(cfg) == 75



# --------------------------------------------------------------------------- keeping what is held (keep_held)
#
# An obstacle in sight and closing, in the table's zones when the keeping began, keeps what
# is held while the train moves (cycle.py: keep, State.kept; envelope.keep_held). The table
# here never brakes, so the curves, the error rules and the hold alone decide; with Model 1
# the observation is the table's zone itself.

FAR = 40000               # 4 km: beyond the table's zones (alpha1 + 1 km) and every curve at 30 m/s


def keeper(**kw):
    from tests.test_core_cycle import M1, maintain_only

    # its pictures jump: a plausibility window shorter than the period compares no two reports
    return normal_driver(Config(plausibility_ms=1, **kw), maintain_only(M1))


def sees(d, distance: int, closing: int, stale: bool = False) -> tuple:
    reports = present(d.tick, distance, closing=closing)
    return with_channel(reports, 5, Report(DEGRADED, 0, 0, STATIC, d.tick)) if stale else reports


def emergency_inside_ebi(d) -> None:
    """The obstacle at the supervised EBI: an emergency, the table's emergency zone (its
    critical zone ends at the zone limit, without the sampling period), and keeping begins."""
    c = curves(d.cfg, V, 0, 0, V, 0)
    out = d.cycle(sees(d, c.ebi_dm, V), V)
    assert out.demand == EMERGENCY and out.observation == 2 and d.state.kept


def test_standstill_ends_the_keeping():
    """At standstill what is held goes down to the causes' demand, even with an oncoming
    obstacle in sight in the table's zones."""
    d = keeper()
    emergency_inside_ebi(d)
    out = d.cycle(sees(d, 5000, 100), 0)                 # 500 m, oncoming at 1 m/s; the train stands
    assert out.observation == 1 and out.demand == MAINTAIN and not d.state.kept


def test_1_cms_and_a_closing_speed_of_1_cms_keep():
    """1 cm/s is moving, and 1 cm/s of closing speed is closing: what is held is kept however
    long the obstacle stays in the zones."""
    d = keeper()
    emergency_inside_ebi(d)
    for k in range(3 * d.cfg.release_confirm_cycles):
        out = d.cycle(sees(d, 5000, 1), 1)
        assert out.observation >= 1 and out.demand == EMERGENCY and out.reasons & R_LATCH and d.state.kept, k


def test_once_keeping_at_1_cms_the_zones_no_longer_matter():
    """The keeping began in the zones (inside EBI); the obstacle, still in sight and closing
    at 1 cm/s, is then beyond the zones: still kept, the train rolling at 1 cm/s."""
    d = keeper()
    emergency_inside_ebi(d)
    for k in range(3 * d.cfg.release_confirm_cycles):
        out = d.cycle(sees(d, FAR, 1), 1)
        assert out.observation == 0 and out.demand == EMERGENCY and d.state.kept, k


def _released_after_the_confirmation(d, speed: int, closing: int) -> None:
    """The obstacle in sight, closing, beyond the zones: what is held is released after
    exactly release_confirm_cycles calm cycles."""
    n = d.cfg.release_confirm_cycles
    for k in range(n - 1):
        out = d.cycle(sees(d, FAR, closing), speed)
        assert out.observation == 0 and out.demand == EMERGENCY and out.reasons & R_LATCH and not d.state.kept, k
    out = d.cycle(sees(d, FAR, closing), speed)
    assert out.demand == MAINTAIN and not d.state.kept


def test_an_error_s_emergency_is_not_kept_by_an_obstacle_beyond_the_zones():
    """An emergency the error rules raised (a stale channel, safe_reaction emergency) with no
    obstacle in sight: an obstacle then seen closing but beyond the table's zones does not
    keep it."""
    d = keeper()
    out = d.cycle(with_channel(clear(d.tick), 5, Report(DEGRADED, 0, 0, STATIC, d.tick)), V)
    assert out.demand == EMERGENCY and not d.state.kept
    _released_after_the_confirmation(d, V, V)


def test_what_was_raised_at_standstill_is_not_kept_once_moving():
    """An emergency raised at standstill for an oncoming obstacle inside EBI: keeping starts
    only while moving, so once the train rolls (1 cm/s) and the obstacle is beyond the
    zones, the hold's confirmation runs. (Seen there, 4 km away, it is another obstacle: the
    oncoming one, still inside its curves, is forgotten on that evidence at once with
    forget_ms 100, so that only the hold decides.)"""
    d = keeper(forget_ms=100)
    at = ebi_dm(d.cfg, 0, 0, 0, 1000, 0)                 # the zone limit: inside the supervised EBI
    assert at <= curves(d.cfg, 0, 0, 0, 1000, 0).ebi_dm
    out = d.cycle(sees(d, at, 1000), 0)
    assert out.demand == EMERGENCY and out.observation == 3 and not d.state.kept
    _released_after_the_confirmation(d, 1, 1)


def test_an_obstacle_in_the_zones_with_nothing_held_starts_no_keeping():
    """An obstacle in sight in the table's zones, beyond every curve: nothing is
    held, so nothing is kept; an emergency raised next (a stale channel, the obstacle now
    beyond the zones) is released after the confirmation."""
    d = keeper()
    c = curves(d.cfg, V, 0, 0, V, 0)
    out = d.cycle(sees(d, c.warning_dm + 100, V), V)
    assert out.observation >= 1 and out.demand == MAINTAIN and not d.state.kept
    out = d.cycle(sees(d, FAR, V, stale=True), V)
    assert out.demand == EMERGENCY and not d.state.kept
    _released_after_the_confirmation(d, V, V)


def test_the_safe_stop_fallback_reports_no_track():
    """step's fallback for anything unforeseen: no remembered obstacle in its outputs
    (track_dm 65535, track_cycles 0, track_state none), as the C core's fallback writes."""
    d = normal_driver(Config())
    state, out = step(d.setup, d.state, None, d.tick)
    assert (out.track_dm, out.track_cycles, out.track_state) == (65535, 0, 0)


# --- issue 38 item 1: what any module saw is remembered

def seen_by(tick: int, distance: int, modules: tuple) -> tuple:
    """Both channels of each module in `modules` see an obstacle at `distance`; the others ABSENT."""
    return tuple(Report(PRESENT, distance, 0, STATIC, tick) if i // 2 in modules else Report(ABSENT, 0, 0, STATIC, tick)
                 for i in range(6))


def test_two_modules_seeing_what_the_third_disputes_create_a_strong_track_held_for_forget_ms():
    cfg = Config()
    d = normal_driver(cfg, M1)
    out = d.cycle(seen_by(d.tick, 1500, (1, 2)), 0)
    assert out.system_error and out.reasons & R_DISPUTE
    assert out.track_state == TRACK_SEEN and out.track_dm == 1500 and not out.reasons & R_MEMORY
    assert d.state.track_strong
    for k in range(forget_cycles(cfg) - 1):                  # blind: evidence, but not enough
        out = d.clear(0)
        assert out.track_state == TRACK_CONFIRMING and out.reasons & R_MEMORY, k
    assert d.clear(0).track_state == TRACK_FORGOTTEN


def test_one_module_alone_creates_a_weak_track_forgotten_after_forget_single_ms():
    cfg = Config(forget_single_ms=350)                       # 4 cycles (rounded up)
    n = forget_cycles(cfg, single=True)
    assert n == 4 and forget_cycles(cfg) == 75
    d = normal_driver(cfg, M1)
    out = d.cycle(seen_by(d.tick, 1500, (2,)), 0)
    assert out.track_state == TRACK_SEEN and out.track_dm == 1500 and not d.state.track_strong
    for k in range(n - 1):
        assert d.clear(0).track_state == TRACK_CONFIRMING, k
    out = d.clear(0)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == NO_DISTANCE
    # forget_single_ms never makes a track last longer than forget_ms
    assert forget_cycles(Config(forget_ms=200, forget_single_ms=5000), single=True) == 2


def test_one_channel_alone_creates_nothing_and_a_second_module_makes_a_weak_track_strong():
    cfg = Config(forget_single_ms=100)
    d = normal_driver(cfg, M1)
    out = d.cycle(tuple(Report(PRESENT, 1500, 0, STATIC, d.tick) if i == 4 else Report(ABSENT, 0, 0, STATIC, d.tick)
                        for i in range(6)), 0)
    assert out.track_state == TRACK_NONE                     # module 2 split: its 2oo2 does not see it
    d.cycle(seen_by(d.tick, 1500, (0,)), 0)
    assert not d.state.track_strong
    d.cycle(seen_by(d.tick, 1500, (0, 1)), 0)
    assert d.state.track_strong
    for _ in range(5):                                       # now held for forget_ms, not 100 ms
        assert d.clear(0).track_state == TRACK_CONFIRMING


def test_a_module_s_sighting_where_the_track_can_be_takes_its_position_one_beyond_does_not():
    """At 30 m/s the worst-case prediction runs ahead of the last position (near < far); a
    sighting in between is the remembered obstacle seen where it can be."""
    d = normal_driver(Config(), M2)
    d.cycle(seen_by(d.tick, 30000, (1, 2)), 3000)
    near, far = d.state.track_near, d.state.track_far
    assert near < far == 30000 * UNITS_PER_DM
    out = d.cycle(seen_by(d.tick, 30000, (1, 2)), 3000)     # at far: taken
    assert out.track_state == TRACK_SEEN and out.track_dm == 30000
    d.cycle(seen_by(d.tick, 29800, (1, 2)), 3000)
    out = d.cycle(seen_by(d.tick, 29801, (1, 2)), 3000)     # one dm beyond far: kept
    assert out.track_state == TRACK_HELD and out.track_dm < 29800 and out.reasons & R_MEMORY


def test_in_the_2oo2_topology_the_confirmed_single_module_is_strong_its_distance_dispute_weak():
    cfg = Config(topology="2oo2", forget_single_ms=100)
    d = normal_driver(cfg, M1)
    d.cycle(present(d.tick, 1500, n=2), 0)
    assert d.state.track_strong
    d = normal_driver(cfg, M1)
    d.cycle((Report(PRESENT, 1500, 0, STATIC, d.tick), Report(PRESENT, 1500 + cfg.distance_tolerance_dm + 1, 0, STATIC,
                                                                d.tick)), 0)
    assert d.state.track_far == 1500 * UNITS_PER_DM and not d.state.track_strong


def test_a_strong_track_seen_later_by_one_module_alone_stays_strong():
    cfg = Config(forget_single_ms=100)
    d = normal_driver(cfg, M1)
    d.cycle(seen_by(d.tick, 1500, (0, 1)), 0)
    d.cycle(seen_by(d.tick, 1500, (2,)), 0)
    assert d.state.track_strong
    for _ in range(5):
        assert d.clear(0).track_state == TRACK_CONFIRMING
