"""The monitor and the scenario player as two processes on a real SocketCAN vcan0.

The kernel here has no CAN support, so the bus lives in a user-mode Linux booted by
can_bus.vcan (DESIGN.md section 7). can-utils' candump records the bus; the recorded
BrakeDemand frames are decoded with the DBC and checked. Under CI=true this test must run:
a sandbox that cannot be set up is a failure, not a skip.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import can
import pytest
from cantools.autosar.end_to_end import check_profile2_crc

from can_bus import vcan
from host_load import MAX_STEAL, host_cpu, steal_between
from can_bus.codec import BRAKE_DEMAND_ID, MONITOR_STATUS_ID, database
from monitor.core.types import R_ENVELOPE, R_STALE, R_SYSTEM_ERROR, R_TABLE

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "tests" / "data" / "vcan-stop.toml"     # obstacle stop (about 31 s), then channel 2 silent 34-36 s


def one_session(out: Path) -> tuple[Path, float]:
    before = host_cpu()
    res = vcan.run(["sh", str(ROOT / "tests" / "vcan_session.sh"), str(out), str(SCENARIO)],
                   timeout=240, cwd=ROOT, env={"PYTHONPATH": str(ROOT)})
    steal = steal_between(before, host_cpu())
    assert not res.timed_out, (f"host CPU steal {steal:.0%}", session_files(out), res.console[-2000:])
    assert res.returncode == 0, (res.stdout, res.stderr, session_files(out))
    return out, steal


def session_files(out: Path) -> dict:
    """The tails of what the monitor and the player wrote: a session that timed out once in CI
    (its player waits for the monitor's NORMAL without a limit) showed only the kernel's console."""
    names = ("monitor.err", "monitor.json", "player.err", "player.json")
    return {n: (out / n).read_text(errors="replace")[-1500:] if (out / n).is_file() else "(absent)" for n in names}


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """One session; a second one if the host's hypervisor took so much CPU that the sandbox ran
    in fits (host_load.py), and the one with less steal is judged. The steal is written to
    host.txt in the session's folder and quoted by the checks that depend on timing."""
    if shutil.which("apt-get") is None and not (vcan.cache_dir() / "root/usr/bin/linux.uml").is_file():
        if os.environ.get("CI") == "true":
            pytest.fail("no apt-get to fetch user-mode-linux, and no cached sandbox")
        pytest.skip("needs apt-get (Debian) for the user-mode-linux sandbox")
    out, steal = one_session(tmp_path_factory.mktemp("vcan"))
    if steal > MAX_STEAL:
        out, steal = min((out, steal), one_session(tmp_path_factory.mktemp("vcan")), key=lambda r: r[1])
    (out / "host.txt").write_text(f"host CPU steal {steal:.0%} during the session")
    return out


def host(session: Path) -> str:
    return (session / "host.txt").read_text()


def frames(path: Path, frame_id: int) -> list[can.Message]:
    return [m for m in can.LogReader(str(path)) if m.arbitration_id == frame_id]


def test_player_reports_an_obstacle_stop_and_the_injected_fault(session):
    player = json.loads((session / "player.json").read_text())
    assert player["outcome"] == "stopped"
    assert player["margin_m"] > 0
    assert player["scenario_s"] >= 20.0
    assert "silence@ch2" in player["faults_injected"]


def test_monitor_exits_cleanly_and_saw_the_fault(session):
    monitor = json.loads((session / "monitor.json").read_text())
    player = json.loads((session / "player.json").read_text())
    context = f"monitor {monitor}; player {player}; {host(session)}"
    assert monitor["frames_received"] > 1000, context
    assert monitor["frames_rejected"] == 0, context
    assert monitor["faults_detected"].get("cycles_stale", 0) >= 10, context      # 2 s of silence, 100 ms cycles


def test_recorded_brake_demands_decode_and_tell_the_story(session):
    msg = database().get_message_by_frame_id(BRAKE_DEMAND_ID)
    demands = frames(session / "bus.log", BRAKE_DEMAND_ID)
    levels = "".join(str(msg.decode(bytes(m.data), decode_choices=False)["Level"]) for m in demands)
    context = f"{len(demands)} BrakeDemand frames, levels {levels}; {host(session)}"
    assert len(demands) >= 200, context                                 # >= 20 s of 100 ms cycles
    assert all(check_profile2_crc(bytes(m.data), BRAKE_DEMAND_ID & 0xFF) for m in demands)
    decoded = [msg.decode(bytes(m.data), decode_choices=False) for m in demands]
    counters = [d["Counter"] for d in decoded]
    gaps = [(i, a, b) for i, (a, b) in enumerate(zip(counters, counters[1:])) if (b - a) % 16 != 1]
    assert not gaps, f"alive counter must step by one: {gaps[:5]}; {context}"
    # while the train approaches, the table or the envelope demands emergency braking
    obstacle = [d for d in decoded if d["Level"] == 2 and d["Reason"] & (R_TABLE | R_ENVELOPE)]
    assert obstacle, f"no emergency demand caused by the obstacle; {context}"
    # the silent channel is detected: emergency for a stale channel / system error
    fault = [d for d in decoded if d["Level"] == 2 and d["Reason"] & R_STALE and d["Reason"] & R_SYSTEM_ERROR]
    assert len(fault) >= 10, f"{len(fault)} fault frames; {context}"
    assert decoded.index(obstacle[0]) < decoded.index(fault[-1]), context
    # SIGTERM: the last word of the monitor is an emergency demand
    assert decoded[-1]["Level"] == 2, f"last frame {decoded[-1]}; {context}"


def test_monitor_status_carries_the_table_hash(session):
    from importlib import resources

    from monitor.core.table import decode

    sha = decode(resources.files("monitor.tables").joinpath("m1.table.rgt").read_bytes()).sha256
    msg = database().get_message_by_frame_id(MONITOR_STATUS_ID)
    status = [msg.decode(bytes(m.data), decode_choices=False) for m in frames(session / "bus.log", MONITOR_STATUS_ID)]
    assert len(status) >= 200
    assert {s["TableHash"] for s in status} == {int(sha[:3], 16)}
    assert {s["Mode"] for s in status} >= {1, 2}                        # NORMAL, and DEGRADED during the fault


def decoded_cycles(result, frame_id: int) -> dict:
    """{cycle: (recorded, replayed)} of one output frame's decoded signals, where they differ."""
    msg = database().get_message_by_frame_id(frame_id)
    return {k: tuple(msg.decode(bytes.fromhex(x)[:8], decode_choices=False) for x in (a, b))
            for k, fid, a, b in result.mismatches if fid == frame_id}


def node_runs(status: dict) -> list[list[int]]:
    """The runs of consecutive cycles in which the two monitors' tables were in different nodes."""
    runs: list[list[int]] = []
    for k in sorted(k for k, (a, b) in status.items() if a["Node"] != b["Node"]):
        if runs and runs[-1][-1] == k - 1:
            runs[-1].append(k)
        else:
            runs.append([k])
    return runs


def test_the_monitor_on_the_ls_bus_decides_as_the_monitor_on_vcan0(session, tmp_path):
    """Issue 42: the session's candump replayed through the FMI-LS-BUS system (the C monitor
    node, a player node, our bus simulation, fmucontainer, FMPy) brakes as the monitor on vcan0
    did. The monitor on vcan0 ran on the wall clock beside the player process; the replay puts
    each input on the tick the recorded monitor gave it (fmu.lsbus_replay.on_ticks: on eight
    sessions 0 to 91 of 401 or 402 cycles differ in any field, none in a brake level or a table node).
    What the wall clock decided cannot be replayed exactly: a frame that arrived as the recorded
    monitor woke was drained by one of two cycles (the voted distance moves by one report, 0.1
    to 1.5 m), and a tick is known to the ms. Where that happens at a zone's edge (this
    scenario's obstacle meets the emergency zone at about cycle 6) the table may take another
    path, and since issue 41 confirms a warning for 10 cycles, the paths meet again up to 14
    cycles later (CI, 2026-11-30, on the earlier alignment: levels apart from cycle 21). So the
    decision is judged where it must agree: in every cycle in which both tables are in the same
    node, the brake level (table and supervision) is vcan0's, and the nodes part for at most 15
    cycles at a time and 30 in all. With the wrong table (m2) 380 and 381 levels of two sessions
    differ, 373 and 374 of them where the nodes agree; test_lsbus_monitor holds every field to
    the Python monitor exactly on the simulated clock."""
    from fmu import lsbus_replay
    from monitor import tables

    result = lsbus_replay.replay(session / "bus.log", tables.read("m1"), tmp_path, keys=None, realtime=True)
    assert result.compared // 4 >= 300, result
    runs = node_runs(decoded_cycles(result, MONITOR_STATUS_ID))
    apart = {k for run in runs for k in run}
    levels = [(k, a["Level"], b["Level"]) for k, (a, b) in decoded_cycles(result, BRAKE_DEMAND_ID).items()
              if k not in apart]
    assert not levels, (levels, runs)
    assert max(map(len, runs), default=0) <= 15 and len(apart) <= 30, runs


def test_sandbox_leaves_nothing_behind():
    assert vcan.leftovers() == []
    assert sys.executable


def test_sandbox_timeout_kills_the_kernel_and_cleans_up(session):
    import subprocess
    import tempfile

    res = vcan.run(["sleep", "100"], timeout=8)
    assert res.timed_out and res.returncode == 124
    assert vcan.leftovers() == []
    assert not list(Path(tempfile.gettempdir()).glob(f"{vcan.SANDBOX_PREFIX}{os.getpid()}-*"))
    # zombies (state Z) hold no resources: they wait for PID 1 to reap them
    ps = subprocess.run(["ps", "-eo", "stat=,args="], capture_output=True, text=True).stdout.splitlines()
    mine = f"uml_dir={Path(tempfile.gettempdir()) / vcan.SANDBOX_PREFIX}{os.getpid()}-"   # other workers' sandboxes may run
    alive = [line for line in ps if "linux.uml" in line and mine in line and not line.strip().startswith("Z")]
    assert alive == []


def test_sandbox_returns_the_command_exit_code_and_output(session):
    res = vcan.run(["sh", "-c", "ip -br link show vcan0; cat /sys/class/net/vcan0/mtu; uname -r; "
                    "echo oops >&2; exit 3"], timeout=60)
    assert res.returncode == 3
    link, mtu, release = res.stdout.splitlines()
    assert "vcan0" in link and "UP" in link
    assert int(mtu) == vcan.CANFD_MTU                     # a CAN FD bus (cangen -m needs it), not CAN XL
    # the kernel that boots on AMX hosts (Debian testing's 7.x), unless the user chose the host's
    if vcan.kernel_suite() != "host":
        assert int(release.split(".")[0]) >= 7, release
    assert res.stderr.strip() == "oops"
