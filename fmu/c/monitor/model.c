/* The monitor FMU's model: FMI values in, one core cycle per 100 ms, FMI values out.
 * Any communication step: the cycles whose instants fall in the step run (model_do_step).
 *
 * Real inputs are read into the core's integer units towards the safe side: distance
 * rounded down to dm, closing and train speed rounded up to cm/s. NaN or a value outside
 * its range becomes a value the core refuses (the channel counts as DEGRADED, the train
 * state as a train-input error). fmu/reference.py does exactly the same in Python. */
#include "rg_reading.h"
#include <stdio.h>

#include "model.h"
#include "rg_table.h"
#include "variables.h"

#define CH_FIELDS 5
typedef char channel_layout_check[(vr_ch2_status - vr_ch1_status == CH_FIELDS &&
                                   vr_ch1_distance == vr_ch1_status + 1 && vr_ch1_closing_speed == vr_ch1_status + 2 &&
                                   vr_ch1_type == vr_ch1_status + 3 && vr_ch1_valid == vr_ch1_status + 4 &&
                                   vr_ch6_valid == vr_ch1_status + 6 * CH_FIELDS - 1) ? 1 : -1];

static void set_outputs_start(ModelData *m)
{
    m->outputs.demand = RG_EMERGENCY;
    m->outputs.reasons = RG_R_INIT;
    m->outputs.distance_dm = RG_NO_DISTANCE;
    m->outputs.node = (int32_t)RG_TABLE_START;
    m->outputs.mode = RG_INIT;
    m->outputs.module_flags = 0;
    m->outputs.system_error = 0;
    m->outputs.observation = 0;
    m->outputs.cycle = 0;
    m->outputs.error_cycles = 0;
    m->outputs.warning = 0;
    m->outputs.track_dm = RG_NO_DISTANCE;
    m->outputs.track_cycles = 0;
    m->outputs.track_state = RG_TRACK_NONE;
    m->outputs.r1_ppm = 0;
    m->outputs.r2_ppm = 0;
    m->outputs.risk_score = 0;
    m->outputs.risk_category = 1;
    m->outputs.table_risk_ppm = (int32_t)((uint32_t)RG_TABLE_BYTES[RG_TABLE_RISK_OFFSET + 4u * RG_TABLE_START]
        | ((uint32_t)RG_TABLE_BYTES[RG_TABLE_RISK_OFFSET + 4u * RG_TABLE_START + 1u] << 8)
        | ((uint32_t)RG_TABLE_BYTES[RG_TABLE_RISK_OFFSET + 4u * RG_TABLE_START + 2u] << 16)
        | ((uint32_t)RG_TABLE_BYTES[RG_TABLE_RISK_OFFSET + 4u * RG_TABLE_START + 3u] << 24));
}

#define SET_START(name, start) m->params.name = (start);
#define GET_PARAMETER(name, start) case vr_##name: return m->params.name;
#define SET_PARAMETER(name, start) case vr_##name: m->params.name = v; break;

void model_set_start_values(ModelData *m)
{
    int i;
    rg_config_default(&m->params);
    RG_PARAMETERS(SET_START)
    m->topology = RG_START_TOPOLOGY;
    for (i = 0; i < RG_MAX_CHANNELS; i++) {
        m->status[i] = 0;
        m->type[i] = 0;
        m->valid[i] = 0;
        m->distance[i] = 0.0;
        m->closing[i] = 0.0;
        m->inputs.reports[i].heard = 0;
        m->inputs.reports[i].status = 0;
        m->inputs.reports[i].distance_dm = 0;
        m->inputs.reports[i].closing_cms = 0;
        m->inputs.reports[i].obstacle = 0;
        m->inputs.reports[i].tick = 0;
    }
    m->speed = 0.0;
    m->track = 0;
    m->brake = 0;
    m->inputs.overruns = 0;
    m->cycles = 0;
    m->table.bytes = RG_TABLE_BYTES;
    m->table.length = RG_TABLE_LENGTH;
    m->table.action_offset = RG_TABLE_ACTION_OFFSET;
    m->table.next_offset = RG_TABLE_NEXT_OFFSET;
    m->table.risk_offset = RG_TABLE_RISK_OFFSET;
    m->table.nodes = RG_TABLE_NODES;
    m->table.observations = RG_TABLE_OBSERVATIONS;
    m->table.index_bytes = RG_TABLE_INDEX_BYTES;
    m->table.start = RG_TABLE_START;
    m->table.model = RG_TABLE_MODEL;
    m->table.period_ms = RG_TABLE_PERIOD_MS;
    set_outputs_start(m);
}

int model_initialize(ModelData *m, char *msg, size_t len)
{
    static const char hex[] = "0123456789abcdef";
    static const char expected[] = RG_TABLE_SHA256;
    rg_config *c = &m->config;
    int i;
    if (m->topology != 3 && m->topology != 2) {
        snprintf(msg, len, "topology = %ld: must be 3 (3oo3) or 2 (a single 2oo2 module)", (long)m->topology);
        return RG_ERROR;
    }
    *c = m->params;
    c->modules = m->topology == 3 ? 3 : 1;
    if (rg_config_check(c, msg, len) != 0) return RG_ERROR;
    if (rg_table_check(&m->table, c, msg, len) != 0) return RG_ERROR;
    /* the compiled-in hash must be the one the table's own trailer holds */
    for (i = 0; i < 32; i++) {
        uint8_t b = m->table.bytes[m->table.length - 32 + (uint32_t)i];
        if (expected[2 * i] != hex[b >> 4] || expected[2 * i + 1] != hex[b & 15]) {
            snprintf(msg, len, "table refused: its SHA-256 differs from the one it was built with (%s)", expected);
            return RG_ERROR;
        }
    }
    rg_initial_state(&m->table, c, &m->state);
    set_outputs_start(m);
    m->cycles = 0;
    return RG_OK;
}

