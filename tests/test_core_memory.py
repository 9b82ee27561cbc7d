"""Obstacle memory (issue 29): an obstacle lost from sight is remembered, predicted worst case,
supervised by the curves, and forgotten only on evidence (fresh unanimous ABSENT inside the
declared sensor range for forget_ms) or once the train has passed it. Every test drives the
real core cycle by cycle through `create()` with a shipped table."""
from __future__ import annotations

import pytest

from monitor.core.braking import curves, ebi_dm
from monitor.core.config import Config, forget_cycles, gradient_accel_mms2
from monitor.core.memory import UNITS_PER_DM, near_travel, seen_beyond
from monitor.core.types import (
    ABSENT, DEGRADED, EMERGENCY, MAINTAIN, NO_DISTANCE, PRESENT, R_ENVELOPE, R_LATCH, R_MEMORY, SERVICE, STATIC,
    TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_NONE, TRACK_PASSED, TRACK_SEEN, Report,
)
from tests.test_core_cycle import M1, M2, clear, disagreeing, maintain_only, normal_driver, present, with_channel

V = 3000                  # 30 m/s


def firm(d, distance: int, speed: int, closing=None, cycles: int = 3):
    """Vote an obstacle in `cycles` cycles in a row; the last output."""
    for _ in range(cycles):
        out = d.present(distance, speed) if closing is None else d.cycle(present(d.tick, distance, closing=closing), speed)
    return out


def accel(cfg: Config) -> int:
    return cfg.max_accel_mms2 + gradient_accel_mms2(cfg.max_gradient_permille)


def at_1500(cfg: Config, moves: int) -> int:
    """An obstacle remembered 150 m ahead of a standing train, in dm, after `moves` predictions:
    each the worst-case creep of a train that reads 0 cm/s but may accelerate (a T^2 / 2:
    3.5 mm at the default declaration) plus the sensors' closing accuracy (the error budget:
    100 cm/s for a period, 1 dm), so 1.0349 dm a cycle."""
    step = near_travel(0, cfg.speed_error_permille, accel(cfg), cfg.closing_accuracy_cms, cfg.period_ms)
    return (1500 * UNITS_PER_DM - moves * step) // UNITS_PER_DM


def test_a_blind_spell_after_an_emergency_keeps_the_emergency_on_the_remembered_obstacle():
    """The stress search's defect: every channel goes blind during an emergency braking. The
    remembered obstacle stays inside EBI, so the demand stays emergency (reason memory and
    envelope, not the latch), and its distance is predicted worst case every cycle (its own
    speed 0 plus the sensors' closing accuracy)."""
    cfg = Config()
    d = normal_driver(cfg, M2)
    ebi = curves(cfg, V, 0, 0, 0, 0).ebi_dm               # the reports' closing speed: 0
    out = firm(d, ebi - 100, V)
    assert out.demand == EMERGENCY and out.track_state == TRACK_SEEN and out.track_dm == ebi - 100
    near = (ebi - 100) * UNITS_PER_DM
    for k in range(30):                                   # 3 s blind, far longer than the release confirmation
        near -= near_travel(V, cfg.speed_error_permille, accel(cfg), cfg.closing_accuracy_cms, cfg.period_ms)
        out = d.clear(V)
        assert out.demand == EMERGENCY, k
        assert out.reasons & R_MEMORY and out.reasons & R_ENVELOPE and not out.reasons & R_LATCH
        assert out.track_dm == near // UNITS_PER_DM and out.distance_dm == NO_DISTANCE
        assert out.track_state == TRACK_CONFIRMING and out.track_cycles == k + 1


def test_the_track_is_forgotten_at_exactly_the_confirmation_time_and_a_stale_cycle_restarts_it():
    cfg = Config(forget_ms=1250)                          # 13 cycles (rounded up)
    n = forget_cycles(cfg)
    assert n == 13
    d = normal_driver(cfg, M1)
    firm(d, 1500, 0)                                      # 150 m ahead of a train at standstill
    for k in range(5):
        assert d.clear(0).track_state == TRACK_CONFIRMING
    out = d.cycle(with_channel(clear(d.tick), 3, None), 0)    # one channel silent: no evidence
    assert out.track_state == TRACK_HELD and out.track_dm == at_1500(cfg, 6)
    for k in range(n - 1):
        out = d.clear(0)
        assert out.track_state == TRACK_CONFIRMING and out.track_dm == at_1500(cfg, 7 + k), k
    out = d.clear(0)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == NO_DISTANCE
    assert d.clear(0).track_state == TRACK_NONE


