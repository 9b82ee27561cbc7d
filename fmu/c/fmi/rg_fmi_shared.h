/* The checks both FMI wrappers (fmi2.c, fmi3.c) make the same way, in one place: which
 * variables may be set when, whether the generated variable table is sound, and how a
 * communication point and a step size are matched against the fixed step. The including
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

/* The model runs on a fixed step: the number n >= 1 of FIXED_STEPs in `h` (relative
 * tolerance 1e-9), or 0 if `h` is no positive whole multiple. h / FIXED_STEP < 2^53 keeps
 * n exact and the conversion defined. */
static inline uint64_t rg_fixed_steps(double h)
{
    double q = h / FIXED_STEP, rounded = rg_floor(q + 0.5);
    if (!(h > 0.0) || !(q < 9007199254740992.0) || rounded < 1.0 ||
        rg_fabs(h - rounded * FIXED_STEP) > 1e-9 * rg_fmax(1.0, h))
        return 0;
    return (uint64_t)rounded;
}

#endif
