"""Bad input through the front door: Hypothesis-driven fuzzing of the CAN receive path.

What runs is the real shell: `can_bus.runner.MonitorRunner` on an in-memory python-can bus
with the simulated clock. Each frame is put on the bus at its arrival time and the runner's
own `drain()` takes it (`MonitorCore.ingest`: kind tally, receive filter, FD/remote/error
refusal, foreign frames on the output IDs, then `Receiver.accept` with per-ID rate policing,
the E2E CRC, alive counter, range checks; the rate window is one period, as the runner sets
it); at every period boundary the runner's own `cycle()` steps the core
(`monitor.core.cycle.step`) with the latched reports, returns its CycleRecord and sends its
three frames.

What goes in: one Hypothesis example is one stream. Hypothesis draws the shipped table
(m1, m2), the topology (3oo3, 2oo2), a traffic profile and an 8 KB byte string; the byte
string is read as a program whose instructions make frames and move time (`Traffic`):
  * nominal cycles: every channel and the TrainState, consistent, with persistent faults
    (2oo2 disagreement, a distance offset, a silent or degraded channel, a silent or bad train);
  * valid frames of every DBC message, encoded by the codec (`codec.Sender`: CRC and counter),
    the monitor's own output IDs 0x010/0x040/0x041 among them (foreign frames);
  * mutated valid frames: bit flips, byte changes, truncation, extension up to 64 bytes,
    counter replay and jump, payload replacement, IDs swapped (DBC, 11-bit, 29-bit), the
    extended/remote/error/FD flags, then the CRC recomputed or not;
  * fully random frames: 11-bit, 29-bit and out-of-spec IDs, remote and error frames, FD,
    lengths 0..64, a DLC that disagrees with the data;
  * hostile frames the shell refuses or drops: CAN FD frames (valid payloads too), remote
    requests and controller error frames (warning, passive, bus-off, restart) on the
    monitored IDs, frames on the output IDs 0x010/0x040/0x041, 29-bit and unmonitored 11-bit
    neighbours of the monitored IDs;
  * signals out of their DBC range with a valid CRC and counter (module/channel mismatch too);
  * babbling bursts (4..23 frames of one sender, 0..39 ms apart; valid, with bad CRC or wrong
    length, or interleaved with FD/remote frames on the same ID), replays of earlier frames,
    small time steps, explicit cycles and silences of up to 40 periods.

What is checked, after every frame and every cycle:
  * no exception escapes the runner (`drain`, `cycle`); an exception swallowed inside the
    core's fail-safe (`step` returning its SAFE_STOP fallback) counts as one too;
  * accounting: each frame moves exactly one counter by exactly one (accepted, one reject
    reason, or `filtered`) and the kind tally by one, the runner counts it as received, and
    per stream frames received = accepted + sum of rejected by reason + filtered;
  * the reason: a reference receiver written here from the DBC and the documented rules
    (own classification, own receive filter, own CRC-8 0x2F, own bit unpacking, the rate
    window and quarantine) predicts the outcome of every frame, the frame's kind, the bus
    state error frames announce, the latched reports and TrainState; the runner must agree;
  * every cycle: the CycleRecord it returns agrees with `runner.outputs` and with the
    reference (the TrainState speed it used, the ForeignOutput diagnostic), and it sent
    BrakeDemand, MonitorStatus and MonitorTrack in this order, each with a valid CRC, its
    alive counter one on from the last cycle's and its unused bits 0, carrying the demand
    and reasons, the mode and ForeignOutput bit, and the track (state, memory bit, distance,
    age) as the core's outputs give it;
  * domains: every latched report is absent or (status 0..2, distance 0..60000 dm, closing
    -15000..15000 cm/s, obstacle 0..2, integer tick <= now), the TrainState is absent or in
    range; the core's State (mode 0..3, node < table nodes, seen within the channel mask,
    held demand level 0..2, disagree/healthy/error counts >= 0, cycle +1 per cycle) and Outputs
    (demand 0..2, reasons < 16384, distance 0..60000 or 65535, observation < table
    observations, module flags, node/mode/cycle equal to the state's), the documented mode
    rules (INIT and SAFE_STOP demand emergency; the demand is never below the level held:
    an emergency held demands emergency, a service held at least service) and the obstacle
    memory (track state 0..5; a track distance 0..60000 exactly while a track is remembered,
    NO_DISTANCE otherwise, the State agreeing; unvoted cycles counting up while held or
    confirming, 0 otherwise; the memory reason exactly when the track is nearer than the
    voted obstacle).
A stream stops at its first exception or violation, so a fault is counted once and does
not cascade; the report keeps the first few with the frame's bytes.

`run(frames, progress, seed)` returns the figures; `section(out_dir, quick, progress)` is
the verification part (quick: 20,000 frames in one process; full: 1,000,000 frames over two
processes).

The pieces, one concept each: `reference` (the DBC and the receive rules read independently:
the oracle), `stats` (the figures), `harness` (the real runner on an in-memory bus, and the
checks after every frame and cycle), `traffic` (the byte string read as a traffic program),
`streams` (Hypothesis streams, worker jobs, `run`) and `part` (`section`). This package
re-exports their public names, so `from verification import fuzz` reads as before.
"""
from __future__ import annotations

