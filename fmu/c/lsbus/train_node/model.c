/* The train network node: see config.h. */
#include <stdio.h>
#include <string.h>

#include "net_variables.h"
#include "rg_lsbus.h"
#include "rg_reading.h"
#include "rg_network.h"
#include "rg_node_keys.h"
#include "train_params.h"            /* generated: TRAIN_PARAMS[] (net vr, train vr, type, start), tvr_* */

#define PERIOD_NS ((int64_t)TRAIN_NODE_PERIOD_MS * 1000000)
#define CH_FIELDS 5                  /* status, distance, closing_speed, type, valid (train model.c checks it) */

static const rg_train_param *param_of(uint32_t vr)
{
    int i;
    for (i = 0; i < N_TRAIN_PARAMS; i++)
        if (TRAIN_PARAMS[i].net == vr) return &TRAIN_PARAMS[i];
    return NULL;
}

static void set_param(ModelData *t, const rg_train_param *p, double v)
{
    if (p->type == RG_NT_FLOAT64) model_set_real(t, p->train, v);
    else if (p->type == RG_NT_INT32) model_set_integer(t, p->train, (int32_t)v);
    else model_set_boolean(t, p->train, v != 0.0);
}

void net_start_values(NetData *m)
{
    int i;
    model_set_start_values(&m->train);
    for (i = 0; i < N_TRAIN_PARAMS; i++)
        set_param(&m->train, &TRAIN_PARAMS[i], TRAIN_PARAMS[i].start);
    m->bit_rate = 500000;
    m->last_demand_ns = -1;
    m->receiver_brake_ns = -1;
}

void net_set_resources(NetData *m, const char *path) { snprintf(m->resources, sizeof m->resources, "%s", path); }

void net_terminate(NetData *m) { (void)m; }

static int queue(NetData *m, int r, const rg_frame *f, char *msg, size_t len)
{
    if (r < 0) {
        snprintf(msg, len, "t = %lld ms: frame 0x%03X could not be sealed (libcrypto or a missing key)",
                 (long long)(m->next_ns / 1000000), (unsigned)f->id);
        return RG_NET_ERROR;
    }
    rg_node_send(&m->tx, f->id, f->is_fd, f->is_fd, f->data, (uint16_t)f->length);
    m->frames_tx++;
    return RG_NET_OK;
}

/* The instant next_ns: the newest accepted demand to the model, then the model's outputs at
 * this instant to the bus. */
static int instant(NetData *m, char *msg, size_t len)
{
    ModelData *t = &m->train;
    rg_frame f;
    int c;
    if (m->rx.has_demand) {
        model_set_integer(t, tvr_brake_demand, (int32_t)m->rx.demand.level);
        model_set_integer(t, tvr_monitor_cycle, (int32_t)m->rx.demand.cycle);
    }
    if (queue(m, rg_send_train(&m->sender, read_speed_cms(model_get_real(t, tvr_train_speed)),
                               model_get_integer(t, tvr_train_track_condition),
                               model_get_integer(t, tvr_train_brake_status), &f), &f, msg, len) != RG_NET_OK)
        return RG_NET_ERROR;
    for (c = 0; c < TRAIN_CHANNELS; c++) {
        const uint32_t base = (uint32_t)tvr_ch1_status + (uint32_t)(CH_FIELDS * c);
        if (!model_get_boolean(t, base + 4))
            continue;                                   /* the silence fault: nothing on the bus */
        if (queue(m, rg_send_report(&m->sender, c, model_get_integer(t, base),
                                    read_distance_dm(model_get_real(t, base + 1)),
                                    read_closing_cms(model_get_real(t, base + 2)), model_get_integer(t, base + 3), &f),
                  &f, msg, len) != RG_NET_OK)
            return RG_NET_ERROR;
    }
    m->instants++;
    m->next_ns += PERIOD_NS;
    return RG_NET_OK;
}

int net_initialize(NetData *m, char *msg, size_t len)
{
    int r;
    if (model_initialize(&m->train, msg, len) != RG_OK)
        return RG_NET_ERROR;
    r = rg_node_keys(m->resources, &m->keys, msg, len);
    if (r < 0)
        return RG_NET_ERROR;
    m->secured = r;
    rg_receiver_init(&m->rx, RG_MAX_CHANNELS, 0, m->secured ? &m->keys : NULL);
    rg_sender_init(&m->sender, m->secured ? &m->keys : NULL);
    rg_node_configure(&m->tx, 0, (uint32_t)m->bit_rate);
    m->next_ns = 0;
    m->instants = 0;
    m->last_demand_ns = -1;
    m->receiver_brake_ns = -1;
    return instant(m, msg, len);                       /* instant 0: the monitor's cycle 0 reads these */
}

