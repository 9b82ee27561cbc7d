/* railguard online core in C99; see rg_core.h. Each function mirrors the Python function
 * of the same name in monitor/core, and the tests compare the two step by step. */
#include "rg_core.h"

#include <stdio.h>

#include "rg_sha256.h"

/* ACSL: the contracts on the functions below are the PEP 316 contracts of monitor/core
 * (freshness.py, voter.py, braking.py, envelope.py, config.py's gradient), proved with
 * Frama-C WP; fmu/c/proof/ holds the EVA driver for the whole step; docs/proof.md says how
 * to run both and what they cover. Where a Python precondition is not needed by the C
 * function it is left out (the contract then holds for every input, which is stronger) or
 * becomes the premise of the ensures that needs it; a C precondition can be wider than
 * Python's where EVA needs it (the range is then whatever the int64 arithmetic allows). */
/*@ predicate rg_in_range_p(integer status, integer distance_dm, integer closing_cms, integer obstacle) =
        0 <= status <= 2 && 0 <= distance_dm <= 60000 && -15000 <= closing_cms <= 15000 && 0 <= obstacle <= 2;
    predicate rg_fresh_p(integer received, integer now, integer timeout_ticks) =
        received <= now && now - received <= timeout_ticks;
    logic integer rg_max3(integer a, integer b, integer c) = \max(a, \max(b, c));
    logic integer rg_min3(integer a, integer b, integer c) = \min(a, \min(b, c));
    logic integer rg_run_num(integer v, integer a, integer t) = 2 * v * t * 10000 + a * t * t;
*/

void rg_config_default(rg_config *cfg)
{
    cfg->period_ms = 100;
    cfg->timeout_cycles = 3;
    cfg->persistence_cycles = 10;
    cfg->emergency_decel_mms2 = 2400;
    cfg->emergency_band2_cms = 3000;
    cfg->emergency_band2_mms2 = 2200;
    cfg->emergency_band3_cms = 0;
    cfg->emergency_band3_mms2 = 0;
    cfg->service_decel_mms2 = 800;
    cfg->emergency_buildup_ms = 1000;
    cfg->service_buildup_ms = 2000;
    cfg->traction_cutoff_ms = 800;
    cfg->max_accel_mms2 = 500;
    cfg->speed_error_permille = 20;
    cfg->slippery_permille = 700;
    cfg->degraded_permille = 800;
    cfg->max_gradient_permille = 20;
    cfg->standstill_margin_dm = 50;
    cfg->warning_ms = 2000;
    cfg->emergency_release = RG_RELEASE_REVOCABLE;
    cfg->release_confirm_cycles = 5;
    cfg->warning_margin_dm = 10000;
    cfg->fast_closing_cms = 2000;
    cfg->safe_reaction = RG_EMERGENCY;
    cfg->modules = 3;
    cfg->recovery_cycles = 10;
    cfg->max_overruns = 3;
    cfg->distance_tolerance_dm = 100;
    cfg->forget_ms = 7500;
    cfg->forget_single_ms = 1000;
    cfg->sensor_range_dm = 4000;
    cfg->distance_accuracy_dm = 500;
    cfg->closing_accuracy_cms = 100;
    cfg->plausibility_ms = 30000;
}

static int refuse(char *msg, size_t len, const char *name, long long value, const char *why)
{
    if (msg != NULL && len > 0) {
        snprintf(msg, len, "%s = %lld: %s", name, value, why);
    }
    return 1;
}

static const char DECEL_WHY[] = "a deceleration must be 1..20000 mm/s^2 (magnitude)";
static const char BAND_WHY[] = "must be 0 (no band) or a speed up to 12000 cm/s";
static const char TIME_WHY[] = "must be 0..30000 ms";
static const char FALL_WHY[] = "must not exceed the band below it: the guaranteed deceleration may only fall with speed";
static const char FACTOR_WHY[] =
    "a deceleration factor must be 1..1000 per mille (adverse conditions never brake better)";

/* the weakest guaranteed emergency deceleration over the speed bands */
static int64_t weakest_band(const rg_config *c)
{
    rg_band bands[RG_MAX_BANDS] = {{0, 0}, {0, 0}, {0, 0}};
    int32_t n = rg_emergency_bands(c, bands), i;
    int64_t a = bands[0].decel_mms2;
    for (i = 1; i < n; i++) {
        if (bands[i].decel_mms2 < a) a = bands[i].decel_mms2;
    }
    return a;
}

/* config.check's checks of the braking declaration, in its order */
static int check_declaration(const rg_config *c, char *msg, size_t len)
{
    int64_t g, weakest;
    if (c->emergency_decel_mms2 < 1 || c->emergency_decel_mms2 > 20000)
        return refuse(msg, len, "emergency_decel_mms2", c->emergency_decel_mms2, DECEL_WHY);
    if (c->service_decel_mms2 < 1 || c->service_decel_mms2 > 20000)
        return refuse(msg, len, "service_decel_mms2", c->service_decel_mms2, DECEL_WHY);
    if (c->emergency_band2_cms < 0 || c->emergency_band2_cms > RG_MAX_SPEED_CMS)
        return refuse(msg, len, "emergency_band2_cms", c->emergency_band2_cms, BAND_WHY);
    if (c->emergency_band3_cms < 0 || c->emergency_band3_cms > RG_MAX_SPEED_CMS)
        return refuse(msg, len, "emergency_band3_cms", c->emergency_band3_cms, BAND_WHY);
    if (c->emergency_band3_cms != 0
        && !(c->emergency_band3_cms > c->emergency_band2_cms && c->emergency_band2_cms > 0))
        return refuse(msg, len, "emergency_band3_cms", c->emergency_band3_cms,
                      "band 3 needs band 2 and must start above it");
    if (c->emergency_band2_cms != 0 && (c->emergency_band2_mms2 < 1 || c->emergency_band2_mms2 > 20000))
        return refuse(msg, len, "emergency_band2_mms2", c->emergency_band2_mms2, DECEL_WHY);
    if (c->emergency_band3_cms != 0 && (c->emergency_band3_mms2 < 1 || c->emergency_band3_mms2 > 20000))
        return refuse(msg, len, "emergency_band3_mms2", c->emergency_band3_mms2, DECEL_WHY);
    /* the equivalent build-up covers a linear ramp only if the deceleration never rises with speed */
    if (c->emergency_band2_cms != 0 && c->emergency_band2_mms2 > c->emergency_decel_mms2)
        return refuse(msg, len, "emergency_band2_mms2", c->emergency_band2_mms2, FALL_WHY);
    if (c->emergency_band3_cms != 0 && c->emergency_band3_mms2 > c->emergency_band2_mms2)
        return refuse(msg, len, "emergency_band3_mms2", c->emergency_band3_mms2, FALL_WHY);
    weakest = weakest_band(c);
    if (c->service_decel_mms2 > weakest)
        return refuse(msg, len, "service_decel_mms2", c->service_decel_mms2,
                      "must not exceed the guaranteed emergency deceleration of any speed band");
    if (c->emergency_buildup_ms < 0 || c->emergency_buildup_ms > 30000)
        return refuse(msg, len, "emergency_buildup_ms", c->emergency_buildup_ms, TIME_WHY);
    if (c->service_buildup_ms < 0 || c->service_buildup_ms > 30000)
        return refuse(msg, len, "service_buildup_ms", c->service_buildup_ms, TIME_WHY);
    if (c->traction_cutoff_ms < 0 || c->traction_cutoff_ms > 30000)
        return refuse(msg, len, "traction_cutoff_ms", c->traction_cutoff_ms, TIME_WHY);
    if (c->max_accel_mms2 < 0 || c->max_accel_mms2 > 5000)
        return refuse(msg, len, "max_accel_mms2", c->max_accel_mms2, "must be 0..5000 mm/s^2");
    if (c->speed_error_permille < 0 || c->speed_error_permille > 500)
        return refuse(msg, len, "speed_error_permille", c->speed_error_permille,
                      "must be 0..500 (per mille of the speed)");
    if (c->slippery_permille < 1 || c->slippery_permille > 1000)
        return refuse(msg, len, "slippery_permille", c->slippery_permille, FACTOR_WHY);
    if (c->degraded_permille < 1 || c->degraded_permille > 1000)
        return refuse(msg, len, "degraded_permille", c->degraded_permille, FACTOR_WHY);
    if (c->max_gradient_permille < 0 || c->max_gradient_permille > 60)
        return refuse(msg, len, "max_gradient_permille", c->max_gradient_permille,
                      "must be 0..60 per mille (downhill)");
    if (c->standstill_margin_dm < 0 || c->standstill_margin_dm > 10000)
        return refuse(msg, len, "standstill_margin_dm", c->standstill_margin_dm, "must be 0..10000 dm");
    g = rg_gradient_accel_mms2(c->max_gradient_permille);
    if (weakest * c->slippery_permille * c->degraded_permille / 1000000 - g < RG_MIN_GUARANTEED_DECEL_MMS2)
        return refuse(msg, len, "max_gradient_permille", c->max_gradient_permille,
                      "on this downhill with slippery track and degraded brakes the guaranteed deceleration is "
                      "below 100 mm/s^2: the train cannot be said to stop");
    if ((int64_t)c->service_decel_mms2 * c->slippery_permille * c->degraded_permille / 1000000 - g
        < RG_MIN_GUARANTEED_DECEL_MMS2)
        return refuse(msg, len, "service_decel_mms2", c->service_decel_mms2,
                      "too weak to stop the train on the steepest downhill with slippery track and degraded brakes");
    return 0;
}

int rg_config_check(const rg_config *c, char *msg, size_t len)
{
    if (c->modules != 3 && c->modules != 1)
        return refuse(msg, len, "modules", c->modules,
                      "must be 3 (3oo3 over three 2oo2 modules) or 1 (one 2oo2 module)");
    if (c->period_ms < 1 || c->period_ms > 10000)
        return refuse(msg, len, "period_ms", c->period_ms, "must be 1..10000 ms");
    if (c->timeout_cycles < 1)
        return refuse(msg, len, "timeout_cycles", c->timeout_cycles,
                      "must be at least 1 cycle (0 would make every report stale)");
    if ((int64_t)c->timeout_cycles * c->period_ms > RG_MAX_AGE_MS)
        return refuse(msg, len, "timeout_cycles", c->timeout_cycles,
                      "a report may be at most 60 s old (timeout_cycles x period_ms > 60000 ms)");
    if (c->persistence_cycles < 1 || c->persistence_cycles > 1000)
        return refuse(msg, len, "persistence_cycles", c->persistence_cycles, "must be 1..1000 cycles");
    if (check_declaration(c, msg, len) != 0) return 1;
    if (c->warning_ms < 0 || c->warning_ms > 60000)
        return refuse(msg, len, "warning_ms", c->warning_ms, "must be 0..60000 ms");
    if (c->emergency_release != RG_RELEASE_AT_STANDSTILL && c->emergency_release != RG_RELEASE_REVOCABLE)
        return refuse(msg, len, "emergency_release", c->emergency_release,
                      "must be 0 (held to standstill) or 1 (revocable when its cause is gone)");
    if (c->release_confirm_cycles < 1 || c->release_confirm_cycles > 1000)
        return refuse(msg, len, "release_confirm_cycles", c->release_confirm_cycles, "must be 1..1000 cycles");
    if (c->warning_margin_dm < 0 || c->warning_margin_dm > 60000)
        return refuse(msg, len, "warning_margin_dm", c->warning_margin_dm, "must be 0..60000 dm");
    if (c->fast_closing_cms < 1 || c->fast_closing_cms > 15000)
        return refuse(msg, len, "fast_closing_cms", c->fast_closing_cms, "must be 1..15000 cm/s");
    if (c->safe_reaction != RG_SERVICE && c->safe_reaction != RG_EMERGENCY)
        return refuse(msg, len, "safe_reaction", c->safe_reaction, "must be 1 (service) or 2 (emergency)");
    if (c->recovery_cycles < 1 || c->recovery_cycles > 100000)
        return refuse(msg, len, "recovery_cycles", c->recovery_cycles, "must be 1..100000 cycles");
    if (c->max_overruns < 1 || c->max_overruns > 1000)
        return refuse(msg, len, "max_overruns", c->max_overruns, "must be 1..1000");
    if (c->distance_tolerance_dm < 0 || c->distance_tolerance_dm > 60000)
        return refuse(msg, len, "distance_tolerance_dm", c->distance_tolerance_dm, "must be 0..60000 dm");
    if (c->forget_ms < 1 || c->forget_ms > 600000)
        return refuse(msg, len, "forget_ms", c->forget_ms, "must be 1..600000 ms (10 min; rounded up to whole cycles)");
    if (c->forget_single_ms < 1 || c->forget_single_ms > 600000)
        return refuse(msg, len, "forget_single_ms", c->forget_single_ms,
                      "must be 1..600000 ms (at most forget_ms counts; rounded up to whole cycles)");
    if (c->sensor_range_dm < 1 || c->sensor_range_dm > RG_MAX_DISTANCE_DM)
        return refuse(msg, len, "sensor_range_dm", c->sensor_range_dm, "must be 1..60000 dm");
    if (c->distance_accuracy_dm < 0 || c->distance_accuracy_dm > 60000)
        return refuse(msg, len, "distance_accuracy_dm", c->distance_accuracy_dm, "must be 0..60000 dm");
    if (c->closing_accuracy_cms < 0 || c->closing_accuracy_cms > 15000)
        return refuse(msg, len, "closing_accuracy_cms", c->closing_accuracy_cms, "must be 0..15000 cm/s");
    if (c->plausibility_ms < 1 || c->plausibility_ms > 60000)
        return refuse(msg, len, "plausibility_ms", c->plausibility_ms, "must be 1..60000 ms");
    return 0;
}

static int table_refuse(char *msg, size_t len, const char *why)
{
    if (msg != NULL && len > 0) {
        snprintf(msg, len, "table refused: %s", why);
    }
    return 1;
}

