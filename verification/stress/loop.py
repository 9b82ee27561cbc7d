"""The closed loop: one encounter under one disturbance sequence, the shipped table behind the
supervision stepped by `monitor.core.cycle` exactly as the runner steps it, the world's train
(the train FMU's physics) moving with its demands; and batches of sequences as dask tasks.
"""
from __future__ import annotations

import math

from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import (ABSENT, MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS, NORMAL, PRESENT,
                                STATIC, Inputs, Report, Train)

from .. import world_train
from ..campaign.tables import shipped_setup
from ..scale import Cluster, map_ordered
from .disturbances import WINDOW, Disturbance
from .encounters import APPEAR_S, BEHIND_M, CHANNELS, ENCOUNTERS, GHOST_M, NOISE_SIGMA_M, RANGE_M, Encounter


def closed_loop(model: str, enc: Encounter, d: Disturbance, world: world_train.WorldTrain,
                cfg: Config = Config(), margin_m: float = 0.0, keep: bool = False) -> dict:
    """One encounter under disturbance `d`: the monitor (shipped table `model`) steps on what
    the six channels report, the world's train moves with its demands. Returns the verdict
    (`failure`: an avoidable collision or a gap below `margin_m`), the closest gap, the
    `cycles` of the window it read (the run's end depends on those only, so what `d` holds
    after them decides nothing) and, with `keep`, every cycle's reports, speed and demand
    (what the candump log is written from)."""
    setup = shipped_setup(model, cfg)
    period = cfg.period_ms
    state = cycle.initial_state(setup)
    twin = world_train.TrainTwin(world, enc.speed_mps, record=True)
    appear_m = enc.appear_m(cfg)
    obstacle_at = None                  # world position of the obstacle once it appeared
    latched = [None] * CHANNELS
    rows = []
    started, applied_before = False, 0
    released = False                    # an emergency let go to no braking while the train still moved towards the obstacle
    closest, collision, impact, unavoidable = math.inf, False, None, False
    k_appear = None
    cycles = 0                          # cycles of the window the run read (it stops once the train stands)
    for k in range(int(120 * 1000 / period)):
        tick = k * period
        t = twin.time if started else 0.0
        if started and obstacle_at is None and t >= APPEAR_S - 1e-9:
            obstacle_at = twin.position + appear_m
            k_appear = k
            unavoidable = not twin.can_stop_for(appear_m, 0.0, applied_before)
        j = None if k_appear is None else k - k_appear
        seen_x, seen_v = twin.at(t - world.sensor_latency_s) if started else (0.0, 0.0)
        gap = None if obstacle_at is None else obstacle_at - seen_x
        visible = gap is not None and 0.0 < gap <= RANGE_M
        dist = j is not None and 0 <= j < WINDOW
        if dist:
            cycles = j + 1
        for c in range(CHANNELS):
            if dist and d.drop[j, c]:
                continue                                    # lost: the latched report ages
            if visible and not d.module[c // 2] and not (dist and (d.blind[j] or d.miss[j, c])):
                x = gap + NOISE_SIGMA_M * (float(d.z[j, c]) if dist else 0.0)
                latched[c] = Report(PRESENT, min(MAX_DISTANCE_DM, max(0, round(x * 10))),
                                    max(-MAX_CLOSING_CMS, min(MAX_CLOSING_CMS, round(seen_v * 100))), STATIC, tick)
            elif visible and d.behind[0] and gap + BEHIND_M <= RANGE_M:   # missed: it sees past, to the object behind
                x = gap + BEHIND_M + NOISE_SIGMA_M * (float(d.z[j, c]) if dist else 0.0)
                latched[c] = Report(PRESENT, min(MAX_DISTANCE_DM, max(0, round(x * 10))),
                                    max(-MAX_CLOSING_CMS, min(MAX_CLOSING_CMS, round(seen_v * 100))), STATIC, tick)
            elif not visible and dist and d.ghost[j, c]:
                latched[c] = Report(PRESENT, round(GHOST_M * 10), round(seen_v * 100), STATIC, tick)
            else:
                latched[c] = Report(ABSENT, 0, 0, 0, tick)
        speed_cms = min(MAX_SPEED_CMS, round(twin.measured_speed() * 100)) if started else 0
        state, out = cycle.step(setup, state, Inputs(tuple(latched), Train(speed_cms, 0, 0), 0), tick)
        if keep:
            rows.append((tick, tuple(latched), speed_cms, out.demand, twin.speed if started else 0.0,
                         None if obstacle_at is None else obstacle_at - twin.position))
        if not started:
            started = out.mode == NORMAL and out.demand == 0
            if k > 100:
                raise RuntimeError("the monitor did not let the train enter within 10 s")
            continue
        for _ in twin.cycle(applied_before, out.demand, period):
            if obstacle_at is not None:
                g = obstacle_at - twin.position
                closest = min(closest, g)
                if g <= 0.0:
                    collision, impact = True, twin.speed
                    break
        if applied_before == 2 and out.demand == 0 and obstacle_at is not None and twin.speed > 0.0:
            released = True             # not a step down to service: no braking at all
        applied_before = out.demand
        if collision or (obstacle_at is not None and twin.speed == 0.0) or (j is not None and j > 600):
            break
    failure = (collision or closest < margin_m) and not unavoidable
    res = {"failure": bool(failure), "collision": collision, "unavoidable": unavoidable, "released": released,
           "closest_m": round(closest, 3), "impact_speed_mps": None if impact is None else round(impact, 3),
           "appear_m": appear_m, "cycles": cycles}
    if keep:
        res["rows"] = rows
    return res


def _evaluate(job: tuple) -> list[dict]:
    """A dask task: several disturbance sequences through the closed loop."""
    model, enc_name, world, cfg, margin_m, batch = job
    enc = ENCOUNTERS[enc_name]
    return [closed_loop(model, enc, d, world, cfg, margin_m) for d in batch]


def evaluate_all(model: str, enc: Encounter, ds: list[Disturbance], world, cfg: Config, margin_m: float,
                 cluster: Cluster, batch: int = 25) -> list[dict]:
    jobs = [(model, enc.name, world, cfg, margin_m, ds[i:i + batch]) for i in range(0, len(ds), batch)]
    return [r for chunk in map_ordered(_evaluate, jobs, cluster) for r in chunk]
