/* Secured frames in C: see rg_secoc.h. */
#include "rg_secoc.h"

#include <string.h>

#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/params.h>

static EVP_MAC *cmac_algorithm(void)
{
    static EVP_MAC *mac = NULL;    /* fetched once: the algorithm object is shared and read-only */
    if (mac == NULL) {
        mac = EVP_MAC_fetch(NULL, "CMAC", NULL);
    }
    return mac;
}

int rg_secoc_authenticator(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t payload[RG_SECOC_PAYLOAD],
                           uint64_t freshness, uint8_t out[RG_SECOC_MAC])
{
    uint8_t message[2 + RG_SECOC_PAYLOAD + 8];
    uint8_t full[16];
    size_t length = 0;
    int i, ok;
    char cipher[] = "AES-128-CBC";
    OSSL_PARAM params[2];
    EVP_MAC *mac = cmac_algorithm();
    EVP_MAC_CTX *ctx;

    if (mac == NULL) {
        return -1;
    }
    message[0] = (uint8_t)(frame_id >> 8);
    message[1] = (uint8_t)frame_id;
    memcpy(message + 2, payload, RG_SECOC_PAYLOAD);
    for (i = 0; i < 8; i++) {
        message[2 + RG_SECOC_PAYLOAD + i] = (uint8_t)(freshness >> (56 - 8 * i));
    }
    params[0] = OSSL_PARAM_construct_utf8_string(OSSL_MAC_PARAM_CIPHER, cipher, 0);
    params[1] = OSSL_PARAM_construct_end();
    ctx = EVP_MAC_CTX_new(mac);
    if (ctx == NULL) {
        return -1;
    }
    ok = EVP_MAC_init(ctx, key, RG_SECOC_KEY, params) && EVP_MAC_update(ctx, message, sizeof message)
         && EVP_MAC_final(ctx, full, &length, sizeof full) && length == sizeof full;
    EVP_MAC_CTX_free(ctx);
    if (!ok) {
        return -1;
    }
    memcpy(out, full, RG_SECOC_MAC);
    OPENSSL_cleanse(full, sizeof full);
    return 0;
}

int rg_secoc_protect(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t payload[RG_SECOC_PAYLOAD],
                     uint64_t freshness, uint8_t frame[RG_SECOC_FRAME])
{
    int i;
    memcpy(frame, payload, RG_SECOC_PAYLOAD);
    for (i = 0; i < RG_SECOC_FV_WIRE; i++) {
        frame[RG_SECOC_PAYLOAD + i] = (uint8_t)(freshness >> (8 * i));
    }
    return rg_secoc_authenticator(key, frame_id, payload, freshness, frame + RG_SECOC_PAYLOAD + RG_SECOC_FV_WIRE);
}

uint64_t rg_secoc_rebuild(int has_newest, uint64_t newest, uint32_t low)
{
    uint64_t next, candidate;
    if (!has_newest) {
        return low;                  /* the smallest value above -1 with these low bits */
    }
    next = newest + 1u;
    candidate = (next & ~(uint64_t)0xFFFFFFFFu) | low;
    return candidate > newest ? candidate : candidate + ((uint64_t)1 << 32);
}

int rg_secoc_check(const uint8_t key[RG_SECOC_KEY], uint16_t frame_id, const uint8_t *data, size_t length,
                   int has_newest, uint64_t newest, uint64_t *freshness)
{
    uint8_t want[RG_SECOC_MAC];
    uint32_t low = 0;
    uint64_t value, ahead;
    unsigned char diff = 0;
    int i;

    if (length != RG_SECOC_FRAME) {
        return RG_SECOC_WRONG_LENGTH;
    }
    for (i = RG_SECOC_FV_WIRE - 1; i >= 0; i--) {
        low = (low << 8) | data[RG_SECOC_PAYLOAD + i];
    }
    value = rg_secoc_rebuild(has_newest, newest, low);
    ahead = has_newest ? value - newest : value + 1u;
    if (ahead > RG_SECOC_WINDOW) {
        return RG_SECOC_STALE;
    }
    if (rg_secoc_authenticator(key, frame_id, data, value, want) != 0) {
        return RG_SECOC_ERROR;
    }
    for (i = 0; i < RG_SECOC_MAC; i++) {    /* every byte compared: the time does not tell where they differ */
        diff |= (unsigned char)(want[i] ^ data[RG_SECOC_PAYLOAD + RG_SECOC_FV_WIRE + i]);
    }
    if (diff != 0) {
        return RG_SECOC_BAD_MAC;
    }
    *freshness = value;
    return RG_SECOC_OK;
}
