/* FMI 2.0 Co-Simulation wrapper around one railguard model (see model.h).
 *
 * Everything FMI-specific lives here: instance memory, the calling-sequence state machine
 * of FMI 2.0 Co-Simulation, value-reference checks and logging. The model only computes.
 * One instance is one memory block allocated in fmi2Instantiate; nothing is allocated later.
 *
 * Error policy. Every fmi2Error is logged (category "logError", also with debug logging
 * off) and puts the instance into state `error`: the standard says the simulation cannot
 * be continued after fmi2Error, and for a safety monitor it is better to stop than to run
 * on with, say, an input that was not set. From `error` only getting values (diagnosis),
 * fmi2Reset, fmi2SetDebugLogging and fmi2FreeInstance are allowed.
 *
 * States that this FMU never enters: stepInProgress and stepCanceled (fmi2DoStep is
 * synchronous), stepFailed (fmi2DoStep never returns fmi2Discard: a failing model step is
 * an fmi2Error) and fatal (no failure here corrupts the instance).
 *
 * Log categories: "logError" (errors, always) and "logDebug" (call trace and fmi2Discard
 * notes, only with debug logging on).
 */
#define RG_FMI_EXIT_INIT "fmi2ExitInitializationMode"
#include "rg_fmi_shared.h"
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"
#include "variables.h"

#if defined(__GNUC__)
#define RG_PRINTF(f, a) __attribute__((format(printf, f, a)))
#else
#define RG_PRINTF(f, a)
#endif

/* States as bits so that "allowed in" is a mask. */
enum {
    S_INSTANTIATED = 1u << 0,
    S_INITIALIZATION_MODE = 1u << 1,
    S_STEP_COMPLETE = 1u << 2,
    S_TERMINATED = 1u << 3,
    S_ERROR = 1u << 4
};

#define M_ANY (S_INSTANTIATED | S_INITIALIZATION_MODE | S_STEP_COMPLETE | S_TERMINATED | S_ERROR)
#define M_GET (S_INITIALIZATION_MODE | S_STEP_COMPLETE | S_TERMINATED | S_ERROR)
#define M_SET (S_INSTANTIATED | S_INITIALIZATION_MODE | S_STEP_COMPLETE)
#define M_STATUS (S_STEP_COMPLETE | S_TERMINATED)

#define TEXT_SIZE 512

typedef struct {
    unsigned state;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    fmi2CallbackFreeMemory free_memory; /* matches how this block was allocated */
    int logging_on;                     /* debug messages; errors are always logged */
    int debug_category;                 /* "logDebug" selected by fmi2SetDebugLogging */
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

static const char *state_name(unsigned s)
{
    switch (s) {
    case S_INSTANTIATED: return "instantiated";
    case S_INITIALIZATION_MODE: return "initializationMode";
    case S_STEP_COMPLETE: return "stepComplete";
    case S_TERMINATED: return "terminated";
    case S_ERROR: return "error";
    default: return "unknown";
    }
}

static const char *type_name(unsigned t)
{
    switch (t) {
    case RG_T_REAL: return "Real";
    case RG_T_INTEGER: return "Integer";
    case RG_T_BOOLEAN: return "Boolean";
    case RG_T_STRING: return "String";
    default: return "unknown";
    }
}

/* ---- logging ---------------------------------------------------------------------- */

/* An FMI 2.0 logger treats the message as a printf format, and '#' starts a variable
 * reference (#r12#); both are doubled so that any text (names, model messages) is shown
 * as written. Truncates rather than overflows. */
static void emit(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, const char *name,
                 fmi2Status status, const char *category, const char *text, char *out, size_t size)
{
    size_t i, j = 0;
    if (!logger)
        return;
    for (i = 0; text[i] != '\0' && j + 2 < size; i++) {
        if (text[i] == '%' || text[i] == '#')
            out[j++] = text[i];
        out[j++] = text[i];
    }
    out[j] = '\0';
    logger(env, name, status, category, out);
}

static void vlog(Instance *inst, fmi2Status status, const char *category, const char *fmt, va_list ap)
{
    vsnprintf(inst->text, sizeof inst->text, fmt, ap);
    emit(inst->logger, inst->env, inst->name, status, category, inst->text, inst->out, sizeof inst->out);
}

static int debug_on(const Instance *inst)
{
    return inst->logging_on && inst->debug_category;
}

/* Log an error and enter state `error`; returns fmi2Error so callers can `return fail(...)`. */
static fmi2Status fail(Instance *inst, const char *fmt, ...) RG_PRINTF(2, 3);
static fmi2Status fail(Instance *inst, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vlog(inst, fmi2Error, "logError", fmt, ap);
    va_end(ap);
    inst->state = S_ERROR;
    return fmi2Error;
}

static void trace(Instance *inst, const char *fmt, ...) RG_PRINTF(2, 3);
static void trace(Instance *inst, const char *fmt, ...)
{
    va_list ap;
    if (!debug_on(inst))
        return;
    va_start(ap, fmt);
    vlog(inst, fmi2OK, "logDebug", fmt, ap);
    va_end(ap);
}

/* ---- shared checks ---------------------------------------------------------------- */

/* The instance behind `c` if the call is allowed in its state; NULL (after logging and
 * entering `error`) if not, or if `c` is NULL. */
static Instance *begin(fmi2Component c, const char *fn, unsigned allowed)
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return NULL;
    if (!(inst->state & allowed)) {
        fail(inst, "%s: not allowed in state %s", fn, state_name(inst->state));
        return NULL;
    }
    return inst;
}

