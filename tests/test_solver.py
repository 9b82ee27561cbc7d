"""HSVI/PBVI/Perseus, the fast informed and sawtooth upper bounds, controller compilation and exact evaluation."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import independent_values
from monitor.core import table as table_format
from monitor.offline import pipeline
from monitor.offline.controller import Controller, evaluate, minimise, occupancy, reachable, value_at
from monitor.offline.layered import (
    ConditionLayer, Layered, action_values, compile_monotone, edge_values, fixed_edge_q, improve_layered, raise_monotone,
)
from monitor.offline.hysteresis import with_last_demand
from monitor.offline.models import Plan
from monitor.offline.table_view import render
from monitor.offline.params import ConfigError
from monitor.offline.bounds import Dynamics, UpperBound, upper_backup
from monitor.offline.solver import METHODS, SolverSettings, fast_informed_bound, solve
from verification.monotone import check as monotone_check

TIGER_VALUE = 19.37  # optimal discounted value of Tiger at the uniform belief (g = 0.95)


def value_at_start(model, ctrl: Controller) -> float:
    return float(evaluate(model, ctrl)[ctrl.start] @ model.b0)


def mdp_q(model, tol: float = 1e-10) -> np.ndarray:
    """Q of the fully observable MDP (value iteration, written independently)."""
    S, A, _ = model.shape
    Q = np.zeros((A, S))
    for _ in range(100000):
        V = Q.max(axis=0)
        Qn = model.R.T + model.discount * np.einsum("ast,t->as", model.T, V)
        if np.abs(Qn - Q).max() < tol:
            return Qn
        Q = Qn
    raise AssertionError("MDP value iteration did not converge")


def simulate(model, ctrl: Controller, episodes: int, horizon: int, seed: int) -> np.ndarray:
    """Discounted returns of the closed loop, sampled with numpy (vectorised over episodes)."""
    rng = np.random.default_rng(seed)
    S, _, Z = model.shape
    cumT = np.cumsum(model.T, axis=2)
    cumO = np.cumsum(model.O, axis=2)
    s = np.minimum(np.searchsorted(np.cumsum(model.b0), rng.random(episodes), side="right"), S - 1)
    n = np.full(episodes, ctrl.start)
    ret = np.zeros(episodes)
    disc = 1.0
    for _ in range(horizon):
        a = ctrl.action[n]
        ret += disc * model.R[s, a]
        disc *= model.discount
        s = np.minimum((rng.random(episodes)[:, None] > cumT[a, s]).sum(axis=1), S - 1)
        o = np.minimum((rng.random(episodes)[:, None] > cumO[a, s]).sum(axis=1), Z - 1)
        n = ctrl.next[n, o]
    return ret


# ------------------------------------------------------------------ Tiger


def test_tiger_controller_reaches_the_known_optimum(tiger, tiger_solved):
    sol, comp = tiger_solved
    assert comp.value == pytest.approx(TIGER_VALUE, abs=0.01)
    assert sol.lower_bound <= sol.upper_bound
    assert comp.value <= sol.upper_bound + 1e-9
    # the lower bound is the value of the alpha vectors at b0: a valid bound on the optimum
    assert sol.lower_bound <= TIGER_VALUE + 0.01
    assert sol.lower_bound == pytest.approx(float((sol.alphas @ tiger.b0).max()))
    # the number reported is the exact value of the shipped controller
    assert comp.value == pytest.approx(value_at_start(tiger, comp.controller), abs=1e-9)
    assert comp.controller.start == 0


def test_tiger_controller_listens_before_opening(tiger, tiger_solved):
    _, comp = tiger_solved
    ctrl = comp.controller
    listen = tiger.actions.index("listen")
    assert ctrl.action[ctrl.start] == listen
    # after one 'tiger-left' and one 'tiger-right' the belief is back at uniform: never open then
    left, right = tiger.observations.index("tiger-left"), tiger.observations.index("tiger-right")
    n = ctrl.next[ctrl.next[ctrl.start, left], right]
    assert ctrl.action[n] == listen


def test_fast_informed_bound_is_an_upper_bound(tiger, tiger_solved):
    sol, comp = tiger_solved
    Q = fast_informed_bound(tiger)
    assert np.allclose(Q, sol.upper_q)
    assert float((Q @ tiger.b0).max()) >= comp.value
    # the sawtooth points tighten it: the reported bound is below the FIB, above the controller
    assert comp.value - 1e-9 <= sol.upper_bound <= float((Q @ tiger.b0).max()) - 1.0
    # V*(e_s) <= max_a Q(a, s), and every controller node is <= V*
    assert np.all(comp.values <= Q.max(axis=0)[None, :] + 1e-9)


@pytest.mark.parametrize("name", ["tiger", "m1"])
def test_fast_informed_bound_lies_between_controller_and_mdp(request, name):
    """FIB is never looser than the MDP bound (QMDP) and never below a real policy's value."""
    model = request.getfixturevalue("tiger") if name == "tiger" else request.getfixturevalue("m1")[0]
    Q = fast_informed_bound(model)
    assert np.all(Q <= mdp_q(model) + 1e-6)
    # Q is a fixed point of the FIB backup
    S, A, Z = model.shape
    inner = np.einsum("ast,ato,bt->asob", model.T, model.O, Q)
    assert np.allclose(model.R.T + model.discount * inner.max(axis=3).sum(axis=2), Q, atol=1e-5)


