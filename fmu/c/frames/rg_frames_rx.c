/* The receive side of the frame layer: codec.Receiver, security's check, and
 * runner.MonitorCore's ingest and inputs (see rg_frames.h). */
#include "rg_frames.h"

#include <string.h>

static const uint32_t FRAME_IDS[RG_FRAMES_MESSAGES] = {
    RG_DBC_BRAKE_DEMAND_FRAME_ID,
    RG_DBC_OBSTACLE_REPORT_M1_C1_FRAME_ID, RG_DBC_OBSTACLE_REPORT_M1_C2_FRAME_ID,
    RG_DBC_OBSTACLE_REPORT_M2_C1_FRAME_ID, RG_DBC_OBSTACLE_REPORT_M2_C2_FRAME_ID,
    RG_DBC_OBSTACLE_REPORT_M3_C1_FRAME_ID, RG_DBC_OBSTACLE_REPORT_M3_C2_FRAME_ID,
    RG_DBC_TRAIN_STATE_FRAME_ID, RG_DBC_MONITOR_STATUS_FRAME_ID, RG_DBC_MONITOR_TRACK_FRAME_ID,
    RG_DBC_MONITOR_RISK_FRAME_ID,
};

/* keys.OWNER: the sender whose key signs each message */
static const int32_t OWNER[RG_FRAMES_MESSAGES] = {
    RG_KEY_MONITOR, 0, 1, 2, 3, 4, 5, RG_KEY_TRAIN, RG_KEY_MONITOR, RG_KEY_MONITOR, RG_KEY_MONITOR,
};

int32_t rg_frames_index(uint32_t frame_id)
{
    int32_t i;
    for (i = 0; i < RG_FRAMES_MESSAGES; i++) {
        if (FRAME_IDS[i] == frame_id) return i;
    }
    return -1;
}

int32_t rg_frames_owner(int32_t index)
{
    return OWNER[index];
}

uint8_t rg_frames_crc(const uint8_t data[RG_FRAME_LENGTH], uint32_t frame_id)
{
    uint8_t crc = 0xFFu, byte;
    int i, bit;
    for (i = 1; i <= RG_FRAME_LENGTH; i++) {
        byte = i < RG_FRAME_LENGTH ? data[i] : (uint8_t)(frame_id & 0xFFu);   /* bytes 1..7, then the data ID */
        crc ^= byte;
        for (bit = 0; bit < 8; bit++) {
            crc = (uint8_t)((crc & 0x80u) ? (uint8_t)(crc << 1) ^ 0x2Fu : (uint8_t)(crc << 1));
        }
    }
    return (uint8_t)(crc ^ 0xFFu);
}

#define OBSTACLE_RANGE(m)                                                                                      \
    {                                                                                                          \
        struct rg_dbc_obstacle_report_##m##_t v;                                                               \
        rg_dbc_obstacle_report_##m##_unpack(&v, data, RG_FRAME_LENGTH);                                        \
        return rg_dbc_obstacle_report_##m##_crc_is_in_range(v.crc)                                             \
               && rg_dbc_obstacle_report_##m##_counter_is_in_range(v.counter)                                  \
               && rg_dbc_obstacle_report_##m##_status_is_in_range(v.status)                                    \
               && rg_dbc_obstacle_report_##m##_obstacle_type_is_in_range(v.obstacle_type)                      \
               && rg_dbc_obstacle_report_##m##_distance_is_in_range(v.distance)                                \
               && rg_dbc_obstacle_report_##m##_closing_speed_is_in_range(v.closing_speed)                      \
               && rg_dbc_obstacle_report_##m##_module_is_in_range(v.module)                                    \
               && rg_dbc_obstacle_report_##m##_channel_is_in_range(v.channel);                                 \
    }

