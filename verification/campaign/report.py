"""The campaign's text in the report: the tables per fault and per fault x scenario, the ghost
runs beside the quick campaign's figures before the braking curves, and the section's
Markdown (what is measured, the catalogue and detection, the bus and vcan samples).
"""
from __future__ import annotations

from typing import Optional

from .. import world_train
from ..report import md_table
from .catalogue import CATALOGUE, HOSTILE, HOSTILE_KINDS, KINDS, TABLE_KINDS
from .specs import SEEDS, combos
from .runs import GHOST_S
from .scenarios import GHOST_SCENARIO, NOISE_SIGMA_M, RANGE_M, SCENARIOS, UNAVOIDABLE


# The quick campaign's core-level and ghost runs (324 + 24) with the monitor before the braking
# curves (commit 75a5c9f: nominal alpha2, a 2oo2 disagreement answered by safe_reaction, every
# emergency latched to standstill), in that commit's own world (a train braking at the nominal
# 1 and 3 m/s^2), measured by running the campaign's measures over that commit's core.
BEFORE_QUICK = {"commit": "75a5c9f", "runs": 348, "false_braking": 32, "brake_without_obstacle": 146,
                "ghosts": 24, "ghosts_stopped": 24, "unsafe": 0}


def pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _row_label(kinds: tuple) -> str:
    return "none" if not kinds else "+".join(kinds)


def _cell(c: dict) -> str:
    if not c or not c["runs"]:
        return "-"
    return (f"{c['unsafe_runs']}/{c['crashes']}/{c['collisions']}/{100 * c['false_braking'] / c['runs']:.0f}%/"
            f"{100 * c['brake_without_obstacle'] / c['runs']:.0f}%")


def faults_by_scenarios_table(core: dict, pairs: bool = True) -> str:
    """Rows: fault-free, each single fault, each fault in pairs; columns: scenarios; cell:
    unsafe runs / crashes / collisions / false-braking rate."""
    cells = core["cells"]
    rows = []
    labels = [("none", "none (fault-free)")] + [(k, CATALOGUE[k].label) for k in KINDS]
    if pairs:
        labels += [("pair:" + k, f"{CATALOGUE[k].label} + another") for k in KINDS]
    for key, label in labels:
        row = [label]
        for s in SCENARIOS:
            row.append(_cell(cells.get(f"{key}|{s.name}")))
        rows.append(row)
    return md_table(["fault \\ scenario"] + [s.name for s in SCENARIOS], rows)


def faults_table(core: dict) -> str:
    """One row per fault kind over all scenarios (the README table)."""
    rows = []
    for key in ("none",) + KINDS:
        c = core["single"].get(key)
        p = core["paired"].get(key)
        det = core["detection"].get(key)
        label = "none (fault-free)" if key == "none" else CATALOGUE[key].label
        both = {k: (c or {}).get(k, 0) + (p or {}).get(k, 0)
                for k in ("runs", "unsafe_runs", "crashes", "collisions", "false_braking", "brake_without_obstacle")}
        detected = "-" if det is None else f"{det['detected']}/{det['manifest']}"
        rows.append([label, f"{both['runs']:,}", both["unsafe_runs"], both["crashes"], both["collisions"],
                     pct(both["false_braking"] / both["runs"]) if both["runs"] else "-",
                     pct(both["brake_without_obstacle"] / both["runs"]) if both["runs"] else "-", detected])
    rows.append(["**all runs**", f"{core['runs']:,}", core["unsafe"], core["crashes"], core["collisions"],
                 pct(core["false_braking_rate"]), pct(core["brake_without_obstacle_rate"]), ""])
    return md_table(["fault (single or in a pair)", "runs", "unsafe", "crashes", "collisions", "false braking",
                     "braking without an obstacle", "detected (single runs)"], rows)


