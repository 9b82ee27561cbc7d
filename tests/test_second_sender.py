"""Issue 39 items 2 and 3: a second sender on an ID is a fault, never a race, and the brake
side's reference receiver brakes on silence, a second sender, an unknown level and from
power-up, holding what it raised to standstill.

The closed-loop runs are `railguard run` as users run it (subprocess, both tables); each
attack is also played with the second-sender rule switched off, in process, to show that it
is the rule that stops the train (without it the forger wins: collision).
"""
from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest
from cantools.autosar.end_to_end import apply_profile2_crc

from can_bus import codec, session
from can_bus import scenario as scenarios
from can_bus.brake_receiver import TIMEOUT_PERIODS, BrakeReceiver
from can_bus.codec import BRAKE_DEMAND_ID, CONFLICT_WINDOW_MS, OBSTACLE_IDS, SECOND_SENDER_QUARANTINE_MS, Receiver
from monitor.core.config import Config
from monitor.core.types import ABSENT, EMERGENCY, PRESENT, Report
from verification.campaign.tables import shipped_setup

CH = 2
FID = OBSTACLE_IDS[CH]


def report(status: int, distance_dm: int = 0) -> dict:
    return codec.report_signals(Report(status, distance_dm, 2000 if status == PRESENT else 0, 0, 0), CH)


def demand(level: int, cycle: int) -> dict:
    return {"Level": level, "Warning": 0, "Reason": 0, "Cycle": cycle}


# ----------------------------------------------------------------------------- the receiver

def test_a_forged_frame_in_step_makes_the_channel_refused_until_a_second_after_the_last_conflict():
    rx = Receiver()
    assert rx.accept(FID, codec.encode(FID, report(PRESENT, 5000), 0), 0)
    # the forger's "absent" with the next counter comes first and is believed for a moment ...
    assert rx.accept(FID, codec.encode(FID, report(ABSENT), 1), 99)
    assert rx.reports[CH].status == ABSENT
    # ... until the genuine frame repeats that counter with other content: a second sender
    assert rx.accept(FID, codec.encode(FID, report(PRESENT, 4980), 1), 100) is None
    assert rx.rejected["second_sender"] == 1 and rx.reports[CH] is None and rx.contested(FID, 100)
    # refused, whoever sends, until SECOND_SENDER_QUARANTINE_MS after the last conflict
    for k, tick in enumerate(range(200, 100 + SECOND_SENDER_QUARANTINE_MS, 100)):
        assert rx.accept(FID, codec.encode(FID, report(PRESENT, 4960), 2 + k), tick) is None
    assert rx.reports[CH] is None and rx.contested(FID, 100 + SECOND_SENDER_QUARANTINE_MS - 1)
    assert not rx.contested(FID, 100 + SECOND_SENDER_QUARANTINE_MS)
    # then the genuine sender is heard again (one counter jump to resynchronise)
    t = 100 + SECOND_SENDER_QUARANTINE_MS
    assert rx.accept(FID, codec.encode(FID, report(PRESENT, 4800), 12), t) is None
    assert rx.accept(FID, codec.encode(FID, report(PRESENT, 4780), 13), t + 100) == "ObstacleReport_M2C1"
    assert rx.reports[CH].distance_dm == 4780 and rx.rejected["counter_jump"] == 1


def test_a_forger_that_keeps_going_keeps_the_channel_refused():
    rx = Receiver()
    rx.accept(FID, codec.encode(FID, report(PRESENT, 5000), 0), 0)
    for k in range(1, 40):                 # 4 s of a forger in step, every period
        rx.accept(FID, codec.encode(FID, report(ABSENT), k), 100 * k - 1)
        rx.accept(FID, codec.encode(FID, report(PRESENT, 5000 - 20 * k), k), 100 * k)
        assert rx.reports[CH] is None and rx.contested(FID, 100 * k)
    assert rx.rejected["second_sender"] == 2 * 39 - 1


