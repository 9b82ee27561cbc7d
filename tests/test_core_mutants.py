"""Deterministic tests on the core's behaviour at its exact boundaries (issue 14, item 5).

Mutation testing (`verification/mutation/`) found behaviours of `monitor/core` that the
example-based, property-based and stateful tests let change unnoticed: a flag raised by one
module alone, the direction of a 2oo2 disagreement, the exact distance tolerance, exactly
alpha2, obstacle code 3, the status taken as min instead of max, non-int fields taken as
valid, 1 cm/s and the latch, ... Each test here pins one such behaviour with plain asserts
on values written out (or computed independently) and says in its docstring which
behaviour it pins. Everything runs through the real core: the small functions directly,
against their documented contracts, and whole cycles through `create`/`step`.
"""
from __future__ import annotations

import json

import pytest

from monitor.core import voter
from monitor.core.config import Config
from monitor.core.cycle import create, initial_state, step
from monitor.core.types import (
    ABSENT, DEGRADED, DEGRADED_MODE, EMERGENCY, MAINTAIN, NORMAL, PRESENT, R_DISPUTE, R_ENVELOPE, R_STALE,
    R_SYSTEM_ERROR, SERVICE, STATIC, Inputs, Report, Train,
)
from monitor.tables import read

V = 4000          # 40 m/s
FAR = 50000       # 5 km: beyond every curve at 40 m/s


class Core:
    """The real core, cycle by cycle, on a tick advancing by the period."""

    def __init__(self, cfg: Config = Config(), table: str = "m1"):
        self.cfg = cfg
        self.setup = create(cfg, read(table))
        self.state = initial_state(self.setup)
        self.tick = 0

    def cycle(self, reports, speed: int = 0, train=None, overruns: int = 0, tick=None):
        tick = self.tick if tick is None else tick
        train = Train(speed) if train is None else train
        self.state, out = step(self.setup, self.state, Inputs(tuple(reports), train, overruns), tick)
        self.tick = tick + self.cfg.period_ms
        return out

    def reports(self, statuses, distances=None, closing: int = 0, obstacle: int = STATIC):
        distances = distances or [0] * len(statuses)
        return [Report(s, d if s == PRESENT else 0, closing, obstacle, self.tick) for s, d in zip(statuses, distances)]

    def clear(self, speed: int = 0):
        return self.cycle(self.reports([ABSENT] * self.cfg.channels), speed)

    def normal(self):
        out = self.clear(0)
        assert out.mode == NORMAL and out.demand == MAINTAIN
        return self


# --------------------------------------------------------------------------- 2oo2 and 3oo3 voting


@pytest.mark.parametrize("module", [0, 1, 2])
def test_a_flag_raised_by_one_module_alone_is_a_system_error(module):
    """3oo3: a module whose two channels both see the obstacle but more than the tolerance
    apart raises its flag while all three modules report PRESENT; that flag alone, whichever
    module raised it, makes the system error (a dispute: all channels fresh)."""
    core = Core().normal()
    dists = [FAR] * 6
    dists[2 * module + 1] = FAR + 101
    out = core.cycle(core.reports([PRESENT] * 6, dists), V)
    assert out.module_flags == 1 << module
    assert out.system_error and out.mode == DEGRADED_MODE
    assert out.reasons & R_SYSTEM_ERROR and out.reasons & R_DISPUTE and out.warning
    assert voter.vote_3oo3(*(PRESENT, FAR, module == 0), *(PRESENT, FAR, module == 1), *(PRESENT, FAR, module == 2)) \
        == (PRESENT, FAR, True)


def test_3oo3_three_unflagged_degraded_modules_are_a_system_error():
    """vote_3oo3's contract: a DEGRADED system status is an error by itself, even when no
    module raised its flag and the three modules agree (defence in depth)."""
    assert voter.vote_3oo3(DEGRADED, 0, False, DEGRADED, 0, False, DEGRADED, 0, False) == (DEGRADED, 0, True)
    assert voter.vote_3oo3(ABSENT, 7, False, ABSENT, 7, False, ABSENT, 7, False) == (ABSENT, 7, False)


def test_single_module_degraded_without_flag_is_a_system_error():
    """vote_single's contract (2oo2 topology): a DEGRADED module is an error even without its flag."""
    assert voter.vote_single(DEGRADED, 9, False) == (DEGRADED, 9, True)
    assert voter.vote_single(PRESENT, 9, False) == (PRESENT, 9, False)
    assert voter.vote_single(PRESENT, 9, True) == (PRESENT, 9, True)


def test_distances_exactly_the_tolerance_apart_agree():
    """2oo2: two PRESENT distances exactly distance_tolerance_dm apart agree (no flag), in
    either order; one dm more raises the flag, in either order."""
    assert voter.distances_disagree(PRESENT, 1000, PRESENT, 1100, 100) is False
    assert voter.distances_disagree(PRESENT, 1100, PRESENT, 1000, 100) is False
    assert voter.distances_disagree(PRESENT, 1000, PRESENT, 1101, 100) is True
    assert voter.distances_disagree(PRESENT, 1101, PRESENT, 1000, 100) is True
    assert voter.distances_disagree(PRESENT, 1000, PRESENT, 1000, 0) is False


@pytest.mark.parametrize("sa, sb", [(ABSENT, PRESENT), (PRESENT, ABSENT), (DEGRADED, PRESENT), (PRESENT, DEGRADED),
                                    (ABSENT, ABSENT)])
def test_distances_disagree_only_when_both_channels_see_the_obstacle(sa, sb):
    """distances_disagree is about two PRESENT channels: with one channel not PRESENT it is
    False whatever the distances (the status disagreement is the 2oo2 flag's business)."""
    assert voter.distances_disagree(sa, 0, sb, 5000, 100) is False
    assert voter.distances_disagree(sa, 5000, sb, 0, 100) is False


@pytest.mark.parametrize("sa, sb, want", [(ABSENT, PRESENT, True), (PRESENT, ABSENT, True), (ABSENT, ABSENT, False),
                                          (PRESENT, PRESENT, False), (DEGRADED, PRESENT, False),
                                          (PRESENT, DEGRADED, False), (ABSENT, DEGRADED, False),
                                          (DEGRADED, ABSENT, False)])
def test_disagreement_is_absent_against_present_in_both_directions(sa, sb, want):
    """A 2oo2 disagreement (the perceptor-error counter) is one channel ABSENT and the other
    PRESENT, in either direction, and nothing else."""
    assert voter.disagreement(sa, sb) is want


@pytest.mark.parametrize("sa, sb", [(a, b) for a in range(3) for b in range(3)])
def test_vote_2oo2_every_status_pair(sa, sb):
    """vote_2oo2 over all nine status pairs: status is the maximum, the flag is up on any
    difference or DEGRADED, the distance is the PRESENT channel's (the shorter of two)."""
    st, dist, flag = voter.vote_2oo2(sa, 300, sb, 200)
    assert st == max(sa, sb)
    assert flag == (sa != sb or DEGRADED in (sa, sb))
    want = {(True, True): 200, (True, False): 300, (False, True): 200, (False, False): 65535}
    assert dist == want[(sa == PRESENT, sb == PRESENT)]


@pytest.mark.parametrize("module", [0, 1, 2])
def test_one_module_alone_seeing_an_obstacle_inside_ebi_brakes_emergency(module):
    """3oo3: one module sees an obstacle 50 m ahead of a train at 40 m/s (inside EBI), the
    other two see nothing. A dispute, and the voted distance is that module's: emergency."""
    core = Core(Config(safe_reaction=SERVICE)).normal()
    statuses = [ABSENT] * 6
    statuses[2 * module] = statuses[2 * module + 1] = PRESENT
    out = core.cycle(core.reports(statuses, [500] * 6), V)
    assert out.distance_dm == 500 and out.system_error and out.reasons & R_DISPUTE
    assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE


# --------------------------------------------------------------------------- freshness and range


