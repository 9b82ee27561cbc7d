"""The monitor core vectorised over many trains at once (numpy), for Monte Carlo runs.

It covers the case the papers simulate: one perception source whose report every channel
repeats (all six channels fresh, in range and agreeing), so the voters pass the picture
through and no error rule fires. What remains of a cycle is the integer envelope, the
zone, the observation, the table step and the emergency latch, computed here with the
same integer formulas as monitor/core. `agrees_with_core` replays sampled trains through
the real `monitor.core.cycle.step` and compares every output: the Monte Carlo figures
are only as good as that check, which `railguard verify` runs every time.
"""
from __future__ import annotations

import numpy as np

from monitor.core import cycle
from monitor.core.types import (
    ABSENT, EMERGENCY, Inputs, NO_DISTANCE, PRESENT, R_ENVELOPE, R_LATCH, R_TABLE, Report, Train,
)


def braking_distance_dm(speed_cms: np.ndarray, decel_mms2: int, reaction_ms: int) -> np.ndarray:
    """monitor.core.envelope.braking_distance_dm on arrays (int64, rounded up)."""
    v = speed_cms.astype(np.int64)
    num = v * v * 10000 + 2 * decel_mms2 * v * reaction_ms
    den = 2 * decel_mms2 * 10000
    return -(-num // den)


class VectorMonitor:
    """n monitors stepped together; every channel of train i reports the same thing."""

    def __init__(self, setup: cycle.Setup, n: int):
        self.setup = setup
        self.cfg = setup.config
        self.action = np.asarray(setup.action, dtype=np.int64)
        self.next = np.asarray(setup.next, dtype=np.int64)
        self.node = np.full(n, setup.table.start, dtype=np.int64)
        self.latched = np.zeros(n, dtype=bool)
        self.m2 = setup.model == "m2"

    def step(self, present: np.ndarray, distance_dm: np.ndarray, speed_cms: np.ndarray,
             closing_cms: np.ndarray | None = None, obstacle: np.ndarray | None = None,
             track: np.ndarray | None = None, brake: np.ndarray | None = None) -> dict:
        """One cycle for all trains; returns demand, observation, node, reasons, distance."""
        cfg = self.cfg
        n = present.shape[0]
        zeros = np.zeros(n, dtype=np.int64)
        dist = np.where(present, distance_dm, NO_DISTANCE).astype(np.int64)
        alpha1 = braking_distance_dm(speed_cms, cfg.service_decel_mms2, cfg.reaction_ms)
        alpha2 = braking_distance_dm(speed_cms, cfg.emergency_decel_mms2, cfg.reaction_ms)
        env = present & (dist <= alpha2)
        zone = np.where(dist <= alpha2, 3, np.where(dist <= alpha1, 2, np.where(dist <= alpha1 + cfg.warning_margin_dm, 1, 0)))
        zone = np.where(present, zone, 0)
        if self.m2:
            closing = np.where(present, zeros if closing_cms is None else closing_cms, speed_cms)
            spd = np.where(closing < 0, 0, np.where(closing < cfg.fast_closing_cms, 1, 2))
            obst = np.where(present, zeros if obstacle is None else obstacle, 0)
            trk = zeros if track is None else track
            brk = zeros if brake is None else brake
            obs = (((zone * 3 + spd) * 3 + obst) * 2 + trk) * 2 + brk
        else:
            obs = zone
        self.node = self.next[self.node, obs]
        table = self.action[self.node]
        demand = np.maximum(table, np.where(env, EMERGENCY, 0))
        held = (self.latched | (demand == EMERGENCY)) & (speed_cms > 0)
        reasons = np.where(table > 0, R_TABLE, 0) | np.where(env, R_ENVELOPE, 0) | np.where(held & self.latched, R_LATCH, 0)
        self.latched = held
        final = np.where(held, EMERGENCY, demand)
        return {"demand": final, "observation": obs, "node": self.node.copy(), "reasons": reasons, "distance_dm": dist}


def core_outputs(setup: cycle.Setup, present, distance_dm, speed_cms, closing_cms=None, obstacle=None,
                 track=None, brake=None) -> list:
    """The real core over one train's sequence (arrays over time), all six channels alike."""
    state = cycle.initial_state(setup)
    outs = []
    for k in range(len(present)):
        tick = k * setup.config.period_ms
        p = bool(present[k])
        rep = Report(PRESENT if p else ABSENT, int(distance_dm[k]) if p else 0,
                     int(closing_cms[k]) if (p and closing_cms is not None) else 0,
                     int(obstacle[k]) if (p and obstacle is not None) else 0, tick)
        train = Train(int(speed_cms[k]), 0 if track is None else int(track[k]), 0 if brake is None else int(brake[k]))
        state, out = cycle.step(setup, state, Inputs((rep,) * setup.config.channels, train), tick)
        outs.append(out)
    return outs


def agrees_with_core(setup: cycle.Setup, trace: dict, trains: int = 20) -> tuple[bool, int]:
    """Replay the first `trains` trains of a recorded Monte Carlo trace through the real
    core; (all equal, cycles compared). `trace` holds (time, train) arrays of the inputs
    (present, distance_dm, speed_cms and, for m2, closing_cms, obstacle, track, brake) and
    of the outputs (demand, observation, node)."""
    compared = 0
    for i in range(min(trains, trace["present"].shape[1])):
        col = {k: (None if v is None else v[:, i]) for k, v in trace.items()}
        outs = core_outputs(setup, col["present"], col["distance_dm"], col["speed_cms"], col.get("closing_cms"),
                            col.get("obstacle"), col.get("track"), col.get("brake"))
        for k, out in enumerate(outs):
            if (out.demand, out.observation, out.node) != (col["demand"][k], col["observation"][k], col["node"][k]):
                return False, compared
            if out.mode != 1:     # NORMAL throughout: the vector model assumes no error rule fires
                return False, compared
            compared += 1
    return True, compared
