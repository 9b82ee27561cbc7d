"""The shipped C cycle `rg_step` (fmu/c/core/rg_core.c) run by the C interpreter of
c_symbolic.py, with cycle.step's interface, so that a proof runs the whole C cycle on symbolic
numbers exactly as it runs the Python `monitor.core.cycle._step`.

`step_runner(prog, summaries)(setup, state, inputs, tick) -> (State, Outputs)` converts the
Python values into the C structs as the shells fill them (a channel never heard, None in
Python, is `heard = 0` with every field 0: fmu/c/monitor/model.c), builds `rg_table` from the
table's bytes with the offsets fmu/generate.py gives the C (rg_table.h), runs `rg_step` and
converts `rg_state` / `rg_outputs` back with the Python field meanings (a Track per slot, the
C's 0/1 flags as bool where concrete). Any integer field may be a SymInt. `summaries` replace
the C functions of those names (modular verification: the proof of the caller assumes the
callee's contract); every other function runs as the shipped C.
"""
from __future__ import annotations

import hashlib
from typing import Callable

from monitor.core import table as table_mod
from monitor.core.plausibility import NO_REFERENCE
from monitor.core.types import Outputs, State, Track

from .c_symbolic import ConfigView, Program, Ref, Struct
from .symbolic import SymInt, Unsupported

MAX_MODULES, MAX_CHANNELS = 3, 6           # RG_MAX_MODULES, RG_MAX_CHANNELS (checked against the structs)
PLAUS_FIELDS = ("ref_dm", "ref_tick", "last_tick", "last_closing", "lo", "hi", "bad")   # plausibility.py's order
TRACK_FIELDS = ("near", "far", "closing", "cycles", "absent", "strong")                 # types.Track's order
REPORT_FIELDS = ("status", "distance_dm", "closing_cms", "obstacle", "tick")            # types.Report's order
OUTPUT_FLAGS = ("system_error", "warning")  # rg_outputs' int32 flags that Outputs holds as bool
STATE_FLAGS = ("kept", "strong")            # State's and Track's bools: 0/1 in C


def _int(value, what: str):
    """An integer field for the C: an int or a SymInt; a bool only for a flag of the state (the
    Python reads a bool input field as no int: DEGRADED, an invalid train; the C has no bool)."""
    if isinstance(value, bool) and what.rsplit(".", 1)[-1] in STATE_FLAGS:
        return int(value)
    if isinstance(value, (int, SymInt)) and not isinstance(value, bool):
        return value
    raise Unsupported(f"{what} = {value!r}: the C core takes integers only")


def _flag(value):
    """A C 0/1 flag as Python's bool where it is concrete."""
    return bool(value) if isinstance(value, int) else value


def _fill(prog: Program, name: str, values: dict) -> Struct:
    """A struct of type `name`, each field given converted to its C type (range-checked)."""
    s = prog.blank(("struct", name), 0)
    for field, value in values.items():
        s[field] = prog.convert(_int(value, f"{name}.{field}"), prog.field_type(name, field))
    return s


def table_struct(prog: Program, table: table_mod.Table) -> Struct:
    """`rg_table` as the C gets it: the file's bytes (rebuilt from the decoded table and checked
    against its SHA-256) with fmu/generate.py's offsets, counted from the end."""
    header = table.header
    data = table_mod.encode(header, table.action, table.next, table.risk, risk_info=header["risk"])
    if hashlib.sha256(data[:-32]).hexdigest() != table.sha256:
        raise Unsupported("the table's bytes cannot be rebuilt from the decoded table (SHA-256 differs)")
    n, z, w = table.nodes, len(table.observations), int(header["index_bytes"])
    risk_offset = len(data) - 32 - 4 * n
    next_offset = risk_offset - n * z * w
    s = _fill(prog, "rg_table", {
        "length": len(data), "action_offset": next_offset - n, "next_offset": next_offset, "risk_offset": risk_offset,
        "nodes": n, "observations": z, "index_bytes": w, "start": table.start,
        "model": {"m1": 1, "m2": 2}[table.model], "period_ms": round(float(header["params"]["time_step_s"]) * 1000)})
    s["bytes"] = list(data)
    return s


