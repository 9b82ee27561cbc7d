"""Counts over the runs: the core-level runs by fault kind (single and in pairs), scenario,
table and cell, with detection per kind; the bus and vcan samples; and the runs digest, the
one hash that says two campaigns made the same runs with the same outcomes.
"""
from __future__ import annotations

import hashlib
import json
from collections import Counter, defaultdict

from .catalogue import KINDS
from .scenarios import UNAVOIDABLE


def aggregate(results: list[dict]) -> dict:
    """Counts over core-level runs: totals, per fault kind (single and in pairs), per
    scenario, per (fault kind, scenario), detection per kind."""
    def blank():
        return {"runs": 0, "unsafe": 0, "unsafe_runs": 0, "unavoidable": 0, "beyond_declaration": 0, "crashes": 0,
                "collisions": 0, "false_braking": 0, "brake_without_obstacle": 0}

    def add(cell, r):
        cell["runs"] += 1
        cell["unsafe"] += bool(r["unsafe"])
        cell["unsafe_runs"] += bool(r["unsafe"])
        cell["unavoidable"] += bool(r.get("unavoidable"))
        cell["beyond_declaration"] += bool(r.get("beyond_declaration"))
        cell["crashes"] += r["crash"] is not None
        cell["collisions"] += bool(r["collision"])
        cell["false_braking"] += bool(r["false_braking"])
        cell["brake_without_obstacle"] += bool(r.get("brake_without_obstacle"))

    total = blank()
    single = defaultdict(blank)        # kind ("none" for fault-free) -> counts
    paired = defaultdict(blank)        # kind -> counts over pairs that contain it
    scen = defaultdict(blank)
    cells = defaultdict(blank)         # (row, scenario): rows "none", kind (single), "pair:kind"
    models = defaultdict(blank)
    detection = {k: {"single_runs": 0, "manifest": 0, "detected": 0, "max_latency": 0, "missed": []} for k in KINDS}
    pair_manifest = pair_detected = 0
    pair_missed = []
    margins = defaultdict(list)
    corrupt_accepted = 0
    for r in results:
        add(total, r)
        add(scen[r["scenario"]], r)
        add(models[r["model"]], r)
        corrupt_accepted += r.get("corrupt_frames_accepted", 0)
        if r.get("stop_margin_m") is not None and not r["kinds"]:
            margins[r["model"]].append(r["stop_margin_m"])
        if len(r["kinds"]) <= 1:
            label = r["kinds"][0] if r["kinds"] else "none"
            add(single[label], r)
            add(cells[(label, r["scenario"])], r)
        else:
            for k in set(r["kinds"]):
                add(paired[k], r)
                add(cells[("pair:" + k, r["scenario"])], r)
        if len(r["kinds"]) == 1 and r["faults"] and r["faults"][0]["kind"] in detection:
            f = r["faults"][0]
            d = detection[f["kind"]]
            d["single_runs"] += 1
            if f["manifest_cycle"] is not None:
                d["manifest"] += 1
                if f["detected"]:
                    d["detected"] += 1
                    d["max_latency"] = max(d["max_latency"], f["latency_cycles"] or 0)
                elif len(d["missed"]) < 5:
                    d["missed"].append(r["key"])
        elif len(r["kinds"]) == 2 and r["faults"]:
            if any(f["manifest_cycle"] is not None for f in r["faults"]):
                pair_manifest += 1
                if any(f["detected"] for f in r["faults"]):
                    pair_detected += 1
                elif len(pair_missed) < 5:
                    pair_missed.append(r["key"])
    unsafe_examples = [{"key": r["key"], "first": r["unsafe_first"]} for r in results if r["unsafe"]][:10]
    crash_examples = [{"key": r["key"], "crash": r["crash"]} for r in results if r["crash"]][:10]
    runs = max(1, total["runs"])
    return {
        "runs": total["runs"], "unsafe": total["unsafe_runs"], "unavoidable": total["unavoidable"],
        "beyond_declaration": total["beyond_declaration"],
        "crashes": total["crashes"], "collisions": total["collisions"], "false_braking": total["false_braking"],
        "false_braking_rate": total["false_braking"] / runs, "brake_without_obstacle": total["brake_without_obstacle"],
        "brake_without_obstacle_rate": total["brake_without_obstacle"] / runs,
        "false_braking_examples": [r["key"] for r in results if r["false_braking"]][:10], "single": dict(single), "paired": dict(paired), "by_scenario": dict(scen),
        "by_model": dict(models), "cells": {f"{a}|{b}": v for (a, b), v in cells.items()}, "detection": detection,
        "pairs": {"manifest": pair_manifest, "detected": pair_detected, "missed": pair_missed},
        "unsafe_examples": unsafe_examples, "crash_examples": crash_examples,
        "corrupt_frames_accepted": corrupt_accepted,
        "fault_free_stop_margin_m": {m: (min(v), max(v)) for m, v in margins.items()},
    }


def bus_summary(runs: list[dict]) -> dict:
    kinds_detected: dict = {}
    for r in runs:
        if r.get("detection_run", True):
            for k, ok in (r.get("detected") or {}).items():
                kinds_detected[k] = kinds_detected.get(k, True) and bool(ok)
    n = len(runs)
    fb = sum(bool(r.get("false_braking")) for r in runs)
    without = sum(bool(r.get("brake_without_obstacle")) for r in runs)
    return {"runs": n, "unsafe": sum(bool(r.get("unsafe")) for r in runs),
            "crashes": sum(r.get("crash") is not None for r in runs),
            "collisions": sum(bool(r.get("collision")) for r in runs),
            "collisions_avoidable": sum(bool(r.get("collision")) and r.get("scenario") != UNAVOIDABLE for r in runs),
            "false_braking": fb, "false_braking_rate": fb / n if n else 0.0, "brake_without_obstacle": without,
            "brake_without_obstacle_rate": without / n if n else 0.0, "detected": kinds_detected,
            "frames_rejected": dict(sum((Counter(r.get("rejects") or {}) for r in runs), Counter())),
            "unsafe_examples": [{"name": r["name"], "first": r.get("unsafe_first")} for r in runs if r.get("unsafe")][:5],
            "crash_examples": [{"name": r["name"], "crash": r["crash"]} for r in runs if r.get("crash")][:5]}


OUTCOME_KEYS = ("unsafe", "unavoidable", "collision", "closest_m", "stop_margin_m", "false_braking", "max_demand",
                "cycles", "crash")


def runs_digest(results: list[dict]) -> str:
    """SHA-256 over every core-level run's key (scenario, faults, seed, table) and outcome, in
    key order: the same for any number of workers and any order the runs came back in."""
    h = hashlib.sha256()
    for r in sorted(results, key=lambda r: (r["key"], r.get("ghost_dm", 0))):
        h.update(json.dumps([r["key"], r.get("ghost_dm", 0)] + [r.get(k) for k in OUTCOME_KEYS],
                            sort_keys=True, default=str).encode() + b"\n")
    return h.hexdigest()


def vruns_detail(runs: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in ("unsafe_first",)} for r in runs]