def test_a_byte_equal_duplicate_is_harmless_and_an_old_repeat_is_no_conflict():
    rx = Receiver()
    frame = codec.encode(FID, report(PRESENT, 5000), 0)
    rx.accept(FID, frame, 0)
    assert rx.accept(FID, frame, 10) is None                   # a gateway's duplicate
    assert rx.rejected == {"repeated_counter": 1} and not rx.contested(FID, 10)
    assert rx.reports[CH].distance_dm == 5000
    # the same counter with other content long after (not within the window): no second sender
    late = CONFLICT_WINDOW_MS + 10
    assert rx.accept(FID, codec.encode(FID, report(PRESENT, 4000), 0), late) is None
    assert rx.rejected["repeated_counter"] == 2 and not rx.contested(FID, late)


# ----------------------------------------------------------------------------- the brake receiver

def feed(rx: Receiver, level: int, counter: int, tick: int) -> None:
    rx.accept(BRAKE_DEMAND_ID, codec.encode(BRAKE_DEMAND_ID, demand(level, counter), counter), tick)


def test_the_brake_receiver_brakes_from_power_up_until_the_first_valid_frame():
    rx, br = Receiver(), BrakeReceiver(100)
    assert br.level(rx, 0, 30.0) == EMERGENCY and br.latched is None and br.summary() == {"power_up": 1}
    feed(rx, 0, 0, 50)
    assert br.level(rx, 100, 30.0) == 0          # the first valid frame ends it, even under way


def test_silence_brakes_after_the_timeout_and_holds_to_standstill():
    rx, br = Receiver(), BrakeReceiver(100)
    feed(rx, 0, 0, 0)
    assert br.level(rx, 0, 0.0) == 0
    last = 0
    for k in range(1, 6):
        feed(rx, 0, k, 100 * k)
        last = 100 * k
        assert br.level(rx, last, 30.0) == 0
    # the monitor falls silent (crashed, bus-off): a frame younger than TIMEOUT_PERIODS periods
    # still counts ...
    assert br.level(rx, last + TIMEOUT_PERIODS * 100 - 1, 30.0) == 0
    # ... and at TIMEOUT_PERIODS periods the brakes apply (the timing contract's bound, exactly)
    assert br.level(rx, last + TIMEOUT_PERIODS * 100, 30.0) == EMERGENCY and br.latched == "timeout"
    # the monitor is back and says none: held while the train moves ...
    t = last + 1000
    feed(rx, 0, 6, t)
    assert br.level(rx, t, 12.0) == EMERGENCY
    feed(rx, 0, 7, t + 100)
    assert br.level(rx, t + 100, 0.0) == 0                     # ... released once it stands
    assert br.summary() == {"timeout": 2}


def test_a_second_sender_on_brake_demand_brakes():
    rx, br = Receiver(), BrakeReceiver(100)
    feed(rx, 0, 0, 0)
    br.level(rx, 0, 0.0)
    feed(rx, 2, 1, 100)                                        # the monitor demands emergency
    assert br.level(rx, 100, 30.0) == EMERGENCY and br.latched is None
    rx.accept(BRAKE_DEMAND_ID, codec.encode(BRAKE_DEMAND_ID, demand(0, 2), 2), 199)   # the forger's "none" first
    feed(rx, 2, 2, 200)                                        # the monitor's frame, same counter: a conflict
    assert br.level(rx, 200, 29.0) == EMERGENCY and br.latched == "second_sender"


def test_an_unknown_level_brakes_at_once():
    rx, br = Receiver(), BrakeReceiver(100)
    feed(rx, 0, 0, 0)
    br.level(rx, 0, 0.0)
    bad = bytearray(codec.encode(BRAKE_DEMAND_ID, demand(0, 1), 1))
    bad[1] |= 0x30                                            # Level = 3, then a CRC that fits
    rx.accept(BRAKE_DEMAND_ID, bytes(apply_profile2_crc(bad, codec.data_id(BRAKE_DEMAND_ID))), 100)
    assert rx.rejected["out_of_range"] == 1
    assert br.level(rx, 100, 20.0) == EMERGENCY and br.latched == "invalid_level"


# ----------------------------------------------------------------------------- closed loop, as users run it

