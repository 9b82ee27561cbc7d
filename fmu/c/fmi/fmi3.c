/* FMI 3.0 Co-Simulation wrapper around one railguard model (see model.h).
 * Built with -DDISABLE_PREFIX: FMI3_FUNCTION_PREFIX stays undefined, so the exported
 * names are the plain fmi3XXX ones.
 *
 * Everything FMI-specific lives here: instance memory, the calling-sequence state machine
 * of FMI 3.0 Co-Simulation without event mode (Instantiated -> InitializationMode ->
 * StepMode -> Terminated), value-reference checks and logging. The model only computes.
 * One instance is one memory block allocated in fmi3InstantiateCoSimulation; nothing is
 * allocated later. Every function of fmi3Functions.h is defined (importers such as FMPy
 * bind them all by name); the ones this FMU does not support log and return fmi3Error.
 *
 * Error policy. Every fmi3Error is logged (category "logError", also with debug logging
 * off) and, as the standard prescribes ("If any function ... returns fmi3Error, the FMU
 * enters state Terminated"), moves the instance to Terminated. From there only getting
 * values (for diagnosis), fmi3Reset, fmi3SetDebugLogging and fmi3FreeInstance are allowed.
 *
 * Log categories: "logError" (errors, always) and "logDebug" (call trace, only with
 * debug logging on).
 */
#define RG_FMI_EXIT_INIT "fmi3ExitInitializationMode"
#include "rg_fmi_shared.h"
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model.h"
#include "variables.h"

#if defined(__GNUC__)
#define RG_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define RG_PRINTF(f, a)
#endif

/* States as bits so that "allowed in" is a mask. EventMode, ConfigurationMode and the
 * other modes are never entered (hasEventMode = false, no structural parameters). */
enum {
    S_INSTANTIATED = 1u << 0,
    S_INITIALIZATION_MODE = 1u << 1,
    S_STEP_MODE = 1u << 2,
    S_TERMINATED = 1u << 3
};

#define M_ANY (S_INSTANTIATED | S_INITIALIZATION_MODE | S_STEP_MODE | S_TERMINATED)
#define M_GET (S_INSTANTIATED | S_INITIALIZATION_MODE | S_STEP_MODE | S_TERMINATED)
#define M_SET (S_INSTANTIATED | S_INITIALIZATION_MODE | S_STEP_MODE)

#define TEXT_SIZE 512

typedef struct {
    unsigned state;
    int failed; /* Terminated was entered by an error (only changes messages) */
    fmi3LogMessageCallback log_message;
    fmi3InstanceEnvironment env;
    int logging_on;     /* debug messages; errors are always logged */
    int debug_category; /* "logDebug" selected by fmi3SetDebugLogging */
    double start_time;
    int stop_time_defined;
    double stop_time;
    int64_t time_ns; /* FMU time - start_time in whole ns (rg_fmi_shared.h): no drift */
    ModelData data;
    char model_msg[256];
    char text[TEXT_SIZE];
    char out[2 * TEXT_SIZE + 1];
    char name[]; /* instance name, allocated with the struct */
} Instance;

static const char *state_name(const Instance *inst)
{
    switch (inst->state) {
    case S_INSTANTIATED: return "Instantiated";
    case S_INITIALIZATION_MODE: return "InitializationMode";
    case S_STEP_MODE: return "StepMode";
    case S_TERMINATED: return inst->failed ? "Terminated (after an error)" : "Terminated";
    default: return "unknown";
    }
}

static const char *type_name(unsigned t)
{
    switch (t) {
    case RG_T_REAL: return "Float64";
    case RG_T_INTEGER: return "Int32";
    case RG_T_BOOLEAN: return "Boolean";
    case RG_T_STRING: return "String";
    default: return "unknown";
    }
}

/* ---- logging ---------------------------------------------------------------------- */

/* In FMI 3.0 messages '#' starts a value reference (#12#), so a literal '#' is doubled.
 * Truncates rather than overflows. */
