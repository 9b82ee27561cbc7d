"""`railguard replay`: the core over a recorded bus log, through the live receive path."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .. import options, output
from ..setup import monitor_setup


def _plot(args: argparse.Namespace, points) -> Path:
    from monitor.core.types import NO_DISTANCE
    from monitor.plot import plot_run

    return plot_run(Path(args.out) / f"replay-{Path(args.file).stem}.png", f"railguard replay: {Path(args.file).name}",
                    [x.tick / 1000 for x in points], [0.0 if x.speed_cms is None else x.speed_cms / 100 for x in points],
                    None, [None if x.distance_dm == NO_DISTANCE else x.distance_dm / 10 for x in points],
                    [x.demand for x in points], [x.mode for x in points])


def _change_line(d) -> str:
    from monitor.core.types import DEMAND_NAMES, MODE_NAMES, NO_DISTANCE, REASON_NAMES

    reasons = ",".join(n for b, n in enumerate(REASON_NAMES) if d.reasons & (1 << b)) or "-"
    dist = "none" if d.distance_dm == NO_DISTANCE else f"{d.distance_dm / 10:.1f} m"
    return (f"{d.tick / 1000:8.1f}  {DEMAND_NAMES[d.demand]:<9}  {MODE_NAMES[d.mode]:<9}  {d.node:>4}  "
            f"{dist:>14}  {reasons}")


def _stats_lines(stats: dict, args: argparse.Namespace, first, last) -> None:
    span = 0.0 if first is None else (last.tick - first.tick) / 1000
    print(f"{stats['cycles']} cycles over {span:.1f} s; frames {stats['frames']}, "
          f"accepted {stats['accepted']}, rejected {sum(stats['rejected'].values())}, filtered {stats['filtered']}")
    if stats["rejected"]:
        print("rejected: " + ", ".join(f"{k} {v}" for k, v in stats["rejected"].items()))
    if stats["bus_events"]:
        print("bus state: " + ", ".join(f"{k} {v}" for k, v in stats["bus_events"].items())
              + f" (last: {stats['bus_state']})")
    for a in stats["time_anomaly_lines"]:
        print(f"line {a['line']}: timestamp jumps {a['jump_s']:+.6f} s ({a['kind']}): {a['action']}", file=sys.stderr)
    extra = sum(stats["time_anomalies"].values()) - len(stats["time_anomaly_lines"])
    if extra > 0:
        print(f"... and {extra} more timestamp anomalies", file=sys.stderr)
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
    replayer = rp.Replay(setup, max_gap_s=args.max_gap, on_time_error=args.on_time_error, source=args.file)
    thinned = rp.Thinned()
    first = last = None
    changes = shown = 0
    if args.json:
        sys.stdout.write('{"decisions": [')
    else:
        print("    time  demand     mode       node  voted distance  reasons")
    for d in replayer.run(logfile.read(args.file)):
        if args.json:
            sys.stdout.write(("" if first is None else ", ")
                             + json.dumps([d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm]))
        elif last is None or (d.demand, d.mode) != (last.demand, last.mode):
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
                    "reads) through the live monitor's receive path and core, print where demand and mode change, "
                    "the frames rejected by reason (fd_frame, remote_frame, error_frame, foreign_output, bad_crc, ...), "
                    "frames the live receive filter would not deliver (filtered), the bus state its error frames "
                    "announce, and plot. The log is streamed (constant memory); a line that is not a frame, or a "
                    "NaN/inf timestamp, stops with exit 2 naming file and line. The same file always gives the same "
                    "decisions.",
    )
    rp.add_argument("file", metavar="FILE", help="a CAN log file")
    options.add_monitor(rp)
    options.add_out(rp, what="folder for the plot")
    rp.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    options.add_json(rp, "print every decision as JSON (streamed: [tick, demand, reasons, mode, node, distance_dm] "
                         "per cycle) with the frame counts")
    rp.add_argument("--max-gap", type=options.positive_float, default=60.0, metavar="S",
                    help="a timestamp jump of more than S seconds, forward or back, ends a segment "
                         "(default: %(default)s)")
    rp.add_argument("--on-time-error", choices=("split", "refuse"), default="split",
                    help="at such a jump: replay the rest as a fresh start of the monitor (split) or stop with "
                         "exit 2 naming the line (refuse) (default: %(default)s)")
    rp.add_argument("--max-lines", type=options.positive_int, default=200, metavar="N",
                    help="list at most N changes of demand or mode (default: %(default)s)")
    rp.set_defaults(func=replay)
