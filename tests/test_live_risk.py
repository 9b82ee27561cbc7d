"""Issue 31 item 6's machinery: the papers' risk read back from a recorded bus log with
python-can and cantools, the seed-001 world replayed on the bus, and the checks that would
catch a log that does not say what the monitor decided. The part itself runs in
`railguard verify --quick` (tests/test_verify.py); these are its pieces, small."""
from __future__ import annotations

import math

import numpy as np
import pytest

from can_bus.codec import MONITOR_RISK_ID
from can_bus.player import TraceRow
from can_bus.runner import per_mille_up
from can_bus.session import run_virtual
from monitor.core import cycle
from monitor.core.config import Config
from monitor.offline.risk import r2_linear
from monitor.tables import read
from verification.fastcore import zone_alphas, zone_of
from verification.live_risk.bus_log import monitor_signals
from verification.live_risk.measure import replay_agrees, seed000_episodes, seed000_figures
from verification.live_risk.players import seed000_scenarios, true_zones, world_scenario, world_trace_player
from verification.seed001.world import Settings, load_setup, simulate


@pytest.fixture(scope="module")
def episodes(tmp_path_factory):
    logs = tmp_path_factory.mktemp("live")
    eps, setup = seed000_episodes(2, 7, logs, lambda _msg: None)
    return eps, setup, logs


def test_bus_log_reads_every_cycle_as_the_runner_sent_it(tmp_path):
    """cantools' decode of the log = the runner's own records, cycle by cycle; the shell's
    last emergency after the final cycle is not read as a cycle."""
    setup = cycle.create(Config(), read("m1"), "m1")
    sc = seed000_scenarios(1, 3)[0]
    res = run_virtual(setup, sc, tmp_path, plot=False)
    sig = monitor_signals(tmp_path / f"run-{sc.name}.log")
    recs = res.runner.records
    assert [r.tick for r in recs] == sig["tick"].tolist()
    assert [r.demand for r in recs] == sig["level"].astype(int).tolist()
    assert [per_mille_up(r.r1_ppm) for r in recs] == np.rint(sig["r1_pct"] * 10).astype(int).tolist()
    assert [per_mille_up(r.r2_ppm) for r in recs] == np.rint(sig["r2_pct"] * 10).astype(int).tolist()
    assert [r.risk_category for r in recs] == sig["category"].astype(int).tolist()
    assert [r.table_risk_ppm for r in recs] == sig["table_ppm"].astype(int).tolist()
    assert sig["r2_pct"].max() > 40.0          # the obstacle came into the zones: not a flat log


def test_fig7c_from_the_bus_is_eq17_of_the_true_distance(episodes):
    """At the obstacle's first report, R2 on the bus is eq. 17 of the true distance (0.5 m
    noise, one cycle of travel, 0.1 % steps), about 0.5 as the paper's Fig. 7c; R1 low."""
    eps, _, _ = episodes
    for e in eps:
        assert e.first >= 0 and e.outcome == "stopped"
        assert abs(e.signals["r2_pct"][e.first] / 100 - e.r2_true_first) < 0.02
    f = seed000_figures(eps)
    assert 0.4 <= f["r2_first_mean"] <= 0.55 and f["r1_first_max"] < 0.1
    assert f["collisions"] == 0 and f["about_to_crash_cycles"] > 0


def test_replay_catches_a_log_whose_risk_was_altered(episodes, tmp_path):
    """The replay check compares every MonitorRisk frame: one R2 changed in the file (CRC
    bytes untouched: cantools does not check them) is found."""
    eps, setup, _ = episodes
    e = eps[0]
    ok, n = replay_agrees(setup, e.log, e.signals)
    assert ok and n == e.signals["tick"].size
    lines = e.log.read_text().splitlines()
    target = f"{MONITOR_RISK_ID:03X}#"
    k = next(i for i, line in enumerate(lines) if target in line and not line.split("#")[1].startswith("00000000"))
    head, data = lines[k].split("#")
    raw = bytearray(bytes.fromhex(data))
    raw[4] ^= 0x08                                # inside R2 (bits 31..41)
    lines[k] = head + "#" + raw.hex().upper()
    bad = tmp_path / "altered.log"
    bad.write_text("\n".join(lines) + "\n")
    sig = monitor_signals(bad)
    assert not np.array_equal(sig["r2_pct"], e.signals["r2_pct"])
    assert replay_agrees(setup, bad, sig)[0] is False


def test_a_recorded_seed001_world_replays_on_the_bus_as_it_ran(tmp_path):
    """The world-trace player gives the bus monitor the recorded world's inputs: it demands
    what the twin demanded on every cycle and sends the picture's category; fed another
    train's inputs, it would not."""
    run = simulate(Settings(trains=2, steps=400, record=2, belief_trains=0, seed=5))
    setup, _, _ = load_setup()
    for i in range(2):
        name = f"w{i}"
        run_virtual(setup, world_scenario(name, 400, 100), tmp_path, plot=False,
                    player=world_trace_player(run.trace, run.sample, i, setup))
        sig = monitor_signals(tmp_path / f"run-{name}.log")
        k = sig["tick"] // 100
        assert k.tolist() == list(range(400))
        assert np.array_equal(sig["level"], run.trace["demand"][k, i])
        present = run.sample["present"][k, i] > 0
        assert present.any()
        assert np.array_equal(sig["category"][present], run.sample["picture_risk"][k, i][present])
    other = monitor_signals(tmp_path / "run-w1.log")
    assert not np.array_equal(other["category"], monitor_signals(tmp_path / "run-w0.log")["category"])


def test_true_zones_cut_the_truth_as_the_monitor_cuts_its_picture():
    cfg = Config()
    rows = [TraceRow(0.0, 40.0, None, 0, 1, 0), TraceRow(0.1, 40.0, 300.0, 0, 1, 100),
            TraceRow(0.2, 20.0, 1000.0, 0, 1, 200)]
    tz = true_zones(cfg, np.array([0, 100, 200]), rows)
    assert math.isnan(tz["distance_m"][0]) and tz["zone"][0] == 0
    v = np.array([4000, 4000, 2000])
    a1, a2 = zone_alphas(cfg, v, v, 0)
    assert tz["zone"][1:].tolist() == zone_of(np.array([3000, 10000]), a1[1:], a2[1:], cfg.warning_margin_dm).tolist()
    assert tz["zone"][1] == 3                     # 300 m at 40 m/s: inside EBI
    assert 0.0 <= r2_linear(1000.0, tz["alpha1_m"][2], tz["alpha2_m"][2]) <= 1.0