static void emit(fmi3LogMessageCallback log_message, fmi3InstanceEnvironment env, fmi3Status status,
                 const char *category, const char *text, char *out, size_t size)
{
    size_t i, j = 0;
    if (!log_message)
        return;
    for (i = 0; text[i] != '\0' && j + 2 < size; i++) {
        if (text[i] == '#')
            out[j++] = text[i];
        out[j++] = text[i];
    }
    out[j] = '\0';
    log_message(env, status, category, out);
}

static void vlog(Instance *inst, fmi3Status status, const char *category, const char *fmt, va_list ap)
{
    vsnprintf(inst->text, sizeof inst->text, fmt, ap);
    emit(inst->log_message, inst->env, status, category, inst->text, inst->out, sizeof inst->out);
}

/* Log an error and enter Terminated; returns fmi3Error so callers can `return fail(...)`. */
static fmi3Status fail(Instance *inst, const char *fmt, ...) RG_PRINTF(2, 3);
static fmi3Status fail(Instance *inst, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(inst, fmi3Error, "logError", fmt, ap);
    va_end(ap);
    inst->state = S_TERMINATED;
    inst->failed = 1;
    return fmi3Error;
}

static void trace(Instance *inst, const char *fmt, ...) RG_PRINTF(2, 3);
static void trace(Instance *inst, const char *fmt, ...)
{
    va_list ap;
    if (!inst->logging_on || !inst->debug_category)
        return;
    va_start(ap, fmt);
    vlog(inst, fmi3OK, "logDebug", fmt, ap);
    va_end(ap);
}

/* ---- shared checks ---------------------------------------------------------------- */

/* The instance if the call is allowed in its state; NULL (after logging and entering
 * Terminated) if not, or if `instance` is NULL. */
static Instance *begin(fmi3Instance instance, const char *fn, unsigned allowed)
{
    Instance *inst = (Instance *)instance;
    if (!inst)
        return NULL;
    if (!(inst->state & allowed)) {
        fail(inst, "%s: not allowed in state %s", fn, state_name(inst));
        return NULL;
    }
    return inst;
}

static fmi3Status unsupported(fmi3Instance instance, const char *fn)
{
    Instance *inst = (Instance *)instance;
    if (!inst)
        return fmi3Error;
    return fail(inst, "%s: not supported by this FMU", fn);
}

static double now(const Instance *inst)
{
    return rg_time_of(inst->start_time, inst->time_ns);
}

/* All variables are scalars, so nValues must equal nValueReferences; both arrays must
 * exist when there is something to transfer. */
static int check_arrays(Instance *inst, const char *fn, const fmi3ValueReference vr[], size_t nvr,
                        const void *values, size_t nValues)
{
    if (nValues != nvr) {
        fail(inst, "%s: nValues = %lu but nValueReferences = %lu (all variables are scalars)", fn,
             (unsigned long)nValues, (unsigned long)nvr);
        return 0;
    }
    if (nvr > 0 && (!vr || !values)) {
        fail(inst, "%s: NULL array for %lu value references", fn, (unsigned long)nvr);
        return 0;
    }
    return 1;
}

/* Check every value reference before touching anything, so that a refused call has no
 * effect: it exists, has the type of the function and, for a set, may be set now. */
static int check_vrs(Instance *inst, const char *fn, const fmi3ValueReference vr[], size_t nvr,
                     const void *values, size_t nValues, unsigned type, int set)
{
    size_t i;
    if (!check_arrays(inst, fn, vr, nvr, values, nValues))
        return 0;
    for (i = 0; i < nvr; i++) {
        const rg_variable *v;
        const char *why;
        if (vr[i] >= N_VARIABLES) {
            fail(inst, "%s: unknown value reference %u", fn, (unsigned)vr[i]);
            return 0;
        }
        v = &VARIABLES[vr[i]];
        if (v->type != type) {
            fail(inst, "%s: variable %s (value reference %u) is of type %s, not %s", fn, v->name,
                 (unsigned)vr[i], type_name(v->type), type_name(type));
            return 0;
        }
        if (set && (why = rg_not_settable(v, (inst->state & (S_INSTANTIATED | S_INITIALIZATION_MODE)) != 0)) != NULL) {
            fail(inst, "%s: variable %s (value reference %u) %s (state %s)", fn, v->name, (unsigned)vr[i],
                 why, state_name(inst));
            return 0;
        }
    }
    return 1;
}

