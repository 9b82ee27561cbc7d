"""Plausibility of one channel's reports over time (issue 38 item 3): a distance that does
not shrink as the channel's own closing speed says it must is a fault of that channel.

A sensor stuck on one report (a frozen image, a hung tracker) keeps sending fresh frames
with valid counters; freshness, range and the voters all pass it, and a common freeze of
every channel hides an approaching obstacle for good. What a frozen report cannot do is keep
its story straight: its distance must shrink by what its closing speed says the obstacle ran.

The check is one-sided, to the safe side. Between a reference report and the newest one the
obstacle ran at least `lo` and at most `hi` (the reported closing speeds, the lower and the
higher of each consecutive pair, times the time between them). A report *farther* than the
reference less `lo`, beyond the declared accuracy (twice the distance accuracy, one per report,
plus the closing-speed accuracy over the span), is implausible: the channel counts as DEGRADED
until a whole `window_ms` of its reports agrees with their closing speeds again. A report
*nearer* than the reference less `hi` is something new in front (an object entering the
track) and starts a new reference; nearer is never a fault. A channel that is not PRESENT has
no story to check: its reference is dropped (and its fault with it: it is judged again from
its next sighting on).

Positions are in 1e-5 m, as in memory.py (cm/s x ms); the state of one channel is a tuple
(ref_dm, ref_tick, last_tick, last_closing, lo, hi, bad) and NO_REFERENCE before a sighting.
"""
from __future__ import annotations

from .memory import UNITS_PER_DM

NO_REF = -1
NO_REFERENCE = (NO_REF, 0, 0, 0, 0, 0, 0)


def slack(accuracy_dm: int, accuracy_cms: int, span_ms: int) -> int:
    """How far two reports `span_ms` apart may disagree with the travel between them, in
    1e-5 m: each distance within `accuracy_dm`, the closing speed within `accuracy_cms`.

    pre: 0 <= accuracy_dm <= 60000 and 0 <= accuracy_cms <= 15000 and 0 <= span_ms
    post: __return__ == 2 * accuracy_dm * 10000 + accuracy_cms * span_ms
    """
    return 2 * accuracy_dm * UNITS_PER_DM + accuracy_cms * span_ms


def anchor(distance_dm: int, closing_cms: int, tick: int, bad: int) -> tuple:
    """A new reference at this report: nothing run since it yet, the fault as given."""
    return (distance_dm, tick, tick, closing_cms, 0, 0, bad)


def check(prev: tuple[int, int, int, int, int, int, int], present: bool, distance_dm: int, closing_cms: int, tick: int,
          accuracy_dm: int, accuracy_cms: int, window_ms: int) -> tuple:
    """The channel's plausibility state after this cycle's report; its last field is 1 while
    the channel is implausible.

    pre: 0 <= distance_dm <= 60000 and -15000 <= closing_cms <= 15000
    pre: 0 <= accuracy_dm <= 60000 and 0 <= accuracy_cms <= 15000 and 1 <= window_ms <= 60000
    pre: len(prev) == 7 and prev[1] <= prev[2] and prev[6] in (0, 1)
    post: not present or __return__[0] != -1
    post: present or __return__ == (-1, 0, 0, 0, 0, 0, 0)
    post: not (present and prev[0] == -1) or __return__ == (distance_dm, tick, tick, closing_cms, 0, 0, prev[6])
    post: not (present and prev[0] != -1 and tick == prev[2]) or __return__ == prev
    post: __return__[6] in (0, 1)
    post: not (present and prev[0] != -1 and 0 < tick - prev[2] <= window_ms and distance_dm * 10000 > prev[0] * 10000 - prev[4] - min(closing_cms, prev[3]) * (tick - prev[2]) + slack(accuracy_dm, accuracy_cms, tick - prev[1])) or __return__ == (distance_dm, tick, tick, closing_cms, 0, 0, 1)
    """
    if not present:
        return NO_REFERENCE
    ref, ref_tick, last_tick, last_closing, lo, hi, bad = prev
    bad = 1 if bad else 0
    if ref == NO_REF:
        return anchor(distance_dm, closing_cms, tick, bad)
    if tick == last_tick:
        return prev
    dt = tick - last_tick
    if dt < 0 or dt > window_ms:          # out of order or a gap: no evidence either way
        return anchor(distance_dm, closing_cms, tick, bad)
    lo += (closing_cms if closing_cms < last_closing else last_closing) * dt
    hi += (closing_cms if closing_cms > last_closing else last_closing) * dt
    span = tick - ref_tick
    tolerance = slack(accuracy_dm, accuracy_cms, span)
    d, r = distance_dm * UNITS_PER_DM, ref * UNITS_PER_DM
    if d > r - lo + tolerance:            # farther than the obstacle can be: implausible
        return anchor(distance_dm, closing_cms, tick, 1)
    if d < r - hi - tolerance:            # nearer than it can be: something new in front
        return anchor(distance_dm, closing_cms, tick, bad)
    if span >= window_ms:                 # a whole window that agrees: plausible again
        return anchor(distance_dm, closing_cms, tick, 0)
    return (ref, ref_tick, tick, closing_cms, lo, hi, bad)