ATTACKS = ("hostile-forged-absent", "hostile-forged-brake-none", "hostile-replay-absent", "hostile-replay-brake-none")


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory):
    exe = shutil.which("railguard")
    assert exe, "the railguard entry point is not installed (pip install -e .)"
    out = {}
    for name in ATTACKS:
        for table in ("m1", "m2"):
            d = tmp_path_factory.mktemp(f"{name}-{table}")
            p = subprocess.run([exe, "run", "--scenario", name, "--table", table, "--json", "--no-plot", "--out", str(d),
                                "--unsecured"],         # the unsecured bus: the rule is its only defence
                               capture_output=True, text=True, timeout=300)
            assert p.returncode == 0, p.stderr[-800:]
            out[name, table] = (json.loads(p.stdout), d / f"run-{name}.log")
    return out


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_forged_absent_in_step_stops_the_train_and_names_the_second_sender(cli_runs, table):
    s, _ = cli_runs["hostile-forged-absent", table]
    assert s["outcome"] == "stopped" and s["margin_m"] > 300, s
    assert s["rejects"]["second_sender"] > 1000 and s["faults_detected"]["frames_second_sender"] > 1000
    assert s["hostile_frames"]["forge_absent"] > 2000
    assert s["first_emergency_after_init_s"] == pytest.approx(5.1)   # the vehicle stops on the track at 5 s


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_forged_brake_none_stops_the_train_by_the_brake_receiver(cli_runs, table):
    s, _ = cli_runs["hostile-forged-brake-none", table]
    assert s["outcome"] == "stopped" and s["margin_m"] > 300, s
    assert s["brake_receiver"]["second_sender"] > 100
    assert s["rejects"]["foreign_output"] == s["hostile_frames"]["forge_brake_none"] > 300


@pytest.mark.parametrize("table", ["m1", "m2"])
def test_a_replay_of_recorded_frames_in_step_stops_the_train(cli_runs, table):
    """No forging: the node sends back the sensors' own recorded "absent" frames, and the
    monitor's own recorded "none" demands, byte for byte when each counter value is due."""
    s, _ = cli_runs["hostile-replay-absent", table]
    assert s["outcome"] == "stopped" and s["margin_m"] > 300 and s["hostile_frames"]["replay_absent"] > 2000, s
    assert s["rejects"]["second_sender"] > 1000 and s["first_emergency_after_init_s"] == pytest.approx(5.1)
    s, _ = cli_runs["hostile-replay-brake-none", table]
    # the recorded frames carry old Cycle values: they differ from the monitor's at once, and the
    # brake receiver holds the train from the first conflict (2 s), before the vehicle is there
    assert s["outcome"] == "stopped" and s["margin_m"] > 400 and s["brake_receiver"]["second_sender"] > 300, s


@pytest.mark.parametrize("name", ATTACKS)
def test_without_the_rule_the_forger_wins(name, tmp_path, monkeypatch):
    """The same attacks with the second-sender rule off (a repeat is never a conflict): the
    receivers keep the forger's frames and the train collides (issue 39's finding)."""
    monkeypatch.setattr(codec, "CONFLICT_WINDOW_MS", -1)
    res = session.run_virtual(shipped_setup("m2", Config()), scenarios.load(name), tmp_path, plot=False)
    assert res.summary["outcome"] == "collision"


def test_the_recorded_log_replayed_names_the_second_sender_on_the_brake_side(cli_runs):
    """`railguard replay` of the run's candump log: every frame also goes to the reference
    brake receiver, as the brake controller on that bus read it; it would have braked from
    the first conflict to the end, for the second sender alone."""
    _, log = cli_runs["hostile-forged-brake-none", "m2"]
    p = subprocess.run([shutil.which("railguard"), "replay", str(log), "--json", "--no-plot"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-800:]
    s = json.loads(p.stdout)
    assert set(s["brake_receiver"]) == {"second_sender"} and s["brake_receiver"]["second_sender"] > 300
    assert s["rejected"]["foreign_output"] > 300          # the monitor side flags the foreign sender
