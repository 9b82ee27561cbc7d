"""Example-based behaviour of one monitor cycle, `monitor.core.cycle.step` (DESIGN.md 3 and 4).

Every test drives the real core through `create()` with a shipped table and checks what a
wrong implementation would get wrong: modes, demands, reason bits, voted distance and the
refusals at start-up. Expected values are written out or computed here independently.
"""
from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import pytest

import monitor
from monitor.core.config import Config, ConfigurationError, forget_cycles
from monitor.core.cycle import create, initial_state, replay, step
from monitor.core.braking import curves, ebi_dm
from monitor.core.table import decode, encode
from monitor.core.types import (
    ABSENT, DEGRADED, DEGRADED_MODE, DYNAMIC, EMERGENCY, INIT, MAINTAIN, MAX_CLOSING_CMS,
    MAX_DISTANCE_DM, MAX_SPEED_CMS, NO_DISTANCE, NORMAL, PRESENT, R_DEADLINE, R_ENVELOPE, R_INIT,
    R_DISPUTE, R_LATCH, R_PERCEPTOR, R_SAFE_STOP, R_SBI, R_STALE, R_SYSTEM_ERROR, R_TABLE, R_TRAIN_INPUT,
    R_WARNING, SAFE_STOP, SERVICE, STATIC, TRACK_FORGOTTEN, TRACK_NONE, TRAIN, Inputs, Report, State, Train,
)

TABLES = Path(monitor.__file__).resolve().parent / "tables"
M1 = (TABLES / "m1.table.rgt").read_bytes()
M2 = (TABLES / "m2.table.rgt").read_bytes()
PERIOD = 100
V = 4000  # 40 m/s, the papers' speed
HELD = Config(emergency_release=0)   # ETCS national value: emergency held to standstill
FAR = 30000  # 3 km: beyond the warning curve at 40 m/s (about 640 m)


# --------------------------------------------------------------------------- helpers


def clear(tick: int, n: int = 6) -> tuple:
    return tuple(Report(ABSENT, 0, 0, STATIC, tick) for _ in range(n))


def present(tick: int, distance: int, n: int = 6, closing: int = 0, obstacle: int = STATIC) -> tuple:
    return tuple(Report(PRESENT, distance, closing, obstacle, tick) for _ in range(n))


def with_channel(reports: tuple, i: int, report) -> tuple:
    r = list(reports)
    r[i] = report
    return tuple(r)


class Driver:
    """Runs the core cycle by cycle on a tick that advances by the period."""

    def __init__(self, cfg: Config = Config(), table: bytes = M1):
        self.setup = create(cfg, table)
        self.cfg = cfg
        self.state = initial_state(self.setup)
        self.tick = 0
        self.out = None

    def cycle(self, reports, speed=0, overruns=0, train=None):
        if train is None:
            train = Train(speed)
        self.state, self.out = step(self.setup, self.state, Inputs(reports, train, overruns), self.tick)
        self.tick += self.cfg.period_ms
        return self.out

    def clear(self, speed=0, **kw):
        return self.cycle(clear(self.tick, self.cfg.channels), speed, **kw)

    def present(self, distance, speed=0, **kw):
        return self.cycle(present(self.tick, distance, self.cfg.channels), speed, **kw)


def normal_driver(cfg: Config = Config(), table: bytes = M1) -> Driver:
    """A driver that has left INIT at standstill with a clear track (node = start's successor)."""
    d = Driver(cfg, table)
    out = d.clear(0)
    assert out.mode == NORMAL and out.demand == MAINTAIN
    return d


# --------------------------------------------------------------------------- INIT


def test_init_demands_emergency_until_every_channel_has_been_fresh_once():
    d = Driver()
    # channels 4 and 5 never heard, channel 3 reports from the future: not fresh
    reps = with_channel(clear(0)[:4] + (None, None), 3, Report(ABSENT, 0, 0, STATIC, 50))
    out = d.cycle(reps, 0)
    assert out.mode == INIT and out.demand == EMERGENCY
    assert out.reasons & R_INIT and out.reasons & R_STALE
    # channels become fresh one after the other; INIT holds while any is still missing
    for missing in (3, 4, 5):
        reps = clear(d.tick)[:missing] + (None,) * (6 - missing)
        out = d.cycle(reps, 0)
        assert out.mode == INIT, missing
        assert out.demand == EMERGENCY and out.reasons & R_INIT
        assert out.node == d.setup.table.start
    # every channel fresh: NORMAL, and a clear track at speed needs no braking (m1: maintain)
    out = d.clear(V)
    assert out.mode == NORMAL
    assert out.demand == MAINTAIN
    assert out.reasons == 0
    assert out.distance_dm == NO_DISTANCE and not out.system_error and out.module_flags == 0
    for _ in range(5):
        out = d.clear(V)
        assert (out.mode, out.demand, out.reasons) == (NORMAL, MAINTAIN, 0)


def test_init_ends_when_each_channel_was_fresh_once_even_if_not_together():
    d = Driver()
    # channel i reports only in cycle i; the timeout is 3 cycles, so 0 and 1 are stale again at the end
    reports = [None] * 6
    for i in range(6):
        reports[i] = Report(ABSENT, 0, 0, STATIC, d.tick)
        out = d.cycle(tuple(reports), 0)
        if i < 5:
            assert out.mode == INIT and out.demand == EMERGENCY and out.reasons & R_INIT
    # all seen, but channels 0 and 1 are stale now: leave INIT into DEGRADED, still braking
    assert out.mode == DEGRADED_MODE
    assert not out.reasons & R_INIT
    assert out.reasons & R_STALE and out.reasons & R_SYSTEM_ERROR and out.system_error
    assert out.module_flags == 0b001
    assert out.demand == EMERGENCY


@pytest.mark.parametrize("bad", [None, Report(3, 0, 0, STATIC, 0), "future", "old"], ids=repr)
@pytest.mark.parametrize("speed", [0, V])
def test_a_channel_that_is_never_fresh_keeps_init_forever(bad, speed):
    d = Driver()
    for _ in range(60):
        if bad == "future":
            r = Report(ABSENT, 0, 0, STATIC, d.tick + 1)
        elif bad == "old":
            r = Report(ABSENT, 0, 0, STATIC, d.tick - 301)
        elif bad is None:
            r = None
        else:
            r = bad._replace(tick=d.tick)
        out = d.cycle(with_channel(clear(d.tick), 3, r), speed)
        assert out.mode == INIT
        assert out.demand == EMERGENCY
        assert out.reasons & R_INIT and out.reasons & R_STALE
        assert out.node == d.setup.table.start


