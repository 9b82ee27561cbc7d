/* The bus simulation FMU (FMI-LS-BUS "Bus Simulation FMU", CAN): arbitration by ID, bit
 * timing at the declared rates, a transmit queue per node, error frames on request and a
 * babbling node, all in rg_canbus.c; this model connects it to one terminal per node. */
#ifndef RG_BUS_CONFIG_H
#define RG_BUS_CONFIG_H

#include <stdint.h>
#include <stdio.h>

#include "build_info.h"
#include "bus_nodes.h"
#include "rg_canbus.h"
#include "rg_network.h"

#define MODEL_IDENTIFIER railguard_canbus
#define BUS_BUFFER 4096
#define BUS_EVENTS 64

typedef struct {
    char resources[RG_NET_STRING];
    /* parameters */
    int32_t bit_rate, data_bit_rate;
    int32_t flood_id;                /* -1: no babbling node */
    double flood_start, flood_stop;  /* s */
    int32_t error_id, error_count;   /* the next error_count transmissions of error_id end in an error frame */
    int32_t watch_id;                /* the ID whose timing the outputs report (BrakeDemand) */
    char trace_file[RG_NET_STRING];
    /* the bus and the operations waiting for each node's Tx_Clock */
    rg_canbus bus;
    uint8_t pending[BUS_NODES][BUS_BUFFER];
    size_t pending_size[BUS_NODES];
    uint8_t out[BUS_NODES][BUS_BUFFER];
    size_t out_size[BUS_NODES];
    rg_canbus_event events[BUS_EVENTS];
    int64_t now_ns;
    int armed, delivered;            /* Event Mode hand-over (model.c, net_update_discrete_states) */
    FILE *trace;
    /* outputs */
    int32_t frames, errors, dropped, overflow, config_mismatch;
    int32_t watch_frames;
    int64_t watch_max_delay_ns, watch_last_end_ns, watch_max_gap_ns;
} NetData;

#endif
