"""The shell as a newcomer meets it (issue 15): every defect found by trying the CLI from a
fresh clone has a test here, run as a user runs it (`python -m railguard` in a subprocess)."""
from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from conftest import ROOT
from railguard.main import build_parser

ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def cli(*args, cwd=None, env=None, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "railguard", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or ROOT, env=env or ENV, timeout=timeout)


def one_line_error(res: subprocess.CompletedProcess, *needles: str) -> str:
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    assert "Traceback" not in res.stderr
    lines = res.stderr.splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("railguard: error: "), lines[0]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def subcommands() -> dict[str, argparse.ArgumentParser]:
    """Every (sub)command's parser, by its name ("table show" for nested ones)."""
    found = {}

    def walk(parser, prefix):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    found[(prefix + " " + name).strip()] = sub
                    walk(sub, prefix + " " + name)

    walk(build_parser(), "")
    return found


# ------------------------------------------------------------------ --help


def test_every_option_with_a_default_shows_it_in_help():
    for name, parser in subcommands().items():
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction, argparse._StoreTrueAction,
                                   argparse._VersionAction)):
                continue
            if not action.option_strings and action.nargs is None:
                continue        # a required positional: nothing to default
            if any(g.required and action in g._group_actions for g in parser._mutually_exclusive_groups):
                continue        # one of a required choice (solve --model | --pomdp)
            assert action.help and "default" in action.help, (name, action.dest, action.help)


def test_every_help_text_reads_as_written():
    """argparse %-formats option help but prints descriptions as written: a doubled %% in a
    description reached users as "2 %% phantoms" (railguard evaluate --help)."""
    for name, parser in subcommands().items():
        text = parser.format_help()
        assert "%%" not in text and "%(" not in text, (name, [l for l in text.splitlines() if "%" in l])


def test_one_default_table_everywhere():
    from monitor.tables import DEFAULT

    assert DEFAULT == "m2"
    for name, parser in subcommands().items():
        for action in parser._actions:
            if action.dest == "table" and action.default is not None:
                assert action.default == DEFAULT, (name, action.default)
    help_text = cli("build-fmu", "--help").stdout
    assert f"default: {DEFAULT}" in help_text


def test_help_of_scenario_commands_lists_every_shipped_scenario_they_play():
    from monitor import scenario

    entries = scenario.catalogue()
    assert {"static-obstacle", "late-obstacle", "stress-blackout-release"} <= {e.name for e in entries}
    for command, player in (("run", "run"), ("cosim", "cosim"), ("play", "run")):
        text = cli(command, "--help").stdout
        for e in entries:
            assert (e.name in text) == (player in e.players), (command, e.name, e.players)
    listing = json.loads(cli("scenarios", "--json").stdout)
    assert [x["name"] for x in listing] == [e.name for e in entries]


def test_play_help_promises_no_bus_it_refuses_and_refuses_in_one_line():
    text = " ".join(cli("play", "--help").stdout.split())
    assert "in-process virtual bus" not in text.split("--interface", 1)[1].split("--channel", 1)[0]
    one_line_error(cli("play", "static-obstacle"), "real bus")


# ------------------------------------------------------------------ conventions


def test_table_show_takes_a_shipped_name():
    res = cli("table", "show", "m1")
    assert res.returncode == 0, res.stderr
    assert "model m1" in res.stdout and "nodes" in res.stdout
    assert cli("table", "show").stdout.splitlines()[0].endswith("model m2")


def test_table_show_m2_is_read_in_a_minute_and_full_has_every_transition():
    """Issue 31 items 1 and 5: the summary fits 200 lines of at most 160 characters and names
    every node's action, its risk (the table's column, ppm) and its successors likeliest first
    with their probabilities (all of them, or the likeliest and how many more); --full lists
    every successor of every node."""
    import re

    from monitor.core.table import decode
    from monitor.tables import read

    t = decode(read("m2"))
    res = cli("table", "show", "m2")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert len(lines) <= 200 and max(len(line) for line in lines) <= 160
    assert f"{min(t.risk):,} .. {max(t.risk):,} ppm" in res.stdout            # the risk column's range
    rows = lines[lines.index(next(line for line in lines if line.startswith("node  action"))) + 1:]
    assert len(rows) == t.nodes
    for n, row in enumerate(rows):
        fields = row.split()
        assert fields[:2] == [str(n), t.actions[t.action[n]]] and int(fields[2].replace(",", "")) == t.risk[n]
        pieces = row.split(None, 3)[3].split("; ")
        more = re.fullmatch(r"\+(\d+) more \(--full\)", pieces[-1])
        shown = pieces[:-1] if more else pieces
        targets = set(t.next[n])
        nodes = [int(p.split()[0]) for p in shown]
        assert set(nodes) <= targets and len(nodes) + (int(more.group(1)) if more else 0) == len(targets), row
        chances = [0.0 if p.endswith("never") else float(p.split()[1]) for p in shown]
        assert chances == sorted(chances, reverse=True), row                  # the likeliest first
        assert sum(chances) <= 100 + 0.5 * len(chances)                         # rounded percentages
    full = cli("table", "show", "m2", "--full").stdout.splitlines()
    rows = full[full.index(next(line for line in full if line.startswith("node  action"))) + 1:]
    assert {int(x) for x in re.findall(r"(\d+) <- ", rows[0].split(None, 3)[3])} == set(t.next[0])
    assert max(len(line) for line in full) > 160                          # nothing left out there


