/* The few floating-point helpers the wrappers and the monitor model need, written out so
 * that the monitor FMU's binary does not depend on libm: FMI 2.0 has no way to declare a
 * library dependency, and a binary rebuilt from the FMU's sources by a generic builder
 * (FMPy's CMake project links no -lm) must still load in a process without libm. */
#ifndef RG_MATH_H
#define RG_MATH_H

#define RG_EXACT_LIMIT 9007199254740992.0 /* 2^53: every double beyond is an integer */

static inline double rg_fabs(double x) { return x < 0.0 ? -x : x; }

static inline double rg_fmax(double a, double b) { return a > b ? a : b; }

static inline int rg_isfinite(double x) { return x == x && x - x == 0.0; }

/* floor(x) for any double (NaN and infinities returned unchanged) */
static inline double rg_floor(double x)
{
    double t;
    if (!(x > -RG_EXACT_LIMIT && x < RG_EXACT_LIMIT)) return x;
    t = (double)(long long)x;
    return t > x ? t - 1.0 : t;
}

/* ceil(x) for any double (NaN and infinities returned unchanged) */
static inline double rg_ceil(double x)
{
    double t;
    if (!(x > -RG_EXACT_LIMIT && x < RG_EXACT_LIMIT)) return x;
    t = (double)(long long)x;
    return t < x ? t + 1.0 : t;
}

#endif
