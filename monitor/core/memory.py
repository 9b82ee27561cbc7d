"""Obstacle memory (DESIGN.md section 14): an obstacle lost from sight is not forgotten.

A voted obstacle is kept as a track and predicted forward every cycle, worst case for
the train: a static obstacle stays where it was, a receding one is taken to stop at once, an
oncoming one keeps closing at its last speed, and the train runs at its measured speed plus
the speed error, accelerating under traction and downhill. The sensors' declared accuracy is
counted where the step uses a track (cycle.py, the error budget): a track moves at its own
speed plus the closing accuracy, and counts as passed or inside the sensors' range with the
distance accuracy added to its farthest position. The report's age is counted once, at
the end of the cycle that saw it, at that cycle's speed: the remembered curves count no age (a
train that has braked since would otherwise count the age's travel at a lower speed than the
one it ran at; issue 30 item 4). The curves supervise the voted and every
remembered obstacle (cycle.py), so a blind spell never lowers a demand while the train is
inside a remembered obstacle's curve.

What is remembered follows the voter's safe side, not its unanimity: a picture in which any
module sees the obstacle with both its channels creates the track (`observe`).

The track is forgotten only on positive evidence: every module reports ABSENT, fresh and
unanimous, or every module sees something farther than the remembered obstacle can be
(`seen_beyond`: the sensors report their nearest object), for `forget_ms` while the
remembered position lies inside the sensors' declared range (`sensor_range_dm`); or the train
has passed the remembered position (its least possible travel took it beyond). A farther
sighting never replaces the track: it is remembered beside it (several obstacles at once,
tracks.py; the functions here act on one of them).

Positions are integers in 1e-5 m, the unit of cm/s x ms, so that dead reckoning is exact:
one period at v cm/s is v * period_ms units; `UNITS_PER_DM` of them make a decimetre.
"""
from __future__ import annotations

from .types import NO_DISTANCE, NO_TRACK, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_PASSED

UNITS_PER_DM = 10000


