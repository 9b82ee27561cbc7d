"""The issue's common freeze as users run it (issue 38 item 3): every channel stuck on its last
report at about 2,200 m, fresh frames, `railguard run --scenario frozen-all-2200m`. The rule
itself: tests/test_plausibility.py (in the mutation kill set, which runs no subprocess)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest


def _run(tmp_path, table: str, *extra: str) -> dict:
    out = subprocess.run([sys.executable, "-m", "railguard", "run", "--scenario", "frozen-all-2200m", "--table", table,
                          "--out", str(tmp_path), "--no-plot", "--json", *extra], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_the_issue_s_common_freeze_stops_the_train_as_users_run_it(tmp_path, table):
    """Every channel stuck at about 2,200 m with fresh frames: stopped, the fault named in the
    summary; with a plausibility window shorter than one period (no two reports are ever
    compared: the check out of the way, as before issue 38 item 3) the same world collides
    without a single braking cycle. (Declaring the sensors 6 km inaccurate no longer does that:
    the curves count the declared accuracy, the error budget, and brake from the start.)"""
    s = _run(tmp_path, table)
    assert s["outcome"] == "stopped" and s["faults_detected"]["cycles_implausible"] > 0
    assert 13.5 <= s["first_emergency_after_init_s"] <= 14.5        # the freeze at 10 s, 3.5 s to tell
    blunt = tmp_path / "blunt.toml"
    blunt.write_text("[monitor]\nplausibility_ms = 1\n")
    s = _run(tmp_path, table, "--monitor-config", str(blunt))
    assert s["outcome"] == "collision" and s["demands"]["emergency"] == 0
    assert not s["faults_detected"]                                  # (nothing told the freeze)
