"""The monitor network FMU (C core + C frame layer on the FMI-LS-BUS bus) decides cycle by
cycle as the Python monitor of `railguard run` does on the same traffic (issue 42): a run's
candump log is replayed through the container, and every frame the C monitor sends carries
the payload the Python monitor sent (level, reasons, cycle, status, track, risk, counters,
CRC). The runs are the README's command on shipped scenarios, secured with one key set."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from can_bus.keys import new_set
from fmu import lsbus_replay
from fmu.network_nodes import build_monitor_node
from monitor import tables

SCENARIOS = ("static-obstacle", "hostile-replay-brake-none")   # all 24 railguard run plays: docs/fmu.md


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("lsbus-monitor")
    keys = new_set(root / "keys", test=True).folder
    monitor = build_monitor_node(tables.read("m2"), root, keys=keys)
    return root, keys, monitor


def run_log(setup, scenario: str) -> Path:
    """The candump log of `railguard run --scenario SCENARIO` (run once per module)."""
    root, keys, _ = setup
    out = root / scenario
    if not out.is_dir():
        res = subprocess.run([sys.executable, "-m", "railguard", "run", "--scenario", scenario, "--keys", str(keys),
                              "--out", str(out), "--no-plot", "--quiet", "--json"], capture_output=True, text=True)
        assert res.returncode == 0, res.stderr
    return next(out.glob("*.log"))


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_the_c_monitor_on_the_bus_sends_what_the_python_monitor_sent(setup, scenario):
    root, keys, monitor = setup
    out = root / scenario
    log = run_log(setup, scenario)
    result = lsbus_replay.replay(log, b"", out / "replay", keys=keys, monitor_fmu=monitor)
    assert result.compared >= 4 * 150, result              # every shipped scenario runs at least 15 s
    assert result.recorded - result.compared <= 4          # the Python monitor's last emergency at shutdown
    assert result.mismatches == [], result.mismatches[:4]


def test_a_wrong_table_is_caught(setup, tmp_path):
    """The comparison can fail: the m1 table on an m2 run differs from the first cycle on."""
    root, keys, _ = setup
    log = run_log(setup, "static-obstacle")
    m1 = build_monitor_node(tables.read("m1"), tmp_path, keys=keys)
    result = lsbus_replay.replay(log, b"", tmp_path / "replay", keys=keys, monitor_fmu=m1)
    assert len(result.mismatches) > 100


def test_frames_the_monitor_did_not_send_are_told_apart(setup):
    """A replayed (stale) or forged frame on the monitor's own IDs is traffic, not the monitor's."""
    root, keys, _ = setup
    log = run_log(setup, "hostile-replay-brake-none")
    inputs, recorded = lsbus_replay.read_log(log, keys)
    hostile = [f for f in inputs if f[1] == 0x10]
    assert hostile and len(recorded) % 4 == 0
    assert [fid for _, fid, _ in recorded] == [0x10, 0x40, 0x41, 0x42] * (len(recorded) // 4)


def test_a_wall_clock_log_keeps_the_ticks_the_recorded_monitor_gave():
    """on_ticks: the recorded monitor ticked at T0 + k x 100 ms and sent each BrakeDemand a
    latency after (up to 3 ms, the SIGTERM word a period low); a frame stamped s must reach the
    replayed monitor (ticks k x 100 ms, deciding REPLAY_PHASE_MS later) at s - T0, so that its
    age and its cycle are the recorded ones; frames before the replay or after it are dropped.
    The earlier alignment put every frame on the next tick (age 0 instead of 90 ms)."""
    from can_bus.codec import BRAKE_DEMAND_ID
    t0, latency = -0.0778, [0.0002, 0.0009, 0.0004, 0.003, 0.0001] * 8
    recorded = [(t0 + k * 0.1 + d, BRAKE_DEMAND_ID, b"") for k, d in enumerate(latency)]
    recorded.append((recorded[-1][0] + 0.003, BRAKE_DEMAND_ID, b""))       # the last word on SIGTERM
    inputs = [(t0 - 0.01, 0x20, False, b"a"), (t0 + 0.0123, 0x20, False, b"b"), (t0 + 2.0101, 0x21, False, b"c"),
              (t0 + 5.0, 0x21, False, b"d")]
    played = lsbus_replay.on_ticks(inputs, recorded, 0.1)
    assert [d for _, _, _, d in played] == [b"b", b"c"]
    assert [round(t, 4) for t, _, _, _ in played] == [0.0122, 2.01]
    with pytest.raises(lsbus_replay.BuildError, match="no BrakeDemand"):
        lsbus_replay.on_ticks(inputs, [], 0.1)                              # not a monitor's log
