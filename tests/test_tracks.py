"""Several remembered obstacles (issue 38 item 2, monitor/core/tracks.py): a sighting ahead of
or beyond every remembered obstacle is remembered beside them, the nearest is what the track
outputs show, every one is supervised on its own curves, and a full memory merges its two
farthest to the safe side of both. The rules on their own, then through the real cycle."""
from __future__ import annotations

from monitor.core.config import Config, forget_cycles, track_accel_mms2
from monitor.core.memory import UNITS_PER_DM, near_travel
from monitor.core.tracks import AHEAD, BEYOND, MEASURES, absorbed, assign, insert, merge, ordered, relation
from monitor.core.types import (
    EMERGENCY, NO_TRACK, NO_TRACKS, PRESENT, R_MEMORY, STATIC, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD,
    TRACK_SEEN, Report, Track,
)
from tests.test_core_cycle import M2, clear, normal_driver, present

U = UNITS_PER_DM
ACC = 500                                   # the default declared accuracy, dm: windows of 2 x 50 m


def held(near_dm: int, far_dm: int | None = None, closing: int = 0, strong: bool = True) -> Track:
    return Track(near_dm * U, (near_dm if far_dm is None else far_dm) * U, closing, 0, 0, strong)


def creep(cfg: Config) -> int:
    """What a remembered static obstacle comes nearer per period with the train at rest, in
    1e-5 m: the train may accelerate from rest, and the obstacle may close at the declared
    closing accuracy (the error budget: 1 dm per cycle at the defaults)."""
    return near_travel(0, cfg.speed_error_permille, track_accel_mms2(cfg), cfg.closing_accuracy_cms, cfg.period_ms)


def one_module(tick: int, distance: int, module: int = 0) -> tuple:
    """Only `module` sees the obstacle, with both channels: a disputed picture that creates."""
    reports = list(clear(tick))
    reports[2 * module] = reports[2 * module + 1] = Report(PRESENT, distance, 0, STATIC, tick)
    return tuple(reports)


def test_where_a_sighting_lies_against_a_track():
    assert relation(10000 * U, 10000 * U, 9000, ACC) == MEASURES       # within two accuracies: measured
    assert relation(10000 * U, 10000 * U, 8999, ACC) == AHEAD          # nearer than the track can be
    assert relation(10000 * U, 10000 * U, 11000, ACC) == MEASURES
    assert relation(10000 * U, 10000 * U, 11001, ACC) == BEYOND        # farther than it can be


def test_a_sighting_measures_the_nearest_track_whose_window_holds_it_or_is_new():
    tracks = (held(10000), held(30000), Track())
    assert assign(tracks, 10500, ACC, True) == (0, False)
    assert assign(tracks, 20000, ACC, True) == (-1, True)               # between them: another obstacle
    assert assign(tracks, 30000, ACC, True) == (1, False)               # beyond A, B measured
    assert assign(tracks, 50000, ACC, True) == (-1, True)               # beyond both
    assert assign(tracks, 5000, ACC, True) == (-1, True)                # ahead of both
    assert assign(tracks, 50000, ACC, False) == (0, False)              # one that may not create: the nearest
    assert assign(NO_TRACKS, 50000, ACC, False) == (-1, False)
    assert absorbed((held(10000), held(10400), held(30000)), 0, 10200, ACC) == (1,)


def test_a_full_memory_merges_its_two_farthest_to_the_safe_side_of_both():
    tracks = [held(10000), held(30000, 30500, closing=500, strong=False), held(20000)]
    out, ages, states = insert(tracks, [0, 0, 0], [TRACK_HELD] * 3, held(40000, closing=100), 70, TRACK_SEEN)
    assert out == [held(10000), held(20000), Track(30000 * U, 40000 * U, 500, 0, 0, True)]
    assert ages == [0, 0, 0] and states == [TRACK_HELD] * 3
    out, ages, _ = insert(out, [0, 0, 0], [TRACK_HELD] * 3, held(5000), 70, TRACK_SEEN)   # a nearer one: kept
    assert out == [held(5000), held(10000), Track(20000 * U, 40000 * U, 500, 0, 0, True)] and ages == [70, 0, 0]
    assert merge(held(2, 9), held(3, 4, closing=7)) == Track(2 * U, 9 * U, 7, 0, 0, True)
    assert merge(held(2, 9), held(3, 4, strong=False)).strong and merge(held(2, 9, strong=False), held(3, 4)).strong
    assert ordered([Track(), held(7), held(7, 8)], [1, 2, 3], [4, 5, 6]) == (
        [held(7), held(7, 8), Track()], [2, 3, 1], [5, 6, 4])                           # stable, empty last


