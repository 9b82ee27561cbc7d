"""`railguard run`: the monitor and (optionally) the scenario player on one bus, a bus
recording, a summary and a plot.

On python-can's in-process `virtual` bus the two share a simulated clock and interleave
period by period (player sends, monitor drains and steps), so a run is deterministic and
takes no wall time. On a real bus (SocketCAN vcan0, a HIL rig) the monitor runs in real
time; the player then runs as a separate process (`railguard play`) or in a thread.
"""
from __future__ import annotations

import signal
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import can

from monitor.core import cycle as core
from monitor.core.types import DEMAND_NAMES, MODE_NAMES, NO_DISTANCE, REASON_NAMES, TRACK_NAMES

from . import frames
from .clock import SimClock, WallClock
from .logfile import CandumpWriter
from .player import Player
from .runner import MonitorRunner, TrackTally, held_unseen, risk_columns, risk_summary, track_columns
from .scenario import Scenario
from .security import describe as describe_security

VIRTUAL_CHANNEL = "railguard"
ATTACK_REFUSALS = ("bad_mac", "stale_freshness", "second_sender", "classical_frame", "foreign_output")
RECORDER_BUDGET_S = 0.010    # per cycle on a real bus: the recorder may never hold the monitor's cycle


class BusOpenError(RuntimeError):
    """The CAN interface could not be opened; the message names it and says what to do."""


class MonitorNotReady(RuntimeError):
    """The player waited its limit for the monitor's NORMAL with no demand, and it never came."""


def open_bus(bus_kwargs: dict, *, monitor: bool = False) -> can.BusABC:
    """Open a python-can bus; on SocketCAN every connection has CAN FD frames enabled (the
    secured bus sends them), and the monitor's own gets the kernel receive filter, so that it
    sees, and counts, what replay counts."""
    kwargs = dict(bus_kwargs)
    if kwargs.get("interface") == "socketcan":
        kwargs.setdefault("fd", True)          # every node: a secured bus's frames are CAN FD frames
        if monitor:
            kwargs.setdefault("can_filters", frames.kernel_filters())
    try:
        return can.Bus(**kwargs)
    except Exception as exc:  # noqa: BLE001 - python-can raises OSError, CanError, ValueError, ...
        iface, channel = bus_kwargs.get("interface"), bus_kwargs.get("channel")
        hint = ("; a virtual SocketCAN bus without kernel CAN support: python -m can_bus.vcan -- railguard run "
                "--interface socketcan --channel vcan0 ...; with the vcan module: ip link add dev vcan0 type vcan "
                "&& ip link set up vcan0")
        raise BusOpenError(f"cannot open CAN interface {iface!r} channel {channel!r}: "
                           f"{str(exc).strip() or type(exc).__name__}{hint}") from None


