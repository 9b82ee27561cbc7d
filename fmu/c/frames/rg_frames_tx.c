/* The sending side of the frame layer and the brakes' receiver: codec.Sender and encode,
 * runner.MonitorRunner.send, the player's reports and train state, brake_receiver.py
 * (see rg_frames.h). */
#include "rg_frames.h"

#include <string.h>

void rg_sender_init(rg_sender *s, const rg_keyset *keys)
{
    memset(s, 0, sizeof *s);
    if (keys != NULL) {
        s->secured = 1;
        s->keys = *keys;
    }
}

int rg_sender_frame(rg_sender *s, uint32_t frame_id, const uint8_t payload[RG_FRAME_LENGTH], rg_frame *out)
{
    int32_t index = rg_frames_index(frame_id);
    int32_t c;
    uint8_t data[RG_FRAME_LENGTH];
    if (index < 0) return -1;
    c = s->has_counter[index] ? (s->counter[index] + 1) & 0xF : 0;
    s->has_counter[index] = 1;
    s->counter[index] = c;
    memcpy(data, payload, RG_FRAME_LENGTH);
    data[1] = (uint8_t)((data[1] & 0xF0u) | (uint8_t)c);
    data[0] = rg_frames_crc(data, frame_id);
    out->id = frame_id;
    memset(out->data, 0, sizeof out->data);
    if (!s->secured) {
        memcpy(out->data, data, RG_FRAME_LENGTH);
        out->length = RG_FRAME_LENGTH;
        out->is_fd = 0;
        return 0;
    }
    {
        int32_t owner = rg_frames_owner(index);
        uint64_t fv = s->next_freshness[index];
        if (!s->keys.have[owner]) return -1;       /* a node signs only its own IDs */
        s->next_freshness[index] = fv + 1u;
        out->length = RG_SECOC_FRAME;
        out->is_fd = 1;
        return rg_secoc_protect(s->keys.key[owner], (uint16_t)frame_id, data, fv, out->data);
    }
}

static int32_t min32(int32_t a, int32_t b)
{
    return a < b ? a : b;
}

/* runner.per_mille_up: 0.1 % from ppm, rounded up */
static int32_t per_mille_up(int32_t ppm)
{
    int32_t q = ppm / 1000, r = ppm % 1000;
    return r > 0 ? q + 1 : q;                 /* Python's floor division of (ppm + 999) // 1000 */
}

/* runner.track_age: cycles x period to the nearest 0.1 s, saturating */
static int32_t track_age(int32_t cycles, int32_t period_ms)
{
    int64_t a = ((int64_t)cycles * period_ms + 50) / 100;
    if ((int64_t)cycles * period_ms + 50 < 0 && ((int64_t)cycles * period_ms + 50) % 100 != 0) a -= 1;   /* floor */
    return a > RG_TRACK_AGE_MAX ? RG_TRACK_AGE_MAX : (int32_t)a;
}

int rg_monitor_send(rg_sender *s, const rg_outputs *out, int32_t foreign_output, int32_t table_hash,
                    int32_t deadline_misses, int32_t period_ms, int32_t withhold_demand, rg_frame frames[4])
{
    uint8_t payload[RG_FRAME_LENGTH];
    int32_t flags, n = 0;
    flags = (out->module_flags & 7) | (out->system_error ? 1 << 3 : 0);
    flags |= (out->reasons & RG_R_STALE ? 1 << 4 : 0) | (out->reasons & RG_R_PERCEPTOR ? 1 << 5 : 0);
    if (!withhold_demand) {
        struct rg_dbc_brake_demand_t v;
        memset(&v, 0, sizeof v);
        v.level = (uint8_t)out->demand;
        v.warning = (uint8_t)(out->warning != 0);
        v.reason = (uint16_t)(out->reasons & 0xFFFF);
        v.cycle = (uint32_t)out->cycle;
        rg_dbc_brake_demand_pack(payload, &v, sizeof payload);
        if (rg_sender_frame(s, RG_DBC_BRAKE_DEMAND_FRAME_ID, payload, &frames[n++]) != 0) return -1;
    }
    {
        struct rg_dbc_monitor_status_t v;
        memset(&v, 0, sizeof v);
        v.mode = (uint8_t)out->mode;
        v.warning = (uint8_t)(out->warning != 0);
        v.foreign_output = (uint8_t)(foreign_output != 0);
        v.node = (uint16_t)min32(out->node, 1023);
        v.error_flags = (uint8_t)flags;
        v.voted_distance = (uint16_t)(out->distance_dm != RG_NO_DISTANCE ? out->distance_dm : RG_NO_DISTANCE_RAW);
        v.table_hash = (uint16_t)table_hash;
        v.deadline_misses = (uint8_t)min32(deadline_misses, 15);
        rg_dbc_monitor_status_pack(payload, &v, sizeof payload);
        if (rg_sender_frame(s, RG_DBC_MONITOR_STATUS_FRAME_ID, payload, &frames[n++]) != 0) return -1;
    }
    {
        struct rg_dbc_monitor_track_t v;
        memset(&v, 0, sizeof v);
        v.track_state = (uint8_t)out->track_state;
        v.memory = (uint8_t)((out->reasons & RG_R_MEMORY) != 0);
        v.track_distance = (uint16_t)min32(out->track_dm, RG_NO_DISTANCE_RAW);
        v.track_age = (uint16_t)track_age(out->track_cycles, period_ms);
        rg_dbc_monitor_track_pack(payload, &v, sizeof payload);
        if (rg_sender_frame(s, RG_DBC_MONITOR_TRACK_FRAME_ID, payload, &frames[n++]) != 0) return -1;
    }
    {
        struct rg_dbc_monitor_risk_t v;
        memset(&v, 0, sizeof v);
        v.risk_category = (uint8_t)out->risk_category;
        v.risk_score = (uint8_t)out->risk_score;
        v.r1 = (uint16_t)per_mille_up(out->r1_ppm);
        v.r2 = (uint16_t)per_mille_up(out->r2_ppm);
        v.table_risk = (uint32_t)out->table_risk_ppm;
        v.unsecured = (uint8_t)(s->secured == 0);
        rg_dbc_monitor_risk_pack(payload, &v, sizeof payload);
        if (rg_sender_frame(s, RG_DBC_MONITOR_RISK_FRAME_ID, payload, &frames[n++]) != 0) return -1;
    }
    return n;
}

