"""Physical sense of the derived models (monitor/offline/models, pomdp.py, params.py, risk.py)."""
from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from monitor.offline.models import load, model1, model2
from monitor.offline.params import ConfigError
from monitor.offline.pomdp import POMDP, ModelError
from monitor.offline.risk import r1_logistic, r2_linear, risk_category, risk_score

TOL = 1e-12


# ------------------------------------------------------------------ POMDP validation


def small_model(**changes) -> POMDP:
    """Two states, two actions, two observations; distinct names so messages can be checked."""
    args = dict(
        name="toy",
        states=("s-alpha", "s-beta"),
        actions=("act-x", "act-y"),
        observations=("obs-p", "obs-q"),
        T=np.array([[[0.9, 0.1], [0.2, 0.8]], [[0.5, 0.5], [0.3, 0.7]]]),
        O=np.array([[[0.6, 0.4], [0.1, 0.9]], [[0.5, 0.5], [0.25, 0.75]]]),
        R=np.array([[1.0, -1.0], [0.0, 2.0]]),
        discount=0.9,
        b0=np.array([0.5, 0.5]),
    )
    args.update(changes)
    return POMDP(**args)


def test_valid_small_model_is_accepted_and_read_only():
    m = small_model()
    assert m.shape == (2, 2, 2)
    with pytest.raises(ValueError):
        m.T[0, 0, 0] = 0.5  # arrays are frozen


def test_transition_row_not_summing_to_one_names_action_and_state():
    T = np.array([[[0.9, 0.1], [0.2, 0.8]], [[0.5, 0.5], [0.3, 0.6]]])  # act-y, s-beta sums to 0.9
    with pytest.raises(ModelError) as info:
        small_model(T=T)
    msg = str(info.value)
    assert "act-y" in msg and "s-beta" in msg
    assert "act-x" not in msg and "s-alpha" not in msg
    assert "T[" in msg


def test_observation_row_not_summing_to_one_names_action_and_state():
    O = np.array([[[0.6, 0.4], [0.1, 0.95]], [[0.5, 0.5], [0.25, 0.75]]])  # act-x, s-beta
    with pytest.raises(ModelError) as info:
        small_model(O=O)
    msg = str(info.value)
    assert "act-x" in msg and "s-beta" in msg and "O[" in msg
    assert "act-y" not in msg


def test_negative_probability_is_refused_even_if_row_sums_to_one():
    T = np.array([[[1.5, -0.5], [0.2, 0.8]], [[0.5, 0.5], [0.3, 0.7]]])
    with pytest.raises(ModelError, match="negative"):
        small_model(T=T)


@pytest.mark.parametrize("field", ["T", "O", "R", "b0"])
def test_nan_is_refused(field):
    arr = np.array(getattr(small_model(), field), dtype=float)
    arr.flat[0] = np.nan
    with pytest.raises(ModelError, match=field):
        small_model(**{field: arr})


def test_infinite_reward_is_refused():
    with pytest.raises(ModelError):
        small_model(R=np.array([[np.inf, 0.0], [0.0, 0.0]]))


@pytest.mark.parametrize(
    "field, value",
    [
        ("T", np.full((2, 2, 3), 1.0 / 3)),
        ("T", np.full((2, 2), 0.5)),
        ("O", np.full((2, 3, 2), 0.5)),
        ("R", np.zeros((2, 3))),
        ("R", np.zeros((3, 2))),
        ("b0", np.array([1.0, 0.0, 0.0])),
    ],
)
def test_wrong_shape_is_refused(field, value):
    with pytest.raises(ModelError, match="shape"):
        small_model(**{field: value})


@pytest.mark.parametrize("discount", [1.0, 1.5, -0.1, float("nan")])
def test_discount_outside_unit_interval_is_refused(discount):
    with pytest.raises(ModelError):
        small_model(discount=discount)


def test_start_belief_must_sum_to_one_and_names_must_be_unique():
    with pytest.raises(ModelError):
        small_model(b0=np.array([0.6, 0.6]))
    with pytest.raises(ModelError, match="duplicate"):
        small_model(states=("same", "same"))