@pytest.mark.parametrize("picture", ["disputed", "degraded"])
def test_no_evidence_while_the_picture_is_disputed_or_degraded(picture):
    cfg = Config()
    d = normal_driver(cfg, M1)
    firm(d, 1500, 0)
    for k in range(3 * forget_cycles(cfg)):
        reports = with_channel(clear(d.tick), 2, Report(DEGRADED, 0, 0, STATIC, d.tick)) if picture == "degraded" \
            else disagreeing(d.tick, 30000)
        out = d.cycle(reports, 0)
        assert out.track_state in (TRACK_HELD, TRACK_SEEN) and out.track_dm == at_1500(cfg, k + 1), k


def test_absence_beyond_the_declared_sensor_range_is_no_evidence():
    """The obstacle at 150 m may lie its distance accuracy (50 m) farther: 200 m, beyond the
    declared 190 m, so absence is no evidence; seen again at 140 m (190 m counting the
    accuracy) it is inside the range, and absence forgets it."""
    cfg = Config(sensor_range_dm=1900)
    d = normal_driver(cfg, M1)
    firm(d, 1500, 0)
    for k in range(2 * forget_cycles(cfg)):
        out = d.clear(0)
        assert out.track_state == TRACK_HELD and out.track_dm == at_1500(cfg, k + 1), k
    out = d.present(cfg.sensor_range_dm - cfg.distance_accuracy_dm, 0)     # seen again inside the range
    assert out.track_state == TRACK_SEEN and out.track_dm == 1400
    for _ in range(forget_cycles(cfg) - 1):
        assert d.clear(0).track_state == TRACK_CONFIRMING
    assert d.clear(0).track_state == TRACK_FORGOTTEN


