/* railguard online core in C99; see rg_core.h. Each function mirrors the Python function
 * of the same name in monitor/core, and the tests compare the two step by step. */
#include "rg_core.h"

#include <stdio.h>

#include "rg_sha256.h"

/* ACSL: the contracts on the functions below are the PEP 316 contracts of monitor/core
 * (freshness.py, voter.py, envelope.py), proved with Frama-C WP; fmu/c/proof/ holds the
 * EVA driver for the whole step; docs/proof.md says how to run both and what they cover.
 * Where a Python precondition is not needed by the C function it is left out (the contract
 * then holds for every int32 input, which is stronger) or becomes the premise of the
 * ensures that needs it. */
/*@ predicate rg_in_range_p(integer status, integer distance_dm, integer closing_cms, integer obstacle) =
        0 <= status <= 2 && 0 <= distance_dm <= 60000 && -15000 <= closing_cms <= 15000 && 0 <= obstacle <= 2;
    predicate rg_fresh_p(integer received, integer now, integer timeout_ticks) =
        received <= now && now - received <= timeout_ticks;
    logic integer rg_max3(integer a, integer b, integer c) = \max(a, \max(b, c));
    logic integer rg_min3(integer a, integer b, integer c) = \min(a, \min(b, c));
    logic integer rg_braking_num(integer v, integer a, integer t) = v * v * 10000 + 2 * a * v * t;
*/

void rg_config_default(rg_config *cfg)
{
    cfg->period_ms = 100;
    cfg->timeout_cycles = 3;
    cfg->persistence_cycles = 3;
    cfg->service_decel_mms2 = 1000;
    cfg->emergency_decel_mms2 = 3000;
    cfg->reaction_ms = 500;
    cfg->warning_margin_dm = 2000;
    cfg->fast_closing_cms = 2000;
    cfg->safe_reaction = RG_EMERGENCY;
    cfg->modules = 3;
    cfg->recovery_cycles = 10;
    cfg->max_overruns = 3;
    cfg->distance_tolerance_dm = 100;
}

static int refuse(char *msg, size_t len, const char *name, long value, const char *why)
{
    if (msg != NULL && len > 0) {
        snprintf(msg, len, "%s = %ld: %s", name, value, why);
    }
    return 1;
}

