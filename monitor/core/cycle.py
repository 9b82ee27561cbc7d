"""One monitor cycle: step(setup, state, inputs, tick) -> (state, outputs).

freshness -> 2oo2 per module -> 3oo3 across modules -> braking curves (EBI, SBI, warning)
-> observation -> table -> demand (only ever upwards) -> emergency latch and release.
Pure: the same setup, state, inputs and tick always give the same result. The mode
machine is documented in docs/core.md, the curves and the responses in
docs/supervision.md.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from . import config as config_mod
from .config import Config, ConfigurationError
from .braking import curves, ebi_dm
from .config import RELEASE_REVOCABLE, forget_cycles, track_accel_mms2
from .envelope import combine, hold, keep_held, supervision_demand, table_hold, zone
from .freshness import channel_status
from .memory import UNITS_PER_DM, distance_dm, far_travel, forget, near_travel, observe, seen_beyond
from .tracks import absorbed, assign, insert, ordered
from .plausibility import NO_REFERENCE, check as plausibility_check
from .observation import OBSERVATIONS, m2_observation, speed_class
from .risk import CRITICAL, MAX_SCORE, PPM, r1_ppm, r2_ppm, risk_category, risk_score
from .table import Table, TableError, decode
from .types import (
    ABSENT, DEGRADED, DEGRADED_MODE, EMERGENCY, INIT, MAINTAIN, MAX_COUNT, MAX_SPEED_CMS, NO_DISTANCE, NO_TRACK,
    NORMAL, PRESENT, R_DEADLINE, R_ENVELOPE, R_IMPLAUSIBLE, R_INIT, R_LATCH, R_MEMORY, R_PERCEPTOR, R_SAFE_STOP, R_STALE,
    R_DISPUTE, R_SBI, R_SYSTEM_ERROR, R_TABLE, R_TRAIN_INPUT, R_WARNING, SAFE_STOP, SERVICE, STATIC,
    TRACK_FORGOTTEN, TRACK_HELD, TRACK_NONE, TRACK_PASSED, TRACK_SEEN, TRACKS, Inputs, Outputs, State,
    Track,
)
from .voter import disagreement, distances_disagree, vote_2oo2, vote_3oo3, vote_single


class Setup(NamedTuple):
    """A checked configuration and table, ready to run."""

    config: Config
    table: Table
    model: str
    timeout_ticks: int
    action: tuple
    next: tuple
    all_seen: int
    forget_cycles: int    # evidence cycles that forget a remembered obstacle
    forget_single: int    # the same for an obstacle only one module ever saw
    track_accel: int      # mm/s^2 the train may gain per second: traction plus the steepest downhill


def create(cfg: Config, table_bytes: bytes, expect_model: str | None = None) -> Setup:
    """Check the configuration and the table together; refuse to start on any mismatch."""
    config_mod.check(cfg)
    try:
        table = decode(table_bytes, expect_model)
    except TableError as exc:
        raise ConfigurationError(f"table refused: {exc}") from None
    model = table.model
    if model not in OBSERVATIONS:
        raise ConfigurationError(f"table is for model {model!r}; this monitor maps observations for {', '.join(OBSERVATIONS)}")
    if table.observations != OBSERVATIONS[model]:
        raise ConfigurationError(f"table observations do not match model {model!r}'s (a table for a different model?)")
    if len(table.actions) != 3:
        raise ConfigurationError(f"table has {len(table.actions)} actions; the monitor needs maintain/service/emergency")
    params = table.header.get("params")
    step_s = params.get("time_step_s") if isinstance(params, dict) else None
    if isinstance(step_s, bool) or not isinstance(step_s, (int, float)) or not math.isfinite(step_s):
        raise ConfigurationError(f"table header gives no numeric time step (params.time_step_s = {step_s!r})")
    if round(step_s * 1000) != cfg.period_ms:
        raise ConfigurationError(f"table was solved for a time step of {step_s} s but period_ms = {cfg.period_ms}")
    return Setup(cfg, table, model, cfg.timeout_cycles * cfg.period_ms, table.action, table.next,
                 (1 << cfg.channels) - 1, forget_cycles(cfg), forget_cycles(cfg, single=True), track_accel_mms2(cfg))


def initial_state(setup: Setup) -> State:
    modules = (0,) * setup.config.modules
    return State(INIT, setup.table.start, MAINTAIN, 0, modules, 0, 0, 0, 0, modules,
                 plaus=(NO_REFERENCE,) * setup.config.channels)


def _train(train) -> tuple[int, int, int, bool]:
    """(speed, track, brake, valid): an invalid train state is read to the safe side."""
    try:
        v, k, b = train.speed_cms, train.track, train.brake
        if type(v) is int and type(k) is int and type(b) is int:
            return train_in_range(v, k, b)
    except (AttributeError, TypeError):
        pass
    return MAX_SPEED_CMS, 1, 1, False


def train_in_range(v: int, k: int, b: int) -> tuple[int, int, int, bool]:
    """(speed, track, brake, valid) of an integer train state, out of range read to the safe
    side (apart from `_train`'s type guard, so that the proof runs it on symbolic numbers)."""
    if 0 <= v <= MAX_SPEED_CMS and k in (0, 1) and b in (0, 1):
        return v, k, b, True
    return MAX_SPEED_CMS, 1, 1, False


def _inc(count: int) -> int:
    """count + 1, saturating at MAX_COUNT as the C core's 32-bit counters do."""
    return count + 1 if count < MAX_COUNT else MAX_COUNT


def step(setup: Setup, state: State, inputs: Inputs, tick: int) -> tuple[State, Outputs]:
    """One cycle. Total: whatever the inputs, it returns a state and outputs; if anything
    unforeseen went wrong inside, the result is SAFE_STOP with an emergency demand."""
    try:
        return _step(setup, state, inputs, tick)
    except Exception:  # noqa: BLE001 - the monitor must never stop; fail to the safe side
        cycle, errors = _inc(state.cycle), _inc(state.error_cycles)
        out = Outputs(EMERGENCY, R_SAFE_STOP | R_SYSTEM_ERROR | R_LATCH, NO_DISTANCE, state.node,
                      SAFE_STOP, 0, True, 0, cycle, errors, True, r1_ppm=PPM // 2, r2_ppm=PPM,
                      risk_score=MAX_SCORE, risk_category=CRITICAL, table_risk_ppm=PPM)
        return state._replace(mode=SAFE_STOP, held=EMERGENCY, healthy=0, cycle=cycle, error_cycles=errors, calm=0), out


def _step(setup: Setup, state: State, inputs: Inputs, tick: int) -> tuple[State, Outputs]:
    cfg = setup.config
    reports = tuple(inputs.reports)
    n = cfg.channels
    if len(reports) < n:
        reports = reports + (None,) * (n - len(reports))

    # 1. freshness and range per channel
    statuses = [channel_status(reports[i], tick, setup.timeout_ticks) for i in range(n)]
    # 1b. plausibility (plausibility.py): a PRESENT channel whose distance does not shrink as
    #     its own closing speeds say is DEGRADED (a frozen sensor keeps sending fresh frames)
    plaus = list(state.plaus[:n]) + [NO_REFERENCE] * (n - len(state.plaus))
    implausible = False
    for i in range(n):
        present = statuses[i] == PRESENT
        r = reports[i]
        plaus[i] = plausibility_check(plaus[i], present, r.distance_dm if present else 0, r.closing_cms if present else 0,
                                      r.tick if present else 0, cfg.distance_accuracy_dm, cfg.closing_accuracy_cms,
                                      cfg.plausibility_ms)
        if plaus[i][6]:                                 # (only ever set while PRESENT)
            statuses[i] = DEGRADED
            implausible = True
    seen = state.seen
    stale = False
    closing = None
    obstacle = STATIC
    age = 0
    for i, s in enumerate(statuses):
        if s == DEGRADED:
            stale = True
        else:
            seen |= 1 << i
            if s == PRESENT:
                r = reports[i]
                closing = r.closing_cms if closing is None or r.closing_cms > closing else closing
                obstacle = r.obstacle if r.obstacle > obstacle else obstacle
                age = tick - r.tick if tick - r.tick > age else age

    # 2. 2oo2 per module, with disagreement persistence: disagreement cycles add up until
    #    `persistence_cycles` calm cycles in a row clear them, so a flapping channel escalates
    results = []
    disagree = []
    agree = []
    flags = 0
    perceptor = False
    for m in range(cfg.modules):
        sa, sb = statuses[2 * m], statuses[2 * m + 1]
        da = reports[2 * m].distance_dm if sa == PRESENT else 0
        db = reports[2 * m + 1].distance_dm if sb == PRESENT else 0
        res = vote_2oo2(sa, da, sb, db)
        if distances_disagree(sa, da, sb, db, cfg.distance_tolerance_dm):
            res = (res[0], res[1], True)
        results.append(res)
        if res[2]:
            flags |= 1 << m
        if disagreement(sa, sb):
            count, calm_m = _inc(state.disagree[m]), 0
        else:
            calm_m = _inc(state.agree[m])
            count = 0 if calm_m >= cfg.persistence_cycles else state.disagree[m]
        disagree.append(count)
        agree.append(calm_m)
        if count >= cfg.persistence_cycles:
            perceptor = True

    # 3. 3oo3 across modules (or the single module)
    if cfg.modules == 3:
        (s1, d1, f1), (s2, d2, f2), (s3, d3, f3) = results
        sys_status, distance, sys_error = vote_3oo3(s1, d1, f1, s2, d2, f2, s3, d3, f3)
    else:
        sys_status, distance, sys_error = vote_single(*results[0])

    # 4. obstacle memory (memory.py): the remembered obstacle was moved to this cycle at the
    #    end of the last one (worst case, its report's age included: `t_age` is the age of a
    #    sighting this cycle, not yet counted); the train's least travel moves what "passed" reads
    speed, track, brake, train_ok = _train(inputs.train)
    err = cfg.speed_error_permille
    own_speed = speed * (1000 - err) // 1000          # the train's share of a closing speed
    # and back: a remembered own speed plus the train's least speed rounded up, so that no
    # curve counts less of the obstacle's speed than the memory holds (issue 40 item 2)
    own_speed_up = -(-speed * (1000 - err) // 1000)
    toward = speed if closing is None else closing
    confirmed = distance != NO_DISTANCE and sys_status == PRESENT and not sys_error
    # modules that see it with both channels: one creates a track, two (or a confirmed
    # picture) make it strong, remembered for forget_ms; one module's alone for forget_single_ms
    seeing = sum(statuses[2 * m] == PRESENT and statuses[2 * m + 1] == PRESENT for m in range(cfg.modules))
    # several obstacles (tracks.py): the sighting measures the nearest track whose window
    # holds it, creates one ahead of or beyond them all; a confirmed sighting beyond a track
    # is evidence that it is gone (the sensors report their nearest object), counted as
    # ABSENT is (forget), never an instant replacement
    tracks = list(state.tracks)               # (every State holds TRACKS slots: NO_TRACKS by default)
    ages, states = [0] * TRACKS, [TRACK_NONE] * TRACKS
    slot, create, gone = -1, False, ()
    if distance != NO_DISTANCE:
        slot, create = assign(tuple(tracks), distance, cfg.distance_accuracy_dm, confirmed or seeing > 0)
        gone = absorbed(tuple(tracks), slot, distance, cfg.distance_accuracy_dm) if confirmed and slot >= 0 else ()
    evidence_absent = sys_status == ABSENT and not sys_error
    for i, t in enumerate(tracks):
        if t.near == NO_TRACK:
            continue
        if i == slot:
            near, far, t_closing, ages[i] = observe(t.near, t.far, t.closing, distance, toward - own_speed, age,
                                                    confirmed, seeing > 0)
            seen_now = near == distance * UNITS_PER_DM
            states[i] = TRACK_SEEN if seen_now else TRACK_HELD   # (a farther disputed sighting: not seen)
            tracks[i] = Track(near, far, t_closing, 0 if seen_now else _inc(t.cycles), 0,
                              t.strong or confirmed or seeing >= 2)
        elif i in gone:                               # the same obstacle as the one measured: its
            kept = tracks[slot]                       # closing speed stays remembered there
            tracks[slot] = kept._replace(closing=kept.closing if kept.closing > t.closing else t.closing)
            tracks[i], states[i] = Track(), TRACK_NONE
        else:                                         # not seen: evidence, or held
            far = t.far - far_travel(speed if train_ok else 0, err, setup.track_accel, cfg.period_ms)
            beyond = confirmed and seen_beyond(t.near, t.far, distance, cfg.distance_accuracy_dm)
            # the farthest the obstacle can lie: a distance accuracy beyond where it was reported
            # (the error budget); passed, and inside the sensors' range, only counting that
            reach = far + cfg.distance_accuracy_dm * UNITS_PER_DM
            absent, states[i] = forget(t.absent, (beyond or evidence_absent) and not stale,
                                       reach <= cfg.sensor_range_dm * UNITS_PER_DM, reach < 0,
                                       setup.forget_cycles if t.strong else setup.forget_single)
            lost = states[i] == TRACK_FORGOTTEN or states[i] == TRACK_PASSED
            tracks[i] = Track() if lost else Track(t.near, far, t.closing, _inc(t.cycles), absent, t.strong)
    first_lost = states[0] == TRACK_FORGOTTEN or states[0] == TRACK_PASSED   # what happened to the nearest
    first_state = states[0]
    if create:
        near, far, t_closing, t_age = observe(NO_TRACK, NO_TRACK, 0, distance, toward - own_speed, age, confirmed, True)
        tracks, ages, states = insert(tracks, ages, states, Track(near, far, t_closing, 0, 0, confirmed or seeing >= 2),
                                      t_age, TRACK_SEEN)
    tracks, ages, states = ordered(tracks, ages, states)
    t_dm = distance_dm(tracks[0].near)
    t_state = first_state if first_lost else (states[0] if tracks[0].near != NO_TRACK else TRACK_NONE)
    t_cycles = 0 if first_lost else tracks[0].cycles
    # the remembered obstacles as the next cycle finds them, from the memory alone (moved_tracks)
    next_tracks = moved_tracks(setup, tracks, ages, states, speed)

    # 5. braking curves at the measured speed (docs/supervision.md) for the voted obstacle and
    #    for every remembered one (its closing speed and the age of a sighting it took this
    #    cycle), unless it is the confirmed picture itself, under the reported conditions; the
    #    highest demand counts. The table's zones under normal conditions; the observation reads
    #    the voted picture alone. Every curve is computed before anything is decided from them
    #    (the proof of the whole cycle follows the step to there: verification/physics/whole_cycle.py)
    voted = curves(cfg, speed, track, brake, toward, age) if distance != NO_DISTANCE else None
    watched = [(i, t, curves(cfg, speed, track, brake, t.closing + own_speed_up, ages[i]))
               for i, t in enumerate(tracks)
               if t.near != NO_TRACK and not (confirmed and t.near == distance * UNITS_PER_DM)]
    if voted is not None:
        alpha1, alpha2 = _zone_limits(cfg, speed, toward, age)
        z = zone(distance, alpha1, alpha2, cfg.warning_margin_dm)
        env, warn = supervision_demand(True, distance, voted.ebi_dm, voted.sbi_dm, voted.warning_dm, state.latched)
    else:
        z = 3 if sys_status == DEGRADED else 0
        env, warn = MAINTAIN, False
    # the nearest remembered obstacle is what the risk reads, and one that no channel shows this
    # cycle is the memory's reason
    nearest, memory_reason = -1, False
    for i, t, curve in watched:
        env_t, warn_t = supervision_demand(True, distance_dm(t.near), curve.ebi_dm, curve.sbi_dm, curve.warning_dm,
                                           state.latched)
        env, warn = combine(env, env_t, MAINTAIN), warn or warn_t
        nearest = i if nearest < 0 else nearest
        memory_reason = memory_reason or states[i] != TRACK_SEEN
    spd = speed_class(toward, cfg.fast_closing_cms)
    obs = z if setup.model == "m1" else m2_observation(z, spd, obstacle, track, brake)

    # the papers' risk at the nearest obstacle, voted or remembered (risk.py); a blind picture
    # with nothing remembered reads as an obstacle at 0 m, as the observation reads it critical
    r1 = r2 = 0
    near_dm = distance
    if nearest >= 0 and (distance == NO_DISTANCE or distance_dm(tracks[nearest].near) < distance):
        near_dm = distance_dm(tracks[nearest].near)
        alpha1, alpha2 = _zone_limits(cfg, speed, tracks[nearest].closing + own_speed_up, ages[nearest])
    elif distance == NO_DISTANCE and sys_status == DEGRADED:
        near_dm = 0
        alpha1, alpha2 = _zone_limits(cfg, speed, speed, 0)
    if near_dm != NO_DISTANCE:
        r1, r2 = r1_ppm(near_dm, alpha1), r2_ppm(near_dm, alpha1, alpha2)
    score = risk_score(z, spd, obstacle, track, brake)

    # modes; a dispute is a system error with every channel fresh: channels disagree
    # about an obstacle, answered by the curves and a warning rather than by safe_reaction
    error = sys_error or not train_ok
    dispute = sys_error and train_ok and not stale
    overrun_limit = inputs.overruns >= cfg.max_overruns
    healthy = 0 if (error or stale or perceptor or overrun_limit) else _inc(state.healthy)
    mode = state.mode
    if perceptor or overrun_limit:
        mode = SAFE_STOP
    elif mode == INIT:
        if seen == setup.all_seen:
            mode = DEGRADED_MODE if error else NORMAL
    elif mode == SAFE_STOP:
        if train_ok and speed == 0 and healthy >= cfg.recovery_cycles:
            mode = NORMAL
    elif error:
        mode = DEGRADED_MODE
    elif mode == DEGRADED_MODE and healthy >= cfg.recovery_cycles:
        mode = NORMAL

    # 6. table (held during any system error: it reads only pictures the voter confirms;
    #    the curves and the error rules answer meanwhile)
    #    what the table raised is held while the voted picture is in the table's zones (a
    #    remembered obstacle is the curves' business: the table acts on what is seen)
    if mode == INIT:
        node = setup.table.start
        table_demand = MAINTAIN
    else:
        node = state.node if error and mode != SAFE_STOP else setup.next[state.node][obs]
        table_demand = table_hold(state.table_held, setup.action[node], speed, z == 0)

    # 7. demands, only ever upwards, then the hold (released only after `release_confirm_cycles`
    #    in which the causes, remembered obstacles included, ask for less); INIT brakes without
    #    holding, so a monitor started on a moving train releases once its picture is valid
    reasons = 0
    error_demand = MAINTAIN
    if table_demand:
        reasons |= R_TABLE
    if env == EMERGENCY:
        reasons |= R_ENVELOPE
    elif env == SERVICE:
        reasons |= R_SBI
    if stale:
        reasons |= R_STALE
    if implausible:
        reasons |= R_IMPLAUSIBLE
    if memory_reason:
        reasons |= R_MEMORY
    if error:
        reasons |= R_SYSTEM_ERROR | (0 if train_ok else R_TRAIN_INPUT)
        if dispute:
            reasons |= R_DISPUTE
            warn = True
        elif mode != INIT:           # in INIT the emergency below covers it, unlatched
            error_demand = cfg.safe_reaction
    if mode == SAFE_STOP:
        error_demand = EMERGENCY
        reasons |= R_SAFE_STOP | (R_PERCEPTOR if perceptor else 0) | (R_DEADLINE if overrun_limit else 0)
    demand = combine(table_demand, env, error_demand)
    # an obstacle in sight and closing in, in the table's zones when the keeping began, keeps
    # what is held: lowering it now would only raise it again nearer (issue 29 item 6: a clean
    # stop or a clean release); the zones shrink with the speed, so once keeping it stays
    # until the obstacle is out of sight, opens the gap, or the train stands
    keep = distance != NO_DISTANCE and toward > 0 and (z != 0 or state.kept)
    held, calm, final = hold(state.held, state.calm, keep_held(demand, state.held, speed, keep), speed,
                             cfg.emergency_release == RELEASE_REVOCABLE, cfg.release_confirm_cycles)
    if final > demand:
        reasons |= R_LATCH
    if mode == INIT:
        final = EMERGENCY
        reasons |= R_INIT
    if warn:
        reasons |= R_WARNING

    error_cycles = _inc(state.error_cycles) if error or stale else state.error_cycles
    cycle = _inc(state.cycle)
    new_state = State(mode, node, held, seen, tuple(disagree), healthy, cycle, error_cycles, calm, tuple(agree),
                      table_demand if mode != INIT else MAINTAIN, tuple(next_tracks),
                      keep and speed > 0 and held > MAINTAIN, tuple(plaus))
    out = Outputs(final, reasons, distance, node, mode, flags, error, obs, cycle, error_cycles, warn,
                  t_dm, t_cycles, t_state, r1, r2, score, risk_category(score), setup.table.risk[node])
    return new_state, out


def moved_tracks(setup: Setup, tracks: list, ages: list, states: list, speed: int) -> list:
    """The remembered obstacles moved for the next period, worst case for the train, nearest
    first; after a sighting also for the report's age (the remembered curves count no age: a
    position is moved by the age once, at the speed of the cycle that saw it, not at every
    later and perhaps slower speed; issue 30 item 4)."""
    cfg = setup.config
    out = list(tracks)
    for i, t in enumerate(out):
        if t.near != NO_TRACK:
            # the closing speed as measured plus the sensors' accuracy (the error budget)
            moved = t.near - near_travel(speed, cfg.speed_error_permille, setup.track_accel,
                                         t.closing + cfg.closing_accuracy_cms, cfg.period_ms + ages[i])
            out[i] = t._replace(near=moved if moved > 0 else 0)
    return ordered(out, list(ages), list(states))[0]


def _zone_limits(cfg: Config, speed: int, toward: int, age: int) -> tuple[int, int]:
    """(alpha1, alpha2) of the table's zones and of the papers' risk: alpha2 = EBI and alpha1
    = the service curve's EBI, both under normal conditions and as zone limits (braking.ebi_dm:
    without the supervision's sampling period; alpha1 at least alpha2)."""
    alpha2 = ebi_dm(cfg, speed, 0, 0, toward, age)
    alpha1 = ebi_dm(cfg, speed, 0, 0, toward, age, service=True)
    return (alpha1 if alpha1 > alpha2 else alpha2), alpha2


def replay(setup: Setup, sequence) -> list:
    """Run the core over recorded (tick, Inputs) pairs from the initial state; the same
    sequence always gives the same list of Outputs."""
    state = initial_state(setup)
    outputs = []
    for tick, inputs in sequence:
        state, out = step(setup, state, inputs, tick)
        outputs.append(out)
    return outputs