static uint32_t next_node(const rg_table *t, uint32_t node, uint32_t obs)
{
    uint32_t at = t->next_offset + (node * t->observations + obs) * t->index_bytes;
    uint32_t value = t->bytes[at];
    if (t->index_bytes == 2) {
        value |= (uint32_t)t->bytes[at + 1] << 8;
    }
    return value;
}

static uint32_t node_risk(const rg_table *t, uint32_t node)
{
    uint32_t at = t->risk_offset + 4u * node;
    return (uint32_t)t->bytes[at] | ((uint32_t)t->bytes[at + 1] << 8)
        | ((uint32_t)t->bytes[at + 2] << 16) | ((uint32_t)t->bytes[at + 3] << 24);
}

int rg_table_check(const rg_table *t, const rg_config *cfg, char *msg, size_t len)
{
    static const uint8_t magic[8] = {'R', 'G', 'T', 'A', 'B', 'L', 'E', '\n'};
    uint8_t digest[32];
    uint32_t i, node, obs, body_end;
    if (t->bytes == NULL || t->length < 8 + 2 + 4 + 32)
        return table_refuse(msg, len, "too short to be a table");
    for (i = 0; i < 8; i++) {
        if (t->bytes[i] != magic[i])
            return table_refuse(msg, len, "not a railguard table (bad magic bytes)");
    }
    if ((t->bytes[8] | (t->bytes[9] << 8)) != 2)
        return table_refuse(msg, len, "table format version is not 2 (format 1 has no risk column: railguard table upgrade FILE)");
    rg_sha256(t->bytes, t->length - 32, digest);
    for (i = 0; i < 32; i++) {
        if (digest[i] != t->bytes[t->length - 32 + i])
            return table_refuse(msg, len, "corrupted: SHA-256 over the content does not match the one stored in it");
    }
    if (t->model != RG_MODEL_M1 && t->model != RG_MODEL_M2)
        return table_refuse(msg, len, "unknown model");
    if (t->observations != (t->model == RG_MODEL_M1 ? RG_M1_OBSERVATIONS : RG_M2_OBSERVATIONS))
        return table_refuse(msg, len, "observation count does not match the model");
    if (t->nodes < 1 || t->nodes > 65536 || (t->index_bytes != 1 && t->index_bytes != 2) || t->start >= t->nodes)
        return table_refuse(msg, len, "bad dimensions");
    body_end = t->next_offset + t->nodes * t->observations * t->index_bytes;
    if (t->action_offset + t->nodes != t->next_offset || body_end != t->risk_offset
        || t->risk_offset + 4u * t->nodes != t->length - 32)
        return table_refuse(msg, len, "body does not fit the dimensions");
    for (node = 0; node < t->nodes; node++) {
        if (t->bytes[t->action_offset + node] > RG_EMERGENCY)
            return table_refuse(msg, len, "an action index is >= the 3 actions");
        for (obs = 0; obs < t->observations; obs++) {
            if (next_node(t, node, obs) >= t->nodes)
                return table_refuse(msg, len, "a next-node index is >= the number of nodes");
        }
        if (node_risk(t, node) > RG_PPM)
            return table_refuse(msg, len, "a node's risk is above 1000000 ppm");
    }
    if (t->period_ms != cfg->period_ms)
        return table_refuse(msg, len, "table was solved for a different time step than period_ms");
    return 0;
}

void rg_initial_state(const rg_table *t, const rg_config *cfg, rg_state *s)
{
    int32_t m;
    (void)cfg;
    s->mode = RG_INIT;
    s->node = (int32_t)t->start;
    s->held = RG_MAINTAIN;
    s->seen = 0;
    for (m = 0; m < RG_MAX_MODULES; m++) {
        s->disagree[m] = 0;
        s->agree[m] = 0;
    }
    s->healthy = 0;
    s->cycle = 0;
    s->error_cycles = 0;
    s->calm = 0;
    s->table_held = RG_MAINTAIN;
    for (m = 0; m < RG_TRACKS; m++) {   /* every slot empty (types.NO_TRACKS) */
        s->tracks[m].near = RG_NO_TRACK;
        s->tracks[m].far = RG_NO_TRACK;
        s->tracks[m].closing = s->tracks[m].cycles = 0;
        s->tracks[m].absent = s->tracks[m].strong = 0;
    }
    s->kept = 0;
    for (m = 0; m < RG_MAX_CHANNELS; m++) rg_plausibility(&s->plaus[m], 0, 0, 0, 0, 0, 0, 1);
}

/* config.py's forget_cycles: cycles of evidence that make forget_ms (`single`: the lesser
 * of forget_single_ms and forget_ms), rounded up (never forget early). At least 1 (an
 * accepted configuration has both >= 1, so the guard never acts; EVA, which does not
 * relate the fields, needs it for rg_forget). */
int32_t rg_forget_cycles(const rg_config *cfg, int32_t single)
{
    const int64_t period = cfg->period_ms < 1 ? 1 : cfg->period_ms;
    const int64_t ms = single && cfg->forget_single_ms < cfg->forget_ms ? cfg->forget_single_ms : cfg->forget_ms;
    const int64_t n = (ms + period - 1) / period;
    return n < 1 ? 1 : (n > RG_MAX_COUNT ? RG_MAX_COUNT : (int32_t)n);
}

/*@ assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 <==> rg_in_range_p(status, distance_dm, closing_cms, obstacle);
*/
int32_t rg_in_range(int32_t status, int32_t distance_dm, int32_t closing_cms, int32_t obstacle)
{
    return RG_ABSENT <= status && status <= RG_DEGRADED && 0 <= distance_dm && distance_dm <= RG_MAX_DISTANCE_DM &&
           -RG_MAX_CLOSING_CMS <= closing_cms && closing_cms <= RG_MAX_CLOSING_CMS && 0 <= obstacle && obstacle <= 2;
}

/*@ assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 <==> rg_fresh_p(received, now, timeout_ticks);
*/
int32_t rg_is_fresh(int64_t received, int64_t now, int64_t timeout_ticks)
{
    /* received <= now && now - received <= timeout_ticks, for every int64 tick without an
     * overflow: the difference is only formed when 0 <= received <= now; for received < 0
     * the bound moves to the other side, where timeout_ticks >= 0 keeps the sum in range
     * (a negative timeout_ticks makes no report fresh, as now - received >= 0). */
    if (received >= 0) return received <= now && now - received <= timeout_ticks;
    return received <= now && timeout_ticks >= 0 && now <= timeout_ticks + received;
}

/*@ requires \valid_read(r);
    assigns \nothing;
    ensures \result == 0 || \result == 1 || \result == 2;
    ensures \result == 2 || (\result == r->status && r->heard != 0 && rg_fresh_p(r->tick, now, timeout_ticks));
    ensures r->status == 1 && r->heard != 0 && rg_fresh_p(r->tick, now, timeout_ticks) ==> \result >= 1;
    ensures r->heard != 0 && rg_fresh_p(r->tick, now, timeout_ticks)
            && rg_in_range_p(r->status, r->distance_dm, r->closing_cms, r->obstacle) ==> \result == r->status;
    ensures !(r->heard != 0 && rg_fresh_p(r->tick, now, timeout_ticks)
              && rg_in_range_p(r->status, r->distance_dm, r->closing_cms, r->obstacle)) ==> \result == 2;
*/
int32_t rg_effective_status(const rg_report *r, int64_t now, int64_t timeout_ticks)
{
    if (!r->heard || !rg_is_fresh(r->tick, now, timeout_ticks))
        return RG_DEGRADED;
    if (!rg_in_range(r->status, r->distance_dm, r->closing_cms, r->obstacle))
        return RG_DEGRADED;
    return r->status;
}

/*@ requires \valid(status) && \valid(distance) && \valid(flag);
    requires \separated(status, distance, flag);
    assigns *status, *distance, *flag;
    ensures *status == \max(sa, sb);
    ensures *flag == 0 || *flag == 1;
    ensures *flag == 1 <==> (sa != sb || sa == 2 || sb == 2);
    ensures sa == 1 && sb == 1 ==> *distance == \min(da, db);
    ensures sa == 1 && sb != 1 ==> *distance == da;
    ensures sb == 1 && sa != 1 ==> *distance == db;
    ensures sa != 1 && sb != 1 ==> *distance == 65535;
    ensures sa == 1 || sb == 1 ==> *status >= 1;
*/
void rg_vote_2oo2(int32_t sa, int32_t da, int32_t sb, int32_t db, int32_t *status, int32_t *distance, int32_t *flag)
{
    *status = sa > sb ? sa : sb;
    if (sa == RG_PRESENT && sb == RG_PRESENT) {
        *distance = da < db ? da : db;
    } else if (sa == RG_PRESENT) {
        *distance = da;
    } else if (sb == RG_PRESENT) {
        *distance = db;
    } else {
        *distance = RG_NO_DISTANCE;
    }
    *flag = sa != sb || sa == RG_DEGRADED || sb == RG_DEGRADED;
}

/*@ assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 <==> ((sa == 0 && sb == 1) || (sa == 1 && sb == 0));
*/
int32_t rg_disagreement(int32_t sa, int32_t sb)
{
    return (sa == RG_ABSENT && sb == RG_PRESENT) || (sa == RG_PRESENT && sb == RG_ABSENT);
}

/*@ assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 <==> (sa == 1 && sb == 1 && (da - db > tolerance_dm || db - da > tolerance_dm));
*/
int32_t rg_distances_disagree(int32_t sa, int32_t da, int32_t sb, int32_t db, int32_t tolerance_dm)
{
    int64_t diff = (int64_t)da - (int64_t)db;
    return sa == RG_PRESENT && sb == RG_PRESENT && (diff > tolerance_dm || -diff > tolerance_dm);
}

/*@ requires \valid_read(s + (0 .. 2)) && \valid_read(d + (0 .. 2)) && \valid_read(f + (0 .. 2));
    requires \valid(status) && \valid(distance) && \valid(error);
    requires \separated(status, distance, error, s + (0 .. 2), d + (0 .. 2), f + (0 .. 2));
    assigns *status, *distance, *error;
    ensures *status == rg_max3(s[0], s[1], s[2]);
    ensures *distance == rg_min3(d[0], d[1], d[2]);
    ensures *error == 0 || *error == 1;
    ensures *error == 1 <==> (f[0] != 0 || f[1] != 0 || f[2] != 0 || s[0] != s[1] || s[1] != s[2]
                              || rg_max3(s[0], s[1], s[2]) == 2);
    ensures s[0] != s[1] || s[1] != s[2] ==> *error == 1;
*/
void rg_vote_3oo3(const int32_t s[3], const int32_t d[3], const int32_t f[3],
                  int32_t *status, int32_t *distance, int32_t *error)
{
    int32_t st = s[0];
    int32_t dist = d[0];
    if (s[1] > st) st = s[1];
    if (s[2] > st) st = s[2];
    if (d[1] < dist) dist = d[1];
    if (d[2] < dist) dist = d[2];
    *status = st;
    *distance = dist;
    *error = f[0] || f[1] || f[2] || s[0] != s[1] || s[1] != s[2] || st == RG_DEGRADED;
}

/*@ requires 0 <= limit <= 60000;
    assigns \nothing;
    ensures 0 <= \result <= limit;
    ensures rg_fresh_p(received, now, limit) ==> \result == now - received;
*/
int32_t rg_age_ms(int64_t received, int64_t now, int64_t limit)
{
    /* the age of a fresh report, now - received, for every int64 tick without an overflow
     * (as in rg_is_fresh); anything older reads as `limit` */
    int64_t d;
    if (received >= 0) {
        if (now < received) return 0;
        d = now - received;
    } else if (now < 0) {
        if (now < received) return 0;
        d = now - received;
    } else if (now > limit || received < now - limit) {
        return (int32_t)limit;
    } else {
        d = now - received;
    }
    /* (d >= 0 in every branch; EVA, which does not relate d to the branch taken, reads
     * the range from these two tests) */
    if (d < 0) d = 0;
    return d < limit ? (int32_t)d : (int32_t)limit;
}

/*@ requires 0 <= gradient_permille <= 60;
    assigns \nothing;
    ensures \result * 1000 >= 9810 * gradient_permille;
    ensures (\result - 1) * 1000 < 9810 * gradient_permille || \result == 0;
*/
int32_t rg_gradient_accel_mms2(int32_t gradient_permille)
{
    return (9810 * gradient_permille + 999) / 1000;
}

int32_t rg_emergency_bands(const rg_config *cfg, rg_band bands[RG_MAX_BANDS])
{
    int32_t n = 1;
    bands[0].from_cms = 0;
    bands[0].decel_mms2 = cfg->emergency_decel_mms2;
    if (cfg->emergency_band2_cms != 0) {
        bands[1].from_cms = cfg->emergency_band2_cms;
        bands[1].decel_mms2 = cfg->emergency_band2_mms2;
        n = 2;
        if (cfg->emergency_band3_cms != 0) {
            bands[2].from_cms = cfg->emergency_band3_cms;
            bands[2].decel_mms2 = cfg->emergency_band3_mms2;
            n = 3;
        }
    }
    return n;
}

/*@ requires 0 <= decel_mms2 <= 20000 && 0 <= factor_permille <= 1000;
    assigns \nothing;
    ensures 0 <= \result <= decel_mms2;
    ensures \result * 1000 <= decel_mms2 * factor_permille;
    ensures (\result + 1) * 1000 > decel_mms2 * factor_permille;
*/
int64_t rg_scaled_decel_mms2(int64_t decel_mms2, int64_t factor_permille)
{
    return decel_mms2 * factor_permille / 1000;
}

/*@ requires 0 <= decel_mms2 <= 20000 && 1 <= slippery_permille <= 1000 && 1 <= degraded_permille <= 1000;
    requires 0 <= gradient_mms2 <= 1000;
    assigns \nothing;
    ensures \result <= decel_mms2 - gradient_mms2;
    ensures \result >= -gradient_mms2;
    ensures track == 0 && brake == 0 ==> \result == decel_mms2 - gradient_mms2;
*/
int64_t rg_effective_decel_mms2(int64_t decel_mms2, int32_t track, int32_t brake, int64_t slippery_permille,
                                int64_t degraded_permille, int64_t gradient_mms2)
{
    int64_t a = track ? rg_scaled_decel_mms2(decel_mms2, slippery_permille) : decel_mms2;
    if (brake) a = rg_scaled_decel_mms2(a, degraded_permille);
    return a - gradient_mms2;
}

