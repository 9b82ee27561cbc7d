/* A CAN / CAN FD bus model for FMI-LS-BUS co-simulation (issue 42): arbitration, exact frame
 * lengths (stuff bits from the real CRC), babbling nodes and injected error frames, so that a
 * node flooding ID 0x000 starves BrakeDemand (0x010) here as it would on a real bus (vcan0 has
 * no arbitration). The FMU wrapper calls it; the Python face is fmu/canbus_c.py.
 *
 * Pure and deterministic: no FMI, no I/O, no heap, no floats, no global state; time is integer
 * nanoseconds. The same call sequence gives the same events, bit for bit.
 *
 * Extended IDs (ide=1) are supported: they arbitrate by their 11 base bits, then SRR/IDE
 * (recessive, so a base frame with the same 11 bits wins), then the 18 extension bits. In the
 * statistics and in rg_canbus_error_next an extended ID is named id | RG_CANBUS_EFF (as Linux's
 * CAN_EFF_FLAG does). Remote frames are not modelled (data frames only). */
#ifndef RG_CANBUS_H
#define RG_CANBUS_H

#include <stdint.h>

#define RG_CANBUS_MAX_NODES 8
#define RG_CANBUS_QUEUE 32            /* transmit buffers per node */
#define RG_CANBUS_MAX_IDS 64          /* per-ID statistics slots */
#define RG_CANBUS_DROP_LOG 32         /* dropped submissions kept for the next advance */
#define RG_CANBUS_EFF 0x80000000u     /* marks an extended ID in statistics and error_next */

typedef struct {
    uint32_t id;        /* 11 bits (ide 0) or 29 bits (ide 1) */
    uint8_t ide;        /* 1: extended frame format */
    uint8_t fd;         /* 1: CAN FD frame (FDF recessive) */
    uint8_t brs;        /* 1: bit rate switch (fd frames only) */
    uint8_t len;        /* classic 0..8; fd 0..8, 12, 16, 20, 24, 32, 48, 64 */
    uint8_t data[64];
} rg_can_frame;

enum { RG_CANBUS_DELIVERED = 1, RG_CANBUS_BUS_ERROR = 2, RG_CANBUS_DROPPED = 3 };

/* DELIVERED: end_ns is the end of EOF. BUS_ERROR: end_ns is the end of the error delimiter
 * (the bus is idle 3 bits later). DROPPED: queued_ns = start_ns = end_ns = the submit time. */
typedef struct {
    int32_t kind;
    int32_t node;
    rg_can_frame frame;
    int64_t queued_ns, start_ns, end_ns;
} rg_canbus_event;

/* Delay = start_ns - queued_ns of the transmission that succeeded. */
typedef struct {
    uint32_t id;
    int64_t frames, errors, dropped, max_delay_ns, sum_delay_ns;
} rg_canbus_id_stats;

typedef struct {
    rg_can_frame frame;
    int64_t queued_ns;
    uint32_t seq;       /* submission order: FIFO among equal IDs */
    int32_t used;
} rg_canbus_slot;

typedef struct {
    rg_canbus_slot q[RG_CANBUS_QUEUE];
    int32_t flood_on;
    uint32_t flood_id;
    int64_t flood_from, flood_until;
    int64_t flood_ready;   /* its next frame is pending from here (queued_ns of that frame) */
} rg_canbus_node;

/* One transmission (or attempt): slot -1 is the node's flood frame. */
typedef struct {
    int32_t node, slot, error;
    rg_can_frame frame;
    int64_t queued_ns, start_ns, end_ns, idle_ns;
} rg_canbus_tx;

typedef struct {
    uint32_t id;
    int32_t count;
} rg_canbus_err;

typedef struct {
    int32_t nodes;
    int64_t nominal_bps, data_bps;
    rg_canbus_node node[RG_CANBUS_MAX_NODES];
    int64_t idle_ns;           /* the bus is idle from here (after the last intermission) */
    int32_t busy;              /* 1: cur is on the bus, decided */
    rg_canbus_tx cur;
    uint32_t seq;
    rg_canbus_id_stats stats[RG_CANBUS_MAX_IDS];
    int32_t nstats;
    int64_t stats_lost;        /* events of IDs beyond RG_CANBUS_MAX_IDS (not in stats) */
    rg_canbus_err err[RG_CANBUS_MAX_IDS];
    int32_t nerr;
    int64_t busy_ns;
    rg_canbus_event drops[RG_CANBUS_DROP_LOG];
    int32_t ndrops;
    int64_t drops_lost;        /* DROPPED events beyond the log (still counted in stats) */
} rg_canbus;

void rg_canbus_init(rg_canbus *b, int32_t nodes, int64_t nominal_bps, int64_t data_bps);
/* 0 queued; -1 full or invalid (counted as dropped, reported by the next advance). */
int32_t rg_canbus_submit(rg_canbus *b, int32_t node, const rg_can_frame *f, int64_t now_ns);
/* Babbling node: an 8-byte classic frame of base ID `id` (zeros) always pending in [from, until). */
void rg_canbus_flood(rg_canbus *b, int32_t node, uint32_t id, int64_t from_ns, int64_t until_ns);
/* The next `count` transmissions of `id` (| RG_CANBUS_EFF if extended) end in an error frame. */
void rg_canbus_error_next(rg_canbus *b, uint32_t id, int32_t count);
/* When the next transmission completes (or error frame ends); INT64_MAX if nothing is due. */
int64_t rg_canbus_next_ns(const rg_canbus *b);
/* Complete everything that ends at or before now_ns, in time order; the number of events written. */
int32_t rg_canbus_advance(rg_canbus *b, int64_t now_ns, rg_canbus_event *out, int32_t max);
/* Bits on the wire from SOF to the end of EOF, stuff bits included (intermission not); -1 if
 * the frame is invalid. *data_bits: those sent at the data bit rate (fd with brs), else 0. */
int32_t rg_canbus_frame_bits(const rg_can_frame *f, int32_t *nominal_bits, int32_t *data_bits);
/* The bits themselves, SOF to the end of EOF (0 dominant, the ACK slot as acknowledged), into
 * bits[0..max); returns the count (as rg_canbus_frame_bits), -1 if invalid. */
#define RG_CANBUS_MAX_BITS 768
int32_t rg_canbus_frame_wire(const rg_can_frame *f, uint8_t *bits, int32_t max);
/* The frame's duration (SOF to the end of EOF) on this bus; -1 if invalid. */
int64_t rg_canbus_frame_ns(const rg_canbus *b, const rg_can_frame *f);
const rg_canbus_id_stats *rg_canbus_stats(const rg_canbus *b, int32_t *count);
/* Bus occupied time (frames, error frames, intermissions) of completed transmissions. */
int64_t rg_canbus_busy_ns(const rg_canbus *b);
/* Frames waiting in the node's buffers (the flood frame not counted). */
int32_t rg_canbus_pending(const rg_canbus *b, int32_t node);
/* sizeof of 0: rg_canbus, 1: rg_canbus_event, 2: rg_canbus_id_stats, 3: rg_can_frame (for ctypes). */
int32_t rg_canbus_sizeof(int32_t which);

#endif