# ------------------------------------------------------------------ Model 1

SAFE, OD, ATC, CRASH = range(4)
MAINTAIN, NOMINAL, EMERGENCY = range(3)


def m1_build(**changes) -> POMDP:
    """Model 1 on the paper's fixed zones (the kinematics below are checked against its numbers)."""
    return model1.build(replace(model1.Model1Params(zones="paper"), **changes))


def at_least_as_close(T_row: np.ndarray) -> np.ndarray:
    """[P(s' >= k) for k = 1, 2, 3]: probability of ending in a zone at least as close as k."""
    return np.array([T_row[k:].sum() for k in (1, 2, 3)])


def test_model1_names_and_shape():
    m = m1_build()
    assert m.states == ("Safe", "ObstacleDetected", "AboutToCrash", "Crash")
    assert m.actions == ("maintain", "nominal_braking", "emergency_braking")
    assert m.shape == (4, 3, 4)
    assert m.discount == 0.95
    assert np.array_equal(m.b0, [1.0, 0.0, 0.0, 0.0])


def test_model1_rows_are_stochastic():
    m = m1_build()
    assert np.all(m.T >= 0) and np.all(m.O >= 0)
    assert np.allclose(m.T.sum(axis=2), 1.0, atol=1e-12, rtol=0)
    assert np.allclose(m.O.sum(axis=2), 1.0, atol=1e-12, rtol=0)


@pytest.mark.parametrize("speed", [40.0, 25.0])
def test_model1_braking_never_makes_closer_zones_more_likely(speed):
    """First-order stochastic dominance: emergency <= nominal <= maintain for P(s' >= k)."""
    T = m1_build(speed_mps=speed).T
    for s in range(4):
        emer, nom, keep = (at_least_as_close(T[a, s]) for a in (EMERGENCY, NOMINAL, MAINTAIN))
        assert np.all(emer <= nom + TOL), (s, emer, nom)
        assert np.all(nom <= keep + TOL), (s, nom, keep)


def test_model1_braking_lowers_probability_of_getting_closer():
    T = m1_build().T
    for s in range(4):
        closer = [T[a, s, s + 1:].sum() for a in range(3)]
        assert closer[EMERGENCY] <= closer[NOMINAL] + TOL <= closer[MAINTAIN] + 2 * TOL, (s, closer)
    # where an obstacle is ahead and can still come closer, emergency braking strictly helps
    for s in (OD, ATC):
        assert T[EMERGENCY, s, s + 1:].sum() < T[MAINTAIN, s, s + 1:].sum()
    # and maintaining speed really closes in on an obstacle in the emergency zone
    assert T[MAINTAIN, ATC, CRASH] > 0


def test_model1_obstacle_clears_and_appears_independently_of_action():
    T = m1_build().T
    for a in range(3):
        assert np.allclose(T[a, SAFE], T[0, SAFE], atol=TOL)  # appearance does not depend on braking
        assert np.isclose(T[a, CRASH, SAFE], T[0, CRASH, SAFE], atol=TOL)


@pytest.mark.parametrize("f", [0.05, 0.2, 0.5, 0.75])
def test_model1_appearance_rate_matches_obstacle_fraction(f):
    m = m1_build(obstacle_fraction=f)
    p_clear = m.T[MAINTAIN, CRASH, SAFE]        # a collision only ends by clearing
    p_appear = 1.0 - m.T[MAINTAIN, SAFE, SAFE]  # all appearances land within the warning distance
    assert p_clear > 0
    assert p_appear / p_clear == pytest.approx(f / (1.0 - f), rel=1e-9)


@pytest.mark.parametrize("f", [0.2, 0.5])
def test_model1_stationary_obstacle_fraction_under_maintain(f):
    """Under 'maintain' an obstacle never moves beyond d_w, so it leaves only by clearing:
    the long-run fraction of time with an obstacle must be exactly obstacle_fraction."""
    T = m1_build(obstacle_fraction=f).T[MAINTAIN]
    w, v = np.linalg.eig(T.T)
    pi = np.real(v[:, np.argmin(np.abs(w - 1.0))])
    pi = pi / pi.sum()
    assert 1.0 - pi[SAFE] == pytest.approx(f, rel=1e-9)


