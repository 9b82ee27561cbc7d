/* SHA-256 (FIPS 180-4), for the table integrity check at initialisation. */
#ifndef RG_SHA256_H
#define RG_SHA256_H

#include <stddef.h>
#include <stdint.h>

void rg_sha256(const uint8_t *data, size_t length, uint8_t digest[32]);

#endif
