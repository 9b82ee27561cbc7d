"""The seed worlds played on the in-process bus against the real monitor shell.

- Seed 000: `seed000_scenarios` turns the paper's episode (Table 1's train at 40 m/s braking
  at 1 and 3 m/s^2, a static obstacle appearing uniformly in [(alpha1 + alpha2) / 2, + 50 m]
  of the monitor's zones, NOISE_M of Gaussian distance noise on each channel) into scenarios
  for the ordinary scenario player: the world reacts to the demands the monitor sends.
- Seed 001: `WorldTracePlayer` sends, period by period, the sensor and train frames of one
  recorded train of the seed-001 world (eq. 9's misperceptions included). That world ran
  with the vectorised twin braking it; the monitor on the bus must demand the same on every
  cycle for the recorded truth to be its truth, and the part checks that it does.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Optional

import numpy as np

from can_bus.codec import OBSTACLE_IDS, TRAIN_STATE_ID, report_signals, train_signals
from can_bus.player import Player, TraceRow
from monitor.core.config import Config
from monitor.scenario import Scenario, parse

from ..fastcore import cycle_inputs, zone_alphas, zone_of
from ..seed000.world import SHIPPED

APPEAR_S = 2.0            # the obstacle appears this long after the train entered (at line speed)
EPISODE_S = 40.0          # long enough for the train to stop from 40 m/s at 3 m/s^2
# Each channel's noise. Seed 000's world reads one sensor with 10 m noise; six channels each
# that noisy disagree by more than the voter's 10 m tolerance about every second cycle, and
# the monitor runs in dispute (DEGRADED) from the first report on: the scenario player's
# default sensor (0.5 m) keeps the six channels in agreement, as the paper's one sensor is.
NOISE_M = 0.5


def seed000_scenarios(n: int, seed: int) -> list[Scenario]:
    """n seed-000 episodes (SHIPPED's world) as scenarios: the appearance distance drawn
    uniformly from SHIPPED.appear_window_m() with `seed`, the sensors' noise from `seed`."""
    sc = SHIPPED
    lo, hi = sc.appear_window_m()
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        d0 = float(rng.uniform(lo, hi))
        data = {
            "description": f"seed 000 episode {i}: a static obstacle appears {d0:.1f} m ahead at {APPEAR_S:g} s, 40 m/s",
            "duration_s": EPISODE_S,
            "train": {"speed_mps": sc.line_speed_mps, "service_decel_mps2": sc.brake_mps2[0],
                      "emergency_decel_mps2": sc.brake_mps2[1], "brake_buildup_s": 0.0,
                      "max_traction_mps2": sc.traction_mps2},
            "sensors": {"range_m": 6000.0, "noise_sigma_m": NOISE_M, "seed": int(seed * 1000 + i)},
            "obstacles": [{"position_m": sc.line_speed_mps * APPEAR_S + d0, "appear_s": APPEAR_S, "type": "static"}],
        }
        out.append(parse(data, f"seed000-live-{i:02d}"))
    return out


def true_zones(config: Config, tick_ms: np.ndarray, rows: list[TraceRow]) -> dict:
    """The world's truth per monitor tick: true distance (NaN: none), speed, and the true
    zone (0 free .. 3 critical) of the monitor's own curves at the true speed, a static
    obstacle closing at it (as seed 000's world cuts its states)."""
    by_tick = {r.tick: r for r in rows}
    dist = np.array([np.nan if (r := by_tick.get(int(t))) is None or r.distance_m is None else r.distance_m
                     for t in tick_ms])
    speed = np.array([by_tick[int(t)].speed_mps if int(t) in by_tick else np.nan for t in tick_ms])
    v_cms = np.rint(np.nan_to_num(speed) * 100).astype(np.int64)
    a1, a2 = zone_alphas(config, v_cms, v_cms, 0)
    d_dm = np.floor(np.nan_to_num(dist, nan=1e7) * 10).astype(np.int64)
    zone = np.where(np.isnan(dist), 0, zone_of(d_dm, a1, a2, config.warning_margin_dm))
    return {"distance_m": dist, "speed_mps": speed, "zone": zone, "alpha1_m": a1 / 10.0, "alpha2_m": a2 / 10.0}


@dataclass
class WorldTracePlayer(Player):
    """Plays column `column` of a seed-001 world trace: at tick k * period it sends the
    TrainState and the six ObstacleReports the world's sensors gave at step k (all channels
    alike, as the twin reads them), and keeps the world's truth in its trace rows."""

    world: Optional[dict] = None          # the trace (monitor inputs) of seed001.world.simulate
    truth: Optional[dict] = None          # its sample (truth, for the trace rows)
    column: int = 0
    setup: object = None
    steps: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        super().__post_init__()
        self.started = True
        self.steps = self.world["present"].shape[0]

    def step(self, tick: int, send: bool = True) -> None:
        self.drain(tick)
        k = tick // self.period_ms
        if k >= self.steps:
            return
        i = self.column
        columns = [self.world[key][:, i] for key in
                   ("present", "distance_dm", "speed_cms", "closing_cms", "obstacle", "track", "brake")]
        inputs = cycle_inputs(self.setup, k, *columns)
        status = self.receiver.status
        self.t = (k + 1) * self.period_ms / 1000
        dist = float(self.truth["distance_m"][k, i])
        self.trace.append(TraceRow(k * self.period_ms / 1000, float(self.truth["speed_mps"][k, i]),
                                   None if np.isnan(dist) else dist, self.demand(tick),
                                   None if status is None else int(status["Mode"]), tick))
        self.send(TRAIN_STATE_ID, self.sender.frame(TRAIN_STATE_ID, train_signals(inputs.train)))
        for ch, rep in enumerate(inputs.reports):
            self.send(OBSTACLE_IDS[ch], self.sender.frame(OBSTACLE_IDS[ch], report_signals(rep, ch)))

    @property
    def finished(self) -> bool:
        return self.t >= self.steps * self.period_ms / 1000 - 1e-9

    def outcome(self) -> dict:
        return {"outcome": "recorded world", "margin_m": None, "scenario_s": round(self.t, 1), "final_speed_mps": None}


def world_trace_player(world: dict, truth: dict, column: int, setup) -> partial:
    """run_virtual's `player` for one recorded seed-001 train."""
    return partial(WorldTracePlayer, world=world, truth=truth, column=column, setup=setup)


def world_scenario(name: str, steps: int, period_ms: int) -> Scenario:
    return Scenario(name, description="a recorded train of the seed-001 world", duration_s=steps * period_ms / 1000)
