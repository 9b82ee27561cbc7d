"""What any module saw is remembered (issue 38 item 1): a picture that some module sees with
both its channels creates the track although another module disputes it; what two modules
(or a confirmed picture) saw is held for forget_ms, what one module alone saw for
forget_single_ms; a module's sighting between the worst-case prediction and the last
position takes the track's position. The core is driven cycle by cycle; the world grid plays
the issue's world (one module never sees the obstacle, every channel blind during the
braking) through the scenario player and the monitor shell on the in-process bus."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from can_bus import scenario as scenarios
from can_bus import session
from monitor.core.config import Config, forget_cycles
from monitor.core.memory import UNITS_PER_DM
from monitor.core.types import (
    ABSENT, EMERGENCY, NO_DISTANCE, PRESENT, R_DISPUTE, R_MEMORY, STATIC, TRACK_CONFIRMING, TRACK_FORGOTTEN,
    TRACK_HELD, TRACK_NONE, TRACK_SEEN, Report,
)
from tests.test_can_run import setup_for
from tests.test_core_cycle import M1, M2, clear, normal_driver

SPEEDS_MPS = (10.0, 20.0, 30.0, 40.0)      # the supervision grid's (fmu/acceptance.py)


def seen_by(tick: int, distance: int, modules: tuple) -> tuple:
    """Both channels of each module in `modules` see an obstacle at `distance`; the others ABSENT."""
    return tuple(Report(PRESENT, distance, 0, STATIC, tick) if i // 2 in modules else Report(ABSENT, 0, 0, STATIC, tick)
                 for i in range(6))


def test_two_modules_seeing_what_the_third_disputes_create_a_strong_track_held_for_forget_ms():
    cfg = Config()
    d = normal_driver(cfg, M1)
    out = d.cycle(seen_by(d.tick, 1500, (1, 2)), 0)
    assert out.system_error and out.reasons & R_DISPUTE
    assert out.track_state == TRACK_SEEN and out.track_dm == 1500 and not out.reasons & R_MEMORY
    assert d.state.track_strong
    for k in range(forget_cycles(cfg) - 1):                  # blind: evidence, but not enough
        out = d.clear(0)
        assert out.track_state == TRACK_CONFIRMING and out.reasons & R_MEMORY, k
    assert d.clear(0).track_state == TRACK_FORGOTTEN


def test_one_module_alone_creates_a_weak_track_forgotten_after_forget_single_ms():
    cfg = Config(forget_single_ms=350)                       # 4 cycles (rounded up)
    n = forget_cycles(cfg, single=True)
    assert n == 4 and forget_cycles(cfg) == 75
    d = normal_driver(cfg, M1)
    out = d.cycle(seen_by(d.tick, 1500, (2,)), 0)
    assert out.track_state == TRACK_SEEN and out.track_dm == 1500 and not d.state.track_strong
    for k in range(n - 1):
        assert d.clear(0).track_state == TRACK_CONFIRMING, k
    out = d.clear(0)
    assert out.track_state == TRACK_FORGOTTEN and out.track_dm == NO_DISTANCE
    # forget_single_ms never makes a track last longer than forget_ms
    assert forget_cycles(Config(forget_ms=200, forget_single_ms=5000), single=True) == 2


def test_one_channel_alone_creates_nothing_and_a_second_module_makes_a_weak_track_strong():
    cfg = Config(forget_single_ms=100)
    d = normal_driver(cfg, M1)
    out = d.cycle(tuple(Report(PRESENT, 1500, 0, STATIC, d.tick) if i == 4 else Report(ABSENT, 0, 0, STATIC, d.tick)
                        for i in range(6)), 0)
    assert out.track_state == TRACK_NONE                     # module 2 split: its 2oo2 does not see it
    d.cycle(seen_by(d.tick, 1500, (0,)), 0)
    assert not d.state.track_strong
    d.cycle(seen_by(d.tick, 1500, (0, 1)), 0)
    assert d.state.track_strong
    for _ in range(5):                                       # now held for forget_ms, not 100 ms
        assert d.clear(0).track_state == TRACK_CONFIRMING


def test_a_module_s_sighting_where_the_track_can_be_takes_its_position_one_beyond_does_not():
    """At 30 m/s the worst-case prediction runs ahead of the last position (near < far); a
    sighting in between is the remembered obstacle seen where it can be."""
    d = normal_driver(Config(), M2)
    d.cycle(seen_by(d.tick, 30000, (1, 2)), 3000)
    near, far = d.state.track_near, d.state.track_far
    assert near < far == 30000 * UNITS_PER_DM
    out = d.cycle(seen_by(d.tick, 30000, (1, 2)), 3000)     # at far: taken
    assert out.track_state == TRACK_SEEN and out.track_dm == 30000
    d.cycle(seen_by(d.tick, 29800, (1, 2)), 3000)
    out = d.cycle(seen_by(d.tick, 29801, (1, 2)), 3000)     # one dm beyond far: kept
    assert out.track_state == TRACK_HELD and out.track_dm < 29800 and out.reasons & R_MEMORY


def _world(speed_mps: float, blind: tuple | None) -> str:
    """The issue's world at `speed_mps`: a static obstacle seen 5 s after the start, module 1
    (channels 0, 1) never sees it, every channel blind over `blind` (start, end) in s."""
    text = f"""description = "module miss + blindness at {speed_mps} m/s"