def test_in_range_boundaries_of_every_field():
    """in_range accepts each field's documented range inclusive at both ends (status 0..2,
    distance 0..60000 dm, closing -15000..15000 cm/s, obstacle 0..2) and refuses one step beyond."""
    from monitor.core.freshness import in_range

    for good in [(0, 0, 0, 0), (2, 0, 0, 0), (1, 60000, 0, 0), (1, 0, -15000, 0), (1, 0, 15000, 0), (1, 0, 0, 2),
                 (2, 60000, 15000, 2), (0, 0, -15000, 0)]:
        assert in_range(*good) is True, good
    for bad in [(-1, 0, 0, 0), (3, 0, 0, 0), (1, -1, 0, 0), (1, 60001, 0, 0), (1, 0, -15001, 0), (1, 0, 15001, 0),
                (1, 0, 0, -1), (1, 0, 0, 3)]:
        assert in_range(*bad) is False, bad


def test_obstacle_code_3_is_out_of_range_and_degrades_the_channel():
    """An obstacle type code 3 (one beyond TRAIN) makes the report out of range: the channel
    is DEGRADED, the system error brakes (safe_reaction), never a PRESENT channel."""
    from monitor.core.freshness import channel_status, effective_status

    assert effective_status(PRESENT, 500, 0, 3, 100, 100, 300) == DEGRADED
    assert effective_status(PRESENT, 500, 0, 2, 100, 100, 300) == PRESENT
    assert channel_status(Report(PRESENT, 500, 0, 3, 100), 100, 300) == DEGRADED
    core = Core().normal()
    reps = core.reports([ABSENT] * 6)
    reps[4] = Report(ABSENT, 0, 0, 3, core.tick)
    out = core.cycle(reps, V)
    assert out.system_error and out.module_flags == 0b100 and out.demand == EMERGENCY


@pytest.mark.parametrize("field, value", [("status", True), ("status", 1.0), ("distance_dm", 500.0),
                                          ("closing_cms", 0.0), ("obstacle", 0.0), ("tick", 100.0),
                                          ("distance_dm", True), ("tick", None)])
def test_a_report_field_that_is_not_an_int_degrades_the_channel(field, value):
    """Integers only: a report whose field is a float, a bool or None (values that compare
    like the valid ints) is DEGRADED, whichever field it is; the same report with ints is
    PRESENT. Through a cycle the channel counts as stale and the system error brakes."""
    from monitor.core.freshness import channel_status

    good = Report(PRESENT, 500, 0, STATIC, 100)
    assert channel_status(good, 100, 300) == PRESENT
    bad = good._replace(**{field: value})
    assert channel_status(bad, 100, 300) == DEGRADED
    core = Core().normal()
    reps = core.reports([PRESENT] * 6, [FAR] * 6)
    reps[0] = reps[0]._replace(**{field: value}) if field != "tick" else reps[0]._replace(tick=value)
    if field == "tick" and value is not None:
        reps[0] = reps[0]._replace(tick=float(core.tick))
    out = core.cycle(reps, V)
    assert out.reasons & R_SYSTEM_ERROR and out.module_flags & 1
    assert out.demand == EMERGENCY


# --------------------------------------------------------------------------- observation


def test_m1_observation_is_the_zone_itself():
    """Model 1 observes the zone: m1_observation is the identity on 0..3 (free, warning,
    emergency, critical), as the cycle's `obs = z` is."""
    from monitor.core.observation import M1_OBSERVATIONS, m1_observation

    assert [m1_observation(z) for z in range(4)] == [0, 1, 2, 3]
    assert M1_OBSERVATIONS == ("free", "warning", "emergency", "critical")


# --------------------------------------------------------------------------- the emergency latch


def test_latch_holds_at_1_cms_and_releases_at_standstill():
    """An emergency is held while the train moves at all, 1 cm/s included, and only
    standstill (speed 0) releases it without a revocable release; no calm cycles are
    counted while it is held to standstill."""
    from monitor.core.envelope import hold

    assert hold(MAINTAIN, 0, EMERGENCY, 1, False, 5) == (EMERGENCY, 0, EMERGENCY)
    assert hold(EMERGENCY, 0, MAINTAIN, 1, False, 5) == (EMERGENCY, 0, EMERGENCY)
    assert hold(EMERGENCY, 0, SERVICE, 1, False, 5) == (EMERGENCY, 0, EMERGENCY)
    assert hold(EMERGENCY, 0, MAINTAIN, 0, False, 5) == (MAINTAIN, 0, MAINTAIN)
    assert hold(MAINTAIN, 0, EMERGENCY, 0, True, 5) == (EMERGENCY, 0, EMERGENCY)
    state = (EMERGENCY, 0)
    for _ in range(10):                       # held to standstill: calm never counts
        held, calm, demand = hold(*state, MAINTAIN, 4000, False, 5)
        assert (held, calm, demand) == (EMERGENCY, 0, EMERGENCY)
        state = (held, calm)


def test_revocable_release_after_exactly_confirm_calm_cycles():
    """Revocable release: with release_confirm_cycles = 5 the emergency is still held on
    the 4th calm cycle and released on the 5th; the state after the release is the state of
    a monitor that never held (calm 0); a new emergency cause resets the count. A held
    service is released the same way, even when emergency is held to standstill."""
    from monitor.core.envelope import hold

    held, calm = hold(MAINTAIN, 0, EMERGENCY, 2000, True, 5)[:2]
    assert (held, calm) == (EMERGENCY, 0)
    for k in range(1, 5):
        held, calm, demand = hold(held, calm, MAINTAIN, 2000, True, 5)
        assert (held, calm, demand) == (EMERGENCY, k, EMERGENCY)
    assert hold(held, calm, MAINTAIN, 2000, True, 5) == (MAINTAIN, 0, MAINTAIN)
    assert hold(EMERGENCY, 3, EMERGENCY, 2000, True, 5) == (EMERGENCY, 0, EMERGENCY)
    assert hold(EMERGENCY, 0, MAINTAIN, 2000, True, 1) == (MAINTAIN, 0, MAINTAIN)
    assert hold(EMERGENCY, 4, SERVICE, 2000, True, 5) == (SERVICE, 0, SERVICE)
    assert hold(SERVICE, 3, MAINTAIN, 2000, False, 5) == (SERVICE, 4, SERVICE)
    assert hold(SERVICE, 4, MAINTAIN, 2000, False, 5) == (MAINTAIN, 0, MAINTAIN)
    assert hold(SERVICE, 2, SERVICE, 2000, True, 5) == (SERVICE, 0, SERVICE)


def test_no_calm_is_counted_while_nothing_is_held():
    """Without a held demand above the causes' the calm counter stays 0, whatever the
    demand and speed."""
    from monitor.core.envelope import hold

    for demand in (MAINTAIN, SERVICE):
        for speed in (0, 1, 4000):
            assert hold(demand, 0, demand, speed, True, 5) == (demand, 0, demand)
            assert hold(MAINTAIN, 0, demand, speed, True, 5) == (demand, 0, demand)


def test_table_hold_keeps_what_the_table_raised_inside_its_zones():
    from monitor.core.envelope import table_hold

    assert table_hold(SERVICE, MAINTAIN, 1, False) == SERVICE
    assert table_hold(EMERGENCY, SERVICE, 1, False) == EMERGENCY
    assert table_hold(SERVICE, MAINTAIN, 0, False) == MAINTAIN      # standstill
    assert table_hold(SERVICE, MAINTAIN, 1, True) == MAINTAIN       # zone free
    assert table_hold(SERVICE, EMERGENCY, 1, False) == EMERGENCY


def test_latch_through_the_cycle_at_1_cms():
    """Held to standstill (emergency_release = 0): after an emergency for an obstacle inside
    EBI, the track clears but the train still rolls at 1 cm/s: the demand stays emergency;
    at 0 cm/s it is released."""
    core = Core(Config(emergency_release=0)).normal()
    out = core.cycle(core.reports([PRESENT] + [ABSENT] * 5, [300] + [0] * 5), V)   # disputed: not remembered
    assert out.demand == EMERGENCY and core.state.latched
    for _ in range(12):
        out = core.clear(1)
        assert out.demand == EMERGENCY and core.state.latched and core.state.calm == 0
    out = core.clear(0)
    assert out.demand == MAINTAIN and not core.state.latched and core.state.calm == 0


