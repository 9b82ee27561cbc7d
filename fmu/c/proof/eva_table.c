/* Frama-C EVA driver for the initialisation (docs/proof.md); never compiled into an FMU.
 *
 * EVA runs what the FMU runs before its first cycle: rg_config_check on every configuration
 * (every field over its whole int32 range, so each refusal is reached), rg_table_check
 * (magic, version, SHA-256 over the whole file, dimensions, every action and next-node
 * index) on the shipped policy table from rg_table.h, generated at proof time by
 * verification/proof.py with fmu/generate.py, and rg_initial_state. EVA must find no alarm. */
#include <stdint.h>

#include "__fc_builtin.h"
#include "rg_core.h"
#include "rg_table.h"

int main(void)
{
    rg_config cfg;
    rg_table table;
    rg_state state;
    char msg[160];
    int bad;
    Frama_C_make_unknown((char *)&cfg, sizeof cfg);
    table.bytes = RG_TABLE_BYTES;
    table.length = RG_TABLE_LENGTH;
    table.action_offset = RG_TABLE_ACTION_OFFSET;
    table.next_offset = RG_TABLE_NEXT_OFFSET;
    table.risk_offset = RG_TABLE_RISK_OFFSET;
    table.nodes = RG_TABLE_NODES;
    table.observations = RG_TABLE_OBSERVATIONS;
    table.index_bytes = RG_TABLE_INDEX_BYTES;
    table.start = RG_TABLE_START;
    table.model = RG_TABLE_MODEL;
    table.period_ms = RG_TABLE_PERIOD_MS;
    bad = rg_config_check(&cfg, msg, sizeof msg);
    if (!bad) bad = rg_table_check(&table, &cfg, msg, sizeof msg);
    if (!bad) rg_initial_state(&table, &cfg, &state);
    return bad;
}
