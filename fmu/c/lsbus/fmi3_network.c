/* FMI 3.0 Co-Simulation wrapper for network FMUs (rg_network.h): Event Mode, Clocks and
 * Binaries, as FMI-LS-BUS needs them. Built with -DDISABLE_PREFIX (plain fmi3XXX names).
 *
 * States: Instantiated -> InitializationMode -> EventMode <-> StepMode -> Terminated. A network
 * FMU must be instantiated with eventModeUsed (its clocks tick only in Event Mode); without it
 * instantiation fails with a message. Every fmi3Error is logged under "logError" and moves the
 * instance to Terminated, as the standard prescribes. Every function of fmi3Functions.h is
 * defined (importers bind them all by name); the ones a network FMU does not support log and
 * return fmi3Error. One memory block per instance, allocated once. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "rg_network.h"
#include "net_variables.h"

enum { S_INSTANTIATED = 1, S_INIT = 2, S_EVENT = 4, S_STEP = 8, S_TERMINATED = 16 };
#define S_ANY (S_INSTANTIATED | S_INIT | S_EVENT | S_STEP | S_TERMINATED)
#define S_SET_PARAM (S_INSTANTIATED | S_INIT)

typedef struct {
    unsigned state;
    fmi3LogMessageCallback log_message;
    fmi3InstanceEnvironment env;
    int logging_on;
    double start_time;
    int64_t time_ns;                 /* since start_time */
    NetData data;
    char msg[256];
    char text[640];
    char name[];
} Instance;

static void logf_(Instance *inst, fmi3Status status, const char *category, const char *fmt, ...)
{
    va_list ap;
    if (!inst->log_message)
        return;
    va_start(ap, fmt);
    vsnprintf(inst->text, sizeof inst->text, fmt, ap);
    va_end(ap);
    inst->log_message(inst->env, status, category, inst->text);
}

static fmi3Status fail(Instance *inst, const char *fmt, const char *a, const char *b)
{
    char line[400];
    snprintf(line, sizeof line, fmt, a, b);
    logf_(inst, fmi3Error, "logError", "%s: %s", inst->name, line);
    inst->state = S_TERMINATED;
    return fmi3Error;
}

static int allowed(Instance *inst, unsigned mask, const char *fn)
{
    if (!inst)
        return 0;
    if (inst->state & mask)
        return 1;
    fail(inst, "%s is not allowed in this state%s", fn, "");
    return 0;
}

static const rg_nvar *find(uint32_t vr)
{
    size_t i;
    for (i = 0; i < N_NVARS; i++)
        if (NVARS[i].vr == vr)
            return &NVARS[i];
    return NULL;
}

/* The variable `vr` of `type`, settable now if `set`; NULL (and Terminated) otherwise. */
static const rg_nvar *check_var(Instance *inst, uint32_t vr, int type, int set, const char *fn)
{
    const rg_nvar *v = find(vr);
    if (!v || v->type != type) {
        char ref[24];
        snprintf(ref, sizeof ref, "%u", (unsigned)vr);
        fail(inst, "%s: no variable of this type with value reference %s", fn, ref);
        return NULL;
    }
    if (set) {
        int ok = (v->causality == RG_NC_PARAMETER && (inst->state & S_SET_PARAM)) ||
                 (v->causality == RG_NC_INPUT && (inst->state & (S_INIT | S_EVENT | S_STEP | S_INSTANTIATED)));
        if (!ok) {
            fail(inst, "%s: %s may not be set now", fn, v->name);
            return NULL;
        }
    }
    return v;
}

static int64_t to_ns(double seconds) { return (int64_t)llround(seconds * 1e9); }

