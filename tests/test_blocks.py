"""The fully observed part of a POMDP (monitor/offline/blocks.py) and the solver that splits
its bounds by it (monitor/offline/momdp.py).

The partition is checked against the models' known structure (Tag's robot cell, RockSample's
robot position) and against its defining property, recomputed here by brute force. The split
solver is checked to give the plain solver's bounds at equal iterations (the splitting only
skips zero products), its table to be worth at least its lower bound, and every node of its
policy graph to be worth its vector in every state (independent evaluation, tests/conftest.py).
"""
from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np
import pytest

from conftest import ROOT, independent_values
from monitor.offline.blocks import MIXED, find_blocks
from monitor.offline.bounds import UpperBound
from monitor.offline.controller import compile_controller
from monitor.offline.lower_bound import LowerBound
from monitor.offline.momdp import BlockLowerBound, BlockUpperBound
from monitor.offline import solver
from monitor.offline.solver import SolverSettings, solve

sys.path.insert(0, str(ROOT / "benchmarks"))
import pomdps  # noqa: E402


@pytest.fixture(scope="module")
def tag():
    return pomdps.tag()


@pytest.fixture(scope="module")
def rocksample():
    """RockSample[5,5] (801 states)."""
    return pomdps.rocksample(**pomdps.RS55)


def next_states(model, sources, a, o) -> np.ndarray:
    """States that can follow some state of `sources` under action a with observation o."""
    reach = model.T[a][sources].sum(axis=0) > 0
    return np.flatnonzero(reach & (model.O[a][:, o] > 0))


def check_closed(model, blocks) -> None:
    """The defining property, by brute force: from the start support and from every block,
    each (a, o) leads into one block, the one `following` names."""
    S, A, Z = model.shape
    start = np.flatnonzero(model.b0 > 0)
    for a in range(A):
        for o in range(Z):
            nxt = next_states(model, start, a, o)
            assert len(np.unique(blocks.of_state[nxt])) <= 1, ("start", a, o)
            for x, members in enumerate(blocks.members):
                nxt = next_states(model, members, a, o)
                labels = np.unique(blocks.of_state[nxt])
                assert len(labels) <= 1, (x, a, o, labels)
                assert blocks.following[x, a, o] == (labels[0] if len(labels) else MIXED), (x, a, o)


def test_tag_blocks_are_the_robot_cell_and_the_same_cell_states(tag):
    """29 robot cells (opponent elsewhere or tagged) and the 29 'same cell' states, which the
    'same' observation after the start belief joins across cells."""
    blocks = find_blocks(tag)
    check_closed(tag, blocks)
    assert blocks.count == 30
    groups = {frozenset(tag.states[s] for s in m) for m in blocks.members}
    same = frozenset(f"r{r}_o{r}" for r in range(29))
    assert same in groups
    for r in range(29):
        assert frozenset([f"r{r}_tagged"] + [f"r{r}_o{o}" for o in range(29) if o != r]) in groups
    assert blocks.of(tag.b0) == MIXED                       # the robot starts anywhere


def test_rocksample_blocks_are_the_robot_position(rocksample):
    """The position is never observed, but it follows from the last one and the action."""
    blocks = find_blocks(rocksample)
    check_closed(rocksample, blocks)
    assert blocks.count == 26
    sizes = sorted(len(m) for m in blocks.members)
    assert sizes == [1] + [32] * 25
    for m in blocks.members:
        assert len({rocksample.states[s].split("_")[0] for s in m}) == 1       # one position each
    assert blocks.of(rocksample.b0) == blocks.of_state[np.flatnonzero(rocksample.b0)[0]]


@pytest.mark.parametrize("name", ["tiger", "m1", "m2"])
def test_models_whose_observations_pin_nothing_are_one_block(request, name):
    model = request.getfixturevalue("tiger") if name == "tiger" else request.getfixturevalue(name)[0]
    blocks = find_blocks(model)
    assert blocks.count == 1
    check_closed(model, blocks)


def test_one_block_models_solve_exactly_as_before(tiger):
    on = solve(tiger, SolverSettings(max_iterations=40, momdp=True))
    off = solve(tiger, SolverSettings(max_iterations=40, momdp=False))
    assert on.blocks == off.blocks == 1
    assert on.alphas.tobytes() == off.alphas.tobytes() and on.actions.tolist() == off.actions.tolist()
    assert (on.lower_bound, on.upper_bound, on.iterations) == (off.lower_bound, off.upper_bound, off.iterations)
    assert on.upper.beliefs.tobytes() == off.upper.beliefs.tobytes()