def test_tiger_fast_informed_bound_below_mdp_strictly(tiger):
    """Opening a door is uninformative; FIB must use that, QMDP cannot (200 at every state)."""
    Q = fast_informed_bound(tiger)
    assert np.allclose(mdp_q(tiger).max(axis=0), 10.0 / (1 - 0.95))
    assert float((Q @ tiger.b0).max()) < 150.0


# ------------------------------------------------------------------ exact evaluation


@pytest.mark.parametrize("name", ["tiger", "m1"])
def test_exact_evaluation_matches_an_independent_dense_solve(request, name, tiger_solved, m1_result):
    if name == "tiger":
        model, ctrl = request.getfixturevalue("tiger"), tiger_solved[1].controller
    else:
        model, ctrl = m1_result.model, m1_result.compiled.controller
    V = evaluate(model, ctrl)
    assert np.allclose(V, independent_values(model, ctrl.action, ctrl.next), atol=1e-8, rtol=1e-10)


def test_exact_evaluation_of_a_large_controller_uses_a_converged_solution(m2):
    """Model 2 with 50 nodes (7200 pairs) takes the iterative path: check the Bellman residual
    with an independently written operator, and the value bounds it implies."""
    model, _ = m2
    S, A, Z = model.shape
    rng = np.random.default_rng(5)
    N = 50
    ctrl = Controller(rng.integers(0, A, N), rng.integers(0, N, (N, Z)), 0)
    V = evaluate(model, ctrl)
    assert V.shape == (N, S)
    # (B V)[n, s] = R[s, a_n] + g * sum_s' T[a_n, s, s'] sum_o O[a_n, s', o] (V[next[n, o], s'] - release cost
    # when the next node demands less than n)
    lowered = model.release_cost * (ctrl.action[ctrl.next] < ctrl.action[:, None])                   # (N, Z)
    W = np.stack([(model.O[ctrl.action[n]] * (V[ctrl.next[n]].T - lowered[n])).sum(axis=1) for n in range(N)])  # (N, S')
    BV = model.R[:, ctrl.action].T + model.discount * np.einsum("nst,nt->ns", model.T[ctrl.action], W)
    assert np.abs(BV - V).max() <= 1e-6 * max(1.0, np.abs(model.R).max())
    assert model.release_cost > 0                                    # Model 2 has hysteresis since issue 12
    lo, hi = (model.R.min() - model.release_cost) / (1 - model.discount), model.R.max() / (1 - model.discount)
    assert np.all(V >= lo - 1e-9) and np.all(V <= hi + 1e-9)


