/* The CAN bus model (see rg_canbus.h). Bit layouts, per ISO 11898-1:2015, bits MSB first,
 * 0 = dominant:
 *
 * classic base   SOF ID[11] RTR(0) IDE(0) r0(0) DLC[4] DATA[8n] CRC[15] | CRCdel ACK ACKdel EOF[7]
 * classic ext    SOF ID[28:18] SRR(1) IDE(1) ID[17:0] RTR(0) r1(0) r0(0) DLC[4] DATA CRC[15] | ...
 * FD base        SOF ID[11] RRS(0) IDE(0) FDF(1) res(0) BRS ESI(0) DLC[4] DATA | CRC field | ...
 * FD ext         SOF ID[28:18] SRR(1) IDE(1) ID[17:0] RRS(0) FDF(1) res(0) BRS ESI(0) DLC DATA | ...
 * FD CRC field   FSB SC[3] P FSB CRC[4] FSB CRC[4] ... (a fixed stuff bit, the complement of the
 *                bit before it, ahead of every 4 bits: 6 of them with CRC-17, 7 with CRC-21)
 *
 * Classic: stuff bits (a complement after 5 equal bits, stuff bits counted in the run) from SOF
 * to the end of the CRC sequence, a stuff bit after the CRC's last bit included; the CRC-15
 * (x^15+x^14+x^10+x^8+x^7+x^4+x^3+1, register 0) runs over SOF..DATA without stuff bits.
 * FD: dynamic stuffing from SOF to the end of DATA; when the last 5 bits of DATA are equal no
 * dynamic stuff bit is added, the first fixed stuff bit (the complement anyway) takes its place.
 * SC = the dynamic stuff bits mod 8, Gray-coded, P its even parity. CRC-17 (0x1685B, data <= 16
 * bytes) or CRC-21 (0x102899), register starting with 1 in its top bit, over SOF..DATA with the
 * dynamic stuff bits and over SC and P; the fixed stuff bits are not in the CRC.
 * With BRS the bits after BRS (a stuff bit right after BRS included) up to the last CRC bit go at
 * the data bit rate; the CRC delimiter onwards at the nominal rate.
 *
 * Error choice: an injected error is a CRC error seen by the receivers, signalled after the ACK
 * delimiter: the bus carries the frame up to the ACK delimiter, then 6 bits of error flag and 8 of
 * error delimiter (the event ends there), then the 3-bit intermission. */
#include "rg_canbus.h"

#include <string.h>

#define NS_PER_S 1000000000LL

/* ---- the bit stream ---- */

typedef struct {
    int32_t last, run, dynamic, fd, data_phase, nom, dat;
    uint32_t crc, crc_top, crc_mask, crc_poly;
    uint8_t *out;          /* the bits themselves, when asked for (rg_canbus_frame_wire) */
    int32_t cap;
} wire;

static void crc_bit(wire *w, int32_t bit)
{
    uint32_t fb = (uint32_t)bit ^ ((w->crc & w->crc_top) ? 1u : 0u);
    w->crc = (w->crc << 1) & w->crc_mask;
    if (fb) w->crc ^= w->crc_poly;
}

static void put(wire *w, int32_t bit)
{
    if (w->out != NULL && w->nom + w->dat < w->cap) w->out[w->nom + w->dat] = (uint8_t)bit;
    if (w->data_phase) w->dat++; else w->nom++;
    w->run = (bit == w->last) ? w->run + 1 : 1;
    w->last = bit;
}

/* A bit of the dynamically stuffed part: a pending stuff bit goes first (so none trails the
 * region); in_crc says whether the bit feeds the CRC (classic: not the CRC bits themselves). */
static void stuffed(wire *w, int32_t bit, int32_t in_crc)
{
    if (w->run >= 5) {
        int32_t s = !w->last;
        if (w->fd) crc_bit(w, s);
        put(w, s);
        w->dynamic++;
    }
    if (in_crc) crc_bit(w, bit);
    put(w, bit);
}

static void field(wire *w, uint32_t value, int32_t nbits)
{
    int32_t i;
    for (i = nbits - 1; i >= 0; i--) stuffed(w, (int32_t)((value >> i) & 1u), 1);
}

