"""The CAN shell end to end: scenario runs on the in-process virtual bus, determinism, the
candump recording and its replay, the `run`/`play`/`replay` commands, deadline overruns and
the last emergency demand on shutdown."""
from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import can
import pytest

from can_bus import logfile
from can_bus import replay as rp
from can_bus import scenario as scenarios
from can_bus import session
from can_bus.clock import SimClock
from can_bus.codec import (
    BRAKE_DEMAND_ID, MONITOR_RISK_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, OBSTACLE_IDS, REJECT_REASONS, TRAIN_STATE_ID, Receiver,
    Sender, report_signals,
)
from can_bus.runner import MonitorRunner
from railguard.main import main
from monitor.core import cycle as core
from monitor.core.config import Config
from monitor.core.types import (
    ABSENT, EMERGENCY, INIT, MAINTAIN, PRESENT, R_DEADLINE, R_PERCEPTOR, R_SAFE_STOP, R_STALE, R_SYSTEM_ERROR,
    SAFE_STOP, TRACK_NONE, Report,
)

ROOT = Path(__file__).resolve().parents[1]
TABLE_FILES = {"m1": ROOT / "monitor" / "tables" / "m1.table.rgt", "m2": ROOT / "monitor" / "tables" / "m2.table.rgt"}
SCENARIOS = ("static-obstacle", "no-obstacle", "fault-cascade", "moving-obstacle")
OUTCOMES = {"stopped", "collision", "no_obstacle", "avoided", "incomplete"}
_unique = itertools.count()


