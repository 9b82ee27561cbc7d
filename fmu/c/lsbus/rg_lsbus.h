/* FMI-LS-BUS CAN operations (Network Abstraction, fmi-ls-bus 1.0, chapter "CAN, CAN FD, CAN XL"):
 * writing and reading the Bus Operations that travel in the Tx_Data/Rx_Data binaries.
 *
 * Every operation is OP code (4 bytes), Length (4 bytes: the whole operation, header
 * included) and its arguments; numbers are little-endian, booleans one byte 0/1. A binary
 * may hold several operations back to back; the reader walks them by Length and stops at the
 * first malformed one (a receiver must never trust a length it has not checked). */
#ifndef RG_LSBUS_H
#define RG_LSBUS_H

#include <stddef.h>
#include <stdint.h>

enum {
    RG_OP_FORMAT_ERROR = 0x01,
    RG_OP_CAN_TRANSMIT = 0x10,
    RG_OP_CANFD_TRANSMIT = 0x11,
    RG_OP_CONFIRM = 0x20,
    RG_OP_ARBITRATION_LOST = 0x30,
    RG_OP_BUS_ERROR = 0x31,
    RG_OP_CONFIGURATION = 0x40,
    RG_OP_STATUS = 0x41
};

/* Configuration kinds (the operation's first argument) */
enum { RG_CFG_CAN_BAUDRATE = 0x01, RG_CFG_CANFD_BAUDRATE = 0x02, RG_CFG_ARBITRATION_LOST_BEHAVIOR = 0x04 };
/* Bus error codes and flags */
enum { RG_BUS_ERROR_BIT = 0x01, RG_BUS_ERROR_STUFF = 0x02, RG_BUS_ERROR_FORM = 0x03, RG_BUS_ERROR_CRC = 0x04,
       RG_BUS_ERROR_ACK = 0x05 };
enum { RG_PRIMARY_ERROR_FLAG = 0x01, RG_SECONDARY_ERROR_FLAG = 0x02 };

#define RG_LSBUS_MAX_DATA 64

/* One decoded operation: the fields its OP code uses, the rest zero. */
typedef struct {
    uint32_t op;
    uint32_t id;
    uint8_t ide, rtr, brs, esi;
    uint16_t length;                   /* data bytes of a transmit */
    uint8_t data[RG_LSBUS_MAX_DATA];
    uint8_t error_code, error_flag, is_sender;
    uint8_t kind;                      /* configuration kind */
    uint32_t value;                    /* configuration value (a baud rate) or status */
} rg_lsbus_op;

/* Appenders: write one operation at buf[*used] if it fits in `size`; 0 on success, -1 if it
 * does not fit or the data length is not a valid one (classic 0..8, FD 0..8/12/16/20/24/32/48/64). */
int rg_lsbus_put_transmit(uint8_t *buf, size_t size, size_t *used, uint32_t id, int fd, int brs,
                          const uint8_t *data, uint16_t length);
int rg_lsbus_put_confirm(uint8_t *buf, size_t size, size_t *used, uint32_t id);
int rg_lsbus_put_arbitration_lost(uint8_t *buf, size_t size, size_t *used, uint32_t id);
int rg_lsbus_put_bus_error(uint8_t *buf, size_t size, size_t *used, uint32_t id, uint8_t code, uint8_t flag,
                           uint8_t is_sender);
int rg_lsbus_put_baudrate(uint8_t *buf, size_t size, size_t *used, int fd, uint32_t bps);

/* Read the operation at buf[*offset] into *op and advance *offset.
 * Returns 1 if an operation was read, 0 at the end of the buffer, -1 if the rest is malformed
 * (a length beyond the buffer or too short for its OP code, an invalid data length). */
int rg_lsbus_next(const uint8_t *buf, size_t size, size_t *offset, rg_lsbus_op *op);

/* Is `length` a valid data length (fd: CAN FD, else classic)? */
int rg_lsbus_valid_length(int fd, uint32_t length);

#endif
