"""A failure's artefacts: its frames through the real codec as a candump log, the check that
`railguard replay` of that log decides what the closed loop decided, and the encounter as a
co-simulation scenario in the one scenario language (a lone blindness as the train FMU's
`blind` fault).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from monitor.core.config import Config

from ..campaign.tables import shipped_setup
from .disturbances import Disturbance
from .encounters import APPEAR_S, CHANNELS, NOISE_SIGMA_M, Encounter
from .loop import closed_loop


def write_candump(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, path: Path) -> Path:
    """The failure's frames through the real codec (TrainState and every ObstacleReport that
    was not lost, each cycle at its tick) as a candump -L log."""
    import can

    from can_bus.codec import OBSTACLE_IDS, TRAIN_STATE_ID, Sender, report_signals, train_signals
    from monitor.core.types import Train
    from can_bus.logfile import format_line

    rows = closed_loop(model, enc, d, world, cfg, keep=True)["rows"]
    sender = Sender()
    previous = [None] * CHANNELS
    lines = []
    for tick, reports, speed_cms, _demand, _v, _gap in rows:
        ts = tick / 1000.0
        frame = sender.frame(TRAIN_STATE_ID, train_signals(Train(speed_cms)))
        lines.append(format_line(can.Message(arbitration_id=TRAIN_STATE_ID, data=frame, is_extended_id=False), ts))
        for c, rep in enumerate(reports):
            if rep is previous[c]:
                continue                          # lost frame: nothing on the bus, the latched report ages
            previous[c] = rep
            frame = sender.frame(OBSTACLE_IDS[c], report_signals(rep, c))
            lines.append(format_line(can.Message(arbitration_id=OBSTACLE_IDS[c], data=frame, is_extended_id=False), ts))
    path.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


def replay_matches(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, log: Path) -> bool:
    """`railguard replay` of the log decides, cycle by cycle, what the closed loop decided."""
    from can_bus.replay import replay_file

    rows = closed_loop(model, enc, d, world, cfg, keep=True)["rows"]
    records, _ = replay_file(shipped_setup(model, cfg), log)
    return [r.demand for r in records[:len(rows)]] == [row[3] for row in rows]


def write_cosim_scenario(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, path: Path) -> Path:
    """The encounter as a scenario of the one language (monitor/scenario.py,
    docs/scenarios.md) that `railguard cosim FILE` plays: the world's train, the obstacle that
    comes into view `appear_m` ahead (the sensors reach that far) about APPEAR_S after the
    start, and the disturbance: a single blindness as the `blind` fault; any other
    disturbance listed as comments (the train FMU injects one fault). `railguard run FILE`
    refuses it in one line (the player has no brake dead time and no `blind` fault)."""
    from monitor import scenario as scenario_mod

    appear = enc.appear_m(cfg)
    lines = [f"# railguard stress: the likeliest failure found for table {model}, encounter {enc.name}",
             f"# ({enc.description}); the disturbances it needs:"]
    lines += [f"#   {json.dumps(e)}" for e in d.events(cfg.period_ms)]
    lines += [f'description = "stress {model} {enc.name}: obstacle comes into view {appear} m ahead at '
              f'{enc.speed_mps:g} m/s (the disturbances are listed above)"', "duration_s = 60.0", f'table = "{model}"',
              "", "[train]", f"speed_mps = {enc.speed_mps}"]
    fmu_names = world.fmu_parameters()
    for key, name in scenario_mod.FMU_TRAIN_NAMES.items():
        if key == "emergency_decel_mps2":
            lines.append(f"{key} = {[list(b) for b in world.emergency_decel]}")
        elif name in fmu_names and name != "mass":
            lines.append(f"{key} = {fmu_names[name]}")
    lines += ["", "[[obstacles]]", f"position_m = {round(appear + enc.speed_mps * APPEAR_S, 1)}", "",
              "[sensors]", f"range_m = {appear}", f"noise_sigma_m = {NOISE_SIGMA_M}", "seed = 1"]
    blind = np.nonzero(d.blind)[0]
    alone = d.count() == len(blind) and len(blind) and blind[-1] - blind[0] + 1 == len(blind)
    if alone:                           # one blindness and nothing else: the train FMU's `blind` fault is exactly it
        t0 = APPEAR_S + int(blind[0]) * cfg.period_ms / 1000.0
        lines += ["", "[[faults]]", 'kind = "blind"', f"start_s = {t0:.2f}",
                  f"end_s = {t0 + len(blind) * cfg.period_ms / 1000.0:.2f}"]
    text = "\n".join(lines) + "\n"
    scenario_mod.require(scenario_mod.loads(text, path.stem, str(path)), "cosim")     # the language's own check
    path.write_text(text, encoding="utf-8")
    return path
