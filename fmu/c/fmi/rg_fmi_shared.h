/* The checks both FMI wrappers (fmi2.c, fmi3.c) make the same way, in one place: which
 * variables may be set when, whether the generated variable table is sound, how a
 * communication point is matched against the FMU time and where a step ends (the FMU
 * time in whole nanoseconds). The including
 * file defines RG_FMI_EXIT_INIT, the name of its ExitInitializationMode (for messages). */
#ifndef RG_FMI_SHARED_H
#define RG_FMI_SHARED_H

#include <stdint.h>

#include "model.h"
#include "rg_math.h"
#include "variables.h"

/* Why variable `v` may not be set now, or NULL; `initializing` is true before
 * ExitInitializationMode (instantiated or initialization mode). */
static inline const char *rg_not_settable(const rg_variable *v, int initializing)
{
    if (v->variability == RG_V_CONSTANT)
        return "is a constant and cannot be set";
    switch (v->causality) {
    case RG_C_INPUT:
        return NULL;
    case RG_C_PARAMETER:
        if (v->variability == RG_V_TUNABLE || initializing)
            return NULL;
        return "is a fixed parameter and can only be set before " RG_FMI_EXIT_INIT;
    case RG_C_OUTPUT:
        return "is an output and cannot be set";
    default:
        return "is the independent variable and cannot be set";
    }
}

/* The generated table must satisfy VARIABLES[i].vr == i; checked once per instantiation
 * because every access indexes it by value reference. */
static inline int rg_variables_ok(void)
{
    uint32_t i;
    for (i = 0; i < N_VARIABLES; i++)
        if (VARIABLES[i].vr != i || VARIABLES[i].type > RG_T_STRING)
            return 0;
    return FIXED_STEP > 0.0;
}

/* A communication point matches the FMU time `t` within a relative 1e-9. */
static inline int rg_at_time(double point, double t)
{
    return rg_fabs(point - t) <= 1e-9 * rg_fmax(1.0, rg_fabs(t));
}

/* Time. The FMU's time is a whole number of nanoseconds since startTime (int64_t), never a
 * sum of doubles: a 10 ms step is exactly 10,000,000 ns, so ten of them make exactly one
 * 100 ms monitor cycle however the importer adds its own time up. RG_MAX_NS (2^62 ns, about
 * 146 years) bounds it so that every sum and product below stays far from overflow. */
#define RG_NS_PER_S 1e9
#define RG_MAX_NS 4611686018427387904.0

/* The FMU time in seconds: startTime + ns / 10^9 (a correctly rounded division: 3 x 100 ms
 * is reported as 0.3, the double nearest to 0.3). */
static inline double rg_time_of(double start, int64_t ns)
{
    return start + (double)ns / RG_NS_PER_S;
}

/* Where a step ends, in ns since `start`: the importer's end point point + h rounded to the
 * nearest nanosecond (halves up), never before the FMU time `now_ns` (a step shorter than
 * the rounding then leaves the time as it is). It is measured from the importer's point,
 * not from now_ns: a difference between the two clocks (at most the tolerance of
 * rg_at_time) is not carried forward, as the FMI 2.0 text suggests for a slave with its own
 * time (hc_s = (tc_i - tc_s) + hc_i). `h` is a finite positive number (checked by the
 * caller). -1 if the end lies beyond RG_MAX_NS. */
static inline int64_t rg_step_end_ns(double start, int64_t now_ns, double point, double h)
{
    double x = (point - start) * RG_NS_PER_S + h * RG_NS_PER_S;
    int64_t end;
    if (!(x < RG_MAX_NS))
        return -1;
    end = (int64_t)rg_floor(x + 0.5);
    return end < now_ns ? now_ns : end;
}

/* Why a communicationStepSize cannot be done at all, or NULL. Both FMI 2.0 and FMI 3.0
 * require communicationStepSize > 0.0, so zero, negative and NaN are refused; every other
 * value is accepted (canHandleVariableCommunicationStepSize = true). */
static inline const char *rg_bad_step(double h)
{
    if (!(h > 0.0))
        return "must be > 0 (FMI: communicationStepSize > 0.0)";
    if (!(h < RG_MAX_NS / RG_NS_PER_S))
        return "is too long (the FMU time is limited to 2^62 ns)";
    return NULL;
}

#endif
