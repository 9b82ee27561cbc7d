"""Supervision on guaranteed braking curves (issue 11): ghosts, graded responses, release,
and the braking declaration file.

The closed loop here is a deliberately plain train (the demand acts one cycle late at the
nominal 1 and 3 m/s^2); the braking-worse-than-nominal closed loop is the FMPy grid in
tests/test_supervision_grid.py.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from monitor import declaration
from monitor.core.braking import curves
from monitor.core.config import Config
from monitor.core.cycle import create, initial_state, step
from monitor.core.types import (
    ABSENT, EMERGENCY, MAINTAIN, PRESENT, R_DISPUTE, R_WARNING, SERVICE, STATIC, Inputs, Report, Train,
)
from monitor.tables import read

PERIOD = 100
DECEL = {MAINTAIN: 0.0, SERVICE: 1.0, EMERGENCY: 3.0}


def drive(table: str, speed_mps: float, seconds: float, reports_at, cfg: Config = Config()) -> dict:
    """A train at `speed_mps` on clear track (no real obstacle), its monitor fed by
    `reports_at(k, tick, speed_cms) -> tuple of 6 Reports`; the demand acts one cycle late."""
    setup = create(cfg, read(table))
    state = initial_state(setup)
    v = speed_mps
    applied = MAINTAIN
    demands, warnings, disputes, min_speed = [], 0, 0, v
    for k in range(int(seconds * 1000 / PERIOD)):
        tick = k * PERIOD
        v_cms = min(12000, round(v * 100))
        state, out = step(setup, state, Inputs(reports_at(k, tick, v_cms), Train(v_cms)), tick)
        demands.append(out.demand)
        warnings += bool(out.reasons & R_WARNING)
        disputes += bool(out.reasons & R_DISPUTE)
        v = max(0.0, v - DECEL[applied] * PERIOD / 1000)
        applied = out.demand
        min_speed = min(min_speed, v)
    return {"demands": demands, "warnings": warnings, "disputes": disputes, "min_speed": min_speed, "final": v}


def clear(tick: int) -> tuple:
    return tuple(Report(ABSENT, 0, 0, STATIC, tick) for _ in range(6))


def ghost(channel: int, first: int, cycles: int, where):
    """One channel reports an obstacle that is not there for `cycles` cycles from cycle `first`;
    `where(speed_cms) -> distance_dm` places it."""
    def reports_at(k, tick, v_cms):
        reps = list(clear(tick))
        if first <= k < first + cycles:
            reps[channel] = Report(PRESENT, where(v_cms), v_cms, STATIC, tick)
        return tuple(reps)
    return reports_at


@pytest.mark.parametrize("table", ["m1", "m2"])
@pytest.mark.parametrize("speed", [10.0, 25.0, 40.0])
@pytest.mark.parametrize("channel", [0, 3, 5])
@pytest.mark.parametrize("beyond_m", [1.0, 50.0, 3000.0])
def test_a_short_ghost_beyond_sbi_never_stops_the_train(table, speed, channel, beyond_m):
    """Issue 11 acceptance: a 0.3 s ghost on one channel, clear track beyond SBI: a warning and
    a diagnostic, no braking at all, and the train never comes to a standstill."""
    cfg = Config()
    where = lambda v_cms: min(60000, curves(cfg, v_cms, 0, 0, v_cms, 0).sbi_dm + round(beyond_m * 10))
    run = drive(table, speed, 60.0, ghost(channel, 50, 3, where), cfg)
    assert run["disputes"] == 3 and run["warnings"] >= 3
    assert set(run["demands"][1:]) == {MAINTAIN}
    assert run["min_speed"] == speed


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_a_ghost_inside_ebi_brakes_but_a_revocable_emergency_does_not_stop_the_train(table):
    cfg = Config()
    run = drive(table, 40.0, 30.0, ghost(2, 50, 3, lambda v: curves(cfg, v, 0, 0, v, 0).ebi_dm - 10), cfg)
    assert EMERGENCY in run["demands"][50:53]
    tail = run["demands"][53:]
    held = next(i for i, d in enumerate(tail) if d != EMERGENCY)
    assert held == cfg.release_confirm_cycles - 1    # the confirm-th calm cycle releases
    assert 30.0 < run["min_speed"] < 40.0 and run["final"] == run["min_speed"]


def test_the_same_ghost_with_emergency_held_to_standstill_stops_the_train():
    """The configuration value chooses ETCS's other national value: then the train stops."""
    cfg = Config(emergency_release=0)
    run = drive("m1", 40.0, 30.0, ghost(2, 50, 3, lambda v: curves(cfg, v, 0, 0, v, 0).ebi_dm - 10), cfg)
    assert run["final"] == 0.0


