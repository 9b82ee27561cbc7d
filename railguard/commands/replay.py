"""`railguard replay`: the core over a recorded bus log, through the live receive path."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .. import options, output
from ..setup import bus_keys, monitor_setup


HEADER = "    time  demand     mode       node  voted distance  track                   reasons"


def _plot(args: argparse.Namespace, points) -> Path:
    from can_bus.runner import risk_columns, track_columns
    from monitor.core.types import NO_DISTANCE
    from monitor.plot import plot_run

    return plot_run(Path(args.out) / f"replay-{Path(args.file).stem}.png", f"railguard replay: {Path(args.file).name}",
                    [x.tick / 1000 for x in points], [0.0 if x.speed_cms is None else x.speed_cms / 100 for x in points],
                    None, [None if x.distance_dm == NO_DISTANCE else x.distance_dm / 10 for x in points],
                    [x.demand for x in points], [x.mode for x in points], **track_columns(points), **risk_columns(points))


def _track(d) -> str:
    """The track column: the remembered obstacle's state, and its predicted distance while held."""
    from can_bus.runner import held_unseen
    from monitor.core.types import NO_DISTANCE, TRACK_NAMES, TRACK_NONE

    if d.track_state == TRACK_NONE:
        return "-"
    if held_unseen(d) and d.track_dm != NO_DISTANCE:
        return f"{TRACK_NAMES[d.track_state]} {d.track_dm / 10:.1f} m"
    return TRACK_NAMES[d.track_state]


def _change_line(d) -> str:
    from monitor.core.types import DEMAND_NAMES, MODE_NAMES, NO_DISTANCE, REASON_NAMES

    reasons = ",".join(n for b, n in enumerate(REASON_NAMES) if d.reasons & (1 << b)) or "-"
    dist = "none" if d.distance_dm == NO_DISTANCE else f"{d.distance_dm / 10:.1f} m"
    return (f"{d.tick / 1000:8.1f}  {DEMAND_NAMES[d.demand]:<9}  {MODE_NAMES[d.mode]:<9}  {d.node:>4}  "
            f"{dist:>14}  {_track(d):<22}  {reasons}")


def _listed(d, last) -> bool:
    """A line for the first cycle, a change of demand or mode, a track that starts or stops
    being held unseen, and a track forgotten or passed."""
    from can_bus.runner import held_unseen
    from monitor.core.types import TRACK_FORGOTTEN, TRACK_PASSED

    return (last is None or (d.demand, d.mode, held_unseen(d)) != (last.demand, last.mode, held_unseen(last))
            or d.track_state in (TRACK_FORGOTTEN, TRACK_PASSED))


def decision_row(d) -> list:
    """One cycle in `railguard replay --json`."""
    return [d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm, d.track_dm, d.track_state, d.track_cycles]


def _stats_lines(stats: dict, args: argparse.Namespace, first, last) -> None:
    from monitor.risk_summary import risk_line

    span = 0.0 if first is None else (last.tick - first.tick) / 1000
    print(f"{stats['cycles']} cycles over {span:.1f} s; frames {stats['frames']}, "
          f"accepted {stats['accepted']}, rejected {sum(stats['rejected'].values())}, filtered {stats['filtered']}")
    print(f"bus: {stats['bus_security']}")
    if stats["rejected"]:
        print("rejected: " + ", ".join(f"{k} {v}" for k, v in stats["rejected"].items()))
    if stats.get("note"):
        print(f"note: {stats['note']}")
    if stats["bus_events"]:
        print("bus state: " + ", ".join(f"{k} {v}" for k, v in stats["bus_events"].items())
              + f" (last: {stats['bus_state']})")
    for a in stats["time_anomaly_lines"]:
        print(f"line {a['line']}: timestamp jumps {a['jump_s']:+.6f} s ({a['kind']}): {a['action']}", file=sys.stderr)
    extra = sum(stats["time_anomalies"].values()) - len(stats["time_anomaly_lines"])
    if extra > 0:
        print(f"... and {extra} more timestamp anomalies", file=sys.stderr)
    print(risk_line(stats["risk"]))
    track = stats["track"]
    if track["held_total_s"] or track["forgotten"] or track["passed"]:
        print(f"track held while no channel showed it: longest {track['held_longest_s']:g} s, "
              f"total {track['held_total_s']:g} s; forgotten on evidence {track['forgotten']}, "
              f"passed {track['passed']}; memory cycles {track['memory_cycles']}")
    if stats["segments"] > 1:
        print(f"{stats['segments']} segments, each replayed as a fresh start of the monitor "
              f"(a timestamp jump of more than {args.max_gap:g} s ends a segment)")
    if "agreement_with_recorded" in stats:
        print(f"agreement with the recorded BrakeDemand frames: {stats['agreement_with_recorded']:.1%}")