def setup_for(table: str) -> core.Setup:
    return core.create(Config(), TABLE_FILES[table].read_bytes())


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Every shipped scenario with both shipped tables, run once (no plot) and cached."""
    cache: dict = {}

    def get(table: str, name: str):
        key = (table, name)
        if key not in cache:
            out = tmp_path_factory.mktemp(f"run-{table}-{name}")
            cache[key] = session.run_virtual(setup_for(table), scenarios.load(name), out, plot=False)
        return cache[key]

    return get


def emergency_after_init(result) -> int:
    return sum(1 for r in result.runner.records if r.mode != INIT and r.demand == EMERGENCY)


# ----------------------------------------------------------------------------- scenario runs

@pytest.mark.parametrize("table", ["m1", "m2"])
@pytest.mark.parametrize("name", SCENARIOS)
def test_run_invariants(runs, table, name):
    res = runs(table, name)
    s, runner = res.summary, res.runner
    scen = scenarios.load(name)
    assert s["scenario"] == name and s["table"] == table
    assert s["outcome"] in OUTCOMES and s["outcome"] != "collision"
    assert not res.player.collision
    assert s["deadline_misses"] == 0 == runner.deadline_misses
    assert s["cycles"] == len(runner.records) > 0
    assert sum(s["demands"].values()) == s["cycles"]
    # every frame is either accepted or rejected, and the summary counts the rejections
    assert runner.frames_received == runner.receiver.accepted + runner.receiver.rejected_total
    assert s["frames_received"] == runner.frames_received > 0
    frame_counts = {k: v for k, v in s["faults_detected"].items() if k.startswith("frames_")}
    assert s["frames_rejected"] == sum(frame_counts.values()) == runner.receiver.rejected_total
    assert {k[len("frames_"):] for k in frame_counts} <= set(REJECT_REASONS)
    assert all(v > 0 for v in s["faults_detected"].values())
    # the player injected every fault of the scenario that falls inside the played time
    played = res.player.t
    assert set(s["faults_injected"]) == {f"{f.kind}@ch{f.channel}" for f in scen.faults if f.start_s < played}
    # ticks advance by one period per cycle from 0
    assert [r.tick for r in runner.records] == [100 * i for i in range(len(runner.records))]
    log = Path(s["log"])
    assert log.is_file() and log.stat().st_size > 0
    assert s["plot"] is None


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_static_obstacle_stops_before_it(runs, table):
    res = runs(table, "static-obstacle")
    s = res.summary
    assert s["outcome"] == "stopped"
    assert s["margin_m"] is not None and s["margin_m"] > 0
    assert s["final_speed_mps"] == 0.0
    # the train really ran and then stood in front of the obstacle
    assert max(row.speed_mps for row in res.player.trace) == pytest.approx(30.0)
    assert s["scenario_s"] == pytest.approx(60.0)
    # the silent channel (50-54 s) is seen as stale and the brake is demanded
    assert s["faults_injected"] == ["silence@ch3"]
    assert s["faults_detected"].get("cycles_stale", 0) > 0
    silent = [(rec, row) for rec, row in zip(res.runner.records, res.player.trace) if 50.5 <= row.t_s <= 54.0]
    assert silent and all(rec.reasons & R_STALE and rec.demand == EMERGENCY for rec, _ in silent)


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_no_obstacle_never_brakes(runs, table):
    res = runs(table, "no-obstacle")
    s = res.summary
    assert s["outcome"] == "no_obstacle" and s["margin_m"] is None
    assert emergency_after_init(res) == 0
    # "any braking here is false braking" (no-obstacle.toml)
    assert all(r.demand == MAINTAIN for r in res.runner.records if r.mode != INIT)
    assert s["faults_detected"] == {} and s["frames_rejected"] == 0
    assert s["final_speed_mps"] == pytest.approx(30.0)
    assert s["scenario_s"] == pytest.approx(scenarios.load("no-obstacle").duration_s)    # 25 s: the campaign's too


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_fault_cascade_detects_the_faults(runs, table):
    res = runs(table, "fault-cascade")
    s = res.summary
    fd = s["faults_detected"]
    assert fd.get("frames_bad_crc", 0) > 0                 # bad_crc on channel 0
    # counter_freeze on channel 1: the same counter with other content (its noisy distance) is
    # what a second sender looks like (issue 39): the channel is refused, not merely deduplicated
    assert fd.get("frames_second_sender", 0) > 0
    assert fd.get("cycles_system_error", 0) > 0
    assert fd.get("cycles_perceptor", 0) > 0               # contradiction on channel 4
    assert s["deadline_misses"] == 0
    assert s["frames_rejected"] == sum(v for k, v in fd.items() if k.startswith("frames_")) > 0
    assert s["outcome"] in ("stopped", "avoided")
    assert s["first_emergency_after_init_s"] is not None
    # a perceptor error is a safe stop with an emergency demand
    perceptor = [r for r in res.runner.records if r.reasons & R_PERCEPTOR]
    assert perceptor and all(r.mode == SAFE_STOP and r.demand == EMERGENCY for r in perceptor)


def _rejections_by_channel(log: Path) -> list[tuple[int, int, str]]:
    """(tick, channel, reason) of every rejected obstacle frame in a recorded log."""
    rx = Receiver(rate_window_ms=100)     # as the runner configures it for the 100 ms cycle
    frames = [(f.timestamp, f.msg.arbitration_id, bytes(f.msg.data), f.msg.is_extended_id) for f in logfile.read(log)]
    t0 = frames[0][0]
    out = []
    for ts, fid, data, extended in frames:
        before = dict(rx.rejected)
        if rx.accept(fid, data, round((ts - t0) * 1000), extended) is None and fid in OBSTACLE_IDS:
            reason = next(k for k, v in rx.rejected.items() if v != before.get(k, 0))
            out.append((round((ts - t0) * 1000), fid - OBSTACLE_IDS[0], reason))
    return out


DIAGNOSTIC = R_STALE | R_SYSTEM_ERROR | R_PERCEPTOR | R_SAFE_STOP


@pytest.mark.parametrize("index", range(len(scenarios.load("fault-cascade").faults)),
                         ids=[f"{f.kind}@ch{f.channel}" for f in scenarios.load("fault-cascade").faults])
def test_fault_cascade_every_injected_fault_is_detected(runs, index):
    """fault-cascade.toml: 'Every injected fault kind of the player ... each must be detected'.
    Detected: a rejected frame of the faulty channel, or a diagnostic reason bit (stale,
    system error, perceptor, safe stop), while the fault is active or within 1 s after it."""
    res = runs("m2", "fault-cascade")
    fault = res.player.scenario.faults[index]
    assert f"{fault.kind}@ch{fault.channel}" in res.summary["faults_injected"]
    window = [(rec.tick, rec) for rec, row in zip(res.runner.records, res.player.trace)
              if fault.start_s <= row.t_s <= fault.end_s + 1.0]
    assert window
    ticks = {t for t, _ in window}
    rejected = [r for t, ch, r in _rejections_by_channel(Path(res.summary["log"])) if ch == fault.channel and t in ticks]
    flagged = [rec for _, rec in window if rec.reasons & DIAGNOSTIC]
    assert rejected or flagged, f"{fault.kind} on channel {fault.channel} ({fault.start_s}-{fault.end_s} s) went unnoticed"


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_moving_obstacle_is_played_and_not_hit(runs, table):
    res = runs(table, "moving-obstacle")
    s = res.summary
    assert s["outcome"] in ("stopped", "avoided")
    assert not res.player.collision
    # the train enters the section and the scenario is played to its end
    assert res.player.started, (
        f"the train never entered the section: demands {s['demands']} over {s['cycles']} cycles, "
        f"scenario time {s['scenario_s']} s, reported final speed {s['final_speed_mps']} m/s")
    assert max(row.speed_mps for row in res.player.trace) > 0
    assert s["scenario_s"] == pytest.approx(90.0)


def test_the_vehicle_leaving_the_crossing_and_its_blind_contrast_are_played(runs):
    """The catalogue's pair (docs/scenarios.md): in vehicle-leaves-crossing the vehicle is on the
    track until its leave_s and gone after it, nothing to hit; in vehicle-blinded-crossing it
    stays, every channel is blind for a while, and the train stops before it. Whether the
    monitor releases in the first is the core's to test."""
    res = runs("m2", "vehicle-leaves-crossing")
    leave = res.player.scenario.obstacles[0].leave_s
    assert all(row.distance_m is not None for row in res.player.trace if row.t_s < leave)
    assert all(row.distance_m is None for row in res.player.trace if row.t_s >= leave)
    assert not res.player.collision and res.summary["margin_m"] is None
    assert res.summary["outcome"] in ("avoided", "stopped") and res.summary["scenario_s"] == pytest.approx(40.0)
    blind = runs("m2", "vehicle-blinded-crossing")
    assert set(blind.summary["faults_injected"]) == {f"blind@ch{ch}" for ch in range(6)}
    assert blind.summary["outcome"] == "stopped" and blind.summary["margin_m"] > 0


