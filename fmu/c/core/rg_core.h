/* railguard online core in C99: the same cycle as monitor/core (Python), bit for bit.
 *
 * freshness -> 2oo2 per module -> 3oo3 across modules -> obstacle memory -> braking
 * curves (EBI, SBI, warning) for the nearer of the voted and the remembered obstacle ->
 * observation -> table (its demand held while its obstacle is in its zones) -> demand
 * (only ever upwards) -> hold and release. Integers only (DESIGN.md section 4): distance in dm, speed in cm/s,
 * deceleration in mm/s^2, time in ms ticks; 64-bit intermediates in the curves.
 * No allocation, no I/O, no clock, no floating point. docs/core.md documents the cycle,
 * the modes and the reason bits; docs/fmu.md the C side.
 */
#ifndef RG_CORE_H
#define RG_CORE_H

#include <stddef.h>
#include <stdint.h>

#define RG_MAX_MODULES 3
#define RG_MAX_CHANNELS 6

/* channel and module status: the maximum is the safe side */
#define RG_ABSENT 0
#define RG_PRESENT 1
#define RG_DEGRADED 2

/* demand levels (the table's action indices) */
#define RG_MAINTAIN 0
#define RG_SERVICE 1
#define RG_EMERGENCY 2

/* modes */
#define RG_INIT 0
#define RG_NORMAL 1
#define RG_DEGRADED_MODE 2
#define RG_SAFE_STOP 3

/* reason bits */
#define RG_R_TABLE (1 << 0)
#define RG_R_ENVELOPE (1 << 1)
#define RG_R_SYSTEM_ERROR (1 << 2)
#define RG_R_LATCH (1 << 3)
#define RG_R_INIT (1 << 4)
#define RG_R_SAFE_STOP (1 << 5)
#define RG_R_STALE (1 << 6)
#define RG_R_PERCEPTOR (1 << 7)
#define RG_R_DEADLINE (1 << 8)
#define RG_R_TRAIN_INPUT (1 << 9)
#define RG_R_SBI (1 << 10)
#define RG_R_WARNING (1 << 11)
#define RG_R_DISPUTE (1 << 12)
#define RG_R_MEMORY (1 << 13)
#define RG_R_IMPLAUSIBLE (1 << 14)

/* obstacle memory (monitor/core/memory.py): why the track is what it is this cycle */
#define RG_TRACK_NONE 0
#define RG_TRACK_SEEN 1
#define RG_TRACK_HELD 2
#define RG_TRACK_CONFIRMING 3
#define RG_TRACK_FORGOTTEN 4
#define RG_TRACK_PASSED 5
#define RG_NO_TRACK (-1)          /* no remembered obstacle */
#define RG_UNITS_PER_DM 10000     /* track positions in 1e-5 m (cm/s x ms) */
#define RG_MAX_TRACK (RG_MAX_DISTANCE_DM * RG_UNITS_PER_DM)   /* 6e8: fits int32 */
#define RG_TRACKS 3               /* remembered obstacles kept at once (monitor/core/tracks.py, TRACKS) */
/* where a voted obstacle lies against a remembered one (tracks.relation) */
#define RG_MEASURES 0             /* inside its window: the track measured again */
#define RG_AHEAD 1                /* nearer than it can be: another obstacle */
#define RG_BEYOND 2               /* farther than it can be (rg_seen_beyond): evidence that it is gone */

/* documented input ranges */
#define RG_MAX_DISTANCE_DM 60000
#define RG_MAX_CLOSING_CMS 15000
#define RG_MAX_SPEED_CMS 12000
#define RG_NO_DISTANCE 65535
#define RG_MAX_COUNT 2147483647

/* the braking declaration (monitor/core/config.py, braking.py) */
#define RG_RELEASE_AT_STANDSTILL 0
#define RG_RELEASE_REVOCABLE 1
#define RG_MIN_GUARANTEED_DECEL_MMS2 100
#define RG_CURVE_CAP_DM 1000000
#define RG_MAX_BANDS 3
#define RG_MAX_AGE_MS 60000  /* timeout_cycles x period_ms of an accepted configuration */

/* models */
#define RG_MODEL_M1 1
#define RG_MODEL_M2 2
#define RG_M1_OBSERVATIONS 4
#define RG_M2_OBSERVATIONS 144
#define RG_PPM 1000000u            /* the risk column's unit: parts per million */
#define RG_MAX_RISK_SCORE 20       /* seed 001 eq. 11 at its worst */

