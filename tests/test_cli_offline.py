"""`railguard solve` and `railguard table show`, in-process and as a subprocess."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, TIGER_PATH
from railguard.main import main
from monitor.core.table import decode
from monitor.offline.pomdp_file import read
from monitor.tables import read as read_table

SOLVE_KEYS = {"model", "states", "actions", "observations", "nodes", "lower_bound", "upper_bound",
              "controller_value", "seconds", "table_bytes", "sha256", "table", "pomdp"}


def run_main(capsys, argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_json_object(out: str) -> dict:
    lines = [line for line in out.splitlines() if line.strip()]
    assert len(lines) == 1, out
    obj = json.loads(lines[0])
    assert isinstance(obj, dict)
    return obj


def assert_one_line_error(code, err):
    assert code == 2
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("railguard: error: "), err
    assert len(lines[0]) > len("railguard: error: ")


# ------------------------------------------------------------------ solve


def test_solve_tiger_json(capsys, tmp_path, tiger):
    code, out, err = run_main(capsys, ["solve", "--pomdp", TIGER_PATH, "--json", "--out", tmp_path])
    assert code == 0, err
    assert "Traceback" not in err
    obj = one_json_object(out)
    assert SOLVE_KEYS <= set(obj)
    assert obj["model"] == "tiger"
    assert (obj["states"], obj["actions"], obj["observations"]) == (2, 3, 2)
    assert obj["controller_value"] == pytest.approx(19.37, abs=0.01)
    assert obj["lower_bound"] <= obj["upper_bound"]
    assert obj["controller_value"] <= obj["upper_bound"] + 1e-9
    assert obj["nodes"] >= 1 and obj["seconds"] >= 0
    table_path, pomdp_path = tmp_path / "tiger.table.rgt", tmp_path / "tiger.pomdp"
    assert obj["table"] == str(table_path) and obj["pomdp"] == str(pomdp_path)
    assert table_path.is_file() and pomdp_path.is_file()
    data = table_path.read_bytes()
    assert obj["table_bytes"] == len(data)
    t = decode(data, expect_model="tiger")
    assert obj["sha256"] == t.sha256
    assert t.nodes == obj["nodes"]
    assert t.header["controller_value"] == obj["controller_value"]
    # the written .pomdp is the same model
    again = read(pomdp_path)
    for key in ("T", "O", "R", "b0"):
        assert np.allclose(getattr(again, key), getattr(tiger, key), atol=1e-12), key
    assert (again.states, again.actions, again.observations) == (tiger.states, tiger.actions, tiger.observations)
    assert again.discount == tiger.discount
    if "summary" in obj:
        assert "controller value" in (tmp_path / "tiger.summary.txt").read_text()


def test_solve_without_json_prints_summary(capsys, tmp_path):
    code, out, err = run_main(capsys, ["solve", "--pomdp", TIGER_PATH, "--out", tmp_path])
    assert code == 0, err
    assert "controller value" in out and "lower bound" in out and "upper bound" in out
    assert str(tmp_path / "tiger.table.rgt") in out
    assert "Traceback" not in err


def test_solve_m1_then_table_show(capsys, tmp_path):
    code, out, err = run_main(capsys, ["solve", "--model", "m1", "--json", "--out", tmp_path])
    assert code == 0, err
    obj = one_json_object(out)
    assert obj["model"] == "m1" and (obj["states"], obj["actions"], obj["observations"]) == (4, 3, 4)
    assert obj["lower_bound"] <= obj["upper_bound"]
    # the default model is the one the shipped table was solved for: the solve says how far it is
    shipped = decode(read_table("m1"))
    assert obj["shipped"]["sha256"] == shipped.sha256
    assert obj["shipped"]["controller_value"] == shipped.header["controller_value"]
    diff = obj["controller_value"] - shipped.header["controller_value"]
    summary = (tmp_path / "m1.summary.txt").read_text()
    assert f"shipped table    {shipped.header['controller_value']:.4f}" in summary and f"this table {diff:+.4f}" in summary
    table_path = tmp_path / "m1.table.rgt"
    assert obj["table"] == str(table_path)
    t = decode(table_path.read_bytes(), expect_model="m1")
    # the plan's risk repair ran (issue 41): the header and the JSON say what it bought and paid
    fix = obj["risk_repair"]
    assert fix == t.header["risk_repair"] and fix["hazard_price"] == 20000.0
    assert fix["p_hazard"] < fix["p_hazard_before"] / 10
    assert f"risk repair      P(hazard within 30 s) {fix['p_hazard_before']:.3g} -> {fix['p_hazard']:.3g}" in summary
    # then the warning confirmation, from the repaired table (docs/models.md section 9)
    conf = obj["warning_confirmation"]
    assert conf == t.header["warning_confirmation"] and conf["cycles"] == 10 and conf["paths"] == [[13, 1, 23]]
    assert conf["value_before"] == fix["value"] and conf["value"] == obj["controller_value"] == t.header["controller_value"]
    assert conf["p_hazard_before"] == pytest.approx(fix["p_hazard"], rel=1e-12) and obj["nodes"] == conf["nodes_before"] + 10
    assert "confirmation     a warning alone escalates 10 cycles later (1 path, 10 nodes added)" in summary

    code, out, err = run_main(capsys, ["table", "show", table_path])
    assert code == 0, err
    assert "m1" in out and t.sha256 in out
    listing = out.split("node  action", 1)
    assert len(listing) == 2, out
    rows = [line for line in listing[1].splitlines()[1:] if line.strip()]
    assert len(rows) == t.nodes
    for n, row in enumerate(rows):
        fields = row.split()
        assert int(fields[0]) == n
        assert fields[1] == t.actions[t.action[n]]
        assert fields[1] in ("maintain", "nominal_braking", "emergency_braking")
        assert int(fields[2].replace(",", "")) == t.risk[n]          # the node's risk, ppm
        shown_next = {int(piece.split()[0]) for piece in row.split(None, 3)[3].split("; ")}
        assert shown_next == set(t.next[n])                        # every successor, likeliest first

    code, out, err = run_main(capsys, ["table", "show", "--full", table_path])
    assert code == 0, err
    rows = [line for line in out.split("node  action", 1)[1].splitlines()[1:] if line.strip()]
    for n, row in enumerate(rows):
        for obs in t.observations:  # every observation appears on the node's line
            assert obs in row

    code, out, err = run_main(capsys, ["table", "show", "--json", table_path])
    assert code == 0, err
    shown = one_json_object(out)
    assert shown["sha256"] == t.sha256
    assert shown["action"] == [t.actions[a] for a in t.action]
    assert shown["next"] == [list(r) for r in t.next]
    assert shown["risk_ppm"] == list(t.risk)
    assert shown["header"]["model"] == "m1"


def test_solve_flags_override_settings(capsys, tmp_path):
    code, out, err = run_main(capsys, ["solve", "--model", "m1", "--json", "--out", tmp_path,
                                       "--max-iterations", "2", "--max-nodes", "2", "--seed", "4"])
    assert code == 0, err
    obj = one_json_object(out)
    t = decode((tmp_path / "m1.table.rgt").read_bytes())
    assert t.header["solver"]["max_iterations"] == 2 and t.header["solver"]["seed"] == 4
    assert t.header["solver"]["iterations"] <= 2
    assert obj["nodes"] <= 2


def test_solve_with_config_solver_table(capsys, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("zones = \"paper\"\nalpha1_m = 400.0\n[solver]\nmax_iterations = 3\n", encoding="utf-8")
    code, out, err = run_main(capsys, ["solve", "--model", "m1", "--config", cfg, "--json", "--out", tmp_path / "o"])
    assert code == 0, err
    t = decode((tmp_path / "o" / "m1.table.rgt").read_bytes())
    assert t.header["params"]["alpha1_m"] == 400.0
    assert t.header["solver"]["max_iterations"] == 3
    assert one_json_object(out)["shipped"] is None           # other parameters: no shipped table to compare
    assert "shipped table" not in (tmp_path / "o" / "m1.summary.txt").read_text()


# ------------------------------------------------------------------ errors


def bad_pomdp(tmp_path):
    text = TIGER_PATH.read_text().replace("T: listen\nidentity", "T: listen\n0.5 0.4\n0.0 1.0")
    assert text != TIGER_PATH.read_text()
    path = tmp_path / "bad.pomdp"
    path.write_text(text)
    return path


def corrupted_table(tmp_path):
    good = tmp_path / "good"
    assert main(["solve", "--pomdp", str(TIGER_PATH), "--json", "--out", str(good), "--max-iterations", "5"]) == 0
    data = bytearray((good / "tiger.table.rgt").read_bytes())
    data[len(data) // 2] ^= 0x01
    path = tmp_path / "corrupt.table.rgt"
    path.write_bytes(bytes(data))
    return path


def toml(tmp_path, text):
    path = tmp_path / "cfg.toml"
    path.write_text(text, encoding="utf-8")
    return path


ERROR_CASES = {
    "malformed-toml": lambda p: ["solve", "--model", "m1", "--config", toml(p, "alpha1_m = = 3\n[solver\n"), "--out", p / "o"],
    "unknown-toml-key": lambda p: ["solve", "--model", "m1", "--config", toml(p, "alpha9_m = 1.0\n"), "--out", p / "o"],
    "wrong-toml-type": lambda p: ["solve", "--model", "m1", "--config", toml(p, 'alpha1_m = "x"\n'), "--out", p / "o"],
    "alpha2-above-alpha1": lambda p: ["solve", "--model", "m1", "--config", toml(p, "alpha2_m = 350.0\n"), "--out", p / "o"],
    "unknown-solver-key": lambda p: ["solve", "--model", "m1", "--config", toml(p, "[solver]\nmax_iteration = 3\n"), "--out", p / "o"],
    "solver-not-a-table": lambda p: ["solve", "--model", "m1", "--config", toml(p, "solver = 3\n"), "--out", p / "o"],
    "missing-config": lambda p: ["solve", "--model", "m1", "--config", p / "nope.toml", "--out", p / "o"],
    "pomdp-unknown-config-key": lambda p: ["solve", "--pomdp", TIGER_PATH, "--config", toml(p, "[solvr]\nmax_iterations = 3\n"), "--out", p / "o"],
    "pomdp-row-not-stochastic": lambda p: ["solve", "--pomdp", bad_pomdp(p), "--out", p / "o"],
    "pomdp-missing": lambda p: ["solve", "--pomdp", p / "nope.pomdp", "--out", p / "o"],
    "table-corrupted": lambda p: ["table", "show", corrupted_table(p)],
    "table-missing": lambda p: ["table", "show", p / "nope.table.rgt"],
    "table-not-a-table": lambda p: ["table", "show", TIGER_PATH],
    "table-is-a-directory": lambda p: ["table", "show", p],
}


@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_user_errors_are_one_line_exit_2(capsys, tmp_path, case):
    argv = [str(a) for a in ERROR_CASES[case](tmp_path)]
    capsys.readouterr()  # drop output of the set-up (e.g. solving the table to corrupt)
    code, out, err = run_main(capsys, argv)
    assert_one_line_error(code, err)
    assert not (tmp_path / "o").exists()  # nothing written when the input is refused


def test_error_messages_name_the_problem(capsys, tmp_path):
    code, _, err = run_main(capsys, ERROR_CASES["unknown-toml-key"](tmp_path))
    assert code == 2 and "alpha9_m" in err
    code, _, err = run_main(capsys, ERROR_CASES["pomdp-row-not-stochastic"](tmp_path))
    assert code == 2 and "listen" in err
    code, _, err = run_main(capsys, ERROR_CASES["table-corrupted"](tmp_path))
    assert code == 2 and "corrupt" in err.lower()
    code, _, err = run_main(capsys, ERROR_CASES["table-not-a-table"](tmp_path))
    assert code == 2 and "tiger.pomdp" in err


@pytest.mark.parametrize("case", ["malformed-toml", "pomdp-row-not-stochastic", "pomdp-missing",
                                  "table-corrupted", "table-missing", "table-not-a-table",
                                  "solver-not-a-table"])
def test_user_errors_in_a_subprocess_have_no_traceback(tmp_path, case):
    argv = [str(a) for a in ERROR_CASES[case](tmp_path)]
    proc = subprocess.run([sys.executable, "-m", "railguard", *argv], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("railguard: error: "), proc.stderr
    assert proc.stdout == ""


def test_subprocess_solve_and_show(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "railguard", "solve", "--pomdp", str(TIGER_PATH), "--json",
                           "--out", str(tmp_path)], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    obj = one_json_object(proc.stdout)
    assert obj["controller_value"] == pytest.approx(19.37, abs=0.01)
    proc = subprocess.run([sys.executable, "-m", "railguard", "table", "show", obj["table"]],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr
    assert "listen" in proc.stdout


def test_unknown_model_name_is_an_argparse_error(capsys, tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["solve", "--model", "m9", "--out", str(tmp_path)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "m9" in err and "Traceback" not in err


@pytest.mark.parametrize("argv", [["solve"], ["solve", "--model", "m1", "--pomdp", "x.pomdp"], ["table"],
                                  ["solve", "--model", "m1", "--max-iterations", "0"]])
def test_bad_usage_exits_2(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
