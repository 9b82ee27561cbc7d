"""`railguard verify`, seed 001 part: the paper's three metrics with the m2 table in the loop."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from monitor.offline.risk import risk_category, risk_score
from verification import seed001
from verification.fastcore import agrees_with_core
from verification.seed001 import (
    BeliefFilter, Settings, calibrated_gap_s, expected_obstacle_fraction, load_setup, mean_reward, risk_accuracy,
    risk_categories, simulate, state_components, state_index, time_with_obstacles,
)

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def quick_section(tmp_path_factory):
    out = tmp_path_factory.mktemp("seed001")
    messages = []
    sec = seed001.section(out, True, messages.append)
    return out, sec, messages


@pytest.fixture(scope="module")
def setup_model():
    return load_setup()


def test_quick_section_passes_and_writes_its_figures(quick_section):
    out, sec, messages = quick_section
    failed = [c.line() for c in sec.checks if not c.passed]
    assert not failed, failed
    names = " ".join(c.name for c in sec.checks)
    for needed in ("agrees with the core", "train-seconds", "time with obstacles", "supervision and latch", "impact"):
        assert needed in names
    assert "seed001_metrics.png" in sec.figures
    for fig in sec.figures:
        assert (out / fig).read_bytes()[:8] == PNG
        assert f"]({fig})" in sec.markdown
    for number in ("75.0 %", "96.3 %", "-3.19"):
        assert number in sec.markdown
    assert messages, "progress was never reported"


def test_quick_section_simulates_enough_and_replays_twenty_trains(quick_section):
    _, sec, _ = quick_section
    by_name = {c.name: c for c in sec.checks}
    agree = by_name["seed001: vectorised monitor agrees with the core"]
    assert agree.details["trains"] >= 20 and agree.details["cycles"] >= 20 * 3000
    assert by_name["seed001: train-seconds simulated"].details["main"] >= 50_000
    inv = by_name["seed001: supervision and latch hold on every step"].details
    assert inv["env_steps"] > 1000 and inv["latch_releases"] > 100 and inv["latch_steps"] > inv["latch_releases"]


def test_vectorised_run_agrees_with_the_core_and_the_comparison_can_fail(setup_model):
    setup, _, _ = setup_model
    run = simulate(Settings(trains=144, steps=300, record=20, belief_trains=0))
    ok, cycles = agrees_with_core(setup, run.trace, 20)
    assert ok and cycles == 20 * 300
    # trains with an obstacle in every distance level are among the replayed ones
    assert len(set(run.trace["observation"].ravel() // 36)) == 4
    bad = {k: v.copy() for k, v in run.trace.items()}
    bad["demand"][150, 7] = (bad["demand"][150, 7] + 1) % 3
    assert agrees_with_core(setup, bad, 20)[0] is False
    bad = {k: v.copy() for k, v in run.trace.items()}
    bad["warning"][:, 3] = ~bad["warning"][:, 3].astype(bool)           # the warning output is compared too
    assert agrees_with_core(setup, bad, 20)[0] is False


def test_metrics_on_a_hand_made_trace():
    present = np.array([[1, 0], [1, 1], [0, 0], [1, 0]], dtype=bool)       # (time, train)
    assert time_with_obstacles(present) == pytest.approx(50.0)
    assert time_with_obstacles(np.ones(7, dtype=bool)) == 100.0
    true = np.array([0, 1, 2, 3, 4, 4])
    est = np.array([0, 1, 3, 3, 2, 4])
    assert risk_accuracy(true, est) == pytest.approx(400 / 6)
    assert risk_accuracy(true, est, mask=true > 0) == pytest.approx(300 / 5)
    assert mean_reward(np.array([0.0, -5.0, -20.0, 0.0])) == pytest.approx(-6.25)


def test_risk_categories_and_state_index_match_eq_11_and_the_core():
    for levels in itertools.product(range(4), range(3), range(3), range(2), range(2)):
        i = state_index(*levels)
        assert tuple(int(c) for c in state_components(i)) == levels
        assert int(risk_categories(*levels)) == risk_category(risk_score(*levels))
    assert sorted(state_index(*np.array(list(itertools.product(range(4), range(3), range(3), range(2), range(2)))).T)) == list(range(144))


def test_obstacle_process_is_calibrated_to_75_percent():
    dt, durations, prior = 0.1, (60.0, 10.0, 30.0), (0.5, 0.3, 0.2)
    gap = calibrated_gap_s(3000, dt, durations, prior)
    assert expected_obstacle_fraction(3000, dt, durations, prior, gap) == pytest.approx(75.0, abs=1e-6)
    # long run: the share tends to E[D] / (E[D] + gap) = 39 / 52 for a mean gap of 13 s
    assert expected_obstacle_fraction(100_000, dt, durations, prior, 13.0) == pytest.approx(75.0, abs=0.1)


def test_perfect_perception_gives_full_accuracy_and_eq_9_rates_show():
    perfect = simulate(Settings(trains=144, steps=400, misperception=(0.0,) * 5, belief_trains=0))
    assert perfect.metrics["accuracy_picture"] == 100.0
    assert perfect.metrics["observation_wrong_share"] == 0.0
    noisy = simulate(Settings(trains=144, steps=400, belief_trains=0))
    expected = 100.0 * (1 - np.prod([1 - e for e in (0.02, 0.05, 0.05, 0.02, 0.01)]))   # 14.2 %
    assert noisy.metrics["observation_wrong_share"] == pytest.approx(expected, abs=1.0)
    assert noisy.metrics["accuracy_picture"] < 99.0


def test_same_seed_same_metrics_other_seed_other_metrics():
    a = simulate(Settings(trains=144, steps=300, belief_trains=144))
    b = simulate(Settings(trains=144, steps=300, belief_trains=144))
    c = simulate(Settings(trains=144, steps=300, belief_trains=144, seed=2))
    assert a.metrics == b.metrics and a.collisions == b.collisions
    assert np.array_equal(a.trace["node"], b.trace["node"])
    assert a.metrics != c.metrics


def test_belief_filter_matches_the_dense_bayes_update(setup_model):
    _, _, model = setup_model
    rng = np.random.default_rng(5)
    n = 7
    filt = BeliefFilter(model, n, chunk=3)
    dense = np.tile(model.b0, (n, 1))
    action = np.zeros(n, dtype=np.int64)
    for k in range(12):
        obs = rng.integers(0, 144, n)
        if k:
            dense = np.stack([dense[i] @ model.T[action[i]] for i in range(n)])
        dense = dense * model.O[0][:, obs].T
        dense /= dense.sum(axis=1, keepdims=True)
        best = filt.step(action, obs)
        flat = filt.b.transpose(1, 2, 0).reshape(n, 144)
        np.testing.assert_allclose(flat, dense, atol=1e-12)
        assert np.array_equal(best, np.argmax(dense, axis=1))
        action = rng.integers(0, 3, n)