def test_a_passed_position_is_forgotten_when_the_train_s_least_travel_takes_it_beyond():
    """The train keeps running (a train that does not brake as declared, or a track beside
    the line): the track is forgotten once the least possible travel passes it by more than
    the sensors' distance accuracy (the obstacle may lie that much farther than reported)."""
    cfg = Config(emergency_release=1, sensor_range_dm=1)  # no evidence can count: only passing forgets
    d = normal_driver(cfg, M1)
    d.present(300, 1000)                                  # 30 m ahead at 10 m/s
    least = 1000 * (1000 - cfg.speed_error_permille) // 1000 * cfg.period_ms \
        - (-(-accel(cfg) * cfg.period_ms ** 2 // 20000))
    far, k = 300 * UNITS_PER_DM, 0
    while True:
        far -= least
        out = d.clear(1000)
        k += 1
        if far + cfg.distance_accuracy_dm * UNITS_PER_DM < 0:
            break
        assert out.track_state == TRACK_HELD, k
    assert out.track_state == TRACK_PASSED and out.track_dm == NO_DISTANCE
    assert k == (300 + cfg.distance_accuracy_dm) * UNITS_PER_DM // least + 1 == 82


def test_an_oncoming_obstacle_keeps_closing_while_the_train_stands():
    cfg = Config()
    d = normal_driver(cfg, M2)
    firm(d, 3000, 0, closing=2000)                        # closing at 20 m/s, the train stands
    step = near_travel(0, cfg.speed_error_permille, accel(cfg), 2000 + cfg.closing_accuracy_cms, cfg.period_ms)
    out = d.clear(0)
    assert out.track_dm == (3000 * UNITS_PER_DM - step) // UNITS_PER_DM
    out = d.clear(0)
    assert out.track_dm == (3000 * UNITS_PER_DM - 2 * step) // UNITS_PER_DM


def test_a_receding_obstacle_is_remembered_as_stopped():
    d = normal_driver(Config(), M2)
    firm(d, 3000, 0, closing=-500)                        # receding at 5 m/s: taken to stop at once
    for _ in range(5):
        assert 2990 <= d.clear(0).track_dm <= 3000


# pictures that jump farther than their closing speed allows are implausible (plausibility.py);
# the tests of other rules that jump use a plausibility window shorter than the period: two
# reports are never close enough in time to be compared, so no jump is implausible (a wide
# distance accuracy would do it too, but it is also the curves' and the memory's error budget)
JUMPY = Config(plausibility_ms=1)


def test_a_disputed_sighting_never_creates_a_track_and_a_farther_one_never_hides_a_nearer_track():
    d = normal_driver(JUMPY, M1)
    out = d.cycle(disagreeing(d.tick, 1200), 0)
    assert out.track_state == TRACK_NONE and out.track_dm == NO_DISTANCE
    firm(d, 1500, 0)
    out = d.cycle(disagreeing(d.tick, 2500), 0)           # one channel sees something farther
    assert out.track_dm == at_1500(JUMPY, 1) and out.reasons & R_MEMORY
    out = d.cycle(disagreeing(d.tick, 1200), 0)           # a nearer disputed one brings it nearer
    assert out.track_dm == 1200
    # every module sees it farther, within the two reports' accuracy (2 x 50 m): replaced
    out = d.present(1200 + 2 * JUMPY.distance_accuracy_dm, 0)
    assert out.track_dm == 2200 and not out.reasons & R_MEMORY


def test_a_farther_obstacle_seen_by_every_module_is_evidence_against_the_nearer_one_not_a_replacement():
    """Issue 38 item 2: A at 300 m (inside the 400 m declared sensor range) is seen, lost in a blind cycle (the channels drop their
    plausibility references), then every channel reports B at 2,000 m. The sensors report their
    nearest object, so B is evidence that A is gone, confirmed as ABSENT is: the memory keeps
    A (its curves supervise beside B's, reason memory) for forget_ms of such cycles, then takes
    B. Within the two reports' declared accuracy a farther sighting is A measured again."""
    cfg = Config()
    n = forget_cycles(cfg)
    d = normal_driver(cfg, M2)
    firm(d, 3000, 0, cycles=2)
    # A moved every cycle: the train's creep and the closing accuracy (1.0349 dm)
    step = near_travel(0, cfg.speed_error_permille, accel(cfg), cfg.closing_accuracy_cms, cfg.period_ms)
    out = d.cycle(tuple(Report(DEGRADED, 0, 0, STATIC, d.tick) for _ in range(6)), 0)   # blind
    assert out.track_state == TRACK_HELD and out.track_dm == (3000 * UNITS_PER_DM - step) // UNITS_PER_DM
    for k in range(n - 1):
        out = d.present(20000, 0)
        assert out.distance_dm == 20000 and not out.system_error, k
        assert out.track_state == TRACK_CONFIRMING and out.reasons & R_MEMORY, k
        assert out.track_dm == (3000 * UNITS_PER_DM - (k + 2) * step) // UNITS_PER_DM, k
    out = d.present(20000, 0)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == 20000 and not out.reasons & R_MEMORY
    # a blind or disputed cycle between B's sightings restarts the evidence, as for ABSENT
    d = normal_driver(cfg, M2)
    firm(d, 3000, 0, cycles=2)
    d.cycle(tuple(Report(DEGRADED, 0, 0, STATIC, d.tick) for _ in range(6)), 0)
    for _ in range(n - 1):
        d.present(20000, 0)
    out = d.cycle(tuple(Report(DEGRADED, 0, 0, STATIC, d.tick) for _ in range(6)), 0)
    assert out.track_state == TRACK_HELD
    out = d.present(20000, 0)
    assert out.track_state == TRACK_CONFIRMING and out.track_dm <= 3000
    # farther by the two reports' accuracy (2 x 50 m) at most: the same obstacle, taken at once
    d = normal_driver(cfg, M2)
    firm(d, 3000, 0, cycles=2)
    out = d.present(3000 + 2 * cfg.distance_accuracy_dm, 0)
    assert out.track_state == TRACK_SEEN and out.track_dm == 3000 + 2 * cfg.distance_accuracy_dm


def test_seen_beyond_is_strictly_farther_than_the_track_plus_two_accuracies():
    """memory.seen_beyond to the unit: no track, no evidence; exactly on far + 2 x accuracy the
    same obstacle; one unit (1e-5 m) beyond it, evidence."""
    far = 3000 * UNITS_PER_DM
    assert not seen_beyond(-1, -1, 100, 0) and not seen_beyond(-1, -1, 60000, 500)
    assert not seen_beyond(far, far, 4000, 500)                    # 40,000,000 units: exactly on it
    assert seen_beyond(far, far - 1, 4000, 500)                    # one unit beyond
    assert seen_beyond(far, far, 4001, 500)                        # a dm beyond (not at 3 x accuracy)


def test_the_farther_sighting_that_replaces_a_forgotten_track_is_predicted_as_itself():
    """Once B replaces the forgotten A (the state says A was forgotten, the distance is B's) it
    is a track like any other: no memory reason,
    predicted from B's own closing speed (a static obstacle: the train's worst-case travel and
    the sensors' closing accuracy)."""
    cfg = Config(forget_ms=300)
    n = forget_cycles(cfg)
    d = normal_driver(cfg, M2)
    firm(d, 3000, V, cycles=1)
    d.cycle(tuple(Report(DEGRADED, 0, 0, STATIC, d.tick) for _ in range(6)), V)
    for _ in range(n - 1):
        assert d.present(20000, V).track_state == TRACK_CONFIRMING
    out = d.present(20000, V)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == 20000 and not out.reasons & R_MEMORY
    # (reported closing 0: taken to stop) plus the closing accuracy
    step = near_travel(V, cfg.speed_error_permille, accel(cfg), 0 + cfg.closing_accuracy_cms, cfg.period_ms)
    out = d.cycle(tuple(Report(DEGRADED, 0, 0, STATIC, d.tick) for _ in range(6)), V)
    assert out.track_dm == (20000 * UNITS_PER_DM - step) // UNITS_PER_DM and out.track_state == TRACK_HELD


def test_a_disputed_sighting_the_track_took_keeps_the_track_s_own_curves():
    """A track remembers the fastest closing speed it was seen with. A disputed sighting (one
    channel ABSENT) inside the track's window (sensors declared 300 m inaccurate here) is the
    track measured: it moves the position but not that speed, so the remembered obstacle's
    curves (oncoming) still supervise beside the voted one's (reported static): between the
    two EBIs it is an emergency."""
    cfg = Config(distance_accuracy_dm=3000)
    oncoming = V + 2000                                   # the obstacle closes at 20 m/s of its own
    static, fast = curves(cfg, V, 0, 0, V, 0).ebi_dm, curves(cfg, V, 0, 0, oncoming, 0).ebi_dm
    assert static + 1 < fast and fast + 2000 - static < 2 * cfg.distance_accuracy_dm
    d = normal_driver(cfg, M1)
    firm(d, fast + 2000, V, closing=oncoming, cycles=1)
    out = d.cycle(with_channel(present(d.tick, static + 1, closing=V), 0, Report(ABSENT, 0, 0, STATIC, d.tick)), V)
    assert out.track_state == TRACK_SEEN and out.track_dm == static + 1 and out.system_error
    assert [t.near != -1 for t in d.state.tracks] == [True, False, False]
    assert out.demand == EMERGENCY and out.reasons & R_ENVELOPE


def test_a_disputed_sighting_ahead_of_the_track_is_another_obstacle_and_each_keeps_its_curves():
    """Ahead of where the remembered obstacle can be (its worst case less two accuracies), a
    sighting is another obstacle (tracks.py): a second track at the sighting with its own
    (static) speed, the oncoming one kept where it was, each on its own curves. Neither is
    inside its EBI, so no emergency; the oncoming one, one period on, is still remembered."""
    cfg = Config()
    oncoming = V + 2000
    static, fast = curves(cfg, V, 0, 0, V, 0).ebi_dm, curves(cfg, V, 0, 0, oncoming, 0).ebi_dm
    d = normal_driver(cfg, maintain_only(M1))   # the curves' answer, not the table's
    firm(d, fast + 2000, V, closing=oncoming, cycles=1)
    out = d.cycle(with_channel(present(d.tick, static + 1, closing=V), 0, Report(ABSENT, 0, 0, STATIC, d.tick)), V)
    assert out.track_state == TRACK_SEEN and out.track_dm == static + 1 and out.system_error
    first, second, third = d.state.tracks
    share = V - V * (1000 - cfg.speed_error_permille) // 1000      # the speed error's share of a closing speed
    assert first.closing == share and second.closing == 2000 + share and third.near == -1
    assert (fast + 1800) * UNITS_PER_DM < second.near < (fast + 2000) * UNITS_PER_DM   # two periods closing
    assert out.demand < EMERGENCY and not out.reasons & R_ENVELOPE


def test_release_on_evidence_outside_the_curve_for_the_remembered_obstacle():
    """A remembered obstacle beyond SBI no longer demands: a held emergency is released after
    the confirmation cycles although the obstacle is still remembered (inside the sensor
    range counting its accuracy: absence counts)."""
    cfg = Config()                                        # (350 m after 350.5 m: no jump, plausible)
    c = curves(cfg, V, 0, 0, V, 0)
    d = normal_driver(cfg, M1)
    d.cycle(with_channel(clear(d.tick), 0, Report(PRESENT, c.ebi_dm - 5, V, STATIC, d.tick)), V)   # a dispute inside EBI
    assert d.state.held == EMERGENCY
    at = cfg.sensor_range_dm - cfg.distance_accuracy_dm  # 350 m: its farthest (400 m) inside the range
    assert at > curves(cfg, 1000, 0, 0, 1000, 0).sbi_dm + 2000
    out = firm(d, at, 1000)                               # confirmed, far beyond SBI at 10 m/s: calm 3
    assert out.track_state == TRACK_SEEN and out.demand == EMERGENCY
    for k in range(cfg.release_confirm_cycles - 4):
        out = d.clear(1000)
        assert out.demand == EMERGENCY and out.reasons & R_LATCH, k
    out = d.clear(1000)
    assert out.demand < EMERGENCY and out.track_state == TRACK_CONFIRMING


def test_the_table_s_service_is_held_while_its_obstacle_is_in_the_table_s_zones():
    """Issue 29 item 6: what the table raised is lowered only when the voted picture has left
    the table's zones, so a wavering belief cannot toggle the brake while the obstacle is seen;
    a picture that flickers is bridged by the hold's confirmation cycles."""
    from monitor.core.table import decode, encode

    t = decode(M1)
    Z = len(t.header["observations"])
    # node 0 maintains, node 1 service-brakes; any obstacle sends it to node 1, every clear
    # picture back to node 0: without the hold the demand would toggle with the picture
    table = encode({**t.header, "start": 0}, [MAINTAIN, SERVICE], [[0] + [1] * (Z - 1)] * 2)
    cfg = Config()
    d = normal_driver(cfg, table)
    c = curves(cfg, 1000, 0, 0, 1000, 0)
    dist = c.warning_dm + 2000                            # in the table's zones, beyond every curve
    demands = []
    for k in range(40):
        out = d.present(dist, 1000) if k % 2 == 0 else d.clear(1000)
        demands.append(out.demand)
    assert demands[0] == SERVICE and set(demands) == {SERVICE}
    # a table whose own node wavers while the obstacle stays seen: held by the table's hold
    wavering = encode({**t.header, "start": 0}, [MAINTAIN, SERVICE], [[0] + [1] * (Z - 1), [0] * Z])
    d = normal_driver(cfg, wavering)
    demands = [d.present(dist, 1000).demand for _ in range(40)]
    assert demands[0] == SERVICE and set(demands) == {SERVICE}
    assert d.state.table_held == SERVICE
    out = d.clear(1000)                                   # the picture leaves the zones: the table lets go
    assert d.state.table_held == MAINTAIN and out.demand == SERVICE     # the hold's confirmation follows
    assert d.clear(0).demand == MAINTAIN                  # standstill lets it go


def test_an_obstacle_in_sight_and_closing_keeps_what_is_held_until_it_opens_the_gap():
    """Issue 29 item 6, the curves' side: a static obstacle in sight that raised an emergency
    keeps it while it stays in sight and closing, even where the train, slowed, is beyond
    SBI for it (lowering it would only raise it again nearer: the chatter the FMPy grid
    showed, 4 changes at 30 m/s); the same obstacle opening the gap (receding) lets the hold
    go after the confirmation; once keeping, the shrinking zones do not end it."""
    cfg = Config()
    d = normal_driver(cfg, M1)
    c = curves(cfg, V, 0, 0, V, 0)
    at = ebi_dm(cfg, V, 0, 0, V, 0)                      # the table's critical zone: inside the supervised EBI
    out = d.cycle(present(d.tick, at, closing=V), V)
    assert out.demand == EMERGENCY and out.observation == 3 and out.reasons & R_ENVELOPE
    slow = 300                                            # 3 m/s: far beyond SBI for the same distance
    assert curves(cfg, slow, 0, 0, slow, 0).warning_dm < c.ebi_dm - 100
    for k in range(3 * cfg.release_confirm_cycles):
        out = d.cycle(present(d.tick, c.ebi_dm - 100, closing=slow), slow)
        assert out.demand == EMERGENCY and out.reasons & R_LATCH and d.state.kept, k
    for k in range(cfg.release_confirm_cycles - 1):     # it recedes: the confirmation runs
        assert d.cycle(present(d.tick, c.ebi_dm - 100, closing=-50), slow).demand == EMERGENCY
    out = d.cycle(present(d.tick, c.ebi_dm - 100, closing=-50), slow)
    assert out.demand == MAINTAIN and not d.state.kept
