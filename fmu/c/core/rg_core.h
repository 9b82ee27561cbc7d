/* railguard online core in C99: the same cycle as monitor/core (Python), bit for bit.
 *
 * freshness -> 2oo2 per module -> 3oo3 across modules -> braking curves (EBI, SBI,
 * warning) -> observation -> table -> demand (only ever upwards) -> emergency latch and
 * release. Integers only (DESIGN.md section 4): distance in dm, speed in cm/s,
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
} rg_config;

/* A table file's bytes, checked by rg_table_check before the first step. */
typedef struct {
    const uint8_t *bytes;
    uint32_t length;
    uint32_t action_offset;
    uint32_t next_offset;
    uint32_t nodes;
    uint32_t observations;
    uint32_t index_bytes;
    uint32_t start;
    int32_t model;        /* RG_MODEL_M1 or RG_MODEL_M2 */
    int32_t period_ms;    /* the time step the table was solved for */
} rg_table;

typedef struct {
    int32_t mode;
    int32_t node;
    int32_t latched;
    uint32_t seen;        /* bit i: channel i has been fresh at least once */
    int32_t disagree[RG_MAX_MODULES];
    int32_t healthy;
    int32_t cycle;
    int32_t error_cycles;
    int32_t calm;         /* cycles in a row without an emergency cause while one is held */
} rg_state;

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
} rg_outputs;

/* Python's braking.Curves: distances to the obstacle in dm, capped at RG_CURVE_CAP_DM */
typedef struct {
    int32_t ebd_dm;
    int32_t ebi_dm;
    int32_t sbi_dm;
    int32_t warning_dm;
} rg_curve_set;

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

/* The pieces, exposed for tests and for the proofs (issues 7 and 11). Each mirrors the
 * Python function of the same name: freshness.py, voter.py, braking.py (curves: the
 * EBD, EBI, SBI and warning distances at a measured speed; `service` nonzero: the service
 * brake's, the table's alpha1), envelope.py, config.py (emergency_bands,
 * gradient_accel_mms2). rg_age_ms is the age of a fresh report (Python: tick - r.tick),
 * capped at `limit`; rg_latch returns the new latched flag, with the new calm count and
 * the final demand in its out-parameters; rg_supervision_demand returns the demand, with
 * the warning in `*warning`. */
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
void rg_curves(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
               int32_t age_ms, int32_t service, rg_curve_set *out);
int32_t rg_zone(int32_t distance_dm, int32_t alpha1_dm, int32_t alpha2_dm, int32_t warning_dm);
int32_t rg_supervision_demand(int32_t present, int32_t distance_dm, int32_t ebi_dm, int32_t sbi_dm, int32_t warning_dm,
                              int32_t held, int32_t *warning);
int32_t rg_combine(int32_t table_demand, int32_t envelope, int32_t error_demand);
int32_t rg_latch(int32_t latched, int32_t calm, int32_t demand, int32_t speed_cms, int32_t revocable, int32_t confirm,
                 int32_t *calm_out, int32_t *final_demand);

#endif