static int32_t fd_dlc(int32_t len)
{
    static const uint8_t lens[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};
    int32_t i;
    for (i = 0; i < 16; i++) if (lens[i] == len) return i;
    return -1;
}

static int32_t valid(const rg_can_frame *f)
{
    if (f == NULL || f->ide > 1 || f->fd > 1 || f->brs > 1) return 0;
    if (f->id > (f->ide ? 0x1FFFFFFFu : 0x7FFu)) return 0;
    if (!f->fd) return f->brs == 0 && f->len <= 8;
    return fd_dlc(f->len) >= 0;
}

static int32_t frame_stream(const rg_can_frame *f, int32_t *nominal_bits, int32_t *data_bits, uint8_t *out, int32_t cap)
{
    wire w;
    int32_t i, dlc, width;
    if (!valid(f)) return -1;
    memset(&w, 0, sizeof w);
    w.out = out;
    w.cap = cap;
    w.last = -1;
    w.fd = f->fd;
    width = !f->fd ? 15 : (f->len <= 16 ? 17 : 21);
    w.crc_top = 1u << (width - 1);
    w.crc_mask = (1u << width) - 1u;
    w.crc_poly = width == 15 ? 0x4599u : (width == 17 ? 0x1685Bu : 0x102899u);
    w.crc = f->fd ? w.crc_top : 0u;
    dlc = f->fd ? fd_dlc(f->len) : f->len;

    field(&w, 0, 1);                                    /* SOF */
    if (f->ide) {
        field(&w, f->id >> 18, 11);
        field(&w, 3, 2);                                /* SRR, IDE */
        field(&w, f->id & 0x3FFFFu, 18);
    } else {
        field(&w, f->id, 11);
    }
    if (!f->fd) {
        field(&w, 0, 3);                                /* base: RTR IDE r0; ext: RTR r1 r0 */
    } else {
        if (f->ide) field(&w, 0x2u, 3);                 /* ext: RRS FDF res = 0 1 0 */
        else field(&w, 0x2u, 4);                        /* base: RRS IDE FDF res = 0 0 1 0 */
        field(&w, f->brs, 1);
        if (f->brs) w.data_phase = 1;
        field(&w, 0, 1);                                /* ESI: error active */
    }
    field(&w, (uint32_t)dlc, 4);
    for (i = 0; i < f->len; i++) field(&w, f->data[i], 8);

    if (!f->fd) {
        uint32_t crc = w.crc;
        for (i = width - 1; i >= 0; i--) stuffed(&w, (int32_t)((crc >> i) & 1u), 0);
        if (w.run >= 5) put(&w, !w.last);               /* a stuff bit after the CRC's last bit */
    } else {
        static const uint8_t gray[8] = {0, 1, 3, 2, 6, 7, 5, 4};
        uint32_t g = gray[w.dynamic & 7], seq, crc;
        int32_t n, k;
        uint32_t parity = ((g >> 2) ^ (g >> 1) ^ g) & 1u;
        for (k = 2; k >= 0; k--) crc_bit(&w, (int32_t)((g >> k) & 1u));
        crc_bit(&w, (int32_t)parity);
        crc = w.crc;
        seq = (((g << 1) | parity) << width) | crc;      /* SC P CRC, 4 + width bits */
        n = 4 + width;
        for (k = 0; k < n; k++) {
            if (k % 4 == 0) put(&w, !w.last);           /* fixed stuff bit */
            put(&w, (int32_t)((seq >> (n - 1 - k)) & 1u));
        }
    }
    w.data_phase = 0;
    put(&w, 1);                                         /* CRC delimiter */
    put(&w, 0);                                         /* ACK slot, as a receiver acknowledges it */
    for (i = 0; i < 8; i++) put(&w, 1);                 /* ACK delimiter, EOF(7) */
    if (nominal_bits) *nominal_bits = w.nom;
    if (data_bits) *data_bits = w.dat;
    return w.nom + w.dat;
}

