/* railguard train-dynamics FMU: the plant around the monitor.
 *
 * One train on a straight track, longitudinal dynamics with Davis resistance, gradient,
 * traction (held for a while after a brake demand, if asked) and brakes with a dead time,
 * a linear build-up, speed bands and adhesion factors; one obstacle (static, moving away
 * or oncoming); six sensor channels with Gaussian noise, misses and injectable faults.
 * It is the world the monitor's braking declaration must cover, so it can brake worse
 * than nominal in every way the declaration allows.
 * Fixed internal step FIXED_STEP (10 ms). Doubles throughout: this is the plant, not the
 * deterministic monitor core. Equations, parameters and faults: docs/train_fmu.md.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "variables.h"

#define G_ACCEL 9.81            /* m/s2 */
#define NO_OBSTACLE_DISTANCE 1e9 /* m: true_distance when there is no obstacle */
#define HANDOVER_TIME 1.0       /* s: demands are ignored before this unless released once */
#define SPEED_GAIN 1.0          /* 1/s: proportional gain of the cruise controller */
#define NOISE_BURST_FACTOR 50.0 /* fault 3 multiplies the noise sigma by this */
#define GHOST_DISTANCE 50.0     /* m: what fault 7 reports when nothing is visible */
#define SAMPLE_EPS 1e-9         /* s: tolerance when comparing step and sample times */

enum { TRAIN_WAITING = 0, TRAIN_RUNNING = 1, TRAIN_STOPPED = 2 };

enum {
    FAULT_NONE = 0,
    FAULT_SILENCE = 1,
    FAULT_STUCK = 2,
    FAULT_NOISE_BURST = 3,
    FAULT_MISSED = 4,
    FAULT_DEGRADED = 5,
    FAULT_NAN_DISTANCE = 6,
    FAULT_CONTRADICTION = 7,
    FAULT_BLIND = 8 /* every channel misses at once: a common cause (glare, spray) */
};

/* The channel getters below rely on the five channel variables being consecutive. */
typedef char rg_check_channel_layout[(vr_ch2_status - vr_ch1_status == 5 &&
                                      vr_ch6_valid - vr_ch1_status == 29) ? 1 : -1];

/* ------------------------------------------------------------------ PRNG */

/* splitmix64: one 64-bit state per channel, advanced by a fixed odd increment and
 * scrambled on output. */
static uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    return z ^ (z >> 31);
}

static uint64_t next_u64(uint64_t *state)
{
    *state += UINT64_C(0x9E3779B97F4A7C15);
    return mix64(*state);
}

/* uniform in [0, 1), 53 random bits */
static double next_uniform(uint64_t *state)
{
    return (double)(next_u64(state) >> 11) * (1.0 / 9007199254740992.0);
}

/* standard normal by Box-Muller (two uniforms per draw, the second normal is dropped) */
static double next_gaussian(uint64_t *state)
{
    const double two_pi = 6.283185307179586476925286766559;
    double u1 = 1.0 - next_uniform(state); /* (0, 1]: log is finite */
    double u2 = next_uniform(state);
    return sqrt(-2.0 * log(u1)) * cos(two_pi * u2);
}

static void seed_channels(ModelData *m)
{
    uint64_t base = mix64((uint64_t)(uint32_t)m->sensor_seed ^ UINT64_C(0x5241494C47554152));
    int c;
    for (c = 0; c < TRAIN_CHANNELS; c++) {
        m->rng[c] = mix64(base + (uint64_t)(c + 1) * UINT64_C(0xD1B54A32D192ED03));
    }
}

/* ------------------------------------------------------------------ helpers */

static int demand_level(int32_t d)
{
    if (d == 0) return 0;
    if (d == 1) return 1;
    return 2; /* emergency, and anything out of range */
}

/* the brake decelerations actually achieved, under the reported conditions */
static double condition_factor(const ModelData *m)
{
    return (m->track_condition ? m->slippery_factor : 1.0) * (m->brake_status ? m->degraded_factor : 1.0);
}

static double emergency_at(const ModelData *m, double v)
{
    double a = m->emergency_decel;
    if (m->emergency_band2_speed > 0.0 && v >= m->emergency_band2_speed) a = m->emergency_band2_decel;
    if (m->emergency_band3_speed > 0.0 && v >= m->emergency_band3_speed) a = m->emergency_band3_decel;
    return a * condition_factor(m);
}

static double level_decel(const ModelData *m, int level, double v)
{
    if (level == 0) return 0.0;
    if (level == 1) return m->service_decel * condition_factor(m);
    return emergency_at(m, v);
}

static double resistance_acc(const ModelData *m, double v)
{
    return (m->davis_a + m->davis_b * v + m->davis_c * v * v) / m->mass;
}

