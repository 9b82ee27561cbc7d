/* The railguard frame layer in C (issue 42): what the Python monitor, the scenario player and
 * the brake receiver read and write on the bus, frame for frame, for the network FMUs
 * (FMI-LS-BUS CAN). The Python twins: can_bus/codec.py (Receiver, Sender, encode),
 * can_bus/runner.py (MonitorCore.ingest and decide, MonitorRunner.send), can_bus/security.py
 * and secoc.py (secured frames), can_bus/brake_receiver.py. tests/test_frames_c.py holds the
 * two sides to the same verdicts, latched values and bytes.
 *
 * Signals are packed and unpacked by rg_dbc.{c,h}, which cantools generates from
 * can_bus/railguard.dbc at build time (fmu/frames_c.py), so the DBC stays the one source of
 * truth; the range checks are the generated *_is_in_range functions (raw values). E2E: the
 * AUTOSAR profile 2 layout, CRC-8 (0x2F, init and xor 0xFF) over bytes 1..7 and the data ID
 * (the low byte of the frame ID) in byte 0, alive counter in the low nibble of byte 1.
 * Secured frames: rg_secoc.{c,h} (libcrypto's CMAC).
 *
 * Time is the shells' tick: integer milliseconds (int64_t), as runner.py stamps frames.
 * C99, no heap, no I/O, no floating point. Persistence of the freshness values (security.py
 * writes them to files) is the host's: the structs hold them as plain numbers. */
#ifndef RG_FRAMES_H
#define RG_FRAMES_H

#include <stddef.h>
#include <stdint.h>

#include "rg_core.h"
#include "rg_dbc.h"
#include "rg_secoc.h"

/* the DBC's messages, by index (rg_frames_index): BrakeDemand, the six ObstacleReports,
 * TrainState, MonitorStatus, MonitorTrack, MonitorRisk */
#define RG_FRAMES_MESSAGES 11
#define RG_MSG_BRAKE_DEMAND 0
#define RG_MSG_OBSTACLE 1            /* + channel (0..5) */
#define RG_MSG_TRAIN_STATE 7
#define RG_MSG_MONITOR_STATUS 8
#define RG_MSG_MONITOR_TRACK 9
#define RG_MSG_MONITOR_RISK 10
#define RG_FRAME_LENGTH 8            /* codec.FRAME_LENGTH: the classic frame */
#define RG_FRAME_MAX RG_SECOC_FRAME  /* 20: the secured CAN FD frame */

/* codec.py's constants */
#define RG_BABBLE_QUARANTINE_MS 500
#define RG_MAX_FRAMES_PER_WINDOW 3
#define RG_CONFLICT_WINDOW_MS 500
#define RG_SECOND_SENDER_QUARANTINE_MS 1000
/* runner.py's */
#define RG_FOREIGN_HOLD_CYCLES 10
#define RG_NO_DISTANCE_RAW 65535
#define RG_TRACK_AGE_MAX 65535
/* brake_receiver.py's */
#define RG_BRAKE_TIMEOUT_PERIODS 3

/* Verdicts: RG_ACCEPTED, or the reason a frame was refused, numbered as codec.REJECT_REASONS
 * (1..12) then codec.SHELL_REJECT_REASONS (13..18); RG_FILTERED: outside the monitor's
 * receive filter (frames.monitored: not counted as a reject, runner's tally.filtered). */
enum {
    RG_ACCEPTED = 0,
    RG_REJ_UNKNOWN_ID, RG_REJ_WRONG_LENGTH, RG_REJ_BAD_CRC, RG_REJ_REPEATED_COUNTER, RG_REJ_COUNTER_JUMP,
    RG_REJ_OUT_OF_RANGE, RG_REJ_RATE_EXCEEDED, RG_REJ_SECOND_SENDER, RG_REJ_UNDECODABLE,
    RG_REJ_STALE_FRESHNESS, RG_REJ_BAD_MAC, RG_REJ_NO_KEY,
    RG_REJ_FD_FRAME, RG_REJ_CLASSICAL_FRAME, RG_REJ_REMOTE_FRAME, RG_REJ_ERROR_FRAME, RG_REJ_FOREIGN_OUTPUT,
    RG_REJ_RECEIVE_ERROR,
    RG_FILTERED,
    RG_VERDICTS
};

/* the brakes' causes (brake_receiver.CAUSES); RG_CAUSE_NONE: a valid fresh frame stands */
enum { RG_CAUSE_NONE = -1, RG_CAUSE_POWER_UP = 0, RG_CAUSE_TIMEOUT, RG_CAUSE_SECOND_SENDER, RG_CAUSE_INVALID_LEVEL,
       RG_CAUSES };