def _ghost_and_before(summary: dict) -> str:
    """The ghost runs, and the quick campaign's figures before the braking curves."""
    core, g, b = summary["core"], summary.get("ghost"), BEFORE_QUICK
    out = ""
    if g:
        out += (f"**Ghost runs** ({g['runs']}): clear track, 40 m/s, one channel reports a static obstacle for {GHOST_S} s at "
                f"{', '.join(f'{d / 10:.1f}' for d in g['distances_dm'])} m (just beyond SBI, half-way to the warning "
                "curve, just beyond it, far), every channel in turn. The disagreement is a dispute: a warning and a "
                f"diagnostic, not a brake. Lowest speed {g['min_speed_mps']:.1f} m/s, highest demand {g['max_demand']}, "
                f"{len(g['stopped'])} stopped, {g['false_braking']} braked falsely, {len(g['undiagnosed'])} without the "
                "`dispute` diagnostic.\n\n")
    if summary["mode"] == "quick":
        out += (f"**Before the braking curves** (commit {b['commit']}: nominal alpha2, a 2oo2 disagreement answered by "
                "`safe_reaction`, every emergency held to standstill; that commit's world, whose train braked at the "
                f"nominal 1 and 3 m/s^2): the same {b['runs']} quick runs gave false braking in {b['false_braking']} "
                f"({pct(b['false_braking'] / b['runs'])}), braking without an obstacle in {b['brake_without_obstacle']} "
                f"({pct(b['brake_without_obstacle'] / b['runs'])}), {b['unsafe']} unsafe; {b['ghosts_stopped']} of "
                f"{b['ghosts']} ghosts stopped the train. Now: {core['false_braking']} ({pct(core['false_braking_rate'])}) "
                f"and {core['brake_without_obstacle']} ({pct(core['brake_without_obstacle_rate'])}).\n")
    return out


