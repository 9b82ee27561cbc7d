"""The fuzzing as a verification part: `section(out_dir, quick, progress)`.

Quick mode puts 20,000 frames through the receive path, full mode 1,000,000; the checks are
no exception, no invariant violation, exact accounting, and coverage of every reachable
reject reason, input ID, frame kind, bus state and mode; the Markdown explains the rules.
"""
from __future__ import annotations

from pathlib import Path

from can_bus import codec

from ..report import Check, Progress, Section, md_table
from .reference import ACCEPTED, BUS_STATES, FILTERED, INPUTS, KINDS, OUTPUTS
from .streams import run
from .traffic import TAPE_BYTES


QUICK_FRAMES = 20_000
FULL_FRAMES = 1_000_000


# Reject reasons the fuzzing must produce: the codec's and the shell's, except those no frame
# through this front door can earn:
UNREACHABLE_REASONS = {
    # python-can's recv raising CanError (a broken socket): a virtual bus cannot produce it
    "receive_error": "needs a failing interface",
    # the codec's net for an exception inside its checks: a fault, never a frame's due (the
    # reference never predicts it, so every occurrence is a reason violation)
    "undecodable": "only a codec fault",
    # the receive filter (rule 2) passes only the DBC's own IDs to the codec, and the output
    # IDs stop at rule 4: no frame reaches the codec's unknown-ID check any more (the
    # reference keeps the rule, so one would still show as a mismatch)
    "unknown_id": "the receive filter passes only DBC IDs",
    # the monitor holds a key for every ID it reads (issue 39's secured streams)
    "no_key": "the monitor holds every key",
}
COVERED_REASONS = tuple(r for r in codec.REJECT_REASONS + codec.SHELL_REJECT_REASONS if r not in UNREACHABLE_REASONS)
MODE_NAMES = ("INIT", "NORMAL", "DEGRADED", "SAFE_STOP")


