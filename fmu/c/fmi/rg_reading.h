/* How the monitor reads real-valued sensor and train values into the core's integers, towards
 * the safe side: distance rounded down to dm, closing speed and train speed rounded up to
 * cm/s; NaN or a value outside its range becomes a value the core refuses. One definition for
 * the signal monitor FMU (fmu/c/monitor/model.c) and the train network node, which puts these
 * integers into its frames (fmu/c/lsbus/train_node), so both monitors read the same numbers;
 * fmu/reference.py is the Python twin, held to it by tests/test_fmu_equivalence.py. */
#ifndef RG_READING_H
#define RG_READING_H

#include <stdint.h>

#include "rg_math.h"

static inline int32_t read_distance_dm(double x)
{
    if (!(x >= 0.0 && x <= 6000.0)) return -1;
    return (int32_t)rg_floor(x * 10.0);
}

static inline int32_t read_closing_cms(double x)
{
    if (!(x >= -150.0 && x <= 150.0)) return 99999;
    return (int32_t)rg_ceil(x * 100.0);
}

static inline int32_t read_speed_cms(double x)
{
    if (!(x >= 0.0 && x <= 120.0)) return -1;
    return (int32_t)rg_ceil(x * 100.0);
}

#endif