/* Get/set of a type this FMU has no variables of: legal (and a no-op) for zero value
 * references, an error otherwise. */
static fmi3Status no_such_type(fmi3Instance instance, const char *fn, const char *type, int set,
                               const fmi3ValueReference vr[], size_t nvr, const void *values, size_t nValues)
{
    Instance *inst = begin(instance, fn, set ? M_SET : M_GET);
    if (!inst || !check_arrays(inst, fn, vr, nvr, values, nValues))
        return fmi3Error;
    if (nvr > 0)
        return fail(inst, "%s: value reference %u: this FMU has no variables of type %s", fn, (unsigned)vr[0], type);
    return fmi3OK;
}

static void reset_instance(Instance *inst)
{
    memset(&inst->data, 0, sizeof inst->data);
    model_set_start_values(&inst->data);
    inst->start_time = 0.0;
    inst->stop_time_defined = 0;
    inst->stop_time = 0.0;
    inst->time_ns = 0;
    inst->state = S_INSTANTIATED;
    inst->failed = 0;
}

/* ---- inquiry, logging, creation ----------------------------------------------------- */

const char *fmi3GetVersion(void)
{
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    Instance *inst = begin(instance, "fmi3SetDebugLogging", M_ANY);
    size_t i;
    int selected = nCategories == 0; /* no list: all debug messages */
    if (!inst)
        return fmi3Error;
    if (nCategories > 0 && !categories)
        return fail(inst, "fmi3SetDebugLogging: NULL categories for nCategories = %lu", (unsigned long)nCategories);
    for (i = 0; i < nCategories; i++) {
        if (!categories[i])
            return fail(inst, "fmi3SetDebugLogging: category %lu is NULL", (unsigned long)i);
        /* "logError" needs no switch (errors are always logged); others are ignored */
        if (strcmp(categories[i], "logDebug") == 0 || strcmp(categories[i], "logAll") == 0)
            selected = 1;
    }
    inst->logging_on = loggingOn ? 1 : 0;
    inst->debug_category = selected;
    trace(inst, "fmi3SetDebugLogging: debug logging on");
    return fmi3OK;
}

/* Log why instantiation failed; there is no instance yet, so the buffers are local. */
static void instantiate_error(fmi3LogMessageCallback log_message, fmi3InstanceEnvironment env, const char *fmt, ...)
    RG_PRINTF(3, 4);
