"""Adverse conditions are monotone (issue 11, deliverable 3).

The exhaustive check (verification/monotone.py) on the shipped tables and on a table made to
fail it; then a Hypothesis property over the real core with the shipped m2 table: the same
history of reports and speeds, once with the conditions the first run reports and once with
slippery track and/or degraded brakes added, never demands less on the adverse side.
"""
from __future__ import annotations

import itertools

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from monitor import tables
from monitor.core.config import Config
from monitor.core.cycle import create, initial_state, step
from monitor.core.observation import M2_OBSERVATIONS
from monitor.core.table import decode, encode
from monitor.core.types import ABSENT, PRESENT, Inputs, Report, Train
from verification import monotone
from verification.monotone import check, observation_pairs, raised

# --------------------------------------------------------------------------- the exhaustive check


@pytest.mark.parametrize("name", ["m1", "m2"])
def test_shipped_tables_pass_the_exhaustive_check(name):
    res = check(decode(tables.read(name)))
    assert res.monotone, res.describe()
    assert res.history == ()
    assert res.pairs_reached >= res.nodes  # at least the diagonal (n, n) of every reachable node


def test_m2_pairs_every_observation_with_its_raised_conditions():
    """36 base pictures x 9 (track, brake) pairs with the second at least as adverse: 324;
    m1 has no condition components, so it pairs each observation with itself only."""
    pairs = observation_pairs(M2_OBSERVATIONS)
    assert len(pairs) == 36 * 9
    for o, o2 in pairs:
        a, b = M2_OBSERVATIONS[o].split("-"), M2_OBSERVATIONS[o2].split("-")
        assert a[:3] == b[:3]
        assert (a[3], b[3]) in {("normal", "normal"), ("normal", "slippery"), ("slippery", "slippery")}
        assert (a[4], b[4]) in {("normal", "normal"), ("normal", "degraded"), ("degraded", "degraded")}
    m1 = decode(tables.read("m1"))
    assert observation_pairs(m1.observations).tolist() == [[o, o] for o in range(len(m1.observations))]
    assert sorted(raised("far-away-static-normal-normal")) == sorted(
        f"far-away-static-{k}-{b}" for k, b in itertools.product(("normal", "slippery"), ("normal", "degraded")))


def m2_table(action: list[int], nxt: list[list[int]]) -> bytes:
    header = {"model": "m2", "states": list(M2_OBSERVATIONS), "observations": list(M2_OBSERVATIONS),
              "actions": ["maintain", "nominal_braking", "emergency_braking"], "start": 0}
    return encode(header, action, nxt)


def name_has_adverse(name: str) -> bool:
    return name.endswith(("-slippery-normal", "-normal-degraded", "-slippery-degraded"))


def test_a_non_monotone_table_fails_with_a_shortest_history():
    """Node 0 goes to 1 on normal conditions and to 2 on adverse ones; 1 goes to 3 (service),
    2 to 4 (maintain), whatever is observed. Depth 1 is harmless (1 and 2 both maintain);
    the first violation is two cycles deep, and node 4 also leads to 5 (maintain) so longer
    histories exist that the report must not prefer."""
    Z = len(M2_OBSERVATIONS)
    adverse = [name_has_adverse(n) for n in M2_OBSERVATIONS]
    nxt = [[2 if adverse[o] else 1 for o in range(Z)], [3] * Z, [4] * Z, [3] * Z, [5] * Z, [5] * Z]
    res = check(decode(m2_table([0, 0, 0, 1, 0, 0], nxt)))
    assert not res.monotone
    assert len(res.history) == 2
    first, second = res.history
    assert not name_has_adverse(first.normal) and name_has_adverse(first.adverse)
    assert first.adverse in raised(first.normal)
    assert (first.normal_node, first.adverse_node) == (1, 2)
    assert (second.normal_node, second.adverse_node) == (3, 4)
    assert second.adverse in raised(second.normal)
    assert res.demands == ("nominal_braking", "maintain")
    assert res.violations == 2  # (3, 4) and (3, 5)
    # the history replays through the table to the nodes it names
    t = decode(m2_table([0, 0, 0, 1, 0, 0], nxt))
    n, n2 = t.start, t.start
    for s in res.history:
        n, n2 = t.next[n][M2_OBSERVATIONS.index(s.normal)], t.next[n2][M2_OBSERVATIONS.index(s.adverse)]
        assert (n, n2) == (s.normal_node, s.adverse_node)
    text = res.describe()
    assert first.normal in text and first.adverse in text and "nominal_braking" in text


