/* A network node's key set (issue 39's keys, issue 42's nodes): resources/keys.bin, written by
 * the FMU builder from a key folder, holds for each sender in keys.SENDERS order (ch0..ch5,
 * train, monitor) one byte "held" (0/1) and the 16-byte AES-128 key. No file: the node runs on
 * an unsecured bus (classical E2E frames). */
#ifndef RG_NODE_KEYS_H
#define RG_NODE_KEYS_H

#include <stddef.h>

#include "rg_frames.h"

#define RG_KEYS_FILE "keys.bin"
#define RG_KEYS_BYTES (RG_KEY_OWNERS * (1 + RG_SECOC_KEY))

/* 1: a secured node (*keys filled), 0: no key file (unsecured), -1: a key file that is not
 * RG_KEYS_BYTES long or unreadable (msg says why: a node never falls back to unsecured). */
int rg_node_keys(const char *resources, rg_keyset *keys, char *msg, size_t len);

/* The resources folder as a path (an importer may give a file: URI). */
const char *rg_resource_path(const char *resources);

#endif