static void instantiate_error(fmi3LogMessageCallback log_message, fmi3InstanceEnvironment env, const char *fmt, ...)
{
    char text[TEXT_SIZE], out[2 * TEXT_SIZE + 1];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    emit(log_message, env, fmi3Error, "logError", text, out, sizeof out);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    const char *name = instanceName ? instanceName : "";
    size_t len;
    Instance *inst;

    (void)resourcePath; /* the models need no resources */
    (void)visible;
    (void)earlyReturnAllowed; /* never returns early */
    (void)requiredIntermediateVariables;
    (void)intermediateUpdate; /* providesIntermediateUpdate = false: never called */
    if (name[0] == '\0') {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: instanceName must be a non-empty string");
        return NULL;
    }
    if (!instantiationToken || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: %s: instantiationToken %s does not match %s of this binary (%s)",
                          name, instantiationToken ? instantiationToken : "(NULL)", INSTANTIATION_TOKEN,
                          MODEL_IDENTIFIER);
        return NULL;
    }
    if (eventModeUsed) { /* the standard: only with hasEventMode = true, else an error */
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: %s: eventModeUsed = true but this FMU has no event mode",
                          name);
        return NULL;
    }
    if (nRequiredIntermediateVariables > 0) { /* no variable has intermediateUpdate = true */
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: %s: no variable supports intermediate update "
                          "(nRequiredIntermediateVariables = %lu)",
                          name, (unsigned long)nRequiredIntermediateVariables);
        return NULL;
    }
    if (!rg_variables_ok()) {
        instantiate_error(logMessage, instanceEnvironment,
                          "fmi3InstantiateCoSimulation: %s: inconsistent variable table or FIXED_STEP in this binary",
                          name);
        return NULL;
    }

    len = strlen(name);
    inst = (Instance *)calloc(1, sizeof(Instance) + len + 1);
    if (!inst) {
        instantiate_error(logMessage, instanceEnvironment, "fmi3InstantiateCoSimulation: %s: out of memory", name);
        return NULL;
    }
    memcpy(inst->name, name, len + 1);
    inst->log_message = logMessage;
    inst->env = instanceEnvironment;
    inst->logging_on = loggingOn ? 1 : 0;
    inst->debug_category = 1;
    reset_instance(inst);
    trace(inst, "fmi3InstantiateCoSimulation: %s (%s), fixed step %g s", name, MODEL_IDENTIFIER, FIXED_STEP);
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    instantiate_error(logMessage, instanceEnvironment,
                      "fmi3InstantiateModelExchange: %s supports only Co-Simulation", MODEL_IDENTIFIER);
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    instantiate_error(logMessage, instanceEnvironment,
                      "fmi3InstantiateScheduledExecution: %s supports only Co-Simulation", MODEL_IDENTIFIER);
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!inst)
        return;
    trace(inst, "fmi3FreeInstance");
    free(inst);
}

/* ---- initialization, termination, reset ------------------------------------------- */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Instance *inst = begin(instance, "fmi3EnterInitializationMode", S_INSTANTIATED);
    (void)toleranceDefined; /* fixed-step model: no error control */
    (void)tolerance;
    if (!inst)
        return fmi3Error;
    if (!rg_isfinite(startTime))
        return fail(inst, "fmi3EnterInitializationMode: startTime %g is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return fail(inst, "fmi3EnterInitializationMode: stopTime %g is before startTime %g", stopTime, startTime);
    inst->start_time = startTime;
    inst->stop_time_defined = stopTimeDefined ? 1 : 0;
    inst->stop_time = stopTime;
    inst->state = S_INITIALIZATION_MODE;
    trace(inst, "fmi3EnterInitializationMode: startTime %g", startTime);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *inst = begin(instance, "fmi3ExitInitializationMode", S_INITIALIZATION_MODE);
    if (!inst)
        return fmi3Error;
    inst->model_msg[0] = '\0';
    if (model_initialize(&inst->data, inst->model_msg, sizeof inst->model_msg) != RG_OK) {
        inst->model_msg[sizeof inst->model_msg - 1] = '\0';
        return fail(inst, "fmi3ExitInitializationMode: %s",
                    inst->model_msg[0] ? inst->model_msg : "model initialisation failed");
    }
    inst->state = S_STEP_MODE; /* eventModeUsed = false: straight to StepMode */
    trace(inst, "fmi3ExitInitializationMode");
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterEventMode");
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    Instance *inst = begin(instance, "fmi3Terminate", S_STEP_MODE);
    if (!inst)
        return fmi3Error;
    inst->state = S_TERMINATED;
    trace(inst, "fmi3Terminate at t = %g", now(inst));
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    Instance *inst = begin(instance, "fmi3Reset", M_ANY);
    if (!inst)
        return fmi3Error;
    reset_instance(inst);
    trace(inst, "fmi3Reset");
    return fmi3OK;
}