int rg_send_report(rg_sender *s, int32_t channel, int32_t status, int32_t distance_dm, int32_t closing_cms,
                   int32_t obstacle, rg_frame *out)
{
    uint8_t payload[RG_FRAME_LENGTH];
    struct rg_dbc_obstacle_report_m1_c1_t v;     /* the six reports share one layout (the DBC) */
    if (channel < 0 || channel >= RG_MAX_CHANNELS) return -1;
    memset(&v, 0, sizeof v);
    v.status = (uint8_t)status;
    v.obstacle_type = (uint8_t)obstacle;
    v.distance = (uint16_t)distance_dm;
    v.closing_speed = (int16_t)closing_cms;
    v.module = (uint8_t)(channel / 2);
    v.channel = (uint8_t)(channel % 2);
    rg_dbc_obstacle_report_m1_c1_pack(payload, &v, sizeof payload);
    return rg_sender_frame(s, RG_DBC_OBSTACLE_REPORT_M1_C1_FRAME_ID + (uint32_t)channel, payload, out);
}

int rg_send_train(rg_sender *s, int32_t speed_cms, int32_t track, int32_t brake, rg_frame *out)
{
    uint8_t payload[RG_FRAME_LENGTH];
    struct rg_dbc_train_state_t v;
    memset(&v, 0, sizeof v);
    v.speed = (uint16_t)speed_cms;
    v.track_condition = (uint8_t)track;
    v.brake_status = (uint8_t)brake;
    rg_dbc_train_state_pack(payload, &v, sizeof payload);
    return rg_sender_frame(s, RG_DBC_TRAIN_STATE_FRAME_ID, payload, out);
}

/* ------------------------------------------------------------------ brake_receiver.BrakeReceiver */

void rg_brake_init(rg_brake_receiver *b, int32_t period_ms)
{
    memset(b, 0, sizeof *b);
    b->period_ms = period_ms;
    b->latched = RG_CAUSE_NONE;
}

int32_t rg_brake_fault(rg_brake_receiver *b, const rg_receiver *rx, int64_t tick)
{
    if (rg_receiver_contested(rx, RG_DBC_BRAKE_DEMAND_FRAME_ID, tick)) return RG_CAUSE_SECOND_SENDER;
    if (!rx->has_demand) return b->heard ? RG_CAUSE_TIMEOUT : RG_CAUSE_POWER_UP;
    b->heard = 1;
    if (rx->has_demand_invalid && rx->demand_invalid >= rx->demand_tick) return RG_CAUSE_INVALID_LEVEL;
    if (tick - rx->demand_tick >= (int64_t)RG_BRAKE_TIMEOUT_PERIODS * b->period_ms) {
        if (!b->has_silent) {
            b->has_silent = 1;
            b->silent_ms = tick - rx->demand_tick;
        }
        return RG_CAUSE_TIMEOUT;
    }
    return RG_CAUSE_NONE;
}

int32_t rg_brake_level(rg_brake_receiver *b, const rg_receiver *rx, int64_t tick, int32_t standing)
{
    int32_t cause = rg_brake_fault(b, rx, tick);
    if (cause == RG_CAUSE_POWER_UP) {            /* not held: the first valid frame ends it */
        b->causes[cause]++;
        return RG_EMERGENCY;
    }
    if (cause != RG_CAUSE_NONE) {
        b->latched = cause;
    } else if (b->latched != RG_CAUSE_NONE && standing) {
        b->latched = RG_CAUSE_NONE;
    }
    if (b->latched != RG_CAUSE_NONE) {
        b->causes[b->latched]++;
        return RG_EMERGENCY;
    }
    return rx->demand.level;
}
