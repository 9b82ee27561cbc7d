"""Several remembered obstacles (issue 38 item 2): which track a sighting measures, what a
new one does when every slot is held, and the order the cycle reads them in.

The memory keeps every obstacle that no evidence has cleared, up to TRACKS at once, nearest
first. The sensors report their nearest object (the declaration), so a sighting at d says
that nothing is nearer than d, to within a = 2 x `distance_accuracy_dm` (the two reports'
declared accuracy). Against a track remembered between `near` (worst case) and `far` (least
travel) it is:

* ahead of it (d < near - a): another obstacle. The remembered one cannot be nearer than
  `near` (the memory's invariant), so the sighting is not it; a sighting that may create a
  track creates one and the track is kept;
* the track measured again (near - a <= d <= far + a): `memory.observe` updates it;
* beyond it (d > far + a, `memory.seen_beyond`): a confirmed picture is evidence that it is
  gone, counted as ABSENT is; a disputed one says nothing about it.

A sighting measures the nearest track whose window holds it; a confirmed picture also
measures every farther one whose window holds it (the same obstacle to within the sensors'
accuracy: they are absorbed into it, their closing speed kept there).

The rule when full: when every slot is held and a new obstacle is seen, the two farthest of
them become one (`merge`): the nearer worst-case position, the farther least position, the
faster closing speed, the longer forgetting. It is supervised as the nearer and faster of
the two and forgotten or passed only where the farther could be (in range, passed and seen
beyond are judged on its `far`). Until a sighting measures it: then it is what that sighting
shows, and the farther of the two is no longer remembered. Three nearer obstacles are then
remembered in front of it (the nearest is never merged), and it is lost only if all of them
are cleared by evidence that does not reach it: the memory's limit, stated, not hidden.
"""
from __future__ import annotations

from .memory import UNITS_PER_DM, seen_beyond
from .types import NO_TRACK, TRACK_HELD, Track

MEASURES, AHEAD, BEYOND = 0, 1, 2


def relation(near: int, far: int, distance_dm: int, accuracy_dm: int) -> int:
    """Where a sighting lies against a held track: MEASURES, AHEAD or BEYOND (module doc).

    pre: 0 <= near and -600000000 <= far and 0 <= distance_dm <= 60000 and 0 <= accuracy_dm <= 60000
    post: (__return__ == 2) == seen_beyond(near, far, distance_dm, accuracy_dm)
    post: __return__ != 1 or distance_dm * 10000 < near - 2 * accuracy_dm * 10000
    post: __return__ != 0 or near - 2 * accuracy_dm * 10000 <= distance_dm * 10000 <= far + 2 * accuracy_dm * 10000
    """
    if seen_beyond(near, far, distance_dm, accuracy_dm):
        return BEYOND
    if distance_dm * UNITS_PER_DM < near - 2 * accuracy_dm * UNITS_PER_DM:
        return AHEAD
    return MEASURES


def assign(tracks: tuple[Track, ...], distance_dm: int, accuracy_dm: int, creates: bool) -> tuple[int, bool]:
    """(slot, create) for a voted obstacle at `distance_dm`: the slot of the track it measures
    (-1: none) and whether it is a new obstacle to remember. `creates`: the picture may
    create a track (confirmed, or some module sees it with both channels); one that may not
    (a disputed picture no module confirms) only brings the nearest track nearer, as
    `memory.observe` does with a single track. `tracks` are ordered, nearest first.

    pre: len(tracks) == 3 and all(t.near == -1 or (t.near >= 0 and t.far >= -600000000) for t in tracks)
    pre: 0 <= distance_dm <= 60000 and 0 <= accuracy_dm <= 60000
    post: not (__return__[0] >= 0 and __return__[1]) and (creates or not __return__[1])
    post: __return__[0] == -1 or tracks[__return__[0]].near != -1
    post: not creates or __return__[0] == -1 or relation(tracks[__return__[0]].near, tracks[__return__[0]].far, distance_dm, accuracy_dm) == 0
    post: creates or __return__[0] == (0 if tracks[0].near != -1 else -1)
    """
    if not creates:
        return (0 if tracks[0].near != NO_TRACK else -1), False
    for i, t in enumerate(tracks):
        if t.near == NO_TRACK:
            break
        r = relation(t.near, t.far, distance_dm, accuracy_dm)
        if r == AHEAD:
            return -1, True
        if r == MEASURES:
            return i, False
    return -1, True


def absorbed(tracks: tuple, slot: int, distance_dm: int, accuracy_dm: int) -> tuple:
    """The slots beyond `slot` that a confirmed picture at `distance_dm` also measures: the
    same obstacle to within the sensors' accuracy, emptied into the one it measures."""
    return tuple(j for j in range(slot + 1, len(tracks)) if tracks[j].near != NO_TRACK
                 and relation(tracks[j].near, tracks[j].far, distance_dm, accuracy_dm) == MEASURES)


def merge(a: Track, b: Track) -> Track:
    """Two remembered obstacles as one, to the safe side of both (module doc).

    pre: a.near >= 0 and b.near >= 0 and a.closing >= 0 and b.closing >= 0
    post: __return__.near == min(a.near, b.near) and __return__.far == max(a.far, b.far)
    post: __return__.closing >= a.closing and __return__.closing >= b.closing
    post: __return__.strong == (a.strong or b.strong) and __return__.absent == 0
    """
    return Track(a.near if a.near < b.near else b.near, a.far if a.far > b.far else b.far,
                 a.closing if a.closing > b.closing else b.closing,
                 a.cycles if a.cycles < b.cycles else b.cycles, 0, a.strong or b.strong)


def ordered(tracks: list, ages: list, states: list) -> tuple[list, list, list]:
    """The slots nearest first, empty ones last; equal positions keep their order (stable, as
    the C core's insertion sort is), with each slot's age and state."""
    order = sorted(range(len(tracks)), key=lambda i: (tracks[i].near == NO_TRACK, tracks[i].near))
    return [tracks[i] for i in order], [ages[i] for i in order], [states[i] for i in order]


def insert(tracks: list, ages: list, states: list, new: Track, age: int, state: int) -> tuple[list, list, list]:
    """`new` remembered in the first empty slot; with none empty, the two farthest of the
    held ones and `new` merge into one (held: no slot is as it was seen). The nearest is
    never merged: TRACKS >= 2."""
    for i, t in enumerate(tracks):
        if t.near == NO_TRACK:
            return (tracks[:i] + [new] + tracks[i + 1:], ages[:i] + [age] + ages[i + 1:],
                    states[:i] + [state] + states[i + 1:])
    tracks, ages, states = ordered(tracks + [new], ages + [age], states + [state])
    a, b = tracks[-2], tracks[-1]
    return tracks[:-2] + [merge(a, b)], ages[:-2] + [ages[-2]], states[:-2] + [TRACK_HELD]
