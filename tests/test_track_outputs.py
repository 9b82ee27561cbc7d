"""The remembered obstacle (DESIGN.md section 14, issue 29 item 1) as the shells report it:
the run summary's `track`, `railguard replay` (its stats, the per-cycle JSON columns, the
change lines and the reason name `memory`) and the plot's track columns.

The log here is written by hand with the project's sender: every channel shows a static
obstacle 300 m ahead of a train at 10 m/s, then falls silent (no channel shows it, nothing
says it is gone: held), then reports ABSENT, fresh and unanimous, inside the sensor range
(confirming) until the memory is forgotten on that evidence. All fast: no scenario run.
"""
from __future__ import annotations

import dataclasses

import json
from pathlib import Path

import can
import pytest

from can_bus import codec, logfile, replay, session
from can_bus.clock import SimClock
from can_bus.runner import CycleRecord, MonitorRunner, TrackTally, track_columns
from monitor.core import cycle as core
from monitor.core import types as T
from monitor.core.config import Config, forget_cycles
from monitor.plot import held_spans, plot_run
from railguard.main import main

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "monitor" / "tables" / "m2.table.rgt"
PERIOD = 100
SEEN, SILENT, ABSENT_FOR = 20, 10, 85          # periods of each phase of the log (forget_ms: 75 cycles)
TRACK_KEYS = {"held_longest_s", "held_total_s", "forgotten", "passed", "memory_cycles"}
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def setup():
    return core.create(Config(), TABLE.read_bytes())


def rec(tick: int, state: int, track_dm: int = T.NO_DISTANCE, reasons: int = 0, cycles: int = 0) -> CycleRecord:
    return CycleRecord(tick, 0, reasons, T.NORMAL, 0, T.NO_DISTANCE, 0, False, 1000, False, False, track_dm, cycles,
                       state)


# ----------------------------------------------------------------------------- the tally

def test_track_tally_counts_spells_forgotten_passed_and_memory():
    N, S, H, C, F, P = (T.TRACK_NONE, T.TRACK_SEEN, T.TRACK_HELD, T.TRACK_CONFIRMING, T.TRACK_FORGOTTEN,
                        T.TRACK_PASSED)
    states = [N, S, H, C, H, F, N, S, H, S, H, H, P, N]
    memory = {2, 3, 4, 8, 10, 11}
    tally = TrackTally(PERIOD)
    for k, s in enumerate(states):
        tally.add(rec(k * PERIOD, s, 1000, T.R_MEMORY if k in memory else 0))
    # spells held unseen: cycles 2-4 (held, confirming, held: one spell), 8, 10-11
    assert tally.as_dict() == {"held_longest_s": 0.3, "held_total_s": 0.6, "forgotten": 1, "passed": 1,
                               "memory_cycles": 6}
    assert session.track_summary([rec(0, s) for s in states], 250)["held_longest_s"] == 0.75
    assert TrackTally(PERIOD).as_dict() == dict.fromkeys(TRACK_KEYS, 0) | {"held_longest_s": 0.0,
                                                                            "held_total_s": 0.0}


def test_the_run_summary_has_the_track(setup):
    with can.Bus(interface="virtual", channel="rg-track-summary", receive_own_messages=False) as bus:
        runner = MonitorRunner(bus, setup, SimClock())
        runner.run(cycles=3)
    summary = session.summarise(runner, None, None, None)
    assert set(summary["track"]) == TRACK_KEYS
    assert summary["track"]["forgotten"] == 0 and summary["track"]["held_total_s"] == 0.0
    # the run summary's risk: three INIT cycles without a channel heard read as an obstacle at
    # 0 m (R2 100 %, not low: silence is not clear), then a critical cycle at 80 % R2
    assert summary["risk"]["peak_r2_pct"] == 100.0 and summary["risk"]["low_s"] == 0.0
    runner.records.append(dataclasses.replace(rec(300, T.TRACK_SEEN), r1_ppm=2_001, r2_ppm=800_000, risk_score=17,
                                              risk_category=4, table_risk_ppm=584_188))
    risk = session.summarise(runner, None, None, None)["risk"]
    assert risk["peak_table_ppm"] == 584_188 and risk["critical_s"] == summary["risk"]["critical_s"] + 0.1
    assert sum(v for k, v in risk.items() if k.endswith("_s")) == pytest.approx(0.4)
    runner.records.pop()
    runner.records += [rec(400, T.TRACK_HELD, 900, T.R_MEMORY, 1), rec(500, T.TRACK_HELD, 800, T.R_MEMORY, 2),
                       rec(600, T.TRACK_FORGOTTEN)]
    track = session.summarise(runner, None, None, None)["track"]
    assert track == {"held_longest_s": 0.2, "held_total_s": 0.2, "forgotten": 1, "passed": 0, "memory_cycles": 2}
    # the status line names the remembered obstacle while no channel shows it
    line = session.status_line(runner.records[-2], None, period_ms=PERIOD)
    assert "remembered 80.0 m (held, unseen 0.2 s)" in line
    assert "remembered" not in session.status_line(runner.records[-1], None)


# ----------------------------------------------------------------------------- a log with a lost obstacle

@pytest.fixture(scope="module")
def lost_log(tmp_path_factory) -> Path:
    """Obstacle seen by every channel, then silence, then fresh unanimous ABSENT."""
    path = tmp_path_factory.mktemp("track") / "lost.log"
    tx = codec.Sender()
    lines = []
    for k in range(SEEN + SILENT + ABSENT_FOR):
        t = k * PERIOD / 1000 + 0.005
        frames = [(codec.TRAIN_STATE_ID, {"Speed": 1000})]
        if k < SEEN or k >= SEEN + SILENT:
            status = T.PRESENT if k < SEEN else T.ABSENT
            report = T.Report(status, 3000 - k * 10 if k < SEEN else 0, 0, T.STATIC, 0)
            frames += [(fid, codec.report_signals(report, ch)) for ch, fid in enumerate(codec.OBSTACLE_IDS)]
        for fid, signals in frames:
            msg = can.Message(arbitration_id=fid, data=tx.frame(fid, signals), is_extended_id=False)
            lines.append(logfile.format_line(msg, t))
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


