/* railguard train-dynamics FMU: identity, fixed step and the instance data.
 *
 * ModelData is plain data (no pointers): the parameters, the input, the outputs and the
 * internal state, including the sensor noise generators. The model itself is in
 * model.c; its equations, parameters and faults are described in docs/train_fmu.md.
 */
#ifndef RG_TRAIN_CONFIG_H
#define RG_TRAIN_CONFIG_H

#include <stdint.h>

#define MODEL_IDENTIFIER "railguard_train"
#define INSTANTIATION_TOKEN "{4b9cae65-a4cc-4688-ac28-c403b5610c64}"
#define FIXED_STEP 0.01 /* s: internal integration step */
#define TRAIN_STEP_NS INT64_C(10000000) /* the same in ns: the internal steps start at k * TRAIN_STEP_NS */

#define TRAIN_CHANNELS 6
/* longest brake dead time the demand buffer holds: 5 s in steps of FIXED_STEP */
#define TRAIN_MAX_DELAY_STEPS 500
#define TRAIN_RING_SIZE (TRAIN_MAX_DELAY_STEPS + 1)

/* what one sensor channel outputs (sample-and-hold between samples) */
typedef struct {
    int32_t status;       /* 0 ABSENT, 1 PRESENT, 2 DEGRADED */
    double distance;      /* m */
    double closing_speed; /* m/s, positive when closing */
    int32_t type;         /* 0 static, 1 dynamic, 2 train */
    int valid;            /* the channel is alive (false only under the silence fault) */
} TrainChannel;

/* The outputs that change continuously, at the FMU time: on the 10 ms grid the state
 * itself; between grid instants the state integrated from the last grid instant over
 * the part of the internal step done so far (model.c, model_do_step). */
typedef struct {
    double speed;
    double position;
    double acceleration;
    double true_distance;
    double brake_decel;
    double impact_speed;
    int32_t brake_level;
    int collided;
    int valid[TRAIN_CHANNELS];
} TrainView;

typedef struct {
    /* ---- parameters ---- */
    double initial_speed;   /* m/s, also the cruising speed */
    double mass;            /* kg */
    double davis_a;         /* N */
    double davis_b;         /* N.s/m */
    double davis_c;         /* N.s2/m2 */
    double gradient;        /* per mille, positive uphill */
    double max_traction;    /* m/s2 */
    double cruise_setting;  /* m/s, the cruise controller's target (the cruise_speed parameter); < 0: initial_speed */
    double service_decel;   /* m/s2 */
    double emergency_decel; /* m/s2, below emergency_band2_speed (or at every speed) */
    double emergency_band2_speed; /* m/s, 0: no band 2 */
    double emergency_band2_decel; /* m/s2 from emergency_band2_speed */
    double emergency_band3_speed; /* m/s, 0: no band 3 */
    double emergency_band3_decel; /* m/s2 from emergency_band3_speed */
    double brake_delay;     /* s */
    double brake_buildup;   /* s */
    double traction_cutoff; /* s after a demand; < 0: traction is cut when the brake level applies */
    double speed_error;     /* reported speed = true speed / (1 + speed_error) */
    int32_t track_condition;
    int32_t brake_status;
    double slippery_factor; /* brake decelerations x this while track_condition = 1 */
    double degraded_factor; /* brake decelerations x this while brake_status = 1 */
    int obstacle_present;
    double obstacle_position; /* m at t = 0 */
    double obstacle_speed;    /* m/s */
    int32_t obstacle_type;
    double obstacle_leave_time; /* s: off the track from then on (1e9: never) */
    double sensor_range;           /* m */
    double sensor_noise_sigma;     /* m */
    double sensor_miss_probability;
    double sensor_distance_bias;   /* m, added to every reported distance */
    double sensor_closing_bias;    /* m/s, added to every reported closing speed */
    double sensor_period;          /* s */
    int32_t sensor_seed;
    int32_t fault_kind;
    int32_t fault_channel;
    double fault_start; /* s */
    double fault_end;   /* s */
    double brake_timeout; /* s: the brake receiver's alive timeout on monitor_cycle; 0: no alive check */

    /* ---- inputs ---- */
    int32_t brake_demand;
    int32_t monitor_cycle; /* the monitor's alive counter (its cycle output), delivered with the demand */

    /* ---- outputs ---- */
    TrainChannel ch[TRAIN_CHANNELS];
    double speed;        /* true_speed, m/s (also the state); train.speed is the reported one */
    int32_t out_track_condition;
    int32_t out_brake_status;
    double position;     /* m (also the state) */
    double acceleration; /* m/s2 over the last internal step */
    double true_distance; /* m, 1e9 without an obstacle */
    int32_t brake_level; /* level in effect after the dead time */
    int collided;
    double impact_speed; /* m/s: our speed when the obstacle was reached (0: we stood) */
    int receiver_brake;  /* the brake receiver holds an emergency: monitor_cycle stopped (held to standstill) */

    /* ---- what the getters show: the continuous outputs at the FMU time ---- */
    TrainView view;

    /* ---- internal state ---- */
    int32_t cell_demand;  /* brake_demand as it was at the start of the current internal step */
    int32_t cell_cycle;   /* monitor_cycle, sampled with it */
    int32_t alive_cycle;  /* the newest monitor_cycle value seen ... */
    double alive_since;   /* s: ... and when it was first seen */
    double time;          /* s, = steps * FIXED_STEP */
    int64_t steps;        /* internal steps since t = 0 */
    int phase;            /* TRAIN_WAITING, TRAIN_RUNNING, TRAIN_STOPPED (model.c) */
    int seen_release;     /* brake_demand == 0 has been seen at least once */
    double cruise_speed;  /* m/s */
    double brake_decel;   /* m/s2, current brake deceleration (also the brake_decel output) */
    double brake_target;  /* m/s2, the target brake_decel had in the previous step */
    double demand_start;  /* s, when the brake demand last rose from 0 */
    int32_t last_demand;  /* demand (after the hand-over rule) of the previous step */
    int32_t delay_steps;  /* brake dead time in internal steps */
    int32_t ring_head;    /* index of the newest demand in ring[] */
    unsigned char ring[TRAIN_RING_SIZE]; /* demanded levels, one per internal step */
    int64_t next_sample;  /* index n of the next sensor sample, at n * sensor_period */
    double wreck_position; /* m, where the collision happened */
    uint64_t rng[TRAIN_CHANNELS]; /* one splitmix64 stream per channel */
} ModelData;

#endif
