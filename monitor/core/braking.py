"""Braking curves from the train's *guaranteed* braking (ETCS SUBSET-026 section 3.13,
translated to an obstacle ahead; docs/supervision.md derives every term).

All distances are distances to the obstacle, in dm, for the current measured speed. Each
term is rounded to the safe side on its own (distances and speeds up, decelerations
down), so the sum is never shorter than the exact value.

* EBD: the guaranteed emergency deceleration (speed bands, adhesion factors, downhill
  gradient) stops the train `standstill_margin_dm` before the obstacle.
* The error budget (every supervised curve): the obstacle may be `distance_accuracy_dm`
  nearer than reported and close `closing_accuracy_cms` faster than measured.
* EBI: EBD moved for the speed error, the report's age, four monitor periods (a stalled
  monitor's: its last demand's way to the brakes and their receiver's timeout; see
  SUPERVISED_PERIODS), traction until
  it is cut (accelerating at `max_accel` plus the gradient) and the brake's equivalent
  build-up time (coasting downhill). An oncoming obstacle keeps closing at its own speed
  until the train stands.
* SBI: EBI plus the distance run during the service brake's build-up.
* Warning: SBI plus `warning_ms` of travel.
"""
from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

from .config import Config, emergency_bands, gradient_accel_mms2

CURVE_CAP_DM = 1_000_000        # 100 km: saturate here (every obstacle in range is inside)
# Periods in EBI's reaction phase, after the last cycle that found the train outside EBI. A
# running monitor samples once a period, so the first cycle inside may come a period later,
# and its demand takes a period to the brakes: 2. A monitor that stalls (hangs, crashes,
# overruns) after that cycle sends nothing newer; its last BrakeDemand takes a period and the
# brakes' receiver brakes once it is 3 periods old (can_bus/brake_receiver.py; a late cycle
# sends none below emergency, can_bus/runner.py): 4, the worse, whatever max_overruns lets
# pass. The table's zone limits count the demand's period only: they are where an emergency
# must be commanded, and the POMDP the table was solved for steps at the period itself (its
# own step is the sampling), so they stay the models' zones.
SUPERVISED_PERIODS = 4
ZONE_PERIODS = 1


class Curves(NamedTuple):
    ebd_dm: int
    ebi_dm: int
    sbi_dm: int
    warning_dm: int


def scaled_decel_mms2(decel_mms2: int, factor_permille: int) -> int:
    """A deceleration times a factor <= 1, rounded down (weaker is the safe side).

    pre: 0 <= decel_mms2 <= 20000 and 0 <= factor_permille <= 1000
    post: 0 <= __return__ <= decel_mms2
    post: __return__ * 1000 <= decel_mms2 * factor_permille
    """
    return decel_mms2 * factor_permille // 1000


def effective_decel_mms2(decel_mms2: int, track: int, brake: int, slippery_permille: int, degraded_permille: int,
                         gradient_mms2: int) -> int:
    """The guaranteed deceleration under the reported conditions, less the downhill pull.

    pre: 0 <= decel_mms2 <= 20000 and track in (0, 1) and brake in (0, 1)
    pre: 1 <= slippery_permille <= 1000 and 1 <= degraded_permille <= 1000 and 0 <= gradient_mms2 <= 1000
    post: __return__ <= decel_mms2 - gradient_mms2
    post: __return__ >= -gradient_mms2
    post: not (track == 0 and brake == 0) or __return__ == decel_mms2 - gradient_mms2
    """
    a = scaled_decel_mms2(decel_mms2, slippery_permille) if track else decel_mms2
    a = scaled_decel_mms2(a, degraded_permille) if brake else a
    return a - gradient_mms2