/*@ requires 0 <= speed_cms <= 1000000 && 0 <= accel_mms2 <= 10000 && 0 <= time_ms <= 200000;
    assigns \nothing;
    ensures \result >= 0;
    ensures \result * 200000000 >= rg_run_num(speed_cms, accel_mms2, time_ms);
    ensures (\result - 1) * 200000000 < rg_run_num(speed_cms, accel_mms2, time_ms);
*/
int64_t rg_run_dm(int64_t speed_cms, int64_t accel_mms2, int64_t time_ms)
{
    /* v t + a t^2 / 2 in dm, rounded up: cm/s x ms = 1e-5 m, mm/s^2 x ms^2 = 1e-9 m */
    int64_t num = 2 * speed_cms * time_ms * 10000 + accel_mms2 * time_ms * time_ms;
    return (num + 199999999) / 200000000;
}

/*@ requires 0 <= speed_cms <= 1000000 && 0 <= accel_mms2 <= 10000 && 0 <= time_ms <= 200000;
    assigns \nothing;
    ensures \result >= speed_cms;
    ensures (\result - speed_cms) * 10000 >= accel_mms2 * time_ms;
    ensures (\result - speed_cms - 1) * 10000 < accel_mms2 * time_ms;
*/
int64_t rg_speed_after_cms(int64_t speed_cms, int64_t accel_mms2, int64_t time_ms)
{
    return speed_cms + (accel_mms2 * time_ms + 9999) / 10000;
}

/*@ requires 0 <= speed_cms <= 1000000 && 0 <= lo_cms && 1 <= decel_mms2 <= 20000;
    requires \valid(dist_dm) && \valid(time_ms) && \separated(dist_dm, time_ms);
    assigns *dist_dm, *time_ms;
    ensures *dist_dm >= 0 && *time_ms >= 0;
    ensures speed_cms <= lo_cms ==> *dist_dm == 0 && *time_ms == 0;
*/
void rg_band_stop(int64_t speed_cms, int64_t lo_cms, int64_t hi_cms, int64_t decel_mms2, int64_t *dist_dm,
                  int64_t *time_ms)
{
    /* the part [lo, top) of the band below the speed; (top + lo) (top - lo) = top^2 - lo^2,
     * Python's numerator, written so that EVA sees it is positive */
    int64_t top = (hi_cms < 0 || speed_cms < hi_cms) ? speed_cms : hi_cms;
    int64_t span = top - lo_cms;
    if (span <= 0) {
        *dist_dm = 0;
        *time_ms = 0;
        return;
    }
    *dist_dm = ((top + lo_cms) * span + 2 * decel_mms2 - 1) / (2 * decel_mms2);   /* (cm/s)^2 / (mm/s^2) = dm */
    *time_ms = (span * 10000 + decel_mms2 - 1) / decel_mms2;                      /* (cm/s) / (mm/s^2) = 10 s */
}

void rg_stop_dm_ms(int64_t speed_cms, const rg_band *bands, int32_t count, int64_t *dist_dm, int64_t *time_ms)
{
    int32_t i;
    *dist_dm = 0;
    *time_ms = 0;
    for (i = 0; i < count; i++) {
        int64_t d, t;
        rg_band_stop(speed_cms, bands[i].from_cms, i + 1 < count ? bands[i + 1].from_cms : -1, bands[i].decel_mms2,
                     &d, &t);
        *dist_dm += d;
        *time_ms += t;
    }
}

/*@ requires obstacle_cms <= 1000000 && 0 <= time_ms <= 10000000000;
    assigns \nothing;
    ensures \result >= 0;
    ensures obstacle_cms <= 0 ==> \result == 0;
    ensures obstacle_cms > 0 ==> \result * 10000 >= obstacle_cms * time_ms;
    ensures obstacle_cms > 0 ==> (\result - 1) * 10000 < obstacle_cms * time_ms;
*/
int64_t rg_obstacle_run_dm(int64_t obstacle_cms, int64_t time_ms)
{
    if (obstacle_cms <= 0) return 0;
    return (obstacle_cms * time_ms + 9999) / 10000;
}

/*@ requires x >= 0;
    assigns \nothing;
    ensures \result == \min(x, 1000000);
*/
int32_t rg_cap_dm(int64_t x)
{
    return x < RG_CURVE_CAP_DM ? (int32_t)x : RG_CURVE_CAP_DM;
}

/* The brake's bands under the reported conditions: the emergency bands, or the service
 * brake alone (one band). Never below 1 mm/s^2: an accepted configuration guarantees at
 * least 99 (config.check's worst case, less one for the two roundings), so this guard
 * changes nothing there; it keeps the division in rg_band_stop defined for EVA, which
 * analyses each configuration field over its range on its own. */
static int32_t conditioned_bands(const rg_config *cfg, int32_t track, int32_t brake, int32_t service, int64_t g,
                                 rg_band bands[RG_MAX_BANDS])
{
    int32_t n = 1, i;
    if (service) {
        bands[0].from_cms = 0;
        bands[0].decel_mms2 = cfg->service_decel_mms2;
    } else {
        n = rg_emergency_bands(cfg, bands);
    }
    for (i = 0; i < RG_MAX_BANDS; i++) {   /* (the unused ones too: EVA merges the band index) */
        int64_t a = rg_effective_decel_mms2(bands[i].decel_mms2, track, brake, cfg->slippery_permille,
                                            cfg->degraded_permille, g);
        bands[i].decel_mms2 = a < 1 ? 1 : a;
    }
    return n;
}

void rg_curves(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
               int32_t age_ms, int32_t service, int32_t supervised, rg_curve_set *out)
{
    rg_band bands[RG_MAX_BANDS] = {{0, 0}, {0, 0}, {0, 0}};   /* (whole: EVA merges the band index) */
    const int64_t v = speed_cms, e = cfg->speed_error_permille;
    const int64_t v_max = (v * (1000 + e) + 999) / 1000;
    const int64_t v_min = v * (1000 - e) / 1000;
    const int64_t periods = supervised ? RG_SUPERVISED_PERIODS : RG_ZONE_PERIODS;
    /* the error budget of the supervised curves: the obstacle may be distance_accuracy_dm
       nearer than reported and close closing_accuracy_cms faster than measured */
    const int64_t near_dm = supervised ? cfg->distance_accuracy_dm : 0;
    const int64_t obstacle = (int64_t)closing_cms + (supervised ? cfg->closing_accuracy_cms : 0)
                             - v_min;                   /* the obstacle's own speed towards us */
    const int64_t g = rg_gradient_accel_mms2(cfg->max_gradient_permille);
    const int32_t n = conditioned_bands(cfg, track, brake, service, g, bands);
    const int64_t buildup = service ? cfg->service_buildup_ms : cfg->emergency_buildup_ms;
    int64_t t1, a1, s1, v1, t2, s2, v2, s3, t3, ebi, ebd_dist, ebd_time, ebd, lead, sbi;
    /* phase 1: report age + `periods` monitor periods (RG_SUPERVISED_PERIODS: a stalled
       monitor's; RG_ZONE_PERIODS for the table's zone limits: the demand's) +
       traction cut-off, under full traction and downhill */
    t1 = (int64_t)age_ms + periods * cfg->period_ms + cfg->traction_cutoff_ms;
    a1 = (int64_t)cfg->max_accel_mms2 + g;
    s1 = rg_run_dm(v_max, a1, t1);
    v1 = rg_speed_after_cms(v_max, a1, t1);
    /* phase 2: rest of the brake's equivalent build-up, coasting downhill */
    t2 = buildup - cfg->traction_cutoff_ms;
    if (t2 < 0) t2 = 0;
    s2 = rg_run_dm(v1, g, t2);
    v2 = rg_speed_after_cms(v1, g, t2);
    /* phase 3: guaranteed braking to standstill */
    rg_stop_dm_ms(v2, bands, n, &s3, &t3);
    ebi = s1 + s2 + s3 + cfg->standstill_margin_dm + rg_obstacle_run_dm(obstacle, t1 + t2 + t3) + near_dm;
    rg_stop_dm_ms(v, bands, n, &ebd_dist, &ebd_time);
    ebd = ebd_dist + cfg->standstill_margin_dm + near_dm + rg_obstacle_run_dm(obstacle, ebd_time);
    lead = v_max + (obstacle > 0 ? obstacle : 0);
    sbi = ebi + rg_run_dm(lead, 0, cfg->service_buildup_ms);
    out->ebd_dm = rg_cap_dm(ebd);
    out->ebi_dm = rg_cap_dm(ebi);
    out->sbi_dm = rg_cap_dm(sbi);
    out->warning_dm = rg_cap_dm(sbi + rg_run_dm(lead, 0, cfg->warning_ms));
}

/*@ assigns \nothing;
    ensures 0 <= \result <= 3;
    ensures \result == 3 <==> distance_dm <= alpha2_dm;
    ensures alpha2_dm <= alpha1_dm ==> (\result >= 2 <==> distance_dm <= alpha1_dm);
    ensures alpha2_dm <= alpha1_dm && warning_dm >= 0 ==> (\result >= 1 <==> distance_dm <= alpha1_dm + warning_dm);
*/
int32_t rg_zone(int32_t distance_dm, int32_t alpha1_dm, int32_t alpha2_dm, int32_t warning_dm)
{
    if (distance_dm <= alpha2_dm) return 3;
    if (distance_dm <= alpha1_dm) return 2;
    if ((int64_t)distance_dm <= (int64_t)alpha1_dm + warning_dm) return 1;
    return 0;
}

/*@ requires \valid(warn);
    assigns *warn;
    ensures 0 <= \result <= 2 && (*warn == 0 || *warn == 1);
    ensures present != 0 && distance_dm <= ebi_dm ==> \result == 2;
    ensures present != 0 && distance_dm <= sbi_dm ==> \result >= 1;
    ensures held != 0 && present != 0 && distance_dm <= sbi_dm ==> \result == 2;
    ensures present == 0 ==> \result == 0 && *warn == 0;
    ensures 0 <= ebi_dm <= sbi_dm <= warning_dm ==> (*warn == 1 <==> (present != 0 && distance_dm <= warning_dm));
    ensures ebi_dm <= sbi_dm && present != 0 && distance_dm > sbi_dm ==> \result == 0;
    ensures held == 0 && present != 0 && distance_dm > ebi_dm ==> \result <= 1;
    ensures present != 0 && distance_dm > ebi_dm && distance_dm > sbi_dm ==> \result == 0;
*/
int32_t rg_supervision_demand(int32_t present, int32_t distance_dm, int32_t ebi_dm, int32_t sbi_dm, int32_t warning_dm,
                              int32_t held, int32_t *warn)
{
    if (!present) {
        *warn = 0;
        return RG_MAINTAIN;
    }
    if (distance_dm <= ebi_dm || (held && distance_dm <= sbi_dm)) {
        *warn = 1;
        return RG_EMERGENCY;
    }
    if (distance_dm <= sbi_dm) {
        *warn = 1;
        return RG_SERVICE;
    }
    *warn = distance_dm <= warning_dm;
    return RG_MAINTAIN;
}

/*@ assigns \nothing;
    ensures \result >= envelope && \result >= table_demand && \result >= error_demand;
    ensures \result == table_demand || \result == envelope || \result == error_demand;
    ensures \result == rg_max3(table_demand, envelope, error_demand);
*/
int32_t rg_combine(int32_t table_demand, int32_t envelope, int32_t error_demand)
{
    int32_t d = table_demand;
    if (envelope > d) d = envelope;
    if (error_demand > d) d = error_demand;
    return d;
}

/* The supervised demand (cycle.py): the curves supervise the voted obstacle and, unless a
 * confirmed picture has just replaced it (`remembered` == 0), the remembered one, each on
 * its own curves (the remembered one's with its remembered closing speed and report age);
 * the higher demand counts. `held` is the level held so far: while an emergency is held
 * the obstacle must be back beyond SBI. So a demand a curve raised is never lowered by this
 * function while the train is inside that curve for the remembered obstacle, whatever the
 * voted picture says; rg_combine and rg_hold pass it on (rg_decide). RG_NO_DISTANCE
 * (65535) is "no voted obstacle". */
/*@ requires \valid(warn);
    assigns *warn;
    ensures 0 <= \result <= 2 && (*warn == 0 || *warn == 1);
    ensures remembered != 0 && track_dm <= track_ebi_dm ==> \result == 2;
    ensures remembered != 0 && track_dm <= track_sbi_dm ==> \result >= 1;
    ensures held == 2 && remembered != 0 && track_dm <= track_sbi_dm ==> \result == 2;
    ensures voted_dm != 65535 && voted_dm <= voted_ebi_dm ==> \result == 2;
    ensures voted_dm != 65535 && voted_dm <= voted_sbi_dm ==> \result >= 1;
    ensures held == 2 && voted_dm != 65535 && voted_dm <= voted_sbi_dm ==> \result == 2;
    ensures \result >= 1 ==> (remembered != 0 && (track_dm <= track_ebi_dm || track_dm <= track_sbi_dm))
                             || (voted_dm != 65535 && (voted_dm <= voted_ebi_dm || voted_dm <= voted_sbi_dm));
    ensures voted_dm == 65535 && remembered == 0 ==> \result == 0 && *warn == 0;
*/
int32_t rg_supervised_demand(int32_t voted_dm, int32_t voted_ebi_dm, int32_t voted_sbi_dm, int32_t voted_warning_dm,
                             int32_t remembered, int32_t track_dm, int32_t track_ebi_dm, int32_t track_sbi_dm,
                             int32_t track_warning_dm, int32_t held, int32_t *warn)
{
    const int32_t latched = held == RG_EMERGENCY;
    int32_t demand = RG_MAINTAIN, w = 0, track_demand, track_warn = 0;
    if (voted_dm != RG_NO_DISTANCE)
        demand = rg_supervision_demand(1, voted_dm, voted_ebi_dm, voted_sbi_dm, voted_warning_dm, latched, &w);
    if (remembered) {
        track_demand = rg_supervision_demand(1, track_dm, track_ebi_dm, track_sbi_dm, track_warning_dm, latched,
                                             &track_warn);
        if (track_demand > demand) demand = track_demand;
        if (track_warn) w = 1;
    }
    *warn = w;
    return demand;
}