def test_model1_zero_noise_gives_identity_observations():
    m = m1_build(noise_sigma_m=0.0, false_positive=0.0, missed_detection=0.0)
    for a in range(3):
        assert np.allclose(m.O[a], np.eye(4), atol=1e-12)


def test_model1_observation_diagonal_is_the_most_likely_reading():
    O = m1_build().O
    for a in range(3):
        for s in range(4):
            assert O[a, s].argmax() == s


@pytest.mark.parametrize(
    "changes, strictly_lower",
    [
        (dict(noise_sigma_m=30.0), (OD, ATC, CRASH)),
        (dict(false_positive=0.1), (SAFE,)),
        (dict(missed_detection=0.1), (OD, ATC, CRASH)),
    ],
)
def test_model1_more_noise_lowers_the_diagonal(changes, strictly_lower):
    base = np.diagonal(m1_build().O[0])
    noisy = np.diagonal(m1_build(**changes).O[0])
    assert np.all(noisy <= base + 1e-12), (base, noisy)
    for s in strictly_lower:
        assert noisy[s] < base[s] - 1e-6, (s, base, noisy)


def test_model1_crash_energy_weighting():
    p = model1.Model1Params(zones="paper")
    costs = np.array(p.braking_costs)
    on = m1_build(crash_energy_weighting=True).R
    off = m1_build(crash_energy_weighting=False).R
    crash_on = on[CRASH] + costs   # the Crash penalty itself, braking cost removed
    crash_off = off[CRASH] + costs
    # braking lowers the impact speed, so the crash is less bad, the harder the braking the better
    assert crash_on[EMERGENCY] > crash_on[NOMINAL] > crash_on[MAINTAIN]
    assert crash_on[MAINTAIN] == pytest.approx(p.rewards[CRASH])
    # v^2 - 2 b d averaged over d uniform in [0, alpha2] (no stop before impact at these values)
    v2 = p.speed_mps ** 2
    for a, b in enumerate(p.decelerations_mps2):
        assert crash_on[a] == pytest.approx(p.rewards[CRASH] * (1.0 - b * p.alpha2_m / v2), rel=1e-9)
    assert np.allclose(crash_off, p.rewards[CRASH])
    assert np.array_equal(on[:CRASH], off[:CRASH])  # other states are unaffected
    zero_cost = m1_build(crash_energy_weighting=False, braking_costs=(0.0, 0.0, 0.0)).R
    assert zero_cost[CRASH, EMERGENCY] == zero_cost[CRASH, MAINTAIN] == zero_cost[CRASH, NOMINAL]


def test_model1_rewards_rank_zones_and_charge_braking():
    R = m1_build().R
    for a in range(3):
        assert R[SAFE, a] > R[OD, a] > R[ATC, a] > R[CRASH, a]
    for s in (SAFE, OD, ATC):
        assert R[s, MAINTAIN] > R[s, NOMINAL] > R[s, EMERGENCY]


# ------------------------------------------------------------------ parameter overrides


def write_toml(tmp_path, text: str):
    path = tmp_path / "cfg.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_toml_override_changes_params_and_transitions(tmp_path):
    default_model, _ = load("m1", write_toml(tmp_path, 'zones = "paper"\n'))
    model, plan = load("m1", write_toml(tmp_path, 'zones = "paper"\nalpha1_m = 400.0\n'))
    assert model.params["alpha1_m"] == 400.0
    assert default_model.params["alpha1_m"] == 300.0
    assert model.params["alpha2_m"] == default_model.params["alpha2_m"]
    assert not np.allclose(model.T, default_model.T)
    # a larger alpha1 makes the emergency zone longer: leaving it downwards is slower
    assert model.T[MAINTAIN, ATC, CRASH] < default_model.T[MAINTAIN, ATC, CRASH]