static double grade_acc(const ModelData *m)
{
    return G_ACCEL * m->gradient / 1000.0;
}

static int fault_active(const ModelData *m, int channel, double t)
{
    return m->fault_kind != FAULT_NONE && (m->fault_channel == channel + 1 || m->fault_kind == FAULT_BLIND) &&
           t >= m->fault_start && t < m->fault_end;
}

/* Our speed at the moment the gap closed, in a step that began with gap d0 > 0, speed v
 * and acceleration a held until t_move (the train stands after that), while the obstacle
 * moves at u: the first root of d0 - (v - u) s - a s^2 / 2 = 0. 0 if the gap closed only
 * after the train stood (an oncoming obstacle reached a standing train). */
static double contact_speed(double d0, double v, double a, double t_move, double u)
{
    const double w = v - u;
    const double disc = w * w + 2.0 * a * d0;
    double s;
    if (d0 <= 0.0) return v;
    if (disc < 0.0 || w + sqrt(disc) <= 0.0) return 0.0;
    s = 2.0 * d0 / (w + sqrt(disc));
    if (s > t_move) return 0.0;
    return (v + a * s > 0.0) ? v + a * s : 0.0;
}

/* the obstacle is on the track at the current time: present and not yet left */
static int obstacle_there(const ModelData *m)
{
    return m->obstacle_present && m->time < m->obstacle_leave_time;
}

/* true distance at the current time; also detects the collision (returns 1 on contact).
 * A wreck stays where it is; an obstacle that has left is as none. */
static int update_distance(ModelData *m)
{
    double obstacle;
    if (m->collided) {
        m->true_distance = 0.0;
        return 0;
    }
    if (!obstacle_there(m)) {
        m->true_distance = NO_OBSTACLE_DISTANCE;
        return 0;
    }
    obstacle = m->obstacle_position + m->obstacle_speed * m->time;
    m->true_distance = obstacle - m->position;
    if (m->true_distance <= 0.0) {
        /* collision: the train stops at the obstacle and both stay there */
        m->collided = 1;
        m->position = obstacle;
        m->wreck_position = obstacle;
        m->speed = 0.0;
        m->acceleration = 0.0;
        m->true_distance = 0.0;
        return 1;
    }
    return 0;
}

static void update_valid(ModelData *m)
{
    int c;
    for (c = 0; c < TRAIN_CHANNELS; c++) {
        m->ch[c].valid = !(m->fault_kind == FAULT_SILENCE && fault_active(m, c, m->time));
    }
}

/* one sensor sample of every channel at the current time */
static void sample_sensors(ModelData *m)
{
    const int visible = obstacle_there(m) && m->true_distance > 0.0 &&
                        m->true_distance <= m->sensor_range;
    const double closing = m->speed - m->obstacle_speed + m->sensor_closing_bias;
    int c;
    for (c = 0; c < TRAIN_CHANNELS; c++) {
        TrainChannel *ch = &m->ch[c];
        const int faulty = fault_active(m, c, m->time);
        const int kind = faulty ? m->fault_kind : FAULT_NONE;
        double sigma = m->sensor_noise_sigma;
        /* every channel draws the same numbers every sample, seen or not, faulty or not,
         * so a channel's noise does not depend on what happened before */
        const double u_miss = next_uniform(&m->rng[c]);
        const double noise = next_gaussian(&m->rng[c]);
        int seen = visible && !(u_miss < m->sensor_miss_probability);

        if (kind == FAULT_SILENCE || kind == FAULT_STUCK) {
            continue; /* outputs frozen at their last values */
        }
        if (kind == FAULT_NOISE_BURST) sigma *= NOISE_BURST_FACTOR;
        if (kind == FAULT_MISSED || kind == FAULT_BLIND) seen = 0;

        if (kind == FAULT_CONTRADICTION) {
            if (visible) {
                seen = 0; /* reports ABSENT although something is there */
            } else {
                ch->status = 1; /* reports a ghost */
                ch->distance = GHOST_DISTANCE;
                ch->closing_speed = m->speed;
                ch->type = 0;
                continue;
            }
        }

        if (seen) {
            double d = m->true_distance + m->sensor_distance_bias + sigma * noise;
            ch->status = 1;
            ch->distance = d > 0.0 ? d : 0.0;
            ch->closing_speed = closing;
            ch->type = m->obstacle_type;
        } else {
            ch->status = 0;
            ch->distance = 0.0;
            ch->closing_speed = 0.0;
            ch->type = 0;
        }
        if (kind == FAULT_DEGRADED) ch->status = 2;
        if (kind == FAULT_NAN_DISTANCE) {
            ch->status = 1;
            ch->distance = NAN;
            if (!seen) {
                ch->closing_speed = obstacle_there(m) ? closing : m->speed;
                ch->type = obstacle_there(m) ? m->obstacle_type : 0;
            }
        }
    }
}