/* envelope.hold: a demand, once raised, is held while the train moves and lowered only
 * after the causes have asked for less for `confirm` cycles in a row (`calm` counts them);
 * an emergency only if `revocable`, else at standstill. Returns the new level (= the
 * final demand). `calm + 1` is never formed when it reaches `confirm`: no overflow for
 * any int32. */
/*@ requires confirm >= 1;
    requires \valid(calm_out) && \valid(final_demand) && \separated(calm_out, final_demand);
    assigns *calm_out, *final_demand;
    ensures *final_demand >= demand;
    ensures *final_demand == \result;
    ensures speed_cms <= 0 ==> \result == demand && *calm_out == 0;
    ensures demand == 2 && level <= 2 ==> \result == 2 && *calm_out == 0;
    ensures demand >= level ==> \result == demand && *calm_out == 0;
    ensures 0 <= demand <= 2 && level == 2 && speed_cms > 0 && revocable == 0 ==> \result == 2;
    ensures speed_cms > 0 && calm + 1 < confirm ==> \result >= level;
    ensures \result < level ==> speed_cms <= 0 || calm + 1 >= confirm;
    ensures \result == level || \result == demand;
    ensures *calm_out < confirm && (*calm_out == 0 || *calm_out == calm + 1);
    ensures calm >= 0 ==> *calm_out >= 0;
*/
int32_t rg_hold(int32_t level, int32_t calm, int32_t demand, int32_t speed_cms, int32_t revocable, int32_t confirm,
                int32_t *calm_out, int32_t *final_demand)
{
    int32_t out = level, count = 0;
    if (speed_cms <= 0 || demand >= level) {
        out = demand;
    } else if (level == RG_EMERGENCY && !revocable) {
        out = level;
    } else if (calm >= confirm - 1) {
        out = demand;            /* calm + 1 >= confirm: released */
    } else {
        count = calm + 1;
    }
    *calm_out = count;
    *final_demand = out;
    return out;
}

/* envelope.table_hold: what the table raised is lowered only once the voted picture has left
 * the table's zones (`zone_free`: observed zone 0), or at standstill. */
/*@ assigns \nothing;
    ensures \result >= demand;
    ensures \result == level || \result == demand;
    ensures speed_cms > 0 && zone_free == 0 ==> \result >= level;
    ensures speed_cms <= 0 || zone_free != 0 ==> \result == demand;
*/
int32_t rg_table_hold(int32_t level, int32_t demand, int32_t speed_cms, int32_t zone_free)
{
    if (demand >= level || speed_cms <= 0 || zone_free) return demand;
    return level;
}

/* The cycle's decision (cycle.py step 7 without INIT's emergency): the curves' demand for
 * the supervised obstacle, raised by the table's and the error rules' (only ever upwards),
 * then held. Its contract is the promise of issue 29 for the whole decision: a demand a
 * curve raised is never lowered while the train is inside that curve for the remembered
 * obstacle (inside EBI: emergency; inside SBI: at least service, and emergency while an
 * emergency is held), and what is held is lowered only at standstill or after `confirm`
 * calm cycles. */
/*@ requires \valid_read(voted) && \valid_read(remembered) && \valid(d);
    requires \separated(d, voted) && \separated(d, remembered);
    requires confirm >= 1;
    assigns *d;
    ensures \result == d->final_demand;
    ensures 0 <= d->env <= 2 && (d->warning == 0 || d->warning == 1);
    ensures d->demand == rg_max3(table_demand, d->env, error_demand);
    ensures d->final_demand >= d->demand && d->final_demand >= d->env;
    ensures track_sup != 0 && track_dm <= remembered->ebi_dm ==> d->env == 2 && d->final_demand >= 2;
    ensures track_sup != 0 && track_dm <= remembered->sbi_dm ==> d->env >= 1 && d->final_demand >= 1;
    ensures level == 2 && track_sup != 0 && track_dm <= remembered->sbi_dm ==> d->env == 2 && d->final_demand >= 2;
    ensures voted_dm != 65535 && voted_dm <= voted->ebi_dm ==> d->env == 2 && d->final_demand >= 2;
    ensures level == 2 && voted_dm != 65535 && voted_dm <= voted->sbi_dm ==> d->env == 2 && d->final_demand >= 2;
    ensures d->final_demand < level ==> speed_cms <= 0 || calm + 1 >= confirm;
    ensures keep != 0 && speed_cms > 0 && level <= 2 ==> d->final_demand >= level;
    ensures d->final_demand == level || d->final_demand == d->demand;
    ensures d->calm < confirm;
*/
int32_t rg_decide(int32_t voted_dm, const rg_curve_set *voted, int32_t track_sup, int32_t track_dm,
                  const rg_curve_set *remembered, int32_t table_demand, int32_t error_demand, int32_t level,
                  int32_t calm, int32_t speed_cms, int32_t revocable, int32_t confirm, int32_t keep, rg_decision *d)
{
    int32_t asked;
    d->env = rg_supervised_demand(voted_dm, voted->ebi_dm, voted->sbi_dm, voted->warning_dm, track_sup, track_dm,
                                  remembered->ebi_dm, remembered->sbi_dm, remembered->warning_dm, level, &d->warning);
    d->demand = rg_combine(table_demand, d->env, error_demand);
    /* envelope.keep_held: an obstacle in sight, in the table's zones, closing in keeps what is held */
    asked = keep && speed_cms > 0 && d->demand < level ? level : d->demand;
    return rg_hold(level, calm, asked, speed_cms, revocable, confirm, &d->calm, &d->final_demand);
}

/* ---- obstacle memory (memory.py): positions in 1e-5 m, the unit of cm/s x ms ---------- */

/*@ requires 0 <= accel_mms2 <= 10000 && 1 <= period_ms <= 70000;
    assigns \nothing;
    ensures \result >= 0;
    ensures \result * 20000 >= accel_mms2 * period_ms * period_ms;
    ensures (\result - 1) * 20000 < accel_mms2 * period_ms * period_ms;
*/
int64_t rg_accel_run(int64_t accel_mms2, int64_t period_ms)
{
    /* a T^2 / 2 in 1e-5 m, rounded up: mm/s^2 x ms^2 = 1e-9 m */
    return (accel_mms2 * period_ms * period_ms + 19999) / 20000;
}

/* The most the gap to a remembered obstacle can shrink in the next period: the train at
 * its measured speed plus the speed error, accelerating at `accel_mms2`, and the obstacle
 * closing at its own speed. The third ensures is stronger than Python's two: every term
 * (speed error, acceleration, the obstacle's speed) is there, each rounded up. */
/*@ requires 0 <= speed_cms <= 12000 && 0 <= error_permille <= 500 && 0 <= accel_mms2 <= 10000;
    requires 0 <= obstacle_cms <= 30000 && 1 <= period_ms <= 70000;
    assigns \nothing;
    ensures \result * 1000 >= speed_cms * (1000 + error_permille) * period_ms + obstacle_cms * period_ms * 1000;
    ensures \result >= speed_cms * period_ms + obstacle_cms * period_ms;
    ensures \result * 20000 >= 20 * speed_cms * (1000 + error_permille) * period_ms
                               + accel_mms2 * period_ms * period_ms + 20000 * obstacle_cms * period_ms;
    ensures \result * 20000 < 20 * speed_cms * (1000 + error_permille) * period_ms
                              + accel_mms2 * period_ms * period_ms + 20000 * obstacle_cms * period_ms
                              + 20000 * (period_ms + 1);
*/
int64_t rg_near_travel(int64_t speed_cms, int64_t error_permille, int64_t accel_mms2, int64_t obstacle_cms,
                       int64_t period_ms)
{
    const int64_t x = speed_cms * (1000 + error_permille);
    const int64_t v_max = (x + 999) / 1000;            /* the speed plus its error, rounded up */
    const int64_t run = rg_accel_run(accel_mms2, period_ms);
    /* (hints for the provers: the rounding, then times the period) */
    /*@ assert hint_round: v_max * 1000 >= x && v_max * 1000 < x + 1000; */
    /*@ assert hint_sign: (v_max * 1000 - x) * period_ms >= 0 && (x + 1000 - v_max * 1000) * period_ms > 0; */
    /*@ assert hint_times: v_max * 1000 * period_ms >= x * period_ms
                           && v_max * 1000 * period_ms < x * period_ms + 1000 * period_ms; */
    return v_max * period_ms + run + obstacle_cms * period_ms;
}

/* The least the train can have run in the period that ended at this speed: the measured
 * speed less the speed error, less what acceleration in the period explains, never below
 * 0 (what "passed" is judged on). */
/*@ requires 0 <= speed_cms <= 12000 && 0 <= error_permille <= 500 && 0 <= accel_mms2 <= 10000;
    requires 1 <= period_ms <= 10000;
    assigns \nothing;
    ensures \result >= 0;
    ensures \result * 1000 <= speed_cms * (1000 - error_permille) * period_ms;
    ensures \result == 0 || \result * 20000 <= 20000 * speed_cms * period_ms - accel_mms2 * period_ms * period_ms;
    ensures \result == 0 || \result * 20000 <= 20 * speed_cms * (1000 - error_permille) * period_ms
                                               - accel_mms2 * period_ms * period_ms;
*/
int64_t rg_far_travel(int64_t speed_cms, int64_t error_permille, int64_t accel_mms2, int64_t period_ms)
{
    const int64_t x = speed_cms * (1000 - error_permille);
    const int64_t v_min = x / 1000;                    /* the speed less its error, rounded down */
    const int64_t run = v_min * period_ms - rg_accel_run(accel_mms2, period_ms);
    /* (hints for the provers: the rounding, then times the period) */
    /*@ assert hint_round: 0 <= v_min * 1000 <= x && v_min <= speed_cms; */
    /*@ assert hint_sign: (x - v_min * 1000) * period_ms >= 0 && (speed_cms - v_min) * period_ms >= 0; */
    /*@ assert hint_times: v_min * 1000 * period_ms <= x * period_ms && v_min * period_ms <= speed_cms * period_ms; */
    return run > 0 ? run : 0;
}

#define RG_PLAUS_MAX_SPAN 120000   /* a reference is at most two windows old (window <= 60 s) */
#define RG_PLAUS_MAX_RUN ((int64_t)RG_MAX_CLOSING_CMS * RG_PLAUS_MAX_SPAN)
#define RG_PLAUS_MAX_TICK ((int64_t)1 << 61)

/* A new reference at this report (plausibility.anchor): nothing run since it yet, the fault
 * as given; at RG_NO_TRACK, tick 0, closing 0 and fault 0 it is the state before a sighting. */
/*@ requires \valid(p);
    assigns *p;
    ensures p->ref_dm == distance_dm && p->ref_tick == tick && p->last_tick == tick;
    ensures p->last_closing == closing_cms && p->lo == 0 && p->hi == 0 && p->bad == bad;
*/
void rg_plaus_anchor(rg_plaus *p, int32_t distance_dm, int32_t closing_cms, int64_t tick, int32_t bad)
{
    p->ref_dm = distance_dm;
    p->ref_tick = tick;
    p->last_tick = tick;
    p->last_closing = closing_cms;
    p->lo = 0;
    p->hi = 0;
    p->bad = bad;
}

/* Whether the channel's story goes on from its reference to a report at `tick`: a reference
 * in range, the report after the last one and at most a window later, the reference at most
 * two windows back (always so for a state rg_plausibility wrote: it continues only while the
 * span is under one window). Anything else (a state no cycle produces, a gap, a report out of
 * order, ticks beyond +-2^61 ms, 73 million years: the shells count from 0) is no evidence
 * either way; the bounds keep the arithmetic of the check from overflowing. */
/*@ requires \valid_read(p);
    requires 1 <= window_ms <= 60000;
    assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 ==> 0 <= p->ref_dm <= RG_MAX_DISTANCE_DM
            && -RG_MAX_CLOSING_CMS <= p->last_closing <= RG_MAX_CLOSING_CMS
            && -RG_PLAUS_MAX_RUN <= p->lo <= RG_PLAUS_MAX_RUN && -RG_PLAUS_MAX_RUN <= p->hi <= RG_PLAUS_MAX_RUN
            && -RG_PLAUS_MAX_TICK <= tick <= RG_PLAUS_MAX_TICK
            && -RG_PLAUS_MAX_TICK <= p->last_tick <= RG_PLAUS_MAX_TICK
            && -RG_PLAUS_MAX_TICK <= p->ref_tick <= RG_PLAUS_MAX_TICK
            && 0 <= tick - p->last_tick <= window_ms
            && tick - p->last_tick <= tick - p->ref_tick <= RG_PLAUS_MAX_SPAN;
*/
int32_t rg_plaus_continues(const rg_plaus *p, int64_t tick, int32_t window_ms)
{
    int64_t dt, span;
    if (tick < -RG_PLAUS_MAX_TICK || tick > RG_PLAUS_MAX_TICK || p->last_tick < -RG_PLAUS_MAX_TICK
        || p->last_tick > RG_PLAUS_MAX_TICK || p->ref_tick < -RG_PLAUS_MAX_TICK || p->ref_tick > RG_PLAUS_MAX_TICK)
        return 0;
    dt = tick - p->last_tick;
    span = tick - p->ref_tick;
    return p->ref_dm >= 0 && p->ref_dm <= RG_MAX_DISTANCE_DM && p->last_closing >= -RG_MAX_CLOSING_CMS
           && p->last_closing <= RG_MAX_CLOSING_CMS && p->lo >= -RG_PLAUS_MAX_RUN && p->lo <= RG_PLAUS_MAX_RUN
           && p->hi >= -RG_PLAUS_MAX_RUN && p->hi <= RG_PLAUS_MAX_RUN && dt >= 0 && dt <= window_ms
           && span >= dt && span <= RG_PLAUS_MAX_SPAN;
}

