"""The monitor core vectorised over many trains at once (numpy), for Monte Carlo runs.

It covers the case the papers simulate: one perception source whose report every channel
repeats (all channels fresh, in range and agreeing, the train input valid), so the voters
pass the picture through and no error rule fires; and, with the `modules` input, the same
picture seen by some modules only (both channels of a module alike, the others ABSENT): a
dispute between modules, answered by the curves, a warning and the table held at its node,
and remembered by the memory (issue 38 item 1); and each module's plausibility (issue 38
item 3, monitor.core.plausibility: its channels report alike, so one story per module): a
module whose distance does not shrink as its closing speed says is DEGRADED, a system error
that is no dispute (the safe reaction, the table held, no forgetting evidence, reasons
stale and implausible). What remains of a cycle is computed here
with the same integer formulas as monitor/core, written again on arrays: the braking curves
of `monitor.core.braking` (EBD, EBI, SBI, warning: every term rounded to the safe side), the
table's zones under normal conditions, the observation, the table step, the obstacle memory
of `monitor.core.memory` and `monitor.core.tracks` (verification/fasttracks.py: up to TRACKS remembered obstacles a
train, nearest first: a PRESENT picture measures the nearest track whose window holds it, a
confirmed one also absorbing the farther ones it measures, or is remembered beside them,
the two farthest merged when every slot is held; a confirmed picture beyond a track, and an
ABSENT one with all channels fresh, are evidence that it is gone: each track is predicted
worst case each cycle, forgotten after `forget_cycles` of evidence inside `sensor_range_dm`,
or once passed), the supervision ladder (warning, service at SBI, emergency at EBI, held
inside SBI) on the voted and every remembered obstacle, the table's hold (its demand kept while the
voted picture is in the table's zones), the hold of the demand sent (lowered after
`release_confirm_cycles` cycles asking for less; an emergency only if revocable; released at
standstill) and the reason bits. `agrees_with_core` replays sampled trains through the real
`monitor.core.cycle.step` and compares every output: the Monte Carlo figures are only as
good as that check, which `railguard verify` runs every time and tests/test_fastcore.py
runs on 10,000 random sequences.
"""
from __future__ import annotations

from typing import NamedTuple, Optional

import numpy as np

from monitor.core import cycle, risk
from monitor.core.braking import CURVE_CAP_DM, SUPERVISED_PERIODS, ZONE_PERIODS
from monitor.core.config import RELEASE_REVOCABLE, Config, emergency_bands, gradient_accel_mms2
from monitor.core.memory import UNITS_PER_DM
from monitor.core.types import (
    ABSENT, EMERGENCY, MAINTAIN, NO_DISTANCE, NO_TRACK, NORMAL, PRESENT, R_DISPUTE, R_ENVELOPE, R_LATCH,
    R_IMPLAUSIBLE, R_MEMORY, R_SBI, R_STALE, R_SYSTEM_ERROR, R_TABLE, R_WARNING, SERVICE, STATIC, TRACK_SEEN, TRACKS, Inputs, Report, Train,
)
from verification.fasttracks import TrackMemory, any_slot

I64 = np.int64
OUTPUT_KEYS = ("demand", "reasons", "distance_dm", "node", "observation", "warning", "track_dm", "track_cycles",
               "track_state", "r1_ppm", "r2_ppm", "risk_score", "risk_category", "table_risk_ppm")
# `modules`: bit m set if module m sees the obstacle (None: every module, where present)
INPUT_KEYS = ("present", "distance_dm", "speed_cms", "closing_cms", "obstacle", "track", "brake", "age_ms",
              "modules")


class Curves(NamedTuple):
    """monitor.core.braking.Curves with an array in each field."""

    ebd_dm: np.ndarray
    ebi_dm: np.ndarray
    sbi_dm: np.ndarray
    warning_dm: np.ndarray