typedef struct {
    int32_t heard;        /* 0: never heard from (Python: None) */
    int32_t status;       /* ABSENT / PRESENT / DEGRADED; anything else counts as DEGRADED */
    int32_t distance_dm;
    int32_t closing_cms;  /* positive when closing */
    int32_t obstacle;     /* 0 static, 1 dynamic, 2 train */
    int64_t tick;         /* tick the report was received */
} rg_report;

typedef struct {
    int32_t speed_cms;
    int32_t track;        /* 0 normal, 1 slippery */
    int32_t brake;        /* 0 normal, 1 degraded */
} rg_train;

typedef struct {
    rg_report reports[RG_MAX_CHANNELS];
    rg_train train;
    int32_t overruns;     /* consecutive deadline overruns counted by the shell */
} rg_inputs;

typedef struct {
    int32_t period_ms;
    int32_t timeout_cycles;
    int32_t persistence_cycles;
    /* the train's braking declaration (guaranteed values) */
    int32_t emergency_decel_mms2;   /* speed band 1 (from 0) */
    int32_t emergency_band2_cms;    /* band 2 starts at this speed (0: no band 2) */
    int32_t emergency_band2_mms2;
    int32_t emergency_band3_cms;    /* band 3 starts at this speed (0: no band 3) */
    int32_t emergency_band3_mms2;
    int32_t service_decel_mms2;
    int32_t emergency_buildup_ms;
    int32_t service_buildup_ms;
    int32_t traction_cutoff_ms;
    int32_t max_accel_mms2;
    int32_t speed_error_permille;
    int32_t slippery_permille;
    int32_t degraded_permille;
    int32_t max_gradient_permille;
    int32_t standstill_margin_dm;
    /* supervision and response */
    int32_t warning_ms;
    int32_t emergency_release;      /* RG_RELEASE_REVOCABLE or RG_RELEASE_AT_STANDSTILL */
    int32_t release_confirm_cycles;
    /* Model 2 observation and voting */
    int32_t warning_margin_dm;
    int32_t fast_closing_cms;
    int32_t safe_reaction;
    int32_t modules;      /* 3: 3oo3 over three 2oo2 modules; 1: a single 2oo2 module */
    int32_t recovery_cycles;
    int32_t max_overruns;
    int32_t distance_tolerance_dm; /* 2oo2: PRESENT distances further apart raise the flag */
    /* obstacle memory */
    int32_t forget_ms;              /* fresh unanimous ABSENT this long forgets a remembered obstacle */
    int32_t sensor_range_dm;        /* absence counts as evidence only inside the sensors' declared range */
    int32_t forget_single_ms;       /* the same as forget_ms for an obstacle only one module ever saw */
    /* the sensors' declared accuracy: plausibility of a channel's reports */
    int32_t distance_accuracy_dm;   /* a reported distance is within this of the truth */
    int32_t closing_accuracy_cms;   /* a reported closing speed is within this of the truth */
    int32_t plausibility_ms;        /* an implausible channel is believed again after this long of plausible reports */
} rg_config;

/* One channel's plausibility (monitor/core/plausibility.py): the reference report, the least
 * and the most the obstacle ran since (1e-5 m, from the reported closing speeds), and `bad`
 * while the channel is implausible. ref_dm == RG_NO_TRACK: no reference (not PRESENT). */
typedef struct {
    int32_t ref_dm;
    int32_t last_closing;
    int32_t bad;
    int64_t ref_tick;
    int64_t last_tick;
    int64_t lo;
    int64_t hi;
} rg_plaus;

/* A table file's bytes, checked by rg_table_check before the first step. */
typedef struct {
    const uint8_t *bytes;
    uint32_t length;
    uint32_t action_offset;
    uint32_t next_offset;
    uint32_t risk_offset; /* u32 per node: P(hazard within the horizon | node), ppm */
    uint32_t nodes;
    uint32_t observations;
    uint32_t index_bytes;
    uint32_t start;
    int32_t model;        /* RG_MODEL_M1 or RG_MODEL_M2 */
    int32_t period_ms;    /* the time step the table was solved for */
} rg_table;

/* One remembered obstacle (monitor/core/types.py's Track), positions in 1e-5 m (cm/s x ms). */
typedef struct {
    int32_t near;         /* worst case (nearest); RG_NO_TRACK: the slot is empty */
    int32_t far;          /* the remembered position less the train's least travel (< 0: passed) */
    int32_t closing;      /* its own speed towards the train, cm/s (>= 0) */
    int32_t cycles;       /* cycles since it was last voted */
    int32_t absent;       /* cycles in a row of positive evidence that it is gone */
    int32_t strong;       /* confirmed or seen by two modules at once: forget_ms, not forget_single_ms */
} rg_track_slot;

