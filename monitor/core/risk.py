"""The papers' risk estimators, live, in integers (parts per million) that C computes alike.

- R1, seed 000 eq. 16: R1 = 1 - 1 / (1 + exp(-5 d / alpha1)) = 1 / (1 + exp(5 d / alpha1));
- R2, seed 000 eq. 17: R2 = (alpha1 - d) / (alpha1 - alpha2), clipped to [0, 1];
- rho and its category, seed 001 eq. 11: rho = 3 distance + 2 speed + 2 obstacle + track
  + 2 brake (levels from 0), low <= 7 < moderate <= 11 < high <= 15 < critical.

alpha1 and alpha2 are the monitor's own zone limits (cycle._zone_limits: alpha2 = EBI, alpha1
= the service brake's EBI, both under normal conditions), the same distances that cut the
table's observation into zones, so R2 reaches 1 where the table sees "critical" and R1 is
0.5 at the obstacle. exp has no integer form: e^(-k/1024) is a Q30 power of one rounded
constant (repeated squaring, at most 14 squarings), linearly interpolated between
neighbouring k; against eq. 16 in floats the result is within 1 ppm (tests/test_risk.py).
"""
from __future__ import annotations

PPM = 1_000_000
Q = 30
ONE = 1 << Q
EXP_STEP = 1072693760           # round(exp(-1/1024) * 2^30)
STEPS_PER_UNIT = 1024           # k = 5 d / alpha1 in 1/1024
K_LIMIT = 16 * STEPS_PER_UNIT   # 5 d / alpha1 >= 16: R1 < 0.12 ppm, reported 0
FINE = 10                       # R1 interpolated in 1/1024 ppm
LOW, MODERATE, HIGH, CRITICAL = 1, 2, 3, 4
CATEGORY_NAMES = ("low", "moderate", "high", "critical")     # categories 1..4
MAX_SCORE = 3 * 3 + 2 * 2 + 2 * 2 + 1 + 2


def exp_neg_q30(k: int) -> int:
    """e^(-k/1024) in Q30 (floored at every product), for 0 <= k <= 16384: positive, at most
    2^30 and never increasing in k, checked for every k (tests/test_risk.py: the products are beyond
    CrossHair's solver)."""
    result, base = ONE, EXP_STEP
    while k:
        if k & 1:
            result = (result * base) >> Q
        base = (base * base) >> Q
        k >>= 1
    return result


def _r1_fine(q: int) -> int:
    """1 / (1 + e^(k/1024)) in 1/1024 ppm from q = e^(-k/1024) in Q30: 2^10 10^6 q / (2^30 + q)."""
    return ((PPM << FINE) * q) // (ONE + q)


def r1_ppm(distance_dm: int, alpha1_dm: int) -> int:
    """Seed 000 eq. 16 in ppm: 500,000 at the obstacle, falling to 0 at 3.2 alpha1 (its limit
    for alpha1 -> 0 where the curves give no distance at all: a receding obstacle, standstill).
    Within 1 ppm of the equation in floats, and in [0, 500,000], on tests/test_risk.py's grid."""
    if alpha1_dm <= 0:
        return PPM // 2 if distance_dm == 0 else 0
    num = 5 * STEPS_PER_UNIT * distance_dm
    k, rem = num // alpha1_dm, num % alpha1_dm
    if k >= K_LIMIT:
        return 0
    q = exp_neg_q30(k)
    here, there = _r1_fine(q), _r1_fine((q * EXP_STEP) >> Q)      # k and k + 1
    return (here - ((here - there) * rem) // alpha1_dm + (1 << (FINE - 1))) >> FINE


def r2_ppm(distance_dm: int, alpha1_dm: int, alpha2_dm: int) -> int:
    """Seed 000 eq. 17 in ppm, clipped to [0, 10^6], rounded up (the safe side).

    pre: distance_dm >= 0 and alpha1_dm >= alpha2_dm >= 0
    post: 0 <= __return__ <= 1000000
    """
    if distance_dm <= alpha2_dm:
        return PPM
    if distance_dm >= alpha1_dm:
        return 0
    span = alpha1_dm - alpha2_dm
    return ((alpha1_dm - distance_dm) * PPM + span - 1) // span


def risk_score(zone: int, speed: int, obstacle: int, track: int, brake: int) -> int:
    """Seed 001 eq. 11: rho = 3 alpha + 2 beta + 2 phi + psi + 2 omega.

    pre: 0 <= zone <= 3 and 0 <= speed <= 2 and 0 <= obstacle <= 2 and 0 <= track <= 1 and 0 <= brake <= 1
    post: 0 <= __return__ <= 20
    """
    return 3 * zone + 2 * speed + 2 * obstacle + track + 2 * brake


def risk_category(score: int) -> int:
    """Seed 001's categories: 1 low (<= 7), 2 moderate (8-11), 3 high (12-15), 4 critical.

    post: 1 <= __return__ <= 4
    """
    if score <= 7:
        return LOW
    if score <= 11:
        return MODERATE
    if score <= 15:
        return HIGH
    return CRITICAL