def test_toml_integer_value_for_float_parameter_is_accepted(tmp_path):
    model, _ = load("m1", write_toml(tmp_path, 'zones = "paper"\nalpha1_m = 400\n'))
    assert model.params["alpha1_m"] == 400.0 and isinstance(model.params["alpha1_m"], float)


def test_toml_solver_table_sets_plan(tmp_path):
    _, plan = load("m1", write_toml(tmp_path, "[solver]\nmax_iterations = 7\nseed = 3\nmax_nodes = 9\n"))
    assert plan.settings.max_iterations == 7 and plan.settings.seed == 3 and plan.max_nodes == 9


def test_toml_unknown_key_names_the_key(tmp_path):
    with pytest.raises(ConfigError, match="alpha3_m"):
        load("m1", write_toml(tmp_path, "alpha3_m = 1.0\n"))


def test_toml_unknown_solver_key_names_the_key(tmp_path):
    with pytest.raises(ConfigError, match="max_iteration"):
        load("m1", write_toml(tmp_path, "[solver]\nmax_iteration = 3\n"))


@pytest.mark.parametrize(
    "text, key",
    [
        ('alpha1_m = "far"\n', "alpha1_m"),
        ("crash_energy_weighting = 1\n", "crash_energy_weighting"),
        ("alpha1_m = true\n", "alpha1_m"),
        ("rewards = [1.0, 2.0]\n", "rewards"),
        ("[solver]\nwarning_confirmation = -1\n", "warning_confirmation"),
        ("[solver]\nwarning_confirmation = 1.5\n", "warning_confirmation"),
    ],
)
def test_toml_wrong_type_is_refused(tmp_path, text, key):
    with pytest.raises(ConfigError, match=key):
        load("m1", write_toml(tmp_path, text))


@pytest.mark.parametrize("alpha2", [300.0, 350.0])
def test_alpha2_not_below_alpha1_is_a_model_error(tmp_path, alpha2):
    with pytest.raises(ModelError, match="alpha2_m"):
        load("m1", write_toml(tmp_path, f'zones = "paper"\nalpha2_m = {alpha2}\n'))


def test_malformed_toml_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="malformed"):
        load("m1", write_toml(tmp_path, "alpha1_m = = 3\n"))


def test_missing_config_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError):
        load("m1", tmp_path / "nope.toml")


# ------------------------------------------------------------------ Model 2

DIST, SPEED, OBST, TRACK, BRAKE = range(5)


def m2_build(**changes) -> POMDP:
    return model2.build(replace(model2.Model2Params(), **changes))


def distance_marginal(T_row: np.ndarray) -> np.ndarray:
    """P(next distance level) from a row over the 144 states."""
    return T_row.reshape(model2.DIMS).sum(axis=(1, 2, 3, 4))


def test_model2_has_144_unique_states(m2):
    model, _ = m2
    assert model.shape == (144, 3, 144)
    assert len(set(model.states)) == 144
    assert model.observations == model.states
    assert model.actions == ("maintain", "nominal_braking", "emergency_braking")
    # the state index order is the component order (last component fastest)
    tuples = model2.state_tuples()
    assert len(tuples) == 144 and len(set(tuples)) == 144
    assert model.states[0] == model2.state_name(tuples[0])
    assert all(model.states[i] == model2.state_name(t) for i, t in enumerate(tuples))


def test_model2_rows_are_stochastic(m2):
    model, _ = m2
    assert np.all(model.T >= 0) and np.all(model.O >= 0)
    assert np.allclose(model.T.sum(axis=2), 1.0, atol=1e-12, rtol=0)
    assert np.allclose(model.O.sum(axis=2), 1.0, atol=1e-12, rtol=0)
    assert np.isclose(model.b0.sum(), 1.0)