/* The monitor is a sampled controller. Cycle k runs at its tick instant k * period_ms
 * (ns since the start: k * period_ms * 10^6, exact integers), with the inputs as they are
 * at that instant, i.e. as set before the communication step that contains it. A step
 * from from_ns to to_ns runs every cycle whose instant lies in [from_ns, to_ns): the
 * instant at the start of a step belongs to that step, the one at its end to the next.
 * At 100 ms steps this is one cycle per step, the cycle at the step's start, as always.
 * Between cycles the outputs hold; the outputs at time t are those of the last cycle
 * before t (INIT before the first step). */
int model_do_step(ModelData *m, int64_t from_ns, int64_t to_ns, char *msg, size_t len)
{
    const int64_t period_ns = (int64_t)m->config.period_ms * 1000000;
    int i;
    if (period_ns <= 0 || to_ns < from_ns) {
        snprintf(msg, len, "bad step from %lld ns to %lld ns (period %lld ns)", (long long)from_ns,
                 (long long)to_ns, (long long)period_ns);
        return RG_ERROR;
    }
    while (m->cycles * period_ns < to_ns) {
        int64_t tick = m->cycles * m->config.period_ms;
        for (i = 0; i < RG_MAX_CHANNELS; i++) {
            if (m->valid[i]) {
                rg_report *r = &m->inputs.reports[i];
                r->heard = 1;
                r->status = m->status[i];
                r->distance_dm = read_distance_dm(m->distance[i]);
                r->closing_cms = read_closing_cms(m->closing[i]);
                r->obstacle = m->type[i];
                r->tick = tick;
            }
        }
        m->inputs.train.speed_cms = read_speed_cms(m->speed);
        m->inputs.train.track = m->track;
        m->inputs.train.brake = m->brake;
        rg_step(&m->config, &m->table, &m->state, &m->inputs, tick, &m->outputs);
        m->cycles++;
    }
    return RG_OK;
}

static int channel_of(uint32_t vr, int *field)
{
    if (vr < (uint32_t)vr_ch1_status || vr > (uint32_t)vr_ch6_valid) return -1;
    *field = (int)((vr - (uint32_t)vr_ch1_status) % CH_FIELDS);
    return (int)((vr - (uint32_t)vr_ch1_status) / CH_FIELDS);
}

double model_get_real(const ModelData *m, uint32_t vr)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) return field == 1 ? m->distance[ch] : m->closing[ch];
    if (vr == vr_train_speed) return m->speed;
    return 0.0;
}

int32_t model_get_integer(const ModelData *m, uint32_t vr)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) return field == 0 ? m->status[ch] : m->type[ch];
    switch (vr) {
    case vr_train_track_condition: return m->track;
    case vr_train_brake_status: return m->brake;
    RG_PARAMETERS(GET_PARAMETER)
    case vr_topology: return m->topology;
    case vr_brake_demand: return m->outputs.demand;
    case vr_reasons: return m->outputs.reasons;
    case vr_voted_distance_dm: return m->outputs.distance_dm;
    case vr_node: return m->outputs.node;
    case vr_mode: return m->outputs.mode;
    case vr_module_flags: return m->outputs.module_flags;
    case vr_observation: return m->outputs.observation;
    case vr_cycle: return m->outputs.cycle;
    case vr_error_cycles: return m->outputs.error_cycles;
    case vr_track_dm: return m->outputs.track_dm;
    case vr_track_cycles: return m->outputs.track_cycles;
    case vr_track_state: return m->outputs.track_state;
    case vr_r1_ppm: return m->outputs.r1_ppm;
    case vr_r2_ppm: return m->outputs.r2_ppm;
    case vr_risk_score: return m->outputs.risk_score;
    case vr_risk_category: return m->outputs.risk_category;
    case vr_table_risk_ppm: return m->outputs.table_risk_ppm;
    case vr_period_ms: return RG_TABLE_PERIOD_MS;
    case vr_table_nodes: return (int32_t)RG_TABLE_NODES;
    default: return 0;
    }
}

int model_get_boolean(const ModelData *m, uint32_t vr)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) return m->valid[ch] != 0;
    if (vr == vr_system_error) return m->outputs.system_error != 0;
    if (vr == vr_warning) return m->outputs.warning != 0;
    return 0;
}

const char *model_get_string(const ModelData *m, uint32_t vr)
{
    (void)m;
    if (vr == vr_table_model) return RG_TABLE_MODEL_NAME;
    if (vr == vr_table_sha256) return RG_TABLE_SHA256;
    return "";
}

void model_set_real(ModelData *m, uint32_t vr, double v)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) {
        if (field == 1) m->distance[ch] = v;
        else m->closing[ch] = v;
    } else if (vr == vr_train_speed) {
        m->speed = v;
    }
}

void model_set_integer(ModelData *m, uint32_t vr, int32_t v)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) {
        if (field == 0) m->status[ch] = v;
        else m->type[ch] = v;
        return;
    }
    switch (vr) {
    case vr_train_track_condition: m->track = v; break;
    case vr_train_brake_status: m->brake = v; break;
    RG_PARAMETERS(SET_PARAMETER)
    case vr_topology: m->topology = v; break;
    default: break;
    }
}

void model_set_boolean(ModelData *m, uint32_t vr, int v)
{
    int field = 0, ch = channel_of(vr, &field);
    if (ch >= 0) m->valid[ch] = v != 0;
}