/* ---- getting and setting values of the four types the models use ------------------ */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3GetFloat64", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3GetFloat64", valueReferences, nValueReferences, values, nValues, RG_T_REAL, 0))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        values[i] = VARIABLES[valueReferences[i]].causality == RG_C_INDEPENDENT
                        ? now(inst)
                        : model_get_real(&inst->data, valueReferences[i]);
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3GetInt32", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3GetInt32", valueReferences, nValueReferences, values, nValues, RG_T_INTEGER, 0))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        values[i] = model_get_integer(&inst->data, valueReferences[i]);
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3GetBoolean", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3GetBoolean", valueReferences, nValueReferences, values, nValues, RG_T_BOOLEAN, 0))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        values[i] = model_get_boolean(&inst->data, valueReferences[i]) ? fmi3True : fmi3False;
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3String values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3GetString", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3GetString", valueReferences, nValueReferences, values, nValues, RG_T_STRING, 0))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++) {
        const char *s = model_get_string(&inst->data, valueReferences[i]);
        values[i] = s ? s : "";
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3SetFloat64", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3SetFloat64", valueReferences, nValueReferences, values, nValues, RG_T_REAL, 1))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        model_set_real(&inst->data, valueReferences[i], values[i]);
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3SetInt32", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3SetInt32", valueReferences, nValueReferences, values, nValues, RG_T_INTEGER, 1))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        model_set_integer(&inst->data, valueReferences[i], values[i]);
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3SetBoolean", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi3SetBoolean", valueReferences, nValueReferences, values, nValues, RG_T_BOOLEAN, 1))
        return fmi3Error;
    for (i = 0; i < nValueReferences; i++)
        model_set_boolean(&inst->data, valueReferences[i], values[i] ? 1 : 0);
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3String values[], size_t nValues)
{
    Instance *inst = begin(instance, "fmi3SetString", M_SET);
    if (!inst || !check_vrs(inst, "fmi3SetString", valueReferences, nValueReferences, values, nValues, RG_T_STRING, 1))
        return fmi3Error;
    /* model.h has no string setter: a settable String variable cannot be served */
    if (nValueReferences > 0)
        return fail(inst, "fmi3SetString: variable %s: setting String variables is not supported",
                    VARIABLES[valueReferences[0]].name);
    return fmi3OK;
}

/* ---- types this FMU has no variables of ------------------------------------------- */

fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float32 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetFloat32", "Float32", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                       size_t nValueReferences, fmi3Int8 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetInt8", "Int8", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3UInt8 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetUInt8", "UInt8", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int16 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetInt16", "Int16", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3UInt16 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetUInt16", "UInt16", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3UInt32 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetUInt32", "UInt32", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int64 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetInt64", "Int64", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3UInt64 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3GetUInt64", "UInt64", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    return no_such_type(instance, "fmi3GetBinary", "Binary", 0, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Clock values[])
{
    /* no nValues argument: one value per reference */
    return no_such_type(instance, "fmi3GetClock", "Clock", 0, valueReferences, nValueReferences, values,
                        nValueReferences);
}

fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float32 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetFloat32", "Float32", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                       size_t nValueReferences, const fmi3Int8 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetInt8", "Int8", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3UInt8 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetUInt8", "UInt8", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int16 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetInt16", "Int16", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3UInt16 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetUInt16", "UInt16", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3UInt32 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetUInt32", "UInt32", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int64 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetInt64", "Int64", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3UInt64 values[], size_t nValues)
{
    return no_such_type(instance, "fmi3SetUInt64", "UInt64", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[],
                         size_t nValues)
{
    (void)valueSizes;
    return no_such_type(instance, "fmi3SetBinary", "Binary", 1, valueReferences, nValueReferences, values, nValues);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Clock values[])
{
    return no_such_type(instance, "fmi3SetClock", "Clock", 1, valueReferences, nValueReferences, values,
                        nValueReferences);
}

/* ---- dependencies, FMU state, derivatives, configuration: not supported ------------ */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference;
    (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies)
{
    (void)dependent;
    (void)elementIndicesOfDependent;
    (void)independents;
    (void)elementIndicesOfIndependents;
    (void)dependencyKinds;
    (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies");
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)FMUState;
    return unsupported(instance, "fmi3GetFMUState");
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    (void)FMUState;
    return unsupported(instance, "fmi3SetFMUState");
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)FMUState;
    return unsupported(instance, "fmi3FreeFMUState");
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    (void)FMUState;
    (void)size;
    return unsupported(instance, "fmi3SerializedFMUStateSize");
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size)
{
    (void)FMUState;
    (void)serializedState;
    (void)size;
    return unsupported(instance, "fmi3SerializeFMUState");
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    (void)serializedState;
    (void)size;
    (void)FMUState;
    return unsupported(instance, "fmi3DeserializeFMUState");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns;
    (void)nUnknowns;
    (void)knowns;
    (void)nKnowns;
    (void)seed;
    (void)nSeed;
    (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterConfigurationMode");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3ExitConfigurationMode");
}