def test_exact_value_agrees_with_monte_carlo_model1(m1_result):
    model, comp = m1_result.model, m1_result.compiled
    episodes, horizon = 50000, 400
    # truncation bias is at most g^H max|R| / (1 - g): keep it far below the sampling error
    bias = model.discount ** horizon * np.abs(model.R).max() / (1 - model.discount)
    ret = simulate(model, comp.controller, episodes, horizon, seed=20240611)
    se = ret.std(ddof=1) / np.sqrt(episodes)
    assert bias < 0.05 * se
    assert se < 0.05 * abs(comp.value)  # the test has teeth: 3 SE is < 15 % of the value
    assert abs(ret.mean() - comp.value) <= 3 * se, (ret.mean(), comp.value, se)


def test_exact_value_agrees_with_monte_carlo_tiger(tiger, tiger_solved):
    comp = tiger_solved[1]
    episodes, horizon = 20000, 400
    bias = tiger.discount ** horizon * np.abs(tiger.R).max() / (1 - tiger.discount)
    ret = simulate(tiger, comp.controller, episodes, horizon, seed=7)
    se = ret.std(ddof=1) / np.sqrt(episodes)
    assert bias < 0.05 * se
    assert se < 0.05 * abs(comp.value)
    assert abs(ret.mean() - comp.value) <= 3 * se, (ret.mean(), comp.value, se)


# ------------------------------------------------------------------ reachable / minimise


def duplicated(ctrl: Controller) -> Controller:
    """Each node n gets a copy n + N with the same action; edges alternate between originals
    and copies, so the controller behaves exactly like the original."""
    N, Z = ctrl.next.shape
    action = np.concatenate([ctrl.action, ctrl.action])
    nxt = np.zeros((2 * N, Z), dtype=np.int64)
    for n in range(2 * N):
        for o in range(Z):
            target = int(ctrl.next[n % N, o])
            nxt[n, o] = target + N if (n + o) % 2 else target
    return Controller(action, nxt, ctrl.start + N)


def test_minimise_merges_duplicates_and_preserves_value(tiger, tiger_solved):
    ctrl = tiger_solved[1].controller
    value = value_at_start(tiger, ctrl)
    dup = duplicated(ctrl)
    assert value_at_start(tiger, dup) == pytest.approx(value, abs=1e-9)
    small = minimise(dup)
    assert small.nodes == minimise(ctrl).nodes <= ctrl.nodes
    assert small.start == 0
    assert value_at_start(tiger, small) == pytest.approx(value, abs=1e-9)
    assert np.all(small.next < small.nodes)


def test_minimise_keeps_nodes_that_differ_later(tiger, tiger_solved):
    """All listening nodes share an action, but merging them would lose the count of evidence."""
    ctrl = tiger_solved[1].controller
    listen = tiger.actions.index("listen")
    assert int((ctrl.action == listen).sum()) >= 2
    small = minimise(ctrl)
    assert int((small.action == listen).sum()) == int((ctrl.action == listen).sum())
    assert value_at_start(tiger, small) == pytest.approx(value_at_start(tiger, ctrl), abs=1e-9)


def test_reachable_drops_unreachable_nodes_and_preserves_value(tiger, tiger_solved):
    ctrl = tiger_solved[1].controller
    N, Z = ctrl.next.shape
    # two extra nodes nobody points to (one pointing into the controller, one to itself)
    action = np.concatenate([ctrl.action, [2, 1]])
    nxt = np.vstack([ctrl.next, np.zeros((1, Z), dtype=np.int64), np.full((1, Z), N + 1)])
    # renumber so the start is not node 0: swap node 0 with the last unreachable one
    perm = np.arange(N + 2)
    perm[[0, N + 1]] = perm[[N + 1, 0]]
    inv = np.argsort(perm)
    big = Controller(action[perm], inv[nxt[perm]], int(inv[ctrl.start]))
    assert value_at_start(tiger, big) == pytest.approx(value_at_start(tiger, ctrl), abs=1e-9)
    kept = reachable(big)
    assert kept.nodes == N
    assert kept.start == 0
    assert value_at_start(tiger, kept) == pytest.approx(value_at_start(tiger, ctrl), abs=1e-9)
    assert minimise(big).nodes == minimise(ctrl).nodes


# ------------------------------------------------------------------ Model 1


