"""Hard rules that the policy table cannot override: braking distances, zones, the
emergency envelope, combination of demands (only ever upwards) and the emergency latch."""
from __future__ import annotations

from .types import EMERGENCY, MAINTAIN


def braking_distance_dm(speed_cms: int, decel_mms2: int, reaction_ms: int) -> int:
    """d(v) = v^2 / (2a) + v t_r in decimetres, rounded up (the safe side).

    With v in cm/s and a in mm/s^2, v^2/(2a) is already in dm; v t_r is v * t_r / 10^4 dm.
    pre: 0 <= speed_cms <= 12000 and 1 <= decel_mms2 <= 20000 and 0 <= reaction_ms <= 60000
    post: __return__ >= 0
    post: __return__ * 2 * decel_mms2 * 10000 >= speed_cms * speed_cms * 10000 + 2 * decel_mms2 * speed_cms * reaction_ms
    post: (__return__ - 1) * 2 * decel_mms2 * 10000 < speed_cms * speed_cms * 10000 + 2 * decel_mms2 * speed_cms * reaction_ms or __return__ == 0
    """
    num = speed_cms * speed_cms * 10000 + 2 * decel_mms2 * speed_cms * reaction_ms
    den = 2 * decel_mms2 * 10000
    return -(-num // den)


def zone(distance_dm: int, alpha1_dm: int, alpha2_dm: int, warning_dm: int) -> int:
    """Zone of an obstacle: 0 free, 1 warning, 2 emergency, 3 critical (seed 000 eq. 3).

    pre: 0 <= alpha2_dm <= alpha1_dm and warning_dm >= 0 and distance_dm >= 0
    post: 0 <= __return__ <= 3
    post: (__return__ == 3) == (distance_dm <= alpha2_dm)
    post: (__return__ >= 2) == (distance_dm <= alpha1_dm)
    post: (__return__ >= 1) == (distance_dm <= alpha1_dm + warning_dm)
    """
    if distance_dm <= alpha2_dm:
        return 3
    if distance_dm <= alpha1_dm:
        return 2
    if distance_dm <= alpha1_dm + warning_dm:
        return 1
    return 0


def envelope_demand(obstacle_present: bool, distance_dm: int, alpha2_dm: int) -> int:
    """Emergency braking when a voted obstacle is inside the emergency braking distance.

    post: __return__ == (2 if obstacle_present and distance_dm <= alpha2_dm else 0)
    """
    return EMERGENCY if obstacle_present and distance_dm <= alpha2_dm else MAINTAIN


def combine(table_demand: int, envelope: int, error_demand: int) -> int:
    """The demand sent: rules can only raise the table's demand, never lower it.

    pre: 0 <= table_demand <= 2 and 0 <= envelope <= 2 and 0 <= error_demand <= 2
    post: __return__ >= envelope and __return__ >= table_demand and __return__ >= error_demand
    post: __return__ in (table_demand, envelope, error_demand)
    """
    return max(table_demand, envelope, error_demand)


def latch(latched: bool, demand: int, speed_cms: int) -> tuple[bool, int]:
    """(latched, demand): emergency, once demanded, is held until standstill (as ETCS does).

    pre: 0 <= demand <= 2 and speed_cms >= 0
    post: not (latched and speed_cms > 0) or __return__ == (True, 2)
    post: not (demand == 2 and speed_cms > 0) or __return__[0]
    post: __return__[1] >= demand
    post: not (speed_cms == 0) or __return__ == (False, demand)
    """
    held = (latched or demand == EMERGENCY) and speed_cms > 0
    return held, (EMERGENCY if held else demand)