def section(out_dir, quick: bool, progress: Progress) -> Section:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = QUICK_FRAMES if quick else FULL_FRAMES
    title = "Front-door fuzzing (CAN receive path)"
    try:
        import hypothesis  # noqa: F401
    except ImportError as exc:
        return Section(title, f"Hypothesis is not installed (`pip install hypothesis`): {exc}\n",
                       [Check("fuzz: runs (needs hypothesis)", False, f"ImportError: {exc}")])
    progress(f"fuzz: {target:,} Hypothesis-generated frames into the runner's receive path")
    r = run(target, progress)
    accepted, rej_total = r["accepted"], r["rejected_total"]
    missing_reasons = [x for x in COVERED_REASONS if not r["rejected"].get(x)]
    missing_reasons += [FILTERED] if not r["filtered"] else []
    missing_ids = [f"0x{i:02X}" for i in sorted(INPUTS) if not r["accepted_ids"].get(f"0x{i:02X}")]
    missing_ids += [f"0x{i:02X} (foreign)" for i in OUTPUTS if not r["foreign_ids"].get(f"0x{i:02X}")]
    missing_modes = [MODE_NAMES[m] for m in range(4) if not r["modes"].get(m)]
    missing_other = [k for k in KINDS if not r["frame_kinds"].get(k)]
    missing_other += [st for st in BUS_STATES if not r["bus_states"].get(st)]
    missing_other += ["ForeignOutput cycle"] if not r["foreign_cycles"] else []
    missing = missing_reasons or missing_ids or missing_modes or missing_other
    checks = [
        Check("fuzz: frames through the receive path", r["frames"] >= target,
              f"{r['frames']:,} >= {target:,} in {r['seconds']:.1f} s ({r['frames_per_s']:,.0f} frames/s)",
              {"frames": r["frames"], "seconds": round(r["seconds"], 2), "workers": r["workers"]}),
        Check("fuzz: no exception (runner, receiver, core)", r["exceptions"] == 0 and r["harness_errors"] == 0,
              f"{r['exceptions']} exceptions, {r['harness_errors']} harness errors",
              {"examples": [e for e in r["examples"] if e["kind"] in ("exception", "harness")][:3]}),
        Check("fuzz: no invariant violation (domains, reference receiver)", r["violations"] == 0,
              f"{r['violations']} violations" + (f" {r['violations_by_kind']}" if r["violations"] else ""),
              {"examples": [e for e in r["examples"] if e["kind"] not in ("exception", "harness")][:3]}),
        Check("fuzz: accounting exact (received = accepted + rejected by reason + filtered)",
              r["accounting_exact"] and r["reference_agrees"],
              f"{r['frames']:,} = {accepted:,} + {rej_total:,} + {r['filtered']:,}; "
              f"per-frame errors {r['accounting_errors']}",
              {"rejected": r["rejected"], "filtered": r["filtered"]}),
        Check("fuzz: coverage (every reachable reject reason and filtered, every input accepted, every output "
              "ID foreign, every frame kind and bus state, ForeignOutput, every mode)",
              not missing,
              "complete" if not missing else
              f"missing reasons {missing_reasons}, IDs {missing_ids}, modes {missing_modes}, other {missing_other}",
              {"not reachable here": UNREACHABLE_REASONS}),
    ]
    md = [_SECTION_TEXT.format(target=target, mode="quick" if quick else "full", tape=TAPE_BYTES)]
    md.append(md_table(["frames", "accepted", "rejected", "filtered", "exceptions", "violations",
                        "streams (examples)", "cycles", "time (s)", "frames/s", "workers"],
                       [[f"{r['frames']:,}", f"{accepted:,}", f"{rej_total:,}", f"{r['filtered']:,}", r["exceptions"],
                         r["violations"], f"{r['streams']:,}", f"{r['cycles']:,}", f"{r['seconds']:.1f}",
                         f"{r['frames_per_s']:,.0f}", r["workers"]]]))
    md.append("\nRejected frames by reason (the runner's counters; the reference receiver's prediction):\n\n")
    reasons = list(codec.REJECT_REASONS) + list(codec.SHELL_REJECT_REASONS)
    reasons += sorted(k for k in r["rejected"] if k not in reasons)
    md.append(md_table(["reason", "frames", "reference"],
                       [[k + (f" (not reachable here: {UNREACHABLE_REASONS[k]})" if k in UNREACHABLE_REASONS else ""),
                         f"{r['rejected'].get(k, 0):,}", f"{r['expected'].get(k, 0):,}"] for k in reasons]
                       + [[FILTERED, f"{r['filtered']:,}", f"{r['expected'].get(FILTERED, 0):,}"],
                          [ACCEPTED, f"{accepted:,}", f"{r['expected'].get(ACCEPTED, 0):,}"]]))
    md.append("\nFrames by kind (the runner's tally), bus states announced by error frames, frames by generator, "
              "accepted frames by message, foreign frames by ID, cycles by mode "
              f"({r['foreign_cycles']:,} cycles with ForeignOutput set):\n\n")
    md.append(md_table(["frame kind", "frames"], [[k, f"{r['frame_kinds'].get(k, 0):,}"] for k in KINDS]))
    md.append("\n" + md_table(["bus state", "announced"], [[k, f"{r['bus_states'].get(k, 0):,}"] for k in BUS_STATES]))
    md.append("\n" + md_table(["generator", "frames"], [[k, f"{v:,}"] for k, v in sorted(r["kinds"].items())]))
    md.append("\n" + md_table(["message", "accepted"], [[k, f"{v:,}"] for k, v in sorted(r["accepted_ids"].items())]))
    md.append("\n" + md_table(["output ID", "foreign frames"], [[k, f"{v:,}"] for k, v in r["foreign_ids"].items()]))
    md.append("\n" + md_table(["mode", "cycles"], [[MODE_NAMES[m] if 0 <= int(m) < 4 else m, f"{v:,}"]
                                                  for m, v in sorted(r["modes"].items())]))
    if r["examples"]:
        md.append("\nFirst faults found (frame bytes to reproduce):\n\n")
        md.append(md_table(["kind", "what", "frame", "stream"],
                           [[e["kind"], e.get("what", ""), e.get("frame", ""),
                             f"{e.get('table')}/{e.get('topology')}/{e.get('profile')} seed {e.get('hypothesis_seed')} "
                             f"example {e.get('example')} frame {e.get('frame_index')}"] for e in r["examples"]]))
    return Section(title, "".join(md), checks)