def run_dm(speed_cms: int, accel_mms2: int, time_ms: int) -> int:
    """Distance run in `time_ms` from `speed_cms` accelerating at `accel_mms2`, in dm,
    rounded up: v t + a t^2 / 2 (cm/s x ms = 1e-5 m; mm/s^2 x ms^2 = 1e-9 m).

    pre: 0 <= speed_cms <= 1000000 and 0 <= accel_mms2 <= 10000 and 0 <= time_ms <= 200000
    post: __return__ >= 0
    post: __return__ * 200000000 >= 2 * speed_cms * time_ms * 10000 + accel_mms2 * time_ms * time_ms
    """
    num = 2 * speed_cms * time_ms * 10000 + accel_mms2 * time_ms * time_ms
    return -(-num // 200000000)


def speed_after_cms(speed_cms: int, accel_mms2: int, time_ms: int) -> int:
    """Speed after accelerating at `accel_mms2` for `time_ms`, rounded up.

    pre: 0 <= speed_cms <= 1000000 and 0 <= accel_mms2 <= 10000 and 0 <= time_ms <= 200000
    post: __return__ >= speed_cms
    post: (__return__ - speed_cms) * 10000 >= accel_mms2 * time_ms
    """
    return speed_cms - (-accel_mms2 * time_ms // 10000)


def band_stop(speed_cms: int, lo_cms: int, hi_cms: int, decel_mms2: int) -> tuple[int, int]:
    """(distance dm, time ms), both rounded up, spent braking at `decel_mms2` through the
    part of the speed band [lo, hi) below `speed_cms` (hi < 0: no upper end).

    pre: 0 <= speed_cms <= 1000000 and 0 <= lo_cms and 1 <= decel_mms2 <= 20000
    post: __return__[0] >= 0 and __return__[1] >= 0
    """
    top = speed_cms if hi_cms < 0 or speed_cms < hi_cms else hi_cms
    if top <= lo_cms:
        return 0, 0
    dist = -(-(top * top - lo_cms * lo_cms) // (2 * decel_mms2))      # (cm/s)^2 / (mm/s^2) = dm
    time = -(-(top - lo_cms) * 10000 // decel_mms2)                   # (cm/s) / (mm/s^2) = 10 s
    return dist, time


def stop_dm_ms(speed_cms: int, bands: tuple) -> tuple[int, int]:
    """(distance dm, time ms) to stop from `speed_cms` through ((from_cms, decel), ...)."""
    dist = time = 0
    for i, (lo, a) in enumerate(bands):
        hi = bands[i + 1][0] if i + 1 < len(bands) else -1
        d, t = band_stop(speed_cms, lo, hi, a)
        dist += d
        time += t
    return dist, time


def obstacle_run_dm(obstacle_cms: int, time_ms: int) -> int:
    """Distance an oncoming obstacle closes in `time_ms`, rounded up (0 if not oncoming).

    pre: 0 <= time_ms <= 10000000
    post: __return__ >= 0
    post: obstacle_cms <= 0 or __return__ * 10000 >= obstacle_cms * time_ms
    """
    if obstacle_cms <= 0:
        return 0
    return -(-obstacle_cms * time_ms // 10000)


def _cap(x: int) -> int:
    return x if x < CURVE_CAP_DM else CURVE_CAP_DM


@lru_cache(maxsize=256)
def _brake(cfg: Config, track: int, brake: int, service: bool) -> tuple:
    """(bands under the conditions, equivalent build-up ms, g x gradient): what the curves
    need of the declaration, worked out once per configuration and condition (pure)."""
    g = gradient_accel_mms2(cfg.max_gradient_permille)
    raw = ((0, cfg.service_decel_mms2),) if service else emergency_bands(cfg)
    bands = tuple((lo, effective_decel_mms2(a, track, brake, cfg.slippery_permille, cfg.degraded_permille, g))
                  for lo, a in raw)
    return bands, (cfg.service_buildup_ms if service else cfg.emergency_buildup_ms), g


def _intervention(cfg: Config, speed_cms: int, track: int, brake: int, closing_cms: int, age_ms: int,
                  service: bool, periods: int) -> tuple[int, int, int, tuple]:
    """(EBI dm uncapped, v_max, the obstacle's own speed, bands): the three phases of
    docs/supervision.md section 2 (report age + `periods` monitor periods + traction cut-off,
    under traction and downhill; the rest of the build-up coasting downhill; guaranteed
    braking)."""
    e = cfg.speed_error_permille
    v_max = -(-speed_cms * (1000 + e) // 1000)
    obstacle_cms = closing_cms - speed_cms * (1000 - e) // 1000     # the obstacle's own speed towards us
    bands, buildup, g = _brake(cfg, track, brake, service)
    t1 = age_ms + periods * cfg.period_ms + cfg.traction_cutoff_ms
    a1 = cfg.max_accel_mms2 + g
    s1, v1 = run_dm(v_max, a1, t1), speed_after_cms(v_max, a1, t1)
    t2 = buildup - cfg.traction_cutoff_ms if buildup > cfg.traction_cutoff_ms else 0
    s2, v2 = run_dm(v1, g, t2), speed_after_cms(v1, g, t2)
    s3, t3 = stop_dm_ms(v2, bands)
    ebi = s1 + s2 + s3 + cfg.standstill_margin_dm + obstacle_run_dm(obstacle_cms, t1 + t2 + t3)
    return ebi, v_max, obstacle_cms, bands


def ebi_dm(cfg: Config, speed_cms: int, track: int, brake: int, closing_cms: int, age_ms: int,
           service: bool = False) -> int:
    """EBI as the table's zone limit: where an emergency must be commanded, without the
    supervision's sampling period (ZONE_PERIODS); the models' zones (offline/models/zones.py)."""
    return _cap(_intervention(cfg, speed_cms, track, brake, closing_cms, age_ms, service, ZONE_PERIODS)[0])


def curves(cfg: Config, speed_cms: int, track: int, brake: int, closing_cms: int, age_ms: int,
           service: bool = False) -> Curves:
    """EBD, EBI, SBI and warning distances at a measured speed, for the reported track and
    brake conditions, the obstacle's closing speed (`closing_cms`; none: pass the train's
    speed) and the age of the report the distance came from.

    Every curve counts the sensors' declared accuracy (the error budget, docs/supervision.md
    2.6); the zone limits (`ebi_dm`) do not: they place the table's observation, and the
    supervised curves are the floor under whatever the table decides.

    With `service`, the same construction for the service brake (its guaranteed
    deceleration and build-up); the table's alpha1 is its zone limit, `ebi_dm(..., service=True)`."""
    # the error budget: the obstacle may be `distance_accuracy_dm` nearer than reported and
    # close `closing_accuracy_cms` faster than measured (the sensors' declared accuracy)
    ebi, v_max, obstacle_cms, bands = _intervention(cfg, speed_cms, track, brake,
                                                    closing_cms + cfg.closing_accuracy_cms, age_ms, service,
                                                    SUPERVISED_PERIODS)
    ebi += cfg.distance_accuracy_dm
    ebd_dist, ebd_time = stop_dm_ms(speed_cms, bands)
    ebd = ebd_dist + cfg.standstill_margin_dm + cfg.distance_accuracy_dm + obstacle_run_dm(obstacle_cms, ebd_time)
    lead_cms = v_max + (obstacle_cms if obstacle_cms > 0 else 0)
    sbi = ebi + run_dm(lead_cms, 0, cfg.service_buildup_ms)
    warning = sbi + run_dm(lead_cms, 0, cfg.warning_ms)
    return Curves(_cap(ebd), _cap(ebi), _cap(sbi), _cap(warning))
