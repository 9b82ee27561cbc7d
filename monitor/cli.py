"""`railguard`: the one command, with a subcommand per job.

Errors a user can cause (bad file, bad value, unknown name) print one line on stderr and
exit with code 2; nothing else is allowed to escape as a traceback.
"""
from __future__ import annotations

import argparse
import json
import time
import sys
from pathlib import Path
from typing import Callable, Sequence

from . import __version__

EXIT_USAGE = 2


class UserError(Exception):
    """A problem with the user's input, shown as one line."""


def _user_errors() -> tuple[type[BaseException], ...]:
    from .core.config import ConfigurationError
    from .core.table import TableError
    from .declaration import DeclarationError
    from .offline.params import ConfigError
    from .offline.pomdp import ModelError
    from .offline.pomdp_file import PomdpFormatError

    from verification.scale import ClusterError
    from verification.world_train import WorldTrainError

    errors = [UserError, TableError, ConfigError, ModelError, PomdpFormatError, ConfigurationError, DeclarationError,
              WorldTrainError, ClusterError, OSError]
    try:
        import can

        from can_bus.replay import ReplayError
        from can_bus.scenario import ScenarioError
        from can_bus.session import BusOpenError

        errors += [ScenarioError, ReplayError, BusOpenError, can.CanError]
    except ImportError:  # the CAN shell is optional for the offline commands
        pass
    try:
        from fmu.build import BuildError
        from fmu.cosim import CosimError
        from fmu.scenario import CosimScenarioError

        errors += [BuildError, CosimError, CosimScenarioError]
    except ImportError:  # the FMU shell is optional too
        pass
    return tuple(errors)


def _progress_printer(stream) -> Callable:
    """Solver progress on one refreshed line for a terminal, one line per 25 iterations otherwise."""
    tty = stream.isatty()

    def show(p) -> None:
        text = (f"iter {p.iteration:4d}  lower {p.lower:12.4f}  upper {p.upper:12.4f}  gap {p.gap:10.4f}  "
                f"alphas {p.alphas:4d}  beliefs {p.beliefs:4d}  {p.elapsed:6.1f} s")
        if tty:
            stream.write("\r" + text)
            stream.flush()
        elif p.iteration % 25 == 0:
            stream.write(text + "\n")

    def finish() -> None:
        if tty:
            stream.write("\n")

    def line(text: str) -> None:
        stream.write(text + "\n")
        stream.flush()

    show.finish = finish  # type: ignore[attr-defined]
    show.line = line  # type: ignore[attr-defined]
    return show


def cmd_pareto(args: argparse.Namespace) -> int:
    from pathlib import Path

    from verification import pareto

    if not args.model:
        raise UserError("--pareto sweeps one of the papers' models: give --model m1 or m2")
    grid = pareto.read_grid(args.grid) if args.grid else None
    say = (lambda text: print(text, file=sys.stderr, flush=True))
    out = Path(args.out) / f"pareto-{args.model}"
    from verification.scale import Cluster, check

    cluster = Cluster(args.workers or 1, args.scheduler)
    check(cluster)
    result = pareto.sweep(args.model, out, quick=True, time_budget=args.time_budget, grid=grid, progress=say,
                          cluster=cluster)
    files = [out / "frontier.json"]
    files[0].write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    files.append(pareto.plot(result, out / "frontier.png"))
    if args.json:
        print(json.dumps({**result, "files": [str(f) for f in files]}))
    else:
        sys.stdout.write(pareto.render(result))
        print("wrote " + "\n      ".join(str(f) for f in files) + f"\n      and one table folder per point under {out}")
    return 0