/* frame flags of rg_monitor_ingest (as the bus gives them) */
#define RG_FRAME_EXTENDED 1u         /* a 29-bit identifier */
#define RG_FRAME_FD 2u               /* a CAN FD frame */
#define RG_FRAME_REMOTE 4u           /* a remote request */
#define RG_FRAME_ERROR 8u            /* an error frame (refused; the bus state it announces is not read here) */

/* A key set (keys.py): one AES-128 key per sender, in keys.SENDERS order: ch0..ch5, train,
 * monitor; `have` 0: the node does not hold that key (a frame of that owner: no_key). */
#define RG_KEY_CH0 0
#define RG_KEY_TRAIN 6
#define RG_KEY_MONITOR 7
#define RG_KEY_OWNERS 8
typedef struct {
    uint8_t key[RG_KEY_OWNERS][RG_SECOC_KEY];
    int32_t have[RG_KEY_OWNERS];
} rg_keyset;

/* One frame on the wire. */
typedef struct {
    uint32_t id;
    uint8_t data[RG_FRAME_MAX];
    int32_t length;                  /* 8 classic, 20 secured (CAN FD) */
    int32_t is_fd;
} rg_frame;

/* codec.SenderState: the receiver's view of one frame ID's sender. `has_*` 0: Python's None. */
typedef struct {
    int32_t has_counter;
    int32_t counter;
    int64_t recent[RG_MAX_FRAMES_PER_WINDOW + 1];   /* its newest ticks, oldest first (a deque of 4) */
    int32_t recent_count;
    int32_t has_quarantine;
    int64_t quarantine_until;        /* babbling: refused until this tick */
    int32_t has_last;
    int64_t last_tick;               /* the newest frame that passed the CRC, and its bytes */
    uint8_t last[RG_FRAME_LENGTH];
    int32_t has_contested;
    int64_t contested_until;         /* a second sender: refused until this tick */
} rg_sender_state;

/* codec.Receiver (+ security.Security's receive side when `secured`). */
typedef struct {
    /* set before the first frame (rg_receiver_init) */
    int32_t channels;                /* 6 (3oo3) or 2 (one 2oo2 module) */
    int32_t rate_window_ms;          /* 0: no babbling check; the monitor: its period */
    int32_t secured;                 /* 0: E2E only; 1: secured frames under `keys` */
    rg_keyset keys;
    int32_t has_newest[RG_FRAMES_MESSAGES];   /* secoc.FreshnessWindow: newest accepted value per ID */
    uint64_t newest[RG_FRAMES_MESSAGES];
    rg_sender_state senders[RG_FRAMES_MESSAGES];
    /* latched: the newest valid content of each message (reports[i].heard 0: never heard) */
    rg_report reports[RG_MAX_CHANNELS];
    int32_t has_train;
    rg_train train;
    int64_t train_tick;
    int32_t has_demand;
    struct rg_dbc_brake_demand_t demand;
    int64_t demand_tick;
    int32_t has_demand_invalid;
    int64_t demand_invalid;          /* tick of the newest BrakeDemand refused for its content */
    int32_t has_status, has_track, has_risk;
    struct rg_dbc_monitor_status_t status;
    struct rg_dbc_monitor_track_t track;
    struct rg_dbc_monitor_risk_t risk;
    int64_t status_tick, track_tick, risk_tick;
    /* counts */
    int64_t accepted;
    int64_t rejected[RG_VERDICTS];   /* by verdict (RG_ACCEPTED and RG_FILTERED unused) */
} rg_receiver;

/* runner.MonitorCore's receive side (live: every frame on an output ID is foreign). */
typedef struct {
    rg_receiver rx;
    int32_t period_ms;
    int64_t timeout_ticks;           /* core Setup.timeout_ticks: timeout_cycles x period_ms */
    int64_t foreign_until;           /* -1 until a foreign frame came */
    int64_t kinds[5];                /* frames.KINDS: classical, extended, fd, remote, error */
    int64_t filtered;
} rg_monitor_rx;

/* codec.Sender (+ security.Security's sending side when `secured`). */
typedef struct {
    int32_t has_counter[RG_FRAMES_MESSAGES];
    int32_t counter[RG_FRAMES_MESSAGES];      /* the last counter sent (codec: counters[id]) */
    int32_t secured;
    rg_keyset keys;
    uint64_t next_freshness[RG_FRAMES_MESSAGES];   /* secoc.FreshnessCounter.next (0 in memory) */
} rg_sender;

/* brake_receiver.BrakeReceiver. */
typedef struct {
    int32_t period_ms;
    int32_t latched;                 /* RG_CAUSE_*: an emergency held to standstill; RG_CAUSE_NONE */
    int64_t causes[RG_CAUSES];       /* periods each cause held the brakes */
    int32_t heard;
    int32_t has_silent;
    int64_t silent_ms;
} rg_brake_receiver;