_SECTION_TEXT = """\
{target:,} frames ({mode} mode) went through the real receive path: `MonitorRunner.drain()` on an in-memory
python-can bus with the simulated clock, and at every period boundary `MonitorRunner.cycle()`, which steps
the core (`monitor.core.cycle.step`) with the latched reports, returns the cycle's record and sends
BrakeDemand, MonitorStatus and MonitorTrack. The receive rules, in order, for each frame: (1) it is counted by kind
(classical, 29-bit, FD, remote, error; an error frame also announces a bus state); (2) outside the receive
filter (not an error frame, and 29-bit or an ID other than 0x010, 0x020-0x025, 0x030, 0x040, 0x041) it is
counted as filtered, not as a reject (live, it never reaches the process); (3) an FD, remote or error
frame is refused (`fd_frame`, `remote_frame`, `error_frame`); (4) a frame on the monitor's own output IDs
0x010, 0x040 and 0x041 is foreign (`foreign_output`) and sets the ForeignOutput diagnostic in every cycle within
one second (10 periods) of it; (5) the codec: on an input ID every frame counts for the rate policing
before its length and CRC are looked at, and more than 3 frames within one period quarantine the ID for
500 ms after its last excess frame (`rate_exceeded`, the channel's report withdrawn, its alive counter
forgotten); then `wrong_length`, `bad_crc`, `repeated_counter`/`counter_jump`, `out_of_range`, and the
report latched. Every third stream runs on the secured bus (issue 39; fixed test keys): there FD frames are
the decoded kind and a classical one is refused (`classical_frame`), and after the rate policing a frame
must be 20 bytes, carry a new freshness value (`stale_freshness`) and an authenticator that verifies under
its ID owner's key (`bad_mac`, which refuses the ID as a second sender); the traffic seals most 8-byte
frames, flips bits of some, signs some under a wrong key, replays earlier ones and leaves some classical,
and the reference checks each with its own CMAC and freshness arithmetic, and every frame the monitor sends
for its freshness and authenticator.

**Frames.** One Hypothesis example is one stream: the table (m1, m2), the topology (3oo3, 2oo2), a traffic
profile and a {tape:,}-byte string read as a program of nominal cycles with persistent faults, valid frames
of every DBC message (encoded by the codec; those on the output IDs are foreign), mutated frames (bit flips,
byte changes, truncation, extension up to 64 bytes, counter replay and jump, payload replacement, swapped
IDs, 29-bit, remote, error and FD flags, CRC recomputed or not), fully random frames (11-bit, 29-bit and
out-of-spec IDs, lengths 0..64), hostile frames (CAN FD with valid payloads, remote requests and controller
error frames on the monitored IDs, frames on 0x010/0x040/0x041, 29-bit and unmonitored neighbours of the
monitored IDs), signals out of range with a valid CRC, babbling bursts (valid, with broken CRCs or lengths,
or interleaved with FD/remote frames on the same ID), replays, and time steps, cycles and silences. Time
moves as in the runner's loop with every cycle on time: frames arrive between two ticks, and the cycle at a
tick sees what arrived up to it (deadline overruns are outside this part).

**Checks after every frame and cycle.** No exception escapes the runner, and the core's fail-safe never
swallows one. Each frame moves exactly one counter by one (accepted, one reject reason, or filtered) and
the kind tally by one, and frames received = accepted + rejected + filtered per stream. A reference
receiver written from the DBC and the rules above (its own classification, receive filter, CRC-8 and bit
unpacking) predicts every frame's outcome and kind, the bus state, the latched reports and TrainState:
the runner must agree. Every cycle's record agrees with the core's outputs and the reference (TrainState
speed, ForeignOutput), and it sent BrakeDemand, MonitorStatus and MonitorTrack in this order, each with a
valid CRC, its alive counter one on and its unused bits 0, carrying the demand and reasons, the mode and
the ForeignOutput bit, and the remembered obstacle (state, memory bit, distance, age) as the core gives it.
Latched reports stay in their domain (status 0..2, distance 0..60000 dm, closing -15000..15000 cm/s,
obstacle 0..2, tick <= now), and so do the core's state (mode, node < table nodes, held demand level 0..2,
counters) and outputs (demand 0..2, reasons < 16384, distance 0..60000 or 65535), with emergency in INIT and
SAFE_STOP and the demand never below the level held; the obstacle memory is consistent (track state 0..5, a
distance 0..60000 exactly while a track is remembered, its unvoted cycles counting up while held, the
memory reason exactly when the remembered obstacle is the nearer). A stream stops at its first fault.

"""