def _ceil_div(num: np.ndarray, den) -> np.ndarray:
    return -(-num // den)


def run_dm(speed_cms, accel_mms2, time_ms) -> np.ndarray:
    """braking.run_dm on arrays: v t + a t^2 / 2 in dm, rounded up."""
    return _ceil_div(2 * speed_cms * time_ms * 10000 + accel_mms2 * time_ms * time_ms, 200000000)


def speed_after_cms(speed_cms, accel_mms2, time_ms) -> np.ndarray:
    """braking.speed_after_cms on arrays: v + a t, rounded up."""
    return speed_cms + _ceil_div(accel_mms2 * time_ms, 10000)


def band_stop(speed_cms, lo_cms: int, hi_cms: int, decel_mms2) -> tuple[np.ndarray, np.ndarray]:
    """braking.band_stop on arrays: (dm, ms) braking through [lo, hi) below the speed."""
    top = speed_cms if hi_cms < 0 else np.minimum(speed_cms, hi_cms)
    inside = top > lo_cms
    dist = _ceil_div(top * top - lo_cms * lo_cms, 2 * decel_mms2)
    time = _ceil_div((top - lo_cms) * 10000, decel_mms2)
    return np.where(inside, dist, 0), np.where(inside, time, 0)


def effective_decel(cfg: Config, decel_mms2: int, track, brake, gradient_mms2: int) -> np.ndarray:
    """braking.effective_decel_mms2 on arrays: the factors of the reported conditions, less the downhill pull."""
    a = np.where(track != 0, decel_mms2 * cfg.slippery_permille // 1000, decel_mms2)
    a = np.where(brake != 0, a * cfg.degraded_permille // 1000, a)
    return a - gradient_mms2


def obstacle_run_dm(obstacle_cms, time_ms) -> np.ndarray:
    """braking.obstacle_run_dm on arrays: what an oncoming obstacle closes, rounded up."""
    return np.where(obstacle_cms > 0, _ceil_div(obstacle_cms * time_ms, 10000), 0)


def curves(cfg: Config, speed_cms, track, brake, closing_cms, age_ms, service: bool = False,
           supervised: bool = True) -> Curves:
    """monitor.core.braking.curves on int64 arrays (one element per train), with the sensors'
    error budget; `supervised=False` gives braking.ebi_dm's zone limits (ZONE_PERIODS, no budget)."""
    periods = SUPERVISED_PERIODS if supervised else ZONE_PERIODS
    near_dm = cfg.distance_accuracy_dm if supervised else 0
    v = np.asarray(speed_cms, dtype=I64)
    track, brake = np.asarray(track, dtype=I64), np.asarray(brake, dtype=I64)
    closing, age = np.asarray(closing_cms, dtype=I64), np.asarray(age_ms, dtype=I64)
    e = cfg.speed_error_permille
    v_max = _ceil_div(v * (1000 + e), 1000)
    v_min = v * (1000 - e) // 1000
    obstacle = closing + (cfg.closing_accuracy_cms if supervised else 0) - v_min
    g = gradient_accel_mms2(cfg.max_gradient_permille)
    raw = ((0, cfg.service_decel_mms2),) if service else emergency_bands(cfg)
    buildup = cfg.service_buildup_ms if service else cfg.emergency_buildup_ms
    bands = [(lo, effective_decel(cfg, a, track, brake, g)) for lo, a in raw]
    t1 = age + periods * cfg.period_ms + cfg.traction_cutoff_ms
    a1 = cfg.max_accel_mms2 + g
    s1, v1 = run_dm(v_max, a1, t1), speed_after_cms(v_max, a1, t1)
    t2 = max(buildup - cfg.traction_cutoff_ms, 0)
    s2, v2 = run_dm(v1, g, t2), speed_after_cms(v1, g, t2)
    s3, t3 = _stop(v2, bands)
    ebi = s1 + s2 + s3 + cfg.standstill_margin_dm + near_dm + obstacle_run_dm(obstacle, t1 + t2 + t3)
    ebd_dist, ebd_time = _stop(v, bands)
    ebd = ebd_dist + cfg.standstill_margin_dm + near_dm + obstacle_run_dm(obstacle, ebd_time)
    lead = v_max + np.maximum(obstacle, 0)
    sbi = ebi + run_dm(lead, 0, cfg.service_buildup_ms)
    warning = sbi + run_dm(lead, 0, cfg.warning_ms)
    return Curves(*(np.minimum(x, CURVE_CAP_DM) for x in (ebd, ebi, sbi, warning)))


def _stop(speed_cms, bands: list) -> tuple[np.ndarray, np.ndarray]:
    """braking.stop_dm_ms on arrays: bands are (from_cms, decel array) lowest first."""
    dist = np.zeros_like(speed_cms)
    time = np.zeros_like(speed_cms)
    for i, (lo, a) in enumerate(bands):
        hi = bands[i + 1][0] if i + 1 < len(bands) else -1
        d, t = band_stop(speed_cms, lo, hi, a)
        dist, time = dist + d, time + t
    return dist, time


def zone_alphas(cfg: Config, speed_cms, closing_cms, age_ms) -> tuple[np.ndarray, np.ndarray]:
    """(alpha1, alpha2) of the table's zones as the core cuts them: alpha2 = EBI under normal
    conditions, alpha1 = the service curve's EBI under normal conditions, at least alpha2,
    both as zone limits (ZONE_PERIODS: without the supervision's sampling period)."""
    zero = np.zeros_like(np.asarray(speed_cms, dtype=I64))
    alpha2 = curves(cfg, speed_cms, zero, zero, closing_cms, age_ms, supervised=False).ebi_dm
    alpha1 = curves(cfg, speed_cms, zero, zero, closing_cms, age_ms, service=True, supervised=False).ebi_dm
    return np.maximum(alpha1, alpha2), alpha2


def zone_of(distance_dm, alpha1_dm, alpha2_dm, warning_dm: int) -> np.ndarray:
    """envelope.zone on arrays: 0 free, 1 warning, 2 emergency, 3 critical (seed 000 eq. 3)."""
    return np.where(distance_dm <= alpha2_dm, 3, np.where(distance_dm <= alpha1_dm, 2,
                                                          np.where(distance_dm <= alpha1_dm + warning_dm, 1, 0)))


def r1_ppm(distance_dm, alpha1_dm) -> np.ndarray:
    """monitor.core.risk.r1_ppm on arrays (seed 000 eq. 16), the same integer steps."""
    d, a = np.asarray(distance_dm, dtype=I64), np.asarray(alpha1_dm, dtype=I64)
    safe_a = np.where(a > 0, a, 1)
    num = 5 * risk.STEPS_PER_UNIT * d
    k, rem = num // safe_a, num % safe_a
    k = np.minimum(k, risk.K_LIMIT)

    q, base, bits = np.full(k.shape, risk.ONE, dtype=I64), np.full(k.shape, risk.EXP_STEP, dtype=I64), k.copy()
    while bits.any():                                   # risk.exp_neg_q30
        q = np.where(bits & 1, (q * base) >> risk.Q, q)
        base = (base * base) >> risk.Q
        bits >>= 1

    def fine(q):
        return ((risk.PPM << risk.FINE) * q) // (risk.ONE + q)

    here, there = fine(q), fine((q * risk.EXP_STEP) >> risk.Q)
    r = (here - ((here - there) * rem) // safe_a + (1 << (risk.FINE - 1))) >> risk.FINE
    r = np.where(k >= risk.K_LIMIT, 0, r)
    return np.where(a > 0, r, np.where(d == 0, risk.PPM // 2, 0))


def r2_ppm(distance_dm, alpha1_dm, alpha2_dm) -> np.ndarray:
    """monitor.core.risk.r2_ppm on arrays (seed 000 eq. 17, rounded up, clipped)."""
    d, a1, a2 = (np.asarray(x, dtype=I64) for x in (distance_dm, alpha1_dm, alpha2_dm))
    span = np.maximum(a1 - a2, 1)
    return np.where(d <= a2, risk.PPM, np.where(d >= a1, 0, ((a1 - d) * risk.PPM + span - 1) // span))


def risk_category(score) -> np.ndarray:
    return np.select([score <= 7, score <= 11, score <= 15], [risk.LOW, risk.MODERATE, risk.HIGH], risk.CRITICAL)


def supervision(present, distance_dm, c: Curves, held) -> tuple[np.ndarray, np.ndarray]:
    """envelope.supervision_demand on arrays: (demand, warning)."""
    emergency = present & ((distance_dm <= c.ebi_dm) | (held & (distance_dm <= c.sbi_dm)))
    service = present & (distance_dm <= c.sbi_dm)
    demand = np.where(emergency, EMERGENCY, np.where(service, SERVICE, MAINTAIN))
    return demand, present & (distance_dm <= c.warning_dm)


def hold(level, calm, demand, speed_cms, revocable: bool, confirm: int):
    """envelope.hold on arrays: (level, calm, demand sent). A demand below the level held is
    held for `confirm` - 1 cycles and let through on the confirm-th (calm counts them); an
    emergency held to standstill if not `revocable`; everything let through at standstill."""
    lower = (speed_cms > 0) & (demand < level)
    stuck = lower & (level == EMERGENCY) if not revocable else np.zeros_like(lower)
    holding = lower & (stuck | (calm + 1 < confirm))
    level = np.where(holding, level, demand)
    return level, np.where(holding & ~stuck, calm + 1, 0), level


def table_hold(level, demand, speed_cms, zone_free):
    """envelope.table_hold on arrays: the table's demand, kept at `level` (what it sent last
    cycle) while the train moves and the voted picture is in the table's zones."""
    return np.where((demand >= level) | (speed_cms == 0) | zone_free, demand, level)




class TablePolicy:
    """The table step of the core on arrays: node = next[node, obs], demand = action[node]."""

    def __init__(self, action, nxt, start: int, n: int):
        self.action = np.asarray(action, dtype=I64)
        self.next = np.asarray(nxt, dtype=I64)
        self.node = np.full(n, start, dtype=I64)

    def step(self, obs: np.ndarray, applied: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(demand, node) after this cycle's observation; `applied` (the demand sent last
        cycle) is what a belief-tracking policy predicts with, a table needs only its node."""
        self.node = self.next[self.node, obs]
        return self.action[self.node], self.node


class VectorMonitor:
    """n monitors stepped together; every channel of train i reports the same thing.

    `policy` replaces the table step (anything with TablePolicy's `step`): the evaluation
    runs baselines and the belief-tracking policy behind the same supervision. Default: the
    setup's table."""

    def __init__(self, setup: cycle.Setup, n: int, policy=None):
        self.setup = setup
        self.cfg = setup.config
        self.policy = policy or TablePolicy(setup.action, setup.next, setup.table.start, n)
        self.applied = np.zeros(n, dtype=I64)
        self.held = np.zeros(n, dtype=I64)          # State.held: the demand level held
        self.calm = np.zeros(n, dtype=I64)
        self.table_held = np.zeros(n, dtype=I64)    # State.table_held
        self.memory = TrackMemory(setup, n)        # State.tracks (verification/fasttracks.py)
        self.kept = np.zeros(n, dtype=bool)
        # State.plaus per module (its two channels report alike here): plausibility.check's
        # reference distance (-1: none), its report tick, the last report's tick and closing
        # speed, the least and the most run since, and whether the module is implausible
        shape = (n, self.cfg.modules)
        self.p_ref = np.full(shape, -1, dtype=I64)
        self.p_ref_tick = np.zeros(shape, dtype=I64)
        self.p_last_tick = np.zeros(shape, dtype=I64)
        self.p_last_closing = np.zeros(shape, dtype=I64)
        self.p_lo = np.zeros(shape, dtype=I64)
        self.p_hi = np.zeros(shape, dtype=I64)
        self.p_bad = np.zeros(shape, dtype=bool)
        self.tick = 0                               # the cycle's tick: k * period_ms
        self.m2 = setup.model == "m2"
        # the table's risk column at its node; another policy's nodes are not the table's: 0
        self.risk = np.asarray(setup.table.risk, dtype=I64) if policy is None else None


    def _plausibility(self, sees: np.ndarray, dist, closing, report_tick) -> np.ndarray:
        """Step 1b of the cycle (plausibility.check) for each module's channels: `sees`
        (n, modules) where they report the obstacle PRESENT; returns (n, modules) implausible."""
        cfg = self.cfg
        d, c, t = dist[:, None], closing[:, None], report_tick[:, None]
        fresh = sees & (self.p_ref == -1)
        new = sees & ~fresh & (t != self.p_last_tick)
        dt = t - self.p_last_tick
        gap = new & ((dt < 0) | (dt > cfg.plausibility_ms))
        go = new & ~gap
        lo = self.p_lo + np.minimum(c, self.p_last_closing) * dt
        hi = self.p_hi + np.maximum(c, self.p_last_closing) * dt
        span = t - self.p_ref_tick
        tol = 2 * cfg.distance_accuracy_dm * UNITS_PER_DM + cfg.closing_accuracy_cms * span
        du, ru = d * UNITS_PER_DM, self.p_ref * UNITS_PER_DM
        farther = go & (du > ru - lo + tol)
        nearer = go & ~farther & (du < ru - hi - tol)
        whole = go & ~farther & ~nearer & (span >= cfg.plausibility_ms)
        anchor = fresh | gap | farther | nearer | whole
        cont = go & ~anchor
        self.p_bad = np.where(sees, (self.p_bad | farther) & ~whole, False)
        self.p_ref = np.where(anchor, d, np.where(sees, self.p_ref, -1))
        self.p_ref_tick = np.where(anchor, t, np.where(sees, self.p_ref_tick, 0))
        self.p_last_tick = np.where(anchor | cont, t, np.where(sees, self.p_last_tick, 0))
        self.p_last_closing = np.where(anchor | cont, c, np.where(sees, self.p_last_closing, 0))
        self.p_lo = np.where(cont, lo, np.where(sees & ~anchor, self.p_lo, 0))
        self.p_hi = np.where(cont, hi, np.where(sees & ~anchor, self.p_hi, 0))
        return self.p_bad.copy()

    def step(self, present: np.ndarray, distance_dm: np.ndarray, speed_cms: np.ndarray,
             closing_cms: Optional[np.ndarray] = None, obstacle: Optional[np.ndarray] = None,
             track: Optional[np.ndarray] = None, brake: Optional[np.ndarray] = None,
             age_ms: Optional[np.ndarray] = None, modules: Optional[np.ndarray] = None) -> dict:
        """One cycle for all trains. closing_cms None: the train's speed (a static obstacle);
        obstacle, track, brake, age_ms None: 0; modules None: every module sees what is
        present (a bit mask; a train whose mask lacks a module has a dispute where present).
        Returns the outputs (OUTPUT_KEYS), the policy's own demand (`table`, before the
        table's hold; `table_demand` after it), `track_far`: the `far` position, judged this
        cycle, of the track the outputs track_state/track_dm/track_cycles report on (1e-5 m,
        what passing and the sensor range are judged on: the nearest track, or the nearest
        of last cycle if this cycle forgot or passed it; NO_TRACK without one), `dispute`,
        the curves of the supervised obstacle (the voted one, else the nearest remembered
        one) and the zone limits the papers' risk was read with (`alpha1_dm`, `alpha2_dm`)."""
        cfg = self.cfg
        present = np.asarray(present, dtype=bool)
        speed = np.asarray(speed_cms, dtype=I64)
        zeros = np.zeros(present.shape[0], dtype=I64)
        track = zeros if track is None else np.asarray(track, dtype=I64)
        brake = zeros if brake is None else np.asarray(brake, dtype=I64)
        everyone = (1 << cfg.modules) - 1
        seeing = np.full(present.shape[0], everyone, dtype=I64) if modules is None else np.asarray(modules, dtype=I64)
        if present.any() and ((seeing[present] & everyone) == 0).any():
            raise ValueError("a present obstacle needs at least one module that sees it (modules mask 0)")
        mask = seeing & everyone
        # 1b. plausibility: a module whose channels' distance does not shrink as their closing
        #     speeds say is DEGRADED (both channels alike), a system error that is no dispute
        raw_age = zeros if age_ms is None else np.where(present, age_ms, 0).astype(I64)
        raw_closing = speed if closing_cms is None else np.where(present, closing_cms, 0).astype(I64)
        bit = np.arange(cfg.modules)
        sees = present[:, None] & (((mask[:, None] >> bit) & 1) == 1)
        bad = self._plausibility(sees, np.where(present, distance_dm, 0).astype(I64), raw_closing,
                                 self.tick - raw_age)
        self.tick += cfg.period_ms
        implausible = bad.any(axis=1)
        mask = mask & ~(bad * (1 << bit)).sum(axis=1)
        present = present & (mask != 0)                 # what the voter sees PRESENT
        age = np.where(present, raw_age, 0)
        dist = np.where(present, distance_dm, NO_DISTANCE).astype(I64)
        toward = np.where(present, raw_closing, speed)
        own = speed * (1000 - cfg.speed_error_permille) // 1000      # the train's share of a closing speed
        own_up = -(-speed * (1000 - cfg.speed_error_permille) // 1000)   # and back, rounded up (cycle.py)
        dispute = present & (mask != everyone) & ~implausible
        error = dispute | implausible                   # the table holds its node
        several = present & ((mask & (mask - 1)) != 0)      # two modules or more (two bits set)
        confirmed = present & ~error
        t_state, t_cycles, track_dm, far, ages, states = self.memory.observe(present, confirmed, several, dist, speed,
                                                                      toward, own, age, implausible)
        # 5. every remembered obstacle on its own curves (its closing speed, the age of a
        # sighting it took this cycle), unless it is the confirmed picture itself; the nearest
        # of them is what the risk reads (cycle.py step 5). The supervised obstacle of the
        # `curves` output: the voted one, else the nearest remembered one
        near, closing = self.memory.slots[0], self.memory.slots[2]
        watched = (near != NO_TRACK) & ~(confirmed & (near == dist * UNITS_PER_DM))
        remembered = any_slot(watched)
        first = watched.argmax(axis=0)
        n = present.shape[0]
        rows = np.arange(n)
        n_dm = np.where(remembered, near[first, rows] // UNITS_PER_DM, NO_DISTANCE)
        n_toward = closing[first, rows] + own_up
        n_age = ages[first, rows]
        sup = present | remembered
        sup_dist = np.where(present, dist, n_dm)
        sup_toward = np.where(present, toward, n_toward)
        sup_age = np.where(present, age, n_age)
        held_emergency = self.held == EMERGENCY
        # the remembered obstacles the supervised one does not cover (beside a voted one, or
        # beyond the nearest): their curves in the same call, after the trains' (k, r: slot, train)
        k, r = np.nonzero(watched & (present | (np.arange(TRACKS)[:, None] != first)))
        both = curves(cfg, np.concatenate((speed, speed[r])), np.concatenate((track, track[r])),
                      np.concatenate((brake, brake[r])), np.concatenate((sup_toward, closing[k, r] + own_up[r])),
                      np.concatenate((sup_age, ages[k, r])))
        c = Curves(*(x[:n] for x in both))
        env, warn = supervision(sup, sup_dist, c, held_emergency)
        if r.size:
            env_t, warn_t = supervision(True, near[k, r] // UNITS_PER_DM, Curves(*(x[n:] for x in both)),
                                        held_emergency[r])
            np.maximum.at(env, r, env_t)
            warn[r[warn_t]] = True
        memory = any_slot(watched & (states != TRACK_SEEN))   # a remembered obstacle no channel shows
        # the zones of the supervised obstacle; the papers' risk at the nearest (monitor/core/
        # risk.py): a remembered one nearer than the voted one (q), or a DEGRADED picture with
        # nothing seen or remembered read as an obstacle at 0 m (b), in the same call
        q = np.nonzero(present & remembered & (n_dm < dist))[0]
        b = np.nonzero(~sup & implausible)[0]
        all1, all2 = zone_alphas(cfg, np.concatenate((speed, speed[q], speed[b])),
                                 np.concatenate((sup_toward, n_toward[q], speed[b])),
                                 np.concatenate((sup_age, n_age[q], zeros[b])))
        alpha1, alpha2 = all1[:n], all2[:n]
        sup_zone = np.where(sup, zone_of(sup_dist, alpha1, alpha2, cfg.warning_margin_dm), 0)
        zone = np.where(present, sup_zone, np.where(implausible, 3, 0))  # the voted picture alone; DEGRADED: 3
        if q.size or b.size:
            alpha1[q], alpha2[q] = all1[n:n + q.size], all2[n:n + q.size]
            alpha1[b], alpha2[b] = all1[n + q.size:], all2[n + q.size:]
            sup_dist[q], sup_dist[b] = n_dm[q], 0
            sup = sup.copy()
            sup[b] = True
        warn = warn | dispute
        spd = np.where(toward < 0, 0, np.where(toward < cfg.fast_closing_cms, 1, 2))
        obst = zeros + STATIC if obstacle is None else np.where(present, obstacle, STATIC)
        obs = (((zone * 3 + spd) * 3 + obst) * 2 + track) * 2 + brake if self.m2 else zone
        r1 = np.where(sup, r1_ppm(np.where(sup, sup_dist, 0), alpha1), 0)
        r2 = np.where(sup, r2_ppm(np.where(sup, sup_dist, 0), alpha1, alpha2), 0)
        score = 3 * zone + 2 * spd + 2 * obst + track + 2 * brake
        if dispute.any() and not isinstance(self.policy, TablePolicy):
            raise ValueError("disputes between modules are modelled for the table policy only")
        if error.any() and isinstance(self.policy, TablePolicy):   # a system error holds the table at its node
            before = self.policy.node.copy()
            self.policy.step(obs, self.applied)
            self.policy.node = np.where(error, before, self.policy.node)
            node = self.policy.node
            action = self.policy.action[node]
        else:                                       # (a baseline policy steps on: the safe reaction answers)
            action, node = self.policy.step(obs, self.applied)
        table = table_hold(self.table_held, action, speed, zone == 0)     # the voted picture's zone
        self.table_held = table
        demand = np.maximum(np.maximum(table, env), np.where(implausible, cfg.safe_reaction, MAINTAIN))
        keep = present & ((zone != 0) | self.kept) & (toward > 0) & (speed > 0)      # envelope.keep_held
        asked = np.where(keep, np.maximum(demand, self.held), demand)
        self.held, self.calm, final = hold(self.held, self.calm, asked, speed,
                                           cfg.emergency_release == RELEASE_REVOCABLE, cfg.release_confirm_cycles)
        self.kept = keep & (self.held > MAINTAIN)
        self.applied = final
        reasons = (np.where(table > 0, R_TABLE, 0) | np.where(env == EMERGENCY, R_ENVELOPE, 0)
                   | np.where(env == SERVICE, R_SBI, 0) | np.where(final > demand, R_LATCH, 0)
                   | np.where(warn, R_WARNING, 0) | np.where(memory, R_MEMORY, 0)
                   | np.where(dispute, R_SYSTEM_ERROR | R_DISPUTE, 0)
                   | np.where(implausible, R_SYSTEM_ERROR | R_STALE | R_IMPLAUSIBLE, 0))
        out = {"demand": final, "reasons": reasons, "observation": obs, "node": np.array(node, copy=True),
               "distance_dm": dist, "warning": warn, "track_dm": track_dm, "track_cycles": t_cycles,
               "track_state": t_state, "r1_ppm": r1, "r2_ppm": r2, "risk_score": score,
               "risk_category": risk_category(score), "table_risk_ppm": self.risk[node] if self.risk is not None else np.zeros_like(node), "track_far": far, "table": action, "table_demand": table, "curves": c,
               "alpha1_dm": alpha1, "alpha2_dm": alpha2, "dispute": dispute, "implausible": implausible}
        self.memory.move(speed, ages)
        return out


# what twin_trace records besides the outputs (as `twin_<key>`): the policy's demand, the
# table's after its hold, the far position of the track the outputs report on (VectorMonitor.step);
# for the tests' coverage counts
TWIN_EXTRAS = ("table", "table_demand", "track_far")


def twin_trace(setup: cycle.Setup, inputs: dict) -> dict:
    """Run VectorMonitor over (steps, trains) input arrays (INPUT_KEYS; missing ones are
    their defaults) and return the inputs with the outputs (`out_<key>`, OUTPUT_KEYS) and
    TWIN_EXTRAS (`twin_<key>`), all (steps, trains)."""
    present = np.asarray(inputs["present"], dtype=bool)
    steps, n = present.shape
    vm = VectorMonitor(setup, n)
    trace = {k: np.asarray(v) for k, v in inputs.items() if v is not None}
    for key in OUTPUT_KEYS:
        trace["out_" + key] = np.zeros((steps, n), dtype=bool if key == "warning" else I64)
    for key in TWIN_EXTRAS:
        trace["twin_" + key] = np.zeros((steps, n), dtype=I64)
    for k in range(steps):
        out = vm.step(*(None if inputs.get(key) is None else np.asarray(inputs[key])[k] for key in INPUT_KEYS))
        for key in OUTPUT_KEYS:
            trace["out_" + key][k] = out[key]
        for key in TWIN_EXTRAS:
            trace["twin_" + key][k] = out[key]
    return trace


def core_outputs(setup: cycle.Setup, present, distance_dm, speed_cms, closing_cms=None, obstacle=None,
                 track=None, brake=None, age_ms=None, modules=None) -> list:
    """The real core over one train's sequence (arrays over time), the channels of every
    seeing module alike; the same defaults as VectorMonitor.step (closing: the train's
    speed; modules: all; the rest 0)."""
    state = cycle.initial_state(setup)
    period = setup.config.period_ms
    outs = []
    for k in range(len(present)):
        inputs = cycle_inputs(setup, k, present, distance_dm, speed_cms, closing_cms, obstacle, track, brake, age_ms,
                              modules)
        state, out = cycle.step(setup, state, inputs, k * period)
        outs.append(out)
    return outs


def cycle_inputs(setup: cycle.Setup, k: int, present, distance_dm, speed_cms, closing_cms=None, obstacle=None,
                 track=None, brake=None, age_ms=None, modules=None) -> Inputs:
    """The core's inputs at cycle k of one train's sequence (core_outputs' defaults), every
    channel of a seeing module alike, the others ABSENT: what a recorded world's sensors
    sent, for the core or for the bus."""
    tick = k * setup.config.period_ms
    p = bool(present[k])
    speed = int(speed_cms[k])
    age = int(age_ms[k]) if (p and age_ms is not None) else 0
    rep = Report(PRESENT if p else ABSENT, int(distance_dm[k]) if p else 0,
                 (speed if closing_cms is None else int(closing_cms[k])) if p else 0,
                 int(obstacle[k]) if (p and obstacle is not None) else STATIC, tick - age)
    train = Train(speed, 0 if track is None else int(track[k]), 0 if brake is None else int(brake[k]))
    if not p or modules is None:
        return Inputs((rep,) * setup.config.channels, train)
    absent = Report(ABSENT, 0, 0, STATIC, tick)
    mask = int(modules[k])
    return Inputs(tuple(rep if mask >> (i // 2) & 1 else absent for i in range(setup.config.channels)), train)


def _twin_column(trace: dict, key: str, i: int) -> Optional[np.ndarray]:
    """Train i's twin output `key`: `out_<key>` (twin_trace) or `<key>` (the seed worlds'
    traces, where `distance_dm` is the input)."""
    if "out_" + key in trace:
        return trace["out_" + key][:, i]
    return trace[key][:, i] if key in trace and key != "distance_dm" else None


def first_mismatch(setup: cycle.Setup, trace: dict, trains: int = 20) -> tuple[Optional[dict], int]:
    """Replay the first `trains` trains of a trace (inputs INPUT_KEYS, twin outputs as
    twin_trace or the seed worlds write them) through the real core; (the first difference
    or None, cycles compared). Every cycle must also be NORMAL with no flag or error (the
    case the twin covers), but for a dispute between modules (a system error with no module
    flagged exactly in the disputed cycles) and for an implausible module (a system error
    exactly in the cycles whose twin reasons say so, its module flagged)."""
    compared = 0
    for i in range(min(trains, trace["present"].shape[1])):
        inp = {k: (trace[k][:, i] if k in trace else None) for k in INPUT_KEYS}
        outs = core_outputs(setup, *(inp[k] for k in INPUT_KEYS))
        twin = {k: c for k in OUTPUT_KEYS if (c := _twin_column(trace, k, i)) is not None}
        everyone = (1 << setup.config.modules) - 1
        disputed = (np.zeros(len(outs), dtype=bool) if inp["modules"] is None
                    else np.asarray(inp["present"], dtype=bool) & ((np.asarray(inp["modules"]) & everyone) != everyone))
        implausible = ((np.asarray(twin["reasons"]) & R_IMPLAUSIBLE) != 0 if "reasons" in twin
                       else np.zeros(len(outs), dtype=bool))
        erring = (disputed & ~implausible) | implausible
        for k, out in enumerate(outs):
            voted = int(inp["distance_dm"][k]) if inp["present"][k] else NO_DISTANCE
            own = () if implausible[k] or "distance_dm" in twin else (("distance_dm", voted),)
            for key, value in (*own, *((key, c[k]) for key, c in twin.items())):
                if getattr(out, key) != value:
                    return {"train": i, "cycle": k, "field": key, "core": getattr(out, key), "twin": value}, compared
            if erring.any():
                if (out.module_flags and not implausible[k]) or out.system_error != bool(erring[k]):
                    return {"train": i, "cycle": k, "field": "system_error", "core": out,
                            "twin": f"system error {bool(erring[k])}, module flags only if implausible"}, compared
            elif out.mode != NORMAL or out.module_flags or out.system_error or out.error_cycles:
                return {"train": i, "cycle": k, "field": "mode", "core": out, "twin": "NORMAL, no error"}, compared
            compared += 1
    return None, compared


def agrees_with_core(setup: cycle.Setup, trace: dict, trains: int = 20) -> tuple[bool, int]:
    """(all equal, cycles compared) of first_mismatch."""
    bad, compared = first_mismatch(setup, trace, trains)
    return bad is None, compared