typedef struct {
    int32_t mode;
    int32_t node;
    int32_t held;         /* the demand level held (0 none, 1 service, 2 emergency) */
    uint32_t seen;        /* bit i: channel i has been fresh at least once */
    int32_t disagree[RG_MAX_MODULES];  /* disagreement cycles not yet cleared by a calm spell */
    int32_t healthy;
    int32_t cycle;
    int32_t error_cycles;
    int32_t calm;         /* cycles in a row in which the held demand could have been lowered */
    int32_t agree[RG_MAX_MODULES];     /* cycles in a row without disagreement (clear `disagree`) */
    int32_t table_held;   /* the table's demand, held while its obstacle is in the table's zones */
    rg_track_slot tracks[RG_TRACKS];  /* the remembered obstacles: nearest first, empty slots last */
    int32_t kept;           /* an obstacle in sight and closing keeps what is held (keep_held) */
    rg_plaus plaus[RG_MAX_CHANNELS];  /* per channel: plausibility of its reports over time */
} rg_state;

/* A remembered obstacle as rg_observe updates it (from a slot of rg_state.tracks), with the
 * age of the report its position came from this cycle. */
typedef struct {
    int32_t near;
    int32_t far;
    int32_t closing_cms;
    int32_t age_ms;
} rg_track;

typedef struct {
    int32_t demand;
    int32_t reasons;
    int32_t distance_dm;
    int32_t node;
    int32_t mode;
    int32_t module_flags;
    int32_t system_error;
    int32_t observation;
    int32_t cycle;
    int32_t error_cycles;
    int32_t warning;      /* obstacle inside the warning curve, or disputed */
    int32_t track_dm;     /* remembered obstacle's predicted (worst-case) distance; RG_NO_DISTANCE if none */
    int32_t track_cycles; /* cycles since the remembered obstacle was last voted */
    int32_t track_state;  /* RG_TRACK_NONE / SEEN / HELD / CONFIRMING / FORGOTTEN / PASSED */
    int32_t r1_ppm;       /* seed 000 eq. 16 at the nearest obstacle (monitor/core/risk.py) */
    int32_t r2_ppm;       /* seed 000 eq. 17 */
    int32_t risk_score;   /* seed 001 eq. 11, rho (0..20) */
    int32_t risk_category; /* 1 low, 2 moderate, 3 high, 4 critical */
    int32_t table_risk_ppm; /* the table's risk column at the node: P(hazard within 30 s | node) */
} rg_outputs;

/* Python's braking.Curves: distances to the obstacle in dm, capped at RG_CURVE_CAP_DM */
typedef struct {
    int32_t ebd_dm;
    int32_t ebi_dm;
    int32_t sbi_dm;
    int32_t warning_dm;
} rg_curve_set;

/* what rg_decide decides in a cycle, before INIT's emergency */
typedef struct {
    int32_t env;          /* the curves' demand for the supervised obstacle */
    int32_t warning;      /* the curves' warning for it */
    int32_t demand;       /* max(table, curves, error rules) */
    int32_t calm;         /* the hold's new calm count */
    int32_t final_demand; /* after the hold: the new held level */
} rg_decision;

/* one speed band of a brake: from this speed up, this deceleration */
typedef struct {
    int64_t from_cms;
    int64_t decel_mms2;
} rg_band;

/* The defaults of monitor/core/config.py. */
void rg_config_default(rg_config *cfg);

/* 0 if the configuration can be used, else nonzero with `msg` naming the bad value. */
int rg_config_check(const rg_config *cfg, char *msg, size_t len);

/* 0 if the table's bytes are intact (magic, version, SHA-256, dimensions, every action
 * and next-node index in range) and fit the configuration's period; else nonzero with
 * `msg` saying what is wrong. */
int rg_table_check(const rg_table *table, const rg_config *cfg, char *msg, size_t len);

void rg_initial_state(const rg_table *table, const rg_config *cfg, rg_state *state);

/* One cycle at `tick`. Total: every input value gives a state and outputs. */
void rg_step(const rg_config *cfg, const rg_table *table, rg_state *state,
             const rg_inputs *inputs, int64_t tick, rg_outputs *out);

