"""What the monitor said on the bus, read back from a candump log with the users' own tools:
python-can's log reader and cantools with railguard.dbc, no railguard decoding code in
between (a witness that shares nothing with the codec it checks).

`monitor_signals(path)` gives one row per monitor cycle, keyed by its tick: the BrakeDemand
level and the MonitorRisk signals in the DBC's units (R1, R2 in per cent, 0.1 % steps).
"""
from __future__ import annotations

from pathlib import Path

import can
import cantools
import numpy as np

DBC = Path(__file__).resolve().parents[2] / "can_bus" / "railguard.dbc"
SIGNALS = {"BrakeDemand": ("Level",), "MonitorRisk": ("R1", "R2", "RiskScore", "RiskCategory", "TableRisk")}
COLUMNS = ("level", "r1_pct", "r2_pct", "score", "category", "table_ppm")


def database():
    return cantools.database.load_file(str(DBC))


def monitor_signals(path: str | Path, db=None) -> dict:
    """{'tick': ms, 'level', 'r1_pct', 'r2_pct', 'score', 'category', 'table_ppm'}: arrays over
    the cycles with both a BrakeDemand and a MonitorRisk frame. A simulated run's timestamps are
    its ticks in seconds. The first frame of each tick counts: the shell's last emergency, sent
    at the last cycle's tick after it, is not a cycle."""
    db = db or database()
    wanted = {db.get_message_by_name(name).frame_id: name for name in SIGNALS}
    rows: dict[int, dict] = {}
    with can.LogReader(str(path)) as reader:
        for msg in reader:
            name = wanted.get(msg.arbitration_id)
            if name is None or msg.is_error_frame or msg.is_remote_frame:
                continue
            tick = round(msg.timestamp * 1000)
            row = rows.setdefault(tick, {})
            if name in row:
                continue
            row[name] = db.decode_message(msg.arbitration_id, msg.data, decode_choices=False)
    ticks = sorted(t for t, r in rows.items() if len(r) == len(SIGNALS))
    out = {"tick": np.array(ticks, dtype=np.int64)}
    names = [(m, s) for m, sigs in SIGNALS.items() for s in sigs]
    for col, (m, s) in zip(COLUMNS, names):
        out[col] = np.array([rows[t][m][s] for t in ticks], dtype=float)
    return out