/* sample the sensors if a sample time n * period has been reached */
static void maybe_sample(ModelData *m)
{
    int due = 0;
    while ((double)m->next_sample * m->sensor_period <= m->time + SAMPLE_EPS) {
        due = 1;
        m->next_sample++;
    }
    if (due) sample_sensors(m);
}

/* ------------------------------------------------------------------ one internal step */

/* brake deceleration: towards the target of the level in effect at the build-up rate
 * (full emergency deceleration over brake_buildup); once built, it follows the target
 * as the speed crosses a band */
static void update_brake(ModelData *m, int level, int previous_level, double v, double dt)
{
    const double target = level_decel(m, level, v);
    if (m->brake_buildup <= 0.0 || (level == previous_level && m->brake_decel == m->brake_target)) {
        m->brake_decel = target;
    } else {
        const double ramp = emergency_at(m, v) / m->brake_buildup * dt;
        if (m->brake_decel < target) {
            m->brake_decel = (m->brake_decel + ramp < target) ? m->brake_decel + ramp : target;
        } else if (m->brake_decel > target) {
            m->brake_decel = (m->brake_decel - ramp > target) ? m->brake_decel - ramp : target;
        }
    }
    m->brake_target = target;
}

/* traction acceleration: the cruise controller (feed-forward of resistance and gradient
 * plus a proportional term, in [0, max_traction]) while no brake applies; with
 * traction_cutoff >= 0, full traction for traction_cutoff after a brake demand (the
 * demand found the train accelerating), then none until the demand is gone */
static double traction_acc(const ModelData *m, int demand, int level, double t, double v)
{
    double traction;
    if (m->phase != TRAIN_RUNNING || m->cruise_speed <= 0.0) return 0.0;
    if (m->traction_cutoff >= 0.0 && demand > 0) {
        return (t - m->demand_start < m->traction_cutoff - SAMPLE_EPS) ? m->max_traction : 0.0;
    }
    if (level != 0) return 0.0;
    traction = resistance_acc(m, v) + grade_acc(m) + SPEED_GAIN * (m->cruise_speed - v);
    if (traction < 0.0) traction = 0.0;
    if (traction > m->max_traction) traction = m->max_traction;
    return traction;
}

/* The brake receiver (issue 39 item 3): the monitor's cycle counter comes with its demand;
 * once it has not changed for brake_timeout after the hand-over (a monitor FMU
 * that froze, crashed or is no longer stepped; off with brake_timeout = 0), or the demand is
 * a level no monitor sends (not 0..2), the receiver demands emergency and holds it until the
 * train stands (and the counter moves again). */
static int alive_lost(ModelData *m, double t, double v)
{
    const int unknown = m->cell_demand < 0 || m->cell_demand > 2;
    if (m->cell_cycle != m->alive_cycle) {
        m->alive_cycle = m->cell_cycle;
        m->alive_since = t;
    }
    if ((m->brake_timeout > 0.0 && t >= HANDOVER_TIME - SAMPLE_EPS &&
         t - m->alive_since >= m->brake_timeout - SAMPLE_EPS) || (unknown && t >= HANDOVER_TIME - SAMPLE_EPS))
        m->receiver_brake = 1;
    else if (m->receiver_brake && v <= 0.0)
        m->receiver_brake = 0; /* held to standstill, and the counter moves again */
    return m->receiver_brake;
}

/* One internal step of `dt` seconds from m->time, ending at `t_end`: a whole step of the
 * grid (dt = FIXED_STEP), or the first part of one (model_do_step's preview). The demand is
 * the one sampled at the start of the step (cell_demand). */