def test_a_confirmed_sighting_beyond_the_track_is_remembered_at_once_and_outlives_its_forgetting():
    """The hole of one remembered obstacle: B, confirmed beyond A, counted against A but was
    not remembered, so a blindness that completed A's forgetting left nothing. Now B is a
    second track from its first sighting; A's forgetting reports B as the track."""
    cfg = Config()
    n = forget_cycles(cfg)
    step = creep(cfg)
    d = normal_driver(cfg, M2)
    d.present(3000)                                                     # A, 300 m, inside the declared range
    d.clear()                                                           # (drops plausibility's references)
    out = d.present(12000)                                              # B, 1.2 km: beyond A
    assert out.track_state == TRACK_CONFIRMING and out.track_dm == (3000 * U - 2 * step) // U   # (creeping)
    assert d.state.tracks[1].near == 12000 * U - step
    for _ in range(n - 3):
        out = d.clear()                                                 # blind: evidence for A (in range) only
    assert out.track_state == TRACK_CONFIRMING
    out = d.clear()
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == (12000 * U - (n - 2) * step) // U
    for _ in range(3 * n):                                              # B beyond range: held however long
        out = d.clear()
    assert out.track_state == TRACK_HELD and out.track_dm == (12000 * U - (4 * n - 2) * step) // U
    assert out.reasons & R_MEMORY


def test_a_confirmed_sighting_ahead_of_the_track_keeps_the_track():
    """A nearer confirmed sighting used to replace the track; it is another obstacle, and when
    it leaves (ABSENT inside the range: evidence for both) the farther one beyond the range
    is still remembered."""
    cfg = Config()
    n = forget_cycles(cfg)
    step = creep(cfg)
    d = normal_driver(cfg, M2)
    d.present(20000)                                                    # A, 2 km: beyond the declared range
    d.clear()
    out = d.present(3000)                                               # C, 300 m
    assert out.track_state == TRACK_SEEN and out.track_dm == 3000 and out.track_cycles == 0
    assert d.state.tracks[1].near == 20000 * U - 3 * step
    for _ in range(n):
        out = d.clear()
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == (20000 * U - (n + 2) * step) // U