@dataclass
class Recorder:
    """Writes every frame on the bus to a candump -L .log (can_bus/logfile.py keeps error
    frames' classes, which python-can's writer drops). On a real bus it reads for at most
    RECORDER_BUDGET_S per cycle; if that was not enough, the log is marked incomplete."""

    bus: can.BusABC
    path: Path
    clock: object
    count: int = 0
    complete: bool = True

    def __post_init__(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.writer = CandumpWriter(self.path)

    def drain(self, budget_s: Optional[float] = None) -> None:
        end = None if budget_s is None or self.clock.simulated else time.monotonic() + budget_s
        while True:
            msg = self.bus.recv(timeout=0.0)
            if msg is None:
                return
            self.writer.write(msg, self.clock.now_s() if self.clock.simulated else msg.timestamp)
            self.count += 1
            if end is not None and time.monotonic() > end:
                self.complete = False
                return

    def close(self) -> None:
        self.drain(budget_s=None if self.clock.simulated else 1.0)
        self.writer.stop()


@dataclass
class RunResult:
    summary: dict
    runner: MonitorRunner
    player: Optional[Player] = None
    extra: dict = field(default_factory=dict)


FAULT_REASONS = ("stale", "system_error", "perceptor", "deadline", "train_input", "implausible")   # diagnostics, not the track
FAULT_BITS = sum(1 << bit for bit, name in enumerate(REASON_NAMES) if name in FAULT_REASONS)


def detected_faults(runner: MonitorRunner) -> dict:
    """What the monitor noticed: rejected frames by reason, and diagnostic reason bits."""
    seen = Counter()
    for rec in runner.records:
        for bit, name in enumerate(REASON_NAMES):
            if rec.reasons & (1 << bit) and name in FAULT_REASONS:
                seen[name] += 1
    out = {f"frames_{k}": v for k, v in sorted(runner.receiver.rejected.items()) if v}
    out.update({f"cycles_{k}": v for k, v in sorted(seen.items())})
    return out


def changes_by_cause(records: list) -> dict:
    """Demand changes split by what caused them: `faults` if the cycle before or after the change
    carries a diagnostic reason (a stale channel, a system error, a missed deadline, ...), else
    `encounter` (the table, the envelope, the track). The hysteresis target of issue 12 (at most
    2 per encounter) is about the second; an injected fault adds its own on top."""
    out = {"encounter": 0, "faults": 0}
    for a, b in zip(records, records[1:]):
        if a.demand != b.demand:
            out["faults" if (a.reasons | b.reasons) & FAULT_BITS else "encounter"] += 1
    return out


def track_summary(records: list, period_ms: int) -> dict:
    """The remembered obstacle over the run (runner.TrackTally): longest and total time held
    while no channel showed it, tracks forgotten on evidence and passed, memory cycles."""
    tally = TrackTally(period_ms)
    for rec in records:
        tally.add(rec)
    return tally.as_dict()


def summarise(runner: MonitorRunner, player: Optional[Player], log: Optional[Path], plot: Optional[Path],
              recorder_complete: bool = True) -> dict:
    levels = Counter(DEMAND_NAMES[r.demand] for r in runner.records)
    by_cause = changes_by_cause(runner.records)
    changes = sum(by_cause.values())
    summary = {
        "outcome": "monitor_only",
        "margin_m": None,
        "cycles": len(runner.records),
        "demands": {name: levels.get(name, 0) for name in DEMAND_NAMES},
        "demand_changes": changes,
        "demand_changes_by_cause": by_cause,
        "init_cycles": sum(1 for r in runner.records if r.mode == 0),     # start-up: emergency until sensors are fresh
        "first_emergency_after_init_s": next((r.tick / 1000 for r in runner.records if r.demand == 2 and r.mode != 0),
                                             None),
        "faults_detected": detected_faults(runner),
        "track": track_summary(runner.records, runner.period),
        "risk": risk_summary(runner.records, runner.period),
        "frames_received": runner.frames_received,
        "frames_rejected": runner.receiver.rejected_total,
        "rejects": {k: v for k, v in sorted(runner.receiver.rejected.items()) if v},
        "frames_filtered": runner.monitor.tally.filtered,
        "frame_kinds": {k: v for k, v in sorted(runner.monitor.tally.kinds.items())},
        "bus_state": runner.monitor.tally.bus_state,
        "bus_events": dict(sorted(runner.monitor.tally.bus_events.items())),
        "foreign_output_cycles": sum(1 for r in runner.records if r.foreign_output),
        "deadline_misses": runner.deadline_misses,
        "max_send_gap_ms": None if runner.clock.simulated else runner.max_send_gap_ms,   # wall time only
        "send_failures": runner.send_failures,
        "demands_withheld": runner.demands_withheld,   # late cycles' BrakeDemand below emergency
        "bus_security": describe_security(runner.security),
        "attack": attack_note(runner, player),
        "table": runner.setup.model,
        "table_sha256": runner.setup.table.sha256,
        "log": None if log is None else str(log),
        "log_complete": recorder_complete,
        "plot": None if plot is None else str(plot),
    }
    if player is not None:
        summary.update(player.outcome())
        summary["scenario"] = player.scenario.name
        summary["faults_injected"] = sorted(f"{k}@ch{c}" for k, c in player.faults_injected)
    return summary


def attack_note(runner: MonitorRunner, player: Optional[Player]) -> Optional[str]:
    """An attack the bus saw, named (issue 39): the frames refused as another node's (forged,
    replayed, unsecured on a secured bus, on the monitor's own IDs) and the brake receiver's
    second-sender periods; None if there was none."""
    parts = [f"{k} {v:,}" for k, v in sorted(runner.receiver.rejected.items()) if v and k in ATTACK_REFUSALS]
    if player is not None:                # the brake side's own receiver (BrakeDemand forged or replayed)
        parts += [f"brake side {k} {v:,}" for k, v in sorted(player.receiver.rejected.items())
                  if v and k in ATTACK_REFUSALS]
        held = player.brakes.causes.get("second_sender", 0)
        if held:
            parts.append(f"brake receiver: second sender {held:,} periods")
    return "frames refused as an attack: " + ", ".join(parts) if parts else None


def make_plot(path: Path, runner: MonitorRunner, player: Optional[Player], title: str) -> Path:
    from monitor.plot import plot_run

    recs = runner.records
    t = [r.tick / 1000 for r in recs]
    voted = [None if r.distance_dm == NO_DISTANCE else r.distance_dm / 10 for r in recs]
    if player is not None and len(player.trace) >= len(recs):
        rows = player.trace[: len(recs)]
        speed = [row.speed_mps for row in rows]
        true_d = [row.distance_m for row in rows]
    else:
        speed = [0.0 if r.speed_cms is None else r.speed_cms / 100 for r in recs]
        true_d = None
    if runner.security is None:
        title += " - UNSECURED bus (E2E only)"
    attack = attack_note(runner, player)
    if attack:
        title += "\n" + attack
    return plot_run(path, title, t, speed, true_d, voted, [r.demand for r in recs], [r.mode for r in recs],
                    speed_distance=speed_distance(runner, player), **track_columns(recs), **risk_columns(recs))


def speed_distance(runner: MonitorRunner, player: Optional[Player]):
    """The run's speed-distance picture: the monitor's curves for the scenario's obstacle
    (the nearest at the end of the run) and the train's trajectory once it entered the
    section; without an obstacle, the trajectory against the monitor's record alone."""
    from monitor.plot import SpeedDistance

    recs = runner.records
    cfg = runner.setup.config
    if player is None:
        speed = [0.0 if r.speed_cms is None else r.speed_cms / 100 for r in recs]
        return SpeedDistance(cfg, None, travelled([r.tick / 1000 for r in recs], speed), speed,
                             [r.demand for r in recs], [r.warning for r in recs])
    pairs = [(row, rec) for row, rec in zip(player.trace, recs) if row.speed_mps > 0 or row.t_s > 0]
    near = player.obstacle_distance()
    spec = near[1] if near is not None else None
    tr = player.scenario.train
    with_obstacle = spec is not None and any(row.distance_m is not None for row, _ in pairs)
    if with_obstacle:
        pairs = [(row, rec) for row, rec in pairs if row.distance_m is not None]
    speed = [row.speed_mps for row, _ in pairs]
    return SpeedDistance(
        cfg, [row.distance_m for row, _ in pairs] if with_obstacle else None,
        travelled([row.t_s for row, _ in pairs], speed), speed,
        [rec.demand for _, rec in pairs], [rec.warning for _, rec in pairs],
        obstacle_speed_mps=spec.speed_mps if with_obstacle else 0.0, track=int(tr.track == "slippery"),
        brake=int(tr.brake == "degraded"), visible_m=player.scenario.sensors.range_m if with_obstacle else None)


def travelled(t_s: list, speed_mps: list) -> list:
    """Distance run since the first sample (trapezoidal rule over the samples)."""
    out, x = [], 0.0
    for i, v in enumerate(speed_mps):
        if i:
            x += 0.5 * (v + speed_mps[i - 1]) * (t_s[i] - t_s[i - 1])
        out.append(x)
    return out


def status_line(rec, player: Optional[Player], bus_state: str = "error_active", period_ms: int = 100) -> str:
    speed = f"{(player.speed if player.started else 0.0):5.1f} m/s" if player is not None else (
        "   -     " if rec.speed_cms is None else f"{rec.speed_cms / 100:5.1f} m/s")
    dist = "   none " if rec.distance_dm == NO_DISTANCE else f"{rec.distance_dm / 10:7.1f}"
    return (f"t {rec.tick / 1000:7.1f} s  speed {speed}  voted distance {dist} m  "
            f"demand {DEMAND_NAMES[rec.demand]:<9}  mode {MODE_NAMES[rec.mode]:<9}  node {rec.node}"
            + track_note(rec, period_ms)
            + ("  FOREIGN SENDER on the monitor's output IDs" if rec.foreign_output else "")
            + ("" if bus_state == "error_active" else f"  bus {bus_state.replace('_', '-')}"))


def track_note(rec, period_ms: int) -> str:
    """The remembered obstacle on the status line, while no channel shows it."""
    if not held_unseen(rec) or rec.track_dm == NO_DISTANCE:
        return ""
    return (f"  remembered {rec.track_dm / 10:.1f} m ({TRACK_NAMES[rec.track_state]}, "
            f"unseen {rec.track_cycles * period_ms / 1000:.1f} s)")


class StopOnSignal:
    """SIGINT/SIGTERM set a flag instead of killing the run, so that the run can end with a
    last emergency demand and its summary (restored on exit; a no-op outside the main thread)."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.previous = {}

    def __enter__(self) -> threading.Event:
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self.previous[sig] = signal.signal(sig, lambda *_: self.event.set())
            except ValueError:
                pass
        return self.event

    def __exit__(self, *exc) -> None:
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)


def reporter(recorder: Recorder, show: Optional[Callable[[str], None]], player: Optional[Player],
             bus_state: Callable[[], str] = lambda: "error_active", period_ms: int = 100) -> Callable:
    """What follows every monitor cycle: the recorder takes the bus's frames (within its
    budget on a real bus) and every tenth cycle shows a status line."""
    count = [0]

    def after_cycle(rec) -> None:
        recorder.drain(RECORDER_BUDGET_S)
        if show is not None and count[0] % 10 == 0:
            show(status_line(rec, player, bus_state(), period_ms))
        count[0] += 1

    return after_cycle


def run_virtual(setup: core.Setup, scenario: Scenario, out_dir: Path, *, show: Optional[Callable[[str], None]] = None,
                plot: bool = True, duration_s: Optional[float] = None, player: Callable[..., Player] = Player,
                keys: Optional[Path] = None) -> RunResult:
    """Monitor + player + recorder on the in-process virtual bus, simulated clock; with
    `duration_s`, the run ends after that much monitor time even if the scenario has not.
    `player(bus, scenario, period_ms)` makes the world's side (default: the scenario player;
    verification plays recorded worlds through a subclass). `keys`: the key set of a secured
    bus (every node signs and verifies, security.py); None: unsecured, E2E only."""
    out_dir.mkdir(parents=True, exist_ok=True)     # before any bus is opened: a bad --out is one error, no bus left open
    with StopOnSignal() as stop:
        return _run_virtual(setup, scenario, out_dir, show, plot, stop, duration_s, player, keys)


def node_security(keys: Optional[Path]) -> tuple:
    """(monitor's, player's) Security on the key set `keys`, or (None, None) unsecured. The
    monitor holds every key it verifies and its own; the player, the sensors' and the train's
    it signs with and the monitor's that its brake receiver verifies."""
    if keys is None:
        return None, None
    from .keys import SENDERS
    from .security import for_node

    return for_node(keys, "monitor", SENDERS), for_node(keys, "player", SENDERS)