int32_t rg_frames_in_range(int32_t index, const uint8_t data[RG_FRAME_LENGTH])
{
    switch (index) {
    case RG_MSG_BRAKE_DEMAND: {
        struct rg_dbc_brake_demand_t v;
        rg_dbc_brake_demand_unpack(&v, data, RG_FRAME_LENGTH);
        return rg_dbc_brake_demand_crc_is_in_range(v.crc) && rg_dbc_brake_demand_counter_is_in_range(v.counter)
               && rg_dbc_brake_demand_level_is_in_range(v.level) && rg_dbc_brake_demand_warning_is_in_range(v.warning)
               && rg_dbc_brake_demand_reason_is_in_range(v.reason) && rg_dbc_brake_demand_cycle_is_in_range(v.cycle);
    }
    case RG_MSG_OBSTACLE + 0: OBSTACLE_RANGE(m1_c1)
    case RG_MSG_OBSTACLE + 1: OBSTACLE_RANGE(m1_c2)
    case RG_MSG_OBSTACLE + 2: OBSTACLE_RANGE(m2_c1)
    case RG_MSG_OBSTACLE + 3: OBSTACLE_RANGE(m2_c2)
    case RG_MSG_OBSTACLE + 4: OBSTACLE_RANGE(m3_c1)
    case RG_MSG_OBSTACLE + 5: OBSTACLE_RANGE(m3_c2)
    case RG_MSG_TRAIN_STATE: {
        struct rg_dbc_train_state_t v;
        rg_dbc_train_state_unpack(&v, data, RG_FRAME_LENGTH);
        return rg_dbc_train_state_crc_is_in_range(v.crc) && rg_dbc_train_state_counter_is_in_range(v.counter)
               && rg_dbc_train_state_track_condition_is_in_range(v.track_condition)
               && rg_dbc_train_state_brake_status_is_in_range(v.brake_status)
               && rg_dbc_train_state_speed_is_in_range(v.speed);
    }
    case RG_MSG_MONITOR_STATUS: {
        struct rg_dbc_monitor_status_t v;
        rg_dbc_monitor_status_unpack(&v, data, RG_FRAME_LENGTH);
        return rg_dbc_monitor_status_crc_is_in_range(v.crc) && rg_dbc_monitor_status_counter_is_in_range(v.counter)
               && rg_dbc_monitor_status_mode_is_in_range(v.mode) && rg_dbc_monitor_status_warning_is_in_range(v.warning)
               && rg_dbc_monitor_status_foreign_output_is_in_range(v.foreign_output)
               && rg_dbc_monitor_status_node_is_in_range(v.node)
               && rg_dbc_monitor_status_error_flags_is_in_range(v.error_flags)
               && rg_dbc_monitor_status_voted_distance_is_in_range(v.voted_distance)
               && rg_dbc_monitor_status_table_hash_is_in_range(v.table_hash)
               && rg_dbc_monitor_status_deadline_misses_is_in_range(v.deadline_misses);
    }
    case RG_MSG_MONITOR_TRACK: {
        struct rg_dbc_monitor_track_t v;
        rg_dbc_monitor_track_unpack(&v, data, RG_FRAME_LENGTH);
        return rg_dbc_monitor_track_crc_is_in_range(v.crc) && rg_dbc_monitor_track_counter_is_in_range(v.counter)
               && rg_dbc_monitor_track_track_state_is_in_range(v.track_state)
               && rg_dbc_monitor_track_memory_is_in_range(v.memory)
               && rg_dbc_monitor_track_track_distance_is_in_range(v.track_distance)
               && rg_dbc_monitor_track_track_age_is_in_range(v.track_age);
    }
    case RG_MSG_MONITOR_RISK: {
        struct rg_dbc_monitor_risk_t v;
        rg_dbc_monitor_risk_unpack(&v, data, RG_FRAME_LENGTH);
        return rg_dbc_monitor_risk_crc_is_in_range(v.crc) && rg_dbc_monitor_risk_counter_is_in_range(v.counter)
               && rg_dbc_monitor_risk_risk_category_is_in_range(v.risk_category)
               && rg_dbc_monitor_risk_risk_score_is_in_range(v.risk_score)
               && rg_dbc_monitor_risk_r1_is_in_range(v.r1) && rg_dbc_monitor_risk_r2_is_in_range(v.r2)
               && rg_dbc_monitor_risk_unsecured_is_in_range(v.unsecured)
               && rg_dbc_monitor_risk_table_risk_is_in_range(v.table_risk);
    }
    default:
        return 0;
    }
}

/* ------------------------------------------------------------------ codec.Receiver */

