"""Run the core over a recorded bus log (.log, .asc, .blf, ...) and report its decisions.

Frames are taken in timestamp order; the tick of a frame is its time since the first frame
in ms; the core steps at every period boundary with what had arrived by then, exactly as
the runner does live. The result depends only on the file: replaying it twice gives the
same decisions. Where the log holds the monitor's own BrakeDemand frames, the replayed
demands are compared with the recorded ones.
"""
from __future__ import annotations

from pathlib import Path

import can

from monitor.core import cycle as core
from monitor.core.types import Inputs

from .codec import BRAKE_DEMAND_ID, Receiver
from .runner import CycleRecord


class ReplayError(ValueError):
    """A log that cannot be replayed (unreadable, unknown format, empty)."""


Decision = CycleRecord  # a replayed cycle is recorded exactly like a live one


def read_frames(path: str | Path) -> list[tuple[float, int, bytes, bool]]:
    p = Path(path)
    if not p.is_file():
        raise ReplayError(f"{p}: no such file")
    try:
        frames = [(float(m.timestamp), int(m.arbitration_id), bytes(m.data), bool(m.is_extended_id))
                  for m in can.LogReader(str(p)) if not (m.is_error_frame or m.is_remote_frame)]
    except ValueError as exc:
        raise ReplayError(f"{p}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file, said in one line
        raise ReplayError(f"{p}: cannot read as a CAN log: {type(exc).__name__}: {exc}") from None
    if not frames:
        raise ReplayError(f"{p}: no CAN frames in the file")
    frames.sort(key=lambda f: f[0])
    return frames


def replay(setup: core.Setup, frames) -> tuple[list[CycleRecord], dict]:
    """Decisions of the core over the frames, and a comparison with recorded BrakeDemands."""
    period = setup.config.period_ms
    t0 = frames[0][0]
    rx = Receiver(channels=setup.config.channels, rate_window_ms=period)
    state = core.initial_state(setup)
    decisions: list[CycleRecord] = []
    recorded: list[tuple[int, int]] = []
    i = 0
    last_tick = round((frames[-1][0] - t0) * 1000)
    tick = 0
    while tick <= last_tick + period:
        while i < len(frames) and round((frames[i][0] - t0) * 1000) <= tick:
            ts, fid, data, extended = frames[i]
            ftick = round((ts - t0) * 1000)
            if rx.accept(fid, data, ftick, extended) == "BrakeDemand" and fid == BRAKE_DEMAND_ID:
                recorded.append((ftick, int(rx.demand["Level"])))
            i += 1
        train = rx.train if rx.train_tick is not None and tick - rx.train_tick <= setup.timeout_ticks else None
        state, out = core.step(setup, state, Inputs(tuple(rx.reports), train, 0), tick)
        decisions.append(CycleRecord(tick, out.demand, out.reasons, out.mode, out.node, out.distance_dm,
                                     out.module_flags, out.system_error, None if train is None else train.speed_cms))
        tick += period
    stats = {"frames": len(frames), "accepted": rx.accepted, "rejected": dict(rx.rejected),
             "recorded_demands": len(recorded)}
    if recorded:
        by_tick = {d.tick: d.demand for d in decisions}
        # a recorded demand sent after the cycle at tick T is compared with our decision at T
        matches = sum(1 for t, lvl in recorded if by_tick.get(t - t % period) == lvl)
        stats["agreement_with_recorded"] = matches / len(recorded)
    return decisions, stats