/* ---- E2E and the DBC */
int32_t rg_frames_index(uint32_t frame_id);                     /* -1: not in the DBC */
uint8_t rg_frames_crc(const uint8_t data[RG_FRAME_LENGTH], uint32_t frame_id);
int32_t rg_frames_in_range(int32_t index, const uint8_t data[RG_FRAME_LENGTH]);  /* every signal in its DBC range */
int32_t rg_frames_owner(int32_t index);                         /* keys.OWNER: RG_KEY_* of a message index */

/* ---- receive */
void rg_receiver_init(rg_receiver *rx, int32_t channels, int32_t rate_window_ms, const rg_keyset *keys);
/* codec.Receiver.accept: RG_ACCEPTED (content latched) or the reason (counted). */
int32_t rg_receiver_accept(rg_receiver *rx, uint32_t frame_id, int32_t extended, const uint8_t *data, size_t length,
                           int64_t tick);
/* codec.Receiver.contested */
int32_t rg_receiver_contested(const rg_receiver *rx, uint32_t frame_id, int64_t tick);

/* Receiver of `channels` channels (2 x cfg.modules), its babbling window one period, the
 * train state's timeout timeout_cycles x period_ms (cycle.Setup.timeout_ticks); `keys` NULL:
 * an unsecured bus (classical frames), else a secured one (CAN FD frames only). */
void rg_monitor_rx_init(rg_monitor_rx *m, int32_t channels, int32_t period_ms, int32_t timeout_cycles,
                        const rg_keyset *keys);
/* runner.MonitorCore.ingest of a live monitor: filter, frame kind, foreign output, codec. */
int32_t rg_monitor_ingest(rg_monitor_rx *m, uint32_t frame_id, uint32_t flags, const uint8_t *data, size_t length,
                          int64_t tick);
/* runner.MonitorCore.decide's inputs at `tick`: the latched reports, the train state (invalid,
 * speed -1, once older than the timeout or never heard), `overruns`; *foreign_output the
 * MonitorStatus flag of the cycle. */
void rg_monitor_inputs(const rg_monitor_rx *m, int64_t tick, int32_t overruns, rg_inputs *in,
                       int32_t *foreign_output);

/* Everything a receiver latched and counted, as integers (Python's None: -1, or a 0 `has`
 * flag), in the order of fmu/frames_c.py's SNAPSHOT: for tests and for hosts that show it.
 * Returns the number written (RG_SNAPSHOT), or -1 if `size` is too small. */
#define RG_SNAPSHOT (6 * 6 + 5 + 6 + 2 + 10 + 6 + 8 + 1 + (RG_VERDICTS - 2) + 4 * RG_FRAMES_MESSAGES)
int32_t rg_receiver_snapshot(const rg_receiver *rx, int64_t *out, size_t size);
size_t rg_frames_sizeof(int32_t which);    /* 0 rg_receiver, 1 rg_monitor_rx, 2 rg_sender, 3 rg_brake_receiver */

/* ---- send */
void rg_sender_init(rg_sender *s, const rg_keyset *keys);
/* codec.Sender.frame of an 8-byte packed payload (counter and CRC are set here). 0, -1 on a
 * libcrypto failure or a frame ID the node holds no key for (Python: KeyFileError). */
int rg_sender_frame(rg_sender *s, uint32_t frame_id, const uint8_t payload[RG_FRAME_LENGTH], rg_frame *out);
/* runner.MonitorRunner.send: the cycle's frames in order (BrakeDemand left out if
 * `withhold_demand`), their number returned (3 or 4), -1 on failure. */
int rg_monitor_send(rg_sender *s, const rg_outputs *out, int32_t foreign_output, int32_t table_hash,
                    int32_t deadline_misses, int32_t period_ms, int32_t withhold_demand, rg_frame frames[4]);
/* the player: codec.report_signals / train_signals encoded by the Sender */
int rg_send_report(rg_sender *s, int32_t channel, int32_t status, int32_t distance_dm, int32_t closing_cms,
                   int32_t obstacle, rg_frame *out);
int rg_send_train(rg_sender *s, int32_t speed_cms, int32_t track, int32_t brake, rg_frame *out);

/* ---- the brakes */
void rg_brake_init(rg_brake_receiver *b, int32_t period_ms);
int32_t rg_brake_fault(rg_brake_receiver *b, const rg_receiver *rx, int64_t tick);
/* BrakeReceiver.level: 0 none, 1 service, 2 emergency; `standing`: the train's speed is 0. */
int32_t rg_brake_level(rg_brake_receiver *b, const rg_receiver *rx, int64_t tick, int32_t standing);

#endif
