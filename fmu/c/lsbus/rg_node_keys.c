/* A network node's key set: see rg_node_keys.h. */
#include "rg_node_keys.h"

#include <stdio.h>
#include <string.h>

const char *rg_resource_path(const char *resources)
{
    return strncmp(resources, "file://", 7) == 0 ? resources + 7 : resources;
}

int rg_node_keys(const char *resources, rg_keyset *keys, char *msg, size_t len)
{
    char path[512];
    unsigned char blob[RG_KEYS_BYTES + 1];
    const char *dir = rg_resource_path(resources);
    size_t n, dl = strlen(dir);
    FILE *fp;
    int i;
    snprintf(path, sizeof path, "%s%s%s", dir, (dl && dir[dl - 1] != '/') ? "/" : "", RG_KEYS_FILE);
    memset(keys, 0, sizeof *keys);
    fp = fopen(path, "rb");
    if (!fp)
        return 0;
    n = fread(blob, 1, sizeof blob, fp);
    fclose(fp);
    if (n != RG_KEYS_BYTES) {
        snprintf(msg, len, "%s: %u bytes, a key set is %d", path, (unsigned)n, RG_KEYS_BYTES);
        return -1;
    }
    for (i = 0; i < RG_KEY_OWNERS; i++) {
        keys->have[i] = blob[i * (1 + RG_SECOC_KEY)] ? 1 : 0;
        memcpy(keys->key[i], blob + i * (1 + RG_SECOC_KEY) + 1, RG_SECOC_KEY);
    }
    return 1;
}