int rg_config_check(const rg_config *c, char *msg, size_t len)
{
    if (c->modules != 3 && c->modules != 1)
        return refuse(msg, len, "modules", c->modules, "must be 3 (3oo3 over three 2oo2 modules) or 1 (one 2oo2 module)");
    if (c->period_ms < 1 || c->period_ms > 10000)
        return refuse(msg, len, "period_ms", c->period_ms, "must be 1..10000 ms");
    if (c->timeout_cycles < 1)
        return refuse(msg, len, "timeout_cycles", c->timeout_cycles, "must be at least 1 cycle (0 would make every report stale)");
    if (c->persistence_cycles < 1)
        return refuse(msg, len, "persistence_cycles", c->persistence_cycles, "must be at least 1 cycle");
    if (c->persistence_cycles > c->timeout_cycles)
        return refuse(msg, len, "persistence_cycles", c->persistence_cycles, "must not exceed timeout_cycles");
    if (c->service_decel_mms2 <= 0)
        return refuse(msg, len, "service_decel_mms2", c->service_decel_mms2, "a deceleration must be positive (mm/s^2, magnitude)");
    if (c->emergency_decel_mms2 <= 0)
        return refuse(msg, len, "emergency_decel_mms2", c->emergency_decel_mms2, "a deceleration must be positive (mm/s^2, magnitude)");
    if (c->emergency_decel_mms2 < c->service_decel_mms2)
        return refuse(msg, len, "emergency_decel_mms2", c->emergency_decel_mms2, "must be at least service_decel_mms2");
    if (c->emergency_decel_mms2 > 20000)
        return refuse(msg, len, "emergency_decel_mms2", c->emergency_decel_mms2, "more than 20 m/s^2 is not a train");
    if (c->reaction_ms < 0 || c->reaction_ms > 60000)
        return refuse(msg, len, "reaction_ms", c->reaction_ms, "must be 0..60000 ms");
    if (c->warning_margin_dm < 0 || c->warning_margin_dm > 60000)
        return refuse(msg, len, "warning_margin_dm", c->warning_margin_dm, "must be 0..60000 dm");
    if (c->fast_closing_cms < 1 || c->fast_closing_cms > 15000)
        return refuse(msg, len, "fast_closing_cms", c->fast_closing_cms, "must be 1..15000 cm/s");
    if (c->safe_reaction != RG_SERVICE && c->safe_reaction != RG_EMERGENCY)
        return refuse(msg, len, "safe_reaction", c->safe_reaction, "must be 1 (service) or 2 (emergency)");
    if (c->recovery_cycles < 1)
        return refuse(msg, len, "recovery_cycles", c->recovery_cycles, "must be at least 1 cycle");
    if (c->max_overruns < 1)
        return refuse(msg, len, "max_overruns", c->max_overruns, "must be at least 1");
    if (c->distance_tolerance_dm < 0 || c->distance_tolerance_dm > 60000)
        return refuse(msg, len, "distance_tolerance_dm", c->distance_tolerance_dm, "must be 0..60000 dm");
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
    if ((t->bytes[8] | (t->bytes[9] << 8)) != 1)
        return table_refuse(msg, len, "table format version is not 1");
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
    if (t->action_offset + t->nodes != t->next_offset || body_end != t->length - 32)
        return table_refuse(msg, len, "body does not fit the dimensions");
    for (node = 0; node < t->nodes; node++) {
        if (t->bytes[t->action_offset + node] > RG_EMERGENCY)
            return table_refuse(msg, len, "an action index is >= the 3 actions");
        for (obs = 0; obs < t->observations; obs++) {
            if (next_node(t, node, obs) >= t->nodes)
                return table_refuse(msg, len, "a next-node index is >= the number of nodes");
        }
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
    s->latched = 0;
    s->seen = 0;
    for (m = 0; m < RG_MAX_MODULES; m++) s->disagree[m] = 0;
    s->healthy = 0;
    s->cycle = 0;
    s->error_cycles = 0;
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

/*@ requires 0 <= speed_cms <= 12000 && 1 <= decel_mms2 <= 20000 && 0 <= reaction_ms <= 60000;
    assigns \nothing;
    ensures \result >= 0;
    ensures \result * 2 * decel_mms2 * 10000 >= rg_braking_num(speed_cms, decel_mms2, reaction_ms);
    ensures (\result - 1) * 2 * decel_mms2 * 10000 < rg_braking_num(speed_cms, decel_mms2, reaction_ms) || \result == 0;
*/
int32_t rg_braking_distance_dm(int32_t speed_cms, int32_t decel_mms2, int32_t reaction_ms)
{
    int64_t v = speed_cms, a = decel_mms2, t = reaction_ms;
    int64_t num = v * v * 10000 + 2 * a * v * t;
    int64_t den = 2 * a * 10000;
    return (int32_t)((num + den - 1) / den);
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

/*@ assigns \nothing;
    ensures \result == (present != 0 && distance_dm <= alpha2_dm ? 2 : 0);
*/
int32_t rg_envelope_demand(int32_t present, int32_t distance_dm, int32_t alpha2_dm)
{
    return present && distance_dm <= alpha2_dm ? RG_EMERGENCY : RG_MAINTAIN;
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

/*@ requires \valid(final_demand);
    assigns *final_demand;
    ensures \result == 0 || \result == 1;
    ensures latched != 0 && speed_cms > 0 ==> \result == 1 && *final_demand == 2;
    ensures demand == 2 && speed_cms > 0 ==> \result == 1;
    ensures demand <= 2 ==> *final_demand >= demand;
    ensures speed_cms == 0 ==> \result == 0 && *final_demand == demand;
    ensures *final_demand == (\result == 1 ? 2 : demand);
*/
int32_t rg_latch(int32_t latched, int32_t demand, int32_t speed_cms, int32_t *final_demand)
{
    int32_t held = (latched || demand == RG_EMERGENCY) && speed_cms > 0;
    *final_demand = held ? RG_EMERGENCY : demand;
    return held;
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
 * (here: a state whose node is outside the table). */
static void safe_stop_fallback(rg_state *s, rg_outputs *out)
{
    s->cycle = inc(s->cycle);
    s->error_cycles = inc(s->error_cycles);
    s->mode = RG_SAFE_STOP;
    s->latched = 1;
    s->healthy = 0;
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
}

void rg_step(const rg_config *cfg, const rg_table *t, rg_state *s, const rg_inputs *in, int64_t tick, rg_outputs *out)
{
    const int32_t modules = cfg->modules == 1 ? 1 : 3;
    const int32_t channels = 2 * modules;
    const int64_t timeout_ticks = (int64_t)cfg->timeout_cycles * cfg->period_ms;
    const uint32_t all_seen = (1u << channels) - 1u;
    int32_t statuses[RG_MAX_CHANNELS];
    int32_t ms[RG_MAX_MODULES], md[RG_MAX_MODULES], mf[RG_MAX_MODULES], disagree[RG_MAX_MODULES];
    uint32_t seen = s->seen;
    int32_t stale = 0, have_closing = 0, closing = 0, obstacle = 0, flags = 0, perceptor = 0;
    int32_t sys_status, distance, sys_error;
    int32_t speed, track, brake, train_ok, alpha1, alpha2, env, z, obs, error, overrun_limit, healthy, mode;
    int32_t node, table_demand, reasons, error_demand, demand, latched, final_demand, error_cycles;
    int32_t i, m;

    if (s->node < 0 || (uint32_t)s->node >= t->nodes) {
        safe_stop_fallback(s, out);
        return;
    }

    /* 1. freshness and range per channel */
    for (i = 0; i < channels; i++) {
        statuses[i] = rg_effective_status(&in->reports[i], tick, timeout_ticks);
        if (statuses[i] == RG_DEGRADED) {
            stale = 1;
        } else {
            seen |= 1u << i;
            if (statuses[i] == RG_PRESENT) {
                const rg_report *r = &in->reports[i];
                /* rg_effective_status's contract gives this (WP proves it); EVA, which
                 * cannot relate the status to the fields, takes the ranges from it */
                /*@ assert present_in_range: 0 <= r->distance_dm <= 60000 && -15000 <= r->closing_cms <= 15000
                                             && 0 <= r->obstacle <= 2; */
                if (!have_closing || r->closing_cms > closing) closing = r->closing_cms;
                have_closing = 1;
                if (r->obstacle > obstacle) obstacle = r->obstacle;
            }
        }
    }

    /* 2. 2oo2 per module, with disagreement persistence */
    for (m = 0; m < modules; m++) {
        int32_t sa = statuses[2 * m], sb = statuses[2 * m + 1];
        int32_t da = sa == RG_PRESENT ? in->reports[2 * m].distance_dm : 0;
        int32_t db = sb == RG_PRESENT ? in->reports[2 * m + 1].distance_dm : 0;
        rg_vote_2oo2(sa, da, sb, db, &ms[m], &md[m], &mf[m]);
        if (rg_distances_disagree(sa, da, sb, db, cfg->distance_tolerance_dm)) mf[m] = 1;
        if (mf[m]) flags |= 1 << m;
        disagree[m] = rg_disagreement(sa, sb) ? inc(s->disagree[m]) : 0;
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

    /* 4. envelope at the current speed; an invalid train state is read to the safe side */
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
    alpha1 = rg_braking_distance_dm(speed, cfg->service_decel_mms2, cfg->reaction_ms);
    alpha2 = rg_braking_distance_dm(speed, cfg->emergency_decel_mms2, cfg->reaction_ms);
    env = rg_envelope_demand(distance != RG_NO_DISTANCE, distance, alpha2);

    /* 5. observation */
    if (distance != RG_NO_DISTANCE) {
        z = rg_zone(distance, alpha1, alpha2, cfg->warning_margin_dm);
    } else {
        z = sys_status == RG_DEGRADED ? 3 : 0;
    }
    if (t->model == RG_MODEL_M1) {
        obs = z;
    } else {
        int32_t spd = speed_class(have_closing ? closing : speed, cfg->fast_closing_cms);
        obs = (((z * 3 + spd) * 3 + obstacle) * 2 + track) * 2 + brake;
    }

    /* modes */
    error = sys_error || !train_ok;
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

    /* 6. table */
    if (mode == RG_INIT) {
        node = (int32_t)t->start;
        table_demand = RG_MAINTAIN;
    } else {
        node = (int32_t)next_node(t, (uint32_t)s->node, (uint32_t)obs);
        table_demand = t->bytes[t->action_offset + (uint32_t)node];
    }

    /* 7. demands, only ever upwards, then the latch */
    reasons = 0;
    error_demand = RG_MAINTAIN;
    if (table_demand) reasons |= RG_R_TABLE;
    if (env) reasons |= RG_R_ENVELOPE;
    if (stale) reasons |= RG_R_STALE;
    if (error) {
        error_demand = cfg->safe_reaction;
        reasons |= RG_R_SYSTEM_ERROR | (train_ok ? 0 : RG_R_TRAIN_INPUT);
    }
    if (mode == RG_INIT) {
        error_demand = RG_EMERGENCY;
        reasons |= RG_R_INIT;
    }
    if (mode == RG_SAFE_STOP) {
        error_demand = RG_EMERGENCY;
        reasons |= RG_R_SAFE_STOP | (perceptor ? RG_R_PERCEPTOR : 0) | (overrun_limit ? RG_R_DEADLINE : 0);
    }
    demand = rg_combine(table_demand, env, error_demand);
    latched = rg_latch(s->latched, demand, speed, &final_demand);
    if (latched && s->latched) reasons |= RG_R_LATCH;

    error_cycles = (error || stale) ? inc(s->error_cycles) : s->error_cycles;
    s->mode = mode;
    s->node = node;
    s->latched = latched;
    s->seen = seen;
    for (m = 0; m < RG_MAX_MODULES; m++) s->disagree[m] = m < modules ? disagree[m] : 0;
    s->healthy = healthy;
    s->cycle = inc(s->cycle);
    s->error_cycles = error_cycles;

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
}
