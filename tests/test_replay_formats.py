"""`railguard replay` reads the log formats users have: candump .log, Vector .asc and .blf.

A recorded run converted to each format with python-can must replay to the same decisions.
"""
from __future__ import annotations

from importlib import resources

import can
import pytest

from can_bus import replay, scenario, session
from monitor.core import cycle
from monitor.core.config import Config


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("rec")
    setup = cycle.create(Config(), resources.files("monitor.tables").joinpath("m1.table.rgt").read_bytes())
    result = session.run_virtual(setup, scenario.load("static-obstacle"), out, plot=False)
    return setup, result.summary["log"], out


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_other_formats_replay_to_the_same_decisions(recorded, suffix):
    setup, log, out = recorded
    converted = out / f"bus{suffix}"
    with can.Logger(str(converted)) as writer:
        for msg in can.LogReader(log):
            writer.on_message_received(msg)
    base, stats = replay.replay_file(setup, log)
    other, other_stats = replay.replay_file(setup, converted)
    assert other_stats["frames"] == stats["frames"] > 1000
    assert [(d.tick, d.demand, d.mode, d.node) for d in other] == [(d.tick, d.demand, d.mode, d.node) for d in base]
    assert any(d.demand == 2 for d in base)


def test_replay_refuses_an_empty_log(recorded, tmp_path):
    empty = tmp_path / "empty.log"
    empty.write_text("")
    with pytest.raises(replay.ReplayError, match="no CAN frames"):
        replay.replay_file(recorded[0], empty)
