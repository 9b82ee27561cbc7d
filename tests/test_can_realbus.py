"""The README's real-bus commands, exactly as written, end to end (issue 13).

In one sandbox boot (can_bus.vcan, DESIGN.md section 7; tests/vcan_realbus.sh):
- `railguard keys new hil-keys`, the key set the commands below are secured with;
- `railguard run --interface socketcan --channel vcan0 --keys hil-keys --no-player`, started in the
  background by sh (so with SIGINT ignored until the monitor installs its handler) and
  interrupted with SIGINT after about 4 s: exit 0, status lines on stderr, the human summary
  on stdout, no traceback;
- `railguard run --interface socketcan --channel vcan0 --keys hil-keys --duration 3`: player
  thread and monitor in real time, with the live status line, every frame a secured CAN FD frame;
- the monitor and `railguard play ... --keys hil-keys` as two processes, the monitor killed.
On the host: the same real-time path on python-can's virtual interface, and the one-line
error (exit 2) when the interface cannot be opened. Under CI=true a sandbox that cannot
be set up is a failure, not a skip.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from can_bus import vcan

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tests" / "vcan_realbus.sh"
STATUS = re.compile(r"^t\s+\d+\.\d s .*\bdemand \w+", re.M)        # the live status line
SUMMARY_KEYS = ("cycles", "demands", "frames_received", "deadline_misses")


def railguard() -> str:
    exe = shutil.which("railguard")
    if exe is None:
        pytest.fail("the railguard entry point is not installed (pip install -e .)")
    return exe


def human_summary(stdout: str) -> dict:
    """The summary's `key  value` lines."""
    rows = {}
    for line in stdout.splitlines():
        m = re.match(r"^(\w+)\s{2,}(.*)$", line)
        if m:
            rows[m.group(1)] = m.group(2)
    return rows


def check_run(stdout: str, stderr: str, rc: int, what: str) -> None:
    context = f"{what}: rc {rc}\nstdout:\n{stdout[-2000:]}\nstderr:\n{stderr[-2000:]}"
    assert "Traceback" not in stdout + stderr, context
    assert rc == 0, context
    assert STATUS.search(stderr), f"no status line; {context}"
    summary = human_summary(stdout)
    assert all(k in summary for k in SUMMARY_KEYS), f"no human summary; {context}"
    assert int(summary["cycles"]) > 0, context


@pytest.fixture(scope="module")
def sandbox(tmp_path_factory):
    if shutil.which("apt-get") is None and not (vcan.cache_dir() / "root/usr/bin/linux.uml").is_file():
        if os.environ.get("CI") == "true":
            pytest.fail("no apt-get to fetch user-mode-linux, and no cached sandbox")
        pytest.skip("needs apt-get (Debian) for the user-mode-linux sandbox")
    out = tmp_path_factory.mktemp("realbus")
    t = time.monotonic()
    res = vcan.run(["sh", str(SCRIPT), str(out)], timeout=180, cwd=ROOT, env={"PYTHONPATH": str(ROOT)})
    print(f"sandbox session {time.monotonic() - t:.1f} s")
    assert not res.timed_out, res.console[-2000:]
    assert res.returncode == 0, (res.stdout, res.stderr)
    return out


def read(folder: Path) -> tuple[str, str, int]:
    rc = (folder / "rc").read_text().strip() if (folder / "rc").exists() else ""
    return ((folder / "stdout").read_text(errors="replace"), (folder / "stderr").read_text(errors="replace"),
            int(rc) if rc.lstrip("-").isdigit() else -1)


def test_readme_monitor_command_on_vcan0_stops_cleanly_on_sigint(sandbox):
    stdout, stderr, rc = read(sandbox / "monitor")
    check_run(stdout, stderr, rc, "railguard run --interface socketcan --channel vcan0 --keys hil-keys --no-player (SIGINT)")
    assert "SIGKILL" not in stderr
    summary = human_summary(stdout)
    assert summary["outcome"] == "monitor_only"
    # ended by SIGINT after about 4 s, not by itself: several status lines (one per second)
    assert len(STATUS.findall(stderr)) >= 3, stderr
    assert (sandbox / "monitor" / "railguard-out" / "run-vcan0.log").is_file()


def test_player_and_monitor_on_vcan0_with_status_line(sandbox):
    stdout, stderr, rc = read(sandbox / "player")
    check_run(stdout, stderr, rc, "railguard run --interface socketcan --channel vcan0 --keys hil-keys --duration 3")
    summary = human_summary(stdout)
    assert summary["outcome"] != "monitor_only"          # the player ran and reported its outcome
    assert int(summary["cycles"]) == 30                    # 3 s of 100 ms cycles
    assert summary["bus_security"].startswith("secured") and "TEST" not in summary["bus_security"], summary
    assert int(summary["frames_received"]) >= 25 * 7 and summary["rejects"] == "-", summary   # every secured
    assert summary["frame_kinds"].startswith("fd "), summary                 # CAN FD frame on vcan0 verified


def test_kill_9_of_the_monitor_brakes_the_train_within_the_receivers_timeout(sandbox):
    """Issue 39: the monitor killed (SIGKILL) under way on vcan0; `railguard play`'s brake
    receiver sees no BrakeDemand for its timeout, brakes, and holds it to standstill."""
    folder = sandbox / "kill"
    stdout, stderr, rc = read(folder)
    assert rc == 0 and "Traceback" not in stdout + stderr, (rc, stderr[-1500:])
    s = json.loads(stdout)
    assert s["final_speed_mps"] == 0.0, s                  # stands: at 10 m/s it would have run on
    assert s["bus_security"].startswith("secured"), s
    held = s["brake_receiver"]
    assert set(held) <= {"power_up", "timeout"} and held.get("timeout", 0) > 0, held
    # it braked once the newest valid BrakeDemand was older than the timeout (3 periods),
    # measured on the player's clock: at most one period of the player's own cycle later
    assert 300 <= s["brake_timeout_after_ms"] <= 400 + 50, s
    # and held the brakes from then to the end (15 s of world, the kill about 3 s after the entry)
    assert held["timeout"] >= 100, held


def test_virtual_interface_in_real_time_with_the_player(tmp_path):
    proc = subprocess.run([railguard(), "run", "--interface", "virtual", "--channel", "foo", "--duration", "2", "--unsecured"],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path)
    check_run(proc.stdout, proc.stderr, proc.returncode, "railguard run --interface virtual --channel foo --duration 2 --unsecured")
    assert int(human_summary(proc.stdout)["cycles"]) == 20


def test_unopenable_interface_is_one_line_exit_2(tmp_path):
    proc = subprocess.run([railguard(), "run", "--interface", "socketcan", "--channel", "nosuch0", "--no-player", "--unsecured"],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path)
    lines = proc.stderr.strip().splitlines()
    context = f"rc {proc.returncode}, stderr {proc.stderr!r}, stdout {proc.stdout!r}"
    assert proc.returncode == 2, context
    assert len(lines) == 1, context
    assert "socketcan" in lines[0] and "nosuch0" in lines[0] and "python -m can_bus.vcan" in lines[0], context
    assert "Traceback" not in proc.stderr + proc.stdout