@pytest.mark.parametrize("cfg", [Config(), HELD], ids=["revocable", "held"])
def test_a_monitor_started_on_a_moving_train_brakes_until_its_picture_is_valid_then_releases(cfg):
    """INIT demands emergency without latching it (issue 11, deliver 4), whatever the release
    mode: the train is not stopped just because the monitor started while it moved."""
    d = Driver(cfg)
    for _ in range(5):
        out = d.cycle(clear(d.tick)[:5] + (None,), V)
        assert out.mode == INIT and out.demand == EMERGENCY and out.reasons & R_INIT
        assert not d.state.latched
    out = d.clear(V)
    assert out.mode == NORMAL
    assert out.demand == MAINTAIN and out.reasons == 0
    # but a real emergency during INIT (obstacle inside EBI) is latched as any emergency
    d = Driver(cfg)
    out = d.cycle(present(0, 100)[:5] + (None,), V)
    assert out.mode == INIT and out.demand == EMERGENCY and out.reasons & R_ENVELOPE and d.state.latched


# --------------------------------------------------------------------------- stale channel, DEGRADED


@pytest.mark.parametrize("channel", range(6))
def test_one_silent_channel_is_a_system_error(channel):
    d = normal_driver()
    assert d.clear(V).demand == MAINTAIN
    old = Report(ABSENT, 0, 0, STATIC, d.tick - 3 * PERIOD - 1)
    out = d.cycle(with_channel(clear(d.tick), channel, old), V)
    assert out.demand >= d.cfg.safe_reaction
    assert out.demand == EMERGENCY
    assert out.reasons & R_STALE and out.reasons & R_SYSTEM_ERROR
    assert out.system_error
    assert out.mode == DEGRADED_MODE
    assert out.module_flags == 1 << (channel // 2)


def test_freshness_boundary_is_exactly_the_timeout():
    d = normal_driver()
    edge = Report(ABSENT, 0, 0, STATIC, d.tick - 3 * PERIOD)   # now - tick == 300: fresh
    out = d.cycle(with_channel(clear(d.tick), 2, edge), V)
    assert (out.mode, out.demand, out.reasons, out.system_error) == (NORMAL, MAINTAIN, 0, False)
    late = Report(ABSENT, 0, 0, STATIC, d.tick - 3 * PERIOD - 1)  # 301: stale
    out = d.cycle(with_channel(clear(d.tick), 2, late), V)
    assert out.mode == DEGRADED_MODE and out.reasons & R_STALE and out.demand == EMERGENCY
    ahead = Report(ABSENT, 0, 0, STATIC, d.tick + 1)              # from the future: not fresh
    out = d.cycle(with_channel(clear(d.tick), 2, ahead), V)
    assert out.reasons & R_STALE and out.system_error


def test_safe_reaction_service_is_used_for_a_system_error():
    d = normal_driver(Config(safe_reaction=SERVICE))
    out = d.cycle(with_channel(clear(d.tick), 0, None), V)
    assert out.system_error and out.mode == DEGRADED_MODE
    assert out.demand == SERVICE      # m1 clear track: the table says maintain, the error says service


@pytest.mark.parametrize("recovery", [10, 4])
def test_degraded_recovers_to_normal_only_after_recovery_cycles(recovery):
    cfg = HELD._replace(recovery_cycles=recovery)
    d = normal_driver(cfg)
    out = d.cycle(with_channel(clear(d.tick), 5, None), V)
    assert out.mode == DEGRADED_MODE and out.demand == EMERGENCY
    # error gone, but the count restarts if the error comes back before recovery
    for _ in range(recovery - 1):
        out = d.clear(V)
        assert out.mode == DEGRADED_MODE
        assert not out.system_error and not out.reasons & R_STALE
        assert out.demand == EMERGENCY and out.reasons & R_LATCH   # moving: latched
    out = d.cycle(with_channel(clear(d.tick), 1, None), V)
    assert out.mode == DEGRADED_MODE and out.system_error
    for _ in range(recovery - 1):
        out = d.clear(V)
        assert out.mode == DEGRADED_MODE
    out = d.clear(V)
    assert out.mode == NORMAL
    assert out.demand == EMERGENCY and out.reasons & R_LATCH      # still moving: latch holds
    out = d.clear(0)
    assert out.mode == NORMAL and out.demand == MAINTAIN and out.reasons == 0


def test_a_revocable_emergency_from_a_stale_channel_is_released_when_the_channel_is_back():
    cfg = Config()
    d = normal_driver(cfg)
    for _ in range(4):
        out = d.cycle(with_channel(clear(d.tick), 5, None), V)
        assert out.demand == EMERGENCY and out.reasons & R_STALE
    for k in range(cfg.release_confirm_cycles - 1):
        out = d.clear(V)
        assert out.demand == EMERGENCY and out.reasons & R_LATCH, k     # cause gone, not yet confirmed
    out = d.clear(V)
    assert out.demand == MAINTAIN and not out.reasons & R_LATCH        # released while moving
    assert out.mode == DEGRADED_MODE                                  # the mode recovers on its own count


def test_degraded_recovery_at_standstill_releases_the_demand():
    d = normal_driver()
    out = d.cycle(with_channel(clear(d.tick), 0, None), 0)
    assert out.mode == DEGRADED_MODE and out.demand == EMERGENCY
    for _ in range(9):
        out = d.clear(0)
        assert out.mode == DEGRADED_MODE
        assert out.demand == MAINTAIN   # no error now and at standstill nothing is latched
    out = d.clear(0)
    assert out.mode == NORMAL


# --------------------------------------------------------------------------- perceptor error, SAFE_STOP


def disagreeing(tick: int, distance: int = FAR) -> tuple:
    """Module 0 split: channel 0 sees an obstacle, channel 1 none; modules 1 and 2 see none."""
    return with_channel(clear(tick), 0, Report(PRESENT, distance, 0, STATIC, tick))


def test_persistent_2oo2_disagreement_is_a_perceptor_error_and_safe_stop():
    d = normal_driver()
    for k in range(1, d.cfg.persistence_cycles):
        out = d.cycle(disagreeing(d.tick), V)
        assert out.mode == DEGRADED_MODE, k
        assert out.system_error and out.module_flags == 0b001
        assert not out.reasons & (R_PERCEPTOR | R_SAFE_STOP)
        # a dispute about an obstacle far beyond the curves: a warning and a diagnostic
        assert out.demand == MAINTAIN and out.warning and out.reasons & R_DISPUTE and out.reasons & R_WARNING
    out = d.cycle(disagreeing(d.tick), V)
    assert out.mode == SAFE_STOP
    assert out.reasons & R_PERCEPTOR and out.reasons & R_SAFE_STOP
    assert out.demand == EMERGENCY
    # healthy again but moving: SAFE_STOP is kept however long it lasts; the perceptor
    # error itself clears after persistence_cycles calm cycles in a row
    for k in range(3 * d.cfg.recovery_cycles):
        out = d.clear(V)
        assert out.mode == SAFE_STOP and out.demand == EMERGENCY
        assert out.reasons & R_SAFE_STOP
        assert bool(out.reasons & R_PERCEPTOR) == (k < d.cfg.persistence_cycles - 1), k
    # an invalid speed is not a standstill
    out = d.cycle(clear(d.tick), train=Train(-1))
    assert out.mode == SAFE_STOP and out.demand == EMERGENCY
    for _ in range(d.cfg.recovery_cycles - 1):
        out = d.clear(V)
        assert out.mode == SAFE_STOP
    # standstill after recovery_cycles healthy cycles: leave SAFE_STOP
    out = d.clear(0)
    assert out.mode == NORMAL
    assert out.demand == MAINTAIN and out.reasons == 0


def test_safe_stop_at_standstill_needs_recovery_cycles_healthy_cycles():
    d = normal_driver()
    for _ in range(d.cfg.persistence_cycles):
        out = d.cycle(disagreeing(d.tick), 0)
    assert out.mode == SAFE_STOP
    # the perceptor error clears after persistence_cycles calm cycles, then recovery_cycles healthy ones
    for _ in range(d.cfg.persistence_cycles - 1 + d.cfg.recovery_cycles - 1):
        out = d.clear(0)
        assert out.mode == SAFE_STOP and out.demand == EMERGENCY and out.reasons & R_SAFE_STOP
    out = d.clear(0)
    assert out.mode == NORMAL and out.demand == MAINTAIN


def test_a_disagreement_shorter_than_persistence_is_no_perceptor_error():
    """Disagreements separated by persistence_cycles calm cycles in a row never add up."""
    d = normal_driver()
    for _ in range(10):
        for _ in range(d.cfg.persistence_cycles - 1):
            out = d.cycle(disagreeing(d.tick), V)
            assert out.mode == DEGRADED_MODE and not out.reasons & R_PERCEPTOR
        for _ in range(d.cfg.persistence_cycles):
            out = d.clear(V)
            assert out.mode in (DEGRADED_MODE, NORMAL) and not out.reasons & R_PERCEPTOR


@pytest.mark.parametrize("calm", [1, 5, 9])
def test_disagreements_add_up_until_a_calm_spell_of_persistence_cycles(calm):
    """Issue 29 item 5: a flapping channel (disagreeing, then agreeing for fewer than
    persistence_cycles) escalates to a perceptor error: the count is not restarted by a
    short agreement."""
    d = normal_driver()
    n = d.cfg.persistence_cycles
    for k in range(n - 1):
        out = d.cycle(disagreeing(d.tick), V)
        if k % 3 == 2:
            for _ in range(calm):
                out = d.clear(V)
                assert not out.reasons & R_PERCEPTOR
    out = d.cycle(disagreeing(d.tick), V)
    assert out.mode == SAFE_STOP and out.reasons & R_PERCEPTOR and out.demand == EMERGENCY


def test_disagreement_in_the_other_direction_and_other_module_counts_too():
    d = normal_driver(Config(persistence_cycles=2))
    reps = lambda t: with_channel(present(t, FAR), 3, Report(ABSENT, 0, 0, STATIC, t))
    out = d.cycle(reps(d.tick), V)
    assert out.mode == DEGRADED_MODE and out.module_flags == 0b010
    out = d.cycle(reps(d.tick), V)
    assert out.mode == SAFE_STOP and out.reasons & R_PERCEPTOR


# --------------------------------------------------------------------------- 3oo3


@pytest.mark.parametrize("module", range(3))
def test_3oo3_one_module_sees_an_obstacle_the_others_none(module):
    d = normal_driver()
    far = 50000  # free zone at 40 m/s: the table alone would maintain
    reps = clear(d.tick)
    for ch in (2 * module, 2 * module + 1):
        reps = with_channel(reps, ch, Report(PRESENT, far, 0, STATIC, d.tick))
    out = d.cycle(reps, V)
    assert out.system_error
    assert out.module_flags == 0            # each module agrees with itself
    assert out.reasons & R_SYSTEM_ERROR and out.reasons & R_DISPUTE and not out.reasons & R_STALE
    assert out.mode == DEGRADED_MODE
    assert out.demand == MAINTAIN and out.warning   # a dispute beyond SBI: warning, no braking
    assert out.distance_dm == far           # voted distance: the shortest reported


def test_3oo3_unanimous_obstacle_is_no_error_and_distance_is_the_shortest():
    d = normal_driver()
    dists = (50000, 50100, 49990, 49950, 50060, 50020)     # within 10 m inside each module
    reps = tuple(Report(PRESENT, x, 0, STATIC, d.tick) for x in dists)
    out = d.cycle(reps, V)
    assert not out.system_error and out.module_flags == 0
    assert out.mode == NORMAL
    assert out.distance_dm == 49950
    assert out.demand == MAINTAIN and out.reasons == 0


@pytest.mark.parametrize("gap", [101, 5000])
def test_2oo2_distances_too_far_apart_raise_the_module_flag(gap):
    """A stuck value or a noise burst on one channel: both PRESENT, distances more than
    distance_tolerance_dm (100 dm) apart. The module's flag goes up: system error, answered as a
    dispute (far beyond the curves: a warning), and the shorter distance is the one supervised."""
    d = normal_driver()
    dists = [50000] * 6
    dists[3] = 50000 + gap
    out = d.cycle(tuple(Report(PRESENT, x, 0, STATIC, d.tick) for x in dists), V)
    assert out.module_flags == 0b010 and out.system_error
    assert out.demand == MAINTAIN and out.reasons & R_SYSTEM_ERROR and out.reasons & R_DISPUTE and out.warning
    assert out.distance_dm == 50000


def test_2oo2_distances_at_the_tolerance_agree():
    d = normal_driver()
    dists = [50000, 50100, 50000, 49900, 50000, 50000]
    out = d.cycle(tuple(Report(PRESENT, x, 0, STATIC, d.tick) for x in dists), V)
    assert out.module_flags == 0 and not out.system_error


def test_3oo3_one_module_degraded_channel_status_2_is_an_error():
    d = normal_driver()
    out = d.cycle(with_channel(clear(d.tick), 4, Report(DEGRADED, 0, 0, STATIC, d.tick)), V)
    assert out.system_error and out.module_flags == 0b100 and out.demand == EMERGENCY


@pytest.mark.parametrize("topology, channel", [("3oo3", c) for c in range(6)] + [("2oo2", 0), ("2oo2", 1)])
def test_a_fresh_obstacle_whose_partner_channel_is_stale_still_counts_for_the_envelope(topology, channel):
    """A channel reports an obstacle 0.5 m ahead at 40 m/s, fresh and in range; its partner
    channel is stale. The obstacle is inside the emergency braking distance, so the
    envelope must demand emergency braking whatever the configured safe reaction is
    (DESIGN 3.4), and the voted distance must be the shortest reported one."""
    cfg = Config(safe_reaction=SERVICE, topology=topology)
    d = normal_driver(cfg)
    reps = with_channel(clear(d.tick, cfg.channels), channel, Report(PRESENT, 5, 100, STATIC, d.tick))
    reps = with_channel(reps, channel ^ 1, Report(ABSENT, 0, 0, STATIC, d.tick - 1000))
    out = d.cycle(reps, V)
    assert out.system_error
    got = (out.demand, bool(out.reasons & R_ENVELOPE), out.distance_dm)
    assert got == (EMERGENCY, True, 5)


# --------------------------------------------------------------------------- envelope


def normal_curves(cfg, speed, closing=0):
    """The curves under normal conditions for a fresh report (closing 0, as `present` sends)."""
    return curves(cfg, speed, 0, 0, closing, 0)


@pytest.mark.parametrize("speed", [1, 1000, V, 8333, MAX_SPEED_CMS])
def test_ebi_just_inside_and_just_outside(speed):
    cfg = Config()
    ebi = normal_curves(cfg, speed).ebi_dm
    assert ebi > 0
    # just inside: a table that never brakes (m1's own, risk-repaired since issue 41, brakes on
    # a first "emergency" itself), so the supervision must
    d = normal_driver(cfg, maintain_only(M1))
    assert d.state.node == d.setup.table.start == 0
    out = d.present(ebi, speed)
    assert out.mode == NORMAL and not out.system_error
    assert out.distance_dm == ebi
    # the table's critical zone ends at the zone limit (without the sampling period), nearer
    # than the supervised EBI: there the table reads the emergency zone
    zone_limit = ebi_dm(cfg, speed, 0, 0, 0, 0)
    assert zone_limit < ebi                               # (and the zone limits count no error budget)
    alpha1 = max(ebi_dm(cfg, speed, 0, 0, speed, 0, service=True), ebi_dm(cfg, speed, 0, 0, speed, 0))
    assert out.observation == (3 if ebi <= zone_limit else 2 if ebi <= alpha1 else 1)
    assert out.reasons & R_ENVELOPE
    assert not out.reasons & R_TABLE
    assert out.demand == EMERGENCY
    # just outside: no emergency from the curves, service from SBI (the table may add its own)
    d = normal_driver(cfg)
    table = d.setup.table
    assert d.state.node == table.start == 0
    out = d.present(ebi + 1, speed)
    assert out.distance_dm == ebi + 1
    assert not out.reasons & R_ENVELOPE
    assert out.reasons & R_SBI and out.warning
    obs = 2 if ebi + 1 <= alpha1 else 1
    assert out.observation == obs
    assert out.demand == max(SERVICE, table.action[table.next[0][obs]])
    assert bool(out.reasons & R_TABLE) == (table.action[table.next[0][obs]] > 0)


@pytest.mark.parametrize("speed", [1, 1000, V, MAX_SPEED_CMS])
def test_sbi_and_warning_boundaries(speed):
    """The ladder on the m2 table from its start, whose first answer to a far, static obstacle
    is no braking: service exactly up to SBI, a warning exactly up to the warning curve."""
    cfg = Config()
    c = normal_curves(cfg, speed)
    assert c.ebi_dm < c.sbi_dm < c.warning_dm
    for distance, demand, warn in ((c.sbi_dm, SERVICE, True), (c.sbi_dm + 1, MAINTAIN, True),
                                   (c.warning_dm, MAINTAIN, True), (c.warning_dm + 1, MAINTAIN, False)):
        d = normal_driver(cfg, M2)
        out = d.present(distance, speed, )
        assert (out.reasons & R_SBI != 0, out.warning, out.reasons & R_WARNING != 0) == (demand == SERVICE, warn, warn), distance
        assert out.demand >= demand and not out.reasons & R_ENVELOPE


def test_adverse_conditions_move_the_curves_out():
    cfg = Config()
    d = normal_driver(cfg)
    normal = normal_curves(cfg, V)
    slippery = curves(cfg, V, 1, 0, 0, 0)
    both = curves(cfg, V, 1, 1, 0, 0)
    assert normal.ebi_dm < slippery.ebi_dm < both.ebi_dm
    # an obstacle between the normal and the slippery EBI: emergency only when slippery is reported
    out = d.cycle(present(d.tick, normal.ebi_dm + 10), train=Train(V, 1, 0))
    assert out.reasons & R_ENVELOPE and out.demand == EMERGENCY
    d = normal_driver(cfg)
    out = d.cycle(present(d.tick, normal.ebi_dm + 10), train=Train(V, 0, 0))
    assert not out.reasons & R_ENVELOPE


def test_an_oncoming_obstacle_and_an_old_report_move_the_curves_out():
    cfg = Config()
    static = normal_curves(cfg, V, closing=V)
    oncoming = normal_curves(cfg, V, closing=V + 1000)        # the obstacle closes at 10 m/s itself
    old = curves(cfg, V, 0, 0, V, 3 * PERIOD)
    assert oncoming.ebi_dm > static.ebi_dm + 10 * 15 * 10     # it runs at least 15 s x 10 m/s meanwhile
    assert old.ebi_dm >= static.ebi_dm + V * 3 * PERIOD // 10000
    d = normal_driver(cfg)
    reps = tuple(Report(PRESENT, static.ebi_dm + 10, V, STATIC, d.tick - 3 * PERIOD) for _ in range(6))
    out = d.cycle(reps, V)
    assert out.reasons & R_ENVELOPE and out.demand == EMERGENCY   # 300 ms old: it counts


def test_envelope_at_standstill_keeps_the_standstill_margin():
    cfg = Config()
    ebi0 = normal_curves(cfg, 0).ebi_dm
    assert ebi0 > cfg.standstill_margin_dm     # the train may start to roll within a cycle
    d = normal_driver()
    out = d.present(ebi0, 0)
    assert out.reasons & R_ENVELOPE and out.demand == EMERGENCY
    d = normal_driver()
    out = d.present(ebi0 + 1, 0)
    assert not out.reasons & R_ENVELOPE


def test_envelope_with_m2_table():
    cfg = Config()
    ebi = normal_curves(cfg, V).ebi_dm
    d = normal_driver(cfg, M2)
    out = d.present(ebi, V)
    assert out.reasons & R_ENVELOPE and out.demand == EMERGENCY
    d = normal_driver(cfg, M2)
    out = d.present(ebi + 1, V)
    assert not out.reasons & R_ENVELOPE and out.demand >= SERVICE


# --------------------------------------------------------------------------- latch


def test_emergency_latch_holds_until_a_standstill_cycle():
    """A disputed obstacle (one channel) inside EBI is answered while reported but not
    remembered: when it is gone, only the latch holds the emergency, to standstill."""
    d = normal_driver(HELD)
    out = d.cycle(disagreeing(d.tick, 1000), V)   # inside the envelope at 40 m/s
    assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE and out.track_state == TRACK_NONE
    assert not out.reasons & R_LATCH    # the cycle that demands it names its cause
    for speed in (V, V, 100, 1, MAX_SPEED_CMS):
        out = d.clear(speed)           # the cause is gone, the train still moves
        assert out.demand == EMERGENCY
        assert out.reasons & R_LATCH and not out.reasons & R_ENVELOPE
    out = d.clear(0)
    assert out.demand == MAINTAIN and not out.reasons & R_LATCH


def maintain_only(table: bytes) -> bytes:
    """The table's model with a one-node controller that never brakes: the latch and the
    curves alone decide (the shipped tables brake for an obstacle this close themselves)."""
    t = decode(table)
    Z = len(t.header["observations"])
    return encode({**t.header, "start": 0}, [0], [[0] * Z])


def test_a_revocable_emergency_needs_the_obstacle_back_beyond_sbi_for_the_confirmation_time():
    cfg = Config()
    c = normal_curves(cfg, V)
    d = normal_driver(cfg, maintain_only(M2))
    out = d.present(c.ebi_dm, V)
    assert out.demand == EMERGENCY and d.state.latched
    # between EBI and SBI: the cause is not gone (hysteresis), however long it lasts
    for _ in range(3 * cfg.release_confirm_cycles):
        out = d.present(c.sbi_dm, V)
        assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE
    # beyond SBI: released after exactly release_confirm_cycles cycles
    for k in range(cfg.release_confirm_cycles - 1):
        out = d.present(c.sbi_dm + 1, V)
        assert out.demand == EMERGENCY and out.reasons & R_LATCH, k
    out = d.present(c.sbi_dm + 1, V)
    assert not d.state.latched and out.demand < EMERGENCY


def test_a_revocable_emergency_is_released_after_the_obstacle_is_voted_absent_for_the_confirmation_time():
    """A disputed obstacle is not remembered: the revocable release counts calm cycles."""
    cfg = Config(release_confirm_cycles=7)
    d = normal_driver(cfg)
    assert d.cycle(disagreeing(d.tick, 100), V).demand == EMERGENCY
    for k in range(6):
        out = d.clear(V)
        assert out.demand == EMERGENCY and out.reasons & R_LATCH, k
        if k == 3:
            assert d.cycle(disagreeing(d.tick, 100), V).demand == EMERGENCY   # back: the count restarts
    for k in range(4):                                          # 2 calm cycles above, 4 more: 6
        assert d.clear(V).demand == EMERGENCY, k
    out = d.clear(V)                                            # the 7th
    assert out.demand == MAINTAIN and not d.state.latched


def test_service_braking_is_held_for_the_confirmation_time_only():
    """Issue 29 item 2: a service demand is lowered only after release_confirm_cycles calm
    cycles (it used to drop at once), and never latched beyond them."""
    cfg = Config(safe_reaction=SERVICE)
    d = normal_driver(cfg)
    out = d.cycle(with_channel(clear(d.tick), 0, None), V)
    assert out.demand == SERVICE
    for k in range(cfg.release_confirm_cycles - 1):
        out = d.clear(V)
        assert out.demand == SERVICE and out.reasons & R_LATCH, k
        assert d.state.held == SERVICE and d.state.calm == k + 1
    out = d.clear(V)
    assert out.demand == MAINTAIN and not out.reasons & R_LATCH and d.state.held == MAINTAIN


# --------------------------------------------------------------------------- deadline


def test_deadline_overruns_lead_to_safe_stop():
    d = normal_driver()
    out = d.clear(V, overruns=d.cfg.max_overruns - 1)
    assert (out.mode, out.demand) == (NORMAL, MAINTAIN)
    out = d.clear(V, overruns=d.cfg.max_overruns)
    assert out.mode == SAFE_STOP
    assert out.reasons & R_DEADLINE and out.reasons & R_SAFE_STOP
    assert out.demand == EMERGENCY
    out = d.clear(0, overruns=d.cfg.max_overruns + 5)
    assert out.mode == SAFE_STOP and out.demand == EMERGENCY and out.reasons & R_DEADLINE
    for _ in range(d.cfg.recovery_cycles - 1):
        out = d.clear(0)
        assert out.mode == SAFE_STOP and not out.reasons & R_DEADLINE
    assert d.clear(0).mode == NORMAL


def test_deadline_limit_is_configurable():
    d = normal_driver(Config(max_overruns=1))
    out = d.clear(0, overruns=1)
    assert out.mode == SAFE_STOP and out.reasons & R_DEADLINE and out.demand == EMERGENCY


# --------------------------------------------------------------------------- out-of-range inputs


def _bad_report(now, **fields):
    return Report(**{**Report(ABSENT, 0, 0, STATIC, now)._asdict(), **fields})


BAD_REPORTS = {
    "distance -1": dict(status=PRESENT, distance_dm=-1),
    "distance too far": dict(status=PRESENT, distance_dm=MAX_DISTANCE_DM + 1),
    "absent with bad distance": dict(distance_dm=10 ** 9),
    "status 3": dict(status=3),
    "status -1": dict(status=-1),
    "obstacle 7": dict(status=PRESENT, distance_dm=20000, obstacle=7),
    "obstacle -1": dict(status=PRESENT, distance_dm=20000, obstacle=-1),
    "closing 10**6": dict(status=PRESENT, distance_dm=20000, closing_cms=10 ** 6),
    "closing -10**6": dict(status=PRESENT, distance_dm=20000, closing_cms=-10 ** 6),
    "closing just over": dict(status=PRESENT, distance_dm=20000, closing_cms=MAX_CLOSING_CMS + 1),
    "future tick": "future",
    "status str": dict(status="1"),
    "status None": dict(status=None),
    "distance str": dict(status=PRESENT, distance_dm="100"),
    "distance None": dict(status=PRESENT, distance_dm=None),
    "closing None": dict(status=PRESENT, distance_dm=100, closing_cms=None),
    "obstacle str": dict(status=PRESENT, distance_dm=100, obstacle="train"),
    "tick None": dict(tick=None),
    "tick str": "tick str",
}


@pytest.mark.parametrize("cfg", [Config(), Config(safe_reaction=SERVICE)], ids=["emergency", "service"])
@pytest.mark.parametrize("speed", [0, V])
@pytest.mark.parametrize("name", sorted(BAD_REPORTS))
@pytest.mark.parametrize("channel", [0, 5])
def test_out_of_range_report_is_a_system_error(name, speed, cfg, channel):
    d = normal_driver(cfg)
    spec = BAD_REPORTS[name]
    if spec == "future":
        bad = _bad_report(d.tick + 1)
    elif spec == "tick str":
        bad = _bad_report(str(d.tick))
    else:
        bad = _bad_report(d.tick, **spec)
    out = d.cycle(with_channel(clear(d.tick), channel, bad), speed)
    assert out.demand in (SERVICE, EMERGENCY)
    assert out.demand >= cfg.safe_reaction
    assert out.system_error
    assert out.reasons & R_STALE and out.reasons & R_SYSTEM_ERROR
    assert out.module_flags == 1 << (channel // 2)
    assert out.mode == DEGRADED_MODE
    assert out.distance_dm == NO_DISTANCE


BAD_TRAINS = {
    "speed -1": Train(-1),
    "speed huge": Train(10 ** 12),
    "speed just over": Train(MAX_SPEED_CMS + 1),
    "speed str": Train("4000"),
    "speed None": Train(None),
    "speed bool": Train(True),
    "track 2": Train(V, 2, 0),
    "brake 5": Train(V, 0, 5),
    "train None": None,
    "train tuple": (V,),
}


@pytest.mark.parametrize("cfg", [Config(), Config(safe_reaction=SERVICE)], ids=["emergency", "service"])
@pytest.mark.parametrize("name", sorted(BAD_TRAINS))
def test_out_of_range_train_is_a_system_error(name, cfg):
    d = normal_driver(cfg)
    out = step(d.setup, d.state, Inputs(clear(d.tick), BAD_TRAINS[name], 0), d.tick)[1]
    assert out.demand >= cfg.safe_reaction
    assert out.system_error
    assert out.reasons & R_SYSTEM_ERROR and out.reasons & R_TRAIN_INPUT
    assert out.mode != NORMAL


@pytest.mark.parametrize("inputs", [
    Inputs(clear(100)[:5]),
    Inputs(()),
    Inputs(clear(100)[:1], Train(V)),
    Inputs(None, Train(V)),
    Inputs(clear(100)[:5] + ((1, 2),)),
    Inputs(clear(100)[:5] + ("garbage",)),
    Inputs(clear(100), Train(V), "many"),
    None,
    "not inputs",
], ids=repr)
def test_malformed_inputs_never_raise_and_brake(inputs):
    for cfg in (Config(), Config(safe_reaction=SERVICE)):
        d = normal_driver(cfg)
        state, out = step(d.setup, d.state, inputs, 100)
        assert out.demand >= cfg.safe_reaction
        assert out.demand in (SERVICE, EMERGENCY)
        assert out.system_error or out.mode == SAFE_STOP
        assert isinstance(state, State)


def test_bad_tick_argument_never_raises():
    for tick in (None, "100", -5):
        d = normal_driver()
        _, out = step(d.setup, d.state, Inputs(clear(100), Train(V)), tick)
        assert out.demand == EMERGENCY


# --------------------------------------------------------------------------- braking curves


def exact_ebi_m(cfg: Config, v_cms: int, track: int, brake: int, closing_cms: int, age_ms: int) -> Fraction:
    """EBI in metres, in exact fractions, written from docs/supervision.md (not from the code)."""
    v = Fraction(v_cms, 100)
    e = Fraction(cfg.speed_error_permille, 1000)
    g = Fraction(981, 100) * Fraction(cfg.max_gradient_permille, 1000)
    f = (Fraction(cfg.slippery_permille, 1000) if track else 1) * (Fraction(cfg.degraded_permille, 1000) if brake else 1)
    bands = [(Fraction(0), Fraction(cfg.emergency_decel_mms2, 1000))]
    if cfg.emergency_band2_cms:
        bands.append((Fraction(cfg.emergency_band2_cms, 100), Fraction(cfg.emergency_band2_mms2, 1000)))
    vmax, vmin = v * (1 + e), v * (1 - e)
    t1 = Fraction(age_ms + 4 * cfg.period_ms + cfg.traction_cutoff_ms, 1000)   # the timing contract's 4 periods
    a1 = Fraction(cfg.max_accel_mms2, 1000) + g
    v1 = vmax + a1 * t1
    t2 = max(Fraction(cfg.emergency_buildup_ms - cfg.traction_cutoff_ms, 1000), Fraction(0))
    v2 = v1 + g * t2
    s = vmax * t1 + a1 * t1 * t1 / 2 + v1 * t2 + g * t2 * t2 / 2
    time = t1 + t2
    for i, (lo, a) in enumerate(bands):
        hi = bands[i + 1][0] if i + 1 < len(bands) else None
        top = v2 if hi is None else min(v2, hi)
        if top > lo:
            dec = a * f - g
            s += (top * top - lo * lo) / (2 * dec)
            time += (top - lo) / dec
    # the error budget (docs/supervision.md 2.6): the obstacle up to the distance accuracy
    # nearer than reported, closing up to the closing accuracy faster than measured
    obstacle = Fraction(closing_cms + cfg.closing_accuracy_cms, 100) - vmin
    return (s + Fraction(cfg.standstill_margin_dm + cfg.distance_accuracy_dm, 10)
            + (obstacle * time if obstacle > 0 else 0))


@pytest.mark.parametrize("cfg", [Config(), Config(emergency_band2_cms=0, max_gradient_permille=0, speed_error_permille=0),
                                 Config(traction_cutoff_ms=1500, emergency_buildup_ms=700)], ids=["shipped", "flat", "long-cutoff"])
@pytest.mark.parametrize("track, brake", [(0, 0), (1, 0), (0, 1), (1, 1)])
def test_ebi_is_never_shorter_than_the_exact_curve_and_hardly_longer(cfg, track, brake):
    """Every term is rounded up on its own (and the speeds after each phase too), so the
    integer curve may exceed the exact one, but by little (2 m + 0.1 %); it must never fall short."""
    for v in list(range(0, MAX_SPEED_CMS + 1, 251)) + [1, 2999, 3000, 3001, MAX_SPEED_CMS]:
        for closing, age in ((v, 0), (v + 1000, 0), (v, 300), (-500, 100)):
            got = curves(cfg, v, track, brake, closing, age).ebi_dm
            exact = exact_ebi_m(cfg, v, track, brake, closing, age) * 10
            assert exact <= got <= exact * Fraction(1001, 1000) + 20, (v, closing, age, got, float(exact))


def test_curve_reference_values():
    """The shipped train at 40 m/s on a level-looking but declared 20 per mille downhill: EBI
    about 564 m with the sensors' error budget (50 m and 1 m/s; 492.9 m without it; the old
    nominal envelope said 287 m; 476 m before the sampling period was counted, 481.5 m before
    the stalled monitor was: 4 periods of reaction, not 2)."""
    c = curves(Config(), 4000, 0, 0, 4000, 0)
    assert c == (4676, 5638, 6490, 7342)
    assert curves(Config(), 0, 0, 0, 0, 0).ebi_dm == 578
    exact = Config(distance_accuracy_dm=0, closing_accuracy_cms=0)
    assert curves(exact, 4000, 0, 0, 4000, 0) == (3990, 4929, 5761, 6593)
    assert curves(exact, 0, 0, 0, 0, 0).ebi_dm == 60


def test_curves_are_ordered_and_grow_with_speed_and_adverse_conditions():
    cfg = Config()
    prev = None
    for v in range(0, MAX_SPEED_CMS + 1, 50):
        rows = [curves(cfg, v, t, b, v, 0) for t, b in ((0, 0), (1, 0), (0, 1), (1, 1))]
        for c in rows:
            assert c.ebd_dm <= c.ebi_dm <= c.sbi_dm <= c.warning_dm
        assert rows[0].ebi_dm <= rows[1].ebi_dm <= rows[3].ebi_dm and rows[0].ebi_dm <= rows[2].ebi_dm <= rows[3].ebi_dm
        if prev is not None:
            assert rows[0].ebi_dm >= prev
        prev = rows[0].ebi_dm


# --------------------------------------------------------------------------- configuration refusals


@pytest.mark.parametrize("changes, field", [
    (dict(timeout_cycles=0), "timeout_cycles"),
    (dict(service_decel_mms2=-1), "service_decel_mms2"),
    (dict(emergency_decel_mms2=0), "emergency_decel_mms2"),
    (dict(persistence_cycles=0), "persistence_cycles"),
    (dict(persistence_cycles=1001), "persistence_cycles"),
    (dict(timeout_cycles=601), "timeout_cycles"),
    (dict(emergency_band2_mms2=0), "emergency_band2_mms2"),
    (dict(emergency_band2_mms2=2500), "emergency_band2_mms2"),        # rises with speed (issue 40 item 4)
    (dict(emergency_band3_cms=5000, emergency_band3_mms2=2300), "emergency_band3_mms2"),
    (dict(emergency_band3_cms=2000), "emergency_band3_cms"),
    (dict(service_decel_mms2=2300), "service_decel_mms2"),
    (dict(slippery_permille=1001), "slippery_permille"),
    (dict(degraded_permille=0), "degraded_permille"),
    (dict(speed_error_permille=-1), "speed_error_permille"),
    (dict(max_gradient_permille=61), "max_gradient_permille"),
    (dict(emergency_decel_mms2=500, emergency_band2_cms=0, service_decel_mms2=400), "max_gradient_permille"),
    (dict(max_gradient_permille=40), "service_decel_mms2"),     # the worst case cannot stop
    (dict(emergency_buildup_ms=30001), "emergency_buildup_ms"),
    (dict(emergency_release=2), "emergency_release"),
    (dict(release_confirm_cycles=0), "release_confirm_cycles"),
    (dict(topology="4oo4"), "topology"),
    (dict(safe_reaction=0), "safe_reaction"),
    (dict(safe_reaction=3), "safe_reaction"),
    (dict(period_ms=0), "period_ms"),
    (dict(recovery_cycles=0), "recovery_cycles"),
    (dict(max_overruns=0), "max_overruns"),
    (dict(period_ms=100.0), "period_ms"),
    (dict(timeout_cycles=True), "timeout_cycles"),
])
@pytest.mark.parametrize("table", [M1, M2], ids=["m1", "m2"])
def test_bad_configuration_is_refused_naming_the_field(changes, field, table):
    with pytest.raises(ConfigurationError, match=field):
        create(Config(**changes), table)


@pytest.mark.parametrize("table", [M1, M2], ids=["m1", "m2"])
def test_table_for_another_period_is_refused(table):
    with pytest.raises(ConfigurationError, match="period_ms"):
        create(Config(period_ms=50), table)
    create(Config(period_ms=100), table)   # the right one is accepted


@pytest.mark.parametrize("table", [M1, M2], ids=["m1", "m2"])
@pytest.mark.parametrize("where", [0, 9, 20, "header", "body", -33, -1])
def test_corrupted_table_is_refused(table, where):
    data = bytearray(table)
    if where == "header":
        pos = 14 + 40
    elif where == "body":
        pos = len(data) - 32 - 3
    else:
        pos = where % len(data)
    data[pos] ^= 0x01
    with pytest.raises(ConfigurationError, match="table"):
        create(Config(), bytes(data))


def test_truncated_or_empty_table_is_refused():
    for data in (b"", M1[:10], M1[:-1], M1 + b"\0"):
        with pytest.raises(ConfigurationError):
            create(Config(), data)


def tiger_table(**header_changes) -> bytes:
    header = {
        "model": "tiger",
        "states": ["tiger-left", "tiger-right"],
        "actions": ["listen", "open-left", "open-right"],
        "observations": ["hear-left", "hear-right"],
        "params": {"time_step_s": 0.1},
    }
    header.update(header_changes)
    return encode(header, [0, 1], [[0, 1], [1, 0]])


def test_foreign_table_is_refused():
    data = tiger_table()
    decode(data)   # a well-formed table...
    with pytest.raises(ConfigurationError, match="tiger"):
        create(Config(), data)                          # ...for a model the monitor cannot map
    with pytest.raises(ConfigurationError):
        create(Config(), data, expect_model="tiger")


def test_table_with_foreign_observations_is_refused():
    # says m1 but observes a tiger: the observation names give it away
    with pytest.raises(ConfigurationError, match="observations"):
        create(Config(), tiger_table(model="m1"))


def test_m1_table_with_too_few_actions_is_refused():
    t = decode(M1)
    header = dict(t.header, actions=["maintain", "emergency_braking"])
    data = encode(header, [min(a, 1) for a in t.action], t.next)
    with pytest.raises(ConfigurationError, match="actions"):
        create(Config(), data)


def test_table_of_the_wrong_model_is_refused():
    with pytest.raises(ConfigurationError, match="m2"):
        create(Config(), M1, expect_model="m2")
    with pytest.raises(ConfigurationError, match="m1"):
        create(Config(), M2, expect_model="m1")
    assert create(Config(), M1, expect_model="m1").model == "m1"
    assert create(Config(), M2, expect_model="m2").model == "m2"


@pytest.mark.parametrize("params", [
    [0.1],                       # not a JSON object
    {"time_step_s": "0.1"},      # not a number
    {"time_step_s": [0.1]},
    "0.1",
], ids=repr)
def test_table_with_malformed_time_step_is_refused_cleanly(params):
    """A hashed, well-formed table file whose header has a malformed params entry must be
    refused with ConfigurationError like every other bad table, not crash start-up."""
    t = decode(M1)
    data = encode(dict(t.header, params=params), t.action, t.next)
    with pytest.raises(ConfigurationError):
        create(Config(), data)


def test_table_without_time_step_is_refused():
    t = decode(M1)
    header = {k: v for k, v in t.header.items() if k != "params"}
    with pytest.raises(ConfigurationError, match="time step"):
        create(Config(), encode(header, t.action, t.next))


# --------------------------------------------------------------------------- 2oo2 topology


def test_2oo2_topology_runs_on_two_reports():
    cfg = Config(topology="2oo2")
    d = Driver(cfg)
    assert initial_state(d.setup).disagree == (0,)
    out = d.cycle((Report(ABSENT, 0, 0, STATIC, 0), None), 0)
    assert out.mode == INIT and out.demand == EMERGENCY
    out = d.clear(0)
    assert out.mode == NORMAL and out.demand == MAINTAIN
    out = d.clear(V)
    assert (out.mode, out.demand, out.reasons) == (NORMAL, MAINTAIN, 0)
    # both channels see an obstacle inside the envelope: the shorter distance is voted
    t = d.tick
    out = d.cycle((Report(PRESENT, 1560, 0, STATIC, t), Report(PRESENT, 1500, 0, STATIC, t)), V)
    assert out.distance_dm == 1500 and not out.system_error
    assert out.reasons & R_ENVELOPE and out.demand == EMERGENCY
    out = d.clear(0)
    assert out.demand == MAINTAIN         # standstill releases the emergency
    for _ in range(forget_cycles(cfg) - 1):   # the remembered obstacle is forgotten on evidence
        out = d.clear(0)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == NO_DISTANCE
    # disagreement: error now, perceptor error after persistence_cycles
    for k in range(cfg.persistence_cycles):
        t = d.tick
        out = d.cycle((Report(PRESENT, FAR, 0, STATIC, t), Report(ABSENT, 0, 0, STATIC, t)), V)
        assert out.system_error and out.module_flags == 1
        assert out.demand == (EMERGENCY if k == cfg.persistence_cycles - 1 else MAINTAIN)
    assert out.mode == SAFE_STOP and out.reasons & R_PERCEPTOR


def test_2oo2_topology_stale_channel_is_an_error():
    d = normal_driver(Config(topology="2oo2"))
    out = d.cycle((Report(ABSENT, 0, 0, STATIC, d.tick), Report(ABSENT, 0, 0, STATIC, d.tick - 400)), V)
    assert out.system_error and out.reasons & R_STALE and out.demand == EMERGENCY
    out = d.cycle((Report(ABSENT, 0, 0, STATIC, d.tick),), V)   # one report only
    assert out.system_error and out.reasons & R_STALE and out.demand == EMERGENCY


# --------------------------------------------------------------------------- replay


def recorded_sequence(n_channels: int = 6) -> list:
    seq = []
    tick = 0
    speeds = [0, 0, 4000, 4000, 4000, 3000, 3000, 2000, 1000, 0] * 5
    for k, v in enumerate(speeds):
        if k % 11 == 3:
            reps = present(tick, 20000 - 300 * k, n_channels, closing=2500, obstacle=TRAIN)
        elif k % 11 == 5:
            reps = present(tick, 1500, n_channels, closing=-50, obstacle=DYNAMIC)
        elif k % 13 == 7:
            reps = with_channel(clear(tick, n_channels), 1, None)
        elif k % 17 == 9:
            reps = disagreeing(tick)[:n_channels]
        else:
            reps = clear(tick, n_channels)
        seq.append((tick, Inputs(reps, Train(v, k % 2 if k > 30 else 0, 0), 0)))
        tick += PERIOD
    return seq


def test_replay_is_deterministic_and_equals_stepping():
    seq = recorded_sequence()
    for table in (M1, M2):
        setup = create(Config(), table)
        a = replay(setup, seq)
        b = replay(setup, list(seq))
        assert a == b and len(a) == len(seq)
        state = initial_state(setup)
        manual = []
        for tick, inputs in seq:
            state, out = step(setup, state, inputs, tick)
            manual.append(out)
        assert manual == a
        assert [o.cycle for o in a] == list(range(1, len(seq) + 1))
        # the sequence exercises more than one demand and mode
        assert {o.demand for o in a} >= {MAINTAIN, EMERGENCY}
        assert {o.mode for o in a} >= {NORMAL, DEGRADED_MODE}


def test_replay_observation_ranges_per_model():
    seq = recorded_sequence()
    s1, s2 = create(Config(), M1), create(Config(), M2)
    o1, o2 = replay(s1, seq), replay(s2, seq)
    assert all(0 <= o.observation < 4 for o in o1)
    assert all(0 <= o.observation < 144 for o in o2)
    assert any(o.observation >= 4 for o in o2)
    assert all(0 <= o.node < s1.table.nodes for o in o1)
    assert all(0 <= o.node < s2.table.nodes for o in o2)
    # voting does not depend on the table
    assert [o.distance_dm for o in o1] == [o.distance_dm for o in o2]
    assert [o.system_error for o in o1] == [o.system_error for o in o2]


def test_replay_in_2oo2_topology():
    seq = recorded_sequence(2)
    setup = create(Config(topology="2oo2"), M1)
    assert replay(setup, seq) == replay(setup, seq)