duration_s = 90.0
[train]
speed_mps = {speed_mps}
[[obstacles]]
position_m = {400.0 + 5.0 * speed_mps}
[sensors]
range_m = 400.0
noise_sigma_m = 0.3
seed = 4
[[faults]]
kind = "missed_detection"
channel = 0
start_s = 0.0
[[faults]]
kind = "missed_detection"
channel = 1
start_s = 0.0
"""
    if blind:
        text += f'[[faults]]\nkind = "blind"\nstart_s = {blind[0]}\nend_s = {blind[1]}\n'
    return text


@pytest.mark.parametrize("table", ["m1", "m2"])
@pytest.mark.parametrize("speed", SPEEDS_MPS)
def test_module_miss_and_a_blindness_shorter_than_forget_ms_during_the_braking_stop_the_train(tmp_path, table, speed):
    """The blindness starts on the cycle after the first braking demand and lasts forget_ms
    less 0.5 s: the brake stays on (the memory holds what two modules saw) and the train stops."""
    setup = setup_for(table)
    free = session.run_virtual(setup, scenarios.parse(tomllib.loads(_world(speed, None)), "free"), tmp_path / "free", plot=False)
    first = next(r.tick for r in free.runner.records if r.mode != 0 and r.demand > 0)
    start = first / 1000.0 + 0.1
    end = start + setup.config.forget_ms / 1000.0 - 0.5
    res = session.run_virtual(setup, scenarios.parse(tomllib.loads(_world(speed, (start, end))), "blind"), tmp_path / "blind", plot=False)
    s = res.summary
    assert s["outcome"] == "stopped" and not res.player.collision, (speed, table, s["outcome"])
    assert s["track"]["memory_cycles"] > 0
    # the demand never fell to none while the train moved during the blindness
    blind = [r for r in res.runner.records if start * 1000 <= r.tick < end * 1000 and r.distance_dm == NO_DISTANCE]
    assert blind and all(r.demand > 0 for r in blind if r.reasons & R_MEMORY)
    assert max(r.demand for r in blind) == EMERGENCY or all(r.demand > 0 for r in blind)


def test_the_shipped_module_miss_world_stops_as_users_run_it(tmp_path):
    for table in ("m1", "m2"):
        out = subprocess.run([sys.executable, "-m", "railguard", "run", "--scenario", "module-miss-blind", "--table", table,
                              "--out", str(tmp_path), "--no-plot", "--json"], capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        s = json.loads(out.stdout)
        assert s["outcome"] == "stopped" and s["track"]["memory_cycles"] > 0, (table, s["outcome"])