/* One channel's plausibility after this cycle's report (monitor/core/plausibility.py): a
 * PRESENT report farther than the reference less the least the obstacle ran (the lower of
 * each pair of reported closing speeds times the time between them), beyond the declared
 * accuracy (each distance within accuracy_dm, the closing speed within accuracy_cms over the
 * span), makes the channel implausible until a whole window of its reports agrees again; a
 * report nearer than the most it ran is something new in front and starts a new reference;
 * a channel that is not PRESENT drops its reference and its fault. A state no cycle produces
 * (rg_plaus_continues) starts a new reference and keeps the fault: no evidence either way. */
/*@ requires \valid(p);
    requires 0 <= distance_dm <= 60000 && -15000 <= closing_cms <= 15000;
    requires 0 <= accuracy_dm <= 60000 && 0 <= accuracy_cms <= 15000 && 1 <= window_ms <= 60000;
    assigns *p;
    ensures p->bad == 0 || p->bad == 1;
    ensures present == 0 ==> p->ref_dm == -1 && p->bad == 0 && p->lo == 0 && p->hi == 0;
    ensures present != 0 ==> p->ref_dm >= 0 && p->last_tick == tick;
    ensures present != 0 && \old(p->ref_dm) == -1 ==>
            p->ref_dm == distance_dm && p->ref_tick == tick && p->lo == 0 && p->hi == 0
            && p->bad == (\old(p->bad) != 0);
    ensures present != 0 && \old(p->bad) != 0 && p->bad == 0 ==> p->ref_tick == tick && p->ref_dm == distance_dm;
*/
void rg_plausibility(rg_plaus *p, int32_t present, int32_t distance_dm, int32_t closing_cms, int64_t tick,
                     int32_t accuracy_dm, int32_t accuracy_cms, int32_t window_ms)
{
    int32_t bad;
    int64_t dt, span, lo, hi, tolerance, d, r;
    if (!present) {
        rg_plaus_anchor(p, RG_NO_TRACK, 0, 0, 0);
        return;
    }
    bad = p->bad != 0;
    if (p->ref_dm >= 0 && tick == p->last_tick) {
        p->bad = bad;    /* nothing new this cycle */
        return;
    }
    if (!rg_plaus_continues(p, tick, window_ms)) {
        rg_plaus_anchor(p, distance_dm, closing_cms, tick, bad);
        return;
    }
    /* (what rg_plaus_continues ensures, restated for EVA, which does not read contracts) */
    /*@ assert hint_story: 0 <= p->ref_dm <= RG_MAX_DISTANCE_DM
            && -RG_MAX_CLOSING_CMS <= p->last_closing <= RG_MAX_CLOSING_CMS
            && -RG_PLAUS_MAX_RUN <= p->lo <= RG_PLAUS_MAX_RUN && -RG_PLAUS_MAX_RUN <= p->hi <= RG_PLAUS_MAX_RUN
            && -RG_PLAUS_MAX_TICK <= tick <= RG_PLAUS_MAX_TICK
            && -RG_PLAUS_MAX_TICK <= p->last_tick <= RG_PLAUS_MAX_TICK
            && -RG_PLAUS_MAX_TICK <= p->ref_tick <= RG_PLAUS_MAX_TICK; */
    dt = tick - p->last_tick;
    span = tick - p->ref_tick;
    /*@ assert hint_span: 0 <= dt <= window_ms && dt <= span <= RG_PLAUS_MAX_SPAN; */
    lo = p->lo + (int64_t)(closing_cms < p->last_closing ? closing_cms : p->last_closing) * dt;
    hi = p->hi + (int64_t)(closing_cms > p->last_closing ? closing_cms : p->last_closing) * dt;
    tolerance = 2 * (int64_t)accuracy_dm * RG_UNITS_PER_DM + (int64_t)accuracy_cms * span;
    d = (int64_t)distance_dm * RG_UNITS_PER_DM;
    r = (int64_t)p->ref_dm * RG_UNITS_PER_DM;
    if (d > r - lo + tolerance) {                       /* farther than it can be: implausible */
        rg_plaus_anchor(p, distance_dm, closing_cms, tick, 1);
    } else if (d < r - hi - tolerance) {                /* nearer: something new in front */
        rg_plaus_anchor(p, distance_dm, closing_cms, tick, bad);
    } else if (span >= window_ms) {                     /* a whole window that agrees: plausible again */
        rg_plaus_anchor(p, distance_dm, closing_cms, tick, 0);
    } else {
        p->last_closing = closing_cms;
        p->last_tick = tick;
        p->bad = bad;
        p->lo = lo;
        p->hi = hi;
    }
}

/* Whether a confirmed sighting is evidence that the track is gone rather than the track
 * measured again (memory.seen_beyond): farther than the remembered obstacle can be (far) by
 * more than the two reports' declared accuracy. The sensors report their nearest object, so
 * it counts as ABSENT does (rg_forget) and becomes the track once the old one is forgotten. */
/*@ requires near >= -1 && far >= -600000000 && 0 <= distance_dm <= 65535 && 0 <= accuracy_dm <= 60000;
    assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 ==> near != -1 && distance_dm * 10000 > far;
    ensures \result == 0 && near != -1 ==> distance_dm * 10000 <= far + 2 * accuracy_dm * 10000;
*/
int32_t rg_seen_beyond(int32_t near, int32_t far, int32_t distance_dm, int32_t accuracy_dm)
{
    return near != RG_NO_TRACK && (int64_t)distance_dm * 10000 > (int64_t)far + 2 * (int64_t)accuracy_dm * 10000;
}

/* The track after a voted obstacle at `distance_dm`: a confirmed picture creates or
 * replaces it; a disputed one in which some module sees the obstacle with both channels
 * (`sighted`) creates it when there is none; any disputed one brings an existing track
 * nearer, and a sighted one also moves it to a sighting between `near` and `far` (where the
 * remembered obstacle can be); beyond `far` never (a farther sighting never hides a nearer
 * remembered obstacle). A
 * receding obstacle's speed is remembered as 0. (Python: distance 0..60000; 65535 here,
 * the voted distance's whole range as EVA sees it, still fits int32 in 1e-5 m.) */
/*@ requires \valid(track);
    requires 0 <= distance_dm <= 65535;
    requires track->near >= -1 && track->closing_cms >= 0;
    assigns *track;
    ensures track->near <= distance_dm * 10000;
    ensures track->near == -1 || (track->near >= 0 && track->closing_cms >= 0 && track->closing_cms >= obstacle_cms);
    ensures confirmed != 0 ==> track->near == distance_dm * 10000 && track->far == distance_dm * 10000
                               && track->closing_cms == \max(obstacle_cms, 0) && track->age_ms == age_now;
    ensures sighted != 0 && \old(track->near) == -1 ==>
            track->near == distance_dm * 10000 && track->far == distance_dm * 10000
            && track->closing_cms == \max(obstacle_cms, 0) && track->age_ms == age_now;
    ensures confirmed == 0 && sighted == 0 && \old(track->near) == -1 ==>
            track->near == -1 && track->far == -1 && track->closing_cms == 0 && track->age_ms == 0;
    ensures confirmed == 0 && \old(track->near) != -1 ==>
            (track->near <= \old(track->near) || (sighted != 0 && track->near <= \old(track->far)))
            && track->closing_cms >= \old(track->closing_cms);
    ensures confirmed == 0 && sighted == 0 && \old(track->near) != -1 ==> track->near <= \old(track->near);
*/
void rg_observe(rg_track *track, int32_t distance_dm, int32_t obstacle_cms, int32_t age_now, int32_t confirmed,
                int32_t sighted)
{
    const int32_t d = distance_dm * RG_UNITS_PER_DM;
    const int32_t own = obstacle_cms > 0 ? obstacle_cms : 0;
    if (confirmed || (sighted && track->near == RG_NO_TRACK)) {
        track->near = d;
        track->far = d;
        track->closing_cms = own;
        track->age_ms = age_now;
    } else if (track->near == RG_NO_TRACK) {
        track->far = RG_NO_TRACK;
        track->closing_cms = 0;
        track->age_ms = 0;
    } else {
        if (own > track->closing_cms) track->closing_cms = own;
        if (d <= track->near || (sighted && d <= track->far)) {
            track->near = d;
            track->far = d;
            track->age_ms = age_now;
        }
    }
}

/* The evidence count and state of a remembered obstacle that no channel shows. `far` is
 * the farthest the obstacle can lie: the remembered position less the train's least travel,
 * plus the distance accuracy; below 0 the train has passed it (forgotten at once). Fresh
 * unanimous ABSENT (`evidence`) while `far` lies inside the declared sensor range counts
 * towards forgetting, after `forget_cycles` such cycles in a row; anything else holds it. (Python: forget(cycles, evidence, in_range, passed, n) with
 * in_range = reach <= range_dm * 10000 and passed = reach < 0 computed by cycle.py.) */
/*@ requires forget_cycles >= 1;
    requires \valid(state);
    assigns *state;
    ensures 2 <= *state <= 5;
    ensures *state == 5 <==> far < 0;
    ensures *state == 4 ==> evidence != 0 && 0 <= far <= range_dm * 10000 && cycles_absent + 1 >= forget_cycles;
    ensures far >= 0 && evidence != 0 && far <= range_dm * 10000 ==> *state >= 3;
    ensures far >= 0 && !(evidence != 0 && far <= range_dm * 10000) ==> \result == 0 && *state == 2;
    ensures *state == 3 ==> \result == cycles_absent + 1 && evidence != 0 && 0 <= far <= range_dm * 10000;
    ensures \result < forget_cycles;
    ensures cycles_absent >= 0 ==> \result >= 0;
*/
int32_t rg_forget(int32_t cycles_absent, int32_t evidence, int64_t far, int32_t range_dm, int32_t forget_cycles,
                  int32_t *state)
{
    if (far < 0) {
        *state = RG_TRACK_PASSED;
        return 0;
    }
    if (!evidence || far > (int64_t)range_dm * RG_UNITS_PER_DM) {
        *state = RG_TRACK_HELD;
        return 0;
    }
    if (cycles_absent >= forget_cycles - 1) {   /* cycles_absent + 1 >= forget_cycles (never formed) */
        *state = RG_TRACK_FORGOTTEN;
        return 0;
    }
    *state = RG_TRACK_CONFIRMING;
    return cycles_absent + 1;
}

/* memory.distance_dm: the remembered distance in dm, rounded down (nearer is the safe side). */
/*@ assigns \nothing;
    ensures near == -1 ==> \result == 65535;
    ensures near < 655350000 ==> (near == -1 <==> \result == 65535);
    ensures near >= 0 ==> \result * 10000 <= near && near < (\result + 1) * 10000;
    ensures 0 <= near < 655350000 ==> \result < 65535;
*/
int32_t rg_track_dm(int32_t near)
{
    return near == RG_NO_TRACK ? RG_NO_DISTANCE : near / RG_UNITS_PER_DM;
}

static int32_t inc(int32_t count)
{
    return count < RG_MAX_COUNT ? count + 1 : RG_MAX_COUNT;
}

static int32_t speed_class(int32_t closing_cms, int32_t fast_cms)
{
    if (closing_cms < 0) return 0;
    return closing_cms < fast_cms ? 1 : 2;
}

/* The cycle that Python's `step` falls back to when something unforeseen happens inside
 * (here: a state no cycle can produce, for example a node outside the table). */
static void safe_stop_fallback(rg_state *s, rg_outputs *out)
{
    s->cycle = inc(s->cycle);
    s->error_cycles = inc(s->error_cycles);
    s->mode = RG_SAFE_STOP;
    s->held = RG_EMERGENCY;
    s->healthy = 0;
    s->calm = 0;
    out->demand = RG_EMERGENCY;
    out->reasons = RG_R_SAFE_STOP | RG_R_SYSTEM_ERROR | RG_R_LATCH;
    out->distance_dm = RG_NO_DISTANCE;
    out->node = s->node;
    out->mode = RG_SAFE_STOP;
    out->module_flags = 0;
    out->system_error = 1;
    out->observation = 0;
    out->cycle = s->cycle;
    out->error_cycles = s->error_cycles;
    out->warning = 1;
    out->track_dm = RG_NO_DISTANCE;
    out->track_cycles = 0;
    out->track_state = RG_TRACK_NONE;
    out->r1_ppm = (int32_t)(RG_PPM / 2u);
    out->r2_ppm = (int32_t)RG_PPM;
    out->risk_score = RG_MAX_RISK_SCORE;
    out->risk_category = 4;
    out->table_risk_ppm = (int32_t)RG_PPM;
}

/* cycle._zone_limits: alpha2 = EBI and alpha1 = the service curve's EBI, both under normal
 * conditions and as zone limits (RG_ZONE_PERIODS: without the supervision's sampling period;
 * alpha1 at least alpha2); the table's zones and the papers' risk read them. */
static void zone_limits(const rg_config *cfg, int32_t speed, int32_t toward, int32_t age, int32_t *alpha1,
                        int32_t *alpha2)
{
    rg_curve_set c;
    rg_curves(cfg, speed, 0, 0, toward, age, 0, 0, &c);
    *alpha2 = c.ebi_dm;
    rg_curves(cfg, speed, 0, 0, toward, age, 1, 0, &c);
    *alpha1 = c.ebi_dm > *alpha2 ? c.ebi_dm : *alpha2;
}

/* ---- several remembered obstacles (tracks.py): up to RG_TRACKS, nearest first, empty last -- */

/* rg_ordered below orders RG_TRACKS = 3 slots with three exchanges (an insertion sort) */
#if RG_TRACKS != 3
#error "rg_ordered orders RG_TRACKS = 3 slots with three exchanges: give it an insertion sort's for the new count"
#endif

/* the order's key of an empty slot (tracks.ordered: empty slots after every held one) */
#define RG_EMPTY_KEY ((int64_t)1 << 32)

static const rg_track_slot RG_EMPTY_SLOT = {RG_NO_TRACK, RG_NO_TRACK, 0, 0, 0, 0};