def state_struct(prog: Program, state: State, channels: int) -> Struct:
    """`rg_state` from a State; the slots a topology does not use are 0 (and no reference)."""
    s = _fill(prog, "rg_state", {f: getattr(state, f) for f in (
        "mode", "node", "held", "seen", "healthy", "cycle", "error_cycles", "calm", "table_held", "kept")})
    for f in ("disagree", "agree"):
        values = tuple(getattr(state, f))
        if len(values) > MAX_MODULES:
            raise Unsupported(f"State.{f} has {len(values)} modules; the C has {MAX_MODULES}")
        values += (0,) * (MAX_MODULES - len(values))
        s[f] = [prog.convert(_int(v, f), prog.field_type("rg_state", f)[1]) for v in values]
    if len(state.tracks) != len(s["tracks"]):
        raise Unsupported(f"State.tracks has {len(state.tracks)} slots; the C has {len(s['tracks'])}")
    s["tracks"] = [_fill(prog, "rg_track_slot", dict(zip(TRACK_FIELDS, t))) for t in state.tracks]
    plaus = list(state.plaus[:channels]) + [NO_REFERENCE] * (MAX_CHANNELS - min(channels, len(state.plaus)))
    s["plaus"] = [_fill(prog, "rg_plaus", dict(zip(PLAUS_FIELDS, p))) for p in plaus]
    return s


def inputs_struct(prog: Program, inputs, channels: int) -> Struct:
    """`rg_inputs` from Inputs: a report of a channel the topology has as given, None (never
    heard) and every other channel as the shells leave it: heard 0, every field 0."""
    reports = tuple(inputs.reports)[:channels]
    slots = []
    for r in reports + (None,) * (MAX_CHANNELS - len(reports)):
        values = {"heard": 0} if r is None else {"heard": 1, **{f: getattr(r, f) for f in REPORT_FIELDS}}
        slots.append(_fill(prog, "rg_report", values))
    train = inputs.train
    s = _fill(prog, "rg_inputs", {"overruns": inputs.overruns})
    s["reports"] = slots
    s["train"] = _fill(prog, "rg_train", {"speed_cms": train.speed_cms, "track": train.track, "brake": train.brake})
    return s


def back(s: Struct, out: Struct, modules: int, channels: int) -> tuple[State, Outputs]:
    """rg_state and rg_outputs as the Python cycle's State and Outputs."""
    tracks = tuple(Track(*(s_t[f] for f in TRACK_FIELDS[:-1]), _flag(s_t["strong"])) for s_t in s["tracks"])
    plaus = tuple(tuple(p[f] for f in PLAUS_FIELDS) for p in s["plaus"][:channels])
    state = State(s["mode"], s["node"], s["held"], s["seen"], tuple(s["disagree"][:modules]), s["healthy"], s["cycle"],
                  s["error_cycles"], s["calm"], tuple(s["agree"][:modules]), s["table_held"], tracks, _flag(s["kept"]),
                  plaus)
    outputs = Outputs(**{f: _flag(out[f]) if f in OUTPUT_FLAGS else out[f] for f in Outputs._fields})
    return state, outputs


def step_runner(prog: Program, summaries: dict | None = None) -> Callable:
    """run(setup, state, inputs, tick) -> (State, Outputs): one cycle of the C `rg_step` in
    `prog` (c_symbolic.program()), `summaries` (C name -> callable, given the interpreted
    arguments in C's order, returning the value or writing through a Ref) replacing those
    functions. The table struct is built once per table."""
    if prog.field_type("rg_inputs", "reports")[2] != MAX_CHANNELS or len(prog.structs["rg_outputs"]) != len(
            Outputs._fields) or prog.field_type("rg_state", "disagree")[2] != MAX_MODULES:
        raise Unsupported("rg_core.h's structs no longer match this runner (channels, modules or outputs)")
    missing = set(Outputs._fields) - set(prog.structs["rg_outputs"])
    if missing:
        raise Unsupported(f"rg_outputs lacks {sorted(missing)}")
    runnable = prog.summarised(summaries)
    tables: dict = {}

    def run(setup, state: State, inputs, tick):
        modules = setup.config.modules
        channels = 2 * modules
        if setup.table.sha256 not in tables:
            tables[setup.table.sha256] = table_struct(prog, setup.table)
        table = tables[setup.table.sha256]
        s, inp = state_struct(prog, state, channels), inputs_struct(prog, inputs, channels)
        out = prog.blank(("struct", "rg_outputs"), None)
        runnable.call("rg_step", [ConfigView(setup.config), Ref({"t": table}, "t"), Ref({"s": s}, "s"),
                                  Ref({"in": inp}, "in"), _int(tick, "tick"), Ref({"out": out}, "out")])
        unset = [f for f, v in out.items() if v is None]
        if unset:
            raise Unsupported(f"rg_step left rg_outputs.{', '.join(unset)} unset")
        return back(s, out, modules, channels)
    return run


__all__ = ["step_runner", "table_struct", "state_struct", "inputs_struct"]