static void internal_step(ModelData *m, double dt, double t_end)
{
    const double t = m->time;
    const int raw = demand_level(m->cell_demand);
    const int previous_level = m->brake_level;
    const double d0 = m->true_distance;
    int demand, level;
    double traction, v = m->speed, a, v_new, dx, t_move = dt, impact;

    /* demands: ignored while entering the monitored section (hand-over) */
    if (raw == 0) m->seen_release = 1;
    if (m->phase == TRAIN_WAITING && raw == 0) m->phase = TRAIN_RUNNING;
    demand = (m->seen_release || t >= HANDOVER_TIME - SAMPLE_EPS) ? raw : 0;
    if (alive_lost(m, t, v)) demand = 2;
    if (demand > 0 && m->last_demand == 0) m->demand_start = t;
    m->last_demand = demand;

    /* dead time: the level in effect is the demand of delay_steps steps ago */
    m->ring_head = (m->ring_head + 1) % TRAIN_RING_SIZE;
    m->ring[m->ring_head] = (unsigned char)demand;
    level = m->ring[(m->ring_head + TRAIN_RING_SIZE - m->delay_steps) % TRAIN_RING_SIZE];
    m->brake_level = level;
    update_brake(m, level, previous_level, v, dt);

    m->time = t_end;

    if (m->collided) {
        m->speed = 0.0;
        m->acceleration = 0.0;
        m->position = m->wreck_position;
        update_distance(m);
        return;
    }

    traction = traction_acc(m, demand, level, t, v);
    if (v > 0.0) {
        a = traction - resistance_acc(m, v) - grade_acc(m) - m->brake_decel;
        v_new = v + a * dt;
        if (v_new <= 0.0) {
            /* stops within the step: integrate up to the standstill only */
            const double t_stop = (a < 0.0) ? v / -a : dt;
            t_move = t_stop < dt ? t_stop : dt;
            dx = 0.5 * v * t_move;
            v_new = 0.0;
            if (m->phase == TRAIN_RUNNING && (level > 0 || m->brake_decel > 0.0)) {
                m->phase = TRAIN_STOPPED; /* waits for clearance for the rest of the run */
            }
        } else {
            dx = 0.5 * (v + v_new) * dt;
        }
    } else {
        /* at standstill: resistance and brakes hold the train; it moves off only if the
         * traction beats them, and never rolls back */
        a = 0.0;
        if (traction > 0.0) {
            a = traction - resistance_acc(m, 0.0) - grade_acc(m) - m->brake_decel;
            if (a < 0.0) a = 0.0;
        }
        v_new = a * dt;
        dx = 0.5 * v_new * dt;
    }

    impact = contact_speed(d0, v, a, t_move, m->obstacle_speed);
    m->speed = v_new;
    m->position += dx;
    m->acceleration = a;
    if (update_distance(m)) m->impact_speed = impact;
}

/* the continuous outputs of state `src` become what `m` shows */
static void set_view(ModelData *m, const ModelData *src)
{
    int c;
    m->view.speed = src->speed;
    m->view.position = src->position;
    m->view.acceleration = src->acceleration;
    m->view.true_distance = src->true_distance;
    m->view.brake_decel = src->brake_decel;
    m->view.impact_speed = src->impact_speed;
    m->view.brake_level = src->brake_level;
    m->view.collided = src->collided;
    for (c = 0; c < TRAIN_CHANNELS; c++) m->view.valid[c] = src->ch[c].valid;
}

/* ------------------------------------------------------------------ FMI-facing functions */

void model_set_start_values(ModelData *m)
{
    memset(m, 0, sizeof *m);
    m->initial_speed = 20.0;
    m->mass = 400000.0;
    m->davis_a = 6000.0;
    m->davis_b = 100.0;
    m->davis_c = 8.0;
    m->gradient = 0.0;
    m->max_traction = 0.5;
    m->cruise_setting = -1.0;
    m->service_decel = 1.0;
    m->emergency_decel = 3.0;
    m->emergency_band2_speed = 0.0;
    m->emergency_band2_decel = 0.0;
    m->emergency_band3_speed = 0.0;
    m->emergency_band3_decel = 0.0;
    m->brake_delay = 0.2;
    m->brake_buildup = 0.5;
    m->traction_cutoff = -1.0;
    m->speed_error = 0.0;
    m->track_condition = 0;
    m->brake_status = 0;
    m->slippery_factor = 1.0;
    m->degraded_factor = 1.0;
    m->obstacle_present = 1;
    m->obstacle_position = 500.0;
    m->obstacle_speed = 0.0;
    m->obstacle_type = 0;
    m->obstacle_leave_time = 1e9;
    m->sensor_range = 400.0;
    m->sensor_noise_sigma = 0.3;
    m->sensor_miss_probability = 0.0;
    m->sensor_distance_bias = 0.0;
    m->sensor_closing_bias = 0.0;
    m->sensor_period = 0.1;
    m->sensor_seed = 1;
    m->fault_kind = 0;
    m->fault_channel = 1;
    m->fault_start = 0.0;
    m->fault_end = 1e9;
    m->brake_timeout = 0.3;

    m->brake_demand = 0;
    m->monitor_cycle = 0;

    /* outputs before initialisation: the state at t = 0 without a sensor sample */
    m->speed = m->initial_speed;
    m->position = 0.0;
    m->true_distance = m->obstacle_position;
    m->phase = TRAIN_RUNNING;
    set_view(m, m);
}

static int bad_nonneg(double x)
{
    return !isfinite(x) || x < 0.0;
}

#define FAIL(...) do { snprintf(msg, len, __VA_ARGS__); return RG_ERROR; } while (0)

