/* The monitor FMU: the railguard online core (rg_core.c) behind FMI inputs and outputs.
 * The policy table is compiled in (rg_table.h, generated from the table file); the
 * parameters and their start values come from rg_parameters.h (generated from
 * fmu/variables.py, or from a braking declaration). */
#ifndef RG_MONITOR_CONFIG_H
#define RG_MONITOR_CONFIG_H

#include <stdint.h>

#include "build_info.h"
#include "rg_core.h"
#include "rg_parameters.h"

#define MODEL_IDENTIFIER "railguard_monitor"
#define FIXED_STEP 0.1   /* the core's cycle period, 100 ms: cycles run at its multiples, whatever the
                           communication step (model_do_step) */

typedef struct {
    /* parameters: the fields of rg_config named in RG_PARAMETERS (as in monitor/core/config.py),
     * and the topology code (3: 3oo3, 2: one 2oo2 module) */
    rg_config params;
    int32_t topology;
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
    int64_t cycles;       /* cycles run since initialisation: the next one runs at tick = cycles * period_ms,
                             i.e. at cycles * period_ms * 10^6 ns after the start */
} ModelData;

#endif