static fmi2Status unsupported(fmi2Component c, const char *fn)
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return fmi2Error;
    return fail(inst, "%s: not supported by this FMU", fn);
}

static double now(const Instance *inst)
{
    return rg_time_of(inst->start_time, inst->time_ns);
}

/* Check every value reference before touching anything, so that a refused call has no
 * effect: it exists, has the type of the function and, for a set, may be set now. */
static int check_vrs(Instance *inst, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                     const void *values, unsigned type, int set)
{
    size_t i;
    if (nvr > 0 && (!vr || !values)) {
        fail(inst, "%s: NULL array for %lu value references", fn, (unsigned long)nvr);
        return 0;
    }
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
                 why, state_name(inst->state));
            return 0;
        }
    }
    return 1;
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
}

/* ---- inquiry, logging, creation ----------------------------------------------------- */

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Instance *inst = begin(c, "fmi2SetDebugLogging", M_ANY);
    size_t i;
    int selected = nCategories == 0; /* no list: all debug messages */
    if (!inst)
        return fmi2Error;
    if (nCategories > 0 && !categories)
        return fail(inst, "fmi2SetDebugLogging: NULL categories for nCategories = %lu", (unsigned long)nCategories);
    for (i = 0; i < nCategories; i++) {
        if (!categories[i])
            return fail(inst, "fmi2SetDebugLogging: category %lu is NULL", (unsigned long)i);
        /* "logError" needs no switch (errors are always logged); others are ignored */
        if (strcmp(categories[i], "logDebug") == 0 || strcmp(categories[i], "logAll") == 0)
            selected = 1;
    }
    inst->logging_on = loggingOn != fmi2False;
    inst->debug_category = selected;
    trace(inst, "fmi2SetDebugLogging: debug logging on");
    return fmi2OK;
}

/* Log why instantiation failed; there is no instance yet, so the buffers are local. */
static void instantiate_error(const fmi2CallbackFunctions *f, const char *name, const char *fmt, ...)
    RG_PRINTF(3, 4);
