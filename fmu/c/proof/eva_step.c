/* Frama-C EVA driver for the whole cycle (docs/proof.md); never compiled into an FMU.
 *
 * EVA runs rg_step RG_EVA_STEPS times in a row for
 *   - every configuration rg_config_check accepts: each field over its whole accepted range
 *     (a band's deceleration 1..20000: with the band off any value is accepted, and then
 *     never read). The conditions that link fields (timeout_cycles x period_ms <= 60 s,
 *     band 3 above band 2, service at most every emergency band, the worst-case
 *     deceleration on the steepest downhill >= 100 mm/s^2) are not imposed, so more
 *     configurations are covered than accepted;
 *   - the shipped policy table, bytes and layout from rg_table.h, which verification/proof.py
 *     generates at proof time with fmu/generate.py (the same header the FMU is built with);
 *   - the initial state, or any state at all (every byte of rg_state);
 *   - any inputs: every byte of rg_inputs, so every int32 field and every int64 report tick
 *     over its full range, fresh in each cycle, and any int64 tick for the cycle itself.
 * rg_step is total, so no input needs to be excluded: EVA must find no alarm. */
#include <stdint.h>

#include "__fc_builtin.h"
#include "rg_core.h"
#include "rg_table.h"

#ifndef RG_EVA_STEPS
#define RG_EVA_STEPS 3
#endif

static void any_config(rg_config *c)
{
    c->period_ms = Frama_C_interval(1, 10000);
    c->timeout_cycles = Frama_C_interval(1, 60000);
    c->persistence_cycles = Frama_C_interval(1, 1000);
    c->emergency_decel_mms2 = Frama_C_interval(1, 20000);
    c->emergency_band2_cms = Frama_C_interval(0, RG_MAX_SPEED_CMS);
    c->emergency_band2_mms2 = Frama_C_interval(1, 20000);
    c->emergency_band3_cms = Frama_C_interval(0, RG_MAX_SPEED_CMS);
    c->emergency_band3_mms2 = Frama_C_interval(1, 20000);
    c->service_decel_mms2 = Frama_C_interval(1, 20000);
    c->emergency_buildup_ms = Frama_C_interval(0, 30000);
    c->service_buildup_ms = Frama_C_interval(0, 30000);
    c->traction_cutoff_ms = Frama_C_interval(0, 30000);
    c->max_accel_mms2 = Frama_C_interval(0, 5000);
    c->speed_error_permille = Frama_C_interval(0, 500);
    c->slippery_permille = Frama_C_interval(1, 1000);
    c->degraded_permille = Frama_C_interval(1, 1000);
    c->max_gradient_permille = Frama_C_interval(0, 60);
    c->standstill_margin_dm = Frama_C_interval(0, 10000);
    c->warning_ms = Frama_C_interval(0, 60000);
    c->emergency_release = Frama_C_interval(RG_RELEASE_AT_STANDSTILL, RG_RELEASE_REVOCABLE);
    c->release_confirm_cycles = Frama_C_interval(1, 1000);
    c->warning_margin_dm = Frama_C_interval(0, 60000);
    c->fast_closing_cms = Frama_C_interval(1, 15000);
    c->safe_reaction = Frama_C_interval(RG_SERVICE, RG_EMERGENCY);
    c->recovery_cycles = Frama_C_interval(1, 100000);
    c->max_overruns = Frama_C_interval(1, 1000);
    c->distance_tolerance_dm = Frama_C_interval(0, 60000);
    c->forget_ms = Frama_C_interval(1, 600000);
    c->sensor_range_dm = Frama_C_interval(1, 60000);
    c->forget_single_ms = Frama_C_interval(1, 600000);
    c->distance_accuracy_dm = Frama_C_interval(0, 60000);
    c->closing_accuracy_cms = Frama_C_interval(0, 15000);
    c->plausibility_ms = Frama_C_interval(1, 60000);
}

static void shipped_table(rg_table *t)
{
    t->bytes = RG_TABLE_BYTES;
    t->length = RG_TABLE_LENGTH;
    t->action_offset = RG_TABLE_ACTION_OFFSET;
    t->next_offset = RG_TABLE_NEXT_OFFSET;
    t->risk_offset = RG_TABLE_RISK_OFFSET;
    t->nodes = RG_TABLE_NODES;
    t->observations = RG_TABLE_OBSERVATIONS;
    t->index_bytes = RG_TABLE_INDEX_BYTES;
    t->start = RG_TABLE_START;
    t->model = RG_TABLE_MODEL;
    t->period_ms = RG_TABLE_PERIOD_MS;
}

/* RG_EVA_STEPS cycles from the initial state or from any state. Called once per topology,
 * so that EVA keeps `modules` (and with it the channel count) exact inside rg_step. */
static int32_t run(int32_t modules)
{
    rg_config cfg;
    rg_table table;
    rg_state state;
    rg_inputs in;
    rg_outputs out;
    int k;
    any_config(&cfg);
    cfg.modules = modules;
    shipped_table(&table);
    if (Frama_C_nondet(0, 1)) {
        rg_initial_state(&table, &cfg, &state);
    } else {
        Frama_C_make_unknown((char *)&state, sizeof state);
    }
    for (k = 0; k < RG_EVA_STEPS; k++) {
        Frama_C_make_unknown((char *)&in, sizeof in);
        rg_step(&cfg, &table, &state, &in, (int64_t)Frama_C_long_long_interval(INT64_MIN, INT64_MAX), &out);
    }
    return out.demand;
}

int main(void)
{
    /* rg_config_check accepts modules 3 (3oo3 over three 2oo2 modules) and 1 (one module) */
    return Frama_C_nondet(0, 1) ? run(3) : run(1);
}