void rg_receiver_init(rg_receiver *rx, int32_t channels, int32_t rate_window_ms, const rg_keyset *keys)
{
    memset(rx, 0, sizeof *rx);
    rx->channels = channels < 0 ? 0 : (channels > RG_MAX_CHANNELS ? RG_MAX_CHANNELS : channels);
    rx->rate_window_ms = rate_window_ms;
    if (keys != NULL) {
        rx->secured = 1;
        rx->keys = *keys;
    }
}

static int32_t reject(rg_receiver *rx, int32_t reason)
{
    rx->rejected[reason]++;
    return reason;
}

/* _withdraw: the channel reads as never heard from, the BrakeDemand as absent */
static void withdraw(rg_receiver *rx, int32_t index)
{
    int32_t ch = index - RG_MSG_OBSTACLE;
    if (index >= RG_MSG_OBSTACLE && ch < RG_MAX_CHANNELS && ch < rx->channels) {
        memset(&rx->reports[ch], 0, sizeof rx->reports[ch]);
    } else if (index == RG_MSG_BRAKE_DEMAND) {
        rx->has_demand = 0;
    }
}

static int32_t babbling(rg_receiver *rx, int32_t index, rg_sender_state *st, int64_t tick)
{
    int32_t excess, i;
    if (st->recent_count == RG_MAX_FRAMES_PER_WINDOW + 1) {     /* the deque drops its oldest */
        for (i = 0; i < RG_MAX_FRAMES_PER_WINDOW; i++) st->recent[i] = st->recent[i + 1];
        st->recent_count--;
    }
    st->recent[st->recent_count++] = tick;
    excess = st->recent_count > RG_MAX_FRAMES_PER_WINDOW && 0 <= tick - st->recent[0]
             && tick - st->recent[0] < rx->rate_window_ms;
    if (excess) {
        st->has_quarantine = 1;
        st->quarantine_until = tick + RG_BABBLE_QUARANTINE_MS;
    }
    if (excess || (st->has_quarantine && tick < st->quarantine_until)) {
        withdraw(rx, index);
        return 1;
    }
    return 0;
}

static int32_t second_sender(rg_receiver *rx, int32_t index, rg_sender_state *st, const uint8_t *data, int64_t tick)
{
    int32_t had = st->has_last;
    int64_t last_tick = st->last_tick;
    uint8_t last[RG_FRAME_LENGTH];
    memcpy(last, st->last, sizeof last);
    st->has_last = 1;
    st->last_tick = tick;
    memcpy(st->last, data, RG_FRAME_LENGTH);
    if (had && 0 <= tick - last_tick && tick - last_tick < RG_CONFLICT_WINDOW_MS && (data[1] & 0xF) == (last[1] & 0xF)
        && memcmp(data, last, RG_FRAME_LENGTH) != 0) {
        st->has_contested = 1;
        st->contested_until = tick + RG_SECOND_SENDER_QUARANTINE_MS;
    }
    if (st->has_contested && tick < st->contested_until) {
        withdraw(rx, index);
        return 1;
    }
    return 0;
}

int32_t rg_receiver_contested(const rg_receiver *rx, uint32_t frame_id, int64_t tick)
{
    int32_t index = rg_frames_index(frame_id);
    return index >= 0 && rx->senders[index].has_contested && tick < rx->senders[index].contested_until;
}

/* security.Security.open: RG_ACCEPTED with the payload in `payload`, or the refusal */
static int32_t open_secured(rg_receiver *rx, int32_t index, const uint8_t *data, size_t length,
                            uint8_t payload[RG_FRAME_LENGTH])
{
    int32_t owner = OWNER[index];
    uint64_t fv = 0;
    int verdict;
    if (!rx->keys.have[owner]) return RG_REJ_NO_KEY;
    verdict = rg_secoc_check(rx->keys.key[owner], (uint16_t)FRAME_IDS[index], data, length, rx->has_newest[index],
                             rx->newest[index], &fv);
    switch (verdict) {
    case RG_SECOC_OK:
        rx->has_newest[index] = 1;
        rx->newest[index] = fv;
        memcpy(payload, data, RG_FRAME_LENGTH);
        return RG_ACCEPTED;
    case RG_SECOC_WRONG_LENGTH: return RG_REJ_WRONG_LENGTH;
    case RG_SECOC_STALE: return RG_REJ_STALE_FRESHNESS;
    case RG_SECOC_BAD_MAC: return RG_REJ_BAD_MAC;
    default: return RG_REJ_UNDECODABLE;      /* libcrypto failed: the frame cannot be judged */
    }
}

