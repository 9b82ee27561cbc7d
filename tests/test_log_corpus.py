"""The crafted-log corpus (issue 13): hostile logs, what the monitor must do with each.

tests/corpus/ holds small candump logs written by tests/corpus/make_corpus.py, one hostile
class each (the table in tests/corpus/README.md). For every file:

- the committed bytes are exactly what the generator writes (no drift);
- `railguard replay FILE --json --no-plot --table m1` in a subprocess: exit 0 with decisions
  and counters equal to the in-process replay, or exit 2 with one stderr line naming the
  file and the line, nothing on stdout, no traceback;
- the counters (rejects by reason, filtered, frame kinds, bus events, timestamp anomalies
  with their lines, segments) and the brake behaviour the README documents;
- replay = live: the same frames fed to a real `MonitorRunner` on python-can's virtual bus
  with a simulated clock give the same cycle records, rejects, filtered count and kinds.

A 1,000,000-frame log generated at test time must replay with exit 0 in constant memory
(peak RSS compared with a 100,000-frame log); it runs in the background while the other
tests run. Four hostile files are played with canplayer on real SocketCAN buses (vcan0 and,
at the same time to keep the session short, vcan1..vcan3, one file and one `railguard run`
per bus; sandbox, tests/vcan_corpus.sh); the live monitors' rejects must equal the replay's.
Under CI=true a sandbox that cannot be set up is a failure, not a skip.
"""
from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Callable, Optional

import can
import pytest
from cantools.autosar.end_to_end import check_profile2_crc

from can_bus import codec, logfile, replay, vcan
from can_bus.clock import SimClock
from can_bus.codec import MONITOR_STATUS_ID, OBSTACLE_IDS, TRAIN_STATE_ID, database, encode, report_signals
from can_bus.runner import FOREIGN_HOLD_CYCLES, MonitorRunner
from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import (DEGRADED_MODE, EMERGENCY, INIT, MAINTAIN, NORMAL, R_DISPUTE, R_ENVELOPE, R_PERCEPTOR,
                                R_STALE, R_WARNING, SAFE_STOP)

ROOT = Path(__file__).resolve().parents[1]
CORPUS_DIR = ROOT / "tests" / "corpus"
SCRIPT = ROOT / "tests" / "vcan_corpus.sh"


