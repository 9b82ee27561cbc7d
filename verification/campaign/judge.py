"""The campaign's measures, shared by the core-level runs and the runs on a bus: what is a
reaction to a diagnosed fault, what is false braking and braking without an obstacle, the
cycle at which a fault kind's named diagnostic shows, and the world's verdict on a run
through the real runner (unsafe, false braking, every fault's diagnostic seen).
"""
from __future__ import annotations

from typing import Optional

from monitor.core.types import (
    EMERGENCY, R_DEADLINE, R_INIT, R_LATCH, R_PERCEPTOR, R_SAFE_STOP, R_STALE, R_TRAIN_INPUT, SAFE_STOP,
)

from .catalogue import FRAME_KINDS, REJECT_OF
from .specs import Fault
from .scenarios import RANGE_M, UNAVOIDABLE


FAULT_REACTION = R_STALE | R_SAFE_STOP | R_DEADLINE | R_TRAIN_INPUT | R_INIT   # reasons of a diagnosed fault


def reaction_to_fault(reasons: int, held_by_fault: bool) -> bool:
    """A demand that answers a fault the monitor diagnosed (stale, safe stop, deadline, train
    input, init), or an emergency the latch still holds after such an answer."""
    return bool(reasons & FAULT_REACTION) or bool(reasons & R_LATCH and held_by_fault)


def false_braking_cycles(demands: list, reasons: list, obstacle_in_range: list, moving: list) -> tuple[bool, bool]:
    """(braking without an obstacle, false braking) of a run: a brake demand while the train
    is on its way and no true obstacle is in sensor range; false unless it is the reaction to
    a diagnosed fault (the latch's hold after such a reaction included)."""
    without = false = False
    held_by_fault = False
    for demand, r, near, on in zip(demands, reasons, obstacle_in_range, moving):
        reaction = reaction_to_fault(r, held_by_fault)
        if demand == EMERGENCY and not r & R_LATCH:
            held_by_fault = reaction
        elif demand != EMERGENCY:
            held_by_fault = False
        if on and demand > 0 and not near:
            without = True
            false = false or not reaction
    return without, false


def first_diagnostic(f: Fault, first: int, reasons_l, flags_l, modes_l, receiver,
                      persisted: Optional[int] = None) -> Optional[int]:
    """The first cycle at or after `first` that shows the fault kind's named diagnostic (for a
    contradiction that persisted `persistence_cycles`, from cycle `persisted`: also perceptor)."""
    n = len(reasons_l)
    if f.kind in ("silence", "stale_timestamp"):
        return next((i for i in range(first, n) if reasons_l[i] & R_STALE), None)
    if f.kind in ("stuck", "noise_burst", "missed_detection"):
        bit = 1 << (f.channel // 2)
        return next((i for i in range(first, n) if flags_l[i] & bit), None)
    if f.kind == "contradiction":
        bit = 1 << (f.channel // 2)
        flag = next((i for i in range(first, n) if flags_l[i] & bit), None)
        if persisted is None or flag is None:
            return flag
        perceptor = next((i for i in range(persisted, n) if reasons_l[i] & R_PERCEPTOR), None)
        return None if perceptor is None else max(flag, perceptor)
    if f.kind in FRAME_KINDS:
        if not any(receiver.rejected.get(r, 0) for r in REJECT_OF[f.kind]):
            return None
        return next((i for i in range(first, n) if reasons_l[i] & R_STALE), None)
    if f.kind == "deadline_overrun":
        return next((i for i in range(first, n) if reasons_l[i] & R_DEADLINE and modes_l[i] == SAFE_STOP), None)
    return None


def evaluate_bus(records, trace, trace_ticks, scenario: str, margin_m: float = 0.0) -> dict:
    """The world's verdict on a run on a bus (unsafe: the player's train reached the obstacle
    or came closer than `margin_m`, outside UNAVOIDABLE), and false braking.

    `records` are the runner's CycleRecords; `trace` the player's (t_s, speed_mps,
    distance_m) rows. On the virtual bus row i is the world the reports of cycle i came from;
    on a real bus (`trace_ticks` given) the row of cycle i is the newest one stepped at or
    before its tick."""
    import bisect

    rows = []
    for i, rec in enumerate(records):
        if trace_ticks is None:
            j = i if i < len(trace) else None
        else:
            j = bisect.bisect_right(trace_ticks, rec.tick) - 1
            j = j if j >= 0 else None
        rows.append(trace[j] if j is not None else None)
    cut = next((i for i, row in enumerate(rows) if row is not None and row[2] is not None and row[2] <= 0), None)
    if cut is not None:                      # a collision: the world ends there, as in the core-level runs
        records, rows = records[:cut + 1], rows[:cut + 1]
    gaps = [row[2] for row in trace if row[2] is not None]
    closest = min(gaps, default=None)
    near, moving = [], []
    entered = False
    for rec, row in zip(records, rows):
        entered = entered or (row is not None and row[1] > 0)
        moving.append(entered)
        near.append(row is not None and row[2] is not None and row[2] <= RANGE_M)
    demands = [r.demand for r in records]
    reasons = [r.reasons for r in records]
    n = len(demands)
    unsafe = scenario != UNAVOIDABLE and closest is not None and (closest <= 0.0 or closest < margin_m)
    without, false = false_braking_cycles(demands, reasons, near, moving)
    held = not entered and not any(r & FAULT_REACTION for r in reasons)     # never let go, no diagnosed fault
    return {"cycles": n, "unsafe": int(unsafe), "closest_m": None if closest is None else round(closest, 2),
            "unsafe_first": None if not unsafe else {"gap_m": round(closest, 2), "margin_m": margin_m},
            "brake_without_obstacle": without or not entered, "false_braking": false or held}


def bus_detection(faults, records, rejected, brake_causes=None) -> dict:
    """Per fault kind of a bus run: was its diagnostic seen? (The player's `stale_timestamp`
    replays a report from 10 periods earlier with a fresh frame, so on the bus it shows as a
    2oo2 disagreement, not as a stale channel.) `brake_causes`: the periods the player's
    brake receiver braked, by cause (a hostile BrakeDemand is seen there)."""
    seen = 0
    flags = 0
    modes = set()
    for r in records:
        seen |= r.reasons
        flags |= r.module_flags
        modes.add(r.mode)
    out = {}
    for f in faults:
        k = f.kind
        if k == "silence":
            ok = bool(seen & R_STALE)
        elif k in ("stuck", "noise_burst", "missed_detection", "stale_timestamp"):
            ok = bool(flags & (1 << (f.channel // 2)))
        elif k == "contradiction":            # the player's windows outlast persistence_cycles
            ok = bool(flags & (1 << (f.channel // 2))) and bool(seen & R_PERCEPTOR)
        elif k in FRAME_KINDS:
            ok = any(rejected.get(r, 0) > 0 for r in REJECT_OF[k]) and bool(seen & R_STALE)
        elif k == "deadline_overrun":
            ok = bool(seen & R_DEADLINE) and SAFE_STOP in modes
        elif k == "forge_absent":
            ok = rejected.get("second_sender", 0) > 0 and bool(seen & R_STALE)
        elif k == "forge_brake_none":
            ok = bool(brake_causes) and brake_causes.get("second_sender", 0) > 0
        else:
            ok = False
        out[k] = out.get(k, True) and ok
    return out
