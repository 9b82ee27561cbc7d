"""Exhaustive checks of the shipped policy tables through the real core.

Structure: every (node, observation) pair of both tables, as loaded by `create()`, leads to a
valid node and every node's action is a brake demand. Behaviour: for every node and every
observation, a cycle from that node with a picture that produces the observation moves to
`next[node][obs]` and demands at least `action[next]`.
"""
from __future__ import annotations

import itertools
from pathlib import Path

import pytest

import monitor
from monitor.core.config import Config
from monitor.core.cycle import create, step
from monitor.core.braking import curves, ebi_dm
from monitor.core.envelope import supervision_demand
from monitor.core.observation import M1_OBSERVATIONS, M2_OBSERVATIONS
from monitor.core.table import decode
from monitor.core.types import (
    ABSENT, DEGRADED_MODE, EMERGENCY, NO_DISTANCE, NORMAL, PRESENT, R_ENVELOPE, R_TABLE, SAFE_STOP,
    STATIC, Inputs, Report, State, Train,
)

TABLES = Path(monitor.__file__).resolve().parent / "tables"
BYTES = {m: (TABLES / f"{m}.table.rgt").read_bytes() for m in ("m1", "m2")}
CFG = Config()
NOW = 10_000
MAX_CLOSING = 15000

DIST = ("far", "medium", "close", "critical")
SPEED = ("away", "slow", "fast")
KIND = ("static", "dynamic", "train")
TRACK = ("normal", "slippery")
BRAKE = ("normal", "degraded")


@pytest.fixture(scope="module", params=["m1", "m2"])
def setup(request):
    return create(CFG, BYTES[request.param], expect_model=request.param)


def state_at(setup, node: int, mode: int = NORMAL) -> State:
    return State(mode, node, False, setup.all_seen, (0,) * setup.config.modules, 0, 0, 0, 0)


def alphas(speed: int, closing: int = 0) -> tuple[int, int]:
    """The table's zone limits: EBI and the service curve under normal conditions (fresh
    reports), as zone limits (braking.ebi_dm: without the supervision's sampling period)."""
    a2 = ebi_dm(CFG, speed, 0, 0, closing, 0)
    return max(a2, ebi_dm(CFG, speed, 0, 0, closing, 0, service=True)), a2


def ladder(d: int, speed: int, closing: int = 0, track: int = 0, brake: int = 0) -> int:
    """The supervision's demand for a fresh obstacle at d, nothing held."""
    c = curves(CFG, speed, track, brake, closing, 0)
    return supervision_demand(d != NO_DISTANCE, d, c.ebi_dm, c.sbi_dm, c.warning_dm, False)[0]