def test_a_persistent_dispute_ends_in_safe_stop():
    """A channel that keeps disagreeing is a perceptor error after persistence_cycles (1 s)."""
    cfg = Config()
    run = drive("m1", 20.0, 40.0, ghost(1, 20, 10 ** 6, lambda v: 50000), cfg)
    assert run["demands"][20 + cfg.persistence_cycles - 2] == MAINTAIN
    assert run["demands"][20 + cfg.persistence_cycles - 1] == EMERGENCY
    assert run["final"] == 0.0


def test_a_stale_channel_brakes_then_releases_when_it_is_back():
    cfg = Config()

    def reports_at(k, tick, v_cms):
        reps = list(clear(tick))
        if 50 <= k < 53:
            reps[4] = Report(ABSENT, 0, 0, STATIC, tick - 10_000)
        return tuple(reps)
    run = drive("m2", 30.0, 20.0, reports_at, cfg)
    assert run["demands"][50:53] == [EMERGENCY] * 3
    assert EMERGENCY not in run["demands"][53 + cfg.release_confirm_cycles:]
    assert 20.0 < run["final"] < 30.0


# --------------------------------------------------------------------------- the declaration file


def test_the_shipped_declaration_is_the_configs_default():
    assert declaration.apply(Config(), declaration.shipped()) == Config()


def test_a_declaration_file_sets_the_integer_fields_rounding_to_the_safe_side(tmp_path):
    f = tmp_path / "train.toml"
    f.write_text("[braking]\nemergency_decel = 2.0005\nservice_decel = 0.9999\nemergency_buildup_s = 1.2341\n"
                 "service_buildup_s = 3\ntraction_cutoff_s = 0.5\nmax_accel = 0.7\nspeed_error = 0.0101\n"
                 "slippery_factor = 0.65\ndegraded_factor = 0.5\nmax_downhill_gradient = 12.5\nstandstill_margin_m = 2.01\n")
    cfg = declaration.config_with(Config(), f)
    assert (cfg.emergency_decel_mms2, cfg.emergency_band2_cms, cfg.service_decel_mms2) == (2000, 0, 999)
    assert (cfg.emergency_buildup_ms, cfg.speed_error_permille, cfg.max_gradient_permille, cfg.standstill_margin_dm) == (1235, 11, 13, 21)
    assert (cfg.slippery_permille, cfg.degraded_permille, cfg.max_accel_mms2) == (650, 500, 700)


@pytest.mark.parametrize("text, words", [
    ("emergency_decel = 2.0", "missing key(s) service_decel"),
    ("emergency_decel = 'fast'", "emergency_decel = 'fast': must be a number"),
    ("emergency_decel = [[5.0, 2.0]]", "first band must start at 0"),
    ("emergency_decel = [[0.0, 2.0], [0.0, 1.5]]", "band speeds must increase"),
    ("bogus = 1", "unknown key(s) bogus"),
    ("emergency_decel = nan", "must be a number"),
    ("slippery_factor = 1.2", "slippery_factor = 1.2: must be 0.001..1"),
    ("emergency_decel = = 3", "malformed TOML"),
    ("max_downhill_gradient = 45", "service_decel_mms2"),
])
def test_a_bad_declaration_is_refused_in_one_line_naming_file_and_key(tmp_path, text, words):
    good = dict(declaration.shipped())
    key = text.split("=")[0].strip()
    body = "".join(f"{k} = {v!r}\n".replace("'", '"') if not isinstance(v, list) else f"{k} = {v}\n"
                   for k, v in good.items() if k != key and not (key == "emergency_decel" and k == "service_decel"
                                                                  and "missing" in words))
    f = tmp_path / "bad.toml"
    f.write_text(body + text + "\n")
    with pytest.raises(declaration.DeclarationError) as exc:
        declaration.config_with(Config(), f)
    msg = str(exc.value)
    assert "\n" not in msg and str(f) in msg and words in msg, msg


def test_a_missing_declaration_file_is_one_line(tmp_path):
    with pytest.raises(declaration.DeclarationError, match="no such file .braking declaration"):
        declaration.load(tmp_path / "nope.toml")
