/* The bus simulation model: see config.h. Time is whole nanoseconds; what reaches a node at
 * time T (a frame, a confirmation, a bus error) waits in its pending operations until the
 * importer ticks that node's countdown Tx_Clock, whose interval this model announces. */
#include <stdio.h>
#include <string.h>

#include "net_variables.h"
#include "rg_lsbus.h"
#include "rg_network.h"

static const uint32_t RX_DATA[BUS_NODES] = BUS_RX_DATA;
static const uint32_t TX_DATA[BUS_NODES] = BUS_TX_DATA;
static const uint32_t TX_CLOCK[BUS_NODES] = BUS_TX_CLOCK;

static int node_of(const uint32_t *table, uint32_t vr)
{
    int k;
    for (k = 0; k < BUS_NODES; k++)
        if (table[k] == vr)
            return k;
    return -1;
}

void net_start_values(NetData *m)
{
    m->bit_rate = 500000;
    m->data_bit_rate = 2000000;
    m->flood_id = -1;
    m->flood_start = 0.0;
    m->flood_stop = 1e9;
    m->error_id = -1;
    m->error_count = 0;
    m->watch_id = 0x10;
    m->watch_last_end_ns = -1;
}

void net_set_resources(NetData *m, const char *path) { snprintf(m->resources, sizeof m->resources, "%s", path); }

void net_terminate(NetData *m)
{
    if (m->trace) {
        fclose(m->trace);
        m->trace = NULL;
    }
}

static int64_t seconds_ns(double s) { return s >= 9e9 ? INT64_MAX / 2 : (int64_t)(s * 1e9 + (s >= 0 ? 0.5 : -0.5)); }

int net_initialize(NetData *m, char *msg, size_t len)
{
    if (m->bit_rate < 10000 || m->bit_rate > 1000000 || m->data_bit_rate < m->bit_rate || m->data_bit_rate > 8000000) {
        snprintf(msg, len, "bit_rate must be 10 kbit/s..1 Mbit/s and data_bit_rate bit_rate..8 Mbit/s");
        return RG_NET_ERROR;
    }
    if (m->flood_id > 0x7FF || m->error_id > 0x7FF || m->watch_id < 0 || m->watch_id > 0x7FF) {
        snprintf(msg, len, "flood_id, error_id and watch_id are 11-bit identifiers (flood_id/error_id -1: none)");
        return RG_NET_ERROR;
    }
    rg_canbus_init(&m->bus, BUS_NODES + 1, m->bit_rate, m->data_bit_rate);
    if (m->flood_id >= 0)
        rg_canbus_flood(&m->bus, BUS_NODES, (uint32_t)m->flood_id, seconds_ns(m->flood_start), seconds_ns(m->flood_stop));
    if (m->error_id >= 0 && m->error_count > 0)
        rg_canbus_error_next(&m->bus, (uint32_t)m->error_id, m->error_count);
    if (m->trace_file[0]) {
        m->trace = fopen(m->trace_file, "w");
        if (!m->trace) {
            snprintf(msg, len, "cannot write the trace file %s", m->trace_file);
            return RG_NET_ERROR;
        }
        fprintf(m->trace, "kind,node,id,fd,length,queued_s,start_s,end_s,data\n");
    }
    return RG_NET_OK;
}

static void put(NetData *m, int k, int ok)
{
    if (!ok)
        m->overflow++;
    (void)k;
}

static void trace(NetData *m, const rg_canbus_event *e)
{
    static const char *KIND[] = {"", "delivered", "bus_error", "dropped"};
    int i;
    if (!m->trace)
        return;
    fprintf(m->trace, "%s,%d,0x%03X,%d,%d,%.9f,%.9f,%.9f,", KIND[e->kind & 3], (int)e->node, (unsigned)e->frame.id,
            (int)e->frame.fd, (int)e->frame.len, (double)e->queued_ns / 1e9, (double)e->start_ns / 1e9,
            (double)e->end_ns / 1e9);
    for (i = 0; i < e->frame.len; i++)
        fprintf(m->trace, "%02X", e->frame.data[i]);
    fputc('\n', m->trace);
}