/* The pieces, exposed for tests and for the proofs (issues 7, 11 and 29). Each mirrors the
 * Python function of the same name: freshness.py, voter.py, braking.py (curves: the
 * EBD, EBI, SBI and warning distances at a measured speed; `service` nonzero: the service
 * brake's, the table's alpha1), envelope.py, memory.py, config.py (emergency_bands,
 * gradient_accel_mms2). rg_age_ms is the age of a fresh report (Python: tick - r.tick),
 * capped at `limit`; rg_hold returns the new held level, with the new calm count and
 * the final demand in its out-parameters; rg_supervision_demand returns the demand, with
 * the warning in `*warning`; rg_supervised_demand is cycle.py's supervision of the voted
 * and the remembered obstacle (each on its own curves, the higher demand);
 * rg_decide is the cycle's decision: that demand, combined with the table's and the error
 * rules' and then held (returns the new held level, the rest in `*d`);
 * rg_observe updates `*track` in place (Python returns the new tuple); rg_forget takes
 * the track's least position and the sensor range (Python: in_range and passed, computed
 * from them in cycle.py), returns the evidence count and writes the track state;
 * rg_track_dm is memory.distance_dm. */
int32_t rg_seen_beyond(int32_t near, int32_t far, int32_t distance_dm, int32_t accuracy_dm);
void rg_plaus_anchor(rg_plaus *p, int32_t distance_dm, int32_t closing_cms, int64_t tick, int32_t bad);
int32_t rg_plaus_continues(const rg_plaus *p, int64_t tick, int32_t window_ms);
void rg_plausibility(rg_plaus *p, int32_t present, int32_t distance_dm, int32_t closing_cms, int64_t tick,
                     int32_t accuracy_dm, int32_t accuracy_cms, int32_t window_ms);
int32_t rg_in_range(int32_t status, int32_t distance_dm, int32_t closing_cms, int32_t obstacle);
int32_t rg_is_fresh(int64_t received, int64_t now, int64_t timeout_ticks);
int32_t rg_effective_status(const rg_report *r, int64_t now, int64_t timeout_ticks);
void rg_vote_2oo2(int32_t sa, int32_t da, int32_t sb, int32_t db,
                  int32_t *status, int32_t *distance, int32_t *flag);
int32_t rg_disagreement(int32_t sa, int32_t sb);
int32_t rg_distances_disagree(int32_t sa, int32_t da, int32_t sb, int32_t db, int32_t tolerance_dm);
void rg_vote_3oo3(const int32_t s[3], const int32_t d[3], const int32_t f[3],
                  int32_t *status, int32_t *distance, int32_t *error);
int32_t rg_age_ms(int64_t received, int64_t now, int64_t limit);
int32_t rg_gradient_accel_mms2(int32_t gradient_permille);
int32_t rg_emergency_bands(const rg_config *cfg, rg_band bands[RG_MAX_BANDS]);
int64_t rg_scaled_decel_mms2(int64_t decel_mms2, int64_t factor_permille);
int64_t rg_effective_decel_mms2(int64_t decel_mms2, int32_t track, int32_t brake, int64_t slippery_permille,
                                int64_t degraded_permille, int64_t gradient_mms2);
int64_t rg_run_dm(int64_t speed_cms, int64_t accel_mms2, int64_t time_ms);
int64_t rg_speed_after_cms(int64_t speed_cms, int64_t accel_mms2, int64_t time_ms);
void rg_band_stop(int64_t speed_cms, int64_t lo_cms, int64_t hi_cms, int64_t decel_mms2, int64_t *dist_dm,
                  int64_t *time_ms);
void rg_stop_dm_ms(int64_t speed_cms, const rg_band *bands, int32_t count, int64_t *dist_dm, int64_t *time_ms);
int64_t rg_obstacle_run_dm(int64_t obstacle_cms, int64_t time_ms);
int32_t rg_cap_dm(int64_t x);
/* Periods in EBI's reaction phase (braking.SUPERVISED_PERIODS, ZONE_PERIODS): the supervision
 * counts the worse of a running monitor (the sampling period and the demand's) and a stalled
 * one (its last frame's period and the brakes' receiver timeout, 3 periods); the table's zone
 * limits the demand's only. rg_curves(..., supervised, ...): 1 the supervised curves
 * (braking.curves: RG_SUPERVISED_PERIODS and the sensors' error budget), 0 a zone limit
 * (braking.ebi_dm: RG_ZONE_PERIODS, no budget). */
#define RG_SUPERVISED_PERIODS 4
#define RG_ZONE_PERIODS 1
void rg_curves(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
               int32_t age_ms, int32_t service, int32_t supervised, rg_curve_set *out);