def test_model2_observation_is_product_of_component_confusions(m2):
    """Eq. 9 per component, components independent: P(o | s) = prod_i c_i(o_i | s_i)."""
    model, _ = m2
    eps = model2.Model2Params().misperception
    tuples = model2.state_tuples()
    expected = np.ones((144, 144))
    for i, s in enumerate(tuples):
        for j, o in enumerate(tuples):
            for c, (si, oi) in enumerate(zip(s, o)):
                expected[i, j] *= (1.0 - eps[c]) if si == oi else eps[c] / (model2.DIMS[c] - 1)
    for a in range(3):
        assert np.allclose(model.O[a], expected, atol=1e-15, rtol=1e-12)
    assert np.allclose(np.diagonal(model.O[0]), np.prod([1.0 - e for e in eps]))


def test_model2_zero_misperception_gives_identity():
    m = m2_build(misperception=(0.0, 0.0, 0.0, 0.0, 0.0))
    for a in range(3):
        assert np.array_equal(m.O[a], np.eye(144))


def test_model2_more_misperception_lowers_the_diagonal():
    base = np.diagonal(m2_build().O[0])
    more = np.diagonal(m2_build(misperception=(0.1, 0.05, 0.05, 0.02, 0.01)).O[0])
    assert np.all(more < base)


def test_model2_braking_never_makes_a_closer_distance_more_likely(m2):
    model, _ = m2
    T = model.T
    strict = 0
    for i, s in enumerate(model2.state_tuples()):
        d = s[DIST]
        marg = [distance_marginal(T[a, i]) for a in range(3)]
        closer = [m[d + 1:].sum() for m in marg]
        assert closer[EMERGENCY] <= closer[NOMINAL] + TOL, (model.states[i], closer)
        assert closer[NOMINAL] <= closer[MAINTAIN] + TOL, (model.states[i], closer)
        for k in range(1, 4):  # stochastic dominance over the distance level
            assert marg[EMERGENCY][k:].sum() <= marg[NOMINAL][k:].sum() + TOL
            assert marg[NOMINAL][k:].sum() <= marg[MAINTAIN][k:].sum() + TOL
        strict += closer[EMERGENCY] < closer[MAINTAIN] - 1e-9
    assert strict > 0


def closer_under(model: POMDP, a: int, levels: tuple) -> float:
    i = model2.state_tuples().index(levels)
    d = levels[DIST]
    return float(distance_marginal(model.T[a, i])[d + 1:].sum())


@pytest.mark.parametrize("component", [TRACK, BRAKE])
def test_model2_slippery_track_or_degraded_brakes_weaken_braking(component):
    """On the paper's zones (where emergency braking on good rails just escapes the close
    zone) adverse conditions must make the obstacle come closer."""
    model = model2.build(model2.Model2Params(zones="paper"))
    strict = 0
    for s in model2.state_tuples():
        if s[component] != 0:
            continue
        bad = tuple(1 if c == component else x for c, x in enumerate(s))
        for a in (NOMINAL, EMERGENCY):
            good_p, bad_p = closer_under(model, a, s), closer_under(model, a, bad)
            assert bad_p >= good_p - TOL, (s, a, good_p, bad_p)
            strict += bad_p > good_p + 1e-9
        # without braking the track and the brakes make no difference to the distance
        assert closer_under(model, MAINTAIN, bad) == pytest.approx(closer_under(model, MAINTAIN, s), abs=TOL)
    assert strict > 0
    # a fast obstacle in the close zone: emergency braking on good rails and brakes is the best case
    s = (2, 2, 0, 0, 0)
    bad = tuple(1 if c == component else x for c, x in enumerate(s))
    assert closer_under(model, EMERGENCY, bad) > closer_under(model, EMERGENCY, s)


def paper_reward(cat: int, a: int) -> float:
    """Eq. 10 of seed 001 as printed."""
    if cat == 1:
        return 0.0
    if cat == 2:
        return -5.0 if a != EMERGENCY else 0.0
    if cat == 3:
        return -20.0 if a != NOMINAL else 0.0
    return -100.0 if a != EMERGENCY else 0.0


