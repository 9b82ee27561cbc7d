"""A recorded bus replayed through the FMI-LS-BUS system: the frames of a candump log that the
monitor did not send are played by a player node at their recorded times, the monitor network
FMU decides on them, and its frames, taken from the bus simulation's trace, are compared with
the frames the recorded (Python) monitor sent, cycle by cycle.

This is how the C monitor on the simulated bus is held to the Python monitor of `railguard run`
(the same MonitorRunner on the in-process bus and on vcan0): the same traffic must give the
same decisions. The payloads are compared (the classical frame, the first 8 bytes of a secured
one: level, reasons, cycle, counters and CRC); the freshness values and MACs of secured frames
differ by design (the C node's freshness counters start in memory)."""
from __future__ import annotations

import csv
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import can

from cantools.autosar.end_to_end import check_profile2_crc

from can_bus.codec import BRAKE_DEMAND_ID, FRAME_LENGTH, OUTPUT_IDS, data_id
from can_bus.security import for_node

from .build import BuildError
from .lsbus_system import STEP_S, Node, build_bus, build_container, build_player, run_container
from .network_nodes import build_monitor_node

REPLAY_PHASE_MS = 1     # a real-time log's monitor node decides 1 ms after its tick (on_ticks)


@dataclass
class Replay:
    compared: int = 0
    mismatches: list = field(default_factory=list)     # (cycle, frame ID, recorded payload hex, replayed hex)
    recorded: int = 0
    replayed: int = 0
    trace: Optional[Path] = None

    @property
    def identical(self) -> bool:
        return not self.mismatches and self.compared > 0 and self.compared == min(self.recorded, self.replayed)


def own_frames(msgs, keys: Optional[Path]) -> set:
    """The indices of the recorded monitor's own frames among `msgs`: on a secured bus those
    on its output IDs that verify under its key and are new (a forged frame fails the MAC, a
    replayed one is stale); unsecured, those whose CRC holds and whose alive counter steps by
    one per ID (codec's E2E). Every other frame on an output ID is traffic the monitor received."""
    own = set()
    if keys is not None:
        security = for_node(keys, "replay-check", ["monitor"], state=False)
        for i, m in enumerate(msgs):
            if m.arbitration_id in OUTPUT_IDS and security.open(m.arbitration_id, bytes(m.data))[0] == "ok":
                own.add(i)
        return own
    last: dict = {}
    for i, m in enumerate(msgs):
        fid, data = m.arbitration_id, bytes(m.data)
        if fid not in OUTPUT_IDS or len(data) != FRAME_LENGTH or not check_profile2_crc(data, data_id(fid)):
            continue
        if fid in last and (data[1] - last[fid]) & 0xF != 1:
            continue
        last[fid] = data[1] & 0xF
        own.add(i)
    return own


def read_log(path: Path, keys: Optional[Path] = None) -> tuple[list, list]:
    """(the inputs: (t, id, is_fd, data) of every frame the recorded monitor did not send,
    the monitor's frames: (t, id, data)), times from the log's first frame."""
    try:
        msgs = [m for m in can.LogReader(str(path)) if not m.is_error_frame]
    except (OSError, ValueError) as exc:
        raise BuildError(f"{path}: not a readable candump log ({exc})") from None
    if not msgs:
        raise BuildError(f"{path}: no frames")
    t0 = msgs[0].timestamp
    own = own_frames(msgs, keys)
    inputs = [(m.timestamp - t0, m.arbitration_id, m.is_fd, bytes(m.data)) for i, m in enumerate(msgs) if i not in own]
    outputs = [(m.timestamp - t0, m.arbitration_id, bytes(m.data)) for i, m in enumerate(msgs) if i in own]
    return inputs, outputs