def test_model1_acceptance_controller_within_one_percent_of_lower_bound(m1_result):
    sol, comp = m1_result.solution, m1_result.compiled
    assert sol.lower_bound <= sol.upper_bound
    assert comp.value >= sol.lower_bound - 0.01 * abs(sol.lower_bound)
    assert comp.value <= sol.upper_bound + 1e-9
    # the compiler's budget, and the nodes the warning confirmation puts on its one path
    assert comp.controller.nodes <= m1_result.plan.max_nodes + m1_result.plan.warning_confirmation
    assert np.all(comp.values <= sol.upper_q.max(axis=0)[None, :] + 1e-9)


def test_model1_lower_bound_is_monotone_and_history_consistent(m1_result):
    sol = m1_result.solution
    lowers = [p.lower for p in sol.history]
    uppers = [p.upper for p in sol.history]
    assert lowers == sorted(lowers)
    assert uppers == sorted(uppers, reverse=True)     # the upper bound only tightens
    assert sol.history[-1].lower == sol.lower_bound
    assert sol.history[-1].upper == sol.upper_bound
    assert sol.iterations == len(sol.history)


def test_model1_solving_is_deterministic(m1):
    model, _ = m1
    # 15 HSVI trials: too few for the stall rule (2 x expand_every trials without change) and
    # for a zero gap, so max_iterations stops it
    settings = SolverSettings(target_gap=0.0, time_budget_s=1e9, max_iterations=15, max_beliefs=60,
                              expand_every=10, seed=11)
    plan = Plan(settings, max_nodes=16)
    a, b = pipeline.run(model, plan), pipeline.run(model, plan)
    assert a.solution.stop_reason == b.solution.stop_reason == "max_iterations"
    assert a.solution.alphas.tobytes() == b.solution.alphas.tobytes()
    assert np.array_equal(a.solution.actions, b.solution.actions)
    assert a.solution.witnesses.tobytes() == b.solution.witnesses.tobytes()
    assert a.table == b.table
    assert a.sha256 == b.sha256


def test_model1_table_matches_the_compiled_controller(m1_result):
    t = table_format.decode(m1_result.table, expect_model="m1")
    ctrl = m1_result.compiled.controller
    assert list(t.action) == ctrl.action.tolist()
    assert [list(r) for r in t.next] == ctrl.next.tolist()
    assert t.start == ctrl.start
    assert t.header["controller_value"] == m1_result.compiled.value
    assert t.header["model_sha256"] == pipeline.model_digest(m1_result.model)
    assert t.actions == m1_result.model.actions


# ------------------------------------------------------------------ Model 2 (small settings only)


def test_model2_small_run_respects_bounds_and_node_budget(m2):
    model, plan = m2
    small = Plan(replace(plan.settings, max_iterations=3, max_beliefs=20, expand_every=1), max_nodes=4)
    result = pipeline.run(model, small)
    sol, comp = result.solution, result.compiled
    assert sol.iterations == 3 and sol.stop_reason == "max_iterations"
    assert sol.lower_bound <= sol.upper_bound
    assert comp.value <= sol.upper_bound + 1e-9
    assert comp.controller.nodes <= 4
    assert np.all(comp.controller.next < comp.controller.nodes)
    assert comp.value == pytest.approx(value_at_start(model, comp.controller), abs=1e-9)
    t = table_format.decode(result.table, expect_model="m2")
    assert t.nodes == comp.controller.nodes and len(t.observations) == 144


# ------------------------------------------------------------------ monotone in conditions (issue 11)


def test_condition_layer_of_model2_observations(m2):
    """Memory = the newest (track, brake) report; the base part is (distance, speed, type)."""
    model, plan = m2
    layer = ConditionLayer.of(model.observations, plan.conditions)
    assert plan.conditions == (3, 4) and layer.memories == 4 and layer.bases == 36
    for o, name in enumerate(model.observations):
        parts = name.split("-")
        newest = 2 * (parts[3] == "slippery") + (parts[4] == "degraded")
        assert (layer.step[:, o] == newest).all()
        same_base = [o2 for o2, n2 in enumerate(model.observations) if n2.split("-")[:3] == parts[:3]]
        assert len(same_base) == 4 and {layer.base[o2] for o2 in same_base} == {layer.base[o]}
    # below: (track, brake) componentwise; normal-normal is below everything, nothing is below it but itself
    assert layer.below[0].all() and layer.below[:, 0].tolist() == [True, False, False, False]
    assert not layer.below[1, 2] and not layer.below[2, 1] and layer.below[1, 3] and layer.below[2, 3]
    # raising: each memory demands at least what any memory below it demands
    raised = raise_monotone(np.array([2, 0, 1, 0, 0, 0, 0, 1]), layer)
    assert raised.tolist() == [2, 2, 2, 2, 0, 0, 0, 1]


