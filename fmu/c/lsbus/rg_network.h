/* The contract between the FMI 3.0 wrapper of network FMUs (fmi3_network.c) and one network
 * model (bus/, player/, ...): FMUs with FMI-LS-BUS terminals, which need what the signal FMUs'
 * wrapper (fmu/c/fmi/fmi3.c) does not have: Event Mode, Clocks and Binaries.
 *
 * The model folder's config.h defines MODEL_IDENTIFIER, INSTANTIATION_TOKEN and the struct
 * NetData (plain data, fixed arrays: no heap). The build generates net_variables.h/.c: the
 * value references and NVARS[] (type and causality), so the wrapper refuses an unknown
 * variable, a wrong type or a set that is not allowed now. Time is whole nanoseconds. */
#ifndef RG_NETWORK_H
#define RG_NETWORK_H

#include <stddef.h>
#include <stdint.h>

#define RG_NET_STRING 256            /* a String parameter's longest value, terminator included */
enum { RG_NT_FLOAT64 = 0, RG_NT_INT32 = 1, RG_NT_BOOLEAN = 2, RG_NT_STRING = 3, RG_NT_BINARY = 4, RG_NT_CLOCK = 5 };
enum { RG_NC_PARAMETER = 0, RG_NC_INPUT = 1, RG_NC_OUTPUT = 2, RG_NC_INDEPENDENT = 3 };

typedef struct {
    uint32_t vr;
    uint8_t type;
    uint8_t causality;
    const char *name;
} rg_nvar;

enum { RG_NET_OK = 0, RG_NET_ERROR = 1 };

#include "config.h"                  /* NetData (which may use the definitions above) */

void net_start_values(NetData *m);
/* The FMU's resources folder (a file: URI or a path, as the importer gives it), at instantiation. */
void net_set_resources(NetData *m, const char *resource_path);
/* Terminate or free: release what net_initialize opened (a trace file). */
void net_terminate(NetData *m);
/* Leaving initialisation: check parameters and set up; on error `msg` says why. */
int net_initialize(NetData *m, char *msg, size_t len);
/* Step mode: advance from `from_ns` to `to_ns`; *event_needed = 1 when the model has something
 * to hand over in Event Mode (a Tx clock to raise). */
int net_do_step(NetData *m, int64_t from_ns, int64_t to_ns, int *event_needed, char *msg, size_t len);
/* Event Mode at `now_ns`: one super-dense step; returns 1 if another one is needed. */
int net_update_discrete_states(NetData *m, int64_t now_ns);

double net_get_float64(const NetData *m, uint32_t vr);
int32_t net_get_int32(const NetData *m, uint32_t vr);
int net_get_boolean(const NetData *m, uint32_t vr);
const char *net_get_string(const NetData *m, uint32_t vr);
void net_set_float64(NetData *m, uint32_t vr, double v);
void net_set_int32(NetData *m, uint32_t vr, int32_t v);
void net_set_boolean(NetData *m, uint32_t vr, int v);
void net_set_string(NetData *m, uint32_t vr, const char *v);

/* A clocked Tx binary: its value for the current clock tick (valid until the next call). */
void net_get_binary(NetData *m, uint32_t vr, const uint8_t **data, size_t *size);
/* A clocked Rx binary received at `now_ns`; RG_NET_ERROR if it cannot be taken (msg says why). */
int net_set_binary(NetData *m, uint32_t vr, const uint8_t *data, size_t size, int64_t now_ns, char *msg, size_t len);
/* An output clock: active now? (reading it deactivates it, as FMI 3.0 says). */
int net_get_clock(NetData *m, uint32_t vr);
/* An input clock ticked by the importer at `now_ns`. */
void net_set_clock(NetData *m, uint32_t vr, int64_t now_ns);
/* A countdown clock: 1 with *interval_ns the time to its next tick, 0 if not yet known. */
int net_get_interval(NetData *m, uint32_t vr, int64_t now_ns, int64_t *interval_ns);

#endif