def trace_frames(trace: Path, ids, node: int) -> list:
    """(queued time, ID, data) of the frames `node` (0: the bus's Node1) delivered on `ids`."""
    with open(trace) as fh:
        return [(float(r["queued_s"]), int(r["id"], 16), bytes.fromhex(r["data"])) for r in csv.DictReader(fh)
                if r["kind"] == "delivered" and int(r["id"], 16) in ids and int(r["node"]) == node]


def on_ticks(inputs: list, recorded: list, period_s: float) -> list:
    """A real-time log's inputs moved onto the replay's clock so that each reaches the replayed
    monitor with the tick the recorded one gave it. The recorded monitor decided cycle k at tick
    T0 + k x period (its clock's grid) and sent the BrakeDemand a latency L_k >= 0 later, so
    T0 is the low edge of B_k - k x period (the 5th percentile: the latency varies by a fraction
    of a ms, and the last word sent on SIGTERM sits a period low); a frame stamped s got the
    tick s - T0 and was drained by the first cycle at or after it. The replayed monitor ticks at
    k x period and decides phase_ms (REPLAY_PHASE_MS) later, taking a frame's arrival in whole
    ms as its tick: a frame played at s - T0 keeps both its tick and its cycle (to the ms that
    T0's estimate and the bus's delivery may add). Frames before the replay's start or after
    the last cycle are left out."""
    sends = [t for t, fid, _ in recorded if fid == BRAKE_DEMAND_ID]
    if not sends:
        raise BuildError("no BrakeDemand frame in the log: the recorded monitor's ticks cannot be known")
    t0 = sorted(t - k * period_s for k, t in enumerate(sends))[len(sends) // 20]
    end = len(sends) * period_s
    return [(t - t0, fid, fd, data) for t, fid, fd, data in inputs if 0.0 <= t - t0 <= end]


def replay(log: Path, table_bytes: bytes, out_dir: Path, keys: Optional[Path] = None,
           duration_s: Optional[float] = None, realtime: bool = False, period_s: float = 0.1,
           monitor_fmu: Optional[Path] = None) -> Replay:
    """Replay `log` through monitor node (`monitor_fmu`, else built from the table and keys) +
    player + bus; compare the monitor's frames in order.
    `realtime`: the log is a wall-clock recording (vcan0, two processes): its inputs are put on
    the replay's clock with the ticks the recorded monitor gave them (`on_ticks`; the monitor node
    decides REPLAY_PHASE_MS after its tick); a simulated-clock log
    (`railguard run` on the in-process bus) is already on it."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    inputs, recorded = read_log(Path(log), keys)
    if realtime:
        inputs = on_ticks(inputs, recorded, period_s)
    monitor = monitor_fmu or build_monitor_node(table_bytes, out_dir, keys=keys)
    if Path(monitor).parent.resolve() != out_dir.resolve():
        monitor = Path(shutil.copy(monitor, out_dir / "monitor.fmu"))
    player = build_player(inputs, out_dir, "player.fmu")
    bus = build_bus(2, out_dir)
    trace = out_dir / "replay-trace.csv"
    starts = {("canbus.fmu", "trace_file"): str(trace)}
    if realtime:
        starts[(Path(monitor).name, "phase_ms")] = REPLAY_PHASE_MS
    container = build_container([Node(monitor), Node(player)], bus, out_dir / "replay.fmu", STEP_S, starts)
    end = duration_s if duration_s is not None else inputs[-1][0] + 0.05
    run_container(container, end)
    replayed = trace_frames(trace, set(OUTPUT_IDS), node=0)
    result = Replay(recorded=len(recorded), replayed=len(replayed), trace=trace)
    for k, ((_, rid, rdata), (_, gid, gdata)) in enumerate(zip(recorded, replayed)):
        result.compared += 1
        if rid != gid or rdata[:FRAME_LENGTH] != gdata[:FRAME_LENGTH]:
            result.mismatches.append((k // len(OUTPUT_IDS), rid, rdata[:FRAME_LENGTH].hex(), gdata[:FRAME_LENGTH].hex()))
    return result
