"""2oo2 voting inside a module and 3oo3 voting across modules, always to the safe side.

Seed 002, section 2 and Fig. 5: a module's result is the maximum of its channels'
statuses (ABSENT < PRESENT < DEGRADED), its distance the shorter one, and any disagreement
or DEGRADED channel raises its flag. Section 4.7: the three modules must be unanimous;
any flag, DEGRADED module or split obstacle/no-obstacle indication is a system error.
"""
from __future__ import annotations

from .types import ABSENT, DEGRADED, NO_DISTANCE, PRESENT  # noqa: F401 (NO_DISTANCE documents 65535)


def vote_2oo2(sa: int, da: int, sb: int, db: int) -> tuple[int, int, bool]:
    """(status, distance, flag) of one module from its two channels.

    pre: 0 <= sa <= 2 and 0 <= sb <= 2
    pre: 0 <= da <= 65535 and 0 <= db <= 65535
    post: __return__[0] == max(sa, sb)
    post: __return__[2] == (sa != sb or sa == 2 or sb == 2)
    post: not (sa == 1 and sb == 1) or __return__[1] == min(da, db)
    post: not (sa == 1 and sb != 1) or __return__[1] == da
    post: not (sb == 1 and sa != 1) or __return__[1] == db
    post: not (sa != 1 and sb != 1) or __return__[1] == 65535
    post: not (sa == 1 or sb == 1) or __return__[0] >= 1
    """
    status = sa if sa > sb else sb
    if sa == PRESENT and sb == PRESENT:
        distance = da if da < db else db
    elif sa == PRESENT:
        distance = da
    elif sb == PRESENT:
        distance = db
    else:
        distance = NO_DISTANCE
    flag = sa != sb or sa == DEGRADED or sb == DEGRADED
    return status, distance, flag


def disagreement(sa: int, sb: int) -> bool:
    """Channels contradict each other: one sees an obstacle, the other sees none.

    post: __return__ == ((sa == 0 and sb == 1) or (sa == 1 and sb == 0))
    """
    return (sa == ABSENT and sb == PRESENT) or (sa == PRESENT and sb == ABSENT)


def distances_disagree(sa: int, da: int, sb: int, db: int, tolerance_dm: int) -> bool:
    """Both channels see the obstacle but more than `tolerance_dm` apart: one of them is
    wrong (a stuck value, a noise burst), so the module must raise its flag.

    pre: tolerance_dm >= 0
    post: __return__ == (sa == 1 and sb == 1 and (da - db > tolerance_dm or db - da > tolerance_dm))
    """
    return sa == PRESENT and sb == PRESENT and (da - db > tolerance_dm or db - da > tolerance_dm)


def vote_3oo3(s1: int, d1: int, f1: bool, s2: int, d2: int, f2: bool, s3: int, d3: int, f3: bool) -> tuple[int, int, bool]:
    """(status, distance, error) of the system from three module results.

    A module's distance is that of its PRESENT channel(s), NO_DISTANCE (65535) if none, so
    a fresh obstacle keeps its distance even when the module is DEGRADED because its
    partner channel is stale: the envelope still sees it.
    pre: 0 <= s1 <= 2 and 0 <= s2 <= 2 and 0 <= s3 <= 2
    pre: 0 <= d1 <= 65535 and 0 <= d2 <= 65535 and 0 <= d3 <= 65535
    post: __return__[0] == max(s1, s2, s3)
    post: __return__[2] == (f1 or f2 or f3 or s1 != s2 or s2 != s3 or max(s1, s2, s3) == 2)
    post: not (s1 != s2 or s2 != s3) or __return__[2]
    post: __return__[1] == min(d1, d2, d3)
    """
    status = max(s1, s2, s3)
    distance = d1
    if d2 < distance:
        distance = d2
    if d3 < distance:
        distance = d3
    error = f1 or f2 or f3 or s1 != s2 or s2 != s3 or status == DEGRADED
    return status, distance, error


def vote_single(s: int, d: int, f: bool) -> tuple[int, int, bool]:
    """The system result of a one-module (2oo2) topology: the module's flag is the error.

    pre: 0 <= s <= 2 and 0 <= d <= 65535
    post: __return__[0] == s
    post: __return__[2] == (f or s == 2)
    post: __return__[1] == d
    """
    return s, d, f or s == DEGRADED