static void instantiate_error(const fmi2CallbackFunctions *f, const char *name, const char *fmt, ...)
{
    char text[TEXT_SIZE], out[2 * TEXT_SIZE + 1];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    emit(f->logger, f->componentEnvironment, name, fmi2Error, "logError", text, out, sizeof out);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    const char *name = instanceName ? instanceName : "";
    size_t len;
    void *block;
    Instance *inst;
    fmi2CallbackFreeMemory free_memory;

    (void)fmuResourceLocation; /* the models need no resources */
    (void)visible;
    if (!functions)
        return NULL; /* nothing to log with */
    if (name[0] == '\0') {
        instantiate_error(functions, name, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        instantiate_error(functions, name, "fmi2Instantiate: %s supports only Co-Simulation (fmuType = %d)",
                          MODEL_IDENTIFIER, (int)fmuType);
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, INSTANTIATION_TOKEN) != 0) {
        instantiate_error(functions, name, "fmi2Instantiate: GUID %s does not match %s of this binary (%s)",
                          fmuGUID ? fmuGUID : "(NULL)", INSTANTIATION_TOKEN, MODEL_IDENTIFIER);
        return NULL;
    }
    if (!rg_variables_ok()) {
        instantiate_error(functions, name, "fmi2Instantiate: inconsistent variable table or FIXED_STEP in this binary");
        return NULL;
    }

    len = strlen(name);
    if (functions->allocateMemory && functions->freeMemory) {
        block = functions->allocateMemory(1, sizeof(Instance) + len + 1);
        free_memory = functions->freeMemory;
    } else {
        block = calloc(1, sizeof(Instance) + len + 1);
        free_memory = free;
    }
    if (!block) {
        instantiate_error(functions, name, "fmi2Instantiate: out of memory");
        return NULL;
    }
    memset(block, 0, sizeof(Instance) + len + 1);
    inst = (Instance *)block;
    memcpy(inst->name, name, len + 1);
    /* copies: the environment need not keep `functions` alive */
    inst->logger = functions->logger;
    inst->env = functions->componentEnvironment;
    inst->free_memory = free_memory;
    inst->logging_on = loggingOn != fmi2False;
    inst->debug_category = 1;
    reset_instance(inst);
    trace(inst, "fmi2Instantiate: %s, fixed step %g s", MODEL_IDENTIFIER, FIXED_STEP);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    if (!inst)
        return;
    trace(inst, "fmi2FreeInstance");
    inst->free_memory(inst);
}

/* ---- initialization, termination, reset ------------------------------------------- */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *inst = begin(c, "fmi2SetupExperiment", S_INSTANTIATED);
    (void)toleranceDefined; /* fixed-step model: no error control */
    (void)tolerance;
    if (!inst)
        return fmi2Error;
    if (!rg_isfinite(startTime))
        return fail(inst, "fmi2SetupExperiment: startTime %g is not finite", startTime);
    if (stopTimeDefined && !(stopTime >= startTime))
        return fail(inst, "fmi2SetupExperiment: stopTime %g is before startTime %g", stopTime, startTime);
    inst->start_time = startTime;
    inst->stop_time_defined = stopTimeDefined != fmi2False;
    inst->stop_time = stopTime;
    trace(inst, "fmi2SetupExperiment: startTime %g", startTime);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *inst = begin(c, "fmi2EnterInitializationMode", S_INSTANTIATED);
    if (!inst)
        return fmi2Error;
    inst->state = S_INITIALIZATION_MODE;
    trace(inst, "fmi2EnterInitializationMode");
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = begin(c, "fmi2ExitInitializationMode", S_INITIALIZATION_MODE);
    if (!inst)
        return fmi2Error;
    inst->model_msg[0] = '\0';
    if (model_initialize(&inst->data, inst->model_msg, sizeof inst->model_msg) != RG_OK) {
        inst->model_msg[sizeof inst->model_msg - 1] = '\0';
        return fail(inst, "fmi2ExitInitializationMode: %s",
                    inst->model_msg[0] ? inst->model_msg : "model initialisation failed");
    }
    inst->state = S_STEP_COMPLETE;
    trace(inst, "fmi2ExitInitializationMode");
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = begin(c, "fmi2Terminate", S_STEP_COMPLETE);
    if (!inst)
        return fmi2Error;
    inst->state = S_TERMINATED;
    trace(inst, "fmi2Terminate at t = %g", now(inst));
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = begin(c, "fmi2Reset", M_ANY);
    if (!inst)
        return fmi2Error;
    reset_instance(inst);
    trace(inst, "fmi2Reset");
    return fmi2OK;
}