def test_condition_blind_and_stronger_tables_pass_a_weaker_one_fails():
    Z = len(M2_OBSERVATIONS)
    adverse = [name_has_adverse(n) for n in M2_OBSERVATIONS]
    blind = m2_table([0, 1], [[1] * Z, [0] * Z])
    assert check(decode(blind)).monotone
    more = m2_table([0, 0, 2], [[2 if adverse[o] else 1 for o in range(Z)]] * 3)
    assert check(decode(more)).monotone
    # the same table with the two targets swapped brakes less under adverse conditions
    less = m2_table([0, 0, 2], [[1 if adverse[o] else 2 for o in range(Z)]] * 3)
    res = check(decode(less))
    assert not res.monotone and len(res.history) == 1 and res.demands == ("emergency_braking", "maintain")


def test_verify_section_reports_both_tables(tmp_path):
    sec = monotone.section(tmp_path, True, lambda text: None)
    assert [c.passed for c in sec.checks] == [True, True]
    assert all("violating" in c.figure for c in sec.checks)


# --------------------------------------------------------------------------- the real core

SETUP = create(Config(), tables.read("m2"), expect_model="m2")
HELD = create(Config(emergency_release=0), tables.read("m2"), expect_model="m2")
CHANNELS = SETUP.config.channels
PERIOD = SETUP.config.period_ms

speeds = st.one_of(st.integers(0, 6000), st.sampled_from([0, 1, 500, 2000, 4000]), st.integers(0, 12000))
distances = st.one_of(st.integers(0, 12000), st.integers(0, 60000), st.sampled_from([0, 780, 1000, 2000, 3000]))
closings = st.one_of(st.integers(-1500, 6000), st.sampled_from([0, 2000, 4000]))
pictures = st.one_of(
    st.tuples(st.just("clear"), st.just(0), st.just(0), st.just(0), st.just(0)),
    st.tuples(st.just("obstacle"), distances, closings, st.integers(0, 2), st.integers(0, 3)),
    st.tuples(st.just("one_absent"), distances, closings, st.integers(0, 2), st.integers(0, CHANNELS - 1)),
    st.tuples(st.just("one_stale"), distances, closings, st.integers(0, 2), st.integers(0, CHANNELS - 1)),
)
# (picture, speed, conditions of the first run, conditions added for the second)
cycles = st.tuples(pictures, speeds, st.tuples(st.integers(0, 1), st.integers(0, 1)),
                   st.tuples(st.integers(0, 1), st.integers(0, 1)))


def reports(picture, tick: int) -> tuple:
    kind, d, closing, obstacle, extra = picture
    if kind == "clear":
        return tuple(Report(ABSENT, 0, 0, 0, tick) for _ in range(CHANNELS))
    seen = [Report(PRESENT, d + (i * extra if kind == "obstacle" else 0), closing, obstacle, tick)
            for i in range(CHANNELS)]
    if kind == "one_absent":
        seen[extra] = Report(ABSENT, 0, 0, 0, tick)
    elif kind == "one_stale":
        seen[extra] = seen[extra]._replace(tick=tick - 10 * PERIOD * SETUP.config.timeout_cycles)
    return tuple(seen)


def run_pair(setup, history):
    """Demands of the two runs, cycle by cycle."""
    a, b = initial_state(setup), initial_state(setup)
    out = []
    for i, (picture, speed, (k, br), (rk, rb)) in enumerate(history):
        tick = (i + 1) * PERIOD
        seen = reports(picture, tick)
        a, oa = step(setup, a, Inputs(seen, Train(speed, k, br)), tick)
        b, ob = step(setup, b, Inputs(seen, Train(speed, k | rk, br | rb)), tick)
        out.append((oa.demand, ob.demand, oa, ob))
    return out


@pytest.mark.parametrize("setup", [SETUP, HELD], ids=["default-release", "held-to-standstill"])
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(history=st.lists(cycles, min_size=1, max_size=60))
def test_adverse_conditions_never_lower_the_core_demand(setup, history):
    for i, (normal, adverse, oa, ob) in enumerate(run_pair(setup, history)):
        assert adverse >= normal, (i, oa, ob)


@settings(max_examples=100, deadline=None)
@given(history=st.lists(st.tuples(st.tuples(st.just("obstacle"), st.integers(780, 2000), st.just(2000),
                                            st.just(0), st.just(0)),
                                  st.just(2000), st.just((0, 0)), st.just((1, 1))), min_size=30, max_size=30))
def test_issue_scenario_obstacle_held_at_78_to_210_m_at_20_m_s(history):
    """Issue 11's case: a static obstacle 78-200 m ahead at 20 m/s for 30 cycles; the run with
    slippery track and degraded brakes reported demands at least as much, every cycle."""
    pairs = run_pair(SETUP, history)
    assert all(adverse >= normal for normal, adverse, _, _ in pairs)
    assert sum(adverse > 0 for _, adverse, _, _ in pairs) >= sum(normal > 0 for normal, _, _, _ in pairs)