def test_model2_paper_reward_follows_eq10_as_printed():
    m = m2_build(reward="paper")
    cats = set()
    for i, s in enumerate(model2.state_tuples()):
        cat = risk_category(risk_score(*s))
        cats.add(cat)
        for a in range(3):
            assert m.R[i, a] == paper_reward(cat, a), (m.states[i], cat, a, m.R[i, a])
    assert cats == {1, 2, 3, 4}


def test_model2_corrected_reward_answers_risk_with_braking():
    model = m2_build(reward="corrected")
    seen = set()
    for i, s in enumerate(model2.state_tuples()):
        cat = risk_category(risk_score(*s))
        R = model.R[i]
        if cat == 4:
            assert R[MAINTAIN] < R[EMERGENCY], model.states[i]
            assert R[MAINTAIN] < R[NOMINAL] < R[EMERGENCY] + TOL, model.states[i]
        if cat == 1:
            assert R[EMERGENCY] < R[MAINTAIN], model.states[i]
            assert R[MAINTAIN] == R.max(), model.states[i]
        seen.add(cat)
    assert {1, 4} <= seen
    # at every level, the best response penalises less than doing nothing at critical risk
    by_cat = {c: model.R[[risk_category(risk_score(*s)) == c for s in model2.state_tuples()]] for c in seen}
    worst_maintain = [by_cat[c][:, MAINTAIN].min() for c in sorted(seen)]
    assert worst_maintain == sorted(worst_maintain, reverse=True)


def test_model2_corrected_reward_has_increasing_differences_in_risk():
    """Issue 11: the gain of braking harder never shrinks as the risk category rises, so a
    higher category (adverse conditions add to rho) never makes a weaker response better now.
    Eq. 10 as printed lacks this (high risk prefers nominal, critical emergency)."""
    for rows, increasing in ((model2.CORRECTED_REWARD, True), (model2.CORRECTED_REWARD[::-1], False)):
        gains = [[r[a2] - r[a] for r in rows] for a, a2 in ((0, 1), (1, 2), (0, 2))]
        assert all(g == sorted(g) for g in gains) is increasing
    paper = [[m2_build(reward="paper").R[i] for i, s in enumerate(model2.state_tuples())
              if risk_category(risk_score(*s)) == c][0] for c in (1, 2, 3, 4)]
    assert [r[EMERGENCY] - r[NOMINAL] for r in paper] != sorted(r[EMERGENCY] - r[NOMINAL] for r in paper)


def test_model2_fully_observed_optimum_never_brakes_less_under_adverse_conditions(m2):
    """The model itself has no term that makes braking less worth it under slippery track or
    degraded brakes: with the state known, the optimal action never falls when they turn adverse."""
    model, _ = m2
    V = np.zeros(144)
    for _ in range(2000):
        Q = model.R.T + model.discount * model.T @ V      # (A, S)
        V = Q.max(axis=0)
    best = Q.argmax(axis=0)
    index = {s: i for i, s in enumerate(model2.state_tuples())}
    for (d, r, o, k, b), i in index.items():
        for k2, b2 in itertools.product(range(k, 2), range(b, 2)):
            assert best[index[(d, r, o, k2, b2)]] >= best[i], (model.states[i], k2, b2)
    assert len(set(best.tolist())) == 3


def test_model2_unknown_reward_variant_is_a_model_error(tmp_path):
    with pytest.raises(ModelError, match="bogus"):
        m2_build(reward="bogus")
    with pytest.raises(ModelError, match="bogus"):
        load("m2", write_toml(tmp_path, 'reward = "bogus"\n'))


def test_model2_start_belief_is_far_with_every_track_and_brake_combination(m2):
    """Issue 11: the obstacle starts far, type and speed from the priors, and each of the four
    (track, brake) combinations weighs a quarter, so the solved value weighs adverse conditions."""
    model, _ = m2
    p = model2.Model2Params()
    assert p.start_conditions == "any"
    b = model.b0.reshape(model2.DIMS)
    assert b[1:].sum() == 0.0
    for k, br in itertools.product(range(2), range(2)):
        assert np.allclose(b[0, :, :, k, br], np.outer(p.speed_prior, p.obstacle_prior) / 4, atol=1e-15)