# --------------------------------------------------------------------------- start-up checks


def _m1_with_step(step) -> bytes:
    """The shipped m1 table re-encoded with params.time_step_s = step."""
    from monitor.core.table import decode, encode

    t = decode(read("m1"))
    header = dict(t.header)
    header["params"] = dict(header["params"], time_step_s=step)
    return encode(header, t.action, t.next)


def _with_header_text(data: bytes, old: bytes, new: bytes) -> bytes:
    """A table whose header text has `old` replaced by `new` (length and SHA-256 redone)."""
    import hashlib
    import struct

    magic, version, hlen = struct.unpack_from("<8sHI", data)
    header = data[14:14 + hlen]
    assert header.count(old) == 1
    header = header.replace(old, new)
    body = struct.pack("<8sHI", magic, version, len(header)) + header + data[14 + hlen:-32]
    return body + hashlib.sha256(body).digest()


@pytest.mark.parametrize("step, period", [(1.0, 1000), (0.1, 100), (1, 1000), (0.25, 250)])
def test_table_time_step_must_equal_the_period_exactly(step, period):
    """The table's time step (s) must be the configured period (ms): 1.0 s runs at 1000 ms
    and is refused at 999 and 1001 ms; an int step is accepted like a float."""
    from monitor.core.config import ConfigurationError

    data = _m1_with_step(step)
    assert create(Config(period_ms=period), data).config.period_ms == period
    for other in (period - 1, period + 1):
        with pytest.raises(ConfigurationError, match="time step"):
            create(Config(period_ms=other), data)


@pytest.mark.parametrize("step", [True, "0.1", None, [0.1]])
def test_a_table_time_step_that_is_not_a_number_is_refused(step):
    """params.time_step_s must be a number: true (a bool, although True * 1000 == 1000), a
    string, null or a list are refused at start-up with a ConfigurationError."""
    from monitor.core.config import ConfigurationError

    with pytest.raises(ConfigurationError, match="numeric time step"):
        create(Config(period_ms=1000), _m1_with_step(step))


@pytest.mark.parametrize("text", [b"1e999", b"-1e999"])
def test_an_infinite_table_time_step_is_refused_as_a_configuration_error(text):
    """A header number that JSON reads as infinity (1e999) is no time step: a
    ConfigurationError, not an arithmetic error, refuses to start."""
    from monitor.core.config import ConfigurationError

    data = _with_header_text(_m1_with_step(0.125), b'"time_step_s":0.125', b'"time_step_s":' + text)
    with pytest.raises(ConfigurationError, match="numeric time step"):
        create(Config(), data)


# --------------------------------------------------------------------------- counters and the initial state


@pytest.mark.parametrize("topology, modules", [("3oo3", 3), ("2oo2", 1)])
def test_initial_state_is_init_at_the_start_node_with_every_counter_zero(topology, modules):
    """The monitor starts in INIT at the table's start node, unlatched, nothing seen, every
    counter (disagreement per module, healthy, cycle, error cycles, calm) at 0."""
    from monitor.core.types import INIT, NO_TRACKS, State

    core = Core(Config(topology=topology))
    start = core.setup.table.start
    assert initial_state(core.setup) == State(INIT, start, 0, 0, (0,) * modules, 0, 0, 0, 0, (0,) * modules,
                                              tracks=NO_TRACKS, plaus=((-1, 0, 0, 0, 0, 0, 0),) * (2 * modules))


def test_healthy_and_error_cycles_count_from_zero():
    """healthy counts consecutive error-free cycles from 0 and error_cycles counts cycles
    with an error or a stale channel from 0: 3 clear cycles give healthy 3 and 0 error
    cycles; one silent channel for 2 cycles gives error_cycles 2 and healthy 0; a dispute
    (an error with every channel fresh) counts too; the cycle counter is the number of
    cycles run."""
    core = Core()
    for k in range(1, 4):
        out = core.clear(0)
        assert (core.state.healthy, out.error_cycles, out.cycle) == (k, 0, k)
    for k in range(1, 3):
        reps = core.reports([ABSENT] * 6)
        reps[5] = None
        out = core.cycle(reps, 0)
        assert (core.state.healthy, out.error_cycles, out.cycle) == (0, k, 3 + k)
    out = core.clear(0)
    assert (core.state.healthy, out.error_cycles, out.cycle) == (1, 2, 6)
    out = core.cycle(core.reports([PRESENT] * 2 + [ABSENT] * 4, [FAR] * 6), V)   # a dispute: no channel stale
    assert out.reasons & R_DISPUTE and not out.reasons & R_STALE
    assert (core.state.healthy, out.error_cycles, out.cycle) == (0, 3, 7)


def test_counters_saturate_at_max_count():
    """The cycle and error counters saturate at MAX_COUNT (2^31 - 1) like the C core's
    32-bit counters: one more cycle from MAX_COUNT stays at MAX_COUNT, from MAX_COUNT - 1 it reaches it."""
    from monitor.core.types import MAX_COUNT

    core = Core().normal()
    core.state = core.state._replace(cycle=MAX_COUNT - 1, error_cycles=MAX_COUNT)
    reps = core.reports([ABSENT] * 6)
    reps[0] = None
    out = core.cycle(reps, 0)
    assert (out.cycle, out.error_cycles) == (MAX_COUNT, MAX_COUNT)
    out = core.cycle(reps, 0)
    assert (out.cycle, out.error_cycles) == (MAX_COUNT, MAX_COUNT)


# --------------------------------------------------------------------------- the train input


@pytest.mark.parametrize("train", [Train(4000, 2, 0), Train(4000, 0, 2), Train(4000, True, 0), Train(4000, 0, 1.0),
                                   Train(4000.0, 0, 0), Train(12001, 0, 0), Train(-1, 0, 0)], ids=repr)
def test_an_invalid_train_state_is_read_as_top_speed_slippery_and_degraded(train):
    """A train state out of range or not made of ints (bool and float included) is a
    train-input error read to the safe side: top speed (120 m/s), slippery track AND
    degraded brakes. At 5.9 km the obstacle is inside that EBI (7.4 km) but outside the
    EBI with only one adverse condition (5.0 and 5.7 km): emergency from the curves even
    with safe_reaction = SERVICE, and the m2 observation carries track 1 and brake 1."""
    from monitor.core.types import R_TRAIN_INPUT

    core = Core(Config(safe_reaction=SERVICE), "m2").normal()
    out = core.cycle(core.reports([PRESENT] * 6, [59000] * 6), train=train)
    assert out.reasons & R_TRAIN_INPUT and out.system_error
    assert out.distance_dm == 59000
    assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE
    assert out.observation % 4 == 3          # (... * 2 + track) * 2 + brake with track = brake = 1
    ok = Core(Config(safe_reaction=SERVICE), "m2").normal()
    out = ok.cycle(ok.reports([PRESENT] * 6, [59000] * 6), train=Train(4000, 0, 0))
    assert not out.reasons & R_TRAIN_INPUT and out.observation % 4 == 0


@pytest.mark.parametrize("how", ["node out of the table", "inputs of the wrong type"])
def test_anything_unforeseen_inside_a_cycle_gives_exactly_the_safe_stop_outputs(how):
    """step is total: when the cycle itself fails (a state whose node is outside the table,
    inputs that are no Inputs) the result is SAFE_STOP with an emergency, latched, and
    exactly these outputs: reasons safe_stop + system_error + latch, no distance, the old
    node, no module flag, system error, observation 0, counters + 1, a warning; the state
    keeps its node and seen channels, healthy and calm go to 0."""
    from monitor.core.types import NO_DISTANCE, R_LATCH, R_SAFE_STOP, SAFE_STOP, Outputs

    core = Core().normal()
    core.clear(V)
    before = core.state._replace(healthy=7, calm=3)
    if how == "node out of the table":
        before = before._replace(node=10 ** 6)
        inputs = Inputs(tuple(core.reports([ABSENT] * 6)), Train(V))
    else:
        inputs = None
    state, out = step(core.setup, before, inputs, core.tick)
    assert out == Outputs(EMERGENCY, R_SAFE_STOP | R_SYSTEM_ERROR | R_LATCH, NO_DISTANCE, before.node, SAFE_STOP, 0,
                          True, 0, before.cycle + 1, before.error_cycles + 1, True,
                          r1_ppm=500_000, r2_ppm=1_000_000, risk_score=20, risk_category=4, table_risk_ppm=1_000_000)
    assert state == before._replace(mode=SAFE_STOP, held=EMERGENCY, healthy=0, cycle=before.cycle + 1,
                                    error_cycles=before.error_cycles + 1, calm=0)