def cmd_solve(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from .offline import models, pipeline, pomdp_file
    if args.pareto:
        return cmd_pareto(args)
    if args.pomdp:
        model = pomdp_file.read(args.pomdp)
        plan = models.plan_for_pomdp_file(args.config)
    else:
        model, plan = models.load(args.model, args.config)
    settings = plan.settings
    for flag, field in (("seed", "seed"), ("time_budget", "time_budget_s"), ("max_iterations", "max_iterations"),
                        ("max_beliefs", "max_beliefs"), ("target_gap", "target_gap")):
        value = getattr(args, flag)
        if value is not None:
            settings = replace(settings, **{field: value})
    plan = replace(plan, settings=settings, max_nodes=args.max_nodes or plan.max_nodes)
    show_progress = not args.json or sys.stderr.isatty()
    printer = _progress_printer(sys.stderr) if show_progress else None
    started = {"done": False}

    def compile_line(text: str) -> None:
        if printer is None:
            return
        if not started["done"]:
            printer.finish()
            started["done"] = True
        printer.line(text)

    result = pipeline.run(model, plan, printer, compile_line)
    paths = pipeline.write(result, args.out)
    if args.json:
        out = pipeline.figures(result)
        out.update(table=str(paths["table"]), pomdp=str(paths["pomdp"]), summary=str(paths["summary"]))
        print(json.dumps(out))
    else:
        sys.stdout.write(pipeline.summary_text(result))
        print(f"wrote            {paths['table']}\n                 {paths['pomdp']}\n                 {paths['summary']}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from pathlib import Path

    from verification import evaluate as ev

    from verification.scale import Cluster, check

    cluster = Cluster(args.workers or 1, args.scheduler)
    check(cluster)
    result = ev.evaluate(args.table, quick=args.quick, seed=args.seed, cluster=cluster,
                         progress=None if args.quiet else (lambda text: print(text, file=sys.stderr, flush=True)))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = "evaluate-" + (args.table if args.table in ("m1", "m2") else Path(args.table).name.split(".")[0])
    files = [out / f"{stem}.json"]
    files[0].write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    if not args.no_plot:
        files.append(ev.plot(result, out / f"{stem}.png"))
    if args.json:
        print(json.dumps({**result, "files": [str(f) for f in files]}))
    else:
        sys.stdout.write(ev.render(result))
        print("wrote " + "\n      ".join(str(f) for f in files))
    return 0


def cmd_table_show(args: argparse.Namespace) -> int:
    from .offline import table_view

    table = table_view.read(args.file)
    if args.json:
        print(json.dumps(table_view.as_json(table)))
    else:
        sys.stdout.write(table_view.render(table))
    return 0


# ----------------------------------------------------------------------------- CAN commands

def _table_bytes(spec: str) -> bytes:
    from .tables import TableNotFound, read

    try:
        return read(spec)
    except TableNotFound as exc:
        raise UserError(str(exc)) from None


def _monitor_setup(args: argparse.Namespace):
    from .core import config as core_config
    from .core import cycle
    from .offline.params import read_toml

    values = {}
    if args.monitor_config:
        data = read_toml(args.monitor_config)
        values = data.get("monitor", data)
        if not isinstance(values, dict):
            raise UserError(f"{args.monitor_config}: [monitor] must be a table")
    try:
        cfg = core_config.from_mapping(values)
    except TypeError as exc:
        raise UserError(f"monitor configuration: {exc}") from None
    return cycle.create(_with_braking(cfg, args), _table_bytes(args.table))


def _with_braking(cfg, args: argparse.Namespace):
    """`cfg` with the train's braking declaration from --braking (None: the shipped train's)."""
    from .declaration import config_with

    return config_with(cfg, getattr(args, "braking", None))


BRAKING_HELP = ("the train's braking declaration (TOML, SI units: guaranteed decelerations, build-up "
                "times, speed error, adhesion factors, gradient, standstill margin; docs/supervision.md); "
                "default: the papers' train, monitor/trains/papers-train.toml")


def _bus_kwargs(args: argparse.Namespace) -> dict | None:
    """python-can's usual configuration: --interface/--channel, else its environment
    variables and config files; None if nothing names a bus (then: in-process virtual)."""
    import can

    given = {k: v for k, v in (("interface", args.interface), ("channel", args.channel)) if v}
    try:
        cfg = can.util.load_config(config=given)
    except can.CanInterfaceNotImplementedError as exc:
        if given:
            raise UserError(str(exc)) from None
        return None
    if not cfg.get("interface"):
        return None
    cfg.setdefault("channel", "vcan0" if cfg["interface"] == "socketcan" else "railguard")
    if cfg["interface"] == "virtual":
        cfg.setdefault("receive_own_messages", False)
    return cfg


def _printer(args: argparse.Namespace):
    if args.json or args.quiet:
        return None
    tty = sys.stderr.isatty()

    def show(text: str) -> None:
        sys.stderr.write(("\r" + text) if tty else text + "\n")
        sys.stderr.flush()

    return show


def _print_summary(summary: dict, as_json: bool, tty_line: bool) -> None:
    if tty_line:
        sys.stderr.write("\n")
    if as_json:
        print(json.dumps(summary))
        return
    width = max(len(k) for k in summary)
    for key, value in summary.items():
        if isinstance(value, dict):
            value = ", ".join(f"{k} {v}" for k, v in value.items()) or "-"
        elif isinstance(value, list):
            value = ", ".join(map(str, value)) or "-"
        print(f"{key:<{width}}  {value}")


def cmd_run(args: argparse.Namespace) -> int:
    from can_bus import scenario as scenarios
    from can_bus import session

    setup = _monitor_setup(args)
    scen = None if args.no_player else scenarios.load(args.scenario)
    bus = _bus_kwargs(args)
    out = Path(args.out)
    show = _printer(args)
    if bus is None:
        if scen is None:
            raise UserError("--no-player needs a real bus (--interface/--channel): on the in-process bus nothing would send")
        result = session.run_virtual(setup, scen, out, show=show, plot=not args.no_plot)
    else:
        result = session.run_on_bus(setup, bus, out, scenario=scen, duration_s=args.duration, show=show,
                                    plot=not args.no_plot, name=scen.name if scen else str(bus.get("channel")))
    _print_summary(result.summary, args.json, show is not None and sys.stderr.isatty())
    return 0


def cmd_play(args: argparse.Namespace) -> int:
    import signal
    import threading

    from can_bus import scenario as scenarios
    from can_bus.clock import WallClock
    from can_bus.player import Player
    from can_bus.session import open_bus, play_loop

    scen = scenarios.load(args.scenario)
    bus_cfg = _bus_kwargs(args)
    if bus_cfg is None:
        raise UserError("play needs a bus: give --interface and --channel (e.g. socketcan vcan0)")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    bus = open_bus(bus_cfg)
    try:
        player = Player(bus, scen, args.period, wait_for_monitor=not args.no_wait)
        play_loop(player, WallClock(), stop)
    finally:
        bus.shutdown()
    summary = dict(player.outcome(), scenario=scen.name, frames_sent=player.frames_sent,
                   faults_injected=sorted(f"{k}@ch{c}" for k, c in player.faults_injected))
    _print_summary(summary, args.json, False)
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    from can_bus import logfile
    from can_bus import replay as rp
    from can_bus.plot import plot_run
    from monitor.core.types import DEMAND_NAMES, MODE_NAMES, NO_DISTANCE, REASON_NAMES

    setup = _monitor_setup(args)
    # read the log once before replaying: a bad line stops with exit 2 before any output
    rp.check(args.file, max_gap_s=args.max_gap, on_time_error=args.on_time_error)
    replay = rp.Replay(setup, max_gap_s=args.max_gap, on_time_error=args.on_time_error, source=args.file)
    frames = logfile.read(args.file)
    thinned = rp.Thinned()
    first = last = None
    changes = 0
    shown = 0
    out = sys.stdout
    if args.json:
        out.write('{"decisions": [')
    else:
        print("    time  demand     mode       node  voted distance  reasons")
    for d in replay.run(frames):
        if args.json:
            out.write(("" if first is None else ", ") + json.dumps([d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm]))
        elif last is None or (d.demand, d.mode) != (last.demand, last.mode):
            changes += 1
            if shown < args.max_lines:
                shown += 1
                reasons = ",".join(n for b, n in enumerate(REASON_NAMES) if d.reasons & (1 << b)) or "-"
                dist = "none" if d.distance_dm == NO_DISTANCE else f"{d.distance_dm / 10:.1f} m"
                print(f"{d.tick / 1000:8.1f}  {DEMAND_NAMES[d.demand]:<9}  {MODE_NAMES[d.mode]:<9}  {d.node:>4}  "
                      f"{dist:>14}  {reasons}")
        if first is None:
            first = d
        last = d
        if not args.no_plot:
            thinned.add(d)
    stats = replay.stats.as_dict()
    plot_path = None
    if not args.no_plot:
        ds = thinned.points
        plot_path = plot_run(Path(args.out) / f"replay-{Path(args.file).stem}.png", f"railguard replay: {Path(args.file).name}",
                             [x.tick / 1000 for x in ds], [0.0 if x.speed_cms is None else x.speed_cms / 100 for x in ds], None,
                             [None if x.distance_dm == NO_DISTANCE else x.distance_dm / 10 for x in ds],
                             [x.demand for x in ds], [x.mode for x in ds])
    stats["plot"] = None if plot_path is None else str(plot_path)
    if args.json:
        out.write("], " + json.dumps(stats)[1:] + "\n")
        return 0
    if changes > shown:
        print(f"... {changes - shown} more changes (--max-lines {args.max_lines}; --json gives every cycle)")
    print(f"{stats['cycles']} cycles over {(last.tick - first.tick) / 1000:.1f} s; frames {stats['frames']}, "
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
    if plot_path:
        print(f"plot: {plot_path}")
    return 0


def _add_monitor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--table", default="m2", metavar="m1|m2|FILE",
                   help="policy table: a shipped model name or a .table.rgt file (default: %(default)s)")
    p.add_argument("--braking", metavar="FILE.toml", help=BRAKING_HELP)
    p.add_argument("--monitor-config", metavar="FILE.toml",
                   help="monitor configuration ([monitor] table: period_ms, timeout_cycles, decelerations, ... see docs/core.md)")


def _add_bus_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--interface", help="python-can interface (socketcan, virtual, pcan, ...); default: python-can's "
                                       "environment/config file, else the in-process virtual bus")
    p.add_argument("--channel", help="python-can channel (e.g. vcan0)")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


# ----------------------------------------------------------------------------- FMU commands

def cmd_build_fmu(args: argparse.Namespace) -> int:
    from fmu import build

    from .core.config import Config

    cfg = _with_braking(Config(), args) if args.braking else None
    if args.ssp is not None:
        from fmu import scenario, ssp

        scen = scenario.load(args.ssp or None)
        out = Path(args.out)
        monitor_fmu = build.build_monitor(_table_bytes(scen.table), 2, out, config=cfg)
        train_fmu = build.build_train(out)
        path = ssp.write(out / f"railguard-{scen.name}.ssp", train_fmu, monitor_fmu, scen.train, scen.monitor,
                         scen.duration_s, name=f"railguard-{scen.name}")
    elif args.train:
        path = build.build_train(args.out)
    else:
        path = build.build_monitor(_table_bytes(args.model), args.fmi, args.out, config=cfg)
    print(path)
    return 0


def cmd_cosim(args: argparse.Namespace) -> int:
    import tempfile

    from fmu import build, cosim, scenario

    scen = scenario.load(args.scenario)
    if args.braking:
        from .declaration import load

        scen = scenario.with_braking(scen, load(args.braking), args.braking)
    out = Path(args.out)
    with tempfile.TemporaryDirectory(prefix="railguard-cosim-") as tmp:
        monitor_fmu = args.monitor_fmu or build.build_monitor(_table_bytes(args.table or scen.table), args.fmi, tmp)
        train_fmu = args.train_fmu or build.build_train(tmp)
        result = cosim.run_scenario(scen, monitor_fmu, train_fmu, args.step, args.demand_delay)
    csv_path = cosim.write_csv(result, out / f"cosim-{scen.name}.csv")
    plot_path = None if args.no_plot else cosim.plot(result, out / f"cosim-{scen.name}.png",
                                                      f"railguard co-simulation: {scen.name}")
    summary = {
        "scenario": scen.name, "outcome": result.outcome,
        "margin_m": None if result.margin_m is None else round(result.margin_m, 3),
        "steps": result.steps, "monitor_cycles": result.monitor_cycles, "step_s": args.step,
        "simulated_s": round(result.simulated_s, 3), "wall_s": round(result.wall_s, 4),
        "realtime_factor": round(result.realtime_factor, 1),
        "first_brake_s": result.first_brake_s, "max_demand": result.max_demand,
        "demand_delay_cycles": result.demand_delay_cycles,
        "stop_margin_m": None if result.stop_margin_m is None else round(result.stop_margin_m, 3),
        "impact_speed": round(result.impact_speed, 3),
        "csv": str(csv_path), "plot": None if plot_path is None else str(plot_path),
    }
    if args.json:
        print(json.dumps(summary))
    else:
        margin = "" if result.margin_m is None else f", margin {result.margin_m:.1f} m"
        brake = "never braked" if result.first_brake_s is None else f"first brake demand at {result.first_brake_s:.1f} s"
        print(f"{scen.name}: {result.outcome}{margin}; {brake}; {result.steps} steps of {args.step * 1000:g} ms "
              f"({result.monitor_cycles} monitor cycles) in {result.wall_s:.2f} s = {result.realtime_factor:,.0f}x real time")
        print(f"csv:  {csv_path}")
        if plot_path:
            print(f"plot: {plot_path}")
    return 0


# ----------------------------------------------------------------------------- evidence

def _run_evidence(args: argparse.Namespace, parts: tuple[str, ...]) -> int:
    """Run verification parts, print one line per check (or JSON), exit 1 if one fails."""
    from verification import run

    from .core.config import Config

    started = time.perf_counter()

    def progress(msg: str) -> None:
        if not args.json:
            print(f"[{time.perf_counter() - started:6.1f} s] {msg}", file=sys.stderr, flush=True)

    cfg = _with_braking(Config(), args) if getattr(args, "braking", None) else None
    world = None
    if getattr(args, "world_train", None):
        from verification.world_train import load

        world = load(args.world_train)
    cluster = None
    if getattr(args, "workers", None) is not None or getattr(args, "scheduler", None):
        from verification.scale import Cluster, check

        cluster = Cluster(args.workers or 0, args.scheduler)
        check(cluster)
    sections, report = run.run(args.out, args.quick, progress, parts, config=cfg, world=world,
                               margin_m=getattr(args, "unsafe_margin", 0.0), cluster=cluster)
    checks = [c for s in sections for c in s.checks]
    passed = all(c.passed for c in checks)
    if args.json:
        from verification.report import as_json, plain

        data = as_json(sections)
        data["report"] = str(report)
        print(json.dumps(data, default=plain))
    else:
        for c in checks:
            print(c.line())
        for s in sections:
            if "runs_digest" in s.headline:
                h = s.headline
                print(f"{s.title}: {h['runs']:,} runs, {h['unsafe']} unsafe, {h['collisions']} collisions; "
                      f"runs digest {h['runs_digest']}")
        print(f"{'passed' if passed else 'FAILED'}: {sum(c.passed for c in checks)} of {len(checks)} checks; report {report}")
    return 0 if passed else 1


def cmd_verify(args: argparse.Namespace) -> int:
    from verification import run

    return _run_evidence(args, tuple(args.part) if args.part else run.PARTS)


def cmd_campaign(args: argparse.Namespace) -> int:
    return _run_evidence(args, ("campaign", "fuzz"))


def cmd_stress(args: argparse.Namespace) -> int:
    """Adaptive stress testing: the likeliest failure and P(collision per encounter)."""
    from verification import stress
    from verification.scale import Cluster, check
    from verification.world_train import load

    from .core.config import Config

    cfg = _with_braking(Config(), args)
    world = load(args.world_train) if args.world_train else None
    cluster = Cluster(args.workers or 0, args.scheduler)
    check(cluster)
    started = time.perf_counter()

    def say(msg: str) -> None:
        if not args.json:
            print(f"[{time.perf_counter() - started:6.1f} s] {msg}", file=sys.stderr, flush=True)

    result = stress.run(args.table, args.encounter, Path(args.out), quick=args.quick, cfg=cfg, world=world,
                        margin_m=args.unsafe_margin, seed=args.seed, cluster=cluster, progress=say)
    if args.json:
        print(json.dumps(result, default=str))
    else:
        sys.stdout.write(stress.render(result))
        print("wrote " + "\n      ".join(result["files"]))
    return 0


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 1 <= n <= 1024:
        raise argparse.ArgumentTypeError(f"{text!r} must be 1..1024")
    return n


def _cluster_arguments(p: argparse.ArgumentParser, default: str = "one per core", what: str = "") -> None:
    p.add_argument("--workers", type=_workers, metavar="N",
                   help=f"{what}worker processes of a local dask cluster (default: {default}; 1 runs in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing dask.distributed cluster, e.g. tcp://10.0.0.5:8786 (its workers need "
                        "railguard installed); results are identical to a local run")


def _stress_parser(sub) -> None:
    from verification.stress import ENCOUNTERS

    st = sub.add_parser(
        "stress",
        help="adaptive stress testing: the likeliest disturbance sequence that ends in a collision",
        description="Search (cross-entropy method) for the likeliest sequence of sensor disturbances (a common-cause "
                    "blindness of every channel, misses, lost frames, ghosts, distance noise) that makes the world's "
                    "train hit an obstacle it could have stopped for, with the shipped table and the supervision in the "
                    "loop; prune it to the disturbances it needs; write it as a candump log that `railguard replay` "
                    "reproduces (checked) and as a cosim scenario of the encounter; estimate P(collision per "
                    "encounter) by importance sampling against naive Monte Carlo. Encounters: "
                    + "; ".join(f"{e.name}: {e.description}" for e in ENCOUNTERS.values()) + ".",
    )
    st.add_argument("--table", choices=["m1", "m2"], default="m2", help="the shipped table in the loop (default: %(default)s)")
    st.add_argument("--encounter", choices=sorted(ENCOUNTERS), default="edge-30", help="default: %(default)s")
    st.add_argument("--quick", action="store_true", help="6 iterations of 100 runs, 400 importance samples (about a minute)")
    st.add_argument("--seed", type=int, default=0, help="root of every run's seed (default: %(default)s)")
    st.add_argument("--braking", metavar="FILE.toml", help=BRAKING_HELP)
    st.add_argument("--world-train", metavar="FILE.toml",
                    help="the world's train (default: the braking declaration's worst corner)")
    st.add_argument("--unsafe-margin", type=float, default=0.0, metavar="M",
                    help="a gap below M metres counts as a failure (default: %(default)s)")
    _cluster_arguments(st)
    st.add_argument("--out", default="railguard-out/stress", metavar="DIR", help="output folder (default: %(default)s)")
    st.add_argument("--json", action="store_true",
                    help='print {"most_likely_failure": null or {"log_likelihood", "events", "candump", "cosim", ...}, '
                         '"rare_event": {...}, ...}')
    st.set_defaults(func=cmd_stress)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="railguard",
        description="Railway anti-collision safety monitor: offline POMDP tables, online cyclic monitor.",
    )
    parser.add_argument("--version", action="version", version=f"railguard {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser(
        "solve",
        help="solve a POMDP with point-based value iteration and compile the fixed policy table",
        description=(
            "Solve one of the papers' models (--model) or any Cassandra .pomdp file (--pomdp) with "
            "point-based value iteration, compile the alpha vectors into a finite-state controller, "
            "evaluate it exactly and write DIR/<name>.table.rgt, DIR/<name>.pomdp and DIR/<name>.summary.txt. "
            "Progress (iteration, bounds, gap, elapsed) goes to stderr."
        ),
        epilog="A TOML file given with --config sets model parameters at top level and solver settings "
               "in a [solver] table (seed, max_iterations, max_beliefs, expand_every, target_gap, "
               "time_budget_s, max_nodes). See docs/models.md for every parameter.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--model", choices=["m1", "m2"], help="m1: seed 000, 4 states; m2: seed 001, 144 states")
    src.add_argument("--pomdp", metavar="FILE", help="a Cassandra .pomdp file")
    p.add_argument("--config", metavar="FILE.toml", help="parameter and solver overrides")
    p.add_argument("--out", metavar="DIR", default="railguard-out", help="output folder (default: %(default)s)")
    p.add_argument("--seed", type=int, help="seed of the belief-set expansion (default 0)")
    p.add_argument("--time-budget", type=_positive_float, metavar="S",
                   help="bound the whole run (solve, compile, evaluate) to about S seconds; with --pareto, per point "
                        "(default: the model's, m1 30 s, m2 60 s)")
    p.add_argument("--max-iterations", type=_positive_int, metavar="N", help="stop after N backups")
    p.add_argument("--max-beliefs", type=_positive_int, metavar="N", help="cap on the belief set")
    p.add_argument("--target-gap", type=_positive_float, metavar="X", help="stop when gap <= X * max(1, |upper|)")
    p.add_argument("--max-nodes", type=_positive_int, metavar="N", help="node budget of the compiled controller")
    p.add_argument("--pareto", action="store_true",
                   help="sweep the cost weights (collision, braking, demand change), solve each, judge each table "
                        "like `railguard evaluate --quick` and write DIR/pareto-MODEL/frontier.json and frontier.png "
                        "(p_hazard against unnecessary braking, baselines as points)")
    p.add_argument("--grid", metavar="FILE.toml",
                   help="with --pareto: the weights to sweep, e.g. braking_weight = [1.0, 2.0] and "
                        "release_cost = [0.0, 1.0] (every combination); default: the built-in grid of the model")
    _cluster_arguments(p, "1: the points one after the other, each with a core to itself", "with --pareto: ")
    p.add_argument("--json", action="store_true", help="print one JSON object with the figures and paths")
    p.set_defaults(func=cmd_solve)

    e = sub.add_parser(
        "evaluate",
        help="a table against the simple rules: risk, needless braking, stops, demand changes",
        description="Evaluate a policy table and the baselines threshold, belief_tracking, always_emergency and "
                    "never, each with the braking-curve supervision in front: p_hazard = P(hazard within 30 s) on "
                    "the model's closed loop (exact for finite-state controllers, Monte Carlo for belief tracking); "
                    "unnecessary_braking (fraction of obstacle-free time with a brake demand), stops_per_train_hour "
                    "and demand_changes_per_encounter by Monte Carlo in the model's seed world (m1: seed 000's "
                    "world with 2 %% phantoms and misses; m2: seed 001's), with 95 %% intervals. Writes "
                    "DIR/evaluate-NAME.json and a plot of p_hazard against unnecessary braking.",
        epilog="JSON shape: {\"table\": {...}, \"baselines\": {\"threshold\": {...}, ...}, ...}; every figure "
               "has a *_ci half-width. A table file's belief_tracking baseline needs its .alphas.npz beside it "
               "(railguard solve writes it).",
    )
    e.add_argument("table", metavar="m1|m2|TABLE", help="a shipped model name or a .table.rgt file of model m1 or m2")
    e.add_argument("--quick", action="store_true", help="96 trains x 300 s, 2,000 episodes (default 288 x 600 s, 10,000)")
    e.add_argument("--seed", type=int, default=12, help="seed of every Monte Carlo run (default: %(default)s)")
    e.add_argument("--out", metavar="DIR", default="railguard-out", help="output folder (default: %(default)s)")
    e.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    e.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    _cluster_arguments(e, "1: the policies one after the other", "each policy a dask task; ")
    e.add_argument("--json", action="store_true", help="print one JSON object (the figures and the files written)")
    e.set_defaults(func=cmd_evaluate)

    t = sub.add_parser("table", help="inspect compiled policy tables", description="Inspect compiled policy tables.")
    tsub = t.add_subparsers(dest="table_command", metavar="ACTION")
    tsub.required = True
    show = tsub.add_parser(
        "show",
        help="print a table's header and its controller node by node",
        description="Check a table file (magic, version, SHA-256, dimensions) and print its header and, "
                    "for every node, the action and where each observation leads.",
    )
    show.add_argument("file", metavar="FILE", help="a .table.rgt file")
    show.add_argument("--json", action="store_true", help="print the header and the controller as JSON")
    show.set_defaults(func=cmd_table_show)

    r = sub.add_parser(
        "run",
        help="run the cyclic monitor on CAN (default: with the scenario player on the in-process bus)",
        description="Run the monitor: every period drain the bus, latch the newest valid report per channel, "
                    "step the core, send BrakeDemand and MonitorStatus. With no bus options the monitor and the "
                    "built-in scenario player share python-can's in-process virtual bus on a simulated clock "
                    "(deterministic, as fast as the CPU allows). Writes a candump .log of the bus and a plot, "
                    "prints a summary. SIGINT/SIGTERM: a last emergency demand, the summary, exit 0.",
    )
    _add_monitor_options(r)
    _add_bus_options(r)
    r.add_argument("--scenario", default="static-obstacle", metavar="NAME|FILE.toml",
                   help="scenario for the player (shipped: static-obstacle, moving-obstacle, no-obstacle, fault-cascade)")
    r.add_argument("--no-player", action="store_true", help="monitor only (a real bus where others send)")
    r.add_argument("--duration", type=_positive_float, metavar="S", help="stop after S seconds (real bus)")
    r.add_argument("--out", default="railguard-out", metavar="DIR", help="folder for the .log and the plot (default: %(default)s)")
    r.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    r.add_argument("--quiet", action="store_true", help="no live status line")
    r.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    r.set_defaults(func=cmd_run)

    pl = sub.add_parser(
        "play",
        help="run the scenario player alone on a bus (the monitor runs elsewhere)",
        description="Simulate the train and the six sensor channels of a scenario on a real bus, in real time. "
                    "The train waits at the entry until the monitor reports NORMAL with no demand.",
    )
    pl.add_argument("scenario", metavar="SCENARIO", help="a shipped scenario name or a .toml file")
    _add_bus_options(pl)
    pl.add_argument("--period", type=_positive_int, default=100, metavar="MS", help="send period (default: %(default)s ms)")
    pl.add_argument("--no-wait", action="store_true", help="start at once, do not wait for the monitor")
    pl.add_argument("--json", action="store_true", help="print the outcome as one JSON object")
    pl.set_defaults(func=cmd_play)

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
    _add_monitor_options(rp)
    rp.add_argument("--out", default="railguard-out", metavar="DIR", help="folder for the plot (default: %(default)s)")
    rp.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    rp.add_argument("--json", action="store_true", help="print every decision as JSON (streamed: [tick, demand, "
                    "reasons, mode, node, distance_dm] per cycle) with the frame counts")
    rp.add_argument("--max-gap", type=_positive_float, default=60.0, metavar="S",
                    help="a timestamp jump of more than S seconds, forward or back, ends a segment "
                         "(default: %(default)s)")
    rp.add_argument("--on-time-error", choices=("split", "refuse"), default="split",
                    help="at such a jump: replay the rest as a fresh start of the monitor (split) or stop with "
                         "exit 2 naming the line (refuse) (default: %(default)s)")
    rp.add_argument("--max-lines", type=_positive_int, default=200, metavar="N",
                    help="list at most N changes of demand or mode (default: %(default)s)")
    rp.set_defaults(func=cmd_replay)

    b = sub.add_parser(
        "build-fmu",
        help="build the monitor (or the train-dynamics) FMU and print its path",
        description="Generate the C core with the policy table compiled in, wrap it as an FMI 2.0 or 3.0 "
                    "Co-Simulation FMU with its sources and the linux64 binary (gcc -std=c99 -Wall -Wextra "
                    "-Werror -pedantic), and print the path of the .fmu written.",
    )
    b.add_argument("--model", default="m1", metavar="m1|m2|FILE",
                   help="policy table: shipped m1 or m2, or a .table.rgt file (default: %(default)s)")
    b.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="FMI version (default: %(default)s)")
    b.add_argument("--train", action="store_true", help="build the train-dynamics FMU (FMI 2.0) instead")
    b.add_argument("--braking", metavar="FILE.toml",
                   help=BRAKING_HELP + "; it becomes the monitor FMU's parameter start values")
    b.add_argument("--ssp", nargs="?", const="", metavar="SCENARIO",
                   help="build both FMUs and the SSP of the closed loop for a cosim scenario (default: "
                        "static-obstacle); runs with fmpy.ssp.simulate_ssp at a 0.1 s step")
    b.add_argument("--out", default=".", metavar="DIR", help="output folder (default: the current one)")
    b.set_defaults(func=cmd_build_fmu)

    c = sub.add_parser(
        "cosim",
        help="co-simulate the train-dynamics FMU and the monitor FMU in FMPy",
        description="Build both FMUs (unless given), close the loop in FMPy with a master over FMPy's slave "
                    "classes (train every --step, monitor every 100 ms), write a CSV of all signals and a plot, "
                    "and print the outcome and the speed as a real-time factor.",
        epilog="Shipped scenarios: static-obstacle (default), moving-obstacle, no-obstacle, and one per "
               "single fault: fault-silence, fault-stuck, fault-noise-burst, fault-missed-detection, "
               "fault-degraded, fault-nan-distance, fault-contradiction. See docs/fmu.md.",
    )
    c.add_argument("scenario", nargs="?", default=None, metavar="SCENARIO",
                   help="a shipped scenario name or a .toml file (default: static-obstacle)")
    c.add_argument("--table", metavar="m1|m2|FILE", help="policy table (default: the scenario's)")
    c.add_argument("--fmi", type=int, choices=[2, 3], default=2, help="FMI version of the monitor FMU (default: %(default)s)")
    c.add_argument("--step", type=_positive_float, default=0.01, metavar="S",
                   help="communication step of the train FMU; must divide 0.1 s (default: %(default)s)")
    c.add_argument("--monitor-fmu", metavar="FILE", help="use this monitor FMU instead of building one")
    c.add_argument("--train-fmu", metavar="FILE", help="use this train FMU instead of building one")
    c.add_argument("--braking", metavar="FILE.toml", help=BRAKING_HELP + "; replaces the scenario's [braking]")
    c.add_argument("--demand-delay", type=int, metavar="CYCLES",
                   help="monitor cycles before the train acts on a demand (default: the scenario's, else 1: as on CAN)")
    c.add_argument("--out", default="railguard-out", metavar="DIR", help="folder for the CSV and the plot (default: %(default)s)")
    c.add_argument("--no-plot", action="store_true", help="do not draw the plot")
    c.add_argument("--json", action="store_true", help="print the outcome as one JSON object")
    c.set_defaults(func=cmd_cosim)

    v = sub.add_parser(
        "verify",
        help="compute the evidence: closed-loop probabilities, voter hazard rate, the papers reproduced",
        description="Run every verification part and write a report (Markdown, JSON and PNG figures) into --out: "
                    "the closed-loop Markov analysis of the shipped tables (exact and Storm), the 2oo2/3oo3 voter's "
                    "hazard rate against tolerable rates (seed 002, seed 004), and the simulations of seed 000 and "
                    "seed 001 through the monitor core. Prints one line per check; exit status 1 if any check fails.",
    )
    v.add_argument("--quick", action="store_true", help="smaller Monte Carlo runs and grids (under 2 minutes; what CI runs)")
    v.add_argument("--out", default="railguard-out/verify", metavar="DIR", help="report folder (default: %(default)s)")
    v.add_argument("--part", action="append", choices=["closed_loop", "evaluate", "monotone", "hazard", "seed000", "seed001", "campaign", "stress", "fuzz",
                            "proof", "mutation"],
                   help="run only this part (repeatable)")
    v.add_argument("--json", action="store_true",
                   help='print {"passed": bool, "checks": [{"name", "passed", "figure", ...}], ...}')
    v.set_defaults(func=cmd_verify)

    ca = sub.add_parser(
        "campaign",
        help="fault-injection campaign and receive-path fuzzing on the running monitor",
        description="Every single fault and every pair from the fault catalogue (silence, stuck value, noise burst, "
                    "missed detection, CRC corruption, counter freeze and jump, wrong length, babbling, contradiction, "
                    "stale timestamps, deadline overrun, corrupted or mismatched table) crossed with obstacle scenarios, "
                    "through the core, a sample through the real runner and codec on the virtual bus and on vcan0; then "
                    "random and mutated frames into the receive path. The simulated world is the judge: a run is "
                    "unsafe when the world's train (the train FMU's physics, with parameters of its own: --world-train) "
                    "reaches an obstacle it could have stopped for. Counts unsafe runs, crashes, collisions and false "
                    "braking; prints a digest of every run's seed and outcome; writes a report; exit status 1 if a "
                    "check fails.",
    )
    ca.add_argument("--quick", action="store_true", help="a few hundred runs and 20,000 frames (what CI runs)")
    ca.add_argument("--braking", metavar="FILE.toml", help=BRAKING_HELP)
    ca.add_argument("--world-train", metavar="FILE.toml",
                    help="the simulated world's train, independent of the monitor's declaration (a [world_train] "
                         "table: emergency_decel, service_decel, brake_delay, brake_buildup, gradient, traction_cutoff, "
                         "max_traction, speed_error, davis_a/b/c, mass, sensor_latency_s, output_latency_s; "
                         "verification/world_train.py); default: every run its own train drawn inside the declaration, "
                         "one in four on its worst corners")
    ca.add_argument("--unsafe-margin", type=float, default=0.0, metavar="M",
                    help="a run is unsafe when the world's train reaches an obstacle it could stop for, or comes "
                         "closer to it than M metres (default: %(default)s)")
    _cluster_arguments(ca)
    ca.add_argument("--out", default="railguard-out/campaign", metavar="DIR", help="report folder (default: %(default)s)")
    ca.add_argument("--json", action="store_true",
                    help='print {"passed": bool, "unsafe": N, "runs": N, "runs_digest": "sha256", "checks": [...], ...}')
    ca.set_defaults(func=cmd_campaign)
    _stress_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except BrokenPipeError:   # output piped into `head` and the like: not an error
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except _user_errors() as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if isinstance(exc, OSError) and getattr(exc, "filename", None):
            msg = f"{exc.filename}: {exc.strerror}"
        print(f"railguard: error: {msg}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("railguard: interrupted", file=sys.stderr)
        return 130


def entry() -> None:
    sys.exit(main())


if __name__ == "__main__":
    entry()
