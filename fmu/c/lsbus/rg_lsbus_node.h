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

#endif