int model_initialize(ModelData *m, char *msg, size_t len)
{
    int c;

    if (msg != NULL && len > 0) msg[0] = '\0';
    if (msg == NULL) len = 0;

    if (!isfinite(m->initial_speed) || m->initial_speed < 0.0 || m->initial_speed > 120.0)
        FAIL("initial_speed = %g: must be in [0, 120] m/s", m->initial_speed);
    if (!isfinite(m->mass) || m->mass <= 0.0)
        FAIL("mass = %g: must be a finite value > 0 kg", m->mass);
    if (bad_nonneg(m->davis_a)) FAIL("davis_a = %g: must be finite and >= 0", m->davis_a);
    if (bad_nonneg(m->davis_b)) FAIL("davis_b = %g: must be finite and >= 0", m->davis_b);
    if (bad_nonneg(m->davis_c)) FAIL("davis_c = %g: must be finite and >= 0", m->davis_c);
    if (!isfinite(m->gradient) || m->gradient < -60.0 || m->gradient > 60.0)
        FAIL("gradient = %g: must be in [-60, 60] per mille", m->gradient);
    if (isnan(m->cruise_setting) || m->cruise_setting > 120.0)
        FAIL("cruise_speed = %g: must be <= 120 m/s (negative: initial_speed)", m->cruise_setting);
    if (bad_nonneg(m->max_traction))
        FAIL("max_traction = %g: must be finite and >= 0", m->max_traction);
    if (bad_nonneg(m->service_decel))
        FAIL("service_decel = %g: must be finite and >= 0", m->service_decel);
    if (bad_nonneg(m->emergency_decel))
        FAIL("emergency_decel = %g: must be finite and >= 0", m->emergency_decel);
    if (m->emergency_decel < m->service_decel)
        FAIL("emergency_decel = %g: must be >= service_decel = %g", m->emergency_decel,
             m->service_decel);
    if (bad_nonneg(m->emergency_band2_speed))
        FAIL("emergency_band2_speed = %g: must be finite and >= 0 (0: no band)", m->emergency_band2_speed);
    if (bad_nonneg(m->emergency_band3_speed))
        FAIL("emergency_band3_speed = %g: must be finite and >= 0 (0: no band)", m->emergency_band3_speed);
    if (m->emergency_band3_speed > 0.0 && !(m->emergency_band2_speed > 0.0 &&
                                             m->emergency_band3_speed > m->emergency_band2_speed))
        FAIL("emergency_band3_speed = %g: needs band 2 and must be above emergency_band2_speed = %g",
             m->emergency_band3_speed, m->emergency_band2_speed);
    if (m->emergency_band2_speed > 0.0 && !(isfinite(m->emergency_band2_decel) &&
                                             m->emergency_band2_decel >= m->service_decel))
        FAIL("emergency_band2_decel = %g: must be finite and >= service_decel = %g",
             m->emergency_band2_decel, m->service_decel);
    if (m->emergency_band3_speed > 0.0 && !(isfinite(m->emergency_band3_decel) &&
                                             m->emergency_band3_decel >= m->service_decel))
        FAIL("emergency_band3_decel = %g: must be finite and >= service_decel = %g",
             m->emergency_band3_decel, m->service_decel);
    if (bad_nonneg(m->brake_delay))
        FAIL("brake_delay = %g: must be finite and >= 0", m->brake_delay);
    if (bad_nonneg(m->brake_buildup))
        FAIL("brake_buildup = %g: must be finite and >= 0", m->brake_buildup);
    if (!isfinite(m->traction_cutoff) || m->traction_cutoff > 30.0)
        FAIL("traction_cutoff = %g: must be finite and <= 30 s (negative: cut when the brakes apply)",
             m->traction_cutoff);
    if (!isfinite(m->speed_error) || m->speed_error < 0.0 || m->speed_error > 0.5)
        FAIL("speed_error = %g: must be in [0, 0.5]", m->speed_error);
    if (!(m->slippery_factor > 0.0 && m->slippery_factor <= 1.0))
        FAIL("slippery_factor = %g: must be in (0, 1]", m->slippery_factor);
    if (!(m->degraded_factor > 0.0 && m->degraded_factor <= 1.0))
        FAIL("degraded_factor = %g: must be in (0, 1]", m->degraded_factor);
    if (m->track_condition != 0 && m->track_condition != 1)
        FAIL("track_condition = %ld: must be 0 or 1", (long)m->track_condition);
    if (m->brake_status != 0 && m->brake_status != 1)
        FAIL("brake_status = %ld: must be 0 or 1", (long)m->brake_status);
    if (bad_nonneg(m->obstacle_position))
        FAIL("obstacle.position = %g: must be finite and >= 0", m->obstacle_position);
    if (!isfinite(m->obstacle_speed))
        FAIL("obstacle.speed = %g: must be finite", m->obstacle_speed);
    if (m->obstacle_type < 0 || m->obstacle_type > 2)
        FAIL("obstacle.type = %ld: must be 0, 1 or 2", (long)m->obstacle_type);
    if (isnan(m->obstacle_leave_time) || m->obstacle_leave_time < 0.0)
        FAIL("obstacle.leave_time = %g: must be >= 0 s (1e9: never)", m->obstacle_leave_time);
    if (bad_nonneg(m->sensor_range))
        FAIL("sensor.range = %g: must be finite and >= 0", m->sensor_range);
    if (bad_nonneg(m->sensor_noise_sigma))
        FAIL("sensor.noise_sigma = %g: must be finite and >= 0", m->sensor_noise_sigma);
    if (!(m->sensor_miss_probability >= 0.0 && m->sensor_miss_probability <= 1.0))
        FAIL("sensor.miss_probability = %g: must be in [0, 1]", m->sensor_miss_probability);
    if (!isfinite(m->sensor_distance_bias) || !isfinite(m->sensor_closing_bias))
        FAIL("sensor.distance_bias = %g, sensor.closing_bias = %g: must be finite", m->sensor_distance_bias,
             m->sensor_closing_bias);
    if (!isfinite(m->sensor_period) || m->sensor_period < FIXED_STEP - SAMPLE_EPS)
        FAIL("sensor.period = %g: must be finite and >= %g s", m->sensor_period, FIXED_STEP);
    if (m->fault_kind < 0 || m->fault_kind > 8)
        FAIL("fault.kind = %ld: must be 0..8", (long)m->fault_kind);
    if (m->fault_channel < 1 || m->fault_channel > TRAIN_CHANNELS)
        FAIL("fault.channel = %ld: must be 1..%d", (long)m->fault_channel, TRAIN_CHANNELS);
    if (isnan(m->fault_start)) FAIL("fault.start is NaN");
    if (isnan(m->fault_end)) FAIL("fault.end is NaN");
    if (m->fault_end < m->fault_start)
        FAIL("fault.end = %g: must be >= fault.start = %g", m->fault_end, m->fault_start);
    if (!isfinite(m->brake_timeout) || m->brake_timeout < 0.0 || m->brake_timeout > 10.0)
        FAIL("brake_timeout = %g: must be 0..10 s", m->brake_timeout);

    /* internal state at t = 0 */
    m->time = 0.0;
    m->steps = 0;
    m->cell_demand = 0;
    m->cell_cycle = 0;
    m->alive_cycle = 0;
    m->alive_since = 0.0;
    m->receiver_brake = 0;
    m->cruise_speed = (m->cruise_setting >= 0.0) ? m->cruise_setting : m->initial_speed;
    m->phase = (m->initial_speed > 0.0) ? TRAIN_RUNNING : TRAIN_WAITING;
    m->seen_release = 0;
    m->brake_decel = 0.0;
    m->brake_target = 0.0;
    m->demand_start = 0.0;
    m->last_demand = 0;
    {
        double d = floor(m->brake_delay / FIXED_STEP + 0.5);
        m->delay_steps = (d > TRAIN_MAX_DELAY_STEPS) ? TRAIN_MAX_DELAY_STEPS : (int32_t)d;
    }
    m->ring_head = 0;
    memset(m->ring, 0, sizeof m->ring);
    m->next_sample = 0;
    m->wreck_position = 0.0;
    seed_channels(m);

    /* outputs at t = 0 */
    m->speed = m->initial_speed;
    m->position = 0.0;
    m->acceleration = 0.0;
    m->brake_level = 0;
    m->collided = 0;
    m->impact_speed = 0.0;
    m->out_track_condition = m->track_condition;
    m->out_brake_status = m->brake_status;
    for (c = 0; c < TRAIN_CHANNELS; c++) {
        m->ch[c].status = 0;
        m->ch[c].distance = 0.0;
        m->ch[c].closing_speed = 0.0;
        m->ch[c].type = 0;
    }
    if (update_distance(m)) m->impact_speed = m->initial_speed;
    update_valid(m);
    maybe_sample(m); /* first sample at t = 0 */
    set_view(m, m);
    return RG_OK;
}

