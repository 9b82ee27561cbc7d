"""verification/seed000/: the seed 000 simulation run through the monitor core."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from monitor.core.braking import curves, ebi_dm
from monitor.core.config import Config
from verification import seed000
from verification.seed000 import LITERAL, PAPER, SHIPPED, Scenario, simulate

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def quick_section(tmp_path_factory):
    out = tmp_path_factory.mktemp("seed000")
    messages = []
    return out, seed000.section(out, True, messages.append), messages


@pytest.fixture(scope="module")
def small_run():
    return simulate(SHIPPED, 30, 60.0, seed=7, record=24)


def test_quick_section_passes_and_writes_its_figures(quick_section):
    out, sec, messages = quick_section
    failed = [c.line() for c in sec.checks if not c.passed]
    assert not failed, failed
    names = {c.name for c in sec.checks}
    assert any("agrees with monitor.core" in n for n in names)
    assert any("collisions (shipped)" in n for n in names)
    assert any("train-seconds" in n for n in names)
    core = [c for c in sec.checks if "agrees with monitor.core" in c.name]
    assert all(c.details["trains"] >= 20 and c.details["cycles"] > 0 for c in core)
    for name in ("seed000_fig7a.png", "seed000_fig7b.png", "seed000_fig7c.png", "seed000_fig7d.png"):
        assert name in sec.figures
    for name in sec.figures:
        assert (out / name).read_bytes()[:8] == PNG_MAGIC, name
        assert f"]({name})" in sec.markdown, name
    assert "| collisions |" in sec.markdown and "300" in sec.markdown
    phantoms = next(c for c in sec.checks if "stops without an obstacle per train-hour" in c.name)
    assert phantoms.details["after_revocable"] < phantoms.details["after_held"]
    assert "stops to standstill per train-hour" in sec.markdown and "75a5c9f" in sec.markdown
    assert messages, "progress was never called"


def test_phantoms_stop_the_train_only_when_the_emergency_is_held():
    """The same phantom world: revocable release, few stops; held to standstill, a stop per phantom."""
    revocable = simulate(seed000.PHANTOMS, 40, 60.0, seed=9)
    held = simulate(seed000.PHANTOMS_HELD, 40, 60.0, seed=9)
    assert revocable.metrics["false_onsets"] > 50
    # stops with no obstacle on the line (phantoms); since issue 12 the table also stops for
    # real obstacles that stay reported, which is not what this is about
    # (4 x before the sensors' error budget lengthened the curves: 75 against 24 since, issue 40 item 3)
    assert seed000.stops_per_hour(held, "stops_no_obstacle") > 2.5 * max(1.0, seed000.stops_per_hour(revocable, "stops_no_obstacle"))
    assert held.metrics["stops"] >= held.metrics["stops_no_obstacle"] > 0


def test_vectorised_run_agrees_with_the_real_core(small_run):
    ok, cycles, trains = seed000.core_agreement(small_run, 20)
    assert ok and trains == 20 and cycles == 20 * small_run.steps
    assert small_run.metrics["appearances"] > 0   # something happened worth comparing
    assert (small_run.trace["demand"] > 0).any()


def test_core_agreement_notices_a_wrong_trace(small_run):
    bad = seed000.Run(small_run.scenario, small_run.trains, small_run.steps, small_run.seed, small_run.metrics,
                      {k: v.copy() for k, v in small_run.trace.items()}, small_run.episode, small_run.appear_step)
    k = int(np.argmax(bad.trace["demand"][:, 0] > 0)) if (bad.trace["demand"][:, 0] > 0).any() else 5
    bad.trace["demand"][k, 0] = 2 - bad.trace["demand"][k, 0]
    ok, _, _ = seed000.core_agreement(bad, 20)
    assert not ok


def test_a_train_with_no_obstacle_never_brakes():
    clear = replace(SHIPPED, key="clear", obstacle_fraction=0.0)
    run = simulate(clear, 50, 30.0, seed=3)
    m = run.metrics
    assert m["appearances"] == 0 and m["onsets"] == 0 and m["emergency_steps"] == 0 and m["service_steps"] == 0
    assert (run.trace["demand"] == 0).all() and (run.trace["speed_cms"] == 4000).all()
    assert m["zone_true"][0] == run.trains * run.steps
    assert math.isclose(m["distance_m"], 40.0 * run.train_seconds)


def test_without_phantoms_braking_seldom_starts_without_an_obstacle(small_run):
    """Before the obstacle memory braking never started without an obstacle here; now an
    obstacle that has just left the track can still be braked for (remembered until forget_ms
    of confirmed absence, or kept while the hold's confirmation runs): 4 of 17 onsets in this
    run (2 of 15 with forget_ms = 100), 5 of 18 since the sensors' error budget lengthened the
    curves and moves the memory faster (issue 40 item 3). Issue 29's finding, left for its own
    work: which of them the release rule could avoid."""
    assert small_run.metrics["onsets"] > 0
    assert small_run.metrics["onsets_no_obstacle"] <= small_run.metrics["onsets"] // 3
    assert small_run.metrics["collisions"] == 0


def test_collisions_are_counted_when_braking_cannot_avoid_them():
    # the paper as printed: obstacles 200..250 m ahead, 3 m/s^2 needs 266.7 m from 40 m/s
    run = simulate(LITERAL, 100, 60.0, seed=5)
    assert run.metrics["appearances"] > 10
    assert run.metrics["collisions"] > 0
    assert max(run.metrics["collision_speeds"]) > 0.0


def test_same_seed_same_metrics_other_seed_other_metrics():
    def key(run):
        m = run.metrics
        return (m["appearances"], m["collisions"], m["onsets"], tuple(m["zone_true"]), m["reward_model"],
                m["distance_m"], m["noise_sum"], m["discounted_return"])

    a = simulate(SHIPPED, 40, 40.0, seed=11)
    b = simulate(SHIPPED, 40, 40.0, seed=11)
    c = simulate(SHIPPED, 40, 40.0, seed=12)
    assert key(a) == key(b)
    assert all((a.trace[k] == b.trace[k]).all() for k in a.trace)
    assert key(a) != key(c)


def test_train_seconds_are_counted():
    run = simulate(SHIPPED, 7, 12.3, seed=1, record=5)
    assert run.steps == 123
    assert math.isclose(run.train_seconds, 7 * 12.3)
    assert int(run.metrics["zone_true"].sum()) == 7 * 123
    assert int(run.metrics["zone_obs"].sum()) == 7 * 123
    assert run.trace["present"].shape == (123, 5)


def test_zones_and_obstacle_window():
    a1, a2 = SHIPPED.alphas_at_line_speed_m()
    # the core's zones under normal conditions at 40 m/s, a static obstacle: alpha2 = EBI, alpha1 = the service
    # EBI, as zone limits (one period and no sensor error budget, not the supervision's four periods
    # and 50 m + 1 m/s: its EBI is 563.8 m)
    assert (a1, a2) == (ebi_dm(Config(), 4000, 0, 0, 4000, 0, service=True) / 10,
                        ebi_dm(Config(), 4000, 0, 0, 4000, 0) / 10) == (1588.8, 475.8)
    assert curves(Config(), 4000, 0, 0, 4000, 0).ebi_dm == 5638     # 492.9 m without the budget, 481.5 m with 2 periods
    lo, hi = SHIPPED.appear_window_m()
    assert math.isclose(lo, 1032.3) and math.isclose(hi, 1082.3)
    assert PAPER.alphas_at_line_speed_m() == (300.0, 100.0)   # one cycle (4 m) + v^2/2a with 8.334 / 2.703 m/s^2
    assert PAPER.appear_window_m() == (200.0, 250.0)   # the paper's 200..250 m
    p_a, p_c = SHIPPED.hazards()
    assert math.isclose(p_a / (p_a + p_c), 0.2)
    assert math.isclose(seed000.expected_obstacle_fraction(SHIPPED, 10**6), 0.2, rel_tol=1e-3)


def test_train_motion_is_exact():
    sc = SHIPPED
    v = np.array([40.0])
    travelled = 0.0
    for _ in range(200):
        v, s = seed000._move(v, np.array([3.0]), sc)
        travelled += float(s[0])
    assert v[0] == 0.0 and math.isclose(travelled, 40.0 ** 2 / 6.0)
    v = np.array([39.98])
    v, s = seed000._move(v, np.array([0.0]), sc)     # traction stops at the line speed
    assert v[0] == 40.0 and 3.998 < s[0] < 4.0


def test_noise_and_scenario_parameters_reach_the_monitor():
    noisy = Scenario("noisy", "test", noise_sigma_m=30.0)
    run = simulate(noisy, 40, 60.0, seed=2)
    m = run.metrics
    mean = m["noise_sum"] / m["noise_n"]
    sd = math.sqrt(m["noise_sq"] / m["noise_n"] - mean ** 2)
    assert abs(sd - 30.0) < 1.5
    present = run.trace["present"]
    assert (run.trace["distance_dm"][present] <= 60000).all() and (run.trace["distance_dm"] >= 0).all()