int32_t rg_canbus_frame_bits(const rg_can_frame *f, int32_t *nominal_bits, int32_t *data_bits)
{
    return frame_stream(f, nominal_bits, data_bits, NULL, 0);
}

int32_t rg_canbus_frame_wire(const rg_can_frame *f, uint8_t *bits, int32_t max)
{
    return frame_stream(f, NULL, NULL, bits, max);
}

static int64_t bits_ns(int64_t bits, int64_t bps)
{
    return (bits * NS_PER_S + bps - 1) / bps;         /* ceil: never shorter than the bits */
}

int64_t rg_canbus_frame_ns(const rg_canbus *b, const rg_can_frame *f)
{
    int32_t nom, dat;
    if (rg_canbus_frame_bits(f, &nom, &dat) < 0) return -1;
    return bits_ns(nom, b->nominal_bps) + bits_ns(dat, b->data_bps);
}

/* ---- the bus ---- */

void rg_canbus_init(rg_canbus *b, int32_t nodes, int64_t nominal_bps, int64_t data_bps)
{
    memset(b, 0, sizeof *b);
    b->nodes = nodes < 0 ? 0 : (nodes > RG_CANBUS_MAX_NODES ? RG_CANBUS_MAX_NODES : nodes);
    b->nominal_bps = nominal_bps > 0 ? nominal_bps : 500000;
    b->data_bps = data_bps > 0 ? data_bps : b->nominal_bps;
}

static uint32_t stat_key(const rg_can_frame *f)
{
    return f->ide ? (f->id | RG_CANBUS_EFF) : f->id;
}

/* The arbitration field as one number, lower wins: base 11 bits, then SRR/IDE, then 18 bits. */
static uint32_t arb_key(const rg_can_frame *f)
{
    if (f->ide) return ((f->id >> 18) << 19) | (1u << 18) | (f->id & 0x3FFFFu);
    return f->id << 19;
}

static rg_canbus_id_stats *stats_for(rg_canbus *b, uint32_t key)
{
    int32_t i;
    for (i = 0; i < b->nstats; i++) if (b->stats[i].id == key) return &b->stats[i];
    if (b->nstats == RG_CANBUS_MAX_IDS) { b->stats_lost++; return NULL; }
    memset(&b->stats[b->nstats], 0, sizeof b->stats[0]);
    b->stats[b->nstats].id = key;
    return &b->stats[b->nstats++];
}

static int32_t errors_due(const rg_canbus *b, uint32_t key)
{
    int32_t i;
    for (i = 0; i < b->nerr; i++) if (b->err[i].id == key) return b->err[i].count;
    return 0;
}

static void log_drop(rg_canbus *b, int32_t node, const rg_can_frame *f, int64_t now_ns)
{
    rg_canbus_event *e;
    if (b->ndrops == RG_CANBUS_DROP_LOG) { b->drops_lost++; return; }
    e = &b->drops[b->ndrops++];
    memset(e, 0, sizeof *e);
    e->kind = RG_CANBUS_DROPPED;
    e->node = node;
    if (f != NULL) e->frame = *f;
    e->queued_ns = e->start_ns = e->end_ns = now_ns;
}

int32_t rg_canbus_submit(rg_canbus *b, int32_t node, const rg_can_frame *f, int64_t now_ns)
{
    rg_canbus_id_stats *s = NULL;
    int32_t i;
    if (f != NULL && f->ide <= 1) s = stats_for(b, stat_key(f));
    if (node >= 0 && node < b->nodes && valid(f)) {
        for (i = 0; i < RG_CANBUS_QUEUE; i++) {
            rg_canbus_slot *q = &b->node[node].q[i];
            if (q->used) continue;
            memset(q, 0, sizeof *q);
            q->frame.id = f->id;
            q->frame.ide = f->ide;
            q->frame.fd = f->fd;
            q->frame.brs = f->brs;
            q->frame.len = f->len;
            memcpy(q->frame.data, f->data, f->len);    /* bytes past len zero: deterministic events */
            q->queued_ns = now_ns;
            q->seq = b->seq++;
            q->used = 1;
            return 0;
        }
    }
    if (s != NULL) s->dropped++;
    log_drop(b, node, f, now_ns);
    return -1;
}