/* ---- lifecycle -------------------------------------------------------------------- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    Instance *inst = (Instance *)instance;
    (void)nCategories;
    (void)categories;
    if (!inst)
        return fmi3Error;
    inst->logging_on = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Instance *inst;
    const char *name = instanceName ? instanceName : "";
    (void)visible;
    (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        if (logMessage)
            logMessage(env, fmi3Error, "logError", "instantiation token does not match this FMU's");
        return NULL;
    }
    if (!eventModeUsed) {
        if (logMessage)
            logMessage(env, fmi3Error, "logError",
                       "a network FMU needs Event Mode (eventModeUsed = true): its clocks tick only there");
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof(Instance) + strlen(name) + 1);
    if (!inst)
        return NULL;
    strcpy(inst->name, name);
    inst->log_message = logMessage;
    inst->env = env;
    inst->logging_on = loggingOn;
    inst->state = S_INSTANTIATED;
    net_start_values(&inst->data);
    net_set_resources(&inst->data, resourcePath ? resourcePath : "");
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String a, fmi3String b, fmi3String c, fmi3Boolean d, fmi3Boolean e,
                                          fmi3InstanceEnvironment f, fmi3LogMessageCallback log)
{
    (void)a; (void)b; (void)c; (void)d; (void)e;
    if (log)
        log(f, fmi3Error, "logError", "this FMU supports Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String a, fmi3String b, fmi3String c, fmi3Boolean d,
                                               fmi3Boolean e, fmi3InstanceEnvironment f, fmi3LogMessageCallback log,
                                               fmi3ClockUpdateCallback g, fmi3LockPreemptionCallback h,
                                               fmi3UnlockPreemptionCallback i)
{
    (void)a; (void)b; (void)c; (void)d; (void)e; (void)g; (void)h; (void)i;
    if (log)
        log(f, fmi3Error, "logError", "this FMU supports Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (inst)
        net_terminate(&inst->data);        /* idempotent: also after fmi3Terminate or an error */
    free(instance);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Instance *inst = (Instance *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!allowed(inst, S_INSTANTIATED, "fmi3EnterInitializationMode"))
        return fmi3Error;
    inst->start_time = startTime;
    inst->time_ns = 0;
    inst->state = S_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!allowed(inst, S_INIT, "fmi3ExitInitializationMode"))
        return fmi3Error;
    if (net_initialize(&inst->data, inst->msg, sizeof inst->msg) != RG_NET_OK)
        return fail(inst, "initialisation refused: %s%s", inst->msg, "");
    inst->state = S_EVENT;           /* with eventModeUsed, initialisation ends in Event Mode */
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!allowed(inst, S_STEP | S_EVENT, "fmi3EnterEventMode"))
        return fmi3Error;
    inst->state = S_EVENT;
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!allowed(inst, S_EVENT | S_STEP, "fmi3EnterStepMode"))
        return fmi3Error;
    inst->state = S_STEP;
    return fmi3OK;
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsChanged,
                                    fmi3Boolean *valuesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    Instance *inst = (Instance *)instance;
    int more;
    if (!allowed(inst, S_EVENT, "fmi3UpdateDiscreteStates"))
        return fmi3Error;
    more = net_update_discrete_states(&inst->data, inst->time_ns);
    if (discreteStatesNeedUpdate) *discreteStatesNeedUpdate = more ? fmi3True : fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (nominalsChanged) *nominalsChanged = fmi3False;
    if (valuesChanged) *valuesChanged = fmi3False;
    if (nextEventTimeDefined) *nextEventTimeDefined = fmi3False;
    if (nextEventTime) *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Instance *inst = (Instance *)instance;
    int64_t from, to;
    int event = 0;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (!allowed(inst, S_STEP, "fmi3DoStep"))
        return fmi3Error;
    if (communicationStepSize < 0 || !isfinite(communicationStepSize))
        return fail(inst, "fmi3DoStep: the communication step must be a finite number >= 0%s%s", "", "");
    from = to_ns(currentCommunicationPoint - inst->start_time);
    to = to_ns(currentCommunicationPoint + communicationStepSize - inst->start_time);
    if (from != inst->time_ns && llabs((long long)(from - inst->time_ns)) > 1)
        return fail(inst, "fmi3DoStep: currentCommunicationPoint is not where the last step ended%s%s", "", "");
    from = inst->time_ns;
    if (to < from)
        to = from;
    if (net_do_step(&inst->data, from, to, &event, inst->msg, sizeof inst->msg) != RG_NET_OK)
        return fail(inst, "step failed: %s%s", inst->msg, "");
    inst->time_ns = to;
    if (eventHandlingNeeded) *eventHandlingNeeded = event ? fmi3True : fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = inst->start_time + (double)to / 1e9;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    if (!allowed(inst, S_INIT | S_EVENT | S_STEP | S_TERMINATED, "fmi3Terminate"))
        return fmi3Error;
    net_terminate(&inst->data);
    inst->state = S_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    Instance *inst = (Instance *)instance;
    char resources[RG_NET_STRING];
    if (!inst)
        return fmi3Error;
    net_terminate(&inst->data);
    memcpy(resources, inst->data.resources, sizeof resources);
    memset(&inst->data, 0, sizeof inst->data);
    net_start_values(&inst->data);
    net_set_resources(&inst->data, resources);
    inst->time_ns = 0;
    inst->state = S_INSTANTIATED;
    return fmi3OK;
}