def replay(args: argparse.Namespace) -> int:
    from can_bus import logfile
    from can_bus import replay as rp

    setup = monitor_setup(args)
    # read the log once before replaying: a bad line stops with exit 2 before any output
    rp.check(args.file, max_gap_s=args.max_gap, on_time_error=args.on_time_error)
    keys = None if args.keys is None else bus_keys(args, real_bus=True)
    replayer = rp.Replay(setup, max_gap_s=args.max_gap, on_time_error=args.on_time_error, source=args.file, keys=keys)
    thinned = rp.Thinned()
    first = last = None
    changes = shown = 0
    if args.json:
        sys.stdout.write('{"decisions": [')
    else:
        print(HEADER)
    for d in replayer.run(logfile.read(args.file)):
        if args.json:
            sys.stdout.write(("" if first is None else ", ") + json.dumps(decision_row(d)))
        elif _listed(d, last):
            changes += 1
            if shown < args.max_lines:
                shown += 1
                print(_change_line(d))
        if first is None:
            first = d
        last = d
        if not args.no_plot:
            thinned.add(d)
    stats = replayer.stats.as_dict()
    plot_path = None if args.no_plot else _plot(args, thinned.points)
    stats["plot"] = None if plot_path is None else str(plot_path)
    if args.json:
        sys.stdout.write("], " + json.dumps(stats)[1:] + "\n")
        return 0
    if changes > shown:
        print(f"... {changes - shown} more changes (--max-lines {args.max_lines}; --json gives every cycle)")
    _stats_lines(stats, args, first, last)
    output.wrote([plot_path])
    return 0


def register(sub) -> None:
    rp = sub.add_parser(
        "replay",
        help="run the core over a recorded bus log and show its decisions",
        description="Replay a recorded bus log (candump -L .log, or .asc, .blf, .csv, .trc ... anything python-can "
                    "reads) through the live monitor's receive path and core, print where demand and mode change "
                    "and where the remembered obstacle (the track) is held unseen, forgotten or passed, "
                    "the frames rejected by reason (fd_frame, remote_frame, error_frame, foreign_output, bad_crc, ...), "
                    "frames the live receive filter would not deliver (filtered), the bus state its error frames "
                    "announce, and plot. The log is streamed (constant memory); a line that is not a frame, or a "
                    "NaN/inf timestamp, stops with exit 2 naming file and line. The same file always gives the same "
                    "decisions.",
    )
    rp.add_argument("file", metavar="FILE", help="a CAN log file")
    g = rp.add_mutually_exclusive_group()
    g.add_argument("--keys", metavar="DIR", help="the key set of a log recorded on a secured bus (for a run on the "
                                                 "in-process bus: OUT/test-keys): every frame is verified as live "
                                                 "(default: unsecured)")
    g.add_argument("--unsecured", action="store_true", help="read the log as an unsecured bus, E2E only (the "
                                                            "default; old logs; the output says so)")
    options.add_monitor(rp)
    options.add_out(rp, what="folder for the plot")
    rp.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    options.add_json(rp, "print every decision as JSON (streamed: [tick, demand, reasons, mode, node, distance_dm, "
                         "track_dm, track_state, track_cycles] per cycle) with the frame counts and the track summary")
    rp.add_argument("--max-gap", type=options.positive_float, default=60.0, metavar="S",
                    help="a timestamp jump of more than S seconds, forward or back, ends a segment "
                         "(default: %(default)s)")
    rp.add_argument("--on-time-error", choices=("split", "refuse"), default="split",
                    help="at such a jump: replay the rest as a fresh start of the monitor (split) or stop with "
                         "exit 2 naming the line (refuse) (default: %(default)s)")
    rp.add_argument("--max-lines", type=options.positive_int, default=200, metavar="N",
                    help="list at most N changes of demand, mode or track (default: %(default)s)")
    rp.set_defaults(func=replay)