/*@ // tracks.relation: MEASURES 0, AHEAD 1, BEYOND 2 (rg_seen_beyond)
    logic integer rg_relation_l(integer near, integer far, integer d, integer a) =
        near != -1 && d * 10000 > far + 2 * a * 10000 ? 2 : (d * 10000 < near - 2 * a * 10000 ? 1 : 0);
    // tracks.ordered's key: by position, empty slots (near == -1) after every held one
    logic integer rg_key(integer near) = near == -1 ? 4294967296 : near;
*/

/* Where a voted obstacle at `distance_dm` lies against a remembered one (tracks.relation):
 * beyond where it can be (seen beyond, as rg_seen_beyond says: evidence that it is gone),
 * ahead of where it can be (near less the two reports' accuracy: another obstacle), or inside
 * that window (the track measured again). rg_seen_beyond's test is written out here: a
 * function with a contract is called either from rg_step or from the proved functions, never
 * from both (WP proves the call preconditions in the functions it is given, so one also
 * called from rg_step would keep a partial status), and rg_step calls rg_seen_beyond. */
/*@ requires near >= -1 && far >= -600000000 && 0 <= distance_dm <= 65535 && 0 <= accuracy_dm <= 60000;
    assigns \nothing;
    ensures \result == rg_relation_l(near, far, distance_dm, accuracy_dm);
    ensures 0 <= \result <= 2;
    ensures \result == 2 <==> (near != -1 && distance_dm * 10000 > far + 2 * accuracy_dm * 10000);
    ensures \result == 1 ==> distance_dm * 10000 < near - 2 * accuracy_dm * 10000;
    ensures \result == 0 && near != -1 ==>
            near - 2 * accuracy_dm * 10000 <= distance_dm * 10000 <= far + 2 * accuracy_dm * 10000;
*/
int32_t rg_relation(int32_t near, int32_t far, int32_t distance_dm, int32_t accuracy_dm)
{
    if (near != RG_NO_TRACK
        && (int64_t)distance_dm * RG_UNITS_PER_DM > (int64_t)far + 2 * (int64_t)accuracy_dm * RG_UNITS_PER_DM)
        return RG_BEYOND;
    if ((int64_t)distance_dm * RG_UNITS_PER_DM < (int64_t)near - 2 * (int64_t)accuracy_dm * RG_UNITS_PER_DM)
        return RG_AHEAD;
    return RG_MEASURES;
}

/* tracks.assign: the slot of the track a voted obstacle measures (-1: none) and, in
 * `*create`, whether it is a new obstacle to remember. `creates`: the picture may create a
 * track (confirmed, or some module sees it with both channels); one that may not only brings
 * the nearest track nearer (rg_observe). `tracks` are ordered, nearest first. */
/*@ requires \valid_read(tracks + (0 .. RG_TRACKS - 1)) && \valid(create);
    requires \separated(create, tracks + (0 .. RG_TRACKS - 1));
    requires \forall integer i; 0 <= i < RG_TRACKS ==> tracks[i].near >= -1 && tracks[i].far >= -600000000;
    requires 0 <= distance_dm <= 65535 && 0 <= accuracy_dm <= 60000;
    assigns *create;
    ensures -1 <= \result < RG_TRACKS && (*create == 0 || *create == 1);
    ensures !(\result >= 0 && *create != 0) && (creates != 0 || *create == 0);
    ensures \result == -1 || tracks[\result].near != -1;
    ensures creates == 0 || \result == -1
            || rg_relation_l(tracks[\result].near, tracks[\result].far, distance_dm, accuracy_dm) == 0;
    ensures creates != 0 || \result == (tracks[0].near != -1 ? 0 : -1);
    ensures creates != 0 ==> (\result == -1 <==> *create == 1);
    ensures creates != 0 && \result >= 0 ==> \forall integer j; 0 <= j < \result
            ==> rg_relation_l(tracks[j].near, tracks[j].far, distance_dm, accuracy_dm) == 2;
*/
int32_t rg_assign(const rg_track_slot tracks[RG_TRACKS], int32_t distance_dm, int32_t accuracy_dm, int32_t creates,
                  int32_t *create)
{
    int32_t i;
    *create = 0;
    if (!creates) return tracks[0].near != RG_NO_TRACK ? 0 : -1;
    /*@ loop pragma UNROLL "completely", RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        int32_t r;
        if (tracks[i].near == RG_NO_TRACK) break;
        r = rg_relation(tracks[i].near, tracks[i].far, distance_dm, accuracy_dm);
        if (r == RG_AHEAD) break;
        if (r == RG_MEASURES) return i;
    }
    *create = 1;
    return -1;
}

/* tracks.absorbed's test for the slot at `j`: a held track beyond the measured `slot` that a
 * confirmed picture at `distance_dm` also measures (the same obstacle to within the sensors'
 * accuracy, emptied into the one it measures). */
/*@ requires \valid_read(track);
    requires track->near >= -1 && track->far >= -600000000 && 0 <= distance_dm <= 65535 && 0 <= accuracy_dm <= 60000;
    assigns \nothing;
    ensures \result == 0 || \result == 1;
    ensures \result == 1 <==> (slot >= 0 && j > slot && track->near != -1
                               && rg_relation_l(track->near, track->far, distance_dm, accuracy_dm) == 0);
*/
int32_t rg_absorbed(const rg_track_slot *track, int32_t slot, int32_t j, int32_t distance_dm, int32_t accuracy_dm)
{
    return slot >= 0 && j > slot && track->near != RG_NO_TRACK
           && rg_relation(track->near, track->far, distance_dm, accuracy_dm) == RG_MEASURES;
}

/* tracks.merge: two remembered obstacles as one, to the safe side of both: the nearer worst
 * case, the farther least position, the faster closing speed, strong if either is. (The
 * third ensures is stronger than Python's: the faster of the two, not only at least both.) */
/*@ requires \valid_read(a) && \valid_read(b) && \valid(out);
    requires \separated(out, a) && \separated(out, b);
    assigns *out;
    ensures out->near == \min(a->near, b->near) && out->far == \max(a->far, b->far);
    ensures out->closing >= a->closing && out->closing >= b->closing;
    ensures out->closing == \max(a->closing, b->closing) && out->cycles == \min(a->cycles, b->cycles);
    ensures (out->strong == 0 || out->strong == 1) && (out->strong != 0 <==> (a->strong != 0 || b->strong != 0));
    ensures out->absent == 0;
*/
void rg_merge(const rg_track_slot *a, const rg_track_slot *b, rg_track_slot *out)
{
    out->near = a->near < b->near ? a->near : b->near;
    out->far = a->far > b->far ? a->far : b->far;
    out->closing = a->closing > b->closing ? a->closing : b->closing;
    out->cycles = a->cycles < b->cycles ? a->cycles : b->cycles;
    out->absent = 0;
    out->strong = a->strong || b->strong;
}

/* One exchange of tracks.ordered's stable sort: the slots at i and i + 1 (with their ages and
 * states) swapped if the second goes strictly before the first (nearer, or held before an
 * empty one); equal keys keep their order. */
/*@ requires 0 <= i <= RG_TRACKS - 1;
    requires \valid(tracks + (i .. i + 1)) && \valid(ages + (i .. i + 1)) && \valid(states + (i .. i + 1));
    requires \separated(tracks + (i .. i + 1), ages + (i .. i + 1), states + (i .. i + 1));
    assigns tracks[i .. i + 1], ages[i .. i + 1], states[i .. i + 1];
    ensures rg_key(tracks[i].near) <= rg_key(tracks[i + 1].near);
    ensures rg_key(\old(tracks[i + 1].near)) < rg_key(\old(tracks[i].near)) ==>
            tracks[i].near == \old(tracks[i + 1].near) && tracks[i + 1].near == \old(tracks[i].near);
    ensures rg_key(\old(tracks[i + 1].near)) < rg_key(\old(tracks[i].near)) ==> tracks[i] == \old(tracks[i + 1]);
    ensures rg_key(\old(tracks[i + 1].near)) < rg_key(\old(tracks[i].near)) ==> tracks[i + 1] == \old(tracks[i]);
    ensures rg_key(\old(tracks[i + 1].near)) < rg_key(\old(tracks[i].near)) ==>
            ages[i] == \old(ages[i + 1]) && ages[i + 1] == \old(ages[i])
            && states[i] == \old(states[i + 1]) && states[i + 1] == \old(states[i]);
    ensures rg_key(\old(tracks[i + 1].near)) >= rg_key(\old(tracks[i].near)) ==>
            tracks[i] == \old(tracks[i]) && tracks[i + 1] == \old(tracks[i + 1])
            && tracks[i].near == \old(tracks[i].near) && tracks[i + 1].near == \old(tracks[i + 1].near)
            && ages[i] == \old(ages[i]) && ages[i + 1] == \old(ages[i + 1])
            && states[i] == \old(states[i]) && states[i + 1] == \old(states[i + 1]);
*/
void rg_order_pair(rg_track_slot *tracks, int32_t *ages, int32_t *states, int32_t i)
{
    const int64_t here = tracks[i].near == RG_NO_TRACK ? RG_EMPTY_KEY : tracks[i].near;
    const int64_t next = tracks[i + 1].near == RG_NO_TRACK ? RG_EMPTY_KEY : tracks[i + 1].near;
    if (next < here) {
        const rg_track_slot first = tracks[i], second = tracks[i + 1];
        const int32_t first_age = ages[i], second_age = ages[i + 1];
        const int32_t first_state = states[i], second_state = states[i + 1];
        tracks[i] = second;
        tracks[i + 1] = first;
        ages[i] = second_age;
        ages[i + 1] = first_age;
        states[i] = second_state;
        states[i + 1] = first_state;
    }
}

/* tracks.ordered: the slots nearest first, empty ones last, equal positions in the order they
 * had (a stable sort), each with its age and state: an insertion sort of the RG_TRACKS = 3
 * slots by exchanges (rg_order_pair), so the slots are only ever swapped. */
/*@ requires \valid(tracks + (0 .. RG_TRACKS - 1)) && \valid(ages + (0 .. RG_TRACKS - 1))
             && \valid(states + (0 .. RG_TRACKS - 1));
    requires \separated(tracks + (0 .. RG_TRACKS - 1), ages + (0 .. RG_TRACKS - 1), states + (0 .. RG_TRACKS - 1));
    assigns tracks[0 .. RG_TRACKS - 1], ages[0 .. RG_TRACKS - 1], states[0 .. RG_TRACKS - 1];
    ensures rg_key(tracks[0].near) <= rg_key(tracks[1].near) <= rg_key(tracks[2].near);
*/
void rg_ordered(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS])
{
    rg_order_pair(tracks, ages, states, 0);     /* the first two in order */
    rg_order_pair(tracks, ages, states, 1);     /* the third in its place among them */
    /*@ assert hint_last: rg_key(tracks[0].near) <= rg_key(tracks[2].near)
                          && rg_key(tracks[1].near) <= rg_key(tracks[2].near); */
    rg_order_pair(tracks, ages, states, 0);
}

/* The second half of tracks.insert, for a memory with every slot held: the held ones in
 * order, then `fresh` in its place after them (after any as near: it comes last), and the two
 * farthest merged into the last slot (rg_merge), with the nearer one's age, held (no slot is
 * as it was seen). The nearest is never merged (RG_TRACKS >= 2). */
/*@ requires \valid(tracks + (0 .. RG_TRACKS - 1)) && \valid(ages + (0 .. RG_TRACKS - 1))
             && \valid(states + (0 .. RG_TRACKS - 1)) && \valid_read(fresh);
    requires \separated(tracks + (0 .. RG_TRACKS - 1), ages + (0 .. RG_TRACKS - 1), states + (0 .. RG_TRACKS - 1),
                        fresh);
    assigns tracks[0 .. RG_TRACKS - 1], ages[0 .. RG_TRACKS - 1], states[0 .. RG_TRACKS - 1];
    ensures states[RG_TRACKS - 1] == RG_TRACK_HELD;
*/
void rg_insert_full(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS],
                    const rg_track_slot *fresh, int32_t age, int32_t state)
{
    rg_track_slot all[RG_TRACKS + 1];
    int32_t all_ages[RG_TRACKS + 1], all_states[RG_TRACKS + 1];
    int32_t i;
    /* the held ones in order: rg_ordered's exchanges, written out here so that rg_ordered is
     * called from rg_step alone (WP proves the call preconditions of the contracted functions
     * it is given; a function also called from rg_step would keep a partial status) */
    rg_order_pair(tracks, ages, states, 0);
    rg_order_pair(tracks, ages, states, 1);
    rg_order_pair(tracks, ages, states, 0);
    /*@ loop pragma UNROLL "completely", RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        all[i] = tracks[i];
        all_ages[i] = ages[i];
        all_states[i] = states[i];
    }
    all[RG_TRACKS] = *fresh;
    all_ages[RG_TRACKS] = age;
    all_states[RG_TRACKS] = state;
    /*@ loop pragma UNROLL "completely", RG_TRACKS + 1; */
    for (i = RG_TRACKS - 1; i >= 0; i--) rg_order_pair(all, all_ages, all_states, i);
    /*@ loop pragma UNROLL "completely", RG_TRACKS; */
    for (i = 0; i < RG_TRACKS - 1; i++) {
        tracks[i] = all[i];
        ages[i] = all_ages[i];
        states[i] = all_states[i];
    }
    rg_merge(&all[RG_TRACKS - 1], &all[RG_TRACKS], &tracks[RG_TRACKS - 1]);
    ages[RG_TRACKS - 1] = all_ages[RG_TRACKS - 1];
    states[RG_TRACKS - 1] = RG_TRACK_HELD;
}

/* tracks.insert: `fresh` (with its age and state) remembered in the first empty slot; with
 * none empty, rg_insert_full. Returns the slot `fresh` went to, -1 if the memory was full. */
