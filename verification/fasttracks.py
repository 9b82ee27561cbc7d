"""The obstacle memory of the vectorised core (verification/fastcore.py) on arrays: up to
TRACKS remembered obstacles a train, nearest first, as monitor/core/tracks.py and
monitor/core/memory.py keep them (what a sighting measures, creates or absorbs; the evidence
that a track is gone; the worst-case move each period). Its own module so that the twin's
cycle and its memory each stay readable; fastcore's agreement check covers both.
"""
from __future__ import annotations

import numpy as np

from monitor.core import cycle
from monitor.core.memory import UNITS_PER_DM
from monitor.core.types import (
    MAX_COUNT, NO_DISTANCE, NO_TRACK, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_NONE, TRACK_PASSED,
    TRACK_SEEN, TRACKS,
)

I64 = np.int64


def accel_run(accel_mms2: int, period_ms: int) -> int:
    """memory.accel_run: a T^2 / 2 in 1e-5 m, rounded up."""
    return -(-accel_mms2 * period_ms * period_ms // 20000)


def near_travel(speed_cms, error_permille: int, accel_mms2: int, obstacle_cms, period_ms: int) -> np.ndarray:
    """memory.near_travel on arrays: the most the gap to a remembered obstacle shrinks in a period (1e-5 m)."""
    v_max = -(-(speed_cms * (1000 + error_permille)) // 1000)
    return v_max * period_ms + accel_run(accel_mms2, period_ms) + obstacle_cms * period_ms


def far_travel(speed_cms, error_permille: int, accel_mms2: int, period_ms: int) -> np.ndarray:
    """memory.far_travel on arrays: the least the train ran in the period (1e-5 m), at least 0."""
    run = speed_cms * (1000 - error_permille) // 1000 * period_ms - accel_run(accel_mms2, period_ms)
    return np.maximum(run, 0)


# the rows of TrackMemory.slots: types.Track's fields, each a (TRACKS, n) array (slot i of
# train j at [i, j]: slot-major, so that a train's values broadcast along the trains)
SLOT_FIELDS = ("near", "far", "closing", "cycles", "absent", "strong")


def any_slot(mask: np.ndarray) -> np.ndarray:
    """mask.any(axis=0) of a (TRACKS, n) mask, slot by slot (faster for few slots)."""
    out = mask[0]
    for row in mask[1:]:
        out = out | row
    return out


def _max_slot(values: np.ndarray) -> np.ndarray:
    """values.max(axis=0) of a (TRACKS, n) array, slot by slot."""
    out = values[0]
    for row in values[1:]:
        out = np.maximum(out, row)
    return out


def _ordered(stack: np.ndarray) -> np.ndarray:
    """tracks.ordered on a (fields, TRACKS, n) stack whose first field is `near`: each
    train's slots nearest first, empty ones last, equal positions in their slot order (a
    stable sort). Only the trains out of order are sorted; the stack is reordered in place."""
    key = stack[0].view(np.uint64)                # NO_TRACK (-1) reads as the largest: empty slots last
    wrong = any_slot(key[1:] < key[:-1])
    if wrong.any():
        trains = np.nonzero(wrong)[0]
        perm = np.argsort(key[:, trains], axis=0, kind="stable")
        stack[:, :, trains] = stack[:, perm, trains]
    return stack


def _merge_into_full(stack: np.ndarray, trains: np.ndarray, new: np.ndarray) -> None:
    """tracks.insert with every slot held, for the `trains` of a (fields, TRACKS, n) stack
    (SLOT_FIELDS, then the slots' ages and states; `new`: (fields, trains.size), the new
    track of each of them): the held tracks and the new one in order (stable: the new one
    after equal positions), the two farthest merged (tracks.merge: the nearer near, the
    farther far, the faster closing, the fewer cycles, no evidence, strong if either) with
    the nearer one's age, held. In place."""
    ext = np.concatenate((stack[:, :, trains], new[:, None, :]), axis=1)
    ext = ext[:, np.argsort(ext[0], axis=0, kind="stable"), np.arange(trains.size)]
    a, b = TRACKS - 1, TRACKS
    merged = ext[:, a].copy()                     # (its age: the nearer one's)
    merged[0] = np.minimum(ext[0, a], ext[0, b])
    merged[1] = np.maximum(ext[1, a], ext[1, b])
    merged[2] = np.maximum(ext[2, a], ext[2, b])
    merged[3] = np.minimum(ext[3, a], ext[3, b])
    merged[4] = 0
    merged[5] = ext[5, a] | ext[5, b]
    merged[7] = TRACK_HELD
    stack[:, :a, trains] = ext[:, :a]
    stack[:, a, trains] = merged


class TrackMemory:
    """State.tracks of n trains: (fields, TRACKS, n), the fields of types.Track (SLOT_FIELDS;
    positions in 1e-5 m, NO_TRACK: the slot is empty; strong 0 or 1), nearest first, empty
    slots last."""

    def __init__(self, setup: cycle.Setup, n: int):
        self.setup = setup
        self.slots = np.zeros((len(SLOT_FIELDS), TRACKS, n), dtype=I64)
        self.slots[:2] = NO_TRACK

    def observe(self, present, confirmed, several, dist, speed, toward, own, age, stale) -> tuple:
        """Step 4 of the cycle: the remembered obstacles after this cycle's picture
        (monitor/core/tracks.py with memory.observe and forget, slot by slot). A sighting
        measures the nearest track whose window holds it (tracks.assign; a confirmed one
        also absorbs every farther track it measures, keeping the faster closing speed) or,
        ahead of or beyond them all, is a new track (in the first empty slot; with none, the
        two farthest merge: tracks.insert); a confirmed sighting beyond a track, and ABSENT
        with every channel fresh, are evidence that it is gone (forget_cycles if the track
        is strong: confirmed or `several` modules saw it, else forget_single); the tracks
        are kept ordered nearest first.
        Every present picture here is a module's sighting (it may create a track).
        Returns (t_state, t_cycles, t_dm, far, ages, states): the outputs track_state,
        track_cycles and track_dm; the far position of the track they report on, judged this
        cycle (before a forgotten or passed nearest track is cleared; NO_TRACK: none); and per
        slot (TRACKS, n), in the slots' new order, the age of a sighting it took this cycle
        (0 if it kept its position) and its TRACK_* state."""
        cfg = self.setup.config
        N, F, C, Y, A, S = self.slots                          # (TRACKS, n) each
        occ = N != NO_TRACK
        units = dist * UNITS_PER_DM
        acc2 = 2 * cfg.distance_accuracy_dm * UNITS_PER_DM
        beyond = occ & (units > F + acc2)                     # tracks.relation: BEYOND (memory.seen_beyond)
        measures = occ & ~beyond & (units >= N - acc2)        # MEASURES (else AHEAD: another obstacle)
        # tracks.assign: the first track the sighting is not beyond; it measures it, or is ahead
        # of it (or beyond them all): a new track (the occupied slots come first)
        cand = present & occ & ~beyond
        first = np.empty_like(cand)                           # the first candidate, and the slots after it
        after = np.empty_like(cand)
        before = np.zeros_like(present)
        for i in range(TRACKS):
            first[i], after[i] = cand[i] & ~before, before
            before = before | cand[i]
        is_slot = first & measures
        hit = any_slot(is_slot)
        create = present & ~hit
        gone = measures & after & (confirmed & hit)                            # tracks.absorbed
        # the measured track (memory.observe, sighted): confirmed, or nearer than its worst
        # case, or where it can be (up to far): it takes the position; else it is held there
        seen = is_slot & (confirmed | (units <= N) | (units <= F))
        held_m = is_slot & ~seen
        own_closing = np.maximum(toward - own, 0)
        # the others (not measured, not absorbed): the train's least travel, evidence, forget
        other = occ & ~is_slot & ~gone
        far = F - far_travel(speed, cfg.speed_error_permille, self.setup.track_accel, cfg.period_ms)
        reach = far + cfg.distance_accuracy_dm * UNITS_PER_DM    # the farthest the obstacle can lie
        passed = other & (reach < 0)
        evidence = (other & ~passed & ((confirmed & beyond) | ~(present | stale))
                    & (reach <= cfg.sensor_range_dm * UNITS_PER_DM))
        count = A + 1
        single = self.setup.forget_single
        forgotten = evidence & (count >= single + (self.setup.forget_cycles - single) * S)   # (strong: 0 or 1)
        confirming = evidence & ~forgotten
        kept = other & ~passed & ~forgotten
        # each slot's TRACK_* state: what the nearest's was (before a new track is inserted);
        # the held ones' (seen, held or confirming: the others are emptied) go with them
        first_state = np.where(is_slot[0], np.where(seen[0], TRACK_SEEN, TRACK_HELD),
                               np.where(kept[0], np.where(confirming[0], TRACK_CONFIRMING, TRACK_HELD),
                                        np.where(forgotten[0], TRACK_FORGOTTEN,
                                                 np.where(passed[0], TRACK_PASSED, TRACK_NONE))))
        states = np.where(seen, TRACK_SEEN, np.where(confirming, TRACK_CONFIRMING, TRACK_HELD))
        first_lost = forgotten[0] | passed[0]
        first_far = far[0]
        # (an absorbed track's closing speed stays remembered in the one that measures it)
        taken = np.where(confirmed, own_closing, np.maximum(own_closing, C))
        if gone.any():
            taken = np.maximum(taken, _max_slot(np.where(gone, C, 0)))
        stack = np.stack((np.where(seen, units, np.where(is_slot | kept, N, NO_TRACK)),
                          np.where(seen, units, np.where(is_slot, F, np.where(kept, far, NO_TRACK))),
                          np.where(is_slot, taken, np.where(kept, C, 0)),
                          np.where(held_m | kept, np.minimum(Y + 1, MAX_COUNT), 0),
                          np.where(confirming, count, 0),
                          np.where(is_slot, S | confirmed | several, np.where(kept, S, 0)),
                          np.where(seen, age, 0),
                          states))
        if create.any():                                      # tracks.insert
            free = stack[0] == NO_TRACK
            r = np.nonzero(create)[0]
            u = units[r]
            new = np.stack((u, u, own_closing[r], np.zeros_like(u), np.zeros_like(u), confirmed[r] | several[r],
                            age[r], np.full_like(u, TRACK_SEEN)))
            room = any_slot(free)[r]                          # the first empty slot
            stack[:, free[:, r[room]].argmax(axis=0), r[room]] = new[:, room]
            if not room.all():                                 # none: the two farthest merge
                _merge_into_full(stack, r[~room], new[:, ~room])
        _ordered(stack)
        self.slots = stack[:len(SLOT_FIELDS)]
        near, cycles, ages, states = stack[0], stack[3], stack[6], stack[7]
        has = near[0] != NO_TRACK
        t_dm = np.where(has, near[0] // UNITS_PER_DM, NO_DISTANCE)
        t_state = np.where(first_lost, first_state, np.where(has, states[0], TRACK_NONE))
        t_cycles = np.where(first_lost, 0, cycles[0])
        return t_state, t_cycles, t_dm, np.where(first_lost, first_far, stack[1][0]), ages, states

    def move(self, speed, ages) -> None:
        """The end of the cycle: every remembered obstacle moved for the next period (and a
        sighting's age), worst case for the train, each at its own closing speed; then
        nearest first again."""
        cfg = self.setup.config
        near = self.slots[0]
        moved = near - near_travel(speed, cfg.speed_error_permille, self.setup.track_accel,
                                   self.slots[2] + cfg.closing_accuracy_cms, cfg.period_ms + ages)
        self.slots[0] = np.where(near != NO_TRACK, np.maximum(moved, 0), NO_TRACK)
        _ordered(self.slots)