/* One completed transmission (or error, or drop) handed to every node's pending operations. */
static void distribute(NetData *m, const rg_canbus_event *e)
{
    int k;
    trace(m, e);
    if (e->kind == RG_CANBUS_DROPPED) {
        m->dropped++;
        return;
    }
    if (e->kind == RG_CANBUS_BUS_ERROR) {
        m->errors++;
        for (k = 0; k < BUS_NODES; k++)
            put(m, k, rg_lsbus_put_bus_error(m->pending[k], BUS_BUFFER, &m->pending_size[k], e->frame.id,
                                             RG_BUS_ERROR_CRC, k == (e->node == 0 ? 1 : 0) ? RG_PRIMARY_ERROR_FLAG
                                                                                          : RG_SECONDARY_ERROR_FLAG,
                                             k == e->node) == 0);
        return;
    }
    m->frames++;
    if (e->frame.id == (uint32_t)m->watch_id) {
        int64_t delay = e->start_ns - e->queued_ns;
        m->watch_frames++;
        if (delay > m->watch_max_delay_ns)
            m->watch_max_delay_ns = delay;
        if (m->watch_last_end_ns >= 0 && e->end_ns - m->watch_last_end_ns > m->watch_max_gap_ns)
            m->watch_max_gap_ns = e->end_ns - m->watch_last_end_ns;
        m->watch_last_end_ns = e->end_ns;
    }
    for (k = 0; k < BUS_NODES; k++) {
        if (k == e->node)
            put(m, k, rg_lsbus_put_confirm(m->pending[k], BUS_BUFFER, &m->pending_size[k], e->frame.id) == 0);
        else
            put(m, k, rg_lsbus_put_transmit(m->pending[k], BUS_BUFFER, &m->pending_size[k], e->frame.id, e->frame.fd,
                                            e->frame.brs, e->frame.data, e->frame.len) == 0);
    }
}

static void advance(NetData *m, int64_t to_ns)
{
    int32_t n, i;
    do {
        n = rg_canbus_advance(&m->bus, to_ns, m->events, BUS_EVENTS);
        for (i = 0; i < n; i++)
            distribute(m, &m->events[i]);
    } while (n == BUS_EVENTS);
    m->now_ns = to_ns;
}

int net_do_step(NetData *m, int64_t from_ns, int64_t to_ns, int *event_needed, char *msg, size_t len)
{
    int k;
    (void)from_ns; (void)msg; (void)len;
    advance(m, to_ns);
    m->armed = 0;
    *event_needed = 0;
    for (k = 0; k < BUS_NODES; k++)
        if (m->pending_size[k])
            *event_needed = 1;
    return RG_NET_OK;
}

/* Deliveries are handed over in a later super-dense step than the one the event starts
 * with: fmucontainer 2.0 sets a receiver's clocked Rx_Data only for clocks raised while it
 * updates discrete states (a clock read in its first pass ticks the receiver's Rx_Clock
 * without its data). So the first update arms the Tx clocks, the next read raises them, and
 * one more update lets the importer pass the data on. */
int net_update_discrete_states(NetData *m, int64_t now_ns)
{
    int k;
    (void)now_ns;
    if (m->delivered) {
        m->delivered = 0;
        return 1;
    }
    if (!m->armed)
        for (k = 0; k < BUS_NODES; k++)
            if (m->pending_size[k]) {
                m->armed = 1;
                return 1;
            }
    return 0;
}

double net_get_float64(const NetData *m, uint32_t vr)
{
    switch (vr) {
    case vr_flood_start: return m->flood_start;
    case vr_flood_stop: return m->flood_stop;
    case vr_bus_load: return m->now_ns > 0 ? (double)rg_canbus_busy_ns(&m->bus) / (double)m->now_ns : 0.0;
    case vr_watch_max_delay: return (double)m->watch_max_delay_ns / 1e9;
    case vr_watch_max_gap: return (double)m->watch_max_gap_ns / 1e9;
    default: return 0.0;
    }
}

int32_t net_get_int32(const NetData *m, uint32_t vr)
{
    switch (vr) {
    case vr_bit_rate: return m->bit_rate;
    case vr_data_bit_rate: return m->data_bit_rate;
    case vr_flood_id: return m->flood_id;
    case vr_error_id: return m->error_id;
    case vr_error_count: return m->error_count;
    case vr_watch_id: return m->watch_id;
    case vr_frames: return m->frames;
    case vr_errors: return m->errors;
    case vr_dropped: return m->dropped;
    case vr_overflow: return m->overflow;
    case vr_config_mismatch: return m->config_mismatch;
    case vr_watch_frames: return m->watch_frames;
    default: return 0;
    }
}