def test_model2_small_monotone_run_is_monotone_exact_and_within_budget(m2):
    model, plan = m2
    small = replace(plan, settings=replace(plan.settings, max_iterations=3, max_beliefs=20, expand_every=1),
                    max_nodes=16)
    result = pipeline.run(model, small)
    comp = result.compiled
    assert comp.controller.nodes <= 16
    assert comp.value == pytest.approx(value_at_start(model, comp.controller), abs=1e-9)
    assert comp.value <= result.solution.upper_bound + 1e-9
    t = table_format.decode(result.table, expect_model="m2")
    assert t.header["solver"]["monotone_in"] == [3, 4]
    # the information relaxation ran (3 trials, like the model) and the tighter bound is printed
    relaxed = t.header["relaxation"]
    assert relaxed["reveals"] == "speed, type, track and brake read without error" and relaxed["iterations"] == 3
    assert relaxed["model_upper_bound"] == result.solution.upper_bound
    assert t.header["upper_bound"] == result.upper_bound == min(relaxed["upper_bound"], relaxed["model_upper_bound"])
    fig = pipeline.figures(result)
    assert (fig["upper_bound"], fig["relaxation_upper_bound"]) == (result.upper_bound, relaxed["upper_bound"])
    assert comp.value <= result.upper_bound + 1e-9
    shown = render(t).splitlines()
    assert any(line.startswith("upper bound") and "information relaxation" in line for line in shown)
    assert "information relaxation" in pipeline.summary_text(result)
    res = monotone_check(t)
    assert res.monotone, res.describe()
    # one node per reported (track, brake) combination is the least the layering needs
    layer = ConditionLayer.of(model.observations, plan.conditions)
    with pytest.raises(ConfigError, match="at least 4"):
        compile_monotone(model, result.solution, layer, max_nodes=3)


def random_layered(model, plan, bases: int, seed: int) -> Layered:
    """A layered controller of m2 with random base edges and random actions raised to monotone."""
    layer = ConditionLayer.of(model.observations, plan.conditions)
    rng = np.random.default_rng(seed)
    action = raise_monotone(rng.integers(0, 3, bases * layer.memories), layer)
    return Layered(layer, rng.integers(0, bases, (bases, layer.bases)), action, 0)


def test_layered_gains_are_exact_on_the_model_with_the_last_demand_in_the_state(m2):
    """action_values and edge_values, computed on m2 with the release cost charged on the
    edges, equal the same quantities on with_last_demand(m2), where the cost is part of the
    reward: there V_h[n, (p, s)] = V[n, s] - cost * (a_n < p), a node's action value is its
    plain one-step value, and an edge's worth is the value of the mass it sends."""
    model, plan = m2
    assert model.release_cost > 0
    lay = random_layered(model, plan, bases=3, seed=5)
    ctrl, S, A = lay.controller, model.shape[0], model.shape[1]
    hyst = with_last_demand(model)
    V, Vh = evaluate(model, ctrl), evaluate(hyst, ctrl)
    x, xh = occupancy(model, ctrl, iterations=700), occupancy(hyst, ctrl, iterations=700)
    lower = ctrl.action[:, None] < np.arange(A)[None, :]                                  # (N, p): a_n < p
    assert np.allclose(Vh.reshape(-1, A, S), V[:, None, :] - model.release_cost * lower[:, :, None], atol=1e-9)
    assert np.allclose(xh.reshape(-1, A, S).sum(axis=1), x, atol=1e-12)
    seen = x.sum(axis=1) > 1e-6
    assert seen.sum() >= 4
    q = action_values(model, ctrl, V, x)
    qh = fixed_edge_q(hyst, ctrl, Vh, xh / xh.sum(axis=1, keepdims=True).clip(1e-300))
    assert np.allclose(q[seen], qh[seen], rtol=1e-9, atol=1e-9)
    # the arriving release cost matters: without it the values differ
    plain = fixed_edge_q(model, ctrl, V, x / x.sum(axis=1, keepdims=True).clip(1e-300))
    assert np.abs(plain[seen] - qh[seen]).max() > 1e-3
    # edges: worth[m, b, m2] on the hysteresis model, written out per node and observation
    worth = edge_values(model, lay, V, x)
    Q, layer = lay.layer.memories, lay.layer
    expect = np.zeros_like(worth)
    for n in range(ctrl.nodes):
        a, (m, mem) = int(ctrl.action[n]), divmod(n, Q)
        after = (xh[n] @ hyst.T[a])[:, None] * hyst.O[a]
        for o in range(model.shape[2]):
            targets = np.arange(lay.edges.shape[0]) * Q + layer.step[mem, o]
            expect[m, layer.base[o]] += Vh[targets] @ after[:, o]
    assert np.allclose(worth, expect, rtol=1e-9, atol=1e-12)


