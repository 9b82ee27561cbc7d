"""Shared fixtures: the Tiger problem, the papers' models and their solved tables.

Everything is session-scoped: building Model 2 and solving Model 1 are done once.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
TIGER_PATH = ROOT / "examples" / "tiger.pomdp"
TABLES = ROOT / "monitor" / "tables"

# Modules whose tests judge time: a monitor process in real time on a bus or in the vcan
# sandbox (gaps between BrakeDemand frames, deadline misses, Ctrl-C while running). The README's
# test command runs them after the others, so that the proof, the mutation test and the other
# CPU-bound tests' load on this 2-core machine is never read as the monitor's lateness; they
# run two modules at a time (a worker, so a core, each: measured serially they kept 0.76 of
# the two cores busy, 4 min 57 s; two at a time 2 min 59 s, every test passing, twice).
# A single test that judges wall-clock time elsewhere carries @pytest.mark.realtime itself.
# (test_verify left them when its quick run stopped running the campaign's vcan0 sample, which
# tests/test_campaign.py runs here: nothing it checks is judged by the wall clock)
REALTIME_MODULES = frozenset({"test_can_flood", "test_can_realbus", "test_can_run", "test_campaign", "test_cli_shell",
                              "test_log_corpus", "test_socketcan"})


# The longest modules (minutes on one worker: the whole core's Frama-C proof, the Python
# mutation test, the physics part, the evaluation), collected first: pytest-xdist's
# `--dist loadfile` hands out modules in collection order (with --no-loadscope-reorder,
# pyproject.toml; by default it orders them by their number of tests), and a long one handed
# out last finishes alone while the other worker idles
# test_relaxation last of them: in the realtime phase (two modules at a time) its 90 s m2 solve
# is then handed out first, beside the vcan sandbox sessions, instead of after them
LONGEST_FIRST = ("test_proof", "test_mutation", "test_physics", "test_evaluate", "test_verify", "test_relaxation")


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.path.stem in REALTIME_MODULES:
            item.add_marker(pytest.mark.realtime)
    rank = {stem: i for i, stem in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.stem, len(rank)))      # (stable: the rest as collected)


def independent_values(model, action, nxt) -> np.ndarray:
    """V[n, s] of a finite-state controller by a dense solve written from the definition:

    V[n, s] = R[s, a_n] + g * sum_{s', o} T[a_n, s, s'] O[a_n, s', o] (V[next[n, o], s'] - c [a_next < a_n])
    with c the model's release cost (paid when the next node demands less).
    Independent of monitor.offline.controller (no shared code).
    """
    S = len(model.states)
    Z = len(model.observations)
    N = len(action)
    M = np.eye(N * S)
    r = np.zeros(N * S)
    for n in range(N):
        a = int(action[n])
        for s in range(S):
            i = n * S + s
            r[i] = model.R[s, a]
            for s2 in range(S):
                t = model.T[a, s, s2]
                if t == 0.0:
                    continue
                for o in range(Z):
                    m = int(nxt[n][o])
                    M[i, m * S + s2] -= model.discount * t * model.O[a, s2, o]
                    if int(action[m]) < a:
                        r[i] -= model.discount * t * model.O[a, s2, o] * model.release_cost
    return np.linalg.solve(M, r).reshape(N, S)


@pytest.fixture(scope="session")
def tiger():
    from monitor.offline.pomdp_file import read

    return read(TIGER_PATH)


@pytest.fixture(scope="session")
def tiger_solved(tiger):
    from monitor.offline.controller import compile_controller
    from monitor.offline.solver import SolverSettings, solve

    sol = solve(tiger, SolverSettings())
    return sol, compile_controller(tiger, sol)


@pytest.fixture(scope="session")
def m1():
    from monitor.offline.models import load

    return load("m1")


@pytest.fixture(scope="session")
def m1_result(m1):
    from monitor.offline import pipeline

    model, plan = m1
    return pipeline.run(model, plan)


@pytest.fixture(scope="session")
def m2():
    from monitor.offline.models import load

    return load("m2")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def monitor_fmus(fmu_dir) -> dict:
    """Monitor FMUs built from the shipped tables: {(model, fmi): path}."""
    from fmu.build import build_monitor
    from monitor.tables import read

    return {(m, v): build_monitor(read(m), v, fmu_dir) for m, v in (("m1", 2), ("m2", 2), ("m1", 3))}


@pytest.fixture(scope="session")
def train_fmu(fmu_dir) -> Path:
    from fmu.build import build_train

    return build_train(fmu_dir)


@pytest.fixture(scope="session")
def monitor_drivers(monitor_fmus):
    """One loaded monitor FMU per (model, FMI version), driven through FMPy; each test
    resets it (MonitorDriver.reset) before use."""
    from fmu.driver import MonitorDriver

    opened = {key: MonitorDriver(path) for key, path in monitor_fmus.items()}
    yield opened
    for d in opened.values():
        d.close()