# ----------------------------------------------------------------------------- determinism and replay

def _without_paths(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in ("log", "plot")}


@pytest.mark.parametrize("name", ["static-obstacle", "fault-cascade"])
def test_runs_are_deterministic(runs, tmp_path, name):
    first = runs("m2", name)
    again = session.run_virtual(setup_for("m2"), scenarios.load(name), tmp_path, plot=False)
    assert _without_paths(again.summary) == _without_paths(first.summary)
    assert again.summary["log"] != first.summary["log"]
    a, b = Path(first.summary["log"]).read_bytes(), Path(again.summary["log"]).read_bytes()
    assert a == b
    assert [r.__dict__ for r in again.runner.records] == [r.__dict__ for r in first.runner.records]


@pytest.mark.parametrize("table,name", [("m2", "static-obstacle"), ("m1", "fault-cascade")])
def test_recorded_log_replays(runs, table, name):
    res = runs(table, name)
    setup = setup_for(table)
    log = Path(res.summary["log"])
    frames = list(logfile.read(log))
    # the recorder wrote every frame of the bus: the player's and the monitor's
    lines = [ln for ln in log.read_text().splitlines() if ln.strip()]
    assert len(frames) == len(lines) == res.player.frames_sent + res.runner.frames_sent
    first, stats1 = rp.replay_file(setup, log)
    second, stats2 = rp.replay_file(setup, log)
    assert first == second and stats1 == stats2
    assert stats1["frames"] == len(frames)
    assert stats1["recorded_demands"] == len(res.runner.records) + 1     # + the final emergency
    assert stats1["agreement_with_recorded"] >= 0.95
    # the replay rejects exactly what the live monitor rejected
    assert stats1["rejected"] == dict(res.runner.receiver.rejected)
    # and decides exactly as the live monitor did
    live = [(r.tick, r.demand, r.reasons, r.mode, r.node, r.distance_dm) for r in res.runner.records]
    replayed = [(d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm) for d in first]
    assert replayed[: len(live)] == live


