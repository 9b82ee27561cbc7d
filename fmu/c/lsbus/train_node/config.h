/* The train as a network FMU: the train-dynamics model of the signal co-simulation
 * (fmu/c/train/model.c through its model.h contract, unchanged: the build stages it as
 * train_model.c, train_model.h, train_config.h and train_variables.h, its #include lines
 * rewritten, so that its config.h and variables.h do not meet this node's) behind an
 * FMI-LS-BUS CAN terminal and the C frame layer (fmu/c/frames).
 *
 * At every instant k * period (k = 0 included, in net_initialize) the node first sets the
 * model's brake_demand and monitor_cycle inputs from the newest BrakeDemand frame it
 * accepted (Level and Cycle; before the first one the model's start values stay), then
 * sends TrainState and one ObstacleReport per channel built from the model's outputs at that
 * instant, converted to integers exactly as the signal monitor FMU reads them
 * (fmu/c/monitor/model.c); a channel whose `valid` output is false sends nothing. The model
 * steps with its own 10 ms grid over any communication step. Its alive timeout on
 * monitor_cycle is the brake receiver: when BrakeDemand frames stop arriving, the latched
 * cycle stops changing and the model brakes. So the monitor's demand of the cycle at t acts
 * from t + period, as in fmu/cosim.py with demand_delay_cycles = 1. */
#ifndef RG_TRAIN_NODE_CONFIG_H
#define RG_TRAIN_NODE_CONFIG_H

#include <stdint.h>

#include "train_model.h"             /* ModelData; its identity macros are the train FMU's, not ours */
#undef MODEL_IDENTIFIER
#undef INSTANTIATION_TOKEN

#include "build_info.h"
#include "rg_frames.h"
#include "rg_lsbus_node.h"
#include "rg_network.h"

#define MODEL_IDENTIFIER railguard_train_can
#define TRAIN_NODE_PERIOD_MS 100     /* the monitor's cycle: the m1/m2 tables' period */

typedef struct {
    char resources[RG_NET_STRING];
    int32_t bit_rate;
    ModelData train;                 /* the train-dynamics model, its parameters included */
    int64_t next_ns;                 /* the next instant k * period */
    int64_t instants;
    /* the frame layer */
    int secured;
    rg_keyset keys;
    rg_receiver rx;
    rg_sender sender;
    rg_node_tx tx;
    int64_t frames_rx, rejected, frames_tx, demand_frames;
    int64_t last_demand_ns;          /* arrival of the newest accepted BrakeDemand (-1: none) */
    int64_t receiver_brake_ns;       /* the grid instant the model's alive timeout first braked (-1: never) */
} NetData;

#endif