/* Any communication step. The model integrates on the fixed grid of internal steps
 * [k, k + 1) x 10 ms (times in whole ns since the start). The input brake_demand is sampled
 * at each grid instant k x 10 ms (the value set before the communication step that
 * contains the instant: [from_ns, to_ns) contains its start, not its end) and holds for that
 * internal step. A step runs every internal step that ends at or before to_ns. If to_ns is
 * not on the grid, the state stays at the last grid instant and the outputs show the state
 * at to_ns: a copy of it integrated over the part of the internal step up to to_ns with the
 * same equations (set_view); the whole internal step is computed once the communication
 * reaches its end. Sensors are sampled on the grid only (their outputs hold in between);
 * chN.valid follows the silence fault at to_ns. So the state on the grid does not depend
 * on the communication steps, only on the demand at the grid instants. */
int model_do_step(ModelData *m, int64_t from_ns, int64_t to_ns, char *msg, size_t len)
{
    if (to_ns < from_ns || from_ns < m->steps * TRAIN_STEP_NS ||
        from_ns >= (m->steps + 1) * TRAIN_STEP_NS) {
        if (msg != NULL && len > 0)
            snprintf(msg, len, "bad step from %lld ns to %lld ns (model at %lld ns)", (long long)from_ns,
                     (long long)to_ns, (long long)(m->steps * TRAIN_STEP_NS));
        return RG_ERROR;
    }
    for (;;) {
        const int64_t start = m->steps * TRAIN_STEP_NS;
        if (start >= from_ns && start < to_ns) { /* sample at the grid instant */
            m->cell_demand = m->brake_demand;
            m->cell_cycle = m->monitor_cycle;
        }
        if (start + TRAIN_STEP_NS > to_ns) break;
        internal_step(m, FIXED_STEP, (double)(m->steps + 1) * FIXED_STEP);
        m->steps++;
        update_valid(m);
        maybe_sample(m);
    }
    if (to_ns == m->steps * TRAIN_STEP_NS) {
        set_view(m, m);
    } else {
        ModelData part = *m;
        const double dt = (double)(to_ns - m->steps * TRAIN_STEP_NS) / 1e9;
        internal_step(&part, dt, (double)to_ns / 1e9);
        update_valid(&part);
        set_view(m, &part);
    }
    return RG_OK;
}