def _run_virtual(setup, scenario, out_dir, show, plot, stop: threading.Event, duration_s=None,
                 make_player: Callable[..., Player] = Player, keys: Optional[Path] = None) -> RunResult:
    mon_security, player_security = node_security(keys)
    clock = SimClock()
    period = setup.config.period_ms
    buses = [can.Bus(interface="virtual", channel=VIRTUAL_CHANNEL, receive_own_messages=False) for _ in range(3)]
    mon_bus, player_bus, rec_bus = buses
    log_path = out_dir / f"run-{scenario.name}.log"
    recorder = Recorder(rec_bus, log_path, clock)
    try:
        player = make_player(player_bus, scenario, period)
        player.secure(player_security)
        if player.wants_hostile:
            buses.append(can.Bus(interface="virtual", channel=VIRTUAL_CHANNEL, receive_own_messages=False))
            player.join_hostile(buses[-1])
        runner = MonitorRunner(mon_bus, setup, clock, on_cycle=reporter(recorder, show, player, period_ms=period),
                               security=mon_security)
        limit = int(scenario.duration_s * 1000 / period) + 600   # room for the wait at the entry
        if duration_s is not None:
            limit = min(limit, max(1, round(duration_s * 1000 / period)))

        def player_moves(tick: int) -> None:      # simulated time: the player acts at the tick, then the monitor
            clock.sleep_until_ms(tick)
            player.step(tick)

        runner.run(limit, stop=lambda: stop.is_set() or player.finished, before_cycle=player_moves)
        runner.send_final_emergency()
        recorder.close()
    finally:
        for b in buses:
            b.shutdown()
        for sec in (mon_security, player_security):
            if sec is not None:
                sec.save()
    plot_path = make_plot(out_dir / f"run-{scenario.name}.png", runner, player, f"railguard run: {scenario.name}") if plot else None
    return RunResult(summarise(runner, player, log_path, plot_path, recorder.complete), runner, player)