# --------------------------------------------------------------------------- zones, reasons, modes


def test_table_zones_use_normal_conditions_with_degraded_brakes():
    """The table's zones (alpha1, alpha2) are computed under normal conditions, also when
    the train reports degraded brakes (track normal) or a slippery track: an obstacle one
    dm beyond the normal EBI (but inside the degraded one) is zone 2 (emergency), not 3
    (critical), while the supervision brakes on the degraded EBI."""
    from monitor.core.braking import curves

    for track, brake in ((0, 1), (1, 0)):
        cfg = Config()
        normal = curves(cfg, V, 0, 0, V, 0)
        adverse = curves(cfg, V, track, brake, V, 0)
        service = curves(cfg, V, 0, 0, V, 0, service=True)
        d = normal.ebi_dm + 1
        assert d <= adverse.ebi_dm and d <= service.ebi_dm
        core = Core(cfg).normal()
        out = core.cycle(core.reports([PRESENT] * 6, [d] * 6, closing=V), train=Train(V, track, brake))
        assert out.observation == 2, (track, brake)
        assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE


def test_exact_reasons_of_a_far_dispute_and_of_a_train_input_error():
    """A dispute beyond the warning curve sets exactly system_error, dispute and warning
    (no table bit: the table demands nothing); a train-input error together with a module
    disagreement is no dispute (the train input is not valid): no dispute bit, the safe
    reaction instead."""
    from monitor.core.types import R_TRAIN_INPUT, R_WARNING

    core = Core().normal()
    core.clear(V)
    statuses = [PRESENT] * 2 + [ABSENT] * 4
    out = core.cycle(core.reports(statuses, [FAR] * 6), V)
    assert out.reasons == R_SYSTEM_ERROR | R_DISPUTE | R_WARNING
    assert out.demand == MAINTAIN
    core = Core(Config(safe_reaction=SERVICE)).normal()
    out = core.cycle(core.reports(statuses, [FAR] * 6), train=Train(V, 5, 0))
    assert out.reasons & R_TRAIN_INPUT and out.reasons & R_SYSTEM_ERROR
    assert not out.reasons & R_DISPUTE


def test_exact_reasons_of_a_safe_stop_for_deadline_overruns():
    """Repeated deadline overruns at standstill on a clear track: SAFE_STOP with exactly
    the safe_stop and deadline reasons (no perceptor bit, no table bit) and an emergency."""
    from monitor.core.types import R_DEADLINE, R_SAFE_STOP, SAFE_STOP

    core = Core().normal()
    out = core.cycle(core.reports([ABSENT] * 6), 0, overruns=3)
    assert out.mode == SAFE_STOP and out.demand == EMERGENCY
    assert out.reasons == R_SAFE_STOP | R_DEADLINE


def test_latch_reason_only_when_the_latch_alone_holds_the_emergency():
    """R_LATCH marks an emergency held by the latch alone: while the obstacle stays inside
    EBI the demand is the envelope's own emergency (no latch bit, even though latched),
    once it is gone the held emergency carries the latch bit."""
    from monitor.core.types import R_LATCH

    core = Core(Config(emergency_release=0)).normal()
    for _ in range(3):
        out = core.cycle(core.reports([PRESENT] * 6, [300] * 6), V)
        assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE and not out.reasons & R_LATCH
    latch_bits = []
    for _ in range(30):                  # the table may hold its own emergency for a while
        out = core.clear(V)
        assert out.demand == EMERGENCY
        latch_bits.append(bool(out.reasons & R_LATCH))
    assert latch_bits[-1]


# --------------------------------------------------------------------------- braking arithmetic, exactly


def _ceil(x) -> int:
    import math

    return math.ceil(x)


def test_run_dm_and_speed_after_are_the_exact_values_rounded_up():
    """run_dm is v t + a t^2 / 2 in dm and speed_after_cms is v + a t in cm/s, each rounded
    up, checked against exact fractions in SI units, on values that sit exactly on and one
    unit beside a whole dm or cm/s and on a deterministic random sample."""
    import random
    from fractions import Fraction as F

    from monitor.core.braking import run_dm, speed_after_cms

    cases = [(10000, 1, 1), (10000, 0, 1000), (1, 0, 1), (0, 1, 1), (0, 0, 0), (4000, 500, 1900), (1, 10000, 200000),
             (10000, 1, 2), (3, 7, 9999), (0, 10000, 1)]
    rnd = random.Random(14)
    cases += [(rnd.randrange(0, 12001), rnd.randrange(0, 10001), rnd.randrange(0, 30001)) for _ in range(2000)]
    for v, a, t in cases:
        metres = F(v, 100) * F(t, 1000) + F(a, 1000) * F(t, 1000) ** 2 / 2
        assert run_dm(v, a, t) == _ceil(metres * 10), (v, a, t)
        assert speed_after_cms(v, a, t) == v + _ceil(F(a, 1000) * F(t, 1000) * 100), (v, a, t)


def test_band_stop_and_stop_dm_ms_are_the_exact_values_rounded_up():
    """band_stop brakes from min(speed, hi) down to lo at a constant deceleration: distance
    (top^2 - lo^2) / 2a in dm and time (top - lo) / a in ms, both rounded up; a band above
    the speed, or an empty band (hi = 0, or hi <= lo), costs nothing, not even 1 ms;
    stop_dm_ms adds the bands up, each band ending where the next one starts (three bands)."""
    import random
    from fractions import Fraction as F

    from monitor.core.braking import band_stop, stop_dm_ms

    def exact(speed, lo, hi, a):
        top = speed if hi < 0 else min(speed, hi)
        if top <= lo:
            return 0, 0
        dist_m = (F(top, 100) ** 2 - F(lo, 100) ** 2) / (2 * F(a, 1000))
        time_s = (F(top, 100) - F(lo, 100)) / F(a, 1000)
        return _ceil(dist_m * 10), _ceil(time_s * 1000)

    assert band_stop(1000, 0, 0, 1000) == (0, 0)
    assert band_stop(100, 3000, -1, 2400) == (0, 0)
    assert band_stop(3000, 3000, -1, 2400) == (0, 0)
    assert band_stop(3001, 3000, -1, 1) == exact(3001, 3000, -1, 1) == (3001, 10000)
    rnd = random.Random(15)
    for _ in range(3000):
        lo = rnd.choice([0, rnd.randrange(1, 12000)])
        hi = rnd.choice([-1, lo + rnd.randrange(1, 3000), rnd.randrange(0, 12001)])
        speed, a = rnd.randrange(0, 12001), rnd.randrange(1, 20001)
        assert band_stop(speed, lo, hi, a) == exact(speed, lo, hi, a), (speed, lo, hi, a)
    bands = ((0, 2400), (3000, 2200), (8000, 1500))
    for speed in (0, 1, 2999, 3000, 3001, 7999, 8000, 8001, 12000):
        want = [exact(speed, 0, 3000, 2400), exact(speed, 3000, 8000, 2200), exact(speed, 8000, -1, 1500)]
        assert stop_dm_ms(speed, bands) == (sum(d for d, _ in want), sum(t for _, t in want)), speed
    for speed in (0, 2999, 3000, 3001, 12000):
        want = [exact(speed, 0, 3000, 2400), exact(speed, 3000, -1, 2200)]
        assert stop_dm_ms(speed, bands[:2]) == (sum(d for d, _ in want), sum(t for _, t in want)), speed