static void latch(rg_receiver *rx, int32_t index, const uint8_t *data, int64_t tick)
{
    switch (index) {
    case RG_MSG_TRAIN_STATE: {
        struct rg_dbc_train_state_t v;
        rg_dbc_train_state_unpack(&v, data, RG_FRAME_LENGTH);
        rx->has_train = 1;
        rx->train.speed_cms = v.speed;
        rx->train.track = v.track_condition;
        rx->train.brake = v.brake_status;
        rx->train_tick = tick;
        break;
    }
    case RG_MSG_BRAKE_DEMAND:
        rg_dbc_brake_demand_unpack(&rx->demand, data, RG_FRAME_LENGTH);
        rx->has_demand = 1;
        rx->demand_tick = tick;
        break;
    case RG_MSG_MONITOR_STATUS:
        rg_dbc_monitor_status_unpack(&rx->status, data, RG_FRAME_LENGTH);
        rx->has_status = 1;
        rx->status_tick = tick;
        break;
    case RG_MSG_MONITOR_TRACK:
        rg_dbc_monitor_track_unpack(&rx->track, data, RG_FRAME_LENGTH);
        rx->has_track = 1;
        rx->track_tick = tick;
        break;
    case RG_MSG_MONITOR_RISK:
        rg_dbc_monitor_risk_unpack(&rx->risk, data, RG_FRAME_LENGTH);
        rx->has_risk = 1;
        rx->risk_tick = tick;
        break;
    default:
        break;
    }
}

int32_t rg_receiver_accept(rg_receiver *rx, uint32_t frame_id, int32_t extended, const uint8_t *data, size_t length,
                           int64_t tick)
{
    uint8_t payload[RG_FRAME_LENGTH];
    rg_sender_state *st;
    int32_t index, verdict, counter;
    if (extended) return reject(rx, RG_REJ_UNKNOWN_ID);      /* the DBC has only 11-bit identifiers */
    index = rg_frames_index(frame_id);
    if (index < 0) return reject(rx, RG_REJ_UNKNOWN_ID);
    st = &rx->senders[index];
    if (rx->rate_window_ms > 0 && index >= RG_MSG_OBSTACLE && index <= RG_MSG_TRAIN_STATE
        && babbling(rx, index, st, tick)) {
        st->has_counter = 0;                                 /* the stream is broken: resynchronise afterwards */
        return reject(rx, RG_REJ_RATE_EXCEEDED);
    }
    if (rx->secured) {
        verdict = open_secured(rx, index, data, length, payload);
        if (verdict != RG_ACCEPTED) {
            if (verdict == RG_REJ_BAD_MAC) {                 /* a node without the owner's key writes the ID */
                st->has_contested = 1;
                st->contested_until = tick + RG_SECOND_SENDER_QUARANTINE_MS;
                withdraw(rx, index);
            }
            return reject(rx, verdict);
        }
    } else {
        if (length != RG_FRAME_LENGTH) return reject(rx, RG_REJ_WRONG_LENGTH);
        memcpy(payload, data, RG_FRAME_LENGTH);
    }
    if (rg_frames_crc(payload, frame_id) != payload[0]) return reject(rx, RG_REJ_BAD_CRC);
    if (second_sender(rx, index, st, payload, tick)) return reject(rx, RG_REJ_SECOND_SENDER);
    counter = payload[1] & 0xF;
    if (st->has_counter) {
        int32_t delta = (counter - st->counter) & 0xF;
        if (delta == 0) return reject(rx, RG_REJ_REPEATED_COUNTER);
        if (delta != 1) {
            st->counter = counter;                           /* resynchronise on the next frame */
            return reject(rx, RG_REJ_COUNTER_JUMP);
        }
    }
    st->has_counter = 1;
    st->counter = counter;
    if (!rg_frames_in_range(index, payload)) {
        if (index == RG_MSG_BRAKE_DEMAND) {
            rx->has_demand_invalid = 1;
            rx->demand_invalid = tick;
        }
        return reject(rx, RG_REJ_OUT_OF_RANGE);
    }
    if (index >= RG_MSG_OBSTACLE && index < RG_MSG_OBSTACLE + RG_MAX_CHANNELS) {
        int32_t ch = index - RG_MSG_OBSTACLE;
        struct rg_dbc_obstacle_report_m1_c1_t v;             /* the six reports share one layout (the DBC) */
        rg_dbc_obstacle_report_m1_c1_unpack(&v, payload, RG_FRAME_LENGTH);
        if (ch >= rx->channels || v.module != ch / 2 || v.channel != ch % 2) {
            return reject(rx, RG_REJ_OUT_OF_RANGE);          /* a report claiming another module/channel */
        }
        rx->reports[ch].heard = 1;
        rx->reports[ch].status = v.status;
        rx->reports[ch].distance_dm = v.distance;
        rx->reports[ch].closing_cms = v.closing_speed;
        rx->reports[ch].obstacle = v.obstacle_type;
        rx->reports[ch].tick = tick;
    } else {
        latch(rx, index, payload, tick);
    }
    rx->accepted++;
    return RG_ACCEPTED;
}

