"""Issue 39 item 3 in co-simulation: the train FMU's brake receiver reads the monitor FMU's
cycle counter (delivered with the demand) as its alive signal. A monitor FMU that stops
(crash, hang: the master no longer steps it) leaves its demand at "none" for ever; the
receiver brakes once the counter has not moved for `brake_timeout` (0.3 s) and holds the
emergency to standstill. Without the check the train runs into the obstacle."""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

from fmu import cosim
from fmu import scenario as fs

STOP_S = 5.0


def first_brake_level(res) -> float:
    t, level = res.columns.index("time_s"), res.columns.index("brake_level")
    return next(r[t] for r in res.rows if r[level] > 0)


def test_cosim_cli_a_stopped_monitor_brakes_the_train_by_its_receiver(tmp_path):
    p = subprocess.run([sys.executable, "-m", "railguard", "cosim", "monitor-stop-30", "--json", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-1500:]
    s = json.loads(p.stdout)
    # the monitor never demanded anything; the receiver stopped the train far short of the obstacle
    assert s["max_demand"] == 0 and s["first_brake_s"] is None
    assert s["receiver_brake"] is True and s["outcome"] == "stopped" and s["margin_m"] > 1000


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_the_receiver_brakes_three_periods_after_the_counter_stops_and_only_then(table, monitor_fmus, train_fmu):
    scen = fs.load("monitor-stop-30")
    res = cosim.run_scenario(dataclasses.replace(scen, table=table), monitor_fmus[(table, 2)], train_fmu)
    assert res.outcome == "stopped" and res.receiver_brake and res.max_demand == 0
    # the last frame with a new counter reaches the train at 5.0 s (one cycle late); the
    # receiver brakes once it is older than 0.3 s (the next 10 ms grid instant), then the dead
    # time; a row is stamped at the end of its 10 ms step
    lo = STOP_S + 0.3 + scen.train["brake_delay"]
    assert lo < first_brake_level(res) <= lo + 0.02 + 1e-9
    # the same world without the alive check: the stopped monitor's "none" is obeyed to the end
    blind = dataclasses.replace(scen, table=table, train={**scen.train, "brake_timeout": 0.0})
    assert cosim.run_scenario(blind, monitor_fmus[(table, 2)], train_fmu).outcome == "collision"


def test_a_running_monitor_never_trips_the_receiver(monitor_fmus, train_fmu):
    scen = fs.load("static-600m-20")
    res = cosim.run_scenario(scen, monitor_fmus[("m2", 2)], train_fmu)
    assert res.outcome == "stopped" and not res.receiver_brake