def test_every_remembered_obstacle_is_supervised_on_its_own_curves():
    """A static obstacle near and an oncoming one farther, both unseen: the oncoming one's
    curves (its own speed) demand the emergency the static one's would not."""
    cfg = Config()
    d = normal_driver(cfg, M2)
    v = 1000
    d.cycle(present(d.tick, 20000, closing=v + 4000), v)               # B, 2 km, oncoming at 40 m/s
    d.cycle(clear(d.tick), v)
    d.cycle(present(d.tick, 3000, closing=v), v)                       # A, 300 m, static
    assert [t.closing for t in d.state.tracks][:2] == [v - v * (1000 - cfg.speed_error_permille) // 1000, 4000 + 20]
    for _ in range(500):                                                # blind: A forgotten (in range), B held
        out = d.cycle(clear(d.tick), v)
        if out.demand == EMERGENCY:
            break
    assert out.demand == EMERGENCY and out.reasons & R_MEMORY
    first, second, _ = d.state.tracks
    assert first.closing > 4000 and second.near == NO_TRACK                # B alone, on its own curves
    assert out.track_dm > 1000                                          # farther than a static EBI at 10 m/s


def test_a_single_module_sighting_beyond_the_track_is_remembered_beside_it():
    """Issue 38 item 1 with a track already held: a farther obstacle that one module sees with
    both channels used to be dropped (it never moves the track); it is a weak track of its own."""
    cfg = Config()
    step = creep(cfg)
    d = normal_driver(cfg, M2)
    d.present(3000)
    d.clear()
    out = d.cycle(one_module(d.tick, 15000), 0)
    assert out.system_error and out.track_dm == (3000 * U - 2 * step) // U
    near = [t.near for t in d.state.tracks]
    assert near[1] == 15000 * U - step and not d.state.tracks[1].strong and near[2] == NO_TRACK


def test_four_obstacles_fill_three_tracks_and_the_farthest_two_become_one():
    cfg = Config()
    step = creep(cfg)
    d = normal_driver(cfg, M2)
    for dist in (3000, 8000, 15000, 25000):
        d.cycle(one_module(d.tick, dist), 0)
        d.clear()                                                       # (drops plausibility's references)
    tracks = d.state.tracks
    assert [t.near for t in tracks] == [3000 * U - 8 * step, 8000 * U - 6 * step, 15000 * U - 4 * step]
    assert tracks[2].far >= 24999 * U and all(t.near != NO_TRACK for t in tracks)


# ---- what the mutation run of tracks.py and cycle.py's memory step asked for ----------------

def single_channel(tick: int, distance: int) -> tuple:
    """Channel 0 sees it, its partner does not; the other modules see nothing: a disputed
    picture no module confirms (it may only bring the nearest track nearer)."""
    reports = list(clear(tick))
    reports[0] = Report(PRESENT, distance, 0, STATIC, tick)
    return tuple(reports)


def two_tracks(cfg: Config, near_dm: int, far_dm: int, far_closing: int = 0, v: int = 0):
    """A driver remembering a weak track at `near_dm` (module 0 saw it) beside a strong one at
    `far_dm` (confirmed, closing at `far_closing` + v), the near one created last."""
    d = normal_driver(cfg, M2)
    d.cycle(present(d.tick, far_dm, closing=far_closing + v), v)
    d.cycle(clear(d.tick), v)
    d.cycle(one_module(d.tick, near_dm), v)
    assert [t.near != NO_TRACK for t in d.state.tracks] == [True, True, False]
    return d


def test_a_confirmed_picture_absorbs_every_track_it_measures_keeping_the_faster_speed():
    """Two tracks within one window (the weak one 110 m nearer, the confirmed oncoming one):
    a confirmed static sighting between them measures the nearer and absorbs the farther,
    whose closing speed stays remembered; a one-module sighting there measures the nearer
    only and absorbs nothing."""
    cfg = Config()
    d = two_tracks(cfg, 1900, 3000, far_closing=2000)
    d.cycle(clear(d.tick), 0)
    out = d.present(2500)
    first, second, _ = d.state.tracks
    assert out.track_state == TRACK_SEEN and out.track_dm == 2500 and out.track_cycles == 0
    assert first.closing == 2000 and second.near == NO_TRACK
    d = two_tracks(cfg, 1900, 3000, far_closing=2000)
    d.cycle(clear(d.tick), 0)
    d.cycle(one_module(d.tick, 2500), 0)
    assert [t.near != NO_TRACK for t in d.state.tracks] == [True, True, False]


def test_a_near_confirmed_obstacle_is_no_evidence_against_a_farther_track():
    """The sensors report their nearest object: a confirmed obstacle seen without a break,
    nearer than a remembered one inside the declared range, says nothing about it; the
    farther track is held, however long."""
    cfg = Config()
    d = two_tracks(cfg, 1500, 3500)
    for _ in range(2 * forget_cycles(cfg)):
        out = d.present(1500)
    assert out.track_dm == 1500 and d.state.tracks[1].absent == 0
    assert d.state.tracks[1].near == 3500 * U - (2 * forget_cycles(cfg) + 3) * creep(cfg)   # (creeping: held)


def test_a_disputed_sighting_beyond_a_track_is_no_evidence_against_it():
    """One module sees something beyond the remembered obstacle (a weak track of its own), the
    others nothing: a dispute, not evidence; the nearer track is held, its count restarted."""
    cfg = Config()
    d = normal_driver(cfg, M2)
    d.present(1500)
    d.clear()
    for _ in range(2 * forget_cycles(cfg)):
        out = d.cycle(one_module(d.tick, 3500), 0)
    assert out.track_state == TRACK_HELD and d.state.tracks[0].absent == 0
    assert out.track_dm == (1500 * U - (2 * forget_cycles(cfg) + 1) * creep(cfg)) // U      # (creeping: held)


def test_one_module_seeing_a_track_between_its_two_positions_moves_it_one_channel_does_not():
    """Moving, the worst-case position runs ahead of the least-travel one: one module's
    sighting between them takes the track's position (seen); one channel's alone keeps it."""
    cfg = Config()
    v = 3000
    for reports, state in ((one_module, TRACK_SEEN), (single_channel, TRACK_HELD)):
        d = normal_driver(cfg, M2)
        d.cycle(present(d.tick, 30000, closing=v), v)
        for _ in range(5):
            out = d.cycle(clear(d.tick), v)
        t = d.state.tracks[0]
        between = (t.near + t.far) // 2 // U
        out = d.cycle(reports(d.tick, between), v)
        assert out.track_state == state and (out.track_dm == between) == (state == TRACK_SEEN)


def test_a_weak_track_seen_again_by_its_one_module_stays_weak():
    cfg = Config()
    d = normal_driver(cfg, M2)
    d.cycle(one_module(d.tick, 3000), 0)
    d.cycle(one_module(d.tick, 3000), 0)
    assert not d.state.tracks[0].strong
    for _ in range(forget_cycles(cfg, single=True)):
        out = d.clear()
    assert out.track_state == TRACK_FORGOTTEN and out.track_cycles == 0


def test_in_a_2oo2_monitor_a_confirmed_picture_makes_a_disputed_track_strong():
    """One module: a distance dispute inside it (both channels PRESENT, 100 m apart) creates a
    weak track; the confirmed picture that measures it makes it strong (forget_ms)."""
    cfg = Config(topology="2oo2")
    d = normal_driver(cfg, M2)
    d.cycle((Report(PRESENT, 3000, 0, STATIC, d.tick), Report(PRESENT, 4000, 0, STATIC, d.tick)), 0)
    assert d.state.tracks[0].near != NO_TRACK and not d.state.tracks[0].strong
    d.clear()
    d.cycle(present(d.tick, 3000, n=2), 0)
    assert d.state.tracks[0].strong


def test_the_memory_reason_and_the_risk_read_every_remembered_track():
    """A remembered nearer track unseen and a farther one that a module's sighting measures
    (seen, supervised: the picture is disputed): the memory reason is set for the unseen one;
    blind, the papers' risk reads the nearest remembered obstacle (at 20 m/s)."""
    from monitor.core.cycle import _zone_limits
    from monitor.core.risk import r1_ppm

    cfg = Config()
    v = 2000
    d = two_tracks(cfg, 3000, 6000, v=v)
    d.cycle(clear(d.tick), v)
    far = d.state.tracks[1]
    out = d.cycle(one_module(d.tick, (far.near + far.far) // 2 // U, module=1), v)
    assert out.reasons & R_MEMORY and out.track_state == TRACK_HELD
    assert d.state.tracks[1].cycles == 0                                 # the farther one: seen
    own = v * (1000 - cfg.speed_error_permille) // 1000
    closing = d.state.tracks[0].closing
    blind = d.cycle(clear(d.tick), v)
    alpha1, _ = _zone_limits(cfg, v, closing + own, 0)
    assert blind.r1_ppm == r1_ppm(blind.track_dm, alpha1) and blind.r1_ppm > 0


def test_a_merged_track_is_moved_from_the_age_of_the_sighting_that_made_it_nearest():
    """Three tracks held, a fourth sighting with a report 200 ms old between the two farthest:
    merged with the farthest at the sighting's position, moved by the period and that age (its
    closing speed plus the declared closing accuracy: the error budget)."""
    cfg = Config()
    v = 1000
    d = normal_driver(cfg, M2)
    for dist in (3000, 8000, 20000):
        d.cycle(one_module(d.tick, dist), v)
        d.cycle(clear(d.tick), v)
    reports = list(clear(d.tick))
    reports[0] = reports[1] = Report(PRESENT, 12000, v, STATIC, d.tick - 200)
    d.cycle(tuple(reports), v)
    merged = d.state.tracks[2]
    own = v - v * (1000 - cfg.speed_error_permille) // 1000
    assert merged.near == 12000 * U - near_travel(v, cfg.speed_error_permille, track_accel_mms2(cfg),
                                                  own + cfg.closing_accuracy_cms, 300)


def test_the_risk_reads_a_nearer_voted_obstacle_before_a_farther_remembered_one():
    """A farther track remembered (supervised: not the picture) and a nearer confirmed
    obstacle, at 20 m/s: the papers' risk reads the voted one, on its own zone limits; with a
    DEGRADED channel beside it (its module DEGRADED, the obstacle still voted) too."""
    from monitor.core.cycle import _zone_limits
    from monitor.core.risk import r1_ppm

    cfg = Config()
    v = 2000
    d = normal_driver(cfg, M2)
    d.cycle(present(d.tick, 8000, closing=v), v)
    d.cycle(clear(d.tick), v)
    out = d.cycle(present(d.tick, 3000, closing=v), v)
    alpha1, _ = _zone_limits(cfg, v, v, 0)
    assert out.track_dm == 3000 and out.r1_ppm == r1_ppm(3000, alpha1) > 0
    reports = list(present(d.tick, 3000, closing=v))
    reports[1] = Report(2, 0, 0, STATIC, d.tick)                          # DEGRADED: its module too
    out = d.cycle(tuple(reports), v)
    assert out.distance_dm == 3000 and out.r1_ppm == r1_ppm(3000, alpha1) > 0
