/* The monitor network node: see config.h. */
#include <stdio.h>
#include <string.h>

#include "net_variables.h"
#include "rg_lsbus.h"
#include "rg_network.h"
#include "rg_node_keys.h"
#include "rg_table.h"

#define SET_START(name, start) m->config.name = (start);

static int hexdigit(char c) { return c >= 'a' ? c - 'a' + 10 : c - '0'; }

void net_start_values(NetData *m)
{
    rg_config_default(&m->config);
    RG_PARAMETERS(SET_START)
    m->config.modules = RG_START_TOPOLOGY == 3 ? 3 : 1;
    m->phase_ms = 20;
    m->stop_time = 1e9;
    m->bit_rate = 500000;
    m->table.bytes = RG_TABLE_BYTES;
    m->table.length = RG_TABLE_LENGTH;
    m->table.action_offset = RG_TABLE_ACTION_OFFSET;
    m->table.next_offset = RG_TABLE_NEXT_OFFSET;
    m->table.risk_offset = RG_TABLE_RISK_OFFSET;
    m->table.nodes = RG_TABLE_NODES;
    m->table.observations = RG_TABLE_OBSERVATIONS;
    m->table.index_bytes = RG_TABLE_INDEX_BYTES;
    m->table.start = RG_TABLE_START;
    m->table.model = RG_TABLE_MODEL;
    m->table.period_ms = RG_TABLE_PERIOD_MS;
    m->outputs.demand = RG_EMERGENCY;
    m->outputs.reasons = RG_R_INIT;
    m->outputs.mode = RG_INIT;
}

void net_set_resources(NetData *m, const char *path) { snprintf(m->resources, sizeof m->resources, "%s", path); }

void net_terminate(NetData *m) { (void)m; }

int net_initialize(NetData *m, char *msg, size_t len)
{
    static const char expected[] = RG_TABLE_SHA256;
    int r;
    if (m->phase_ms < 1 || m->phase_ms >= m->config.period_ms) {
        snprintf(msg, len, "phase_ms = %ld: the monitor samples 1 ms to one period after the sensors publish",
                 (long)m->phase_ms);
        return RG_NET_ERROR;
    }
    if (rg_config_check(&m->config, msg, len) != 0 || rg_table_check(&m->table, &m->config, msg, len) != 0)
        return RG_NET_ERROR;
    r = rg_node_keys(m->resources, &m->keys, msg, len);
    if (r < 0)
        return RG_NET_ERROR;
    m->secured = r;
    m->table_hash = hexdigit(expected[0]) << 8 | hexdigit(expected[1]) << 4 | hexdigit(expected[2]);
    rg_initial_state(&m->table, &m->config, &m->state);
    rg_monitor_rx_init(&m->rx, 2 * m->config.modules, m->config.period_ms, m->config.timeout_cycles,
                       m->secured ? &m->keys : NULL);
    rg_sender_init(&m->sender, m->secured ? &m->keys : NULL);
    m->cycles = 0;
    rg_node_configure(&m->tx, 0, (uint32_t)m->bit_rate);
    return RG_NET_OK;
}

static int64_t cycle_ns(const NetData *m, int64_t k)
{
    return (k * m->config.period_ms + m->phase_ms) * 1000000;
}

int net_do_step(NetData *m, int64_t from_ns, int64_t to_ns, int *event_needed, char *msg, size_t len)
{
    (void)from_ns;
    while (cycle_ns(m, m->cycles) <= to_ns && (double)m->cycles * m->config.period_ms < m->stop_time * 1000.0) {
        int64_t tick = m->cycles * m->config.period_ms;
        rg_inputs in;
        rg_frame frames[4];
        int n, i;
        rg_monitor_inputs(&m->rx, tick, 0, &in, &m->foreign);
        rg_step(&m->config, &m->table, &m->state, &in, tick, &m->outputs);
        n = rg_monitor_send(&m->sender, &m->outputs, m->foreign, m->table_hash, 0, m->config.period_ms, 0, frames);
        if (n < 0) {
            snprintf(msg, len, "cycle %lld: the frames could not be sealed (libcrypto)", (long long)m->cycles);
            return RG_NET_ERROR;
        }
        for (i = 0; i < n; i++)
            rg_node_send(&m->tx, frames[i].id, frames[i].is_fd, frames[i].is_fd, frames[i].data,
                         (uint16_t)frames[i].length);
        m->cycles++;
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

double net_get_float64(const NetData *m, uint32_t vr) { return vr == vr_stop_time ? m->stop_time : 0.0; }

int32_t net_get_int32(const NetData *m, uint32_t vr)
{
    switch (vr) {
    case vr_phase_ms: return m->phase_ms;
    case vr_bit_rate: return m->bit_rate;
    case vr_brake_demand: return m->outputs.demand;
    case vr_reasons: return m->outputs.reasons;
    case vr_mode: return m->outputs.mode;
    case vr_node: return m->outputs.node;
    case vr_voted_distance_dm: return m->outputs.distance_dm;
    case vr_track_state: return m->outputs.track_state;
    case vr_cycle: return (int32_t)m->outputs.cycle;
    case vr_frames_rx: return (int32_t)m->frames_rx;
    case vr_frames_rejected: return (int32_t)m->rejected;
    default: return 0;
    }
}

int net_get_boolean(const NetData *m, uint32_t vr)
{
    if (vr == vr_secured) return m->secured;
    if (vr == vr_foreign_output) return m->foreign;
    return 0;
}

const char *net_get_string(const NetData *m, uint32_t vr) { (void)m; (void)vr; return ""; }
void net_set_float64(NetData *m, uint32_t vr, double v)
{
    if (vr == vr_stop_time) m->stop_time = v;
}

void net_set_int32(NetData *m, uint32_t vr, int32_t v)
{
    if (vr == vr_phase_ms) m->phase_ms = v;
    else if (vr == vr_bit_rate) m->bit_rate = v;
}

void net_set_boolean(NetData *m, uint32_t vr, int v) { (void)m; (void)vr; (void)v; }
void net_set_string(NetData *m, uint32_t vr, const char *v) { (void)m; (void)vr; (void)v; }

/* Frames that arrive are stamped as runner.py stamps them: never later than the next cycle's
 * tick (the arrival in whole ms, at most that tick). */
int net_set_binary(NetData *m, uint32_t vr, const uint8_t *data, size_t size, int64_t now_ns, char *msg, size_t len)
{
    size_t offset = 0;
    rg_lsbus_op op;
    int r;
    int64_t tick = now_ns / 1000000, next_tick = m->cycles * m->config.period_ms;
    (void)vr;
    if (tick > next_tick)
        tick = next_tick;
    while ((r = rg_lsbus_next(data, size, &offset, &op)) == 1) {
        uint32_t flags;
        if (op.op != RG_OP_CAN_TRANSMIT && op.op != RG_OP_CANFD_TRANSMIT)
            continue;                                /* confirmations, bus errors: the bus's business */
        flags = (op.ide ? RG_FRAME_EXTENDED : 0u) | (op.op == RG_OP_CANFD_TRANSMIT ? RG_FRAME_FD : 0u) |
                (op.rtr ? RG_FRAME_REMOTE : 0u);
        m->frames_rx++;
        if (rg_monitor_ingest(&m->rx, op.id, flags, op.data, op.length, tick) != RG_ACCEPTED)
            m->rejected++;
    }
    if (r < 0) {
        snprintf(msg, len, "malformed Bus Operation at byte %u of %u", (unsigned)offset, (unsigned)size);
        return RG_NET_ERROR;
    }
    return RG_NET_OK;
}

RG_NODE_TX_CONTRACT
