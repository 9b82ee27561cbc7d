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


def latch(latched: bool, calm: int, demand: int, speed_cms: int, revocable: bool, confirm: int) -> tuple[bool, int, int]:
    """(latched, calm, demand): an emergency, once demanded, is held until standstill or, if
    `revocable`, until its cause has been gone for `confirm` cycles in a row (`calm`
    counts them), as ETCS does by national value.

    pre: 0 <= demand <= 2 and speed_cms >= 0 and confirm >= 1 and calm >= 0
    post: __return__[2] >= demand
    post: not (demand == 2 and speed_cms > 0) or (__return__[0] and __return__[1] == 0)
    post: not (speed_cms == 0) or __return__ == (False, 0, demand)
    post: not (latched and speed_cms > 0 and not revocable) or __return__[0]
    post: not (latched and speed_cms > 0 and calm + 1 < confirm) or __return__[0]
    post: __return__[2] == (2 if __return__[0] else demand)
    post: __return__[1] < confirm and (revocable or __return__[1] == 0)
    """
    held = (latched or demand == EMERGENCY) and speed_cms > 0
    calm = calm + 1 if held and revocable and demand != EMERGENCY else 0
    if held and revocable and calm >= confirm:
        held, calm = False, 0
    return held, calm, (EMERGENCY if held else demand)
