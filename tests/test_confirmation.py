"""The warning confirmation (monitor/offline/confirmation.py): a warning alone escalates the
shipped m1 table CYCLES cycles later, nothing else changes, the header's figures are exact,
and `railguard table confirm` undoes and redoes it as a user runs it."""
import json
import subprocess
import sys

import numpy as np
import pytest

from monitor.core.table import decode
from monitor.offline.confirmation import confirm, undone
from monitor.offline.controller import Controller, evaluate, value_at
from monitor.offline.models import M1_WARNING_CONFIRMATION, rebuild
from monitor.tables import read
from verification.evaluate import hazard_exact

FREE, WARNING, EMERGENCY_OBS = 0, 1, 2


@pytest.fixture(scope="module")
def shipped():
    table = decode(read("m1"))
    return table, rebuild(dict(table.header)), Controller.of_table(table)


def first_brake(ctrl: Controller, observations) -> int:
    """Index of the first observation after which the table demands braking (-1: never)."""
    node = ctrl.start
    for i, o in enumerate(observations):
        node = ctrl.next[node, o]
        if ctrl.action[node] > 0:
            return i
    return -1


def test_a_warning_alone_escalates_the_confirmation_later_and_nothing_else_moves(shipped):
    table, model, ctrl = shipped
    before = undone(ctrl, table.header["warning_confirmation"])
    quiet = [FREE] * 20
    without = first_brake(before, quiet + [WARNING] * 60)
    assert without == 20 + 3                                   # the compiled table: four warnings in a row
    assert first_brake(ctrl, quiet + [WARNING] * 60) == without + M1_WARNING_CONFIRMATION
    assert first_brake(ctrl, quiet + [WARNING] * (3 + M1_WARNING_CONFIRMATION)) == -1
    # an emergency observation inside the confirmation leads where it led before it
    for k in range(1, 4 + M1_WARNING_CONFIRMATION):
        seq = quiet + [WARNING] * k + [EMERGENCY_OBS]
        assert first_brake(ctrl, seq) == first_brake(before, quiet + [WARNING] * min(k, 3) + [EMERGENCY_OBS]) + max(0, k - 3)
    # every copy acts and reads every other observation as the node it copies
    src, obs, _dst = table.header["warning_confirmation"]["paths"][0]
    copies = np.arange(before.nodes, ctrl.nodes)
    others = [o for o in range(ctrl.next.shape[1]) if o != obs]
    assert (ctrl.action[copies] == ctrl.action[src]).all()
    assert (ctrl.next[np.ix_(copies, others)] == before.next[src, others]).all()


def test_the_headers_figures_are_exact_on_verifications_closed_loop(shipped):
    table, model, ctrl = shipped
    entry = table.header["warning_confirmation"]
    before = undone(ctrl, entry)
    steps = int(round(entry["horizon_s"] / 0.1))
    assert entry["p_hazard"] == pytest.approx(hazard_exact(model, ctrl, steps), rel=1e-9)
    assert entry["p_hazard_before"] == pytest.approx(hazard_exact(model, before, steps), rel=1e-9)
    assert entry["p_hazard"] < 1.001 * entry["p_hazard_before"]        # the model cannot price the wait
    assert entry["value"] == pytest.approx(value_at(model, ctrl, evaluate(model, ctrl)), abs=1e-9)
    assert entry["value"] == table.header["controller_value"]
    assert 0 < entry["value_before"] - entry["value"] < 1e-3


def test_zero_cycles_and_a_table_that_never_escalates_on_warnings_are_left_as_they_are(shipped):
    _table, model, ctrl = shipped
    assert confirm(model, ctrl, 0).controller.nodes == ctrl.nodes
    never = Controller(np.zeros(3, dtype=np.int64), np.zeros((3, 4), dtype=np.int64), 0)
    c = confirm(model, never, 10)
    assert c.paths == () and c.controller.nodes == 3
    with pytest.raises(ValueError):
        undone(never, {"nodes_before": 3, "cycles": 10, "paths": [[0, 1, 0]]})


def run(*args):
    return subprocess.run([sys.executable, "-m", "railguard", *args], capture_output=True, text=True, timeout=120)


def test_table_confirm_undoes_and_redoes_the_shipped_confirmation_as_a_user_runs_it(tmp_path):
    zero, again = tmp_path / "zero.table.rgt", tmp_path / "again.table.rgt"
    r = run("table", "confirm", "m1", "--cycles", "0", "--out", str(zero), "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["nodes"] == 30 and "paths" in out and out["cycles"] == 0
    assert (tmp_path / "zero.alphas.npz").is_file()
    r = run("table", "confirm", str(zero), "--cycles", str(M1_WARNING_CONFIRMATION), "--out", str(again))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"confirmation     a warning alone escalates {M1_WARNING_CONFIRMATION} cycles later")
    assert again.read_bytes() == read("m1")
    assert "warning alone escalates" in run("table", "show", "m1").stdout


def test_table_confirm_refuses_what_it_cannot_do_in_one_line(tmp_path):
    for args, words in ((("m2", "--cycles", "10"), "monotone"), (("m1", "--cycles", "-1"), "0..1000"),
                        ((str(tmp_path / "none.table.rgt"), "--cycles", "1"), "cannot read")):
        r = run("table", "confirm", *args, "--out", str(tmp_path / "x.table.rgt"))
        assert r.returncode == 2 and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