def zone_distances(speed: int, closing: int = 0) -> dict:
    """Distances (dm) that lie in each zone at this speed, including every zone boundary."""
    a1, a2 = alphas(speed, closing)
    w = CFG.warning_margin_dm
    cand = {3: [0, a2 // 2, a2], 2: [a2 + 1, (a2 + a1) // 2, a1], 1: [a1 + 1, a1 + w],
            0: [a1 + w + 1, a1 + w + 5000, 60000]}
    return {z: sorted({d for d in ds if 0 <= d <= 60000 and zone_of(d, speed, closing) == z}) for z, ds in cand.items()}


def zone_of(d: int, speed: int, closing: int = 0) -> int:
    a1, a2 = alphas(speed, closing)
    if d <= a2:
        return 3
    if d <= a1:
        return 2
    if d <= a1 + CFG.warning_margin_dm:
        return 1
    return 0


def all_present(distance: int, closing: int = 0, kind: int = STATIC, n: int = 6) -> tuple:
    return tuple(Report(PRESENT, distance, closing, kind, NOW) for _ in range(n))


def all_absent(n: int = 6) -> tuple:
    return tuple(Report(ABSENT, 0, 0, STATIC, NOW) for _ in range(n))


# --------------------------------------------------------------------------- structure


def test_every_entry_of_the_table_is_valid(setup):
    table = setup.table
    z = len(table.observations)
    assert table.nodes == len(setup.action) == len(setup.next) >= 1
    assert 0 <= table.start < table.nodes
    assert len(table.actions) == 3
    for node in range(table.nodes):
        assert setup.action[node] in (0, 1, 2), node
        row = setup.next[node]
        assert len(row) == z, node
        for obs in range(z):
            nxt = row[obs]
            assert isinstance(nxt, int) and 0 <= nxt < table.nodes, (node, obs, nxt)
            assert setup.action[nxt] in (0, 1, 2)


def test_table_dimensions_are_the_models():
    s1, s2 = create(CFG, BYTES["m1"]), create(CFG, BYTES["m2"])
    assert s1.table.observations == M1_OBSERVATIONS and len(M1_OBSERVATIONS) == 4
    assert s2.table.observations == M2_OBSERVATIONS and len(M2_OBSERVATIONS) == 144
    assert s1.table.actions == s2.table.actions == ("maintain", "nominal_braking", "emergency_braking")
    # the table the core runs is the file's own content
    for m, s in (("m1", s1), ("m2", s2)):
        t = decode(BYTES[m])
        assert s.action == t.action and s.next == t.next and s.table.sha256 == t.sha256


def test_every_node_is_reachable_from_the_start(setup):
    seen = {setup.table.start}
    todo = [setup.table.start]
    while todo:
        node = todo.pop()
        for nxt in setup.next[node]:
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    assert seen == set(range(setup.table.nodes))


def test_core_observation_names_equal_the_offline_builders():
    from monitor.offline.models import model1, model2

    assert M2_OBSERVATIONS == tuple(model2.state_name(t) for t in model2.state_tuples())
    assert M1_OBSERVATIONS == tuple(model1.OBSERVATIONS)
    assert tuple(decode(BYTES["m2"]).observations) == M2_OBSERVATIONS
    assert tuple(decode(BYTES["m1"]).observations) == M1_OBSERVATIONS


# --------------------------------------------------------------------------- m1 behaviour


def m1_pictures():
    """(speed, obs, reports, distance) for every zone at several speeds, boundaries included."""
    out = []
    for speed in (1000, 4000, 8000, 12000):
        for z, ds in zone_distances(speed).items():
            for d in ds:
                out.append((speed, z, all_present(d), d))
        out.append((speed, 0, all_absent(), NO_DISTANCE))
    covered = {(s, z) for s, z, _, _ in out}
    assert all((s, z) in covered for s in (1000, 4000) for z in range(4))
    return out


M1_PICTURES = m1_pictures()


@pytest.mark.parametrize("mode", [NORMAL, DEGRADED_MODE, SAFE_STOP])
def test_m1_every_node_and_observation_through_the_core(mode):
    setup = create(CFG, BYTES["m1"])
    table = setup.table
    hits = set()
    for node in range(table.nodes):
        for speed, obs, reports, d in M1_PICTURES:
            _, out = step(setup, state_at(setup, node, mode), Inputs(reports, Train(speed)), NOW)
            ctx = (node, obs, speed, d, out)
            assert not out.system_error, ctx
            assert out.observation == obs, ctx
            assert M1_OBSERVATIONS[out.observation] == ("free", "warning", "emergency", "critical")[obs]
            assert out.distance_dm == d, ctx
            nxt = table.next[node][obs]
            assert out.node == nxt, ctx
            assert out.demand >= table.action[nxt], ctx
            if mode == NORMAL:
                assert out.mode == NORMAL, ctx
                # nothing else asks for braking but the curves (emergency in the critical zone)
                expected = max(table.action[nxt], ladder(d, speed))
                assert out.demand == expected, ctx
                assert bool(out.reasons & R_TABLE) == (table.action[nxt] > 0), ctx
                # the supervised EBI counts the sampling period: it reaches beyond the critical zone
                assert bool(out.reasons & R_ENVELOPE) == (d != NO_DISTANCE and d <= curves(CFG, speed, 0, 0, 0, 0).ebi_dm), ctx
                assert obs < 3 or out.reasons & R_ENVELOPE, ctx
            elif mode == SAFE_STOP:
                assert out.mode == SAFE_STOP and out.demand == EMERGENCY, ctx
            hits.add((node, obs))
    assert hits == set(itertools.product(range(table.nodes), range(4)))


def test_m1_a_run_follows_the_table():
    """Several cycles in a row: the node follows next[][] from the start, obs by obs (the
    pictures jump between zones: sensors declared 6 km inaccurate keep them plausible)."""
    setup = create(CFG._replace(distance_accuracy_dm=60000), BYTES["m1"])
    table = setup.table
    state = state_at(setup, table.start)
    node = table.start
    zones = zone_distances(4000)
    script = [0, 1, 2, 1, 0, 3, 3, 2, 0, 0, 1, 1, 2, 2, 3, 0, 2, 3, 1, 0] * 3
    for k, obs in enumerate(script):
        reports = all_absent() if obs == 0 and k % 2 else all_present(zones[obs][k % len(zones[obs])])
        reports = tuple(r._replace(tick=NOW + 100 * k) for r in reports)
        state, out = step(setup, state, Inputs(reports, Train(4000)), NOW + 100 * k)
        node = table.next[node][obs]
        assert out.mode == NORMAL
        assert out.observation == obs
        assert out.node == node
        assert out.demand >= table.action[node]


# --------------------------------------------------------------------------- m2 behaviour


M2_CLOSING = {0: -100, 1: 500, 2: 3000}   # away, slow (< fast_closing_cms = 2000), fast


def m2_pictures(speed: int = 4000):
    """One picture per observation: every combination of component values."""
    pics = []
    for z, s, kind, track, brake in itertools.product(range(4), range(3), range(3), range(2), range(2)):
        zones = zone_distances(speed, M2_CLOSING[s])
        d = zones[z][len(zones[z]) // 2]
        reports = all_present(d, M2_CLOSING[s], kind)
        name = f"{DIST[z]}-{SPEED[s]}-{KIND[kind]}-{TRACK[track]}-{BRAKE[brake]}"
        pics.append((name, z, reports, Train(speed, track, brake)))
    return pics


def test_m2_observation_of_constructed_pictures_has_the_expected_name():
    setup = create(CFG, BYTES["m2"])
    seen = set()
    for speed in (1000, 4000):
        for name, z, reports, train in m2_pictures(speed):
            _, out = step(setup, state_at(setup, setup.table.start), Inputs(reports, train), NOW)
            assert not out.system_error
            assert M2_OBSERVATIONS[out.observation] == name, (name, out)
            seen.add(out.observation)
    assert seen == set(range(144))


def test_m2_mixed_channels_take_the_worst_closing_speed_and_obstacle_type():
    setup = create(CFG, BYTES["m2"])
    reports = tuple(Report(PRESENT, 30000, c, k, NOW)
                    for c, k in ((-100, 0), (2500, 0), (100, 2), (-5, 1), (0, 0), (1999, 1)))
    _, out = step(setup, state_at(setup, 0), Inputs(reports, Train(4000, 1, 0)), NOW)
    assert M2_OBSERVATIONS[out.observation] == "far-fast-train-slippery-normal"


@pytest.mark.parametrize("closing, expected", [
    (-MAX_CLOSING, "away"), (-1, "away"), (0, "slow"), (1, "slow"),
    (CFG.fast_closing_cms - 1, "slow"), (CFG.fast_closing_cms, "fast"), (MAX_CLOSING, "fast"),
])
def test_m2_speed_class_boundaries(closing, expected):
    setup = create(CFG, BYTES["m2"])
    _, out = step(setup, state_at(setup, 0), Inputs(all_present(30000, closing), Train(4000)), NOW)
    assert not out.system_error
    assert M2_OBSERVATIONS[out.observation].split("-")[1] == expected


def test_m2_clear_track_is_far():
    setup = create(CFG, BYTES["m2"])
    for track, brake in itertools.product(range(2), range(2)):
        _, out = step(setup, state_at(setup, 0), Inputs(all_absent(), Train(4000, track, brake)), NOW)
        name = M2_OBSERVATIONS[out.observation].split("-")
        assert name[0] == "far" and name[3] == TRACK[track] and name[4] == BRAKE[brake]
        assert out.distance_dm == NO_DISTANCE


def test_m2_every_node_and_observation_through_the_core():
    setup = create(CFG, BYTES["m2"])
    table = setup.table
    pics = m2_pictures(4000)
    hits = 0
    for node in range(table.nodes):
        state = state_at(setup, node)
        row = table.next[node]
        for name, z, reports, train in pics:
            _, out = step(setup, state, Inputs(reports, train), NOW)
            obs = out.observation
            assert M2_OBSERVATIONS[obs] == name
            nxt = row[obs]
            assert out.mode == NORMAL
            assert out.node == nxt, (node, name, out)
            assert out.demand >= table.action[nxt]
            d, closing = reports[0].distance_dm, reports[0].closing_cms
            expected = max(table.action[nxt], ladder(d, train.speed_cms, closing, train.track, train.brake))
            assert z < 3 or expected == EMERGENCY
            assert out.demand == expected, (node, name, out)
            hits += 1
    assert hits == table.nodes * 144