def accel_run(accel_mms2: int, period_ms: int) -> int:
    """a T^2 / 2 in 1e-5 m, rounded up: what acceleration can add to (or explain away from)
    a period's travel at constant speed.

    pre: 0 <= accel_mms2 <= 10000 and 1 <= period_ms <= 70000
    post: __return__ >= 0
    post: __return__ * 20000 >= accel_mms2 * period_ms * period_ms
    post: (__return__ - 1) * 20000 < accel_mms2 * period_ms * period_ms or __return__ == 0
    """
    return -(-accel_mms2 * period_ms * period_ms // 20000)


def near_travel(speed_cms: int, error_permille: int, accel_mms2: int, obstacle_cms: int, period_ms: int) -> int:
    """The most the gap to a remembered obstacle can shrink in `period_ms` (the next period,
    and after a sighting also the report's age, which the curves no longer count once the
    position is remembered), in 1e-5 m: the train at its measured speed plus the speed error,
    accelerating at `accel_mms2` (traction plus downhill), and the obstacle closing at its
    own speed (0 if not oncoming).

    pre: 0 <= speed_cms <= 12000 and 0 <= error_permille <= 500 and 0 <= accel_mms2 <= 10000
    pre: 0 <= obstacle_cms <= 30000 and 1 <= period_ms <= 70000
    post: __return__ * 1000 >= speed_cms * (1000 + error_permille) * period_ms + obstacle_cms * period_ms * 1000
    post: __return__ >= speed_cms * period_ms + obstacle_cms * period_ms
    """
    v_max = -(-speed_cms * (1000 + error_permille) // 1000)
    return v_max * period_ms + accel_run(accel_mms2, period_ms) + obstacle_cms * period_ms


def far_travel(speed_cms: int, error_permille: int, accel_mms2: int, period_ms: int) -> int:
    """The least the train can have run in the period that ended at this speed, in 1e-5 m:
    the measured speed less the speed error, less what acceleration in the period explains,
    never below 0 (what "passed" is judged on: the train may be slower than it says).

    pre: 0 <= speed_cms <= 12000 and 0 <= error_permille <= 500 and 0 <= accel_mms2 <= 10000
    pre: 1 <= period_ms <= 10000
    post: __return__ >= 0
    post: __return__ * 1000 <= speed_cms * (1000 - error_permille) * period_ms
    post: __return__ == 0 or __return__ * 20000 <= 20000 * speed_cms * period_ms - accel_mms2 * period_ms * period_ms
    """
    run = speed_cms * (1000 - error_permille) // 1000 * period_ms - accel_run(accel_mms2, period_ms)
    return run if run > 0 else 0


def observe(near: int, far: int, closing: int, distance_dm: int, obstacle_cms: int, age_now: int,
            confirmed: bool, sighted: bool) -> tuple[int, int, int, int]:
    """(near, far, closing, age) of the track after a voted obstacle at `distance_dm`; `age`
    is the age of the report the position came from when this sighting set it (0 when the
    track kept its position: its age was counted when it was moved, see `near_travel`). A
    confirmed picture (every module sees it, no flag: the 3oo3 vote) creates or replaces the
    track. A disputed one in which some module sees the obstacle with both its channels
    (`sighted`: a module's 2oo2 says PRESENT; the voter's safe side, DESIGN.md section 14)
    creates the track at the voted distance when there is none, so a module that misses the
    obstacle does not stop the others' sighting from being remembered. Any disputed picture
    brings an existing track nearer; a module's sighting also takes the track's position
    when it lies between the worst-case prediction (`near`) and the last position less the
    train's least travel (`far`): the remembered obstacle seen where it can be, so that the
    worst case does not drift ahead of what two channels measure. Beyond `far` it never
    moves the track, so a farther sighting never hides a nearer remembered obstacle. One
    channel alone (its module partner disagrees) creates nothing: it is answered while it
    is reported. A receding obstacle's speed is
    remembered as 0 (it may stop at once).

    pre: 0 <= distance_dm <= 60000 and -30000 <= obstacle_cms <= 30000 and age_now >= 0
    pre: near >= -1 and closing >= 0
    pre: sighted or not confirmed
    post: __return__[0] <= distance_dm * 10000
    post: __return__[0] == -1 or (__return__[0] >= 0 and __return__[2] >= 0 and __return__[2] >= obstacle_cms)
    post: not confirmed or __return__[:3] == (distance_dm * 10000, distance_dm * 10000, max(obstacle_cms, 0))
    post: sighted or near != -1 or __return__ == (-1, -1, 0, 0)
    post: not sighted or near != -1 or __return__ == (distance_dm * 10000, distance_dm * 10000, max(obstacle_cms, 0), age_now)
    post: confirmed or near == -1 or ((__return__[0] <= near or (sighted and __return__[0] <= far)) and __return__[2] >= closing)
    post: confirmed or near == -1 or sighted or __return__[0] <= near
    post: __return__[3] in (0, age_now) and (__return__[3] == 0 or __return__[0] == distance_dm * 10000)
    """
    d = distance_dm * UNITS_PER_DM
    own = obstacle_cms if obstacle_cms > 0 else 0
    if confirmed:
        return d, d, own, age_now
    if near == NO_TRACK:
        if sighted:
            return d, d, own, age_now
        return NO_TRACK, NO_TRACK, 0, 0
    faster = own if own > closing else closing
    if d <= near or (sighted and d <= far):
        return d, d, faster, age_now
    return near, far, faster, 0


def seen_beyond(near: int, far: int, distance_dm: int, accuracy_dm: int) -> bool:
    """Whether a confirmed sighting is evidence that the track is gone rather than the track
    measured again (issue 38 item 2): farther than the remembered obstacle can be (`far`) by
    more than the two reports' declared accuracy. The sensors report their nearest object, so
    something seen beyond the remembered position says nothing is there: it counts as ABSENT
    does (`forget`), and becomes the track once the old one is forgotten, never at once.

    pre: near >= -1 and far >= -600000000 and 0 <= distance_dm <= 60000 and 0 <= accuracy_dm <= 60000
    post: not __return__ or (near != -1 and distance_dm * 10000 > far)
    post: __return__ or near == -1 or distance_dm * 10000 <= far + 2 * accuracy_dm * 10000
    """
    return near != NO_TRACK and distance_dm * UNITS_PER_DM > far + 2 * accuracy_dm * UNITS_PER_DM


def forget(cycles_absent: int, evidence: bool, in_range: bool, passed: bool, forget_cycles: int) -> tuple[int, int]:
    """(evidence cycles, track state) of a remembered obstacle that no channel shows: passed
    (the train's least travel took it beyond) forgets at once; fresh unanimous ABSENT inside
    the declared sensor range counts towards forgetting, which happens after `forget_cycles`
    such cycles in a row; anything else (blind, stale, disputed, out of range) holds it.

    pre: cycles_absent >= 0 and forget_cycles >= 1
    post: __return__[1] in (2, 3, 4, 5)
    post: (__return__[1] == 5) == passed
    post: not (__return__[1] == 4) or (evidence and in_range and cycles_absent + 1 >= forget_cycles)
    post: passed or not (evidence and in_range) or __return__[1] >= 3
    post: passed or (evidence and in_range) or __return__ == (0, 2)
    post: __return__[0] < forget_cycles
    """
    if passed:
        return 0, TRACK_PASSED
    if not (evidence and in_range):
        return 0, TRACK_HELD
    count = cycles_absent + 1
    if count >= forget_cycles:
        return 0, TRACK_FORGOTTEN
    return count, TRACK_CONFIRMING


def distance_dm(near: int) -> int:
    """The remembered distance in dm, rounded down (nearer is the safe side), NO_DISTANCE if none.

    pre: near >= -1
    post: near == -1 or __return__ * 10000 <= near
    post: (near == -1) == (__return__ == 65535) or near >= 655350000
    """
    return NO_DISTANCE if near == NO_TRACK else near // UNITS_PER_DM

