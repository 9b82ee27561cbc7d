"""Freshness and range checks of one channel: anything doubtful becomes DEGRADED.

A channel never heard from, a report older than its timeout, a report from the future
(a stale or corrupted timestamp) and any value outside its documented range all count as
DEGRADED, the safe side of the 2oo2 voter.
"""
from __future__ import annotations

from .types import ABSENT, DEGRADED, MAX_CLOSING_CMS, MAX_DISTANCE_DM, PRESENT, TRAIN


def in_range(status: int, distance_dm: int, closing_cms: int, obstacle: int) -> bool:
    """True if every field of a report is inside its documented range.

    post: __return__ == (0 <= status <= 2 and 0 <= distance_dm <= 60000 and -15000 <= closing_cms <= 15000 and 0 <= obstacle <= 2)
    """
    return (ABSENT <= status <= DEGRADED and 0 <= distance_dm <= MAX_DISTANCE_DM
            and -MAX_CLOSING_CMS <= closing_cms <= MAX_CLOSING_CMS and 0 <= obstacle <= TRAIN)


def is_fresh(received: int, now: int, timeout_ticks: int) -> bool:
    """A report received at `received` is fresh at `now` if no older than the timeout.

    pre: timeout_ticks >= 1
    post: __return__ == (received <= now and now - received <= timeout_ticks)
    """
    return received <= now and now - received <= timeout_ticks


def effective_status(status: int, distance_dm: int, closing_cms: int, obstacle: int,
                     received: int, now: int, timeout_ticks: int) -> int:
    """The status the voter sees: the reported one if fresh and in range, else DEGRADED.

    pre: timeout_ticks >= 1
    post: __return__ in (0, 1, 2)
    post: __return__ == 2 or (__return__ == status and is_fresh(received, now, timeout_ticks))
    post: not (status == 1 and is_fresh(received, now, timeout_ticks)) or __return__ >= 1
    """
    if not is_fresh(received, now, timeout_ticks):
        return DEGRADED
    if not in_range(status, distance_dm, closing_cms, obstacle):
        return DEGRADED
    return status


def channel_status(report, now: int, timeout_ticks: int) -> int:
    """effective_status of a Report; DEGRADED for a channel never heard from (None) and for
    a report with a field that is not an int (bool, float, str, None)."""
    if report is None:
        return DEGRADED
    try:
        if not (type(report.status) is int and type(report.distance_dm) is int and type(report.closing_cms) is int
                and type(report.obstacle) is int and type(report.tick) is int):
            return DEGRADED  # integers only (floats would break bit-exact agreement with the C core)
        return effective_status(report.status, report.distance_dm, report.closing_cms,
                                report.obstacle, report.tick, now, timeout_ticks)
    except TypeError:  # a field that is not a number: as bad as out of range
        return DEGRADED


__all__ = ["in_range", "is_fresh", "effective_status", "channel_status", "PRESENT"]