/*@ requires \valid(tracks + (0 .. RG_TRACKS - 1)) && \valid(ages + (0 .. RG_TRACKS - 1))
             && \valid(states + (0 .. RG_TRACKS - 1)) && \valid_read(fresh);
    requires \separated(tracks + (0 .. RG_TRACKS - 1), ages + (0 .. RG_TRACKS - 1), states + (0 .. RG_TRACKS - 1),
                        fresh);
    assigns tracks[0 .. RG_TRACKS - 1], ages[0 .. RG_TRACKS - 1], states[0 .. RG_TRACKS - 1];
    ensures -1 <= \result < RG_TRACKS;
    ensures \result == -1 ==> \forall integer i; 0 <= i < RG_TRACKS ==> \old(tracks[i].near) != -1;
    ensures \result >= 0 ==> tracks[\result] == \old(*fresh);
*/
int32_t rg_insert(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS],
                  const rg_track_slot *fresh, int32_t age, int32_t state)
{
    const rg_track_slot slot = *fresh;
    int32_t i;
    /*@ loop pragma UNROLL "completely", RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        if (tracks[i].near == RG_NO_TRACK) {
            ages[i] = age;
            states[i] = state;
            tracks[i] = slot;
            return i;
        }
    }
    rg_insert_full(tracks, ages, states, fresh, age, state);
    return -1;
}

/* The demand and warning of one remembered obstacle on its own curves (rg_supervision_demand:
 * the obstacle present, an emergency held as `held` says): what rg_step compares to choose the
 * remembered obstacle that rg_decide supervises (the one that demands the most). */
/*@ requires \valid_read(curve) && \valid(warn) && \separated(curve, warn);
    assigns *warn;
    ensures 0 <= \result <= 2 && (*warn == 0 || *warn == 1);
    ensures track_dm <= curve->ebi_dm ==> \result == 2;
    ensures track_dm <= curve->sbi_dm ==> \result >= 1;
    ensures held == 2 && track_dm <= curve->sbi_dm ==> \result == 2;
    ensures curve->ebi_dm <= curve->sbi_dm && track_dm > curve->sbi_dm ==> \result == 0;
    ensures 0 <= curve->ebi_dm <= curve->sbi_dm <= curve->warning_dm ==> (*warn == 1 <==> track_dm <= curve->warning_dm);
*/
int32_t rg_remembered_demand(int32_t track_dm, const rg_curve_set *curve, int32_t held, int32_t *warn)
{
    return rg_supervision_demand(1, track_dm, curve->ebi_dm, curve->sbi_dm, curve->warning_dm, held == RG_EMERGENCY,
                                 warn);
}

void rg_step(const rg_config *cfg, const rg_table *t, rg_state *s, const rg_inputs *in, int64_t tick, rg_outputs *out)
{
    const int32_t modules = cfg->modules == 1 ? 1 : 3;
    const int32_t channels = 2 * modules;
    const int64_t timeout_ticks = (int64_t)cfg->timeout_cycles * cfg->period_ms;
    /* the age limit: timeout_ticks itself for an accepted configuration */
    const int64_t age_limit = timeout_ticks < RG_MAX_AGE_MS ? timeout_ticks : RG_MAX_AGE_MS;
    const uint32_t all_seen = (1u << channels) - 1u;
    const int32_t forget_cycles = rg_forget_cycles(cfg, 0);
    const int32_t forget_single = rg_forget_cycles(cfg, 1);
    /* mm/s^2 the train may gain: traction plus the steepest downhill (cycle.Setup.track_accel) */
    const int64_t track_accel = (int64_t)cfg->max_accel_mms2 + rg_gradient_accel_mms2(cfg->max_gradient_permille);
    const int64_t err = cfg->speed_error_permille;
    int32_t statuses[RG_MAX_CHANNELS], dist[RG_MAX_CHANNELS];
    int32_t ms[RG_MAX_MODULES], md[RG_MAX_MODULES], mf[RG_MAX_MODULES], disagree[RG_MAX_MODULES];
    int32_t agree[RG_MAX_MODULES];
    uint32_t seen = s->seen;
    int32_t stale = 0, implausible = 0, have_closing = 0, closing = 0, obstacle = 0, age = 0, flags = 0, perceptor = 0;
    int32_t sys_status, distance, sys_error, present, toward, warn, own_speed, own_speed_up, confirmed, sighted, keep;
    int32_t speed, track, brake, train_ok, env, z, obs, error, dispute, overrun_limit, healthy, mode;
    int32_t node, table_demand, reasons, error_demand, demand, held, calm, final_demand, error_cycles;
    int32_t t_dm, t_state, t_cycles, slot, create, evidence_absent, first_state, first_lost;
    int32_t nearest, worst, worst_env, worst_warn, memory_reason;
    int32_t spd, near_dm, alpha1 = 1, alpha2 = 0, r1, r2, score;
    int32_t i, m;
    rg_track_slot tracks[RG_TRACKS], next_tracks[RG_TRACKS];
    int32_t ages[RG_TRACKS], states[RG_TRACKS], next_ages[RG_TRACKS], next_states[RG_TRACKS], watched[RG_TRACKS];
    rg_curve_set tcurves[RG_TRACKS];
    rg_decision dec;
    rg_curve_set curve = {0, 0, 0, 0}, tcurve = {0, 0, 0, 0};

    /* a state that no cycle can produce (rg_initial_state and rg_step only ever write these
     * ranges): SAFE_STOP, as Python's step does on an exception. (Written out here, not in
     * a helper, so that EVA narrows the fields' ranges after it.) */
    if (s->node < 0 || (uint32_t)s->node >= t->nodes || s->held < RG_MAINTAIN || s->held > RG_EMERGENCY
        || s->table_held < RG_MAINTAIN || s->table_held > RG_EMERGENCY) {
        safe_stop_fallback(s, out);
        return;
    }
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        /* (a kept track's far may lie up to the distance accuracy below 0: it is passed below that) */
        if (s->tracks[i].near < RG_NO_TRACK || s->tracks[i].near > RG_MAX_TRACK
            || (int64_t)s->tracks[i].far < (s->tracks[i].near == RG_NO_TRACK ? RG_NO_TRACK
                                             : -(int64_t)cfg->distance_accuracy_dm * RG_UNITS_PER_DM)
            || s->tracks[i].far > RG_MAX_TRACK || s->tracks[i].closing < 0
            || s->tracks[i].closing > RG_MAX_CLOSING_CMS) {
            safe_stop_fallback(s, out);
            return;
        }
    }

    /* 1. freshness and range per channel; 1b. plausibility: a PRESENT channel whose distance
     *    does not shrink as its own closing speeds say is DEGRADED (a frozen sensor keeps
     *    sending fresh frames) */
    for (i = 0; i < channels; i++) {
        statuses[i] = rg_effective_status(&in->reports[i], tick, timeout_ticks);
        dist[i] = 0;
        if (statuses[i] == RG_PRESENT) {
            const rg_report *r = &in->reports[i];
            /* rg_effective_status's contract gives this (WP proves it); EVA, which
             * cannot relate the status to the fields, takes the ranges from it */
            /*@ assert present_in_range: 0 <= r->distance_dm <= 60000 && -15000 <= r->closing_cms <= 15000
                                         && 0 <= r->obstacle <= 2; */
            rg_plausibility(&s->plaus[i], 1, r->distance_dm, r->closing_cms, r->tick, cfg->distance_accuracy_dm,
                            cfg->closing_accuracy_cms, cfg->plausibility_ms);
            if (s->plaus[i].bad) {
                statuses[i] = RG_DEGRADED;
                implausible = 1;
            } else {
                int32_t a;
                dist[i] = r->distance_dm;     /* (kept here, where EVA knows its range) */
                if (!have_closing || r->closing_cms > closing) closing = r->closing_cms;
                have_closing = 1;
                if (r->obstacle > obstacle) obstacle = r->obstacle;
                a = rg_age_ms(r->tick, tick, age_limit);
                if (a > age) age = a;
            }
        } else {
            rg_plausibility(&s->plaus[i], 0, 0, 0, 0, 0, 0, 1);
        }
        if (statuses[i] == RG_DEGRADED) {
            stale = 1;
        } else {
            seen |= 1u << i;
        }
    }

    /* 2. 2oo2 per module, with disagreement persistence: disagreement cycles add up until
     *    `persistence_cycles` calm cycles in a row clear them, so a flapping channel escalates */
    for (m = 0; m < modules; m++) {
        int32_t sa = statuses[2 * m], sb = statuses[2 * m + 1];
        int32_t da = dist[2 * m], db = dist[2 * m + 1];   /* the distance if PRESENT, else 0 */
        rg_vote_2oo2(sa, da, sb, db, &ms[m], &md[m], &mf[m]);
        if (rg_distances_disagree(sa, da, sb, db, cfg->distance_tolerance_dm)) mf[m] = 1;
        if (mf[m]) flags |= 1 << m;
        if (rg_disagreement(sa, sb)) {
            disagree[m] = inc(s->disagree[m]);
            agree[m] = 0;
        } else {
            agree[m] = inc(s->agree[m]);
            disagree[m] = agree[m] >= cfg->persistence_cycles ? 0 : s->disagree[m];
        }
        if (disagree[m] >= cfg->persistence_cycles) perceptor = 1;
    }

    /* 3. 3oo3 across modules (or the single module) */
    if (modules == 3) {
        rg_vote_3oo3(ms, md, mf, &sys_status, &distance, &sys_error);
    } else {
        sys_status = ms[0];
        distance = md[0];
        sys_error = mf[0] || ms[0] == RG_DEGRADED;
    }

    /* 4. obstacle memory: the remembered obstacle was moved to this cycle at the end of the
     *    last one (worst case); the train's least travel moves what "passed" reads. An
     *    invalid train state is read to the safe side. */
    speed = in->train.speed_cms;
    track = in->train.track;
    brake = in->train.brake;
    if (0 <= speed && speed <= RG_MAX_SPEED_CMS && (track == 0 || track == 1) && (brake == 0 || brake == 1)) {
        train_ok = 1;
    } else {  /* (written as a branch, not a flag, so that EVA sees the speed's range) */
        train_ok = 0;
        speed = RG_MAX_SPEED_CMS;
        track = 1;
        brake = 1;
    }
    own_speed = (int32_t)((int64_t)speed * (1000 - err) / 1000);   /* the train's share of a closing speed */
    /* and back: a remembered own speed plus the train's least speed rounded up, so that no curve
     * counts less of the obstacle's speed than the memory holds (issue 40 item 2) */
    own_speed_up = (int32_t)(((int64_t)speed * (1000 - err) + 999) / 1000);
    present = distance != RG_NO_DISTANCE;
    toward = have_closing ? closing : speed;
    confirmed = present && sys_status == RG_PRESENT && !sys_error;
    /* modules that see it with both channels: one creates a track, two (or a confirmed
     * picture) make it strong, remembered for forget_ms; one module's alone for forget_single_ms */
    sighted = 0;
    for (m = 0; m < modules; m++)
        if (statuses[2 * m] == RG_PRESENT && statuses[2 * m + 1] == RG_PRESENT) sighted++;
    /* several obstacles (rg_assign and the rest, tracks.py): the sighting measures the nearest
     * track whose window holds it, creates one ahead of or beyond them all; a confirmed sighting
     * beyond a track is evidence that it is gone (the sensors report their nearest object),
     * counted as ABSENT is (rg_forget), never an instant replacement */
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        tracks[i] = s->tracks[i];
        ages[i] = 0;          /* a remembered position's age was counted when it was moved */
        states[i] = RG_TRACK_NONE;
    }
    slot = -1;
    create = 0;
    if (present) slot = rg_assign(tracks, distance, cfg->distance_accuracy_dm, confirmed || sighted > 0, &create);
    evidence_absent = sys_status == RG_ABSENT && !sys_error;
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        rg_track_slot *k = &tracks[i];
        if (k->near == RG_NO_TRACK) continue;
        if (i == slot) {                    /* the track measured (rg_observe) */
            rg_track trk;
            int32_t seen_now;
            trk.near = k->near;
            trk.far = k->far;
            trk.closing_cms = k->closing;
            trk.age_ms = 0;
            rg_observe(&trk, distance, toward - own_speed, age, confirmed, sighted > 0);
            seen_now = trk.near == (int64_t)distance * RG_UNITS_PER_DM;
            ages[i] = trk.age_ms;
            states[i] = seen_now ? RG_TRACK_SEEN : RG_TRACK_HELD;   /* (a farther disputed sighting: not seen) */
            k->near = trk.near;
            k->far = trk.far;
            k->closing = trk.closing_cms;
            k->cycles = seen_now ? 0 : inc(k->cycles);
            k->absent = 0;
            k->strong = k->strong || confirmed || sighted >= 2;
        } else if (confirmed && slot >= 0 && rg_absorbed(k, slot, i, distance, cfg->distance_accuracy_dm)) {
            if (k->closing > tracks[slot].closing) tracks[slot].closing = k->closing;   /* its speed kept there */
            *k = RG_EMPTY_SLOT;             /* the same obstacle as the one measured */
        } else {                            /* not seen: evidence, or held */
            const int64_t far = (int64_t)k->far - rg_far_travel(train_ok ? speed : 0, err, track_accel, cfg->period_ms);
            const int32_t beyond = confirmed && rg_seen_beyond(k->near, k->far, distance, cfg->distance_accuracy_dm);
            /* the farthest the obstacle can lie: a distance accuracy beyond where it was reported */
            const int64_t reach = far + (int64_t)cfg->distance_accuracy_dm * RG_UNITS_PER_DM;
            const int32_t absent = rg_forget(k->absent, (beyond || evidence_absent) && !stale, reach,
                                             cfg->sensor_range_dm, k->strong ? forget_cycles : forget_single,
                                             &states[i]);
            if (states[i] == RG_TRACK_FORGOTTEN || states[i] == RG_TRACK_PASSED) {
                *k = RG_EMPTY_SLOT;
            } else {
                k->far = (int32_t)far;
                k->cycles = inc(k->cycles);
                k->absent = absent;
            }
        }
    }
    first_state = states[0];                /* what happened to the nearest */
    first_lost = first_state == RG_TRACK_FORGOTTEN || first_state == RG_TRACK_PASSED;
    if (create) {                           /* a new obstacle: remembered, or merged (rg_insert) */
        rg_track trk;
        rg_track_slot fresh;
        trk.near = RG_NO_TRACK;
        trk.far = RG_NO_TRACK;
        trk.closing_cms = 0;
        trk.age_ms = 0;
        rg_observe(&trk, distance, toward - own_speed, age, confirmed, 1);
        fresh.near = trk.near;
        fresh.far = trk.far;
        fresh.closing = trk.closing_cms;
        fresh.cycles = 0;
        fresh.absent = 0;
        fresh.strong = confirmed || sighted >= 2;
        (void)rg_insert(tracks, ages, states, &fresh, trk.age_ms, RG_TRACK_SEEN);
    }
    rg_ordered(tracks, ages, states);
    t_dm = rg_track_dm(tracks[0].near);
    t_state = first_lost ? first_state : (tracks[0].near != RG_NO_TRACK ? states[0] : RG_TRACK_NONE);
    t_cycles = first_lost ? 0 : tracks[0].cycles;
    /* the remembered obstacles as the next cycle finds them, from the memory alone: moved for
       the next period, worst case for the train; after a sighting also for the report's age
       (the remembered curves count no age: it is counted once, at the speed of the cycle that
       saw it); then in order (cycle.moved_tracks) */
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        next_tracks[i] = tracks[i];
        next_ages[i] = ages[i];
        next_states[i] = states[i];
        if (next_tracks[i].near != RG_NO_TRACK) {
            const int64_t near = (int64_t)next_tracks[i].near
                                 - rg_near_travel(speed, err, track_accel,
                                                  (int64_t)next_tracks[i].closing + cfg->closing_accuracy_cms,
                                                  (int64_t)cfg->period_ms + ages[i]);
            next_tracks[i].near = near > 0 ? (int32_t)near : 0;
        }
    }
    rg_ordered(next_tracks, next_ages, next_states);

    /* 5. braking curves at the measured speed for the voted obstacle and for every remembered
     *    one (its closing speed and the age of a sighting it took this cycle), unless it is the
     *    confirmed picture itself, under the reported conditions; the highest demand counts
     *    (rg_decide); the table's zones under normal ones; the observation reads the voted
     *    picture alone. Every curve is computed before anything is decided from them (the proof
     *    of the whole cycle follows the step to there: verification/physics/whole_cycle.py) */
    if (present) rg_curves(cfg, speed, track, brake, toward, age, 0, 1, &curve);
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        tcurves[i] = curve;
        watched[i] = tracks[i].near != RG_NO_TRACK
                     && !(confirmed && tracks[i].near == (int64_t)distance * RG_UNITS_PER_DM);
        if (watched[i])
            rg_curves(cfg, speed, track, brake, tracks[i].closing + own_speed_up, ages[i], 0, 1, &tcurves[i]);
    }
    if (present) {
        zone_limits(cfg, speed, toward, age, &alpha1, &alpha2);
        z = rg_zone(distance, alpha1, alpha2, cfg->warning_margin_dm);
    } else {
        z = sys_status == RG_DEGRADED ? 3 : 0;
    }
    /* every remembered obstacle on its own curves (its closing speed and the age of a sighting
     * it took this cycle); rg_decide supervises the one that demands the most (the highest
     * demand, then a warning: rg_supervision_demand warns whenever it demands, so that one's
     * demand and warning are the highest and any of them all). The nearest of them is what
     * the risk reads, and one that no channel shows this cycle is the memory's reason. */
    nearest = -1;
    worst = -1;
    worst_env = RG_MAINTAIN;
    worst_warn = 0;
    memory_reason = 0;
    /*@ loop pragma UNROLL RG_TRACKS + 1; */
    for (i = 0; i < RG_TRACKS; i++) {
        int32_t env_i, warn_i;
        if (!watched[i]) continue;
        env_i = rg_remembered_demand(rg_track_dm(tracks[i].near), &tcurves[i], s->held, &warn_i);
        if (worst < 0 || env_i > worst_env || (env_i == worst_env && warn_i > worst_warn)) {
            worst = i;
            worst_env = env_i;
            worst_warn = warn_i;
            tcurve = tcurves[i];
        }
        if (nearest < 0) nearest = i;
        if (states[i] != RG_TRACK_SEEN) memory_reason = 1;
    }
    spd = speed_class(toward, cfg->fast_closing_cms);
    obs = t->model == RG_MODEL_M1 ? z : (((z * 3 + spd) * 3 + obstacle) * 2 + track) * 2 + brake;

    /* the papers' risk at the nearest obstacle, voted or remembered; a blind picture with
     * nothing remembered reads as an obstacle at 0 m, as the observation reads it critical */
    near_dm = distance;
    if (nearest >= 0 && (distance == RG_NO_DISTANCE || rg_track_dm(tracks[nearest].near) < distance)) {
        near_dm = rg_track_dm(tracks[nearest].near);
        zone_limits(cfg, speed, tracks[nearest].closing + own_speed_up, ages[nearest], &alpha1, &alpha2);
    } else if (distance == RG_NO_DISTANCE && sys_status == RG_DEGRADED) {
        near_dm = 0;
        zone_limits(cfg, speed, speed, 0, &alpha1, &alpha2);
    }
    r1 = near_dm != RG_NO_DISTANCE ? rg_r1_ppm(near_dm, alpha1) : 0;
    r2 = near_dm != RG_NO_DISTANCE ? rg_r2_ppm(near_dm, alpha1, alpha2) : 0;
    score = rg_risk_score(z, spd, obstacle, track, brake);

    /* modes; a dispute is a system error with every channel fresh and the train input valid */
    error = sys_error || !train_ok;
    dispute = sys_error && train_ok && !stale;
    overrun_limit = in->overruns >= cfg->max_overruns;
    healthy = (error || stale || perceptor || overrun_limit) ? 0 : inc(s->healthy);
    mode = s->mode;
    if (perceptor || overrun_limit) {
        mode = RG_SAFE_STOP;
    } else if (mode == RG_INIT) {
        if (seen == all_seen) mode = error ? RG_DEGRADED_MODE : RG_NORMAL;
    } else if (mode == RG_SAFE_STOP) {
        if (train_ok && speed == 0 && healthy >= cfg->recovery_cycles) mode = RG_NORMAL;
    } else if (error) {
        mode = RG_DEGRADED_MODE;
    } else if (mode == RG_DEGRADED_MODE && healthy >= cfg->recovery_cycles) {
        mode = RG_NORMAL;
    }

    /* 6. table (held during any system error: it reads only pictures the voter confirms);
     *    what the table raised is held while the voted picture is in the table's zones (a
     *    remembered obstacle is the curves' business: the table acts on what is seen) */
    if (mode == RG_INIT) {
        node = (int32_t)t->start;
        table_demand = RG_MAINTAIN;
    } else {
        node = (error && mode != RG_SAFE_STOP) ? s->node : (int32_t)next_node(t, (uint32_t)s->node, (uint32_t)obs);
        table_demand = rg_table_hold(s->table_held, t->bytes[t->action_offset + (uint32_t)node], speed, z == 0);
    }

    /* 7. the error rules' demand; the curves' demand for the supervised obstacle, raised by
     *    the table's and the error rules' (only ever upwards), then the hold (released only
     *    after release_confirm_cycles in which the causes, remembered obstacles included, ask
     *    for less): rg_decide, whose contract says that a demand a curve raised is not
     *    lowered while the train is inside that curve for the remembered obstacle. INIT
     *    brakes without holding. */
    reasons = 0;
    error_demand = RG_MAINTAIN;
    if (error && !dispute && mode != RG_INIT) error_demand = cfg->safe_reaction;  /* INIT: covered below, unheld */
    if (mode == RG_SAFE_STOP) error_demand = RG_EMERGENCY;
    /* envelope.keep_held: an obstacle in sight and closing in, in the table's zones when the
     * keeping began, keeps what is held (until out of sight, opening, or standstill) */
    keep = present && toward > 0 && (z != 0 || s->kept != 0);
    held = rg_decide(distance, &curve, worst >= 0, worst >= 0 ? rg_track_dm(tracks[worst].near) : RG_NO_DISTANCE,
                     &tcurve, table_demand, error_demand, s->held, s->calm, speed,
                     cfg->emergency_release == RG_RELEASE_REVOCABLE, cfg->release_confirm_cycles,
                     keep, &dec);
    env = dec.env;
    warn = dec.warning;
    demand = dec.demand;
    calm = dec.calm;
    final_demand = dec.final_demand;
    if (table_demand) reasons |= RG_R_TABLE;
    if (env == RG_EMERGENCY) reasons |= RG_R_ENVELOPE;
    else if (env == RG_SERVICE) reasons |= RG_R_SBI;
    if (stale) reasons |= RG_R_STALE;
    if (memory_reason) reasons |= RG_R_MEMORY;
    if (implausible) reasons |= RG_R_IMPLAUSIBLE;
    if (error) {
        reasons |= RG_R_SYSTEM_ERROR | (train_ok ? 0 : RG_R_TRAIN_INPUT);
        if (dispute) {
            reasons |= RG_R_DISPUTE;
            warn = 1;
        }
    }
    if (mode == RG_SAFE_STOP)
        reasons |= RG_R_SAFE_STOP | (perceptor ? RG_R_PERCEPTOR : 0) | (overrun_limit ? RG_R_DEADLINE : 0);
    if (final_demand > demand) reasons |= RG_R_LATCH;
    if (mode == RG_INIT) {
        final_demand = RG_EMERGENCY;
        reasons |= RG_R_INIT;
    }
    if (warn) reasons |= RG_R_WARNING;

    error_cycles = (error || stale) ? inc(s->error_cycles) : s->error_cycles;
    s->mode = mode;
    s->node = node;
    s->held = held;
    s->seen = seen;
    for (m = 0; m < RG_MAX_MODULES; m++) {
        s->disagree[m] = m < modules ? disagree[m] : 0;
        s->agree[m] = m < modules ? agree[m] : 0;
    }
    s->healthy = healthy;
    s->cycle = inc(s->cycle);
    s->error_cycles = error_cycles;
    s->calm = calm;
    s->table_held = mode != RG_INIT ? table_demand : RG_MAINTAIN;
    for (i = 0; i < RG_TRACKS; i++) s->tracks[i] = next_tracks[i];
    s->kept = keep && speed > 0 && held > RG_MAINTAIN;

    out->demand = final_demand;
    out->reasons = reasons;
    out->distance_dm = distance;
    out->node = node;
    out->mode = mode;
    out->module_flags = flags;
    out->system_error = error;
    out->observation = obs;
    out->cycle = s->cycle;
    out->error_cycles = error_cycles;
    out->warning = warn;
    out->r1_ppm = r1;
    out->r2_ppm = r2;
    out->risk_score = score;
    out->risk_category = rg_risk_category(score);
    out->table_risk_ppm = (int32_t)node_risk(t, (uint32_t)node);
    out->track_dm = t_dm;
    out->track_cycles = t_cycles;
    out->track_state = t_state;
}