/* ------------------------------------------------------------------ get / set */

static const TrainChannel *channel_of(const ModelData *m, uint32_t vr, int *field)
{
    const uint32_t k = vr - (uint32_t)vr_ch1_status;
    *field = (int)(k % 5u);
    return &m->ch[k / 5u];
}

static int k_channel(uint32_t vr)
{
    return (int)((vr - (uint32_t)vr_ch1_status) / 5u);
}

static int is_channel_vr(uint32_t vr)
{
    return vr >= (uint32_t)vr_ch1_status && vr <= (uint32_t)vr_ch6_valid;
}

double model_get_real(const ModelData *m, uint32_t vr)
{
    if (is_channel_vr(vr)) {
        int field;
        const TrainChannel *ch = channel_of(m, vr, &field);
        switch (field) {
        case 1: return ch->distance;
        case 2: return ch->closing_speed;
        default: return 0.0;
        }
    }
    switch (vr) {
    case vr_time: return m->time;
    case vr_initial_speed: return m->initial_speed;
    case vr_mass: return m->mass;
    case vr_davis_a: return m->davis_a;
    case vr_davis_b: return m->davis_b;
    case vr_davis_c: return m->davis_c;
    case vr_gradient: return m->gradient;
    case vr_max_traction: return m->max_traction;
    case vr_cruise_speed: return m->cruise_setting;
    case vr_service_decel: return m->service_decel;
    case vr_emergency_decel: return m->emergency_decel;
    case vr_emergency_band2_speed: return m->emergency_band2_speed;
    case vr_emergency_band2_decel: return m->emergency_band2_decel;
    case vr_emergency_band3_speed: return m->emergency_band3_speed;
    case vr_emergency_band3_decel: return m->emergency_band3_decel;
    case vr_brake_delay: return m->brake_delay;
    case vr_brake_buildup: return m->brake_buildup;
    case vr_traction_cutoff: return m->traction_cutoff;
    case vr_speed_error: return m->speed_error;
    case vr_slippery_factor: return m->slippery_factor;
    case vr_degraded_factor: return m->degraded_factor;
    case vr_obstacle_position: return m->obstacle_position;
    case vr_obstacle_speed: return m->obstacle_speed;
    case vr_obstacle_leave_time: return m->obstacle_leave_time;
    case vr_sensor_range: return m->sensor_range;
    case vr_sensor_noise_sigma: return m->sensor_noise_sigma;
    case vr_sensor_miss_probability: return m->sensor_miss_probability;
    case vr_sensor_distance_bias: return m->sensor_distance_bias;
    case vr_sensor_closing_bias: return m->sensor_closing_bias;
    case vr_sensor_period: return m->sensor_period;
    case vr_fault_start: return m->fault_start;
    case vr_fault_end: return m->fault_end;
    case vr_train_speed: return m->view.speed / (1.0 + m->speed_error);
    case vr_true_speed: return m->view.speed;
    case vr_position: return m->view.position;
    case vr_acceleration: return m->view.acceleration;
    case vr_true_distance: return m->view.true_distance;
    case vr_brake_decel: return m->view.brake_decel;
    case vr_impact_speed: return m->view.impact_speed;
    default: return 0.0;
    }
}