int net_do_step(NetData *m, int64_t from_ns, int64_t to_ns, int *event_needed, char *msg, size_t len)
{
    int64_t now = from_ns;
    for (;;) {
        int64_t end;
        if (now == m->next_ns && instant(m, msg, len) != RG_NET_OK)
            return RG_NET_ERROR;
        end = to_ns < m->next_ns ? to_ns : m->next_ns;
        if (end > now) {
            if (model_do_step(&m->train, now, end, msg, len) != RG_OK)
                return RG_NET_ERROR;
            now = end;
            if (m->receiver_brake_ns < 0 && m->train.receiver_brake)   /* set in the last whole internal step */
                m->receiver_brake_ns = (m->train.steps - 1) * TRAIN_STEP_NS;
        }
        if (now >= to_ns)
            break;
    }
    *event_needed = rg_node_has_pending(&m->tx);
    return RG_NET_OK;
}

int net_update_discrete_states(NetData *m, int64_t now_ns)
{
    (void)m;
    (void)now_ns;
    return 0;
}

static double seconds(int64_t ns) { return ns < 0 ? -1.0 : (double)ns / 1e9; }

double net_get_float64(const NetData *m, uint32_t vr)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL)      /* the train model has no getter for brake_timeout */
        return p->train == (uint32_t)tvr_brake_timeout ? m->train.brake_timeout : model_get_real(&m->train, p->train);
    switch (vr) {
    case vr_position: return model_get_real(&m->train, tvr_position);
    case vr_true_speed: return model_get_real(&m->train, tvr_true_speed);
    case vr_train_speed: return model_get_real(&m->train, tvr_train_speed);
    case vr_acceleration: return model_get_real(&m->train, tvr_acceleration);
    case vr_true_distance: return model_get_real(&m->train, tvr_true_distance);
    case vr_brake_decel: return model_get_real(&m->train, tvr_brake_decel);
    case vr_impact_speed: return model_get_real(&m->train, tvr_impact_speed);
    case vr_last_demand_time: return seconds(m->last_demand_ns);
    case vr_receiver_brake_time: return seconds(m->receiver_brake_ns);
    default: return 0.0;
    }
}

int32_t net_get_int32(const NetData *m, uint32_t vr)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL) return model_get_integer(&m->train, p->train);
    switch (vr) {
    case vr_bit_rate: return m->bit_rate;
    case vr_brake_level: return model_get_integer(&m->train, tvr_brake_level);
    case vr_applied_demand: return m->train.brake_demand;
    case vr_applied_cycle: return m->train.monitor_cycle;
    case vr_frames_rx: return (int32_t)m->frames_rx;
    case vr_frames_rejected: return (int32_t)m->rejected;
    case vr_frames_tx: return (int32_t)m->frames_tx;
    case vr_demand_frames: return (int32_t)m->demand_frames;
    default: return 0;
    }
}

int net_get_boolean(const NetData *m, uint32_t vr)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL) return model_get_boolean(&m->train, p->train);
    switch (vr) {
    case vr_secured: return m->secured;
    case vr_collided: return model_get_boolean(&m->train, tvr_collided);
    case vr_receiver_brake: return model_get_boolean(&m->train, tvr_receiver_brake);
    default: return 0;
    }
}

const char *net_get_string(const NetData *m, uint32_t vr) { (void)m; (void)vr; return ""; }

void net_set_float64(NetData *m, uint32_t vr, double v)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL) set_param(&m->train, p, v);
}

void net_set_int32(NetData *m, uint32_t vr, int32_t v)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL) set_param(&m->train, p, (double)v);
    else if (vr == vr_bit_rate) m->bit_rate = v;
}

void net_set_boolean(NetData *m, uint32_t vr, int v)
{
    const rg_train_param *p = param_of(vr);
    if (p != NULL) set_param(&m->train, p, v ? 1.0 : 0.0);
}

void net_set_string(NetData *m, uint32_t vr, const char *v) { (void)m; (void)vr; (void)v; }

/* Frames from the bus: the monitor's (and anyone's) through the receiver (E2E, SecOC; on a
 * secured bus CAN FD frames only, on an unsecured one classical frames only). The newest
 * accepted BrakeDemand stays latched in rx.demand for the next instant. */
int net_set_binary(NetData *m, uint32_t vr, const uint8_t *data, size_t size, int64_t now_ns, char *msg, size_t len)
{
    size_t offset = 0;
    rg_lsbus_op op;
    int r;
    (void)vr;
    while ((r = rg_lsbus_next(data, size, &offset, &op)) == 1) {
        int fd = op.op == RG_OP_CANFD_TRANSMIT;
        if (op.op != RG_OP_CAN_TRANSMIT && !fd)
            continue;                                /* confirmations, bus errors: the bus's business */
        m->frames_rx++;
        if (op.rtr || fd != m->secured ||
            rg_receiver_accept(&m->rx, op.id, op.ide, op.data, op.length, now_ns / 1000000) != RG_ACCEPTED) {
            m->rejected++;
            continue;
        }
        if (op.id == RG_DBC_BRAKE_DEMAND_FRAME_ID && !op.ide) {
            m->demand_frames++;
            m->last_demand_ns = now_ns;
        }
    }
    if (r < 0) {
        snprintf(msg, len, "malformed Bus Operation at byte %u of %u", (unsigned)offset, (unsigned)size);
        return RG_NET_ERROR;
    }
    return RG_NET_OK;
}

RG_NODE_TX_CONTRACT