def test_obstacle_run_and_scaled_decelerations_are_rounded_to_the_safe_side():
    """An oncoming obstacle closes obstacle_cms x t rounded up (nothing if it is not
    oncoming); a deceleration scaled by a factor in per mille is rounded down; under
    adverse conditions the factors multiply, and the downhill pull is subtracted."""
    import random
    from fractions import Fraction as F
    import math

    from monitor.core.braking import effective_decel_mms2, obstacle_run_dm, scaled_decel_mms2

    rnd = random.Random(16)
    for _ in range(2000):
        o, t = rnd.randrange(-15000, 15001), rnd.randrange(0, 200001)
        want = _ceil(F(o, 100) * F(t, 1000) * 10) if o > 0 else 0
        assert obstacle_run_dm(o, t) == want, (o, t)
        a, f = rnd.randrange(0, 20001), rnd.randrange(0, 1001)
        assert scaled_decel_mms2(a, f) == math.floor(F(a) * F(f, 1000))
    assert obstacle_run_dm(1, 1) == 1 and obstacle_run_dm(0, 10 ** 6) == 0 and obstacle_run_dm(10000, 1) == 1
    assert obstacle_run_dm(10000, 10001) == 10001
    assert effective_decel_mms2(2400, 0, 0, 700, 800, 197) == 2203
    assert effective_decel_mms2(2400, 1, 0, 700, 800, 197) == 1680 - 197
    assert effective_decel_mms2(2400, 0, 1, 700, 800, 197) == 1920 - 197
    assert effective_decel_mms2(2400, 1, 1, 700, 800, 197) == 1344 - 197
    assert effective_decel_mms2(2399, 1, 1, 701, 799, 0) == (2399 * 701 // 1000) * 799 // 1000


# --------------------------------------------------------------------------- the braking curves, exactly


def reference_curves(cfg: Config, speed: int, track: int, brake: int, closing: int, age: int, service: bool = False,
                     supervised: bool = True):
    """EBD, EBI, SBI and warning (dm) written out again from docs/supervision.md in exact
    fractions of SI units, every term rounded to the safe side on its own as the document
    says (distances and speeds up, decelerations down), without monitor.core.braking.

    `supervised` (braking.curves): four periods in EBI's reaction and the sensors' error
    budget (section 2.6: every curve + the distance accuracy a_d, the obstacle's own speed
    from closing + the closing accuracy a_c); not `supervised` (braking.ebi_dm, the table's
    zone limits): the demand's one period and no budget."""
    import math
    from fractions import Fraction as F

    up = math.ceil
    periods = 4 if supervised else 1
    a_d = cfg.distance_accuracy_dm if supervised else 0          # dm: the obstacle may be this much nearer
    a_c = cfg.closing_accuracy_cms if supervised else 0          # cm/s: and close this much faster
    e = cfg.speed_error_permille
    v_max = up(F(speed * (1000 + e), 1000))                       # cm/s, measured speed + error
    obstacle = closing + a_c - math.floor(F(speed * (1000 - e), 1000))  # the obstacle's own speed towards us
    g = up(F(9810 * cfg.max_gradient_permille, 1000))             # mm/s^2 downhill
    if service:
        raw, buildup = [(0, cfg.service_decel_mms2)], cfg.service_buildup_ms
    else:
        raw = [(0, cfg.emergency_decel_mms2)]
        if cfg.emergency_band2_cms:
            raw.append((cfg.emergency_band2_cms, cfg.emergency_band2_mms2))
            if cfg.emergency_band3_cms:
                raw.append((cfg.emergency_band3_cms, cfg.emergency_band3_mms2))
        buildup = cfg.emergency_buildup_ms

    def decel(a):
        if track:
            a = a * cfg.slippery_permille // 1000
        if brake:
            a = a * cfg.degraded_permille // 1000
        return a - g

    bands = [(lo, decel(a)) for lo, a in raw]

    def run(v_cms, a_mms2, t_ms):                # dm, up
        return up((F(v_cms, 100) * F(t_ms, 1000) + F(a_mms2, 1000) * F(t_ms, 1000) ** 2 / 2) * 10)

    def after(v_cms, a_mms2, t_ms):              # cm/s, up
        return v_cms + up(F(a_mms2 * t_ms, 1000) / 10)

    def stop(v_cms):                             # (dm, ms), each band up
        dist = time = 0
        for i, (lo, a) in enumerate(bands):
            hi = bands[i + 1][0] if i + 1 < len(bands) else None
            top = v_cms if hi is None else min(v_cms, hi)
            if top > lo:
                dist += up((F(top, 100) ** 2 - F(lo, 100) ** 2) / (2 * F(a, 1000)) * 10)
                time += up((F(top, 100) - F(lo, 100)) / F(a, 1000) * 1000)
        return dist, time

    def closes(t_ms):                            # dm the oncoming obstacle runs, up
        return up(F(obstacle, 100) * F(t_ms, 1000) * 10) if obstacle > 0 else 0

    t1 = age + periods * cfg.period_ms + cfg.traction_cutoff_ms
    a1 = cfg.max_accel_mms2 + g
    s1, v1 = run(v_max, a1, t1), after(v_max, a1, t1)
    t2 = max(0, buildup - cfg.traction_cutoff_ms)
    s2, v2 = run(v1, g, t2), after(v1, g, t2)
    s3, t3 = stop(v2)
    ebi = s1 + s2 + s3 + cfg.standstill_margin_dm + a_d + closes(t1 + t2 + t3)
    d0, tt0 = stop(speed)
    ebd = d0 + cfg.standstill_margin_dm + a_d + closes(tt0)
    lead = v_max + max(obstacle, 0)
    sbi = ebi + run(lead, 0, cfg.service_buildup_ms)
    warning = sbi + run(lead, 0, cfg.warning_ms)
    cap = 1_000_000
    return tuple(min(x, cap) for x in (ebd, ebi, sbi, warning))


CURVE_CONFIGS = {
    "shipped": Config(),
    "three bands": Config(emergency_band2_cms=2000, emergency_band2_mms2=2000, emergency_band3_cms=6000,
                          emergency_band3_mms2=1600),
    "build-up shorter than cut-off": Config(emergency_buildup_ms=500, service_buildup_ms=700, traction_cutoff_ms=800),
    "flat, no error, no margin": Config(max_gradient_permille=0, speed_error_permille=0, standstill_margin_dm=0,
                                        emergency_band2_cms=0),
    "steep and uncertain": Config(max_gradient_permille=60, speed_error_permille=500, max_accel_mms2=5000,
                                  emergency_decel_mms2=4000, emergency_band2_mms2=3900, service_decel_mms2=3000),
    "odd lead times": Config(service_buildup_ms=1001, warning_ms=1999, speed_error_permille=0),
    "odd error budget": Config(distance_accuracy_dm=123, closing_accuracy_cms=37),
    "exact sensors": Config(distance_accuracy_dm=0, closing_accuracy_cms=0),
}


def _just_past_a_whole_dm(cfg: Config) -> set:
    """Speeds whose run over the service build-up or the warning time (v t, in dm) ends
    just past a whole dm, where rounding up decides the last dm (closing = speed: the lead
    speed is the measured speed plus its error)."""
    out = set()
    for v in range(12001):
        lead = -(-v * (1000 + cfg.speed_error_permille) // 1000)
        for t in (cfg.service_buildup_ms, cfg.warning_ms):
            rest = lead * t % 10000                     # v t in units of 1e-5 m; 1 dm = 10000
            if 0 < rest * 20000 <= t * t:
                out.add(v)
    return set(sorted(out)[:6])


@pytest.mark.parametrize("name", sorted(CURVE_CONFIGS))
def test_curves_equal_the_exact_construction_term_by_term(name):
    """curves() (two periods in the reaction: the sampling and the demand's) and ebi_dm()
    (the table's alpha1 with service=True, alpha2: the demand's period only) equal the curves
    written out again in exact fractions, at 0, 1 and 2 cm/s, at and beside every band edge,
    at the top speed, at speeds whose lead run ends just past a whole dm and at
    deterministic random speeds, under every track/brake condition,
    for obstacles closing, standing, moving away and oncoming (standing: closing = speed as
    measured, and closing = speed less the closing accuracy, where the budget's obstacle
    stands), with report ages 0..timeout. The supervised curves count the sensors' error
    budget, the zone limits do not (docs/supervision.md 2.6)."""
    import random

    from monitor.core.braking import curves, ebi_dm

    cfg = CURVE_CONFIGS[name]
    rnd = random.Random(name)
    speeds = {0, 1, 2, 12000, 11999}
    for edge in (cfg.emergency_band2_cms, cfg.emergency_band3_cms):
        if edge:
            speeds |= {edge - 1, edge, edge + 1}
    speeds |= {rnd.randrange(0, 12001) for _ in range(12)} | _just_past_a_whole_dm(cfg)
    for speed in sorted(speeds):
        for track, brake in ((0, 0), (1, 0), (0, 1), (1, 1)):
            for closing in (speed, speed - cfg.closing_accuracy_cms, 0, -500, speed + 1500, min(15000, speed + 9000)):
                age = rnd.choice([0, 1, 100, 300])
                want = reference_curves(cfg, speed, track, brake, closing, age)
                assert tuple(curves(cfg, speed, track, brake, closing, age)) == want, (speed, track, brake, closing, age)
                zone = reference_curves(cfg, speed, track, brake, closing, age, supervised=False)
                assert ebi_dm(cfg, speed, track, brake, closing, age) == zone[1]
                svc = reference_curves(cfg, speed, track, brake, closing, age, service=True)
                assert tuple(curves(cfg, speed, track, brake, closing, age, service=True)) == svc
                svc_zone = reference_curves(cfg, speed, track, brake, closing, age, service=True, supervised=False)
                assert ebi_dm(cfg, speed, track, brake, closing, age, service=True) == svc_zone[1]
                assert zone[1] <= want[1]                 # the zone limit is never beyond the supervised EBI


def test_curves_saturate_at_100_km():
    """Every curve is capped at 1,000,000 dm (100 km): an obstacle in range is inside it."""
    from monitor.core.braking import CURVE_CAP_DM, curves

    from monitor.core.config import check

    cfg = Config(max_gradient_permille=0, slippery_permille=1000, degraded_permille=1000, emergency_decel_mms2=100,
                 emergency_band2_cms=0, service_decel_mms2=100, traction_cutoff_ms=30000, max_accel_mms2=5000,
                 warning_ms=60000)
    check(cfg)
    c = curves(cfg, 12000, 0, 0, 12000, 300)
    assert CURVE_CAP_DM == 1_000_000
    assert tuple(c) == reference_curves(cfg, 12000, 0, 0, 12000, 300)
    assert c.ebi_dm == c.sbi_dm == c.warning_dm == CURVE_CAP_DM and c.ebd_dm < CURVE_CAP_DM


# --------------------------------------------------------------------------- configuration


def test_defaults_are_the_documented_ones_and_the_papers_train():
    """Config() holds the defaults of docs/core.md and, for the braking declaration, the
    papers' train of monitor/trains/papers-train.toml (read from the file here)."""
    from monitor import declaration
    from monitor.core.config import DECLARATION_FIELDS

    documented = dict(period_ms=100, timeout_cycles=3, persistence_cycles=10, warning_ms=2000, emergency_release=1,
                      release_confirm_cycles=5, warning_margin_dm=10000, fast_closing_cms=2000, safe_reaction=2,
                      topology="3oo3", recovery_cycles=10, max_overruns=3, distance_tolerance_dm=100)
    cfg = Config()
    assert {k: getattr(cfg, k) for k in documented} == documented
    papers = declaration.apply(Config(period_ms=1), declaration.shipped())
    assert {k: getattr(cfg, k) for k in DECLARATION_FIELDS} == {k: getattr(papers, k) for k in DECLARATION_FIELDS}
    assert cfg.modules == 3 and cfg.channels == 6
    assert Config(topology="2oo2").modules == 1 and Config(topology="2oo2").channels == 2


# (field, lowest accepted, highest accepted); one step beyond either end is refused
BOUNDS = [("period_ms", 1, 10000), ("timeout_cycles", 1, 600), ("persistence_cycles", 1, 1000),
          ("emergency_decel_mms2", 2200, 20000), ("service_decel_mms2", 531, 2200),
          ("emergency_buildup_ms", 0, 30000), ("service_buildup_ms", 0, 30000), ("traction_cutoff_ms", 0, 30000),
          ("max_accel_mms2", 0, 5000), ("speed_error_permille", 0, 500), ("max_gradient_permille", 0, 60, 2200),
          ("standstill_margin_dm", 0, 10000), ("warning_ms", 0, 60000), ("emergency_release", 0, 1),
          ("release_confirm_cycles", 1, 1000), ("warning_margin_dm", 0, 60000), ("fast_closing_cms", 1, 15000),
          ("safe_reaction", 1, 2), ("recovery_cycles", 1, 100000), ("max_overruns", 1, 1000),
          ("distance_tolerance_dm", 0, 60000), ("emergency_band2_cms", 0, 12000), ("forget_ms", 1, 600000),
          ("sensor_range_dm", 1, 60000)]


@pytest.mark.parametrize("bound", BOUNDS, ids=[b[0] for b in BOUNDS])
def test_every_configuration_bound_is_exact(bound):
    """Each configuration value is accepted at both ends of its range and refused one step
    beyond (ConfigurationError), on the shipped configuration otherwise: there the
    decelerations' ends are where the band order and the worst case bite (service 531..2200,
    emergency from 2200, band 2's: the guaranteed deceleration only falls with speed), timeout_cycles ends at 60 s / 100 ms, and the gradient is checked
    up to 60 per mille with a service brake of 2200 mm/s^2."""
    from monitor.core.config import ConfigurationError, check

    field, lo, hi = bound[:3]
    base = Config(service_decel_mms2=bound[3]) if len(bound) > 3 else Config()
    for ok in (lo, hi):
        check(base._replace(**{field: ok}))
    for bad in (lo - 1, hi + 1):
        with pytest.raises(ConfigurationError):
            check(base._replace(**{field: bad}))


def test_slippery_and_degraded_factors_and_the_worst_case_deceleration():
    """Adhesion factors are 1..1000 per mille; the worst case (weakest band x slippery x
    degraded, rounded down, less g x gradient rounded up) must leave >= 100 mm/s^2, for the
    emergency bands and for the service brake, exactly at 100 accepted, at 99 refused."""
    from monitor.core.config import ConfigurationError, check

    flat = Config(max_gradient_permille=0, emergency_band2_cms=0, service_decel_mms2=100, emergency_decel_mms2=100)
    for name in ("slippery_permille", "degraded_permille"):
        check(flat._replace(slippery_permille=1000, degraded_permille=1000))
        for bad in (0, 1001):
            with pytest.raises(ConfigurationError, match=name):
                check(flat._replace(**{name: bad}))
    one = flat._replace(slippery_permille=1000, degraded_permille=1000)
    check(one)                                       # 100 * 1 * 1 - 0 = 100: accepted
    with pytest.raises(ConfigurationError, match="service_decel_mms2"):
        check(one._replace(service_decel_mms2=99, emergency_decel_mms2=100))
    with pytest.raises(ConfigurationError, match="emergency_decel_mms2|max_gradient_permille"):
        check(one._replace(emergency_decel_mms2=99, service_decel_mms2=99))
    # 20 per mille downhill: g x 20 = 196.2 -> 197 mm/s^2
    down = one._replace(max_gradient_permille=20, emergency_decel_mms2=297, service_decel_mms2=297)
    check(down)
    with pytest.raises(ConfigurationError, match="max_gradient_permille"):
        check(down._replace(emergency_decel_mms2=296, service_decel_mms2=296))
    with pytest.raises(ConfigurationError, match="service_decel_mms2"):
        check(down._replace(service_decel_mms2=296))
    # slippery 500 and degraded 500 per mille: 400 * 0.25 = 100 accepted, 399 -> 99 refused
    adverse = one._replace(slippery_permille=500, degraded_permille=500, emergency_decel_mms2=400,
                           service_decel_mms2=400)
    check(adverse)
    with pytest.raises(ConfigurationError, match="service_decel_mms2"):
        check(adverse._replace(service_decel_mms2=399))
    with pytest.raises(ConfigurationError):
        check(adverse._replace(emergency_decel_mms2=399, service_decel_mms2=399))


def test_speed_bands_are_checked_in_order():
    """Band 2 starts at 1..12000 cm/s (0: none) with its deceleration 1..20000; band 3 needs
    band 2 and must start above it; the service brake may not exceed the weakest band;
    emergency_bands lists the bands in use, lowest speed first."""
    from monitor.core.config import ConfigurationError, check, emergency_bands

    cfg = Config()
    assert emergency_bands(cfg) == ((0, 2400), (3000, 2200))
    assert emergency_bands(cfg._replace(emergency_band2_cms=0)) == ((0, 2400),)
    three = cfg._replace(emergency_band3_cms=3001, emergency_band3_mms2=2000)
    check(three)
    assert emergency_bands(three) == ((0, 2400), (3000, 2200), (3001, 2000))
    for bad in (dict(emergency_band3_cms=3000, emergency_band3_mms2=2000),
                dict(emergency_band2_cms=0, emergency_band3_cms=3001, emergency_band3_mms2=2000),
                dict(emergency_band3_cms=3001, emergency_band3_mms2=0),
                dict(emergency_band3_cms=3001, emergency_band3_mms2=20001),
                dict(emergency_band3_cms=12001, emergency_band3_mms2=2000),
                dict(emergency_band3_cms=-1),
                dict(emergency_band2_mms2=0), dict(emergency_band2_mms2=20001),
                dict(service_decel_mms2=2201), dict(emergency_band3_cms=3001, emergency_band3_mms2=799)):
        with pytest.raises(ConfigurationError):
            check(cfg._replace(**bad))
    check(cfg._replace(emergency_band3_cms=12000, emergency_band3_mms2=2200))       # equal to band 2: accepted
    for rising in (dict(emergency_band3_cms=12000, emergency_band3_mms2=2201), dict(emergency_band2_mms2=2401)):
        with pytest.raises(ConfigurationError, match="may only fall with speed"):      # (issue 40 item 4)
            check(cfg._replace(**rising))
    check(cfg._replace(emergency_band3_cms=3001, emergency_band3_mms2=800))
    check(cfg._replace(service_decel_mms2=2200))
    check(cfg._replace(emergency_band2_cms=0, emergency_band2_mms2=0, emergency_band3_mms2=-5))


@pytest.mark.parametrize("value", [True, 1.0, "100", None])
def test_configuration_values_must_be_whole_numbers(value):
    """Every configuration value but the topology must be an int: a bool, a float, a string
    or None is refused; an unknown topology or key is refused too."""
    from monitor.core.config import ConfigurationError, check, from_mapping

    for name in ("period_ms", "safe_reaction", "emergency_release", "distance_tolerance_dm"):
        with pytest.raises(ConfigurationError, match="whole number"):
            check(Config()._replace(**{name: value}))
    with pytest.raises(ConfigurationError, match="topology"):
        check(Config(topology="1oo2"))
    with pytest.raises(ConfigurationError, match="unknown"):
        from_mapping({"period_ms": 100, "no_such_key": 1})
    assert from_mapping({"topology": "2oo2", "period_ms": 100}) == Config(topology="2oo2")


def test_gradient_acceleration_is_g_times_gradient_rounded_up():
    """g x gradient in mm/s^2 with g = 9.81 m/s^2, rounded up: 0 -> 0, 1 -> 10, 20 -> 197, 60 -> 589."""
    import math
    from fractions import Fraction as F

    from monitor.core.config import gradient_accel_mms2

    assert [gradient_accel_mms2(p) for p in (0, 1, 20, 60)] == [0, 10, 197, 589]
    assert all(gradient_accel_mms2(p) == math.ceil(F(981, 100) * p) for p in range(61))


def test_configuration_refusals_name_the_first_bad_value_and_why():
    """config.check refuses with the first value that cannot be used and the reason, in its
    documented order: a deceleration of 1 mm/s^2 is in range but weaker than the service
    brake (so is a band's), and a band may not brake better than the one below it; an adhesion factor of 1 per mille is in range but leaves no
    guaranteed deceleration; a service brake of 1 mm/s^2 is in range but too weak on the downhill; band 3 at
    -1 cm/s is out of range (not merely below band 2); band 2 may start at 1 cm/s; a report
    may be at most 60 s old whatever the period."""
    from monitor.core.config import ConfigurationError, check

    def refusal(**kw) -> str:
        with pytest.raises(ConfigurationError) as exc:
            check(Config(**kw))
        return str(exc.value)

    assert refusal(emergency_decel_mms2=1).startswith("emergency_band2_mms2 = 2200: must not exceed the band below")
    assert refusal(emergency_band2_cms=0, emergency_decel_mms2=1).startswith("service_decel_mms2 = 800: must not exceed")
    assert refusal(emergency_decel_mms2=0).startswith("emergency_decel_mms2 = 0: a deceleration must be 1..20000")
    assert refusal(service_decel_mms2=1).startswith("service_decel_mms2 = 1: too weak")
    assert refusal(service_decel_mms2=0).startswith("service_decel_mms2 = 0: a deceleration must be 1..20000")
    assert refusal(emergency_band3_cms=-1).startswith("emergency_band3_cms = -1: must be 0 (no band)")
    assert refusal(emergency_band2_cms=-1).startswith("emergency_band2_cms = -1: must be 0 (no band)")
    assert refusal(emergency_band2_mms2=1).startswith("service_decel_mms2 = 800: must not exceed")
    assert refusal(emergency_band2_mms2=0).startswith("emergency_band2_mms2 = 0: a deceleration must be 1..20000")
    for name in ("slippery_permille", "degraded_permille"):
        assert refusal(**{name: 1}).startswith("max_gradient_permille = 20: on this downhill")
        assert refusal(**{name: 0}).startswith(f"{name} = 0: a deceleration factor must be 1..1000")
    # the worst case takes the weakest band, rounded down: 110 x 0.999 x 0.910 = 99.9999 -> 99 < 100
    assert refusal(emergency_band2_mms2=300, service_decel_mms2=300).startswith("max_gradient_permille = 20: on this")
    edge = dict(max_gradient_permille=0, emergency_band2_cms=0, slippery_permille=999, degraded_permille=910)
    assert refusal(**edge, emergency_decel_mms2=110, service_decel_mms2=110).startswith("max_gradient_permille = 0")
    assert refusal(**edge, emergency_decel_mms2=2000, service_decel_mms2=110).startswith("service_decel_mms2 = 110: too weak")
    check(Config(**edge, emergency_decel_mms2=2000, service_decel_mms2=111))
    check(Config(emergency_band2_cms=1, emergency_band3_cms=2, emergency_band3_mms2=2000))
    check(Config(period_ms=1, timeout_cycles=60000))
    assert refusal(period_ms=1, timeout_cycles=60001).startswith("timeout_cycles = 60001: a report may be at most 60 s")
    assert refusal(period_ms=7, timeout_cycles=8572).startswith("timeout_cycles = 8572")
    check(Config(period_ms=7, timeout_cycles=8571))


# --------------------------------------------------------------------------- the table file


def test_table_length_check_is_exact():
    """A file of exactly prefix + digest bytes (46) is long enough to be read: with a valid
    magic, version and SHA-256 but an empty header it is refused for its header, not as too
    short; one byte less is too short."""
    import hashlib
    import struct

    from monitor.core.table import TableError, decode

    body = struct.pack("<8sHI", b"RGTABLE\n", 2, 0)
    data = body + hashlib.sha256(body).digest()
    assert len(data) == 46
    with pytest.raises(TableError, match="header is not valid JSON"):
        decode(data)
    with pytest.raises(TableError, match="too short"):
        decode(data[:45])


@pytest.mark.parametrize("key", ["states", "actions", "observations"])
@pytest.mark.parametrize("names", [[], ["a", 1], [None], "abc"], ids=repr)
def test_header_name_lists_must_be_non_empty_lists_of_strings(key, names):
    """A table header's states, actions and observations must each be a non-empty list of
    strings: an empty list, a list with a non-string, or a string is refused."""
    from monitor.core.table import TableError, decode, encode

    t = decode(read("m1"))
    header = dict(t.header)
    header[key] = names
    if key == "observations":
        data = _with_header_text(encode(dict(t.header), t.action, t.next),
                                 b'"observations":["free","warning","emergency","critical"]',
                                 b'"observations":' + json.dumps(names, separators=(",", ":")).encode())
    else:
        data = encode(header, t.action, t.next)
    with pytest.raises(TableError, match=f"header '{key}' must be a non-empty list of names"):
        decode(data)


def test_code_constants_follow_the_observation_names():
    """The obstacle, track and brake codes of types.py are the positions of their names in
    Model 2's observation components (static/dynamic/train, normal/slippery, normal/degraded),
    the statuses and demands are ordered to the safe side, and the modes and reason bits
    are distinct."""
    from monitor.core import types as T
    from monitor.core.observation import M2_COMPONENTS

    assert (T.STATIC, T.DYNAMIC, T.TRAIN) == tuple(M2_COMPONENTS[2].index(n) for n in ("static", "dynamic", "train"))
    assert (T.TRACK_NORMAL, T.TRACK_SLIPPERY) == tuple(M2_COMPONENTS[3].index(n) for n in ("normal", "slippery"))
    assert (T.BRAKE_NORMAL, T.BRAKE_DEGRADED) == tuple(M2_COMPONENTS[4].index(n) for n in ("normal", "degraded"))
    assert (T.ABSENT, T.PRESENT, T.DEGRADED) == (0, 1, 2) and T.STATUS_NAMES[T.DEGRADED] == "DEGRADED"
    assert (T.MAINTAIN, T.SERVICE, T.EMERGENCY) == (0, 1, 2)
    assert (T.INIT, T.NORMAL, T.DEGRADED_MODE, T.SAFE_STOP) == (0, 1, 2, 3)
    bits = [getattr(T, "R_" + name.upper()) for name in T.REASON_NAMES]
    assert bits == [1 << i for i in range(len(bits))]
    assert (T.MAX_DISTANCE_DM, T.MAX_CLOSING_CMS, T.MAX_SPEED_CMS, T.NO_DISTANCE, T.MAX_COUNT) == \
        (60000, 15000, 12000, 65535, 2 ** 31 - 1)


def test_exact_reasons_of_a_safe_stop_for_a_persistent_disagreement():
    """A 2oo2 disagreement (module 1: ABSENT/PRESENT, far away, at standstill) persisting
    persistence_cycles is a perceptor error: SAFE_STOP with exactly safe_stop, perceptor,
    system_error, dispute and warning (no deadline bit, no table bit) and an emergency."""
    from monitor.core.types import R_PERCEPTOR, R_SAFE_STOP, R_WARNING, SAFE_STOP

    core = Core(Config(persistence_cycles=3)).normal()
    statuses = [PRESENT, ABSENT] + [ABSENT] * 4
    for _ in range(3):
        out = core.cycle(core.reports(statuses, [FAR] * 6), 0)
    assert out.mode == SAFE_STOP and out.demand == EMERGENCY
    assert out.reasons == R_SAFE_STOP | R_PERCEPTOR | R_SYSTEM_ERROR | R_DISPUTE | R_WARNING


def test_inputs_default_to_a_standing_train_and_no_overrun():
    """Inputs without a train state or an overrun count mean a valid train at standstill on
    a normal track with normal brakes and no deadline overrun: with max_overruns = 1 such a
    cycle is no SAFE_STOP and no train-input error, and nothing brakes on a clear track."""
    from monitor.core.types import R_TRAIN_INPUT, SAFE_STOP

    assert Train() == Train(0, 0, 0)
    assert Inputs(()).train == Train(0, 0, 0) and Inputs(()).overruns == 0
    core = Core(Config(max_overruns=1)).normal()
    state, out = step(core.setup, core.state, Inputs(tuple(core.reports([ABSENT] * 6))), core.tick)
    assert out.mode != SAFE_STOP and not out.reasons & R_TRAIN_INPUT and out.demand == MAINTAIN


@pytest.mark.parametrize("silent", [0, 3, 5])
def test_system_status_is_the_maximum_under_safe_reaction_service(silent):
    """3oo3 status is the maximum of the module statuses (the safe side): one silent channel
    makes its module DEGRADED while the others see nothing, so the system status is
    DEGRADED and, with no voted distance, the table observes 'critical' (3); the error
    answers with safe_reaction = SERVICE and the stale reason."""
    core = Core(Config(safe_reaction=SERVICE)).normal()
    reps = core.reports([ABSENT] * 6)
    reps[silent] = None
    out = core.cycle(reps, V)
    assert out.observation == 3 and out.reasons & R_STALE and out.system_error
    assert out.demand == SERVICE
    statuses = [ABSENT, ABSENT, ABSENT]
    statuses[silent // 2] = DEGRADED
    assert voter.vote_3oo3(statuses[0], 65535, False, statuses[1], 65535, False, statuses[2], 65535, False)[0] == DEGRADED


def test_an_obstacle_of_its_own_speed_1_cms_lengthens_the_lead():
    """SBI and the warning curve lead EBI by the run at the measured speed plus its error
    plus an oncoming obstacle's own speed, counted from the closing speed plus the closing
    accuracy (1 m/s, the error budget): at 49 cm/s (50 with the 2 % error) an obstacle
    measured closing at -51 cm/s may close at 49 cm/s, so it is itself coming at 1 cm/s, the
    lead is 51 cm/s and each curve leads by ceil(51 x 2 s) = 11 dm (10 dm for an obstacle
    that may at worst stand still: measured -52); an obstacle moving away never shortens the
    lead (50 cm/s, measured -52, at worst 48: still 51 cm/s, 11 dm). Without the budget
    (exact sensors) the same holds at the measured closing speeds 49, 48 and 48."""
    from monitor.core.braking import curves

    cfg = Config()
    assert cfg.closing_accuracy_cms == 100
    oncoming = curves(cfg, 49, 0, 0, -51, 0)
    standing = curves(cfg, 49, 0, 0, -52, 0)
    assert (oncoming.sbi_dm - oncoming.ebi_dm, oncoming.warning_dm - oncoming.sbi_dm) == (11, 11)
    assert (standing.sbi_dm - standing.ebi_dm, standing.warning_dm - standing.sbi_dm) == (10, 10)
    assert tuple(oncoming) == reference_curves(cfg, 49, 0, 0, -51, 0)
    away = curves(cfg, 50, 0, 0, -52, 0)           # 51 cm/s with the error; the obstacle moves away at 1 cm/s
    assert (away.sbi_dm - away.ebi_dm, away.warning_dm - away.sbi_dm) == (11, 11)
    exact = Config(closing_accuracy_cms=0)
    oncoming = curves(exact, 49, 0, 0, 49, 0)
    standing = curves(exact, 49, 0, 0, 48, 0)
    assert (oncoming.sbi_dm - oncoming.ebi_dm, oncoming.warning_dm - oncoming.sbi_dm) == (11, 11)
    assert (standing.sbi_dm - standing.ebi_dm, standing.warning_dm - standing.sbi_dm) == (10, 10)
    assert tuple(oncoming) == reference_curves(exact, 49, 0, 0, 49, 0)
    away = curves(exact, 50, 0, 0, 48, 0)
    assert (away.sbi_dm - away.ebi_dm, away.warning_dm - away.sbi_dm) == (11, 11)


def test_keep_held_keeps_only_while_moving_and_only_above_the_causes():
    """envelope.keep_held: while an obstacle in sight closes in, what is held is kept while
    the train moves, 1 cm/s included; at standstill (0 cm/s) the causes' demand goes through,
    so the hold can release there; nothing above the causes is invented."""
    from monitor.core.envelope import keep_held

    assert keep_held(MAINTAIN, EMERGENCY, 1, True) == EMERGENCY
    assert keep_held(MAINTAIN, EMERGENCY, 2, True) == EMERGENCY
    assert keep_held(MAINTAIN, EMERGENCY, 0, True) == MAINTAIN
    assert keep_held(SERVICE, EMERGENCY, 0, True) == SERVICE
    assert keep_held(MAINTAIN, EMERGENCY, 4000, False) == MAINTAIN
    assert keep_held(EMERGENCY, SERVICE, 4000, True) == EMERGENCY