def run_on_bus(setup: core.Setup, bus_kwargs: dict, out_dir: Path, *, scenario: Optional[Scenario],
               duration_s: Optional[float], show: Optional[Callable[[str], None]] = None, plot: bool = True,
               name: str = "bus", keys: Optional[Path] = None) -> RunResult:
    """The monitor in real time on a real bus; with a scenario, the player runs in a thread
    on its own bus connection. SIGINT/SIGTERM end the run: one last emergency demand, the
    summary, exit 0."""
    out_dir.mkdir(parents=True, exist_ok=True)     # before any bus is opened
    with StopOnSignal() as stop:
        return _run_on_bus(setup, bus_kwargs, out_dir, scenario, duration_s, show, plot, name, stop, keys)


def _run_on_bus(setup, bus_kwargs, out_dir, scenario, duration_s, show, plot, name, stop: threading.Event,
                keys: Optional[Path] = None) -> RunResult:
    mon_security, player_security = node_security(keys)
    clock = WallClock()
    log_path = out_dir / f"run-{name}.log"
    opened: list = []
    player = None
    player_thread = None
    try:
        mon_bus = open_bus(bus_kwargs, monitor=True)
        opened.append(mon_bus)
        rec_bus = open_bus(bus_kwargs)
        opened.append(rec_bus)
        recorder = Recorder(rec_bus, log_path, clock)
        period = setup.config.period_ms
        if scenario is not None:
            player_bus = open_bus(bus_kwargs)
            opened.append(player_bus)
            player = Player(player_bus, scenario, period)
            player.secure(player_security)
            if player.wants_hostile:
                opened.append(open_bus(bus_kwargs))
                player.join_hostile(opened[-1])
            player_thread = threading.Thread(target=play_loop, args=(player, clock, stop), daemon=True)
            player_thread.start()

        runner = MonitorRunner(mon_bus, setup, clock,
                               on_cycle=reporter(recorder, show, player, lambda: runner.monitor.tally.bus_state,
                                                 period), security=mon_security)
        cycles = None if duration_s is None else int(duration_s * 1000 / period)
        runner.run(cycles, stop=lambda: stop.is_set() or (player is not None and player.finished))
        stop.set()
        runner.send_final_emergency()
        if player_thread is not None:
            player_thread.join(timeout=2)
        recorder.close()
    finally:
        for b in opened:
            b.shutdown()
        for sec in (mon_security, player_security):
            if sec is not None:
                sec.save()
    plot_path = make_plot(out_dir / f"run-{name}.png", runner, player, f"railguard run on {name}") if plot else None
    return RunResult(summarise(runner, player, log_path, plot_path, recorder.complete), runner, player)


def play_loop(player: Player, clock, stop: threading.Event, wait_limit_ms: int | None = None) -> None:
    """Run the player in real time until its scenario ends or `stop` is set. A player waiting
    for a monitor that never reports NORMAL gives up after `wait_limit_ms` (None: never)."""
    tick = first = clock.now_ms()
    while not stop.is_set() and not player.finished:
        if wait_limit_ms is not None and not player.started and tick - first > wait_limit_ms:
            raise MonitorNotReady(f"the monitor did not report NORMAL with no brake demand within {wait_limit_ms / 1000:g} s "
                                  "(is it running on the same bus? MonitorStatus seen: "
                                  f"{'yes' if player.receiver.status is not None else 'no'}); "
                                  "--wait-limit waits longer, --no-wait starts at once")
        clock.sleep_until_ms(tick)
        late = clock.now_ms() - tick >= player.period_ms    # the next period has begun: catch up silently
        player.step(tick, send=not late)
        tick += player.period_ms


def eprint(text: str) -> None:
    print(text, file=sys.stderr)