def _load_generator():
    spec = importlib.util.spec_from_file_location("make_corpus", CORPUS_DIR / "make_corpus.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


gen = _load_generator()
NAMES = list(gen.CORPUS)
PERIOD = 100
TIMEOUT = Config().timeout_cycles * PERIOD
DETECT = TIMEOUT + PERIOD             # a channel gone bad is stale from this long after its last valid frame


def railguard() -> str:
    exe = shutil.which("railguard")
    if exe is None:
        pytest.fail("the railguard entry point is not installed (pip install -e .)")
    return exe


# ----------------------------------------------------------------------------- expectations

@dataclass(frozen=True)
class Expect:
    rc: int = 0
    error: Optional[str] = None          # exit 2: text of the one stderr line
    line: Optional[int] = None           # exit 2: the line it names
    rejected: dict = field(default_factory=dict)
    filtered: int = 0
    kinds: dict = field(default_factory=lambda: {"classical": 350})
    bus_events: dict = field(default_factory=dict)
    anomalies: tuple = ()                # (line, kind, action)
    segments: tuple = ((1, "start"),)    # (first line, reason)
    recorded_demands: int = 0


SPLIT = "new segment"
EARLY = "taken at the previous frame's time"
EXPECT = {
    "healthy.log": Expect(),
    "bad_crc.log": Expect(rejected={"bad_crc": 10, "counter_jump": 1}),
    "repeated_counter.log": Expect(rejected={"repeated_counter": 10}),
    "counter_jump.log": Expect(rejected={"counter_jump": 10}),
    "wrong_dlc.log": Expect(rejected={"wrong_length": 10, "counter_jump": 1}),
    # 0x041 is MonitorTrack, one of the monitor's own output IDs, since issue 29: its 20 noise
    # frames are another sender's (foreign_output), the other 100 outside the filter
    "unknown_id.log": Expect(rejected={"foreign_output": 20}, filtered=100, kinds={"classical": 470}),
    "extended_id.log": Expect(filtered=24, kinds={"classical": 350, "extended": 24}),
    "fd_frame.log": Expect(rejected={"fd_frame": 24}, kinds={"classical": 350, "fd": 24}),
    "remote_frames.log": Expect(rejected={"remote_frame": 45}, filtered=4, kinds={"classical": 350, "remote": 49}),
    "error_frames.log": Expect(rejected={"error_frame": 4, "counter_jump": 7}, kinds={"classical": 273, "error": 4},
                               bus_events={"bus_off": 1, "error_active": 1, "error_passive": 2}),
    "time_backwards_small.log": Expect(anomalies=((147, "backwards", EARLY),)),
    "time_backwards_large.log": Expect(anomalies=((141, "backwards", SPLIT),), segments=((1, "start"), (141, "backwards"))),
    "stray_zero_timestamp.log": Expect(anomalies=((142, "backwards", SPLIT), (143, "gap", SPLIT)),
                                       segments=((1, "start"), (142, "backwards"), (143, "gap"))),
    "nan_timestamp.log": Expect(rc=2, error="timestamp 'nan' is not a finite number", line=101),
    "inf_timestamp.log": Expect(rc=2, error="timestamp 'inf' is not a finite number", line=101),
    "forward_gap.log": Expect(anomalies=((141, "gap", SPLIT),), segments=((1, "start"), (141, "gap"))),
    "duplicated_frames.log": Expect(rejected={"repeated_counter": 70}, kinds={"classical": 420}),
    "flapping_channel.log": Expect(),
    "extreme_values.log": Expect(rejected={"out_of_range": 50}, kinds={"classical": 420}),
    "spoofed_brake_demand.log": Expect(rejected={"foreign_output": 25}, kinds={"classical": 475}, recorded_demands=50),
    "babbling_channel.log": Expect(rejected={"rate_exceeded": 27}, kinds={"classical": 370}),
    # issue 39: per forged ID the genuine frame of period 10, both frames of 11..19, the genuine
    # ones of 20..28 (refused until 1 s after the last conflict), then one jump to resynchronise
    "forged_absent_in_step.log": Expect(rejected={"second_sender": 56, "counter_jump": 2}, kinds={"classical": 370}),
    "garbage_line.log": Expect(rc=2, error="not a candump line", line=151),
    "empty.log": Expect(rc=2, error="no CAN frames in the file"),
    "binary.log": Expect(rc=2, error="binary data", line=1),
    "obstacle_approach.log": Expect(kinds={"classical": 1372}),
    # issue 39, the secured bus (replayed with the corpus' TEST key set, make_corpus.write_keys)
    "secured_healthy.log": Expect(kinds={"fd": 350}),
    # per forged ID: its 10 forged frames fail the authenticator (each quarantines the ID), the
    # genuine frames of 10..28 are refused (until 1 s after the last), then one jump to resynchronise
    "secured_forged_absent.log": Expect(rejected={"bad_mac": 20, "second_sender": 38, "counter_jump": 2},
                                        kinds={"fd": 370}),
    "secured_stolen_key.log": Expect(rejected={"bad_mac": 10, "second_sender": 19, "counter_jump": 1},
                                     kinds={"fd": 360}),
    "secured_replay.log": Expect(rejected={"stale_freshness": 60}, kinds={"fd": 410}),
}
PARSEABLE = [n for n in NAMES if EXPECT[n].rc == 0]


def key(rec, foreign: bool = True) -> tuple:
    """Everything a cycle record says (optionally without the foreign-sender flag)."""
    out = (rec.tick, rec.demand, rec.reasons, rec.mode, rec.node, rec.distance_dm, rec.module_flags,
           rec.system_error, rec.speed_cms, rec.warning)
    return out + (rec.foreign_output,) if foreign else out


def levels(decisions) -> str:
    return "".join(str(d.demand) for d in decisions)


def without(src: Path, dest: Path, drop: Callable[[str], bool]) -> Path:
    """A copy of a log without the lines `drop` selects."""
    dest.write_text("".join(s + "\n" for s in src.read_text().splitlines() if not drop(s)))
    return dest


def ident(text: str) -> str:
    return text.split()[2].partition("#")[0]


# ----------------------------------------------------------------------------- fixtures

@pytest.fixture(scope="module")
def setup():
    return cycle.create(Config(), resources.files("monitor.tables").joinpath("m1.table.rgt").read_bytes())


KEYS = None     # the corpus' TEST key set, written once (corpus_keys) for the secured_*.log files


def corpus_keys() -> Path:
    """The key set the secured files were recorded with, written as a key set folder (owner-
    only files: git keeps no modes, so it is written at test time, never committed)."""
    global KEYS
    if KEYS is None:
        import tempfile

        KEYS = gen.write_keys(Path(tempfile.mkdtemp(prefix="railguard-corpus-")) / "keys")
    return KEYS


def secured(name: str) -> dict:
    """The replay options of a file: its key set if it was recorded on the secured bus."""
    return {"keys": corpus_keys()} if name in gen.SECURED else {}


@pytest.fixture(scope="module")
def replays(setup):
    """In-process replay of every parseable file: (decisions, stats)."""
    return {n: replay.replay_file(setup, CORPUS_DIR / n, **secured(n)) for n in PARSEABLE}


@dataclass
class Proc:
    rc: int
    stdout: str
    stderr: str
    seconds: float


def run_cli(args: list, timeout: float = 60) -> Proc:
    t = time.monotonic()
    p = subprocess.run([railguard(), *args], capture_output=True, text=True, timeout=timeout, cwd=CORPUS_DIR)
    return Proc(p.returncode, p.stdout, p.stderr, time.monotonic() - t)


@pytest.fixture(scope="module")
def cli():
    """`railguard replay FILE --json --no-plot --table m1` for every file, a few at a time."""
    with ThreadPoolExecutor(max_workers=4) as pool:
        procs = pool.map(lambda n: run_cli(["replay", str(CORPUS_DIR / n), "--json", "--no-plot", "--table", "m1",
                                            *(("--keys", str(corpus_keys())) if n in gen.SECURED else ())]), NAMES)
        return dict(zip(NAMES, procs))


# ----------------------------------------------------------------------------- the 1M-frame log
# started by the first test of the module so that it overlaps with the others (it takes
# about 40 s alone); test_million_frame_log collects it. (A run of only some tests starts
# it when test_million_frame_log needs it.)

BIG_FRAMES = 1_000_000
SMALL_FRAMES = 100_000
RSS_GROWTH_KB = 8 * 1024      # see test_million_frame_log


def write_big(path: Path, frames: int) -> None:
    """`frames` frames of the healthy traffic (the corpus generator's schedule), streamed out."""
    ids = [TRAIN_STATE_ID, *OBSTACLE_IDS]
    payload = {}
    for i, fid in enumerate(ids):
        signals = {"Speed": gen.SPEED_CMS} if fid == TRAIN_STATE_ID else report_signals(gen.CLEAR, i - 1)
        for c in range(16):
            payload[fid, c] = f"{fid:03X}#{encode(fid, signals, c).hex().upper()}"
    with path.open("w") as f:
        buf = []
        for n in range(frames):
            k, i = divmod(n, len(ids))
            us = gen.T0_US + k * 100_000 + i * 1000
            buf.append(f"({us // 1_000_000}.{us % 1_000_000:06d}) vcan0 {payload[ids[i], k & 15]}\n")
            if len(buf) == 10_000:
                f.write("".join(buf))
                buf.clear()
        f.write("".join(buf))


@dataclass
class BigRun:
    frames: int
    log: Path
    out: Path
    proc: subprocess.Popen
    err: object            # the child's stderr file
    started: float
    rc: Optional[int] = None
    maxrss_kb: int = 0
    seconds: float = 0.0
    stderr: str = ""

    def start_sampling(self, timeout: float = 300) -> None:
        self._sampler = threading.Thread(target=self._sample, args=(timeout,), name=f"rss-{self.frames}", daemon=True)
        self._sampler.start()

    def _sample(self, timeout: float) -> None:
        """Reap the child, sampling its peak RSS (VmHWM) every 20 ms while it runs.

        Not getrusage/wait4's ru_maxrss: subprocess starts the child with vfork, and Linux
        carries the parent's (pytest's) peak RSS into the child's ru_maxrss at exec. VmHWM in
        /proc/PID/status is the high-water mark of the child's own address space since exec;
        the replay's memory is flat after its imports, so sampling misses nothing."""
        deadline = time.monotonic() + timeout
        status_file = Path(f"/proc/{self.proc.pid}/status")
        while True:
            try:
                hwm = re.search(r"^VmHWM:\s+(\d+) kB", status_file.read_text(), re.M)
            except OSError:
                hwm = None
            if hwm is not None:
                self.maxrss_kb = max(self.maxrss_kb, int(hwm.group(1)))
            pid, status = os.waitpid(self.proc.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                self.proc.kill()
                pid, status = os.waitpid(self.proc.pid, 0)
                break
            time.sleep(0.02)
        self.seconds = time.monotonic() - self.started
        self.rc = os.waitstatus_to_exitcode(status)
        self.proc.returncode = self.rc

    def wait(self) -> "BigRun":
        self._sampler.join()
        self.err.seek(0)
        self.stderr = self.err.read().decode(errors="replace")
        return self


@pytest.fixture(scope="module")
def big_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("big")
    runs = {}
    for n in (SMALL_FRAMES, BIG_FRAMES):
        log = folder / f"big-{n}.log"
        write_big(log, n)
        out = folder / f"big-{n}.json"
        with out.open("w") as stdout:
            err = (folder / f"big-{n}.err").open("w+b")
            proc = subprocess.Popen([railguard(), "replay", str(log), "--json", "--no-plot", "--table", "m1"],
                                    stdout=stdout, stderr=err, cwd=folder)
        runs[n] = BigRun(n, log, out, proc, err, time.monotonic())
        runs[n].start_sampling()
    yield runs
    for r in runs.values():
        if r.rc is None:
            r.proc.kill()
        r.wait()
        r.err.close()


# ----------------------------------------------------------------------------- corpus files

def test_corpus_is_what_the_generator_writes(request):
    """(Also starts, if their tests are selected, the 1,000,000-frame replay and the sandbox
    session in the background, so that they overlap with the tests that follow.)"""
    selected = {item.originalname for item in request.session.items}
    if "test_million_frame_log" in selected:
        request.getfixturevalue("big_runs")
    if "test_canplayer_on_vcan_rejects_as_replay" in selected:
        request.getfixturevalue("vcan_started")
    committed = sorted(p.name for p in CORPUS_DIR.glob("*.log"))
    assert committed == sorted(NAMES), "tests/corpus/*.log and make_corpus.CORPUS differ: run make_corpus.py"
    for n in NAMES:
        data = (CORPUS_DIR / n).read_bytes()
        assert data == gen.content(n), f"{n} differs from what make_corpus.py writes: run it and commit the result"
        assert len(data) < 100_000, f"{n}: {len(data)} bytes"
    assert set(EXPECT) == set(NAMES)


def test_readme_lists_every_file():
    readme = (CORPUS_DIR / "README.md").read_text()
    rows = re.findall(r"^\| `([^`]+\.log)` \|", readme, re.M)
    assert rows == NAMES, "README.md must list every corpus file once, in the generator's order"


def test_healthy_frames_are_valid_railguard_traffic():
    """The base the hostile classes are laid on: every frame decodes with a correct CRC and
    each ID's counter steps by one (otherwise the hostile files would test nothing)."""
    db = database()
    last = {}
    frames = list(logfile.read(CORPUS_DIR / "healthy.log"))
    assert len(frames) == 350
    for f in frames:
        msg = db.get_message_by_frame_id(f.msg.arbitration_id)
        decoded = msg.decode(bytes(f.msg.data), decode_choices=False)
        fid = f.msg.arbitration_id
        assert check_profile2_crc(bytes(f.msg.data), fid & 0xFF), f.line
        if fid in last:
            assert (decoded["Counter"] - last[fid]) % 16 == 1, f.line
        last[fid] = decoded["Counter"]
    assert all(a.timestamp < b.timestamp for a, b in zip(frames, frames[1:]))
    assert frames[0].timestamp == 1_700_000_000.0


# ----------------------------------------------------------------------------- railguard replay (subprocess)

@pytest.mark.parametrize("name", NAMES)
def test_cli_exit_code_and_output(name, cli, replays):
    exp, proc = EXPECT[name], cli[name]
    context = f"{name}: rc {proc.rc}, stderr {proc.stderr[-1500:]!r}, stdout {proc.stdout[:300]!r}"
    assert "Traceback" not in proc.stdout + proc.stderr, context
    assert proc.rc == exp.rc, context
    if exp.rc == 2:
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1, context
        assert proc.stdout == "", context                 # checked in a first pass, before any output
        path = str(CORPUS_DIR / name)
        assert path in lines[0] and exp.error in lines[0], context
        if exp.line is not None:
            assert f"{path}:{exp.line}:" in lines[0], context
        return
    out = json.loads(proc.stdout)
    decisions, stats = replays[name]
    assert out["decisions"] == [[d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm, d.track_dm,
                                 d.track_state, d.track_cycles] for d in decisions]
    assert out["plot"] is None
    assert {k: v for k, v in out.items() if k not in ("decisions", "plot")} == stats


@pytest.mark.parametrize("name", [n for n in NAMES if EXPECT[n].rc == 2])
def test_bad_log_raises_one_line_log_error_in_process(name, setup):
    exp = EXPECT[name]
    with pytest.raises(logfile.LogError) as info:
        replay.check(CORPUS_DIR / name)
    text = str(info.value)
    assert "\n" not in text and exp.error in text
    if exp.line is not None:
        assert f"{name}:{exp.line}:" in text


# ----------------------------------------------------------------------------- counters

@pytest.mark.parametrize("name", PARSEABLE)
def test_counters(name, replays):
    exp = EXPECT[name]
    decisions, st = replays[name]
    assert st["rejected"] == exp.rejected
    assert st["filtered"] == exp.filtered
    assert st["frame_kinds"] == exp.kinds
    assert st["frames"] == sum(exp.kinds.values())
    own = sum(1 for s in (CORPUS_DIR / name).read_text().splitlines() if s.endswith(" T"))   # the recorded monitor's
    assert st["accepted"] == st["frames"] - sum(exp.rejected.values()) - exp.filtered - own
    assert st["bus_events"] == exp.bus_events
    assert st["bus_state"] == "error_active"                 # every file ends on a working bus
    got = [(a["line"], a["kind"], a["action"]) for a in st["time_anomaly_lines"]]
    assert got == list(exp.anomalies)
    kinds = {}
    for _, kind, _ in exp.anomalies:
        kinds[kind] = kinds.get(kind, 0) + 1
    assert st["time_anomalies"] == kinds
    assert st["segments"] == len(exp.segments)
    assert [(s["line"], s["reason"]) for s in st["segment_starts"]] == list(exp.segments)
    assert st["recorded_demands"] == exp.recorded_demands
    assert st["cycles"] == len(decisions)
    ticks = [d.tick for d in decisions]
    assert ticks == sorted(set(ticks)) and all(t % PERIOD == 0 for t in ticks)


# ----------------------------------------------------------------------------- brake behaviour

def cycles_in(decisions, t0: int, t1: int) -> list:
    return [d for d in decisions if t0 <= d.tick <= t1]


def assert_healthy_start_and_recovery(decisions, fault_start: int) -> None:
    assert decisions[0].mode == INIT and decisions[0].demand == EMERGENCY
    before = cycles_in(decisions, PERIOD, fault_start)
    assert before and all(d.demand == MAINTAIN and d.mode == NORMAL for d in before), levels(before)
    assert decisions[-1].demand == MAINTAIN and decisions[-1].mode == NORMAL, "not recovered at the end"


def assert_fault_window(decisions, first: int, last: int) -> None:
    """Emergency with the stale bit from DETECT after the first hostile frame to the last;
    no 'none' from the first emergency after the fault started to the last hostile frame."""
    window = cycles_in(decisions, first + DETECT, last)
    assert len(window) >= 5, (first, last)
    assert all(d.demand == EMERGENCY and d.reasons & R_STALE for d in window), levels(window)
    after = cycles_in(decisions, first, last)
    start = next(i for i, d in enumerate(after) if d.demand == EMERGENCY)
    assert all(d.demand != MAINTAIN for d in after[start:]), levels(after)


# (first hostile tick, last hostile tick): periods 10..19 at the channel's slot (+1 ms per channel)
FAULTS = {
    "bad_crc.log": (1003, 1903),
    "repeated_counter.log": (1004, 1904),
    "counter_jump.log": (1002, 1902),
    "wrong_dlc.log": (1005, 1905),
    "babbling_channel.log": (1063, 1903),      # first excess frame .. last frame refused in quarantine
    "forged_absent_in_step.log": (1002, 2804),  # first forged frame .. last genuine frame refused
    "extreme_values.log": (2000, 2905),
    "error_frames.log": (1500, 2510),          # no frame received from 1.5 s until the restart
    "secured_forged_absent.log": (1002, 2804),  # first forged frame .. last genuine frame refused
    "secured_stolen_key.log": (1002, 2802),
}


@pytest.mark.parametrize("name", list(FAULTS))
def test_emergency_while_a_channel_is_bad(name, replays):
    decisions, _ = replays[name]
    first, last = FAULTS[name]
    assert_healthy_start_and_recovery(decisions, first)
    assert_fault_window(decisions, first, last)


def test_extreme_values_at_the_limits_are_accepted(replays):
    decisions, st = replays["extreme_values.log"]
    limits = cycles_in(decisions, 800, 1900)     # periods 8..12 at the limits, and the cycles after
    assert all(d.demand == MAINTAIN and d.mode == NORMAL for d in limits), levels(limits)
    assert any(d.speed_cms == 12000 for d in limits)       # 120.00 m/s reached the core


TWIN_DROPS = {   # the hostile lines; the file without them is healthy.log, byte for byte
    "unknown_id.log": lambda s: int(ident(s), 16) in gen.UNKNOWN_IDS and len(ident(s)) == 3,
    "extended_id.log": lambda s: len(ident(s)) == 8,
    "fd_frame.log": lambda s: "##" in s,
    "remote_frames.log": lambda s: "#R" in s,
    "duplicated_frames.log": None,     # the second of two equal lines
    "time_backwards_small.log": lambda s: False,
}


@pytest.mark.parametrize("name", list(TWIN_DROPS))
def test_ignored_frames_change_no_decision(name, replays, tmp_path):
    """FD, extended, remote, unknown-ID and duplicated frames are never latched: the
    decisions equal those of the log without them, which is healthy.log."""
    drop = TWIN_DROPS[name]
    src = CORPUS_DIR / name
    if drop is None:
        lines = src.read_text().splitlines()
        kept = [s for i, s in enumerate(lines) if i == 0 or s != lines[i - 1]]
        stripped = tmp_path / name
        stripped.write_text("".join(s + "\n" for s in kept))
    else:
        stripped = without(src, tmp_path / name, drop)
    if name != "time_backwards_small.log":
        assert stripped.read_text() == (CORPUS_DIR / "healthy.log").read_text()
    decisions, _ = replays[name]
    healthy, _ = replays["healthy.log"]
    own_output = name == "unknown_id.log"       # its 0x041 frames land on MonitorTrack's ID: foreign senders
    assert [key(d, foreign=not own_output) for d in decisions] == [key(d, foreign=not own_output) for d in healthy]
    if own_output:
        lines = [ln for ln in src.read_text().splitlines() if ident(ln) == f"{codec.MONITOR_TRACK_ID:03X}"]
        t0 = float(src.read_text().split()[0].strip("()"))
        first, last = (round((float(ln.split()[0].strip("()")) - t0) * 1000) for ln in (lines[0], lines[-1]))
        hold = FOREIGN_HOLD_CYCLES * PERIOD
        assert [d.tick for d in decisions if d.foreign_output] == [
            d.tick for d in decisions if first <= d.tick <= last + hold]


def test_a_secured_replay_attack_changes_no_decision(replays):
    """Issue 39: sixty genuine secured frames sent again ten periods later, byte for byte, are
    refused for their freshness and the decisions are those of the healthy secured log, which
    are those of the healthy classic one."""
    decisions, _ = replays["secured_replay.log"]
    healthy, _ = replays["secured_healthy.log"]
    classic, _ = replays["healthy.log"]
    assert [key(d) for d in decisions] == [key(d) for d in healthy] == [key(d) for d in classic]


def test_secured_logs_need_their_keys(setup):
    """Without its key set a secured log is refused frame by frame (fd_frame: an unsecured
    reading), and the stats say how to replay it."""
    _, st = replay.replay_file(setup, CORPUS_DIR / "secured_healthy.log")
    assert st["rejected"] == {"fd_frame": 350} and "--keys" in st["note"]


def test_healthy_log_decides_none_after_init(replays):
    decisions, _ = replays["healthy.log"]
    assert len(decisions) == 51
    assert_healthy_start_and_recovery(decisions, decisions[-1].tick)


def test_error_frames_show_the_bus_off_and_change_nothing_else(replays, setup, tmp_path):
    decisions, st = replays["error_frames.log"]
    assert st["bus_events"]["bus_off"] == 1
    stripped = without(CORPUS_DIR / "error_frames.log", tmp_path / "e.log", lambda s: len(ident(s)) == 8)
    twin, twin_st = replay.replay_file(setup, stripped)
    assert [key(d) for d in decisions] == [key(d) for d in twin]
    assert twin_st["bus_events"] == {} and "error_frame" not in twin_st["rejected"]


def test_spoofed_brake_demands_are_foreign_and_change_nothing(replays, setup, tmp_path):
    decisions, st = replays["spoofed_brake_demand.log"]
    assert st["agreement_with_recorded"] == 1.0
    spoofed = lambda s: s.endswith(" R") and ident(s) in ("010", "040")        # noqa: E731
    stripped = without(CORPUS_DIR / "spoofed_brake_demand.log", tmp_path / "s.log", spoofed)
    twin, twin_st = replay.replay_file(setup, stripped)
    assert "foreign_output" not in twin_st["rejected"] and twin_st["recorded_demands"] == 50
    # the brake side (issue 39): the spoofer repeats the monitor's counter with other content,
    # a second sender: its reference receiver brakes from the first spoofed frame (1.05 s) and
    # holds it, the logged train never standing (29 cycles refused, then 11 without a valid frame);
    # without the spoofer it never brakes of its own (power-up: the cycle before the first frame)
    assert st["brake_receiver"] == {"power_up": 1, "second_sender": 29, "timeout": 11}
    assert twin_st["brake_receiver"] == {"power_up": 1}
    assert [key(d, foreign=False) for d in decisions] == [key(d, foreign=False) for d in twin]
    hold = FOREIGN_HOLD_CYCLES * PERIOD
    first, last = 1050, 2950                     # periods 10..29 at +50 ms
    flagged = [d.tick for d in decisions if d.foreign_output]
    assert flagged == [t for t in range(0, decisions[-1].tick + 1, PERIOD) if first <= t <= last + hold]
    assert not any(d.foreign_output for d in twin)


def test_flapping_channel(replays):
    """Issue 29 item 5: DEGRADED from the first PRESENT cycle, at least service with dispute
    and warning in every cycle that sees the obstacle, never 'none' while it flaps (the
    hold bridges the ABSENT cycles), and the flapping escalates to a perceptor error (the
    2oo2 disagreements add up: the agreeing cycles between them are too short to clear
    them): SAFE_STOP with emergency to the end of the file (the logged train never stands).
    At most 2 demand changes after the start: none -> service -> emergency."""
    decisions, _ = replays["flapping_channel.log"]
    assert decisions[0].mode == INIT and decisions[0].demand == EMERGENCY
    before = cycles_in(decisions, PERIOD, 1000)
    assert before and all(d.demand == MAINTAIN and d.mode == NORMAL for d in before), levels(before)
    flapping = cycles_in(decisions, 1100, 3000)
    assert all(d.mode in (DEGRADED_MODE, SAFE_STOP) and d.demand >= 1 for d in flapping), levels(flapping)
    present = [d for d in flapping if (d.tick // PERIOD) % 2 == 1]    # cycle k+1 sees period k (even k: PRESENT)
    assert len(present) == 10
    for d in present:
        assert d.demand >= 1 and d.reasons & R_DISPUTE and d.reasons & R_WARNING and d.distance_dm == 1500, d
    perceptor = [d for d in decisions if d.reasons & R_PERCEPTOR]
    assert perceptor and perceptor[0].tick <= 3000 and perceptor[0].mode == SAFE_STOP
    after = decisions[decisions.index(perceptor[0]):]
    assert all(d.demand == EMERGENCY and d.mode == SAFE_STOP for d in after), levels(after)
    tail = [d.demand for d in decisions[1:]]
    assert sum(a != b for a, b in zip(tail, tail[1:])) <= 2, levels(decisions)


def test_obstacle_approach_ends_in_emergency(replays):
    decisions, _ = replays["obstacle_approach.log"]
    assert all(d.demand == MAINTAIN for d in cycles_in(decisions, PERIOD, 1000))
    v, a, buildup_s = 20.0, Config().emergency_decel_mms2 / 1000, Config().emergency_buildup_ms / 1000
    can_stop_dm = (v * v / (2 * a) + v * buildup_s) * 10      # 83.3 m braking + 20 m build-up
    first = next(d for d in decisions if d.demand == EMERGENCY and d.mode != INIT)
    assert first.distance_dm > can_stop_dm, first
    after = decisions[decisions.index(first):]
    assert all(d.demand == EMERGENCY for d in after), levels(after)      # held to the end
    envelope = [i for i, d in enumerate(decisions) if d.reasons & R_ENVELOPE]
    assert envelope, "the obstacle never came inside EBI"
    assert decisions[envelope[0]].distance_dm > can_stop_dm
    assert all(d.reasons & R_ENVELOPE for d in decisions[envelope[0]:])
    assert decisions[-1].distance_dm == 300 and decisions[-1].demand == EMERGENCY


# ----------------------------------------------------------------------------- timestamps

def test_stray_zero_timestamp_is_bounded_and_restarts_twice(replays, cli):
    decisions, st = replays["stray_zero_timestamp.log"]
    assert st["cycles"] < 60           # the log's 5 s, never the 1.7e9 s jump
    assert cli["stray_zero_timestamp.log"].rc == 0
    starts = st["segment_starts"][1:]
    assert [(s["line"], s["reason"]) for s in starts] == [(142, "backwards"), (143, "gap")]
    by_tick = {d.tick: d for d in decisions}
    for s in starts:                    # each segment is a fresh monitor: INIT again
        assert by_tick[s["tick"]].mode == INIT, s
    print(f"stray (0.000000): railguard replay took {cli['stray_zero_timestamp.log'].seconds:.2f} s")


def test_large_backwards_step_splits_or_refuses(replays, setup):
    decisions, st = replays["time_backwards_large.log"]
    start = st["segment_starts"][1]
    assert {d.tick: d for d in decisions}[start["tick"]].mode == INIT
    with pytest.raises(logfile.LogError, match=r"time_backwards_large.log:141: timestamp jumps -3599.906"):
        replay.replay_file(setup, CORPUS_DIR / "time_backwards_large.log", on_time_error="refuse")
    proc = run_cli(["replay", str(CORPUS_DIR / "time_backwards_large.log"), "--json", "--no-plot",
                    "--on-time-error", "refuse"])
    assert proc.rc == 2 and proc.stdout == "" and len(proc.stderr.strip().splitlines()) == 1, proc
    assert "time_backwards_large.log:141:" in proc.stderr and "Traceback" not in proc.stderr


def test_forward_gap_splits_or_is_replayed_as_silence(replays, setup):
    decisions, st = replays["forward_gap.log"]
    assert st["cycles"] == 52          # 20 periods + 30 periods + the end cycles, not 1,200 more
    wide, wide_st = replay.replay_file(setup, CORPUS_DIR / "forward_gap.log", max_gap_s=200)
    assert wide_st["segments"] == 1 and wide_st["time_anomalies"] == {}
    assert wide_st["cycles"] > 1200
    silence = cycles_in(wide, 1906 + DETECT, 1906 + 120_000)
    assert len(silence) > 1100 and all(d.demand == EMERGENCY and d.reasons & R_STALE for d in silence)


# ----------------------------------------------------------------------------- replay = live

def play_live(setup, path: Path, until_line: Optional[int] = None, sent: Optional[list] = None,
              keys: Optional[Path] = None) -> MonitorRunner:
    """Feed a log's frames to a real MonitorRunner on python-can's virtual bus with a simulated
    clock: for each frame, run every cycle due before its tick (the tick the replay gives it:
    ms since the first frame, never earlier than the frame before), send it from a second bus
    object, drain; at the end run the cycles up to one period after the last frame. Lines
    marked ` T` (sent by the recording host: the recorded monitor's own frames) are not sent,
    since a monitor never receives its own frames. Frames from `until_line` on are not played.
    `sent` collects the frames the runner sent (BrakeDemand, MonitorStatus, MonitorTrack)."""
    clock = SimClock()
    channel = f"corpus-{path.stem}"
    mon_bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    feed = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    texts = path.read_text().splitlines()
    security = None
    if keys is not None:
        from can_bus.keys import SENDERS
        from can_bus.security import for_node

        security = for_node(keys, "live", SENDERS, state=False)
    runner = MonitorRunner(mon_bus, setup, clock, security=security)
    t0 = last_ts = None
    last_tick = 0
    try:
        for f in logfile.read(path):
            if until_line is not None and f.line >= until_line:
                break
            if t0 is None:
                t0 = last_ts = f.timestamp
            ts = max(f.timestamp, last_ts)
            tick = max(last_tick, round((ts - t0) * 1000))
            last_ts, last_tick = ts, tick
            while runner.next_tick < tick:
                clock.sleep_until_ms(runner.next_tick)
                runner.cycle()
            clock.sleep_until_ms(tick)
            if texts[f.line - 1].rstrip().endswith(" T"):
                continue
            feed.send(f.msg)
            runner.drain()
            collect(feed, sent)
        while runner.next_tick <= last_tick + PERIOD:
            clock.sleep_until_ms(runner.next_tick)
            runner.cycle()
        collect(feed, sent)
    finally:
        mon_bus.shutdown()
        feed.shutdown()
    return runner


def collect(bus, into: Optional[list]) -> None:
    """Empty the feeding bus's queue (the runner's own frames), keeping them if asked."""
    while (msg := bus.recv(timeout=0)) is not None:
        if into is not None:
            into.append(msg)


@pytest.mark.parametrize("name", PARSEABLE)
def test_replay_equals_live(name, setup, replays, tmp_path):
    """Logs with several segments: the first segment only (a live monitor does not restart
    on a jump of its log's clock), compared with a replay of that segment alone."""
    decisions, st = replays[name]
    path = CORPUS_DIR / name
    until = st["segment_starts"][1]["line"] if st["segments"] > 1 else None
    if until is not None:
        lines = path.read_text().splitlines()[: until - 1]
        first = tmp_path / name
        first.write_text("".join(s + "\n" for s in lines))
        seg_decisions, st = replay.replay_file(setup, first, **secured(name))
        assert [key(d) for d in seg_decisions] == [key(d) for d in decisions[: len(seg_decisions)]]
        decisions = seg_decisions
    runner = play_live(setup, path, until, keys=secured(name).get("keys"))
    assert [key(r) for r in runner.records] == [key(d) for d in decisions]
    assert {k: v for k, v in runner.receiver.rejected.items() if v} == st["rejected"]
    assert runner.monitor.tally.filtered == st["filtered"]
    own = sum(1 for s in path.read_text().splitlines() if s.endswith(" T"))
    kinds = dict(st["frame_kinds"])
    kinds["classical"] = kinds.get("classical", 0) - own
    assert {k: v for k, v in runner.monitor.tally.kinds.items() if v} == {k: v for k, v in kinds.items() if v}
    assert dict(runner.monitor.tally.bus_events) == st["bus_events"]
    assert runner.frames_received == st["frames"] - own
    assert runner.deadline_misses == 0


def test_live_monitor_status_flags_the_foreign_sender(setup):
    """The MonitorStatus frames the live runner sends carry ForeignOutput exactly in the
    cycles whose record has the flag: from the first spoofed frame until 1 s after the last."""
    sent = []
    runner = play_live(setup, CORPUS_DIR / "spoofed_brake_demand.log", sent=sent)
    status = database().get_message_by_frame_id(MONITOR_STATUS_ID)
    flags = [status.decode(bytes(m.data), decode_choices=False)["ForeignOutput"]
             for m in sent if m.arbitration_id == MONITOR_STATUS_ID]
    assert flags == [int(r.foreign_output) for r in runner.records]
    assert 0 < sum(flags) < len(flags) and flags[0] == 0 and flags[-1] == 0


def test_live_monitor_track_follows_the_records(setup, replays):
    """Every cycle the live runner sends MonitorTrack right after MonitorStatus, carrying the
    cycle's track (state, predicted distance, age): the replay's decisions, frame by frame."""
    sent = []
    runner = play_live(setup, CORPUS_DIR / "obstacle_approach.log", sent=sent)
    ids = [m.arbitration_id for m in sent]
    assert ids == [codec.BRAKE_DEMAND_ID, MONITOR_STATUS_ID, codec.MONITOR_TRACK_ID, codec.MONITOR_RISK_ID] * len(runner.records)
    msg = database().get_message_by_frame_id(codec.MONITOR_TRACK_ID)
    track = [msg.decode(bytes(m.data), decode_choices=False, scaling=False)
             for m in sent if m.arbitration_id == codec.MONITOR_TRACK_ID]
    decisions, _ = replays["obstacle_approach.log"]
    assert [(t["TrackState"], t["TrackDistance"], t["TrackAge"]) for t in track] == [
        (d.track_state, d.track_dm, d.track_cycles) for d in decisions]          # 100 ms: TrackAge = cycles
    assert {t["TrackState"] for t in track} >= {0, 1}       # none, then seen


# ----------------------------------------------------------------------------- 1,000,000 frames

def test_million_frame_log(big_runs):
    """`railguard replay` streams: exit 0, every frame counted, and the peak RSS of the
    1,000,000-frame replay within RSS_GROWTH_KB (8 MB) of the 100,000-frame one. Measured on
    this machine: both about 32 MB, the interpreter with its imports. Holding the decisions
    instead of streaming them would add about 30 MB at 1,000,000 frames (143,000 cycle
    records at some 210 bytes) against 3 MB at 100,000; holding the frames, some 450 MB
    (a parsed can.Message with its LogFrame is about 450 bytes). The absolute bound, 100 MB,
    is three times the interpreter's share."""
    small, big = big_runs[SMALL_FRAMES].wait(), big_runs[BIG_FRAMES].wait()
    for r in (small, big):
        assert r.rc == 0 and "Traceback" not in r.stderr, (r.frames, r.rc, r.stderr[-2000:])
        out = json.loads(r.out.read_text())
        assert out["frames"] == r.frames and out["accepted"] == r.frames and out["rejected"] == {}
        assert out["cycles"] == len(out["decisions"]) == -(-r.frames // 7) + 1
        assert {d[1] for d in out["decisions"][1:]} == {MAINTAIN}
    print(f"railguard replay, {big.frames:,} frames ({big.log.stat().st_size / 1e6:.0f} MB): "
          f"{big.seconds:.1f} s wall (overlapping the other tests), peak RSS {big.maxrss_kb / 1024:.1f} MB; "
          f"{small.frames:,} frames: {small.seconds:.1f} s, peak RSS {small.maxrss_kb / 1024:.1f} MB")
    assert big.maxrss_kb - small.maxrss_kb < RSS_GROWTH_KB, (big.maxrss_kb, small.maxrss_kb)
    assert 0 < small.maxrss_kb and big.maxrss_kb < 100 * 1024


# ----------------------------------------------------------------------------- canplayer on real vcan buses

VCAN_FILES = ("fd_frame.log", "remote_frames.log", "error_frames.log", "spoofed_brake_demand.log")
VCAN_REASONS = ("fd_frame", "remote_frame", "error_frame", "foreign_output")


def sandbox_available() -> bool:
    return shutil.which("apt-get") is not None or (vcan.cache_dir() / "root/usr/bin/linux.uml").is_file()


@dataclass
class VcanSession:
    """The sandbox session, run in a thread from the start of the module (it waits on the
    files' real-time playing most of the time, and overlaps with the other tests)."""

    out: Path
    thread: Optional[threading.Thread] = None
    result: Optional[vcan.VcanResult] = None
    error: Optional[BaseException] = None
    seconds: float = 0.0

    def start(self) -> "VcanSession":
        files = [str(without(CORPUS_DIR / n, self.out / n, lambda s: s.endswith(" T"))) for n in VCAN_FILES]
        # the recorded monitor's own frames (` T`) stay off the bus: a monitor never receives its own

        def run() -> None:
            t = time.monotonic()
            try:
                self.result = vcan.run(["sh", str(SCRIPT), str(self.out / "runs"), *files], timeout=150, cwd=ROOT,
                                       env={"PYTHONPATH": str(ROOT)})
            except BaseException as exc:  # noqa: BLE001 - reported by the tests
                self.error = exc
            self.seconds = time.monotonic() - t

        self.thread = threading.Thread(target=run, name="vcan-corpus", daemon=True)
        self.thread.start()
        return self


@pytest.fixture(scope="module")
def vcan_started(tmp_path_factory):
    """The sandbox session, started in the background (None without a sandbox)."""
    if not sandbox_available():
        yield None
        return
    session = VcanSession(tmp_path_factory.mktemp("vcan-corpus")).start()
    yield session
    session.thread.join(timeout=200)


@pytest.fixture(scope="module")
def vcan_session(vcan_started):
    if vcan_started is None:
        if os.environ.get("CI") == "true":
            pytest.fail("no apt-get to fetch user-mode-linux, and no cached sandbox")
        pytest.skip("needs apt-get (Debian) for the user-mode-linux sandbox")
    vcan_started.thread.join(timeout=200)
    assert not vcan_started.thread.is_alive(), "the sandbox session did not end"
    if vcan_started.error is not None:
        raise vcan_started.error
    res = vcan_started.result
    print(f"vcan sandbox session {vcan_started.seconds:.1f} s (overlapping the other tests): {res.stdout.strip()}")
    assert not res.timed_out, res.console[-2000:]
    return vcan_started.out / "runs", res


@pytest.mark.parametrize("name", VCAN_FILES)
def test_canplayer_on_vcan_rejects_as_replay(name, vcan_session, replays):
    """fd_frame, remote_frame, error_frame and foreign_output counted by `railguard run` on a
    real SocketCAN bus equal the replay's (the other reasons are printed, not compared: a
    frame's arrival time on a loaded sandbox may differ from its recorded time)."""
    runs, res = vcan_session
    folder = runs / Path(name).stem
    err = (folder / "monitor.err").read_text(errors="replace") if (folder / "monitor.err").exists() else ""
    context = f"{name}: sandbox rc {res.returncode}, {res.stdout} {res.stderr[-1000:]} monitor.err {err[-1000:]}"
    assert (folder / "rc").read_text().strip() == "0", context
    assert (folder / "canplayer.rc").read_text().strip() == "0", context
    assert "Traceback" not in err, context
    summary = json.loads((folder / "monitor.json").read_text().strip().splitlines()[-1])
    _, st = replays[name]
    live = {r: summary["rejects"].get(r, 0) for r in VCAN_REASONS}
    expected = {r: st["rejected"].get(r, 0) for r in VCAN_REASONS}
    print(f"{name} on {(folder / 'bus').read_text().strip()}: live rejects {summary['rejects']}, replay {st['rejected']}")
    assert live == expected, f"{context}; live rejects {summary['rejects']}, replay {st['rejected']}"
    if name == "error_frames.log":
        assert summary["bus_events"] == st["bus_events"], summary
