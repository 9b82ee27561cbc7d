/* A network node's side of an FMI-LS-BUS terminal: the Bus Operations it collects during a
 * step and hands over when the importer reads its triggered Tx_Clock (reading the clock moves
 * them to the Tx_Data value, which stays valid until the next tick). */
#ifndef RG_LSBUS_NODE_H
#define RG_LSBUS_NODE_H

#include <stddef.h>
#include <stdint.h>

#define RG_NODE_BUFFER 8192

typedef struct {
    uint8_t pending[RG_NODE_BUFFER];
    size_t pending_size;
    uint8_t out[RG_NODE_BUFFER];
    size_t out_size;
    int64_t sent, dropped;           /* frames handed to the bus; frames that did not fit */
} rg_node_tx;

/* Queue a CAN (fd 0) or CAN FD Transmit; -1 (and counted as dropped) if it does not fit. */
int rg_node_send(rg_node_tx *tx, uint32_t id, int fd, int brs, const uint8_t *data, uint16_t length);
/* Queue a baud-rate Configuration (the bus simulation's rate is then checked against it). */
int rg_node_configure(rg_node_tx *tx, int fd, uint32_t bps);
/* Anything to hand over? */
int rg_node_has_pending(const rg_node_tx *tx);
/* The Tx_Clock read by the importer: active (1) if operations were pending, which become Tx_Data. */
int rg_node_tick(rg_node_tx *tx);
void rg_node_data(const rg_node_tx *tx, const uint8_t **data, size_t *size);

/* The transmit side of the network contract (rg_network.h) for a node model whose NetData keeps
 * its rg_node_tx in `tx`, expanded once in its model.c: Tx_Data is what the last Tx_Clock tick
 * handed over; its Rx_Clock needs no action (the data comes with fmi3SetBinary) and it has no
 * countdown clock. One definition for the player, the monitor node and the train node. */
#define RG_NODE_TX_CONTRACT                                                                       \
    void net_get_binary(NetData *m, uint32_t vr, const uint8_t **data, size_t *size)              \
    {                                                                                             \
        (void)vr;                                                                                 \
        rg_node_data(&m->tx, data, size);                                                         \
    }                                                                                             \
    int net_get_clock(NetData *m, uint32_t vr)                                                    \
    {                                                                                             \
        (void)vr;                                                                                 \
        return rg_node_tick(&m->tx);                                                              \
    }                                                                                             \
    void net_set_clock(NetData *m, uint32_t vr, int64_t now_ns)                                   \
    {                                                                                             \
        (void)m; (void)vr; (void)now_ns;                                                          \
    }                                                                                             \
    int net_get_interval(NetData *m, uint32_t vr, int64_t now_ns, int64_t *interval_ns)           \
    {                                                                                             \
        (void)m; (void)vr; (void)now_ns; (void)interval_ns;                                       \
        return 0;                                                                                 \
    }

#endif