def test_replay_command_prints_the_decisions(runs, capsys, tmp_path):
    res = runs("m2", "static-obstacle")
    log = res.summary["log"]
    code = main(["replay", log, "--json", "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = [ln for ln in out.splitlines() if ln.strip()]
    assert len(lines) == 1
    obj = json.loads(lines[0])
    decisions, stats = rp.replay_file(setup_for("m2"), log)
    assert obj["decisions"] == [[d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm, d.track_dm, d.track_state,
                                 d.track_cycles] for d in decisions]
    assert obj["track"] == stats["track"]
    assert obj["cycles"] == len(decisions)
    assert obj["agreement_with_recorded"] == stats["agreement_with_recorded"]
    assert Path(obj["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_replay_text_output(runs, capsys, tmp_path):
    log = runs("m2", "static-obstacle").summary["log"]
    code = main(["replay", log, "--no-plot", "--out", str(tmp_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "agreement with the recorded BrakeDemand frames" in out
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- CLI

RUN_KEYS = {"outcome", "margin_m", "demands", "faults_detected", "track", "frames_received", "frames_rejected",
            "deadline_misses", "log", "plot"}


def test_run_command_json(capsys, tmp_path):
    code = main(["run", "--json", "--out", str(tmp_path), "--quiet"])
    out, err = capsys.readouterr()
    assert code == 0, err
    lines = [ln for ln in out.splitlines() if ln.strip()]
    assert len(lines) == 1, out
    obj = json.loads(lines[0])
    assert RUN_KEYS <= set(obj)
    assert obj["outcome"] in OUTCOMES
    assert obj["outcome"] == "stopped" and obj["margin_m"] > 0           # default: static-obstacle
    assert obj["scenario"] == "static-obstacle" and obj["table"] == "m2"
    assert obj["deadline_misses"] == 0
    assert set(obj["demands"]) == {"none", "service", "emergency"}
    log, plot = Path(obj["log"]), Path(obj["plot"])
    assert log.parent == tmp_path and plot.parent == tmp_path
    assert log.is_file() and log.stat().st_size > 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Traceback" not in err


def _clean_env() -> dict:
    """No python-can configuration from the environment: no bus is named."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _assert_one_line_error(code, err):
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("railguard: error: ") and len(lines[0]) > len("railguard: error: ")


def _bad_scenario(tmp_path: Path) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text('duration_s = 10.0\n[train]\nspeed_mps = 10.0\nwheels = 8\n')
    return p


def _not_a_log(tmp_path: Path) -> str:
    return "/etc/hostname" if Path("/etc/hostname").is_file() else str(_write(tmp_path / "hostname", "myhost\n"))


def _write(p: Path, text: str) -> Path:
    p.write_text(text)
    return p


ERROR_CASES = {
    "unknown-scenario": lambda tmp: ["run", "--scenario", "nope", "--out", str(tmp)],
    "missing-table": lambda tmp: ["run", "--table", "/nonexistent", "--out", str(tmp)],
    "replay-not-a-log": lambda tmp: ["replay", _not_a_log(tmp), "--out", str(tmp)],
    "replay-garbage-log": lambda tmp: ["replay", str(_write(tmp / "junk.log", "hello world\n(x) y z\n")),
                                       "--out", str(tmp)],
    "play-without-bus": lambda tmp: ["play", "static-obstacle"],
    # nobody on the bus: the player gives up waiting for the monitor instead of waiting forever
    "play-without-monitor": lambda tmp: ["play", "static-obstacle", "--interface", "virtual", "--channel",
                                         "rg-nobody", "--wait-limit", "0.5", "--unsecured"],
    # a real bus is never secured by test keys unasked (issue 39)
    "play-without-keys": lambda tmp: ["play", "static-obstacle", "--interface", "virtual", "--channel", "rg-nobody"],
    "run-with-a-missing-key-set": lambda tmp: ["run", "--keys", str(tmp / "no-such-keys"), "--out", str(tmp)],
    "scenario-unknown-key": lambda tmp: ["run", "--scenario", str(_bad_scenario(tmp)), "--out", str(tmp)],
}


@pytest.mark.parametrize("case", ["unknown-scenario", "missing-table", "replay-garbage-log", "scenario-unknown-key"])
def test_user_errors_in_process(capsys, tmp_path, monkeypatch, case):
    for k in [k for k in os.environ if k.startswith("CAN_")]:
        monkeypatch.delenv(k)
    code = main(ERROR_CASES[case](tmp_path))
    out, err = capsys.readouterr()
    _assert_one_line_error(code, err)
    assert out == ""
    if case == "scenario-unknown-key":
        assert "wheels" in err
    if case == "unknown-scenario":
        assert "nope" in err
    assert not list(tmp_path.glob("run-*")), "nothing is written on a refused run"


@pytest.mark.parametrize("case", ["play-without-bus", "play-without-monitor", "replay-not-a-log", "scenario-unknown-key"])
def test_user_errors_in_a_subprocess(tmp_path, case):
    proc = subprocess.run([sys.executable, "-m", "railguard", *ERROR_CASES[case](tmp_path)],
                          capture_output=True, text=True, timeout=60, env=_clean_env(), cwd=str(tmp_path))
    _assert_one_line_error(proc.returncode, proc.stderr)
    assert proc.stdout == ""
    if case == "play-without-monitor":
        assert "did not report NORMAL" in proc.stderr and "0.5 s" in proc.stderr and "seen: no" in proc.stderr


class StallingClock:
    """Wall-clock stand-in for play_loop: on time, except that one sleep wakes up 350 ms late
    (the host stalled the player's process)."""

    simulated = True

    def __init__(self, stall_at_ms: int) -> None:
        self.t = 0
        self.stall_at_ms = stall_at_ms

    def now_ms(self) -> int:
        return self.t

    def sleep_until_ms(self, tick: int) -> None:
        self.t = max(self.t, tick)
        if self.stall_at_ms is not None and tick >= self.stall_at_ms:
            self.t += 350
            self.stall_at_ms = None


def test_a_late_player_moves_the_train_but_sends_no_burst():
    """A stalled player catches up on the world, not on the bus: at most one frame per ID per
    period even right after the stall (a burst is babbling to the monitor), and the train
    covers the same ground as without the stall."""
    import threading

    import can

    from can_bus.codec import TRAIN_STATE_ID
    from can_bus.player import Player
    from can_bus.scenario import load
    from can_bus.session import play_loop

    def play(clock):
        with can.Bus(interface="virtual", channel="rg-late") as tx:
            player = Player(tx, load("no-obstacle"), wait_for_monitor=False)
            sent_at = []
            original = player.send

            def send(frame_id, data):
                sent_at.append((clock.now_ms(), frame_id))
                original(frame_id, data)

            player.send = send
            play_loop(player, clock, threading.Event())
            return player, sent_at

    steady, _ = play(StallingClock(None))
    late, late_frames = play(StallingClock(1000))
    assert steady.late_periods == 0 and late.late_periods == 3
    assert len(late_frames) == len(set(late_frames)), "a frame ID sent twice at one instant: a burst"
    state = [t for t, fid in late_frames if fid == TRAIN_STATE_ID]
    assert len(state) == len(steady.trace) - 3 == len(set(state)), "one TrainState per period, none in a burst"
    assert late.position == pytest.approx(steady.position) and late.position > 0


def test_the_player_s_obstacle_leaves_the_track_and_blind_hides_it():
    """leave_s (issue 29 item 4): every channel reports the vehicle until it leaves, ABSENT
    after it (as for no obstacle), and the train runs through where it stood without a
    collision. A blind fault makes every channel miss it while it is there."""
    from can_bus.player import Player
    from can_bus.scenario import FaultSpec, ObstacleSpec, Scenario, SensorSpec, TrainSpec

    def play(obstacle, faults=()):
        scen = Scenario("t", duration_s=12.0, train=TrainSpec(speed_mps=10.0), obstacles=(obstacle,),
                        sensors=SensorSpec(noise_sigma_m=0.0), faults=faults)
        with can.Bus(interface="virtual", channel=f"rg-leave-{next(_unique)}") as bus:
            player = Player(bus, scen, wait_for_monitor=False)
            seen = []
            while not player.finished:
                player.move(0)                                   # no demand: the train runs at 10 m/s
                seen.append((round(player.t, 1), {player.true_report(ch, 0).status for ch in range(6)}))
            return player, seen

    player, seen = play(ObstacleSpec(position_m=60.0, leave_s=3.0, type="dynamic"))
    assert {st for t, (st,) in seen if t < 3.0} == {PRESENT}
    assert {st for t, (st,) in seen if t >= 3.0} == {ABSENT} and player.obstacle_distance() is None
    assert not player.collision and player.position == pytest.approx(120.0)
    player, seen = play(ObstacleSpec(position_m=200.0), (FaultSpec("blind", start_s=2.0, end_s=4.0),))
    assert [sorted({st for t, (st,) in seen if a <= t < b}) for a, b in ((0, 2), (2, 4), (4, 12))] == \
        [[PRESENT], [ABSENT], [PRESENT]]
    assert player.faults_injected == {("blind", ch) for ch in range(6)}


# ----------------------------------------------------------------------------- deadline overruns

class JumpingClock:
    """Simulated clock that is on time for the first `steady` readings, then jumps 250 ms
    forward on every reading: every cycle from then on ends after its deadline."""

    simulated = True

    def __init__(self, steady: int = 2) -> None:
        self.steady = steady
        self.calls = 0
        self.t = 0

    def now_ms(self) -> int:
        self.calls += 1
        if self.calls > self.steady:
            self.t += 250
        return self.t

    def now_s(self) -> float:
        return self.t / 1000

    def sleep_until_ms(self, tick: int) -> None:
        pass

    def tick_of_stamp(self, stamp) -> None:
        return None


def virtual_pair():
    channel = f"t-{os.getpid()}-{next(_unique)}"
    return (can.Bus(interface="virtual", channel=channel, receive_own_messages=False),
            can.Bus(interface="virtual", channel=channel, receive_own_messages=False))


def received(bus) -> list:
    out = []
    while True:
        msg = bus.recv(timeout=0.0)
        if msg is None:
            return out
        out.append(msg)


def test_deadline_overruns_lead_to_safe_stop():
    setup = setup_for("m2")
    max_overruns = setup.config.max_overruns
    mon_bus, listener = virtual_pair()
    try:
        runner = MonitorRunner(mon_bus, setup, JumpingClock(steady=3))
        runner.run(cycles=22)
        frames = received(listener)
    finally:
        mon_bus.shutdown()
        listener.shutdown()
    recs = runner.records
    assert len(recs) == 22
    # cycle 0 ends on time; every later cycle overruns
    assert runner.deadline_misses == 21 and runner.overruns == 21
    for k, rec in enumerate(recs):
        consecutive_before = max(0, k - 1)
        if consecutive_before >= max_overruns:
            assert rec.mode == SAFE_STOP, k
            assert rec.reasons & R_DEADLINE and rec.reasons & R_SAFE_STOP, k
            assert rec.demand == EMERGENCY, k
        else:
            assert not rec.reasons & R_DEADLINE, k
            assert rec.mode != SAFE_STOP, k
    # what went on the bus: four valid E2E frames per cycle, in order, but a late cycle's
    # BrakeDemand below emergency, which is withheld (the brakes' receiver times out instead)
    late_low = [k for k, rec in enumerate(recs) if k > 0 and rec.demand != EMERGENCY]
    assert runner.demands_withheld == len(late_low)
    rx = Receiver()
    assert len(frames) == 4 * len(recs) - len(late_low)
    demands, statuses = [], []
    for msg in frames:
        assert not msg.is_extended_id and len(msg.data) == 8
        name = rx.accept(msg.arbitration_id, msg.data, 0)
        assert name in ("BrakeDemand", "MonitorStatus", "MonitorTrack", "MonitorRisk"), dict(rx.rejected)
        if name in ("BrakeDemand", "MonitorStatus"):
            (demands if name == "BrakeDemand" else statuses).append(dict(rx.demand if name == "BrakeDemand" else rx.status))
    assert [f.arbitration_id for f in frames[:4]] == [BRAKE_DEMAND_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID,
                                                      MONITOR_RISK_ID]
    sent = [k for k in range(len(recs)) if k not in late_low]
    assert len(demands) == len(sent) and len(statuses) == len(recs)
    assert all(d["Level"] == EMERGENCY for d in demands[1:])        # late: emergency or nothing
    for k, dem in zip(sent, demands):
        assert dem["Level"] == recs[k].demand and dem["Reason"] == recs[k].reasons, k
    for k, (st, rec) in enumerate(zip(statuses, recs)):
        assert st["Mode"] == rec.mode, k
        # DeadlineMisses counts the misses so far (this cycle's own overrun is known only after it)
        assert st["DeadlineMisses"] == min(15, max(0, k - 1)), k
        if k - 1 >= max_overruns:
            assert st["Mode"] == SAFE_STOP and k in sent, k
    assert statuses[-1]["DeadlineMisses"] == 15                      # saturates


def test_a_late_cycle_sends_no_brake_demand_below_emergency():
    """The timing contract's frame rule: a cycle whose frames would leave after its period
    sends BrakeDemand only at emergency (the core's decision is forced to "none" here, a unit
    test of the runner's send rule): on time, "none" is sent; late, it is withheld, and the
    brakes' receiver, hearing nothing fresh, times out."""
    setup = setup_for("m2")
    mon_bus, listener = virtual_pair()
    try:
        runner = MonitorRunner(mon_bus, setup, JumpingClock(steady=3))
        decide = runner.monitor.decide

        def none_demanded(tick, overruns=0):
            out, rec = decide(tick, overruns)
            return out._replace(demand=0), rec

        runner.monitor.decide = none_demanded
        runner.run(cycles=4)
        frames = received(listener)
    finally:
        mon_bus.shutdown()
        listener.shutdown()
    ids = [f.arbitration_id for f in frames]
    on_time = 4 - runner.deadline_misses
    assert 1 <= on_time < 4 and runner.demands_withheld == runner.deadline_misses
    assert ids.count(BRAKE_DEMAND_ID) == on_time and ids.count(MONITOR_STATUS_ID) == 4
    rx = Receiver()
    levels = [rx.demand["Level"] for f in frames if rx.accept(f.arbitration_id, f.data, 0) == "BrakeDemand"]
    assert levels == [0] * on_time


def test_no_overrun_on_time():
    setup = setup_for("m2")
    mon_bus, listener = virtual_pair()
    try:
        runner = MonitorRunner(mon_bus, setup, SimClock())
        runner.run(cycles=5)
        frames = received(listener)
    finally:
        mon_bus.shutdown()
        listener.shutdown()
    assert runner.deadline_misses == 0
    rx = Receiver()
    for msg in frames:
        rx.accept(msg.arbitration_id, msg.data, 0)
    assert rx.status["DeadlineMisses"] == 0
    assert all(not r.reasons & R_DEADLINE for r in runner.records)


# ----------------------------------------------------------------------------- shutdown and foreign frames

def _feed_healthy(bus, sender: Sender) -> None:
    absent = Report(ABSENT, 0, 0, 0, 0)
    for ch in range(6):
        fid = OBSTACLE_IDS[ch]
        bus.send(can.Message(arbitration_id=fid, data=sender.frame(fid, report_signals(absent, ch)), is_extended_id=False))
    bus.send(can.Message(arbitration_id=TRAIN_STATE_ID, data=sender.frame(TRAIN_STATE_ID, {"Speed": 0}),
                         is_extended_id=False))


def test_final_emergency_on_shutdown():
    setup = setup_for("m2")
    mon_bus, other = virtual_pair()
    try:
        clock = SimClock()
        runner = MonitorRunner(mon_bus, setup, clock)
        sender = Sender()
        for tick in range(0, 500, 100):
            clock.sleep_until_ms(tick)
            _feed_healthy(other, sender)
            runner.drain()
            runner.cycle()
        assert runner.records[-1].demand == MAINTAIN and runner.records[-1].mode != SAFE_STOP
        rx = Receiver()
        for msg in received(other):
            assert rx.accept(msg.arbitration_id, msg.data, 0)
        assert rx.demand["Level"] == MAINTAIN
        runner.send_final_emergency()
        last = received(other)
    finally:
        mon_bus.shutdown()
        other.shutdown()
    assert [m.arbitration_id for m in last] == [BRAKE_DEMAND_ID, MONITOR_STATUS_ID, MONITOR_TRACK_ID, MONITOR_RISK_ID]
    # valid E2E frames with the next counters, so a receiver takes them
    assert rx.accept(last[0].arbitration_id, last[0].data, 1) == "BrakeDemand"
    assert rx.demand["Level"] == EMERGENCY and rx.demand["Reason"] & R_SAFE_STOP
    assert rx.accept(last[1].arbitration_id, last[1].data, 1) == "MonitorStatus"
    assert rx.status["Mode"] == SAFE_STOP
    assert rx.accept(last[2].arbitration_id, last[2].data, 1) == "MonitorTrack"
    assert rx.track["TrackState"] == TRACK_NONE         # the monitor stops supervising: no track


def test_extended_id_frame_is_not_a_standard_report():
    """The DBC's messages are 11-bit frames. A 29-bit frame with arbitration ID 0x20 is a different
    CAN identifier and must not be latched as ObstacleReport_M1C1."""
    setup = setup_for("m2")
    mon_bus, other = virtual_pair()
    try:
        runner = MonitorRunner(mon_bus, setup, SimClock())
        data = Sender().frame(0x20, report_signals(Report(PRESENT, 500, 0, 0, 0), 0))
        other.send(can.Message(arbitration_id=0x20, data=data, is_extended_id=True))
        runner.drain()
    finally:
        mon_bus.shutdown()
        other.shutdown()
    assert runner.frames_received == 1
    assert runner.receiver.reports[0] is None, "an extended-ID frame was latched as channel 0's report"
    # outside the receive filter (11-bit IDs only): never seen by the codec, counted as filtered
    assert runner.receiver.accepted == 0 and runner.receiver.rejected_total == 0
    assert runner.monitor.tally.filtered == 1 and runner.monitor.tally.kinds["extended"] == 1


def test_run_plot_speed_distance_follows_the_run(runs):
    """`railguard run`'s speed-distance diagram: the train's trajectory from the section
    entry, against the distance to the scenario's obstacle, for the monitor's curves under
    the scenario's conditions; without an obstacle, against the distance run, no curves."""
    res = runs("m2", "static-obstacle")
    sd = session.speed_distance(res.runner, res.player)
    assert sd.config == res.runner.setup.config and sd.visible_m == 1000.0 and sd.obstacle_speed_mps == 0.0
    assert len(sd.distance_m) == len(sd.speed_mps) == len(sd.demand) == len(sd.warning) == len(sd.position_m)
    assert sd.speed_mps[0] == 30.0 and min(sd.speed_mps) == 0.0
    assert all(b <= a for a, b in zip(sd.distance_m, sd.distance_m[1:]))            # a static obstacle comes nearer
    assert sd.distance_m[0] == pytest.approx(1200.0 - 3.0, abs=0.01)                  # one period after the entry
    assert sd.distance_m[-1] == pytest.approx(res.summary["margin_m"], abs=0.01)
    assert max(sd.demand) >= 1 and not (sd.track or sd.brake)
    clear = runs("m2", "no-obstacle")
    sd = session.speed_distance(clear.runner, clear.player)
    assert sd.distance_m is None and sd.visible_m is None
    assert sd.position_m[-1] == pytest.approx(30.0 * (len(sd.speed_mps) - 1) * 0.1, rel=1e-9)


class QueuedFrameBus:
    """Hands out one frame that waited in a queue (its receive timestamp in the past), then
    nothing: a unit-test stand-in for a flooded socket's backlog."""

    def __init__(self, msg: can.Message) -> None:
        self.queue = [msg]

    def recv(self, timeout=None):
        return self.queue.pop() if self.queue else None

    def send(self, msg, timeout=None) -> None:
        pass


def test_a_frame_that_waited_in_the_queue_is_as_old_as_its_receive_timestamp():
    """Under a flood a report may sit in the socket's queue; it must age from when the kernel
    received it, not from when the monitor read it (older: stale sooner, the safe side)."""
    import time

    from can_bus.clock import WallClock

    setup = setup_for("m2")
    data = Sender().frame(0x20, report_signals(Report(PRESENT, 500, 0, 0, 0), 0))
    msg = can.Message(arbitration_id=0x20, data=data, is_extended_id=False, timestamp=time.time() - 0.5)
    clock = WallClock()
    runner = MonitorRunner(QueuedFrameBus(msg), setup, clock)
    runner.drain(clock.now_ms())                     # at the deadline: the queued frame is still taken
    latched = runner.receiver.reports[0]
    assert latched is not None and latched.distance_dm == 500
    assert latched.tick <= clock.now_ms() - 490, (latched.tick, clock.now_ms())