def markdown(summary: dict, figure: Optional[str]) -> str:
    core = summary["core"]
    quick = summary["mode"] == "quick"
    lines = [
        f"Every single fault and every pair of faults from the catalogue ({len(KINDS)} kinds; "
        f"{len(combos()) - 1} fault combinations: {len(KINDS)} singles and {len(combos()) - 1 - len(KINDS)} pairs, "
        f"two channels with the same channel fault among them; and the fault-free case) crossed with {len(SCENARIOS)} obstacle "
        f"scenarios{'' if quick else f' and {SEEDS} seeds'} (channels, windows and variants drawn from each run's seed; "
        "tables m1 and m2 alternating), plus the ghost runs, through `monitor.core.cycle` in a simulated world that "
        "does not share the monitor's assumptions. Its train is the train FMU's physics (`verification/world_train.py`, "
        "a Python twin held equal to the FMU in FMPy: dead time, linear build-up, speed bands, gradient, traction "
        "held after a demand), with parameters of its own: "
        + (f"**the world train given with `--world-train`**: {world_train.from_mapping(summary['world_train'], 'world').describe()}. "
           if summary.get("world_train") else
           "one run in four on a corner of the braking declaration (the guaranteed decelerations exactly, the whole "
           "equivalent build-up as dead time, or as half of it plus a ramp twice as long, the steepest downhill, "
           "full traction for the whole cut-off, the speed reported low by the whole error), the others drawn "
           "inside it (each value between the declared limit and a better one), each from the run's own key. ")
        + "Reports reach the monitor as the runner sees them: received up to one period before the cycle that uses "
        "them (a phase drawn per run; the monitor counts that age) and sensed up to 10 ms before their reception "
        "(which it does not see); a demand reaches the brakes up to 10 ms after its cycle. Six channels with "
        f"{NOISE_SIGMA_M} m Gaussian noise and {RANGE_M:.0f} m range. "
        "Frame faults go through the real `can_bus.codec.Receiver` with real encoded frames. A sample runs through the "
        "real `MonitorRunner`, codec and `Player` on the virtual bus (its train: the world train's decelerations, by "
        "default the declaration's worst corner, the emergency one of the weakest band, the force ramping up in twice "
        "the equivalent build-up; its collisions outside sudden-120m are unsafe), and a few sessions on "
        "SocketCAN vcan0 in the user-mode-Linux sandbox. `railguard campaign --braking FILE.toml` runs it all with "
        "another declaration, `--world-train FILE.toml` with another world train.\n",
        "**Unsafe outcome** (the world's verdict): the world's train reaches an obstacle, or comes closer to it than "
        f"the margin ({summary.get('margin_m', 0.0):g} m; `--unsafe-margin`), that it could have stopped for: "
        "*unavoidable* is an obstacle for which, when it came into sensor range, not even an emergency demand "
        "from the next cycle on would have stopped the world's own train (its twin, stepped ahead). "
        "The monitor's braking curves play no part in the verdict. **Crash**: any "
        "exception in a run, including those the core's fail-safe swallows and those the receive path counts as "
        "`undecodable`. **False braking** (issue 11's measure): a run with a brake demand, after the train entered, "
        "while no true obstacle is within sensor range, that is not the reaction to a fault the monitor diagnosed "
        "(reason bits `stale`, `safe_stop`, `deadline`, `train_input`, `init`, a refused table; an emergency the latch "
        "still holds after such a reaction counts as the reaction). **Braking without an obstacle** (the earlier "
        "measure): any such demand, fault reactions and trains held at the entry by a refused table included. "
        "`sudden-120m` puts an object inside the stopping distance: the world finds its collisions unavoidable, "
        "and a check holds that it finds none elsewhere.\n",
        f"**Core-level runs**: {core['runs']:,} in {core['seconds']:.0f} s; unsafe {core['unsafe']}, crashes "
        f"{core['crashes']}, collisions {core['collisions']}, **false braking {core['false_braking']:,} "
        f"({pct(core['false_braking_rate'])})**, braking without an obstacle {core['brake_without_obstacle']:,} "
        f"({pct(core['brake_without_obstacle_rate'])}). Corrupted frames that passed the CRC-8 (multi-byte corruption) "
        f"and were accepted: {core['corrupt_frames_accepted']}. Fault-free stop margins: "
        + ", ".join(f"{m} {a:.1f}..{b:.1f} m" for m, (a, b) in sorted(core["fault_free_stop_margin_m"].items())) + ". "
        + "; ".join(f"Table {m}: {c['runs']:,} runs, {c['unsafe_runs']} unsafe, {c['crashes']} crashes, "
                    f"{c['collisions']} collisions, false braking {pct(c['false_braking'] / c['runs'])}"
                    for m, c in sorted(core["by_model"].items())) + ".\n",
        _ghost_and_before(summary),
        "### Catalogue and detection\n",
        md_table(["fault", "how it is injected", "diagnostic that shows it", "single runs: detected / manifested",
                  "max latency (cycles)"],
                 [[CATALOGUE[k].label + f" (`{k}`)", CATALOGUE[k].injection, CATALOGUE[k].diagnostic,
                   f"{core['detection'][k]['detected']} / {core['detection'][k]['manifest']}",
                   "-" if k in TABLE_KINDS else core["detection"][k]["max_latency"]] for k in KINDS]),
        "\nA value fault *manifests* when the channel's report differs from its fault-free report (status, or "
        "distance by more than twice `distance_tolerance_dm`); a stuck value that stays true (a clear track, a "
        "train at standstill) or a missed detection with nothing in range cannot be seen by any monitor and harms "
        "nothing. Frame faults, silence, stale timestamps and overruns manifest whenever their window is reached; "
        "table faults always.\n",
        "### Results per fault\n", faults_table(core),
        "\n### Faults x scenarios\n",
        "Cell: unsafe runs / crashes / collisions / false-braking rate / rate of braking without an obstacle.\n",
        faults_by_scenarios_table(core),
        "\n### Per scenario\n",
        md_table(["scenario", "description", "runs", "unsafe", "crashes", "collisions", "false braking",
                  "braking without an obstacle"],
                 [[s.name, s.description, f"{c['runs']:,}", c["unsafe_runs"], c["crashes"], c["collisions"],
                   pct(c["false_braking"] / c["runs"]), pct(c["brake_without_obstacle"] / c["runs"])]
                  for s in SCENARIOS + (GHOST_SCENARIO,) if (c := core["by_scenario"].get(s.name))]),
    ]
    if figure:
        lines.append(f"\n![braking without an obstacle, faults x scenarios]({figure})\n")
    if "bus" in summary:
        b = summary["bus"]
        lines += ["\n### Through the real runner and codec on the virtual bus\n",
                  f"{b['runs']} runs of `can_bus.session.run_virtual` (the deadline overrun: the same loop with a clock "
                  "that makes the cycle end 120 ms after its tick; a refused table: the Player alone on the bus) in "
                  f"{b['seconds']:.0f} s: unsafe {b['unsafe']}, crashes {b['crashes']}, collisions {b['collisions']} "
                  f"({b['collisions_avoidable']} outside {UNAVOIDABLE}), false braking {pct(b['false_braking_rate'])}, braking "
                  f"without an obstacle {pct(b['brake_without_obstacle_rate'])}. The player's faults are its "
                  "own (`can_bus.player`): its `stale_timestamp` replays the report of 10 periods earlier in a fresh "
                  "frame, so on the bus it shows as a 2oo2 disagreement (module flag) rather than as a stale channel; "
                  "runs named `-detect` place each fault while the train approaches a static obstacle in sight and must "
                  "show its diagnostic. Two of them put a hostile node on the bus (issue 39, `can_bus/hostile.py`): "
                  + "; ".join(f"`{k}`: {HOSTILE[k].injection}, seen as {HOSTILE[k].diagnostic}" for k in HOSTILE_KINDS)
                  + " (without the second-sender rule both collide); the `-secured-detect` runs play the same two "
                  "attacks on the secured bus (a test key set; the hostile node holds no key): its frames fail the "
                  "authenticator (`bad_mac`), the ID is quarantined as a second sender. Frames rejected by reason: "
                  + (", ".join(f"{k} {v:,}" for k, v in sorted(b["frames_rejected"].items())) or "none") + ".\n",
                  md_table(["run", "scenario", "table", "outcome", "unsafe", "crash", "detected"],
                           [[r["name"], r.get("scenario", ""), r.get("model", ""), r.get("outcome", ""), r.get("unsafe", 0),
                             "yes" if r.get("crash") else "no",
                             ", ".join(f"{k} {'yes' if ok else 'NO'}" for k, ok in (r.get("detected") or {}).items())]
                            for r in b["runs_detail"]])]
    if "vcan" in summary:
        v = summary["vcan"]
        lines.append("\n### On SocketCAN vcan0 (user-mode-Linux sandbox)\n")
        if "error" in v:
            lines.append(f"Not run: {v['error']}\n")
        else:
            lines += [f"{v['runs']} sessions in one sandbox boot ({v['seconds']:.0f} s): the monitor (`MonitorRunner`, "
                      "wall clock) and the `Player` in a thread on the real vcan0. Unsafe "
                      f"{v['unsafe']}, crashes {v['crashes']}, collisions {v['collisions']}.\n",
                      md_table(["session", "outcome", "margin (m)", "frames received", "rejected", "deadline misses",
                                "unsafe", "detected"],
                               [[r["name"], r.get("outcome", r.get("crash", "")), r.get("margin_m"), r.get("frames_received"),
                                 ", ".join(f"{k} {n}" for k, n in sorted((r.get("rejects") or {}).items())) or "none",
                                 r.get("deadline_misses"), r.get("unsafe"),
                                 ", ".join(f"{k} {'yes' if ok else 'NO'}" for k, ok in (r.get("detected") or {}).items())]
                                for r in v["runs_detail"]])]
    return "\n".join(lines)