def test_layered_improvement_raises_the_exact_value_and_keeps_the_layering(m2):
    """From a random layered controller, improve_layered raises the exact value at b0, only
    ever keeps monotone actions, and leaves edges shared by every memory of a base node."""
    model, plan = m2
    lay = random_layered(model, plan, bases=4, seed=7)
    before = value_at(model, lay.controller, evaluate(model, lay.controller))
    lines = []
    better, rounds = improve_layered(model, lay, rounds=3, say=lines.append, deadline=None)
    after = value_at(model, better.controller, evaluate(model, better.controller))
    assert after > before + 1.0 and rounds >= 1 and lines[0].startswith("monotone: round 1, ")
    assert np.array_equal(better.action, raise_monotone(better.action, lay.layer))
    assert better.edges.shape == lay.edges.shape
    t = table_format.encode({"format": "railguard-table", "model": model.name, "states": list(model.states),
                             "actions": list(model.actions), "observations": list(model.observations),
                             "start": better.start}, better.controller.action.tolist(), better.controller.next.tolist())
    assert monotone_check(table_format.decode(t)).monotone


def test_model2_exact_layered_search_is_monotone_exact_and_recorded(m2):
    """`layered_search = "exact"` (railguard solve --layered-search exact): the memory is
    solved with the last demand in the state, the table stays monotone, its exact value is
    at least the layered base's, and the header records the search; a bad value is refused."""
    from monitor.offline.models import plan_from

    model, plan = m2
    small = replace(plan_from({"solver": {"layered_search": "exact"}}, plan),
                    settings=replace(plan.settings, max_iterations=3, max_beliefs=20, expand_every=1), max_nodes=16)
    assert small.layered_search == "exact"
    result = pipeline.run(model, small)
    comp = result.compiled
    assert comp.controller.nodes <= 16 and comp.value >= comp.naive_value - 1e-9
    assert comp.value == pytest.approx(value_at_start(model, comp.controller), abs=1e-9)
    t = table_format.decode(result.table, expect_model="m2")
    assert t.header["solver"]["layered_search"] == "exact"
    assert monotone_check(t).monotone
    with pytest.raises(ConfigError, match="layered_search must be one of actions, exact, got 'best'"):
        plan_from({"solver": {"layered_search": "best"}}, plan)


# ------------------------------------------------------------------ sawtooth upper bound (issue 12)


def random_beliefs(S: int, n: int, seed: int) -> np.ndarray:
    """Dirichlet beliefs, plus sparse ones (a random half of the states zeroed)."""
    rng = np.random.default_rng(seed)
    dense = rng.dirichlet(np.ones(S), size=n)
    sparse = dense * (rng.random((n, S)) < 0.5)
    sparse[np.arange(n), rng.integers(0, S, n)] += 0.1
    return np.vstack([dense, sparse / sparse.sum(axis=1, keepdims=True)])