/* ---- clocks: not supported (no clocks) -------------------------------------------- */

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[])
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)counters;
    (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EvaluateDiscreteStates");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    (void)discreteStatesNeedUpdate;
    (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined;
    (void)nextEventTime;
    return unsupported(instance, "fmi3UpdateDiscreteStates");
}

/* ---- Model Exchange: not supported (Co-Simulation only) --------------------------- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterContinuousTimeMode");
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return unsupported(instance, "fmi3CompletedIntegratorStep");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    (void)time;
    return unsupported(instance, "fmi3SetTime");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    (void)continuousStates;
    (void)nContinuousStates;
    return unsupported(instance, "fmi3SetContinuousStates");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    (void)derivatives;
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStateDerivatives");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators)
{
    (void)eventIndicators;
    (void)nEventIndicators;
    return unsupported(instance, "fmi3GetEventIndicators");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates)
{
    (void)continuousStates;
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStates");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates)
{
    (void)nominals;
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNominalsOfContinuousStates");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    (void)nEventIndicators;
    return unsupported(instance, "fmi3GetNumberOfEventIndicators");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNumberOfContinuousStates");
}

/* ---- Co-Simulation ---------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    /* only allowed in EventMode, which this FMU never enters (eventModeUsed = false) */
    Instance *inst = begin(instance, "fmi3EnterStepMode", 0u);
    (void)inst;
    return fmi3Error;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[],
                                    size_t nValues)
{
    (void)valueReferences;
    (void)nValueReferences;
    (void)orders;
    (void)values;
    (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Instance *inst = begin(instance, "fmi3DoStep", S_STEP_MODE);
    double t, h = communicationStepSize, end;
    int64_t end_ns;
    const char *why;
    (void)noSetFMUStatePriorToCurrentPoint; /* no FMU states are kept */
    if (!inst)
        return fmi3Error;
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        return fail(inst, "fmi3DoStep: NULL output argument");
    t = now(inst);
    /* defined outputs also when the step is refused */
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = t;
    if (!rg_at_time(currentCommunicationPoint, t))
        return fail(inst, "fmi3DoStep: currentCommunicationPoint %.17g differs from the FMU time %.17g",
                    currentCommunicationPoint, t);
    why = rg_bad_step(h);
    if (why)
        return fail(inst, "fmi3DoStep: communicationStepSize %.17g %s", h, why);
    end_ns = rg_step_end_ns(inst->start_time, inst->time_ns, currentCommunicationPoint, h);
    if (end_ns < 0)
        return fail(inst, "fmi3DoStep: communicationStepSize %.17g: the step ends beyond the FMU's time range (2^62 ns)", h);
    end = rg_time_of(inst->start_time, end_ns);
    if (inst->stop_time_defined && end > inst->stop_time + 1e-9 * rg_fmax(1.0, rg_fabs(inst->stop_time)))
        return fail(inst, "fmi3DoStep: step to %.17g goes past stopTime %.17g", end, inst->stop_time);
    inst->model_msg[0] = '\0';
    if (model_do_step(&inst->data, inst->time_ns, end_ns, inst->model_msg, sizeof inst->model_msg) != RG_OK) {
        inst->model_msg[sizeof inst->model_msg - 1] = '\0';
        return fail(inst, "fmi3DoStep: at t = %.17g: %s", t,
                    inst->model_msg[0] ? inst->model_msg : "model step failed");
    }
    inst->time_ns = end_ns;
    *lastSuccessfulTime = now(inst);
    trace(inst, "fmi3DoStep: t = %g, h = %g (to %lld ns after the start)", t, h, (long long)end_ns);
    return fmi3OK;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference;
    (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition");
}