@pytest.fixture(scope="module")
def lost(setup, lost_log):
    return replay.replay_file(setup, lost_log)


def test_replay_remembers_the_lost_obstacle_and_forgets_it_on_evidence(setup, lost):
    decisions, stats = lost
    states = [d.track_state for d in decisions]
    assert T.TRACK_SEEN in states and T.TRACK_HELD in states and T.TRACK_CONFIRMING in states
    assert states.count(T.TRACK_FORGOTTEN) == 1 and T.TRACK_PASSED not in states
    held = [d for d in decisions if d.track_state in (T.TRACK_HELD, T.TRACK_CONFIRMING)]
    # held unseen: a remembered distance, nearer each cycle (the train runs on), aged cycle by cycle
    assert all(d.track_dm != T.NO_DISTANCE and d.distance_dm == T.NO_DISTANCE for d in held)
    assert all(b.track_dm < a.track_dm for a, b in zip(held, held[1:]))
    assert [d.track_cycles for d in held] == list(range(1, len(held) + 1))
    assert all(d.reasons & T.R_MEMORY for d in held)
    # forgotten after forget_ms of evidence, and no track afterwards
    assert states[-1] == T.TRACK_NONE
    assert sum(s == T.TRACK_CONFIRMING for s in states) == forget_cycles(setup.config) - 1
    track = stats["track"]
    assert set(track) == TRACK_KEYS
    assert track["held_longest_s"] == track["held_total_s"] == len(held) * PERIOD / 1000
    assert track["forgotten"] == 1 and track["passed"] == 0
    assert track["memory_cycles"] == sum(bool(d.reasons & T.R_MEMORY) for d in decisions)


def test_replay_json_has_the_track_columns(lost_log, lost, tmp_path, capsys):
    decisions, stats = lost
    assert main(["replay", str(lost_log), "--json", "--no-plot", "--out", str(tmp_path)]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["decisions"] == [[d.tick, d.demand, d.reasons, d.mode, d.node, d.distance_dm, d.track_dm,
                                 d.track_state, d.track_cycles] for d in decisions]
    assert obj["track"] == stats["track"]


def test_replay_text_lists_the_track_and_the_reason_memory(lost_log, lost, tmp_path, capsys):
    decisions, stats = lost
    assert main(["replay", str(lost_log), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "track" in lines[0] and "reasons" in lines[0]
    first_held = next(d for d in decisions if d.track_state == T.TRACK_HELD)
    held_line = next(ln for ln in lines if ln.startswith(f"{first_held.tick / 1000:8.1f}"))
    assert f"held {first_held.track_dm / 10:.1f} m" in held_line and "memory" in held_line.split()[-1]
    assert any(" forgotten " in ln for ln in lines)
    track = stats["track"]
    assert (f"track held while no channel showed it: longest {track['held_longest_s']:g} s, "
            f"total {track['held_total_s']:g} s; forgotten on evidence 1, passed 0") in out
    # the live risk as the core gave it: peaks and the time per seed 001 category cover the replay
    risk = stats["risk"]
    assert risk["peak_r2_pct"] == max(d.r2_ppm for d in decisions) / 1e4
    assert risk["peak_table_ppm"] == max(d.table_risk_ppm for d in decisions) > 0
    assert sum(risk[f"{c}_s"] for c in ("low", "moderate", "high", "critical")) == pytest.approx(len(decisions) * PERIOD / 1000)
    assert (f"risk: peak R1 {risk['peak_r1_pct']:g} %, R2 {risk['peak_r2_pct']:g} %, "
            f"table {risk['peak_table_ppm']:,} ppm") in out
    png = tmp_path / f"replay-{lost_log.stem}.png"
    assert png.read_bytes()[:8] == PNG


# ----------------------------------------------------------------------------- the plot

def test_held_spans_cover_the_held_cycles():
    N, S, H, C = T.TRACK_NONE, T.TRACK_SEEN, T.TRACK_HELD, T.TRACK_CONFIRMING
    t = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    assert held_spans(t, [N, S, H, C, S, H, H]) == [(0.2, 0.4), (0.5, pytest.approx(0.7))]
    assert held_spans(t, [S] * 7) == [] and held_spans([], []) == []


def test_plot_run_draws_the_track_columns(lost, tmp_path):
    decisions, _ = lost
    t = [d.tick / 1000 for d in decisions]
    cols = track_columns(decisions)
    assert set(cols) == {"track_m", "track_state"}
    assert any(m is None for m in cols["track_m"]) and any(m is not None for m in cols["track_m"])
    out = plot_run(tmp_path / "track.png", "track", t, [10.0] * len(t), None,
                   [None if d.distance_dm == T.NO_DISTANCE else d.distance_dm / 10 for d in decisions],
                   [d.demand for d in decisions], [d.mode for d in decisions], **cols)
    assert out.read_bytes()[:8] == PNG
    # the columns are optional: each alone, and neither (the FMU's co-simulation has none yet)
    for extra in ({"track_m": cols["track_m"]}, {"track_state": cols["track_state"]}, {}):
        png = plot_run(tmp_path / f"track-{len(extra)}.png", "track", t, [10.0] * len(t), None, [None] * len(t),
                       [0] * len(t), [1] * len(t), **extra)
        assert png.read_bytes()[:8] == PNG