void rg_canbus_flood(rg_canbus *b, int32_t node, uint32_t id, int64_t from_ns, int64_t until_ns)
{
    rg_canbus_node *n;
    if (node < 0 || node >= b->nodes || id > 0x7FFu) return;
    n = &b->node[node];
    n->flood_on = until_ns > from_ns;
    n->flood_id = id;
    n->flood_from = n->flood_ready = from_ns;
    n->flood_until = until_ns;
}

void rg_canbus_error_next(rg_canbus *b, uint32_t id, int32_t count)
{
    int32_t i;
    if (count <= 0) return;
    for (i = 0; i < b->nerr; i++) if (b->err[i].id == id) { b->err[i].count += count; return; }
    if (b->nerr == RG_CANBUS_MAX_IDS) return;
    b->err[b->nerr].id = id;
    b->err[b->nerr].count = count;
    b->nerr++;
}

static void flood_frame(const rg_canbus_node *n, rg_can_frame *f)
{
    memset(f, 0, sizeof *f);
    f->id = n->flood_id;
    f->len = 8;
}

static int64_t max64(int64_t a, int64_t b) { return a > b ? a : b; }

/* Is the node's flood frame pending at t? */
static int32_t flood_at(const rg_canbus_node *n, int64_t t)
{
    return n->flood_on && n->flood_ready <= t && t < n->flood_until;
}

/* The next transmission if the bus decided now: the earliest time the bus is idle with something
 * pending, and the winner of the arbitration among everything pending then. 0 if none. */
static int32_t pick(const rg_canbus *b, rg_canbus_tx *tx)
{
    int64_t t0 = INT64_MAX;
    int32_t n, i, best_node = -1, best_slot = -1;
    uint32_t best_key = 0;
    for (n = 0; n < b->nodes; n++) {
        const rg_canbus_node *nd = &b->node[n];
        for (i = 0; i < RG_CANBUS_QUEUE; i++)
            if (nd->q[i].used && max64(b->idle_ns, nd->q[i].queued_ns) < t0) t0 = max64(b->idle_ns, nd->q[i].queued_ns);
        if (nd->flood_on) {
            int64_t s = max64(b->idle_ns, nd->flood_ready);
            if (s < nd->flood_until && s < t0) t0 = s;
        }
    }
    if (t0 == INT64_MAX) return 0;
    for (n = 0; n < b->nodes; n++) {
        const rg_canbus_node *nd = &b->node[n];
        int32_t slot = -2;            /* -2 none, -1 flood, >= 0 buffer: the node's offer */
        uint32_t key = 0, seq = 0;
        if (flood_at(nd, t0)) { rg_can_frame f; flood_frame(nd, &f); key = arb_key(&f); slot = -1; }
        for (i = 0; i < RG_CANBUS_QUEUE; i++) {
            const rg_canbus_slot *q = &nd->q[i];
            uint32_t k;
            if (!q->used || q->queued_ns > t0) continue;
            k = arb_key(&q->frame);
            if (slot == -2 || k < key || (k == key && slot >= 0 && q->seq < seq)) { slot = i; key = k; seq = q->seq; }
        }
        if (slot != -2 && (best_node < 0 || key < best_key)) {
            best_node = n; best_slot = slot; best_key = key;
        }
    }
    memset(tx, 0, sizeof *tx);
    tx->node = best_node;
    tx->slot = best_slot;
    if (best_slot >= 0) {
        tx->frame = b->node[best_node].q[best_slot].frame;
        tx->queued_ns = b->node[best_node].q[best_slot].queued_ns;
    } else {
        flood_frame(&b->node[best_node], &tx->frame);
        tx->queued_ns = b->node[best_node].flood_ready;
    }
    tx->start_ns = t0;
    tx->error = errors_due(b, stat_key(&tx->frame)) > 0;
    if (tx->error) {
        int32_t nom, dat;
        rg_canbus_frame_bits(&tx->frame, &nom, &dat);
        /* destroyed part: up to the ACK delimiter (all but EOF), then error flag + delimiter */
        tx->end_ns = t0 + bits_ns(nom - 7, b->nominal_bps) + bits_ns(dat, b->data_bps) + bits_ns(14, b->nominal_bps);
    } else {
        tx->end_ns = t0 + rg_canbus_frame_ns(b, &tx->frame);
    }
    tx->idle_ns = tx->end_ns + bits_ns(3, b->nominal_bps);
    return 1;
}

