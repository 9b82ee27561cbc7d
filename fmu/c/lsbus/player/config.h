/* The frame player: a network node that sends a recorded frame schedule (resources/frames.txt)
 * on its CAN terminal at the recorded times, and watches one ID as a brake receiver does: no
 * frame of it within the timeout and it brakes (the receiver's fail-safe on silence). */
#ifndef RG_PLAYER_CONFIG_H
#define RG_PLAYER_CONFIG_H

#include <stdint.h>

#include "rg_lsbus_node.h"
#include "rg_network.h"
#include "build_info.h"

#define MODEL_IDENTIFIER railguard_player
#define PLAYER_MAX_FRAMES 40000

typedef struct {
    int64_t t_ns;
    uint32_t id;
    uint8_t fd, length;
    uint8_t data[64];
} player_frame;

typedef struct {
    char resources[RG_NET_STRING];
    /* parameters */
    int32_t bit_rate;
    int32_t watch_id;
    double watch_timeout;            /* s */
    /* schedule */
    player_frame frames[PLAYER_MAX_FRAMES];
    int32_t count, next;
    /* terminal */
    rg_node_tx tx;
    int configured;
    /* what it saw */
    int32_t rx_frames, rx_errors, confirmed;
    int32_t watch_frames;
    int64_t watch_last_ns;           /* -1: never */
    int64_t now_ns;
    int brake;                       /* latched: the watched ID fell silent once */
    double first_brake;              /* s, -1 none */
    double watch_max_gap;            /* s: the longest silence of the watched ID after its first frame */
} NetData;

#endif