int net_get_boolean(const NetData *m, uint32_t vr) { (void)m; (void)vr; return 0; }

const char *net_get_string(const NetData *m, uint32_t vr) { return vr == vr_trace_file ? m->trace_file : ""; }

void net_set_float64(NetData *m, uint32_t vr, double v)
{
    if (vr == vr_flood_start) m->flood_start = v;
    else if (vr == vr_flood_stop) m->flood_stop = v;
}

void net_set_int32(NetData *m, uint32_t vr, int32_t v)
{
    switch (vr) {
    case vr_bit_rate: m->bit_rate = v; break;
    case vr_data_bit_rate: m->data_bit_rate = v; break;
    case vr_flood_id: m->flood_id = v; break;
    case vr_error_id: m->error_id = v; break;
    case vr_error_count: m->error_count = v; break;
    case vr_watch_id: m->watch_id = v; break;
    default: break;
    }
}

void net_set_boolean(NetData *m, uint32_t vr, int v) { (void)m; (void)vr; (void)v; }

void net_set_string(NetData *m, uint32_t vr, const char *v)
{
    if (vr == vr_trace_file)
        snprintf(m->trace_file, sizeof m->trace_file, "%s", v);
}

void net_get_binary(NetData *m, uint32_t vr, const uint8_t **data, size_t *size)
{
    int k = node_of(TX_DATA, vr);
    *data = k >= 0 ? m->out[k] : m->out[0];
    *size = k >= 0 ? m->out_size[k] : 0;
}

int net_set_binary(NetData *m, uint32_t vr, const uint8_t *data, size_t size, int64_t now_ns, char *msg, size_t len)
{
    int k = node_of(RX_DATA, vr), r;
    size_t offset = 0;
    rg_lsbus_op op;
    if (k < 0)
        return RG_NET_OK;
    advance(m, now_ns);
    while ((r = rg_lsbus_next(data, size, &offset, &op)) == 1) {
        if (op.op == RG_OP_CAN_TRANSMIT || op.op == RG_OP_CANFD_TRANSMIT) {
            rg_can_frame f;
            memset(&f, 0, sizeof f);
            f.id = op.id;
            f.fd = op.op == RG_OP_CANFD_TRANSMIT;
            f.brs = op.brs;
            f.len = (uint8_t)op.length;
            memcpy(f.data, op.data, op.length);
            rg_canbus_submit(&m->bus, k, &f, now_ns);
        } else if (op.op == RG_OP_CONFIGURATION) {
            if ((op.kind == RG_CFG_CAN_BAUDRATE && op.value != (uint32_t)m->bit_rate) ||
                (op.kind == RG_CFG_CANFD_BAUDRATE && op.value != (uint32_t)m->data_bit_rate))
                m->config_mismatch++;
        }
    }
    if (r < 0) {
        snprintf(msg, len, "node %d sent a malformed Bus Operation at byte %u of %u", k + 1, (unsigned)offset,
                 (unsigned)size);
        return RG_NET_ERROR;
    }
    return RG_NET_OK;
}

/* Node k's triggered Tx_Clock: active at the first communication point at or after a
 * delivery to it; reading it hands the pending operations over as Tx_Data. */
int net_get_clock(NetData *m, uint32_t vr)
{
    int k = node_of(TX_CLOCK, vr);
    if (k < 0 || !m->armed || !m->pending_size[k])
        return 0;
    m->delivered = 1;
    memcpy(m->out[k], m->pending[k], m->pending_size[k]);
    m->out_size[k] = m->pending_size[k];
    m->pending_size[k] = 0;
    return 1;
}

void net_set_clock(NetData *m, uint32_t vr, int64_t now_ns) { (void)m; (void)vr; (void)now_ns; }

int net_get_interval(NetData *m, uint32_t vr, int64_t now_ns, int64_t *interval_ns)
{
    (void)m; (void)vr; (void)now_ns; (void)interval_ns;
    return 0;
}