/* ---------------------------------------------------------------- the papers' risk (risk.py) */

#define RG_EXP_STEP 1072693760u   /* round(exp(-1/1024) * 2^30) */
#define RG_R1_K_LIMIT 16384       /* 5 d / alpha1 >= 16: R1 < 0.12 ppm, reported 0 */

/* e^(-k/1024) in Q30, floored at every product (risk.exp_neg_q30) */
static uint64_t exp_neg_q30(int32_t k)
{
    uint64_t result = 1u << 30, base = RG_EXP_STEP;
    while (k) {
        if (k & 1) result = (result * base) >> 30;
        base = (base * base) >> 30;
        k >>= 1;
    }
    return result;
}

/* 1 / (1 + e^(k/1024)) in 1/1024 ppm from q = e^(-k/1024) in Q30 */
static int64_t r1_fine(uint64_t q)
{
    return (int64_t)((((uint64_t)RG_PPM << 10) * q) / ((1u << 30) + q));
}

int32_t rg_r1_ppm(int32_t distance_dm, int32_t alpha1_dm)
{
    const int64_t num = (int64_t)5 * 1024 * distance_dm;
    int64_t here, there, k, rem, r1;
    uint64_t q;
    if (alpha1_dm <= 0) return distance_dm == 0 ? (int32_t)(RG_PPM / 2u) : 0;
    k = num / alpha1_dm;
    rem = num % alpha1_dm;
    if (k >= RG_R1_K_LIMIT) return 0;
    q = exp_neg_q30((int32_t)k);
    here = r1_fine(q);
    there = r1_fine((q * RG_EXP_STEP) >> 30);   /* k + 1 */
    r1 = (here - ((here - there) * rem) / alpha1_dm + 512) >> 10;
    /* never acts (0 <= r1 <= 500000 already); EVA does not relate here and there */
    return r1 < 0 ? 0 : (r1 > (int64_t)(RG_PPM / 2u) ? (int32_t)(RG_PPM / 2u) : (int32_t)r1);
}

int32_t rg_r2_ppm(int32_t distance_dm, int32_t alpha1_dm, int32_t alpha2_dm)
{
    int64_t span, r2;
    if (distance_dm <= alpha2_dm) return (int32_t)RG_PPM;
    if (distance_dm >= alpha1_dm) return 0;
    span = (int64_t)alpha1_dm - alpha2_dm;
    if (span <= 0) return (int32_t)RG_PPM;      /* never: alpha2 < distance < alpha1 (for EVA) */
    r2 = (((int64_t)alpha1_dm - distance_dm) * RG_PPM + span - 1) / span;
    /* never acts (0 < r2 <= 10^6: 0 < alpha1 - distance < span); EVA does not relate them */
    return r2 < 0 ? 0 : (r2 > (int64_t)RG_PPM ? (int32_t)RG_PPM : (int32_t)r2);
}

int32_t rg_risk_score(int32_t zone, int32_t speed, int32_t obstacle, int32_t track, int32_t brake)
{
    return 3 * zone + 2 * speed + 2 * obstacle + track + 2 * brake;
}

int32_t rg_risk_category(int32_t score)
{
    if (score <= 7) return 1;
    if (score <= 11) return 2;
    if (score <= 15) return 3;
    return 4;
}