def test_split_bounds_value_beliefs_as_the_plain_ones(tag):
    """The same vectors and points, valued split and plain, at beliefs inside one block, over
    several blocks, and after corner updates."""
    rng = np.random.default_rng(3)
    blocks = find_blocks(tag)
    S, A, Z = tag.shape
    fib = rng.uniform(5, 10, (A, S))
    split, plain = BlockUpperBound(fib, blocks), UpperBound(fib)
    lower_split = BlockLowerBound(rng.normal(size=(A, S)), np.arange(A), np.tile(tag.b0, (A, 1)), Z, blocks)
    lower_plain = LowerBound(lower_split.alphas.copy(), np.arange(A), np.tile(tag.b0, (A, 1)), Z)

    def belief(x):
        b = np.zeros(S)
        members = blocks.members[x] if x != MIXED else np.arange(S)
        b[rng.choice(members, size=min(len(members), rng.integers(1, 6)), replace=False)] = rng.random()
        b[members[0]] += 0.1
        return b / b.sum()

    mixed_support = np.arange(S)
    for step in range(300):
        x = MIXED if step % 10 == 0 else int(rng.integers(blocks.count))
        b = belief(x)
        if x == MIXED:
            mixed_support = np.flatnonzero(b)
        if step % 25 == 7:                  # a corner, in a mixed point's support: its slack moves
            b = np.eye(S)[rng.choice(mixed_support)]
        v = float(plain.value(b[None, :])[0]) - rng.uniform(0, 1)
        assert split.add(b, v) == plain.add(b, v)
        vec = rng.normal(size=S)
        lower_split.add(vec, 0, b, np.zeros(Z, dtype=np.int64))
        lower_plain.add(vec, 0, b, np.zeros(Z, dtype=np.int64))
    probe = np.array([belief(MIXED if i % 5 == 0 else int(rng.integers(blocks.count))) for i in range(200)])
    whole = rng.dirichlet(np.ones(S), size=20)                          # over every block: all points count
    within = np.zeros((blocks.count, S))
    for x, members in enumerate(blocks.members):
        within[x, members] = rng.dirichlet(np.ones(len(members)))
    probe = np.vstack([probe, whole, within])
    assert (plain.sawtooth(whole) < whole @ plain.corner - 1e-6).all()             # the points matter there
    assert np.allclose(split.sawtooth(probe), plain.sawtooth(probe), rtol=0, atol=1e-12)
    assert np.allclose(split.value(probe), plain.value(probe), rtol=0, atol=1e-12)
    assert np.allclose(split.merged().value(probe), plain.value(probe), rtol=0, atol=1e-12)
    assert np.allclose([lower_split.value(b) for b in probe], [lower_plain.value(b) for b in probe], atol=1e-12)
    assert split.size == plain.size and split.beliefs.tobytes() == plain.beliefs.tobytes()


@pytest.mark.parametrize("problem, trials", [("rocksample", 40), ("tag", 15)])
def test_split_solver_gives_the_plain_bounds_at_equal_iterations(request, problem, trials):
    model = request.getfixturevalue(problem)
    settings = SolverSettings(max_iterations=trials, time_budget_s=120.0)
    split = solve(model, settings)
    plain = solve(model, replace(settings, momdp=False))
    assert split.blocks > 1 and plain.blocks == 1
    assert split.iterations == plain.iterations == trials
    assert split.lower_bound == pytest.approx(plain.lower_bound, abs=1e-9)
    assert split.upper_bound == pytest.approx(plain.upper_bound, abs=1e-9)
    assert split.lower_bound <= split.upper_bound
    assert len(split.alphas) == len(plain.alphas) and np.allclose(split.alphas, plain.alphas, atol=1e-9)
    assert split.lower_bound == pytest.approx(float(split.lower_value(model.b0)[0]), abs=1e-12)
    # the same points, in the same order, for the compiler and in the merged upper bound
    assert split.beliefs.shape == plain.beliefs.shape and np.allclose(split.beliefs, plain.beliefs, atol=1e-12)
    assert split.upper.size == plain.upper.size and np.allclose(split.upper.values, plain.upper.values, atol=1e-9)
    assert split.graph.n == plain.graph.n


def test_split_solver_table_is_worth_its_lower_bound(monkeypatch):
    """RockSample[4,3] (129 states, 17 blocks): the compiled table, evaluated exactly, is worth
    at least the lower bound at b0, and the split bounds bracket a longer plain run's."""
    model = pomdps.rocksample(n=4, start=(0, 1), rocks=((1, 1), (2, 3), (3, 0)), half_efficiency=3.0)
    monkeypatch.setattr(solver, "MOMDP_MIN_STATES", 0)          # split even this small model
    sol = solve(model, SolverSettings(max_iterations=20))
    assert sol.blocks == 17
    comp = compile_controller(model, sol)
    tol = 1e-9 * abs(sol.lower_bound)
    assert comp.value >= sol.lower_bound - tol
    longer = solve(model, SolverSettings(max_iterations=80, momdp=False))
    assert longer.upper_bound < sol.upper_bound and longer.lower_bound >= sol.lower_bound   # it did get further
    assert comp.value <= longer.upper_bound + tol and sol.upper_bound >= longer.lower_bound - tol


def test_every_node_of_the_split_solver_is_worth_its_vector_in_every_state(monkeypatch):
    """RockSample[3,2] (37 states, 10 blocks): each vector is a valid lower bound in every
    state, also outside the block it was backed up for (Solution.alphas keeps them all)."""
    model = pomdps.rocksample(n=3, start=(0, 1), rocks=((1, 1), (2, 0)), half_efficiency=2.0)
    monkeypatch.setattr(solver, "MOMDP_MIN_STATES", 0)
    sol = solve(model, SolverSettings(max_iterations=25))
    assert sol.blocks == 10 and len(sol.alphas) > model.shape[1]
    for k, node in enumerate(sol.graph_nodes):
        action, nxt, _ = sol.graph.closure(int(node))
        V = independent_values(model, action, nxt)
        assert np.all(V[0] >= sol.alphas[k] - 1e-9 * np.maximum(1.0, np.abs(sol.alphas[k]))), k


def test_small_models_with_blocks_are_solved_plain(m2):
    """m2's information relaxation (144 states, 36 blocks of 4) is below MOMDP_MIN_STATES:
    the split would cost more Python steps than the products it skips."""
    from monitor.offline.models import model2

    relaxed = model2.relaxation(m2[0]).model
    assert find_blocks(relaxed).count == 36 and relaxed.shape[0] < solver.MOMDP_MIN_STATES
    assert solve(relaxed, SolverSettings(max_iterations=2)).blocks == 1
