/* FMI-LS-BUS CAN operations: see rg_lsbus.h. Written from the standard's tables, not from its
 * examples. */
#include "rg_lsbus.h"

#include <string.h>

#define HEADER 8u

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint16_t get16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

int rg_lsbus_valid_length(int fd, uint32_t length)
{
    if (length <= 8)
        return 1;
    return fd && (length == 12 || length == 16 || length == 20 || length == 24 || length == 32 || length == 48 ||
                  length == 64);
}

/* Reserve `length` bytes at buf[*used] with the header written; NULL if they do not fit. */
static uint8_t *reserve(uint8_t *buf, size_t size, size_t *used, uint32_t op, uint32_t length)
{
    uint8_t *p;
    if (*used > size || size - *used < length)
        return NULL;
    p = buf + *used;
    put32(p, op);
    put32(p + 4, length);
    *used += length;
    return p;
}

int rg_lsbus_put_transmit(uint8_t *buf, size_t size, size_t *used, uint32_t id, int fd, int brs,
                          const uint8_t *data, uint16_t length)
{
    /* CAN: OP, Length, ID(4), Ide, Rtr, DL(2), data = 16 + DL; CAN FD: ID(4), Ide, Brs, Esi, DL(2) = 17 + DL */
    uint32_t fixed = fd ? 17u : 16u;
    uint8_t *p;
    if (!rg_lsbus_valid_length(fd, length))
        return -1;
    p = reserve(buf, size, used, fd ? RG_OP_CANFD_TRANSMIT : RG_OP_CAN_TRANSMIT, fixed + length);
    if (!p)
        return -1;
    put32(p + 8, id);
    p[12] = 0;                                       /* Ide: standard 11-bit identifier */
    if (fd) {
        p[13] = brs ? 1 : 0;
        p[14] = 0;                                   /* Esi: error active */
        put16(p + 15, length);
    } else {
        p[13] = 0;                                   /* Rtr: a data frame */
        put16(p + 14, length);
    }
    if (length)
        memcpy(p + fixed, data, length);
    return 0;
}

static int put_id_op(uint8_t *buf, size_t size, size_t *used, uint32_t op, uint32_t id)
{
    uint8_t *p = reserve(buf, size, used, op, 12);
    if (!p)
        return -1;
    put32(p + 8, id);
    return 0;
}

int rg_lsbus_put_confirm(uint8_t *buf, size_t size, size_t *used, uint32_t id)
{
    return put_id_op(buf, size, used, RG_OP_CONFIRM, id);
}

int rg_lsbus_put_arbitration_lost(uint8_t *buf, size_t size, size_t *used, uint32_t id)
{
    return put_id_op(buf, size, used, RG_OP_ARBITRATION_LOST, id);
}

int rg_lsbus_put_bus_error(uint8_t *buf, size_t size, size_t *used, uint32_t id, uint8_t code, uint8_t flag,
                           uint8_t is_sender)
{
    uint8_t *p = reserve(buf, size, used, RG_OP_BUS_ERROR, 15);
    if (!p)
        return -1;
    put32(p + 8, id);
    p[12] = code;
    p[13] = flag;
    p[14] = is_sender ? 1 : 0;
    return 0;
}

int rg_lsbus_put_baudrate(uint8_t *buf, size_t size, size_t *used, int fd, uint32_t bps)
{
    uint8_t *p = reserve(buf, size, used, RG_OP_CONFIGURATION, 13);
    if (!p)
        return -1;
    p[8] = fd ? RG_CFG_CANFD_BAUDRATE : RG_CFG_CAN_BAUDRATE;
    put32(p + 9, bps);
    return 0;
}

int rg_lsbus_next(const uint8_t *buf, size_t size, size_t *offset, rg_lsbus_op *op)
{
    const uint8_t *p;
    uint32_t length, need;
    if (*offset >= size)
        return 0;
    if (size - *offset < HEADER)
        return -1;
    p = buf + *offset;
    memset(op, 0, sizeof *op);
    op->op = get32(p);
    length = get32(p + 4);
    if (length < HEADER || length > size - *offset)
        return -1;
    switch (op->op) {
    case RG_OP_CAN_TRANSMIT:
        if (length < 16)
            return -1;
        op->id = get32(p + 8);
        op->ide = p[12];
        op->rtr = p[13];
        op->length = get16(p + 14);
        need = 16u + op->length;
        if (length != need || !rg_lsbus_valid_length(0, op->length))
            return -1;
        memcpy(op->data, p + 16, op->length);
        break;
    case RG_OP_CANFD_TRANSMIT:
        if (length < 17)
            return -1;
        op->id = get32(p + 8);
        op->ide = p[12];
        op->brs = p[13];
        op->esi = p[14];
        op->length = get16(p + 15);
        need = 17u + op->length;
        if (length != need || !rg_lsbus_valid_length(1, op->length))
            return -1;
        memcpy(op->data, p + 17, op->length);
        break;
    case RG_OP_CONFIRM:
    case RG_OP_ARBITRATION_LOST:
        if (length != 12)
            return -1;
        op->id = get32(p + 8);
        break;
    case RG_OP_BUS_ERROR:
        if (length != 15)
            return -1;
        op->id = get32(p + 8);
        op->error_code = p[12];
        op->error_flag = p[13];
        op->is_sender = p[14];
        break;
    case RG_OP_CONFIGURATION:
        if (length < 9)
            return -1;
        op->kind = p[8];
        if (length >= 13)
            op->value = get32(p + 9);
        else if (length == 10)
            op->value = p[9];
        break;
    case RG_OP_STATUS:
        if (length != 9)
            return -1;
        op->value = p[8];
        break;
    default:
        break;                                       /* unknown operations are skipped by their length */
    }
    *offset += length;
    return 1;
}
