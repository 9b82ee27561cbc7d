/* The frame player node: see config.h. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_variables.h"
#include "rg_lsbus.h"
#include "rg_network.h"

void net_start_values(NetData *m)
{
    m->bit_rate = 500000;
    m->watch_id = 0x10;
    m->watch_timeout = 0.3;
    m->watch_last_ns = -1;
    m->first_brake = -1.0;
}

void net_set_resources(NetData *m, const char *path)
{
    if (strncmp(path, "file://", 7) == 0)
        path += 7;
    snprintf(m->resources, sizeof m->resources, "%s", path);
}

void net_terminate(NetData *m) { (void)m; }

static int hexval(int c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* One line "t_ns id_hex fd hexdata"; 0 on success. */
static int parse_line(const char *line, player_frame *f)
{
    long long t;
    unsigned id, fd;
    char hex[160];
    size_t i, n;
    hex[0] = '\0';
    if (sscanf(line, "%lld %x %u %159s", &t, &id, &fd, hex) < 3 || t < 0 || id > 0x7FF || fd > 1)
        return -1;
    n = strlen(hex);
    if (n % 2 || n / 2 > 64 || !rg_lsbus_valid_length((int)fd, (uint32_t)(n / 2)))
        return -1;
    for (i = 0; i < n / 2; i++) {
        int hi = hexval(hex[2 * i]), lo = hexval(hex[2 * i + 1]);
        if (hi < 0 || lo < 0)
            return -1;
        f->data[i] = (uint8_t)(hi << 4 | lo);
    }
    f->t_ns = t;
    f->id = id;
    f->fd = (uint8_t)fd;
    f->length = (uint8_t)(n / 2);
    return 0;
}

int net_initialize(NetData *m, char *msg, size_t len)
{
    char path[RG_NET_STRING + 32], line[256];
    FILE *fp;
    int lineno = 0;
    if (m->bit_rate <= 0 || m->watch_timeout <= 0) {
        snprintf(msg, len, "bit_rate and watch_timeout must be > 0");
        return RG_NET_ERROR;
    }
    snprintf(path, sizeof path, "%s%sframes.txt", m->resources,
             (m->resources[0] && m->resources[strlen(m->resources) - 1] != '/') ? "/" : "");
    fp = fopen(path, "r");
    if (!fp) {
        snprintf(msg, len, "cannot open the frame schedule %s", path);
        return RG_NET_ERROR;
    }
    m->count = 0;
    while (fgets(line, sizeof line, fp)) {
        lineno++;
        if (line[0] == '#' || line[0] == '\n')
            continue;
        if (m->count >= PLAYER_MAX_FRAMES || parse_line(line, &m->frames[m->count]) != 0 ||
            (m->count && m->frames[m->count].t_ns < m->frames[m->count - 1].t_ns)) {
            snprintf(msg, len, "frames.txt line %d: not 't_ns id_hex fd hexdata' in time order (at most %d frames)",
                     lineno, PLAYER_MAX_FRAMES);
            fclose(fp);
            return RG_NET_ERROR;
        }
        m->count++;
    }
    fclose(fp);
    m->next = 0;
    rg_node_configure(&m->tx, 0, (uint32_t)m->bit_rate);
    return RG_NET_OK;
}

static void watch(NetData *m, int64_t now)
{
    int64_t since = m->watch_last_ns < 0 ? now : now - m->watch_last_ns;
    double gap = (double)since / 1e9;
    if (m->watch_last_ns >= 0 && gap > m->watch_max_gap)
        m->watch_max_gap = gap;
    if (m->watch_last_ns >= 0 && gap > m->watch_timeout && !m->brake) {
        m->brake = 1;
        m->first_brake = (double)now / 1e9;
    }
}

int net_do_step(NetData *m, int64_t from_ns, int64_t to_ns, int *event_needed, char *msg, size_t len)
{
    (void)from_ns;
    (void)msg;
    (void)len;
    while (m->next < m->count && m->frames[m->next].t_ns <= to_ns) {
        const player_frame *f = &m->frames[m->next++];
        rg_node_send(&m->tx, f->id, f->fd, f->fd, f->data, f->length);
    }
    m->now_ns = to_ns;
    watch(m, to_ns);
    *event_needed = rg_node_has_pending(&m->tx);
    return RG_NET_OK;
}

int net_update_discrete_states(NetData *m, int64_t now_ns)
{
    (void)m;
    (void)now_ns;
    return 0;
}

double net_get_float64(const NetData *m, uint32_t vr)
{
    switch (vr) {
    case vr_watch_timeout: return m->watch_timeout;
    case vr_first_brake: return m->first_brake;
    case vr_watch_max_gap: return m->watch_max_gap;
    default: return 0.0;
    }
}

int32_t net_get_int32(const NetData *m, uint32_t vr)
{
    switch (vr) {
    case vr_bit_rate: return m->bit_rate;
    case vr_watch_id: return m->watch_id;
    case vr_rx_frames: return m->rx_frames;
    case vr_rx_errors: return m->rx_errors;
    case vr_confirmed: return m->confirmed;
    case vr_watch_frames: return m->watch_frames;
    case vr_tx_frames: return (int32_t)m->tx.sent;
    default: return 0;
    }
}

int net_get_boolean(const NetData *m, uint32_t vr) { return vr == vr_brake ? m->brake : 0; }
const char *net_get_string(const NetData *m, uint32_t vr) { (void)m; (void)vr; return ""; }

void net_set_float64(NetData *m, uint32_t vr, double v)
{
    if (vr == vr_watch_timeout) m->watch_timeout = v;
}

void net_set_int32(NetData *m, uint32_t vr, int32_t v)
{
    if (vr == vr_bit_rate) m->bit_rate = v;
    else if (vr == vr_watch_id) m->watch_id = v;
}

void net_set_boolean(NetData *m, uint32_t vr, int v) { (void)m; (void)vr; (void)v; }
void net_set_string(NetData *m, uint32_t vr, const char *v) { (void)m; (void)vr; (void)v; }

int net_set_binary(NetData *m, uint32_t vr, const uint8_t *data, size_t size, int64_t now_ns, char *msg, size_t len)
{
    size_t offset = 0;
    rg_lsbus_op op;
    int r;
    (void)vr;
    while ((r = rg_lsbus_next(data, size, &offset, &op)) == 1) {
        if (op.op == RG_OP_CAN_TRANSMIT || op.op == RG_OP_CANFD_TRANSMIT) {
            m->rx_frames++;
            if (op.id == (uint32_t)m->watch_id) {
                watch(m, now_ns);
                m->watch_frames++;
                m->watch_last_ns = now_ns;
            }
        } else if (op.op == RG_OP_CONFIRM) {
            m->confirmed++;
        } else if (op.op == RG_OP_BUS_ERROR) {
            m->rx_errors++;
        }
    }
    if (r < 0) {
        snprintf(msg, len, "malformed Bus Operation at byte %u of %u", (unsigned)offset, (unsigned)size);
        return RG_NET_ERROR;
    }
    return RG_NET_OK;
}

RG_NODE_TX_CONTRACT
