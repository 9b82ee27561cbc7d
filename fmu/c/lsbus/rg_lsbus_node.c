/* A network node's transmit side: see rg_lsbus_node.h. */
#include "rg_lsbus_node.h"

#include <string.h>

#include "rg_lsbus.h"

int rg_node_send(rg_node_tx *tx, uint32_t id, int fd, int brs, const uint8_t *data, uint16_t length)
{
    if (rg_lsbus_put_transmit(tx->pending, sizeof tx->pending, &tx->pending_size, id, fd, brs, data, length) != 0) {
        tx->dropped++;
        return -1;
    }
    tx->sent++;
    return 0;
}

int rg_node_configure(rg_node_tx *tx, int fd, uint32_t bps)
{
    return rg_lsbus_put_baudrate(tx->pending, sizeof tx->pending, &tx->pending_size, fd, bps);
}

int rg_node_has_pending(const rg_node_tx *tx) { return tx->pending_size > 0; }

int rg_node_tick(rg_node_tx *tx)
{
    if (!tx->pending_size)
        return 0;
    memcpy(tx->out, tx->pending, tx->pending_size);
    tx->out_size = tx->pending_size;
    tx->pending_size = 0;
    return 1;
}

void rg_node_data(const rg_node_tx *tx, const uint8_t **data, size_t *size)
{
    *data = tx->out;
    *size = tx->out_size;
}