def test_model2_normal_start_conditions_give_the_belief_before_issue_11():
    b = m2_build(start_conditions="normal").b0.reshape(model2.DIMS)
    p = model2.Model2Params()
    assert np.allclose(b[0, :, :, 0, 0], np.outer(p.speed_prior, p.obstacle_prior), atol=1e-15)
    assert b.sum() == pytest.approx(b[0, :, :, 0, 0].sum())


def test_model2_unknown_start_conditions_are_a_model_error(tmp_path):
    with pytest.raises(ModelError, match="start_conditions"):
        m2_build(start_conditions="wet")
    with pytest.raises(ModelError, match="wet"):
        load("m2", write_toml(tmp_path, 'start_conditions = "wet"\n'))


# ------------------------------------------------------------------ risk functions


def test_risk_score_weights():
    assert risk_score(0, 0, 0, 0, 0) == 0
    units = [tuple(1 if i == j else 0 for i in range(5)) for j in range(5)]
    assert [risk_score(*u) for u in units] == [3, 2, 2, 1, 2]
    assert risk_score(3, 2, 2, 1, 1) == 3 * 3 + 2 * 2 + 2 * 2 + 1 + 2
    for s in itertools.product(range(4), range(3), range(3), range(2), range(2)):
        assert risk_score(*s) == 3 * s[0] + 2 * s[1] + 2 * s[2] + s[3] + 2 * s[4]


@pytest.mark.parametrize(
    "score, cat",
    [(0, 1), (7, 1), (8, 2), (11, 2), (12, 3), (15, 3), (16, 4), (20, 4)],
)
def test_risk_category_boundaries(score, cat):
    assert risk_category(score) == cat


def test_r2_linear_is_clipped_to_unit_interval():
    a1, a2 = 300.0, 100.0
    assert r2_linear(a1, a1, a2) == 0.0
    assert r2_linear(a2, a1, a2) == 1.0
    assert r2_linear(200.0, a1, a2) == pytest.approx(0.5)
    assert r2_linear(1000.0, a1, a2) == 0.0
    assert r2_linear(0.0, a1, a2) == 1.0
    assert r2_linear(-50.0, a1, a2) == 1.0
    values = [r2_linear(d, a1, a2) for d in np.linspace(-100, 1000, 221)]
    assert all(0.0 <= v <= 1.0 for v in values)
    assert all(x >= y for x, y in zip(values, values[1:]))


def test_r1_logistic_decreases_with_distance():
    a1 = 300.0
    d = np.linspace(0.0, 1000.0, 201)
    r = np.array([r1_logistic(x, a1) for x in d])
    assert np.all(np.diff(r) < 0)
    assert np.all((r > 0) & (r <= 0.5 + 1e-15))
    assert r1_logistic(0.0, a1) == pytest.approx(0.5)
    assert r1_logistic(a1, a1) == pytest.approx(1.0 - 1.0 / (1.0 + np.exp(-5.0)))


# ------------------------------------------------------------------ the monitor's zones (issue 12)

def test_model1_zones_are_the_monitors_braking_curves():
    """Model 1's zone limits are what the monitor cuts at the model's speed: alpha2 = EBI,
    alpha1 = the service brake's EBI, warning = Config.warning_margin_dm beyond alpha1."""
    from monitor.core.braking import ebi_dm
    from monitor.core.config import Config

    cfg = Config()
    p = model1.Model1Params()
    v = int(p.speed_mps * 100)
    assert model1.zone_edges(p) == [0.0, ebi_dm(cfg, v, 0, 0, v, 0) / 10, ebi_dm(cfg, v, 0, 0, v, 0, True) / 10,
                                    ebi_dm(cfg, v, 0, 0, v, 0, True) / 10 + cfg.warning_margin_dm / 10]
    alpha1, alpha2, slope1, slope2, _ = model1.geometry(p)
    # the slope is the curve's growth per m/s: EBI grows faster than v / a (latencies, margins)
    assert slope2 > p.speed_mps / 2.4 and slope1 > slope2
    T = m1_build(zones="monitor")
    # with the monitor's zones emergency braking at the nominal 3 m/s^2 escapes EBI, maintaining does not
    assert T.T[EMERGENCY, ATC, CRASH] == 0.0 < T.T[MAINTAIN, ATC, CRASH]
    assert T.T[NOMINAL, ATC, CRASH] < T.T[MAINTAIN, ATC, CRASH]


