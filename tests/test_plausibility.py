"""Plausibility of what is reported (issue 38 item 3): a distance that does not shrink as the
channel's own closing speed says is a fault of that channel (DEGRADED, reason `implausible`);
a common freeze of every channel brakes. The rule alone (monitor/core/plausibility.py), in
the core, the issue's world as users run it: tests/test_frozen_sensors.py.
C == Python on frozen sequences: tests/test_fmu_equivalence.py (frozen_steps); the twin:
tests/test_fastcore.py."""
from __future__ import annotations

import pytest

from monitor.core.config import Config
from monitor.core.cycle import create, initial_state, step
from monitor.core.plausibility import NO_REFERENCE, check
from monitor.core.types import (
    DEGRADED_MODE, EMERGENCY, PRESENT, R_IMPLAUSIBLE, R_STALE, STATIC, Inputs, Report, Train,
)
from monitor.tables import read

ACC_DM, ACC_CMS, WINDOW = 500, 100, 30000       # the defaults
V = 3000                                        # 30 m/s


def run(reports, accuracy_dm=ACC_DM, accuracy_cms=ACC_CMS, window=WINDOW):
    """The states after each (present, distance_dm, closing_cms, tick)."""
    state, states = NO_REFERENCE, []
    for present, d, c, t in reports:
        state = check(state, present, d, c, t, accuracy_dm, accuracy_cms, window)
        states.append(state)
    return states


def frozen(distance_dm: int, closing_cms: int, cycles: int, period: int = 100) -> list:
    return [(True, distance_dm, closing_cms, k * period) for k in range(cycles)]


def test_a_frozen_report_is_implausible_exactly_when_its_closing_speed_s_travel_exceeds_the_tolerance():
    """Stuck at 2,200 m while saying 30 m/s: at span T ms the obstacle ran at least 3000 T units
    and the tolerance is 2 x 500 dm + 100 T units, so the first report with 2900 T > 1e7 (T >
    3448 ms) is implausible: the one at 3500 ms, not the one at 3400 ms."""
    states = run(frozen(22000, V, 40))
    bad = [k for k, s in enumerate(states) if s[6]]
    assert bad and bad[0] == 35 and all(s[6] for s in states[35:])
    # exactly on the tolerance is still plausible (strict), one unit beyond is not
    edge = run([(True, 20000, 1000, 0), (True, 20000 - 100 + 1000, 1000, 1000)], accuracy_cms=0)
    assert not edge[-1][6]          # ran 1e6 units (100 dm), tolerance 1e7 units (1000 dm): 20900 is the bound
    beyond = run([(True, 20000, 1000, 0), (True, 20000 - 100 + 1001, 1000, 1000)], accuracy_cms=0)
    assert beyond[-1][6]


def test_an_honest_approach_with_noise_within_the_accuracy_stays_plausible():
    reports = [(True, 22000 - 30 * k + (400 if k % 2 else -400), V, 100 * k) for k in range(400)]
    assert not any(s[6] for s in run(reports))


def test_the_lower_closing_speed_of_each_pair_counts():
    """Braking from 30 to 10 m/s over 2 s: the obstacle ran at least the lower speed of each
    pair; reports that follow the true travel stay plausible, reports that stop moving do not."""
    closing = [V - 100 * k for k in range(21)] + [1000] * 40
    d, reports = 30000, []
    for k, c in enumerate(closing):
        reports.append((True, d, c, 100 * k))
        d -= c * 100 // 10000
    assert not any(s[6] for s in run(reports, accuracy_dm=0, accuracy_cms=0))
    stuck = [(True, 30000, c, 100 * k) for k, c in enumerate(closing)]
    assert any(s[6] for s in run(stuck, accuracy_dm=100))         # ran >= 80 m, tolerance 20 m + 1 m/s


def test_nearer_is_never_a_fault_and_starts_a_new_reference():
    """Something entering the track in front: a report far nearer than the obstacle can be
    is a new object, not a fault; the new reference then judges what follows."""
    states = run([(True, 40000, 0, 0), (True, 40000, 0, 100), (True, 5000, 0, 200)])
    assert not states[-1][6] and states[-1][0] == 5000 and states[-1][1] == 200


def test_farther_than_possible_is_a_fault_until_a_whole_window_agrees():
    states = run([(True, 10000, 0, 0), (True, 12000, 0, 100)] + [(True, 12000, 0, 100 + 100 * k) for k in range(1, 11)],
                 window=1000)
    assert states[1][6] and all(s[6] for s in states[1:11]) and not states[11][6]


def test_a_channel_that_is_not_present_drops_its_reference_and_its_fault():
    states = run([(True, 10000, 0, 0), (True, 12000, 0, 100), (False, 0, 0, 0), (True, 30000, 0, 300)])
    assert states[1][6] and states[2] == NO_REFERENCE and not states[3][6] and states[3][0] == 30000


