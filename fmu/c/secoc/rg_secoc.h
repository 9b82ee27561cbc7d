/* Secured frames, SecOC style, in C (issue 39; the Python twin is can_bus/secoc.py): the
 * authenticator and the receiver's check of a 20-byte secured CAN FD frame, for the C nodes
 * that will read and write frames (issue 42's network FMUs). AES-CMAC is OpenSSL's (libcrypto,
 * EVP_MAC "CMAC" with AES-128-CBC): no cryptography is written here.
 *
 * The frame: bytes 0..7 the classic frame (E2E), 8..11 the low 32 bits of the sender's 64-bit
 * freshness value for the ID (little-endian), 12..19 the first 8 bytes of AES-CMAC under the
 * ID owner's key over the frame ID (2 bytes, big-endian), bytes 0..7 and the full freshness
 * value (8 bytes, big-endian). */
#ifndef RG_SECOC_H
#define RG_SECOC_H

#include <stddef.h>
#include <stdint.h>

#define RG_SECOC_KEY 16
#define RG_SECOC_PAYLOAD 8
#define RG_SECOC_FV_WIRE 4
#define RG_SECOC_MAC 8
#define RG_SECOC_FRAME (RG_SECOC_PAYLOAD + RG_SECOC_FV_WIRE + RG_SECOC_MAC)
#define RG_SECOC_WINDOW 65536u      /* a frame may be this many values ahead of the newest accepted */

/* verdicts, in the order the receiver decides them (secoc.VERDICTS) */
enum { RG_SECOC_OK = 0, RG_SECOC_WRONG_LENGTH = 1, RG_SECOC_STALE = 2, RG_SECOC_BAD_MAC = 3, RG_SECOC_ERROR = 4 };

/* The truncated authenticator; 0 on success, -1 if libcrypto failed. */
int rg_secoc_authenticator(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t payload[RG_SECOC_PAYLOAD],
                           uint64_t freshness, uint8_t out[RG_SECOC_MAC]);

/* The secured frame of a payload with freshness value `freshness`; 0 on success, -1 on failure. */
int rg_secoc_protect(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t payload[RG_SECOC_PAYLOAD],
                     uint64_t freshness, uint8_t frame[RG_SECOC_FRAME]);

/* The full freshness value: the smallest above the newest accepted (none: has_newest 0) with
 * the low 32 bits `low`. */
uint64_t rg_secoc_rebuild(int has_newest, uint64_t newest, uint32_t low);

/* A received frame judged: RG_SECOC_OK with *freshness the value to remember as the newest,
 * or the reason it is refused (the freshness first, so a stale frame costs no CMAC). */
int rg_secoc_check(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t *data, size_t length,
                   int has_newest, uint64_t newest, uint64_t *freshness);

#endif
