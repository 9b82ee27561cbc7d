"""Hard rules that the policy table cannot override: the table's zones, the supervision
ladder on the braking curves (warning, service at SBI, emergency at EBI), combination of
demands (only ever upwards) and the emergency latch with its release."""
from __future__ import annotations

from .types import EMERGENCY, MAINTAIN, SERVICE


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


def supervision_demand(present: bool, distance_dm: int, ebi_dm: int, sbi_dm: int, warning_dm: int,
                       held: bool) -> tuple[int, bool]:
    """(demand, warning) of the braking curves for the voted obstacle: emergency inside EBI
    (while an emergency is held, inside SBI: the obstacle must be back beyond SBI before
    the cause is gone), service inside SBI, a warning inside the warning curve.

    pre: 0 <= ebi_dm <= sbi_dm <= warning_dm
    post: not present or distance_dm > ebi_dm or __return__[0] == 2
    post: not present or distance_dm > sbi_dm or __return__[0] >= 1
    post: not (held and present and distance_dm <= sbi_dm) or __return__[0] == 2
    post: present or __return__ == (0, False)
    post: __return__[1] == (present and distance_dm <= warning_dm)
    post: not (present and distance_dm > sbi_dm) or __return__[0] == 0
    post: held or not present or distance_dm <= ebi_dm or __return__[0] <= 1
    """
    if not present:
        return MAINTAIN, False
    if distance_dm <= ebi_dm or (held and distance_dm <= sbi_dm):
        return EMERGENCY, True
    if distance_dm <= sbi_dm:
        return SERVICE, True
    return MAINTAIN, distance_dm <= warning_dm


def combine(table_demand: int, envelope: int, error_demand: int) -> int:
    """The demand sent: rules can only raise the table's demand, never lower it.

    pre: 0 <= table_demand <= 2 and 0 <= envelope <= 2 and 0 <= error_demand <= 2
    post: __return__ >= envelope and __return__ >= table_demand and __return__ >= error_demand
    post: __return__ in (table_demand, envelope, error_demand)
    """
    return max(table_demand, envelope, error_demand)


def hold(level: int, calm: int, demand: int, speed_cms: int, revocable: bool, confirm: int) -> tuple[int, int, int]:
    """(level, calm, demand): a demand, once raised, is held while the train moves and is
    lowered only after the causes have asked for less for `confirm` cycles in a row (`calm`
    counts them); an emergency only if `revocable` (ETCS's national value), else at
    standstill. The causes include every remembered obstacle's curves (cycle.py), so a
    demand a curve raised is never lowered while the train is inside that curve.

    pre: 0 <= level <= 2 and 0 <= demand <= 2 and speed_cms >= 0 and confirm >= 1 and calm >= 0
    post: __return__[2] >= demand
    post: __return__[2] == __return__[0]
    post: not (speed_cms == 0) or __return__ == (demand, 0, demand)
    post: not (demand == 2) or __return__ == (2, 0, 2)
    post: not (level == 2 and speed_cms > 0 and not revocable) or __return__[0] == 2
    post: not (speed_cms > 0 and calm + 1 < confirm) or __return__[0] >= level
    post: __return__[0] in (level, demand)
    post: __return__[1] < confirm and (__return__[1] == 0 or __return__[1] == calm + 1)
    """
    if speed_cms == 0 or demand >= level:
        return demand, 0, demand
    if level == EMERGENCY and not revocable:
        return level, 0, level
    if calm + 1 >= confirm:
        return demand, 0, demand
    return level, calm + 1, level


def keep_held(demand: int, level: int, speed_cms: int, keep: bool) -> int:
    """What the hold is asked for: the causes' demand, or, while `keep` (an obstacle in sight,
    in the table's zones, closing in) and the train moves, at least the level held, so that
    nothing is lowered only to be raised again nearer the obstacle.

    pre: 0 <= demand <= 2 and 0 <= level <= 2 and speed_cms >= 0
    post: __return__ >= demand
    post: __return__ in (demand, level)
    post: not (keep and speed_cms > 0) or __return__ >= level
    post: (keep and speed_cms > 0) or __return__ == demand
    """
    return level if keep and speed_cms > 0 and demand < level else demand


def table_hold(level: int, demand: int, speed_cms: int, zone_free: bool) -> int:
    """The table's demand after its hold: what the table raised is lowered only once the
    voted picture has left the table's zones (`zone_free`: observed zone 0), or at
    standstill, so that a table whose belief wavers at low speed does not toggle the brake
    (issue 29 item 6). A remembered obstacle no channel shows is left to the curves: the
    table acts on what is seen, and a one-cycle phantom does not hold its demand.

    pre: 0 <= level <= 2 and 0 <= demand <= 2 and speed_cms >= 0
    post: __return__ >= demand
    post: __return__ in (level, demand)
    post: not (speed_cms > 0 and not zone_free) or __return__ >= level
    post: not (speed_cms == 0 or zone_free) or __return__ == demand
    """
    if demand >= level or speed_cms == 0 or zone_free:
        return demand
    return level
