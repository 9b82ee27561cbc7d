/* The monitor FMU: the railguard online core (rg_core.c) behind FMI inputs and outputs.
 * The policy table is compiled in (rg_table.h, generated from the table file). */
#ifndef RG_MONITOR_CONFIG_H
#define RG_MONITOR_CONFIG_H

#include <stdint.h>

#include "build_info.h"
#include "rg_core.h"

#define MODEL_IDENTIFIER "railguard_monitor"
#define FIXED_STEP 0.1   /* the core's cycle period, 100 ms */

typedef struct {
    /* parameters (names as in monitor/core/config.py) */
    int32_t timeout_cycles, persistence_cycles, service_decel_mms2, emergency_decel_mms2, reaction_ms,
        warning_margin_dm, fast_closing_cms, safe_reaction, recovery_cycles, topology, distance_tolerance_dm;
    /* inputs, as the FMI sees them */
    int32_t status[RG_MAX_CHANNELS], type[RG_MAX_CHANNELS], valid[RG_MAX_CHANNELS];
    double distance[RG_MAX_CHANNELS], closing[RG_MAX_CHANNELS];
    double speed;
    int32_t track, brake;
    /* the core */
    rg_config config;
    rg_table table;
    rg_inputs inputs;     /* the newest report of each channel, with the tick it arrived */
    rg_state state;
    rg_outputs outputs;
    int64_t cycles;       /* cycles run since initialisation: tick = cycles * period_ms */
} ModelData;

#endif