@pytest.mark.parametrize("name", ["tiger", "m1"])
def test_sawtooth_bound_is_an_upper_bound_and_never_above_the_fib(request, name, tiger_solved, m1_result):
    """At random beliefs: controller value <= lower bound-or-better <= upper <= FIB. Every node
    of the compiled controller is a policy, so max_n V[n] . b <= V*(b) <= upper(b)."""
    if name == "tiger":
        model, (sol, comp) = request.getfixturevalue("tiger"), tiger_solved
    else:
        model, sol, comp = m1_result.model, m1_result.solution, m1_result.compiled
    B = random_beliefs(model.shape[0], 200, seed=3)
    upper = sol.upper_value(B)
    fib = (B @ sol.upper_q.T).max(axis=1)
    assert sol.upper.size > 0                                    # the points are really used
    assert np.all(upper >= (B @ comp.values.T).max(axis=1) - 1e-9)
    assert np.all(upper >= sol.lower_value(B) - 1e-9)
    assert np.all(upper <= fib + 1e-12)
    assert np.any(upper < fib - 1e-6)                            # and tighter than the FIB somewhere
    assert sol.upper_bound == pytest.approx(float(sol.upper_value(model.b0)[0]))


def test_sawtooth_interpolates_points_and_corners():
    """Two states, corners (10, 4), one point (0.5, 0.5) worth 5: at (0.75, 0.25) the ratio is
    min(0.75 / 0.5, 0.25 / 0.5) = 0.5, so the value is 8.5 + 0.5 * (5 - 7) = 7.5."""
    ub = UpperBound(np.array([[10.0, 4.0], [0.0, 0.0]]))
    assert ub.add(np.array([0.5, 0.5]), 5.0)
    assert not ub.add(np.array([0.5, 0.5]), 6.0)                 # looser: not stored
    assert ub.sawtooth(np.array([[0.5, 0.5]]))[0] == pytest.approx(5.0)
    assert ub.sawtooth(np.array([[1.0, 0.0], [0.0, 1.0]])).tolist() == [10.0, 4.0]
    assert ub.sawtooth(np.array([[0.75, 0.25]]))[0] == pytest.approx(7.5)
    # a one-hot point lowers its corner
    assert ub.add(np.array([0.0, 1.0]), 3.0)
    assert ub.corner.tolist() == [10.0, 3.0]
    assert ub.sawtooth(np.array([[0.25, 0.75]]))[0] == pytest.approx(min(4.75, 4.75 + 0.5 * (5.0 - 6.5)))


@pytest.mark.parametrize("name", ["tiger", "m1"])
def test_sawtooth_equals_stored_values_at_points_and_corners(request, name, tiger_solved, m1_result):
    sol = tiger_solved[0] if name == "tiger" else m1_result.solution
    ub = sol.upper
    ub.prune()                                                   # no point dominated by the others
    B, v = ub.beliefs, ub.values
    assert len(v) > 0
    assert np.allclose(ub.sawtooth(B), v, rtol=0, atol=1e-9)
    assert np.allclose(ub.sawtooth(np.eye(ub.S)), ub.corner)
    assert np.all(ub.corner <= sol.upper_q.max(axis=0) + 1e-12)


def test_upper_backup_of_the_fib_alone_stays_below_the_fib(tiger):
    """One point-based backup on the FIB is <= the FIB at that belief (it is the FIB's own
    backup with a max moved outside), and >= the known optimum."""
    dyn = Dynamics(tiger)
    ub = UpperBound(fast_informed_bound(tiger))
    for p in (0.5, 0.7, 0.97):
        b = np.array([p, 1 - p])
        q, _, _ = upper_backup(dyn, ub, b)
        assert q.max() <= ub.fib(b[None, :])[0] + 1e-9
    q, _, _ = upper_backup(dyn, ub, tiger.b0)
    assert q.max() >= TIGER_VALUE - 0.01


def test_default_settings_certify_tiger_and_model1_within_one_percent(tiger_solved, m1_result):
    for sol in (tiger_solved[0], m1_result.solution):
        assert sol.stop_reason == "target_gap"
        assert sol.gap <= 0.01 * max(1.0, abs(sol.upper_bound))
    sol = tiger_solved[0]
    assert sol.lower_bound <= TIGER_VALUE + 0.01 and sol.upper_bound >= TIGER_VALUE - 0.01