int64_t rg_canbus_next_ns(const rg_canbus *b)
{
    rg_canbus_tx tx;
    if (b->busy) return b->cur.end_ns;
    return pick(b, &tx) ? tx.end_ns : INT64_MAX;
}

static void finish(rg_canbus *b, rg_canbus_event *e)
{
    const rg_canbus_tx *tx = &b->cur;
    rg_canbus_id_stats *s = stats_for(b, stat_key(&tx->frame));
    rg_canbus_node *nd = &b->node[tx->node];
    memset(e, 0, sizeof *e);
    e->node = tx->node;
    e->frame = tx->frame;
    e->queued_ns = tx->queued_ns;
    e->start_ns = tx->start_ns;
    e->end_ns = tx->end_ns;
    if (tx->error) {
        int32_t i;
        e->kind = RG_CANBUS_BUS_ERROR;
        for (i = 0; i < b->nerr; i++) if (b->err[i].id == stat_key(&tx->frame) && b->err[i].count > 0) b->err[i].count--;
        if (s != NULL) s->errors++;
    } else {
        int64_t delay = tx->start_ns - tx->queued_ns;
        e->kind = RG_CANBUS_DELIVERED;
        if (tx->slot >= 0) nd->q[tx->slot].used = 0;
        else nd->flood_ready = tx->end_ns;       /* the babbler queues its next copy at once */
        if (s != NULL) {
            s->frames++;
            s->sum_delay_ns += delay;
            if (delay > s->max_delay_ns) s->max_delay_ns = delay;
        }
    }
    b->busy_ns += tx->idle_ns - tx->start_ns;
    b->idle_ns = tx->idle_ns;
    b->busy = 0;
}

int32_t rg_canbus_advance(rg_canbus *b, int64_t now_ns, rg_canbus_event *out, int32_t max)
{
    int32_t n = 0, d = 0;
    while (n < max) {
        if (!b->busy) {
            rg_canbus_tx tx;
            /* a transmission starting at now_ns stays undecided: a frame submitted at the same
             * instant must still take part in its arbitration */
            if (pick(b, &tx) && tx.start_ns < now_ns) { b->cur = tx; b->busy = 1; }
        }
        if (d < b->ndrops && b->drops[d].end_ns <= now_ns && (!b->busy || b->drops[d].end_ns <= b->cur.end_ns)) {
            out[n++] = b->drops[d++];
        } else if (b->busy && b->cur.end_ns <= now_ns) {
            finish(b, &out[n++]);
        } else {
            break;
        }
    }
    if (d > 0) {
        memmove(b->drops, b->drops + d, (size_t)(b->ndrops - d) * sizeof b->drops[0]);
        b->ndrops -= d;
    }
    return n;
}

const rg_canbus_id_stats *rg_canbus_stats(const rg_canbus *b, int32_t *count)
{
    if (count) *count = b->nstats;
    return b->stats;
}

int64_t rg_canbus_busy_ns(const rg_canbus *b)
{
    return b->busy_ns;
}

int32_t rg_canbus_pending(const rg_canbus *b, int32_t node)
{
    int32_t i, c = 0;
    if (node < 0 || node >= b->nodes) return 0;
    for (i = 0; i < RG_CANBUS_QUEUE; i++) c += b->node[node].q[i].used != 0;
    return c;
}

int32_t rg_canbus_sizeof(int32_t which)
{
    switch (which) {
    case 0: return (int32_t)sizeof(rg_canbus);
    case 1: return (int32_t)sizeof(rg_canbus_event);
    case 2: return (int32_t)sizeof(rg_canbus_id_stats);
    case 3: return (int32_t)sizeof(rg_can_frame);
    default: return -1;
    }
}
