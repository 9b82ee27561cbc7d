"""What the simulated CAN bus did to the frames, from the bus simulation's trace
(fmu/c/lsbus/bus: one CSV row per transmission: delivered, bus_error or dropped, with its
queue, start and end times): per ID the frames, the queue delay (start - queued: arbitration
lost and the bus busy) and the longest gap between deliveries; the bus load over time; and
the bit-timing figure to judge them against."""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class IdTiming:
    frame_id: int
    frames: int = 0
    errors: int = 0
    dropped: int = 0
    max_delay_s: float = 0.0
    sum_delay_s: float = 0.0
    max_gap_s: float = 0.0
    last_end_s: float | None = None
    delays: list = field(default_factory=list)     # (queued time, delay) of every delivered frame

    @property
    def mean_delay_s(self) -> float:
        return self.sum_delay_s / self.frames if self.frames else 0.0

    def as_dict(self) -> dict:
        return {"id": f"0x{self.frame_id:03X}", "frames": self.frames, "errors": self.errors, "dropped": self.dropped,
                "max_queue_delay_ms": round(self.max_delay_s * 1e3, 3),
                "mean_queue_delay_ms": round(self.mean_delay_s * 1e3, 4),
                "max_gap_ms": round(self.max_gap_s * 1e3, 3)}


@dataclass
class BusTiming:
    ids: dict            # frame ID -> IdTiming
    busy_s: float
    span_s: float
    load_windows: list   # (window end time, load in that window)

    @property
    def load(self) -> float:
        return self.busy_s / self.span_s if self.span_s > 0 else 0.0

    @property
    def peak_load(self) -> float:
        return max((load for _, load in self.load_windows), default=0.0)

    def as_dict(self) -> dict:
        return {"bus_load": round(self.load, 4), "peak_load_100ms": round(self.peak_load, 4),
                "ids": [t.as_dict() for _, t in sorted(self.ids.items())]}


def read_trace(path: Path) -> list[dict]:
    with open(path) as fh:
        return list(csv.DictReader(fh))


def timing(rows: list[dict], span_s: float, window_s: float = 0.1, intermission_bits: int = 3,
           bit_rate: int = 500_000) -> BusTiming:
    ids: dict = {}
    busy = 0.0
    windows = [0.0] * (int(span_s / window_s) + 1)
    for r in rows:
        fid = int(r["id"], 16)
        t = ids.setdefault(fid, IdTiming(fid))
        if r["kind"] == "dropped":
            t.dropped += 1
            continue
        start, end, queued = float(r["start_s"]), float(r["end_s"]), float(r["queued_s"])
        occupied = end - start + intermission_bits / bit_rate
        busy += occupied
        k = min(int(start / window_s), len(windows) - 1)
        windows[k] += occupied
        if r["kind"] == "bus_error":
            t.errors += 1
            continue
        delay = start - queued
        t.frames += 1
        t.sum_delay_s += delay
        t.max_delay_s = max(t.max_delay_s, delay)
        t.delays.append((queued, delay))
        if t.last_end_s is not None:
            t.max_gap_s = max(t.max_gap_s, end - t.last_end_s)
        t.last_end_s = end
    return BusTiming(ids, busy, span_s, [((k + 1) * window_s, min(1.0, b / window_s)) for k, b in enumerate(windows)])


def classic_frame_bits(data_bytes: int) -> tuple[int, int]:
    """(bits without stuffing, the most with stuffing) of a classical base frame, SOF to the end
    of EOF (ISO 11898-1: 44 + 8n bits; stuff bits over the 34 + 8n bits from SOF to the CRC's
    end, at most one per four after the first five)."""
    plain = 44 + 8 * data_bytes
    stuffed_region = 34 + 8 * data_bytes
    return plain, plain + (stuffed_region - 1) // 4