@pytest.mark.parametrize("name, key", [("m1", "alpha1_m = 400.0"), ("m2", 'zones = "monitor"\ncritical_length_m = 50.0')])
def test_paper_lengths_are_refused_with_the_monitors_zones(tmp_path, name, key):
    with pytest.raises(ModelError, match='zones = "paper"'):
        load(name, write_toml(tmp_path, key + "\n"))


def test_model2_levels_are_the_monitors_zones():
    from monitor.offline.models.zones import monitor_zones

    alpha1, alpha2, s1, s2, warning = monitor_zones(40.0)
    assert model2.geometry(model2.Model2Params(zones="monitor")) == (alpha2, alpha1 - alpha2, warning, s1, s2)
    assert model2.Model2Params().zones == "monitor"     # since issue 12: its table earns its place there


def test_model2_hazard_reward_prices_the_hazard_and_the_braking(m2):
    """Reward "hazard" (the default since issue 12) charges what the tables are judged by: a
    step in the critical level (the hazard) whatever is done, and elsewhere the deceleration
    demanded, dearer with the obstacle beyond the warning zone (unnecessary braking) than for
    one within it. Weights scale each part; maintaining is free outside the hazard."""
    model, _ = m2
    p = model2.Model2Params()
    assert model.params["reward"] == "hazard"
    decel = np.array(p.decelerations_mps2)
    for i, s in enumerate(model2.state_tuples()):
        if s[DIST] == 3:
            assert np.all(model.R[i] == -model2.HAZARD_COST * p.collision_weight), model.states[i]
        else:
            per = p.far_braking_cost if s[DIST] == 0 else p.near_braking_cost
            assert np.allclose(model.R[i], -per * decel), model.states[i]
    assert p.far_braking_cost > p.near_braking_cost > 0
    heavy = m2_build(collision_weight=2.0, braking_weight=3.0)
    assert np.allclose(heavy.R[model.R[:, 0] < 0], 2.0 / p.collision_weight * model.R[model.R[:, 0] < 0])
    assert np.allclose(heavy.R[model.R[:, 0] == 0], 3.0 * model.R[model.R[:, 0] == 0])
    with pytest.raises(ModelError, match="far_braking_cost"):
        m2_build(far_braking_cost=-1.0)


def test_release_cost_is_charged_by_controllers_not_by_the_model(tmp_path):
    """release_cost reaches the POMDP (and its digest), not its rewards, and is charged
    only when the controller lowers its demand."""
    from monitor.offline.controller import Controller, evaluate
    from monitor.offline.pipeline import model_digest

    plain = m1_build(release_cost=0.0)
    costly = m1_build(release_cost=3.0)
    assert costly.release_cost == 3.0 and np.array_equal(costly.R, plain.R)
    assert model_digest(costly) != model_digest(plain)
    steady = Controller(np.array([1]), np.zeros((1, 4), dtype=np.int64), 0)
    toggling = Controller(np.array([0, 2]), np.array([[1] * 4, [0] * 4]), 0)
    assert np.allclose(evaluate(costly, steady), evaluate(plain, steady))          # never lowers: no cost
    V0, V1 = evaluate(plain, toggling), evaluate(costly, toggling)
    g = plain.discount
    # node 1 (emergency) lowers to node 0 every time: g c now and every second step after;
    # node 0 only raises (free) and pays from its next step on
    assert np.allclose(V0[1] - V1[1], g * 3.0 / (1 - g * g))
    assert np.allclose(V0[0] - V1[0], g * g * 3.0 / (1 - g * g))