int32_t rg_zone(int32_t distance_dm, int32_t alpha1_dm, int32_t alpha2_dm, int32_t warning_dm);
int32_t rg_supervision_demand(int32_t present, int32_t distance_dm, int32_t ebi_dm, int32_t sbi_dm, int32_t warning_dm,
                              int32_t held, int32_t *warning);
int32_t rg_combine(int32_t table_demand, int32_t envelope, int32_t error_demand);
int32_t rg_hold(int32_t level, int32_t calm, int32_t demand, int32_t speed_cms, int32_t revocable, int32_t confirm,
                int32_t *calm_out, int32_t *final_demand);
int32_t rg_table_hold(int32_t level, int32_t demand, int32_t speed_cms, int32_t zone_free);

/* The papers' risk estimators in ppm (monitor/core/risk.py, bit for bit). */
int32_t rg_r1_ppm(int32_t distance_dm, int32_t alpha1_dm);
int32_t rg_r2_ppm(int32_t distance_dm, int32_t alpha1_dm, int32_t alpha2_dm);
int32_t rg_risk_score(int32_t zone, int32_t speed, int32_t obstacle, int32_t track, int32_t brake);
int32_t rg_risk_category(int32_t score);
int32_t rg_supervised_demand(int32_t voted_dm, int32_t voted_ebi_dm, int32_t voted_sbi_dm, int32_t voted_warning_dm,
                             int32_t remembered, int32_t track_dm, int32_t track_ebi_dm, int32_t track_sbi_dm,
                             int32_t track_warning_dm, int32_t held, int32_t *warning);
int64_t rg_accel_run(int64_t accel_mms2, int64_t period_ms);
int64_t rg_near_travel(int64_t speed_cms, int64_t error_permille, int64_t accel_mms2, int64_t obstacle_cms,
                       int64_t period_ms);
int64_t rg_far_travel(int64_t speed_cms, int64_t error_permille, int64_t accel_mms2, int64_t period_ms);
void rg_observe(rg_track *track, int32_t distance_dm, int32_t obstacle_cms, int32_t age_now, int32_t confirmed,
                int32_t sighted);
int32_t rg_forget(int32_t cycles_absent, int32_t evidence, int64_t far, int32_t range_dm, int32_t forget_cycles,
                  int32_t *state);
int32_t rg_track_dm(int32_t near);
int32_t rg_forget_cycles(const rg_config *cfg, int32_t single);

/* Several remembered obstacles (monitor/core/tracks.py), each mirroring the Python function
 * of the same name: rg_relation; rg_assign returns the slot and writes `create`; rg_absorbed
 * is absorbed's test for one slot `j` (whether j is among the slots it returns); rg_merge
 * writes the merged slot to `*out`; rg_ordered orders the RG_TRACKS slots in place, carrying
 * each slot's age and state along, by exchanges (rg_order_pair: one exchange of its stable
 * insertion sort); rg_insert updates the arrays in place and returns the slot `fresh` went
 * to (-1: none was empty, so the two farthest of the held ones and `fresh` merged into the
 * last slot: rg_insert_full, insert's second half). */
int32_t rg_relation(int32_t near, int32_t far, int32_t distance_dm, int32_t accuracy_dm);
int32_t rg_assign(const rg_track_slot tracks[RG_TRACKS], int32_t distance_dm, int32_t accuracy_dm, int32_t creates,
                  int32_t *create);
int32_t rg_absorbed(const rg_track_slot *track, int32_t slot, int32_t j, int32_t distance_dm, int32_t accuracy_dm);
void rg_merge(const rg_track_slot *a, const rg_track_slot *b, rg_track_slot *out);
void rg_order_pair(rg_track_slot *tracks, int32_t *ages, int32_t *states, int32_t i);
void rg_ordered(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS]);
void rg_insert_full(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS],
                    const rg_track_slot *fresh, int32_t age, int32_t state);
int32_t rg_insert(rg_track_slot tracks[RG_TRACKS], int32_t ages[RG_TRACKS], int32_t states[RG_TRACKS],
                  const rg_track_slot *fresh, int32_t age, int32_t state);
/* One remembered obstacle's demand on its own curves (rg_supervision_demand), its warning in
 * `*warn`: rg_step supervises, through rg_decide, the remembered obstacle that demands most. */
int32_t rg_remembered_demand(int32_t track_dm, const rg_curve_set *curve, int32_t held, int32_t *warn);

#endif