/* ---- values ----------------------------------------------------------------------- */

#define GETTER(Fn, CType, TYPE, expr)                                                                        \
    fmi3Status Fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, CType values[], size_t nv) \
    {                                                                                                        \
        Instance *inst = (Instance *)instance;                                                               \
        size_t i;                                                                                            \
        if (!allowed(inst, S_ANY, #Fn))                                                                      \
            return fmi3Error;                                                                                \
        if (nv < nvr)                                                                                        \
            return fail(inst, "%s: fewer values than value references%s", #Fn, "");                         \
        for (i = 0; i < nvr; i++) {                                                                          \
            if (!check_var(inst, vr[i], TYPE, 0, #Fn))                                                       \
                return fmi3Error;                                                                            \
            values[i] = expr;                                                                                \
        }                                                                                                    \
        return fmi3OK;                                                                                       \
    }

GETTER(fmi3GetFloat64, fmi3Float64, RG_NT_FLOAT64, net_get_float64(&inst->data, vr[i]))
GETTER(fmi3GetInt32, fmi3Int32, RG_NT_INT32, net_get_int32(&inst->data, vr[i]))
GETTER(fmi3GetBoolean, fmi3Boolean, RG_NT_BOOLEAN, net_get_boolean(&inst->data, vr[i]) ? fmi3True : fmi3False)
GETTER(fmi3GetString, fmi3String, RG_NT_STRING, net_get_string(&inst->data, vr[i]))

#define SETTER(Fn, CType, TYPE, stmt)                                                                        \
    fmi3Status Fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const CType values[],     \
                  size_t nv)                                                                                 \
    {                                                                                                        \
        Instance *inst = (Instance *)instance;                                                               \
        size_t i;                                                                                            \
        if (!allowed(inst, S_INSTANTIATED | S_INIT | S_EVENT | S_STEP, #Fn))                                 \
            return fmi3Error;                                                                                \
        if (nv < nvr)                                                                                        \
            return fail(inst, "%s: fewer values than value references%s", #Fn, "");                         \
        for (i = 0; i < nvr; i++) {                                                                          \
            if (!check_var(inst, vr[i], TYPE, 1, #Fn))                                                       \
                return fmi3Error;                                                                            \
            stmt;                                                                                            \
        }                                                                                                    \
        return fmi3OK;                                                                                       \
    }

SETTER(fmi3SetFloat64, fmi3Float64, RG_NT_FLOAT64, net_set_float64(&inst->data, vr[i], values[i]))
SETTER(fmi3SetInt32, fmi3Int32, RG_NT_INT32, net_set_int32(&inst->data, vr[i], values[i]))
SETTER(fmi3SetBoolean, fmi3Boolean, RG_NT_BOOLEAN, net_set_boolean(&inst->data, vr[i], values[i] ? 1 : 0))
SETTER(fmi3SetString, fmi3String, RG_NT_STRING, net_set_string(&inst->data, vr[i], values[i] ? values[i] : ""))

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nv)
{
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(inst, S_ANY, "fmi3GetBinary"))
        return fmi3Error;
    if (nv < nvr)
        return fail(inst, "fmi3GetBinary: fewer values than value references%s%s", "", "");
    for (i = 0; i < nvr; i++) {
        const uint8_t *data;
        size_t size;
        if (!check_var(inst, vr[i], RG_NT_BINARY, 0, "fmi3GetBinary"))
            return fmi3Error;
        net_get_binary(&inst->data, vr[i], &data, &size);
        if (inst->logging_on)
            logf_(inst, fmi3OK, "logDebug", "t=%.9f GetBinary %u: %u bytes", (double)inst->time_ns / 1e9,
                  (unsigned)vr[i], (unsigned)size);
        values[i] = data;
        valueSizes[i] = size;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nv)
{
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(inst, S_EVENT | S_INIT | S_INSTANTIATED, "fmi3SetBinary"))
        return fmi3Error;
    if (nv < nvr)
        return fail(inst, "fmi3SetBinary: fewer values than value references%s%s", "", "");
    for (i = 0; i < nvr; i++) {
        if (!check_var(inst, vr[i], RG_NT_BINARY, 1, "fmi3SetBinary"))
            return fmi3Error;
        if (inst->logging_on)
            logf_(inst, fmi3OK, "logDebug", "t=%.9f SetBinary %u: %u bytes", (double)inst->time_ns / 1e9,
                  (unsigned)vr[i], (unsigned)valueSizes[i]);
        if (net_set_binary(&inst->data, vr[i], values[i], valueSizes[i], inst->time_ns, inst->msg, sizeof inst->msg) !=
            RG_NET_OK)
            return fail(inst, "fmi3SetBinary: %s%s", inst->msg, "");
    }
    return fmi3OK;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[])
{
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(inst, S_EVENT | S_INIT | S_STEP, "fmi3GetClock"))
        return fmi3Error;
    for (i = 0; i < nvr; i++) {
        const rg_nvar *v = check_var(inst, vr[i], RG_NT_CLOCK, 0, "fmi3GetClock");
        if (!v)
            return fmi3Error;
        values[i] = (v->causality == RG_NC_OUTPUT && net_get_clock(&inst->data, vr[i])) ? fmi3ClockActive
                                                                                         : fmi3ClockInactive;
        if (inst->logging_on)
            logf_(inst, fmi3OK, "logDebug", "t=%.9f GetClock %u: %d", (double)inst->time_ns / 1e9, (unsigned)vr[i],
                  (int)values[i]);
    }
    return fmi3OK;
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[])
{
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(inst, S_EVENT, "fmi3SetClock"))
        return fmi3Error;
    for (i = 0; i < nvr; i++) {
        const rg_nvar *v = check_var(inst, vr[i], RG_NT_CLOCK, 0, "fmi3SetClock");
        if (!v)
            return fmi3Error;
        if (v->causality != RG_NC_INPUT)
            return fail(inst, "fmi3SetClock: %s is not an input clock%s", v->name, "");
        if (inst->logging_on)
            logf_(inst, fmi3OK, "logDebug", "t=%.9f SetClock %u: %d", (double)inst->time_ns / 1e9, (unsigned)vr[i],
                  (int)values[i]);
        if (values[i])
            net_set_clock(&inst->data, vr[i], inst->time_ns);
    }
    return fmi3OK;
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[])
{
    Instance *inst = (Instance *)instance;
    size_t i;
    if (!allowed(inst, S_EVENT | S_STEP | S_INIT, "fmi3GetIntervalDecimal"))
        return fmi3Error;
    for (i = 0; i < nvr; i++) {
        int64_t interval = 0;
        if (!check_var(inst, vr[i], RG_NT_CLOCK, 0, "fmi3GetIntervalDecimal"))
            return fmi3Error;
        if (net_get_interval(&inst->data, vr[i], inst->time_ns, &interval)) {
            intervals[i] = (double)interval / 1e9;
            qualifiers[i] = fmi3IntervalChanged;
            if (inst->logging_on)
                logf_(inst, fmi3OK, "logDebug", "t=%.9f interval of %u: %.9f", (double)inst->time_ns / 1e9,
                      (unsigned)vr[i], intervals[i]);
        } else {
            intervals[i] = 0.0;
            qualifiers[i] = fmi3IntervalNotYetKnown;
        }
    }
    return fmi3OK;
}

/* ---- not supported: log and refuse ------------------------------------------------ */

static fmi3Status unsupported(fmi3Instance instance, const char *fn)
{
    Instance *inst = (Instance *)instance;
    if (!inst)
        return fmi3Error;
    return fail(inst, "%s is not supported by this FMU%s", fn, "");
}

#define UNSUPPORTED_GET(Fn, CType)                                                                           \
    fmi3Status Fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, CType values[], size_t nv) \
    {                                                                                                        \
        (void)vr; (void)nvr; (void)values; (void)nv;                                                         \
        return unsupported(instance, #Fn);                                                                   \
    }
#define UNSUPPORTED_SET(Fn, CType)                                                                           \
    fmi3Status Fn(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const CType values[],     \
                  size_t nv)                                                                                 \
    {                                                                                                        \
        (void)vr; (void)nvr; (void)values; (void)nv;                                                         \
        return unsupported(instance, #Fn);                                                                   \
    }
UNSUPPORTED_GET(fmi3GetFloat32, fmi3Float32)
UNSUPPORTED_GET(fmi3GetInt8, fmi3Int8)
UNSUPPORTED_GET(fmi3GetUInt8, fmi3UInt8)
UNSUPPORTED_GET(fmi3GetInt16, fmi3Int16)
UNSUPPORTED_GET(fmi3GetUInt16, fmi3UInt16)
UNSUPPORTED_GET(fmi3GetUInt32, fmi3UInt32)
UNSUPPORTED_GET(fmi3GetInt64, fmi3Int64)
UNSUPPORTED_GET(fmi3GetUInt64, fmi3UInt64)
UNSUPPORTED_SET(fmi3SetFloat32, fmi3Float32)
UNSUPPORTED_SET(fmi3SetInt8, fmi3Int8)
UNSUPPORTED_SET(fmi3SetUInt8, fmi3UInt8)
UNSUPPORTED_SET(fmi3SetInt16, fmi3Int16)
UNSUPPORTED_SET(fmi3SetUInt16, fmi3UInt16)
UNSUPPORTED_SET(fmi3SetUInt32, fmi3UInt32)
UNSUPPORTED_SET(fmi3SetInt64, fmi3Int64)
UNSUPPORTED_SET(fmi3SetUInt64, fmi3UInt64)

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance i, fmi3ValueReference vr, size_t *n)
{ (void)vr; (void)n; return unsupported(i, "fmi3GetNumberOfVariableDependencies"); }
fmi3Status fmi3GetVariableDependencies(fmi3Instance i, fmi3ValueReference a, size_t b[], fmi3ValueReference c[],
                                       size_t d[], fmi3DependencyKind e[], size_t f)
{ (void)a; (void)b; (void)c; (void)d; (void)e; (void)f; return unsupported(i, "fmi3GetVariableDependencies"); }
fmi3Status fmi3GetFMUState(fmi3Instance i, fmi3FMUState *s) { (void)s; return unsupported(i, "fmi3GetFMUState"); }
fmi3Status fmi3SetFMUState(fmi3Instance i, fmi3FMUState s) { (void)s; return unsupported(i, "fmi3SetFMUState"); }
fmi3Status fmi3FreeFMUState(fmi3Instance i, fmi3FMUState *s) { (void)s; return unsupported(i, "fmi3FreeFMUState"); }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance i, fmi3FMUState s, size_t *n)
{ (void)s; (void)n; return unsupported(i, "fmi3SerializedFMUStateSize"); }
fmi3Status fmi3SerializeFMUState(fmi3Instance i, fmi3FMUState s, fmi3Byte b[], size_t n)
{ (void)s; (void)b; (void)n; return unsupported(i, "fmi3SerializeFMUState"); }
fmi3Status fmi3DeserializeFMUState(fmi3Instance i, const fmi3Byte b[], size_t n, fmi3FMUState *s)
{ (void)b; (void)n; (void)s; return unsupported(i, "fmi3DeserializeFMUState"); }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance i, const fmi3ValueReference a[], size_t b,
                                        const fmi3ValueReference c[], size_t d, const fmi3Float64 e[], size_t f,
                                        fmi3Float64 g[], size_t h)
{ (void)a; (void)b; (void)c; (void)d; (void)e; (void)f; (void)g; (void)h;
  return unsupported(i, "fmi3GetDirectionalDerivative"); }
fmi3Status fmi3GetAdjointDerivative(fmi3Instance i, const fmi3ValueReference a[], size_t b,
                                    const fmi3ValueReference c[], size_t d, const fmi3Float64 e[], size_t f,
                                    fmi3Float64 g[], size_t h)
{ (void)a; (void)b; (void)c; (void)d; (void)e; (void)f; (void)g; (void)h;
  return unsupported(i, "fmi3GetAdjointDerivative"); }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance i) { return unsupported(i, "fmi3EnterConfigurationMode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance i) { return unsupported(i, "fmi3ExitConfigurationMode"); }
fmi3Status fmi3GetIntervalFraction(fmi3Instance i, const fmi3ValueReference a[], size_t b, fmi3UInt64 c[],
                                   fmi3UInt64 d[], fmi3IntervalQualifier e[])
{ (void)a; (void)b; (void)c; (void)d; (void)e; return unsupported(i, "fmi3GetIntervalFraction"); }
fmi3Status fmi3GetShiftDecimal(fmi3Instance i, const fmi3ValueReference a[], size_t b, fmi3Float64 c[])
{ (void)a; (void)b; (void)c; return unsupported(i, "fmi3GetShiftDecimal"); }
fmi3Status fmi3GetShiftFraction(fmi3Instance i, const fmi3ValueReference a[], size_t b, fmi3UInt64 c[],
                                fmi3UInt64 d[])
{ (void)a; (void)b; (void)c; (void)d; return unsupported(i, "fmi3GetShiftFraction"); }
fmi3Status fmi3SetIntervalDecimal(fmi3Instance i, const fmi3ValueReference a[], size_t b, const fmi3Float64 c[])
{ (void)a; (void)b; (void)c; return unsupported(i, "fmi3SetIntervalDecimal"); }
fmi3Status fmi3SetIntervalFraction(fmi3Instance i, const fmi3ValueReference a[], size_t b, const fmi3UInt64 c[],
                                   const fmi3UInt64 d[])
{ (void)a; (void)b; (void)c; (void)d; return unsupported(i, "fmi3SetIntervalFraction"); }
fmi3Status fmi3SetShiftDecimal(fmi3Instance i, const fmi3ValueReference a[], size_t b, const fmi3Float64 c[])
{ (void)a; (void)b; (void)c; return unsupported(i, "fmi3SetShiftDecimal"); }
fmi3Status fmi3SetShiftFraction(fmi3Instance i, const fmi3ValueReference a[], size_t b, const fmi3UInt64 c[],
                                const fmi3UInt64 d[])
{ (void)a; (void)b; (void)c; (void)d; return unsupported(i, "fmi3SetShiftFraction"); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance i) { return unsupported(i, "fmi3EvaluateDiscreteStates"); }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance i) { return unsupported(i, "fmi3EnterContinuousTimeMode"); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance i, fmi3Boolean a, fmi3Boolean *b, fmi3Boolean *c)
{ (void)a; (void)b; (void)c; return unsupported(i, "fmi3CompletedIntegratorStep"); }
fmi3Status fmi3SetTime(fmi3Instance i, fmi3Float64 t) { (void)t; return unsupported(i, "fmi3SetTime"); }
fmi3Status fmi3SetContinuousStates(fmi3Instance i, const fmi3Float64 a[], size_t b)
{ (void)a; (void)b; return unsupported(i, "fmi3SetContinuousStates"); }
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance i, fmi3Float64 a[], size_t b)
{ (void)a; (void)b; return unsupported(i, "fmi3GetContinuousStateDerivatives"); }
fmi3Status fmi3GetEventIndicators(fmi3Instance i, fmi3Float64 a[], size_t b)
{ (void)a; (void)b; return unsupported(i, "fmi3GetEventIndicators"); }
fmi3Status fmi3GetContinuousStates(fmi3Instance i, fmi3Float64 a[], size_t b)
{ (void)a; (void)b; return unsupported(i, "fmi3GetContinuousStates"); }
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance i, fmi3Float64 a[], size_t b)
{ (void)a; (void)b; return unsupported(i, "fmi3GetNominalsOfContinuousStates"); }
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance i, size_t *n)
{ (void)n; return unsupported(i, "fmi3GetNumberOfEventIndicators"); }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance i, size_t *n)
{ (void)n; return unsupported(i, "fmi3GetNumberOfContinuousStates"); }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance i, const fmi3ValueReference a[], size_t b, const fmi3Int32 c[],
                                    fmi3Float64 d[], size_t e)
{ (void)a; (void)b; (void)c; (void)d; (void)e; return unsupported(i, "fmi3GetOutputDerivatives"); }
fmi3Status fmi3ActivateModelPartition(fmi3Instance i, fmi3ValueReference c, fmi3Float64 t)
{ (void)c; (void)t; return unsupported(i, "fmi3ActivateModelPartition"); }