/* ------------------------------------------------------------------ runner.MonitorCore */

void rg_monitor_rx_init(rg_monitor_rx *m, int32_t channels, int32_t period_ms, int32_t timeout_cycles,
                        const rg_keyset *keys)
{
    memset(m, 0, sizeof *m);
    rg_receiver_init(&m->rx, channels, period_ms, keys);
    m->period_ms = period_ms;
    m->timeout_ticks = (int64_t)timeout_cycles * period_ms;
    m->foreign_until = -1;
}

static int32_t monitored_id(uint32_t frame_id)
{
    int32_t index = rg_frames_index(frame_id);
    return index >= 0;          /* frames.MONITORED_IDS: every DBC ID (inputs and the monitor's outputs) */
}

int32_t rg_monitor_ingest(rg_monitor_rx *m, uint32_t frame_id, uint32_t flags, const uint8_t *data, size_t length,
                          int64_t tick)
{
    int32_t kind, index;
    /* frames.classify: error first, as the kernel does */
    if (flags & RG_FRAME_ERROR) kind = 4;
    else if (flags & RG_FRAME_REMOTE) kind = 3;
    else if (flags & RG_FRAME_FD) kind = 2;
    else if (flags & RG_FRAME_EXTENDED) kind = 1;
    else kind = 0;
    m->kinds[kind]++;
    if (kind != 4 && ((flags & RG_FRAME_EXTENDED) || !monitored_id(frame_id))) {
        m->filtered++;
        return RG_FILTERED;
    }
    if (kind != (m->rx.secured ? 2 : 0)) {      /* the only kind decoded (secured: a classical frame is unsecured) */
        static const int32_t refusal[5] = {RG_REJ_CLASSICAL_FRAME, RG_REJ_UNKNOWN_ID, RG_REJ_FD_FRAME,
                                           RG_REJ_REMOTE_FRAME, RG_REJ_ERROR_FRAME};
        return reject(&m->rx, refusal[kind]);
    }
    index = rg_frames_index(frame_id);
    if (index == RG_MSG_BRAKE_DEMAND || index >= RG_MSG_MONITOR_STATUS) {   /* live: never the monitor's own */
        m->foreign_until = tick + (int64_t)RG_FOREIGN_HOLD_CYCLES * m->period_ms;
        return reject(&m->rx, RG_REJ_FOREIGN_OUTPUT);
    }
    return rg_receiver_accept(&m->rx, frame_id, 0, data, length, tick);
}

void rg_monitor_inputs(const rg_monitor_rx *m, int64_t tick, int32_t overruns, rg_inputs *in,
                       int32_t *foreign_output)
{
    const rg_receiver *rx = &m->rx;
    int32_t i;
    for (i = 0; i < RG_MAX_CHANNELS; i++) {
        if (i < rx->channels && rx->reports[i].heard) {
            in->reports[i] = rx->reports[i];
        } else {
            memset(&in->reports[i], 0, sizeof in->reports[i]);
        }
    }
    if (!rx->has_train || tick - rx->train_tick > m->timeout_ticks) {
        in->train.speed_cms = -1;               /* Python: None, which the core reads as a train-input error */
        in->train.track = 1;
        in->train.brake = 1;
    } else {
        in->train = rx->train;
    }
    in->overruns = overruns;
    if (foreign_output != NULL) *foreign_output = tick <= m->foreign_until;
}