TIGER75_PUBLISHED = 1.933439  # pomdp-solve via the R package 'pomdp' (README): Tiger at discount 0.75


def test_certified_bounds_contain_the_published_tiger_value_at_discount_075(tiger):
    """A published optimum we did not compute ourselves: Cassandra's pomdp-solve (through
    Hahsler's R package 'pomdp') gives 1.933439 for Tiger at discount 0.75. Our bounds must
    contain it and certify it within 1 %; a bound off by a sign or a discount would not."""
    sol = solve(replace(tiger, discount=0.75), SolverSettings(time_budget_s=30.0, target_gap=1e-4))
    assert sol.lower_bound <= TIGER75_PUBLISHED + 1e-6 <= sol.upper_bound + 2e-6
    assert sol.upper_bound - sol.lower_bound <= 0.01 * abs(sol.upper_bound)
    assert sol.lower_bound == pytest.approx(TIGER75_PUBLISHED, abs=2e-3)


def test_last_demand_in_the_state_prices_the_release_cost_exactly(m1_result):
    """Every table of a model with a release cost is a table of with_last_demand(model) with
    the same exact value; without the cost in the model it would be worth more there."""
    from monitor.offline.hysteresis import with_last_demand

    model, ctrl = m1_result.model, m1_result.compiled.controller
    assert model.release_cost > 0
    lifted = with_last_demand(model)
    assert lifted.release_cost == 0 and lifted.shape == (3 * model.shape[0], *model.shape[1:])
    assert value_at(lifted, ctrl, evaluate(lifted, ctrl)) == pytest.approx(m1_result.compiled.value, abs=1e-9)
    costless = replace(model, release_cost=0.0)
    free = value_at(costless, ctrl, evaluate(costless, ctrl))
    assert free > m1_result.compiled.value + 1e-6


def test_hsvi_is_the_default_and_deterministic(tiger):
    assert SolverSettings().method == "hsvi" and set(METHODS) == {"hsvi", "perseus", "pbvi"}
    settings = SolverSettings(target_gap=0.0, time_budget_s=1e9, max_iterations=12, seed=5)
    a, b = solve(tiger, settings), solve(tiger, settings)
    assert a.stop_reason == b.stop_reason == "max_iterations" and a.iterations == 12
    assert a.alphas.tobytes() == b.alphas.tobytes() and a.witnesses.tobytes() == b.witnesses.tobytes()
    assert a.upper.beliefs.tobytes() == b.upper.beliefs.tobytes()
    assert a.upper_bound == b.upper_bound and a.lower_bound == b.lower_bound


def test_time_budget_and_deadline_stop_the_solver(m2, tiger):
    model, _ = m2
    sol = solve(model, SolverSettings(target_gap=0.0, time_budget_s=0.5, max_iterations=10**6))
    assert sol.stop_reason == "time_budget" and sol.iterations < 10**6
    assert sol.lower_bound <= sol.upper_bound
    import time
    sol = solve(tiger, SolverSettings(target_gap=0.0, time_budget_s=1e9, max_iterations=10**6),
                deadline=time.perf_counter() + 0.3)
    assert sol.stop_reason == "time_budget" and sol.iterations < 10**6
    assert sol.lower_bound <= TIGER_VALUE + 0.01 <= sol.upper_bound + 0.02


@pytest.mark.parametrize("method", ["perseus", "pbvi"])
def test_pbvi_and_perseus_still_bound_tiger(tiger, method):
    sol = solve(tiger, SolverSettings(method=method, max_iterations=60, max_beliefs=40, expand_every=5))
    assert sol.lower_bound <= TIGER_VALUE + 0.01 <= sol.upper_bound
    assert sol.lower_bound > 15.0                                # it really solved something
    assert sol.stop_reason in {"target_gap", "time_budget", "converged", "max_iterations"}
    assert sol.upper_bound == pytest.approx(float((sol.upper_q @ tiger.b0).max()))   # the FIB alone
