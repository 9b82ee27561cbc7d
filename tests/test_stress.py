"""Adaptive stress testing (verification/stress/, `railguard stress`): the disturbance
model's likelihoods, the boundary of blindness the supervision survives at the EBI edge, the
failure the search found (a blackout during emergency braking releases the revocable
emergency) kept as a regression test, its candump log replayed by `railguard replay`, the
importance-sampling estimator, and the command as a user runs it."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu.scenario import load as load_cosim
from monitor.core.config import Config
from verification import stress as st
from verification import world_train as wt

ENC = st.ENCOUNTERS["edge-30"]
CORNER = wt.corners(Config())[0]
FOUND = Path(__file__).parent / "data" / "stress"


def test_log_likelihood_against_the_undisturbed_run():
    d = st.Disturbance.none()
    assert d.log_likelihood() == 0.0 and d.count() == 0
    pb, stays = st.DISTURBANCES["blind"], st.BLIND_STAYS
    d.blind[3:6] = True                                   # begins, goes on twice, ends
    expected = math.log(pb) + 2 * math.log(stays) + math.log(1 - stays) - 4 * math.log(1 - pb)   # cycles 3..6
    assert d.log_likelihood() == pytest.approx(expected, abs=1e-9)
    d.z[0, 0] = 2.0                                       # 2 sigma of noise costs 2
    assert d.log_likelihood() == pytest.approx(expected - 2.0, abs=1e-9)
    assert d.events_log_likelihood() == pytest.approx(expected, abs=1e-9)
    assert st.log_weight(d, st.NOMINAL) == 0.0


def test_blindness_the_supervision_survives_at_the_ebi_edge():
    """An object appears one cycle of travel beyond EBI (30 m/s, the declaration's worst
    train): undisturbed, the train stops about 27 m short; every channel blind for 0.8 s
    from the appearance still stops it; 0.9 s does not (nothing could brake for what no
    channel sees: the sensors' residual risk, not a monitor fault)."""
    assert ENC.appear_m(Config()) == 279.5
    calm = st.closed_loop("m2", ENC, st.Disturbance.none(), CORNER)
    assert not calm["failure"] and 20.0 < calm["closest_m"] < 35.0 and not calm["released"]
    for cycles, fails in ((8, False), (9, True)):
        d = st.Disturbance.none()
        d.blind[:cycles] = True
        res = st.closed_loop("m2", ENC, d, CORNER)
        assert res["failure"] is fails and not res["unavoidable"], (cycles, res)
        assert not res["released"]
    lost = st.Disturbance.none()
    lost.miss[:20, :5] = True                             # five of six channels miss for 2 s: the sixth suffices
    assert abs(st.closed_loop("m2", ENC, lost, CORNER)["closest_m"] - calm["closest_m"]) < 0.5


def test_the_found_failure_a_blackout_during_emergency_braking_releases_it():
    """Regression test of the search's finding (tests/data/stress): every channel blind for
    1.2 s, 2.2 s into the emergency braking, revokes the emergency (its cause looks gone
    for release_confirm_cycles), the train runs on and can no longer stop. Held to
    standstill (emergency_release = 0), the same blackout is survived."""
    data = json.loads((FOUND / "m2-edge-30-blackout-releases-emergency.json").read_text())
    d = st.Disturbance.from_lists(data["disturbance"])
    assert d.log_likelihood() == pytest.approx(data["log_likelihood"], abs=1e-3)
    assert {e["kind"] for e in data["events"]} == {"blind"}
    res = st.closed_loop("m2", ENC, d, CORNER)
    assert res["failure"] and res["collision"] and res["released"] and not res["unavoidable"]
    held = st.closed_loop("m2", ENC, d, CORNER, Config(emergency_release=0))
    assert not held["failure"] and not held["released"] and held["closest_m"] > 20.0


def test_a_failure_replays_from_its_candump_log(tmp_path):
    data = json.loads((FOUND / "m2-edge-30-blackout-releases-emergency.json").read_text())
    d = st.Disturbance.from_lists(data["disturbance"])
    log = st.write_candump("m2", ENC, d, CORNER, Config(), tmp_path / "failure.log")
    assert st.replay_matches("m2", ENC, d, CORNER, Config(), log)
    lines = log.read_text().splitlines()
    assert all(line.startswith("(") and " vcan0 " in line for line in lines)
    # a log that lost the obstacle's reports at the appearance no longer tells the same story
    first_report = next(i for i, line in enumerate(lines) if " 020#" in line and float(line[1:line.index(")")]) > 2.5)
    cut = tmp_path / "cut.log"
    cut.write_text("\n".join(line for i, line in enumerate(lines)
                             if not (" 02" in line and 0 <= i - first_report < 400)) + "\n")
    assert not st.replay_matches("m2", ENC, d, CORNER, Config(), cut)


def test_importance_sampling_with_the_nominal_proposal_is_naive_monte_carlo():
    from verification.scale import Cluster

    root = np.random.SeedSequence(3)
    cfg = Config(emergency_release=0)
    rare = st.rare_events("m2", ENC, st.NOMINAL, CORNER, cfg, 0.0, 60, root, Cluster(1))
    assert rare["failures_in_is_samples"] == round(rare["p_importance_sampling"] * 60)    # every weight is 1
    assert rare["effective_sample_size"] == pytest.approx(rare["failures_in_is_samples"]) or rare["failures_in_is_samples"] == 0
    assert 0.0 <= rare["ci95"][0] <= rare["p_importance_sampling"] <= rare["ci95"][1]


def test_railguard_stress_quick_finds_a_failure_that_replays(tmp_path):
    res = subprocess.run([sys.executable, "-m", "railguard", "stress", "--table", "m2", "--quick", "--json",
                          "--workers", "2", "--out", str(tmp_path)], capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout)
    f = out["most_likely_failure"]
    assert f is not None and -15.0 < f["log_likelihood"] < 0.0 and f["replay_reproduces"] is True
    assert Path(f["candump"]).is_file() and f["impact_speed_mps"] > 0.0
    scen = load_cosim(f["cosim"])
    assert scen.train["initial_speed"] == 30.0 and scen.train["sensor.range"] == out["appear_m"]
    rare = out["rare_event"]
    assert rare["samples"] == 400 and 0.0 < rare["p_importance_sampling"] < 1.0
    assert (tmp_path / "stress.json").is_file() and (tmp_path / "stress-m2-edge-30.png").read_bytes()[:4] == b"\x89PNG"
