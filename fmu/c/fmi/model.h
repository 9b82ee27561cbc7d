/* The contract between the shared FMI 2.0 / 3.0 wrappers (fmi2.c, fmi3.c) and one model
 * (monitor/model.c or train/model.c).
 *
 * Each model folder has a config.h that defines MODEL_IDENTIFIER, INSTANTIATION_TOKEN,
 * FIXED_STEP (seconds: the monitor's cycle, the train's internal step; any communication
 * step is accepted, the model decides what it does between its fixed instants) and the
 * struct ModelData (plain data, no pointers to heap memory). The build also generates
 * variables.h in the model's folder: the value references (an enum in XML order) and
 * the table VARIABLES[] of (value reference, type, causality, variability) that the
 * wrappers use to refuse a get/set of an unknown variable, of the wrong type, or one
 * that may not be set in the current state.
 *
 * The wrappers own the calling-sequence state machine, logging and instance memory;
 * the model only computes. No model function allocates memory.
 */
#ifndef RG_MODEL_H
#define RG_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "config.h"

/* variable types, causalities and variabilities used in VARIABLES[] */
enum { RG_T_REAL = 0, RG_T_INTEGER = 1, RG_T_BOOLEAN = 2, RG_T_STRING = 3 };
enum { RG_C_PARAMETER = 0, RG_C_INPUT = 1, RG_C_OUTPUT = 2, RG_C_INDEPENDENT = 3 };
enum { RG_V_CONSTANT = 0, RG_V_FIXED = 1, RG_V_TUNABLE = 2, RG_V_DISCRETE = 3, RG_V_CONTINUOUS = 4 };

typedef struct {
    uint32_t vr;
    uint8_t type;
    uint8_t causality;
    uint8_t variability;
    const char *name;
} rg_variable;

/* status codes of model functions */
enum { RG_OK = 0, RG_ERROR = 1 };

/* Start values of every variable; called at instantiation and at reset. */
void model_set_start_values(ModelData *m);

/* Leaving initialisation mode: check parameters, set up the internal state.
 * On RG_ERROR, `msg` (of `len` bytes) says what is wrong, naming the variable. */
int model_initialize(ModelData *m, char *msg, size_t len);

/* Advance from `from_ns` to `to_ns`, both in whole nanoseconds since the start of the run
 * (0 <= from_ns <= to_ns; from_ns is where the previous step ended, or 0). The wrapper keeps
 * that time and rounds each step end to the nanosecond (rg_fmi_shared.h). On RG_ERROR,
 * `msg` says why. */
int model_do_step(ModelData *m, int64_t from_ns, int64_t to_ns, char *msg, size_t len);

/* Get / set by value reference. The wrapper has already checked that `vr` exists in
 * VARIABLES[] with this type and that setting it is allowed now. */
double model_get_real(const ModelData *m, uint32_t vr);
int32_t model_get_integer(const ModelData *m, uint32_t vr);
int model_get_boolean(const ModelData *m, uint32_t vr);
const char *model_get_string(const ModelData *m, uint32_t vr);
void model_set_real(ModelData *m, uint32_t vr, double v);
void model_set_integer(ModelData *m, uint32_t vr, int32_t v);
void model_set_boolean(ModelData *m, uint32_t vr, int v);

#endif
