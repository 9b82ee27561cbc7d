"""An obstacle hidden behind a farther one, as users run it (issue 38 item 2):
`railguard run --scenario hidden-behind-3000m-40`. A at 3,000 m is seen for 0.3 s, then hidden
from every channel until 72.5 s; every channel reports B at 5,800 m instead. The rule itself
(a farther confirmed sighting is evidence against the track, never a replacement):
tests/test_core_memory.py, in the mutation kill set. And several obstacles at once
(`oncoming-behind-leaver-10`): B, seen beyond A, is remembered beside it (tests/test_tracks.py)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest


def _run(tmp_path, table: str, *extra: str, scenario: str = "hidden-behind-3000m-40") -> dict:
    out = subprocess.run([sys.executable, "-m", "railguard", "run", "--scenario", scenario, "--table",
                          table, "--out", str(tmp_path), "--no-plot", "--json", *extra], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_an_obstacle_hidden_behind_a_farther_one_is_remembered_and_the_train_stops(tmp_path, table):
    """Stopped short of A, which the memory held the whole time (never forgotten: B's sightings
    count against it only inside the declared sensor range, for forget_ms), braked by A's
    curves from memory (with the error budget about 3 s earlier and 70 to 110 m farther from A
    than without it: A's curves are longer and its remembered position closes at the closing
    accuracy too); with sensors declared 1.5 km inaccurate (so that B, 2.8 km beyond A, cannot
    be told from A measured again: a confirmed sighting replaces the track at once, as before
    issue 38 item 2) the train hits A without braking before A shows again (B stays beyond the
    curves, which count the 1.5 km too, until then)."""
    s = _run(tmp_path, table)
    # m1's table brakes as A shows again (230 to 340 m short of it); issue 41's m2 table leaves
    # the stop to the curves (97.7 m short)
    assert s["outcome"] == "stopped" and (230 if table == "m1" else 80) <= s["margin_m"] <= 340, s
    assert s["track"]["forgotten"] == 0 and s["track"]["held_longest_s"] >= 70
    assert 59 <= s["first_emergency_after_init_s"] <= 61             # A's curves, from memory
    blunt = tmp_path / "blunt.toml"
    blunt.write_text("[monitor]\ndistance_accuracy_dm = 15000\n")
    s = _run(tmp_path, table, "--monitor-config", str(blunt))
    # A was not remembered: nothing braked before it showed again at 72.5 s (held_longest_s no
    # longer tells: with 1.5 km accuracy nothing lies inside the declared 400 m, so after the
    # collision the track at 0 m is held, never forgotten by absence)
    assert s["outcome"] == "collision" and s["first_emergency_after_init_s"] > 72.4, s


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_an_obstacle_seen_beyond_a_remembered_one_is_remembered_too_and_the_train_stands(tmp_path, table):
    """A (380 m) leaves; B, oncoming at 40 m/s, is seen for 1 s beyond it, then the sensors see
    nothing (beyond the declared 400 m that is within their declaration). The blindness
    forgets A (in range), not B (beyond range): B's curves stop the train, which B then
    reaches standing (with one remembered obstacle B was never kept and hit the train at
    about 9 m/s, both tables)."""
    s = _run(tmp_path, table, scenario="oncoming-behind-leaver-10")
    assert s["outcome"] == "struck_at_standstill" and 110 <= s["margin_m"] <= 250, s
    assert s["track"]["forgotten"] == 1 and s["track"]["held_longest_s"] >= 25
    # the world's clock goes on after B reaches the train: the run ends with the scenario (60 s,
    # 601 cycles), not 60 s later at the run's limit (it did, with the clock stopped at 31.6 s)
    assert s["scenario_s"] == 60.0 and s["cycles"] == 601, (s["scenario_s"], s["cycles"])
