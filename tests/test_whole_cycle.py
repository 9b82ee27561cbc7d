"""Issue 40 item 2: the whole cycle proved about what it feeds the memory and the curves
(verification/physics/whole_cycle.py), on the shipped Python step and the C rg_step.

The CLI run of tests/test_physics.py proves every picture for three declarations, shipped,
and sees both planted memory edits refuted in Python and in C and replayed as collisions.
Here, quickly: the finding the proof made (the remembered curves' closing speed rounded down,
up to 1 cm/s of the obstacle's own speed uncounted) fails it again when planted back, in
Python and in C, while the same picture proves on the shipped code; and a weakening's check
stops at the first picture that refutes it.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from monitor.core import cycle
from monitor.core.config import Config
from monitor.tables import read
from verification.physics import weakenings, whole_cycle as wc

CYCLE_PY = Path(cycle.__file__)
PICTURES = {c.picture: c for c in wc.cases()}
BLIND = PICTURES["every channel blind, remembered"]


@pytest.fixture(scope="module")
def setup():
    return cycle.create(Config(), read("m1"))


def _statuses(results):
    return [r.status for r in results]


def test_the_remembered_curve_rounding_the_train_s_share_down_is_refuted(setup, tmp_path):
    # before issue 40 the remembered curves took `t.closing + own_speed` (the train's least
    # speed rounded down): the curve then counted up to 1 cm/s less than the obstacle's own speed
    for language, runner in (("Python", wc.python_step()), ("C", wc.c_step())):
        assert _statuses(wc.prove_case(Config(), setup, runner, BLIND, language)) == ["proved", "proved"]
    planted = CYCLE_PY.read_text().replace("t.closing + own_speed_up, ages[i]", "t.closing + own_speed, ages[i]")
    assert planted != CYCLE_PY.read_text()
    results = wc.prove_case(Config(), setup, wc.python_step({"cycle": planted}), BLIND, "Python")
    assert _statuses(results) == ["proved", "refuted"]
    m, faster = results[1].model, Config().closing_accuracy_cms
    # less than 1 cm/s uncounted: the obstacle within the remembered own speed plus the closing
    # accuracy (the error budget), and faster than the curve counts
    assert -1 < m["obstacle_cms"] - m["remembered_own_cms"] - faster <= 0
    w = weakenings.Weakening("rounded-down", "", (), (("tracks[i].closing + own_speed_up, ages[i]",
                                                       "tracks[i].closing + own_speed, ages[i]"),))
    core = weakenings.weakened_core(w, tmp_path / "core")
    results = wc.prove_case(Config(), setup, wc.c_step(core), BLIND, "C")
    assert _statuses(results) == ["proved", "refuted"]


def test_a_memory_edit_is_refuted_at_the_first_picture_that_shows_it():
    w = weakenings.by_name("memory-moved-at-half")
    results = wc.whole_cycle_results(Config(), sources=weakenings.weakened_sources(w), languages=("Python",),
                                     first_failure=True)
    assert results[-2].status == "refuted" and all(r.proved for r in results[:-2])
    assert len(results) < 2 * len(wc.cases())                       # it stopped there