/* ---- getting and setting values --------------------------------------------------- */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *inst = begin(c, "fmi2GetReal", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2GetReal", vr, nvr, value, RG_T_REAL, 0))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        value[i] = VARIABLES[vr[i]].causality == RG_C_INDEPENDENT ? now(inst) : model_get_real(&inst->data, vr[i]);
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    Instance *inst = begin(c, "fmi2GetInteger", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2GetInteger", vr, nvr, value, RG_T_INTEGER, 0))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        value[i] = (fmi2Integer)model_get_integer(&inst->data, vr[i]);
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    Instance *inst = begin(c, "fmi2GetBoolean", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2GetBoolean", vr, nvr, value, RG_T_BOOLEAN, 0))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        value[i] = model_get_boolean(&inst->data, vr[i]) ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    Instance *inst = begin(c, "fmi2GetString", M_GET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2GetString", vr, nvr, value, RG_T_STRING, 0))
        return fmi2Error;
    for (i = 0; i < nvr; i++) {
        const char *s = model_get_string(&inst->data, vr[i]);
        value[i] = s ? s : "";
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *inst = begin(c, "fmi2SetReal", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2SetReal", vr, nvr, value, RG_T_REAL, 1))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        model_set_real(&inst->data, vr[i], value[i]);
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    Instance *inst = begin(c, "fmi2SetInteger", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2SetInteger", vr, nvr, value, RG_T_INTEGER, 1))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        model_set_integer(&inst->data, vr[i], (int32_t)value[i]);
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    Instance *inst = begin(c, "fmi2SetBoolean", M_SET);
    size_t i;
    if (!inst || !check_vrs(inst, "fmi2SetBoolean", vr, nvr, value, RG_T_BOOLEAN, 1))
        return fmi2Error;
    for (i = 0; i < nvr; i++)
        model_set_boolean(&inst->data, vr[i], value[i] != fmi2False);
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    Instance *inst = begin(c, "fmi2SetString", M_SET);
    if (!inst || !check_vrs(inst, "fmi2SetString", vr, nvr, value, RG_T_STRING, 1))
        return fmi2Error;
    /* model.h has no string setter: a settable String variable cannot be served */
    if (nvr > 0)
        return fail(inst, "fmi2SetString: variable %s: setting String variables is not supported",
                    VARIABLES[vr[0]].name);
    return fmi2OK;
}

/* ---- FMU state, derivatives: not supported (canGetAndSetFMUstate = false etc.) ------ */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return unsupported(c, "fmi2GetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    (void)FMUstate;
    return unsupported(c, "fmi2SetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return unsupported(c, "fmi2FreeFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size)
{
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* ---- Model Exchange: not supported (Co-Simulation only) --------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    return unsupported(c, "fmi2EnterEventMode");
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *fmi2eventInfo)
{
    (void)fmi2eventInfo;
    return unsupported(c, "fmi2NewDiscreteStates");
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    return unsupported(c, "fmi2EnterContinuousTimeMode");
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    (void)enterEventMode;
    (void)terminateSimulation;
    return unsupported(c, "fmi2CompletedIntegratorStep");
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    (void)time;
    return unsupported(c, "fmi2SetTime");
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    (void)x;
    (void)nx;
    return unsupported(c, "fmi2SetContinuousStates");
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    (void)derivatives;
    (void)nx;
    return unsupported(c, "fmi2GetDerivatives");
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    (void)eventIndicators;
    (void)ni;
    return unsupported(c, "fmi2GetEventIndicators");
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    (void)x;
    (void)nx;
    return unsupported(c, "fmi2GetContinuousStates");
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    (void)x_nominal;
    (void)nx;
    return unsupported(c, "fmi2GetNominalsOfContinuousStates");
}

/* ---- Co-Simulation ---------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = begin(c, "fmi2DoStep", S_STEP_COMPLETE);
    double t, h = communicationStepSize, end;
    int64_t end_ns;
    const char *why;
    (void)noSetFMUStatePriorToCurrentPoint; /* no FMU states are kept */
    if (!inst)
        return fmi2Error;
    t = now(inst);
    if (!rg_at_time(currentCommunicationPoint, t))
        return fail(inst, "fmi2DoStep: currentCommunicationPoint %.17g differs from the FMU time %.17g",
                    currentCommunicationPoint, t);
    why = rg_bad_step(h);
    if (why)
        return fail(inst, "fmi2DoStep: communicationStepSize %.17g %s", h, why);
    end_ns = rg_step_end_ns(inst->start_time, inst->time_ns, currentCommunicationPoint, h);
    if (end_ns < 0)
        return fail(inst, "fmi2DoStep: communicationStepSize %.17g: the step ends beyond the FMU's time range (2^62 ns)", h);
    end = rg_time_of(inst->start_time, end_ns);
    if (inst->stop_time_defined && end > inst->stop_time + 1e-9 * rg_fmax(1.0, rg_fabs(inst->stop_time)))
        return fail(inst, "fmi2DoStep: step to %.17g goes past stopTime %.17g", end, inst->stop_time);
    inst->model_msg[0] = '\0';
    if (model_do_step(&inst->data, inst->time_ns, end_ns, inst->model_msg, sizeof inst->model_msg) != RG_OK) {
        inst->model_msg[sizeof inst->model_msg - 1] = '\0';
        return fail(inst, "fmi2DoStep: at t = %.17g: %s", t,
                    inst->model_msg[0] ? inst->model_msg : "model step failed");
    }
    inst->time_ns = end_ns;
    trace(inst, "fmi2DoStep: t = %g, h = %g (to %lld ns after the start)", t, h, (long long)end_ns);
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    /* only allowed in stepInProgress, which this synchronous FMU never enters */
    return unsupported(c, "fmi2CancelStep");
}

/* ---- status inquiry ----------------------------------------------------------------
 * The standard: "If a status is required which cannot be retrieved by the slave it
 * returns fmi2Discard." That is what happens for the kinds about asynchronous steps
 * (fmi2DoStep never returns fmi2Pending). Two kinds have a real answer: the last
 * successful time is the FMU time, and the slave never asks to terminate. fmi2Discard
 * does not change the state; the note is logged only with debug logging on. */

static fmi2Status status_discard(Instance *inst, const char *fn, fmi2StatusKind s)
{
    if (debug_on(inst)) {
        snprintf(inst->text, sizeof inst->text,
                 "%s: status kind %d not supported (this FMU never returns fmi2Pending or fmi2Discard from fmi2DoStep)",
                 fn, (int)s);
        emit(inst->logger, inst->env, inst->name, fmi2Discard, "logDebug", inst->text, inst->out, sizeof inst->out);
    }
    return fmi2Discard;
}

static Instance *begin_status(fmi2Component c, const char *fn, const void *value)
{
    Instance *inst = begin(c, fn, M_STATUS);
    if (inst && !value) {
        fail(inst, "%s: value is NULL", fn);
        return NULL;
    }
    return inst;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    Instance *inst = begin_status(c, "fmi2GetStatus", value);
    if (!inst)
        return fmi2Error;
    return status_discard(inst, "fmi2GetStatus", s);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *inst = begin_status(c, "fmi2GetRealStatus", value);
    if (!inst)
        return fmi2Error;
    if (s != fmi2LastSuccessfulTime)
        return status_discard(inst, "fmi2GetRealStatus", s);
    *value = now(inst);
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    Instance *inst = begin_status(c, "fmi2GetIntegerStatus", value);
    if (!inst)
        return fmi2Error;
    return status_discard(inst, "fmi2GetIntegerStatus", s);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    Instance *inst = begin_status(c, "fmi2GetBooleanStatus", value);
    if (!inst)
        return fmi2Error;
    if (s != fmi2Terminated)
        return status_discard(inst, "fmi2GetBooleanStatus", s);
    *value = fmi2False; /* the model never asks to end the simulation */
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    Instance *inst = begin_status(c, "fmi2GetStringStatus", value);
    if (!inst)
        return fmi2Error;
    return status_discard(inst, "fmi2GetStringStatus", s);
}