from .reference import (
    ACCEPTED, BABBLE_QUARANTINE_MS, BRAKE_DEMAND, BUS_STATES, CAN_ERR_FLAG, CTRL_ACTIVE, CTRL_PASSIVE, CTRL_WARNING,
    DBC_IDS, ERR_BUSOFF, ERR_CRTL, ERR_RESTARTED, FILTERED, FOREIGN_HOLD_CYCLES, INPUTS, KINDS, LAYOUT,
    MAX_FRAMES_PER_WINDOW, MONITORED, MONITOR_RISK, MONITOR_STATUS, MONITOR_TRACK, OBSTACLES, OUTPUTS, SHELL_REASON, TRAIN_STATE,
    UNUSED, ReferenceReceiver, announced_state, crc8_h2f, e2e_crc, frame_kind, in_dbc_range, unpack,
)
from .stats import MAX_EXAMPLES_KEPT, Stats, describe
from .harness import FrontDoorBus, Harness, StreamStop, setup_for
from .traffic import (
    CTRL_BYTES, ERROR_CLASSES, FAULTS, FD_LENGTHS, MONITORED_IDS, OP_TABLES, PROFILES, PROFILE_NAMES, SPEEDS,
    TAPE_BYTES, UNMONITORED_NEIGHBOURS, Tape, TapeEnd, Traffic,
)
from .streams import CHUNK_FRAMES, MAX_FAULTS, STREAM_FRAMES, fuzz_chunk, run, run_stream, stream_strategy
from .part import COVERED_REASONS, FULL_FRAMES, MODE_NAMES, QUICK_FRAMES, UNREACHABLE_REASONS, section

__all__ = [
    "ACCEPTED", "BABBLE_QUARANTINE_MS", "BRAKE_DEMAND", "BUS_STATES", "CAN_ERR_FLAG", "CTRL_ACTIVE", "CTRL_PASSIVE",
    "CTRL_WARNING", "DBC_IDS", "ERR_BUSOFF", "ERR_CRTL", "ERR_RESTARTED", "FILTERED", "FOREIGN_HOLD_CYCLES", "INPUTS",
    "KINDS", "LAYOUT", "MAX_FRAMES_PER_WINDOW", "MONITORED", "MONITOR_RISK", "MONITOR_STATUS", "MONITOR_TRACK", "OBSTACLES", "OUTPUTS",
    "SHELL_REASON", "TRAIN_STATE", "UNUSED", "ReferenceReceiver",
    "announced_state", "crc8_h2f", "e2e_crc", "frame_kind", "in_dbc_range", "unpack", "MAX_EXAMPLES_KEPT", "Stats",
    "describe", "FrontDoorBus", "Harness", "StreamStop", "setup_for", "CTRL_BYTES", "ERROR_CLASSES", "FAULTS",
    "FD_LENGTHS", "MONITORED_IDS", "OP_TABLES", "PROFILES", "PROFILE_NAMES", "SPEEDS", "TAPE_BYTES",
    "UNMONITORED_NEIGHBOURS", "Tape", "TapeEnd", "Traffic", "CHUNK_FRAMES", "MAX_FAULTS", "STREAM_FRAMES", "fuzz_chunk",
    "run", "run_stream", "stream_strategy", "COVERED_REASONS", "FULL_FRAMES", "MODE_NAMES", "QUICK_FRAMES",
    "UNREACHABLE_REASONS", "section",
]