def test_build_fmu_writes_under_railguard_out_and_lists_every_file(tmp_path):
    res = cli("build-fmu", "--table", "m1", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.splitlines() == [str(Path("railguard-out") / "railguard-monitor-m1-fmi2.fmu")]
    assert (tmp_path / "railguard-out" / "railguard-monitor-m1-fmi2.fmu").is_file()
    assert not list(tmp_path.glob("*.fmu"))
    res = cli("build-fmu", "--ssp", "no-obstacle", "--out", tmp_path / "ssp")
    assert res.returncode == 0, res.stderr
    listed = [Path(line) for line in res.stdout.splitlines()]
    assert sorted(p.suffix for p in listed) == [".fmu", ".fmu", ".ssp"], listed
    assert all(p.is_file() for p in listed)
    assert sorted(p.name for p in (tmp_path / "ssp").iterdir()) == sorted(p.name for p in listed)


def test_run_cut_short_by_duration_is_incomplete_and_honours_the_duration(tmp_path):
    res = cli("run", "--duration", "5", "--json", "--no-plot", "--out", tmp_path)
    assert res.returncode == 0, res.stderr
    s = json.loads(res.stdout)
    assert s["outcome"] == "incomplete"
    assert s["final_speed_mps"] > 20          # the train was still running when the run was cut
    assert s["cycles"] == 50                  # 5 s of 100 ms cycles on the simulated bus
    full = json.loads(cli("run", "--json", "--no-plot", "--out", tmp_path).stdout)
    assert full["outcome"] == "stopped" and full["cycles"] > 500


def test_run_text_output_lists_the_files_it_wrote(tmp_path):
    res = cli("run", "--quiet", "--out", tmp_path)
    assert res.returncode == 0, res.stderr
    wrote = res.stdout.split("wrote ", 1)[1].split()
    assert sorted(Path(p).name for p in wrote) == ["run-static-obstacle.log", "run-static-obstacle.png"]
    assert all(Path(p).is_file() for p in wrote)
    assert "first_emergency_after_init_s" in res.stdout and "init_cycles" in res.stdout


def test_monitor_only_run_explains_its_start_up_emergencies(tmp_path):
    res = cli("run", "--interface", "virtual", "--channel", "rg-shell-test", "--no-player", "--duration", "1", "--unsecured",
              "--json", "--no-plot", "--out", tmp_path)
    assert res.returncode == 0, res.stderr
    s = json.loads(res.stdout)
    assert s["outcome"] == "monitor_only"
    # nobody sends: every cycle is in start-up, braking; the summary says so instead of "first emergency: None"
    assert s["demands"]["emergency"] == s["init_cycles"] > 0
    assert s["first_emergency_after_init_s"] is None


# ------------------------------------------------------------------ errors: one line, exit 2


def test_cosim_with_a_file_that_is_not_an_fmu(tmp_path):
    junk = tmp_path / "junk.log"
    junk.write_text("(0.0) vcan0 123#00\n")
    one_line_error(cli("cosim", "--monitor-fmu", junk, "--train-fmu", junk, "--out", tmp_path), "junk.log", "not an FMU")


def test_cosim_json_stdout_stays_json_when_an_fmu_is_missing(tmp_path):
    res = cli("cosim", "--monitor-fmu", "/nonexistent.fmu", "--json", "--out", tmp_path)
    assert res.stdout == ""
    one_line_error(res, "/nonexistent.fmu")


def test_fmu_log_lines_go_to_stderr(tmp_path):
    """An FMU that logs (an error from a refused step) writes on stderr, never on stdout."""
    code = (
        "from fmu import build\n"
        "from fmu.driver import open_slave, close_slave\n"
        "from monitor.tables import read\n"
        f"p = build.build_monitor(read('m1'), 2, {str(tmp_path)!r})\n"
        "s, fmi, unzip = open_slave(p, 'monitor')\n"
        "s.setupExperiment(startTime=0.0); s.enterInitializationMode(); s.exitInitializationMode()\n"
        "try:\n    s.doStep(currentCommunicationPoint=0.0, communicationStepSize=-1.0)\n"
        "except Exception:\n    pass\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout == ""
    assert "[ERROR] monitor:" in res.stderr and "DoStep" in res.stderr


def test_run_with_an_unwritable_out_folder_is_one_line(tmp_path):
    res = cli("run", "--out", "/proc/railguard-x", "--no-plot")
    line = one_line_error(res, "/proc/railguard-x")
    assert "not properly shut down" not in res.stderr, line


def test_replay_of_a_text_file_names_the_file_and_line(tmp_path):
    text = tmp_path / "notes.log"
    text.write_text("hello\nworld\n")
    one_line_error(cli("replay", text, "--out", tmp_path), "notes.log:1", "not a candump line")


def test_config_errors_name_their_file(tmp_path):
    bad = tmp_path / "zones.toml"
    bad.write_text('zones = "paper"\nalpha1_m = -1.0\n')
    one_line_error(cli("solve", "--model", "m1", "--config", bad, "--out", tmp_path), "zones.toml", "alpha1_m")
    bad.write_text("alpha1_m = 800.0\n")
    one_line_error(cli("solve", "--model", "m1", "--config", bad, "--out", tmp_path), "zones.toml", "alpha1_m")
    mon = tmp_path / "monitor.toml"
    mon.write_text("[monitor]\nbogus = 1\n")
    one_line_error(cli("run", "--monitor-config", mon, "--out", tmp_path), "monitor.toml", "bogus")


def test_verify_names_missing_tools_and_how_to_install_them(tmp_path):
    bare = tmp_path / "bin"
    bare.mkdir()
    (bare / "python3").symlink_to(sys.executable)
    res = cli("verify", "--quick", "--part", "proof", "--out", tmp_path, env={**ENV, "PATH": str(bare)})
    line = one_line_error(res, "frama-c", "why3", "z3", "cvc4", "apt-get install", "--skip")
    assert "proof" in line


def _interactive_sigint() -> None:
    """Ctrl-C as a user at a terminal has it: the default disposition. A launcher that runs
    the tests as a background job (`cmd &` in a script) ignores SIGINT, and an ignored SIGINT
    is inherited, which would make this test about the launcher, not about railguard."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_in_a_campaign_is_one_line_and_exit_130(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "railguard", "campaign", "--quick", "--workers", "2", "--out",
                             str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            env=ENV, start_new_session=True, preexec_fn=_interactive_sigint)
    started = time.monotonic()
    while time.monotonic() - started < 120:          # wait until the workers are busy with core runs
        line = proc.stderr.readline()
        if "core runs: [" in line or not line:
            break
    os.killpg(proc.pid, signal.SIGINT)               # what Ctrl-C at a terminal does: the whole group
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    assert err.rstrip().splitlines()[-1] == "railguard: interrupted"


# ------------------------------------------------------------------ the README's commands


def readme_commands() -> list[list[str]]:
    """The railguard command lines of the README's shell blocks, as argument lists."""
    readme = (ROOT / "README.md").read_text()
    lines = []
    for block in readme.split("```sh")[1:]:
        for line in block.split("```", 1)[0].splitlines():
            line = line.split("#", 1)[0].strip()
            if line.startswith("railguard "):
                lines.append(line.split()[1:])
    return lines


def test_every_file_a_readme_command_reads_ships_with_the_repository():
    """A README command runs from a fresh clone as written: no file the user would have to write
    first (outputs of earlier commands, under railguard-out, excepted)."""
    commands = readme_commands()
    assert len(commands) > 20
    for argv in commands:
        for token in argv:
            if token.endswith((".toml", ".log", ".pomdp", ".rgt")) and not token.startswith("railguard-out/"):
                assert (ROOT / token).is_file(), (argv, token)


def test_every_readme_command_parses():
    parser = build_parser()
    for argv in readme_commands():
        args = parser.parse_args(argv)
        assert callable(args.func), argv


def test_the_readme_config_example_works_as_written(tmp_path):
    readme = (ROOT / "README.md").read_text()
    block = readme.split("```toml", 1)[1].split("```", 1)[0]
    shipped = (ROOT / "examples" / "m1-paper-zones.toml").read_text()
    assert block.strip() in shipped          # the README shows the file the command reads
    argv = next(a for a in readme_commands() if "--config" in a)
    res = cli(*argv, "--max-iterations", "3", "--out", tmp_path)
    assert res.returncode == 0, res.stderr
    assert "lower bound" in res.stdout


def test_cosim_at_a_step_that_does_not_divide_the_monitor_period(tmp_path):
    """Refused before issue 15 ("must divide 0.1 s"); the FMUs now take any communication step."""
    runs = {}
    for step in ("0.01", "0.025"):
        res = cli("cosim", "late-obstacle", "--step", step, "--json", "--no-plot", "--out", tmp_path / step)
        assert res.returncode == 0, res.stderr
        runs[step] = json.loads(res.stdout)
    assert runs["0.025"]["outcome"] == runs["0.01"]["outcome"] == "stopped"
    assert runs["0.025"]["monitor_cycles"] == runs["0.01"]["monitor_cycles"]
    assert abs(runs["0.025"]["margin_m"] - runs["0.01"]["margin_m"]) < 1.0