/* ------------------------------------------------------------------ snapshot */

int32_t rg_receiver_snapshot(const rg_receiver *rx, int64_t *out, size_t size)
{
    int32_t n = 0, i;
    if (size < (size_t)RG_SNAPSHOT) return -1;
    for (i = 0; i < RG_MAX_CHANNELS; i++) {
        const rg_report *r = &rx->reports[i];
        out[n++] = r->heard;
        out[n++] = r->heard ? r->status : -1;
        out[n++] = r->heard ? r->distance_dm : -1;
        out[n++] = r->heard ? r->closing_cms : -1;
        out[n++] = r->heard ? r->obstacle : -1;
        out[n++] = r->heard ? r->tick : -1;
    }
    out[n++] = rx->has_train;
    out[n++] = rx->has_train ? rx->train.speed_cms : -1;
    out[n++] = rx->has_train ? rx->train.track : -1;
    out[n++] = rx->has_train ? rx->train.brake : -1;
    out[n++] = rx->has_train ? rx->train_tick : -1;
    out[n++] = rx->has_demand;
    out[n++] = rx->has_demand ? rx->demand.level : -1;
    out[n++] = rx->has_demand ? rx->demand.warning : -1;
    out[n++] = rx->has_demand ? rx->demand.reason : -1;
    out[n++] = rx->has_demand ? (int64_t)rx->demand.cycle : -1;
    out[n++] = rx->has_demand ? rx->demand_tick : -1;
    out[n++] = rx->has_demand_invalid;
    out[n++] = rx->has_demand_invalid ? rx->demand_invalid : -1;
    out[n++] = rx->has_status;
    out[n++] = rx->has_status ? rx->status.mode : -1;
    out[n++] = rx->has_status ? rx->status.warning : -1;
    out[n++] = rx->has_status ? rx->status.foreign_output : -1;
    out[n++] = rx->has_status ? rx->status.node : -1;
    out[n++] = rx->has_status ? rx->status.error_flags : -1;
    out[n++] = rx->has_status ? rx->status.voted_distance : -1;
    out[n++] = rx->has_status ? rx->status.table_hash : -1;
    out[n++] = rx->has_status ? rx->status.deadline_misses : -1;
    out[n++] = rx->has_status ? rx->status_tick : -1;
    out[n++] = rx->has_track;
    out[n++] = rx->has_track ? rx->track.track_state : -1;
    out[n++] = rx->has_track ? rx->track.memory : -1;
    out[n++] = rx->has_track ? rx->track.track_distance : -1;
    out[n++] = rx->has_track ? rx->track.track_age : -1;
    out[n++] = rx->has_track ? rx->track_tick : -1;
    out[n++] = rx->has_risk;
    out[n++] = rx->has_risk ? rx->risk.risk_category : -1;
    out[n++] = rx->has_risk ? rx->risk.risk_score : -1;
    out[n++] = rx->has_risk ? rx->risk.r1 : -1;
    out[n++] = rx->has_risk ? rx->risk.r2 : -1;
    out[n++] = rx->has_risk ? rx->risk.unsecured : -1;
    out[n++] = rx->has_risk ? (int64_t)rx->risk.table_risk : -1;
    out[n++] = rx->has_risk ? rx->risk_tick : -1;
    out[n++] = rx->accepted;
    for (i = RG_REJ_UNKNOWN_ID; i < RG_FILTERED; i++) out[n++] = rx->rejected[i];
    for (i = 0; i < RG_FRAMES_MESSAGES; i++) {
        const rg_sender_state *st = &rx->senders[i];
        out[n++] = st->has_counter ? st->counter : -1;
        out[n++] = st->has_quarantine ? st->quarantine_until : -1;
        out[n++] = st->has_contested ? st->contested_until : -1;
        out[n++] = rx->has_newest[i] ? (int64_t)rx->newest[i] : -1;
    }
    return n;
}

size_t rg_frames_sizeof(int32_t which)
{
    switch (which) {
    case 0: return sizeof(rg_receiver);
    case 1: return sizeof(rg_monitor_rx);
    case 2: return sizeof(rg_sender);
    case 3: return sizeof(rg_brake_receiver);
    default: return 0;
    }
}