int32_t model_get_integer(const ModelData *m, uint32_t vr)
{
    if (is_channel_vr(vr)) {
        int field;
        const TrainChannel *ch = channel_of(m, vr, &field);
        switch (field) {
        case 0: return ch->status;
        case 3: return ch->type;
        default: return 0;
        }
    }
    switch (vr) {
    case vr_brake_demand: return m->brake_demand;
    case vr_monitor_cycle: return m->monitor_cycle;
    case vr_track_condition: return m->track_condition;
    case vr_brake_status: return m->brake_status;
    case vr_obstacle_type: return m->obstacle_type;
    case vr_sensor_seed: return m->sensor_seed;
    case vr_fault_kind: return m->fault_kind;
    case vr_fault_channel: return m->fault_channel;
    case vr_train_track_condition: return m->out_track_condition;
    case vr_train_brake_status: return m->out_brake_status;
    case vr_brake_level: return m->view.brake_level;
    default: return 0;
    }
}

int model_get_boolean(const ModelData *m, uint32_t vr)
{
    if (is_channel_vr(vr)) {
        int field;
        (void)channel_of(m, vr, &field);
        return field == 4 ? m->view.valid[k_channel(vr)] : 0;
    }
    switch (vr) {
    case vr_obstacle_present: return m->obstacle_present;
    case vr_collided: return m->view.collided;
    case vr_receiver_brake: return m->receiver_brake;
    default: return 0;
    }
}

const char *model_get_string(const ModelData *m, uint32_t vr)
{
    (void)m;
    (void)vr;
    return ""; /* this model has no String variables */
}

void model_set_real(ModelData *m, uint32_t vr, double v)
{
    switch (vr) {
    case vr_initial_speed: m->initial_speed = v; break;
    case vr_mass: m->mass = v; break;
    case vr_davis_a: m->davis_a = v; break;
    case vr_davis_b: m->davis_b = v; break;
    case vr_davis_c: m->davis_c = v; break;
    case vr_gradient: m->gradient = v; break;
    case vr_max_traction: m->max_traction = v; break;
    case vr_cruise_speed: m->cruise_setting = v; break;
    case vr_service_decel: m->service_decel = v; break;
    case vr_emergency_decel: m->emergency_decel = v; break;
    case vr_emergency_band2_speed: m->emergency_band2_speed = v; break;
    case vr_emergency_band2_decel: m->emergency_band2_decel = v; break;
    case vr_emergency_band3_speed: m->emergency_band3_speed = v; break;
    case vr_emergency_band3_decel: m->emergency_band3_decel = v; break;
    case vr_brake_delay: m->brake_delay = v; break;
    case vr_brake_buildup: m->brake_buildup = v; break;
    case vr_traction_cutoff: m->traction_cutoff = v; break;
    case vr_speed_error: m->speed_error = v; break;
    case vr_slippery_factor: m->slippery_factor = v; break;
    case vr_degraded_factor: m->degraded_factor = v; break;
    case vr_obstacle_position: m->obstacle_position = v; break;
    case vr_obstacle_speed: m->obstacle_speed = v; break;
    case vr_obstacle_leave_time: m->obstacle_leave_time = v; break;
    case vr_sensor_range: m->sensor_range = v; break;
    case vr_sensor_noise_sigma: m->sensor_noise_sigma = v; break;
    case vr_sensor_miss_probability: m->sensor_miss_probability = v; break;
    case vr_sensor_distance_bias: m->sensor_distance_bias = v; break;
    case vr_sensor_closing_bias: m->sensor_closing_bias = v; break;
    case vr_sensor_period: m->sensor_period = v; break;
    case vr_fault_start: m->fault_start = v; break;
    case vr_fault_end: m->fault_end = v; break;
    case vr_brake_timeout: m->brake_timeout = v; break;
    default: break;
    }
}

void model_set_integer(ModelData *m, uint32_t vr, int32_t v)
{
    switch (vr) {
    case vr_brake_demand: m->brake_demand = v; break;
    case vr_monitor_cycle: m->monitor_cycle = v; break;
    case vr_track_condition: m->track_condition = v; break;
    case vr_brake_status: m->brake_status = v; break;
    case vr_obstacle_type: m->obstacle_type = v; break;
    case vr_sensor_seed: m->sensor_seed = v; break;
    case vr_fault_kind: m->fault_kind = v; break;
    case vr_fault_channel: m->fault_channel = v; break;
    default: break;
    }
}

void model_set_boolean(ModelData *m, uint32_t vr, int v)
{
    switch (vr) {
    case vr_obstacle_present: m->obstacle_present = v ? 1 : 0; break;
    default: break;
    }
}