def test_a_repeated_report_is_no_new_evidence_and_a_gap_starts_a_new_reference():
    states = run([(True, 10000, V, 0), (True, 10000, V, 0), (True, 10000, V, 0)])
    assert states[1] == states[2] == (10000, 0, 0, V, 0, 0, 0)
    gap = run([(True, 10000, V, 0), (True, 10000, V, 31000)])     # later than a window
    assert gap[-1] == (10000, 31000, 31000, V, 0, 0, 0)


# ---------------------------------------------------------------- in the core

def _core(cfg=Config()):
    setup = create(cfg, read("m2"))
    return setup, initial_state(setup)


def _cycle(setup, state, tick, distances, closing=V, speed=V):
    reports = tuple(Report(PRESENT, d, closing, STATIC, tick) for d in distances)
    return step(setup, state, Inputs(reports, Train(speed)), tick)


def test_one_frozen_channel_is_degraded_and_named_a_common_freeze_brakes():
    setup, state = _core()
    d = 40000
    for k in range(60):
        tick = 100 * k
        frozen_d = 40000                                           # channel 3 stuck from the start
        state, out = _cycle(setup, state, tick, [d, d, d, frozen_d, d, d])
        d -= 30
    assert out.reasons & R_IMPLAUSIBLE and out.reasons & R_STALE and out.module_flags == 0b010
    assert state.plaus[3][6] and not any(state.plaus[i][6] for i in (0, 1, 2, 4, 5))
    assert out.distance_dm == d + 30 and out.mode == DEGRADED_MODE
    # every channel frozen: nothing PRESENT is believed, the picture is DEGRADED, emergency
    setup, state = _core()
    outs = []
    for k in range(60):
        state, out = _cycle(setup, state, 100 * k, [22000] * 6)
        outs.append(out)
    first = next(k for k, o in enumerate(outs) if o.reasons & R_IMPLAUSIBLE)
    assert first == 35 and all(o.demand == EMERGENCY and o.reasons & R_IMPLAUSIBLE for o in outs[first:])
    assert all(o.demand == 0 for o in outs[1:first])               # (2,200 m at 30 m/s: beyond every curve)


# ---------------------------------------------------------------- the state, field by field

def test_what_each_outcome_leaves_behind_exactly():
    """Implausible, nearer, a whole window, an out-of-order report and a continuing one: each
    returns the documented tuple (ref_dm, ref_tick, last_tick, last_closing, lo, hi, bad)."""
    a = (True, 20000, 1000, 0)
    # farther than possible: a new reference, implausible
    bad = run([a, (True, 21001, 1000, 1000)], accuracy_cms=0)[-1]
    assert bad == (21001, 1000, 1000, 1000, 0, 0, 1)
    # a fault is carried, as 1, through reports that agree and a report out of order
    carried = run([a, (True, 21001, 1000, 1000), (True, 20901, 1000, 2000)], accuracy_cms=0)[-1]
    assert carried == (21001, 1000, 2000, 1000, 1000000, 1000000, 1)
    back = run([a, (True, 21001, 1000, 1000), (True, 20901, 1000, 2000), (True, 20000, 1000, 1999)],
               accuracy_cms=0)[-1]
    assert back == (20000, 1999, 1999, 1000, 0, 0, 1)
    behind = run([a, (True, 20000, 1000, 100), (True, 20000, 1000, 99)])[-1]     # one tick back: no evidence
    assert behind == (20000, 99, 99, 1000, 0, 0, 0)
    # nearer than possible (the most it ran: 100 dm; tolerance 1000 dm): 18899 is new, 18900 is not
    nearer = run([a, (True, 18899, 1000, 1000)], accuracy_cms=0)[-1]
    assert nearer == (18899, 1000, 1000, 1000, 0, 0, 0)
    inside = run([a, (True, 18900, 1000, 1000)], accuracy_cms=0)[-1]
    assert inside == (20000, 0, 1000, 1000, 1000000, 1000000, 0)
    # the most it ran counts the higher closing speed of the pair: 2000 cm/s for 1 s is 200 dm
    faster = run([(True, 20000, 1000, 0), (True, 18800, 2000, 1000)], accuracy_cms=0)[-1]
    assert faster == (20000, 0, 1000, 2000, 1000000, 2000000, 0)
    # a whole window that agrees clears the fault, exactly at the window; one later is a gap
    cleared = run([a, (True, 21001, 1000, 1000), (True, 20001, 1000, 2000)], accuracy_cms=0, window=1000)[-1]
    assert cleared == (20001, 2000, 2000, 1000, 0, 0, 0)
    gap = run([a, (True, 21001, 1000, 1000), (True, 20000, 1000, 2001)], accuracy_cms=0, window=1000)[-1]
    assert gap == (20000, 2001, 2001, 1000, 0, 0, 1)
