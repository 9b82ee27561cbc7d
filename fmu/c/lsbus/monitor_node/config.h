/* The monitor as a network FMU: the railguard core (rg_core.c) behind an FMI-LS-BUS CAN
 * terminal, reading and writing exactly the DBC frames of vcan0 through the C frame layer
 * (fmu/c/frames: E2E, secured CAN FD frames when resources/keys.bin holds the key set).
 *
 * Cycle k runs at k * period + phase_ms and decides for tick k * period (ms), with the frames
 * that arrived before it, each stamped min(its arrival, the cycle's tick) as runner.py stamps
 * them: the sensors publish at k * period, the bus brings their frames within a few
 * milliseconds, and the monitor samples `phase_ms` later, so that on a quiet bus it decides
 * cycle by cycle as the Python monitor does on vcan0. Its four frames leave at once; the
 * train reads BrakeDemand at its next period. */
#ifndef RG_MONITOR_NODE_CONFIG_H
#define RG_MONITOR_NODE_CONFIG_H

#include <stdint.h>

#include "build_info.h"
#include "rg_core.h"
#include "rg_frames.h"
#include "rg_lsbus_node.h"
#include "rg_network.h"
#include "rg_parameters.h"

#define MODEL_IDENTIFIER railguard_monitor_can

typedef struct {
    char resources[RG_NET_STRING];
    int32_t phase_ms;
    int32_t bit_rate;
    double stop_time;                /* s: no cycle from then on (a crashed or hung monitor: fault monitor_stop) */
    /* the core */
    rg_config config;
    rg_table table;
    rg_state state;
    rg_outputs outputs;
    int64_t cycles;                  /* the next cycle's index */
    int32_t table_hash;
    /* the frame layer */
    int secured;
    rg_keyset keys;
    rg_monitor_rx rx;
    rg_sender sender;
    rg_node_tx tx;
    int32_t foreign;                 /* the last cycle's ForeignOutput flag */
    int64_t frames_rx, rejected;
} NetData;

#endif
