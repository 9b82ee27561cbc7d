"""Adaptive stress testing: the most likely way to a collision, and how likely collisions are.

ACAS X was validated by searching for the most likely path to failure, not only by random
runs. Here the path is a disturbance sequence on the six sensor channels during an
encounter: misses (a channel reports ABSENT with the obstacle in view; seed 002's p_n),
lost frames (the channel's latched report ages), ghosts (a phantom PRESENT) and distance
noise, each with a nominal probability (DISTURBANCES). The world is the campaign's: the
train FMU's physics (verification/world_train.py) on the braking declaration's worst
corner, its sensing and output latencies included; the monitor is the shipped table behind
the supervision, stepped by `monitor.core.cycle` exactly as the runner steps it. A failure is
a collision (or a gap below the margin) with an obstacle the world's train could have
stopped for.

The search is the cross-entropy method: disturbances are drawn from a proposal (independent
per cycle and channel), the runs closest to failure (then: the failures, weighted by their
likelihood ratio) refit the proposal, and the most likely failure seen is then pruned
greedily (every disturbance it can do without is removed). Its log-likelihood is given
relative to the undisturbed run (`log_likelihood`: the sum over its disturbances of
log(p / (1 - p)) for events and -z^2 / 2 for noise of z standard deviations).

The proposal the search converged to is also an importance-sampling density: the
probability of a collision per encounter is estimated with likelihood-ratio weights and a
95 % confidence interval, beside naive Monte Carlo at the same budget.

A failure is written as a candump log (through the real codec) that `railguard replay`
reproduces cycle by cycle, and as a co-simulation scenario of the same encounter: a single
blindness is the train FMU's `blind` fault, so the real FMUs replay it
(fmu/scenarios/stress-blackout-release.toml is the failure found; tests/test_cosim.py);
other disturbances are listed in it as comments.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Optional

import numpy as np
from monitor.core import cycle
from monitor.core.braking import curves
from monitor.core.config import Config
from monitor.core.types import (ABSENT, MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS, NORMAL, PRESENT,
                                STATIC, Inputs, Report, Train)

from . import world_train
from .report import Check, Progress, Section, md_table
from .scale import Cluster, map_ordered
from .world_metrics import wilson_upper

CHANNELS = 6
RANGE_M = 1000.0
NOISE_SIGMA_M = 0.5
GHOST_M = 200.0           # where a ghost is reported (beyond EBI: it can only add braking)
APPEAR_S = 2.0            # the obstacle appears this long after the train entered
WINDOW = 100              # cycles from the appearance on in which disturbances are searched (10 s)
P_MISS = 0.04             # seed 002: p_n, a channel's probability of a false negative
BETA = 0.05               # common-cause share of misses (IEC 61508-6 annex D's beta: 1 % to 10 %)
BLIND_STAYS = 0.9         # a common-cause blindness (glare, spray) goes on to the next cycle: 1 s on average
# nominal probability per cycle: `blind` (all six channels at once, a common cause) begins,
# and then lasts with BLIND_STAYS; the others per channel, independent
DISTURBANCES = {"blind": BETA * P_MISS, "miss": (1 - BETA) * P_MISS, "drop": 0.001, "ghost": 0.001}
EXPLORE = 0.05            # the search's first proposal: a common-cause blindness begins this likely
DEFENSIVE = 0.5           # importance sampling draws from the nominal model this often (bounded weights)
KINDS = tuple(DISTURBANCES)
SHAPES = {"blind": (WINDOW,), "miss": (WINDOW, CHANNELS), "drop": (WINDOW, CHANNELS), "ghost": (WINDOW, CHANNELS)}


@dataclass(frozen=True)
class Encounter:
    name: str
    speed_mps: float
    beyond_cycles: float      # the obstacle appears this many cycles of travel beyond EBI
    description: str

    def appear_m(self, cfg: Config) -> float:
        v = round(self.speed_mps * 100)
        ebi = curves(cfg, v, 0, 0, v, cfg.period_ms).ebi_dm / 10.0
        return round(ebi + self.beyond_cycles * self.speed_mps * cfg.period_ms / 1000.0, 1)


ENCOUNTERS = {e.name: e for e in (
    Encounter("edge-30", 30.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 30 m/s"),
    Encounter("edge-40", 40.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 40 m/s"),
    Encounter("edge-20", 20.0, 1.0, "a static object appears one cycle of travel beyond EBI, the train at 20 m/s"),
)}


# ----------------------------------------------------------------------------- disturbances

@dataclass
class Disturbance:
    """One disturbance sequence over the WINDOW cycles from the appearance (shapes: SHAPES)."""

    blind: np.ndarray         # (WINDOW,): every channel misses (a common cause)
    miss: np.ndarray          # (WINDOW, 6)
    drop: np.ndarray
    ghost: np.ndarray
    z: np.ndarray             # (WINDOW, 6) distance noise in standard deviations

    @staticmethod
    def none() -> "Disturbance":
        return Disturbance(*(np.zeros(SHAPES[k], dtype=bool) for k in KINDS), np.zeros((WINDOW, CHANNELS)))

    def copy(self) -> "Disturbance":
        return Disturbance(*(getattr(self, k).copy() for k in KINDS), self.z.copy())

    def count(self) -> int:
        return int(sum(getattr(self, k).sum() for k in KINDS))

    def log_likelihood(self) -> float:
        """Nominal log-likelihood relative to the undisturbed sequence (no event, no noise)."""
        return NOMINAL.log_density(self) - NOMINAL.log_density(Disturbance.none())

    def events_log_likelihood(self) -> float:
        """The same without the noise: what ranks failures before they are pruned."""
        return self.log_likelihood() + 0.5 * float(np.sum(self.z ** 2))

    def events(self, period_ms: int) -> list[dict]:
        """The disturbances as a list (noise listed where it exceeds 2 sigma)."""
        out = []
        for j in range(WINDOW):
            if self.blind[j]:
                out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": "all",
                            "kind": "blind"})
            for c in range(CHANNELS):
                for kind in KINDS[1:]:
                    if getattr(self, kind)[j, c]:
                        out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": c,
                                    "kind": kind})
                if abs(self.z[j, c]) > 2.0:
                    out.append({"cycle": j, "t_after_appearance_s": j * period_ms / 1000.0, "channel": c,
                                "kind": "noise", "metres": round(float(self.z[j, c]) * NOISE_SIGMA_M, 3)})
        return out

    def as_lists(self) -> dict:
        return {**{k: getattr(self, k).astype(int).tolist() for k in KINDS}, "z": np.round(self.z, 6).tolist()}

    @staticmethod
    def from_lists(data: dict) -> "Disturbance":
        return Disturbance(*(np.array(data[k], dtype=bool) for k in KINDS), np.array(data["z"], dtype=float))


@dataclass
class Proposal:
    """Blindness a Markov chain over the cycles (p["blind"][j]: it begins at j, `stays[j]`: it
    goes on from j - 1 to j); the other events independent per cycle and channel; Gaussian
    noise of unit spread around `mu`."""

    p: dict                   # kind -> probabilities of shape SHAPES[kind]
    mu: np.ndarray            # (WINDOW, 6) noise means, in sigmas
    stays: np.ndarray         # (WINDOW,) probability that a blindness goes on into cycle j

    @staticmethod
    def nominal() -> "Proposal":
        return Proposal({k: np.full(SHAPES[k], v) for k, v in DISTURBANCES.items()}, np.zeros((WINDOW, CHANNELS)),
                        np.full(WINDOW, BLIND_STAYS))

    def explore(self) -> "Proposal":
        """The search's first proposal: blindness (the one event that hides an obstacle from
        every channel at once) begins with EXPLORE in every cycle; the per-channel events
        start at their nominal rates (six independent misses in one cycle are 1e-8 likely)."""
        return Proposal({**self.p, "blind": np.maximum(self.p["blind"], EXPLORE)}, self.mu.copy(), self.stays.copy())

    def sample(self, rng: np.random.Generator) -> Disturbance:
        ev = [rng.random(SHAPES[k]) < self.p[k] for k in KINDS]
        u = rng.random(WINDOW)
        blind = np.zeros(WINDOW, dtype=bool)
        for j in range(WINDOW):
            blind[j] = u[j] < (self.stays[j] if j and blind[j - 1] else self.p["blind"][j])
        ev[0] = blind
        return Disturbance(*ev, self.mu + rng.standard_normal((WINDOW, CHANNELS)))

    def log_density(self, d: Disturbance) -> float:
        out = -0.5 * float(np.sum((d.z - self.mu) ** 2))
        for k in KINDS[1:]:
            x, p = getattr(d, k), self.p[k]
            out += float(np.sum(np.where(x, np.log(p), np.log1p(-p))))
        prev = np.r_[False, d.blind[:-1]]
        q = np.where(prev, self.stays, self.p["blind"])
        return out + float(np.sum(np.where(d.blind, np.log(q), np.log1p(-q))))


NOMINAL = Proposal.nominal()


def log_weight(d: Disturbance, proposal: Proposal) -> float:
    """log p(d) / q(d): the importance weight of a sample drawn from `proposal`."""
    return NOMINAL.log_density(d) - proposal.log_density(d)


# ----------------------------------------------------------------------------- the closed loop

@lru_cache(maxsize=8)
def _setup(model: str, cfg: Config) -> cycle.Setup:
    from monitor.tables import read

    return cycle.create(cfg, read(model))


def closed_loop(model: str, enc: Encounter, d: Disturbance, world: world_train.WorldTrain,
                cfg: Config = Config(), margin_m: float = 0.0, keep: bool = False) -> dict:
    """One encounter under disturbance `d`: the monitor (shipped table `model`) steps on what
    the six channels report, the world's train moves with its demands. Returns the verdict
    (`failure`: an avoidable collision or a gap below `margin_m`), the closest gap and, with
    `keep`, every cycle's reports, speed and demand (what the candump log is written from)."""
    setup = _setup(model, cfg)
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
        for c in range(CHANNELS):
            dist = j is not None and 0 <= j < WINDOW
            if dist and d.drop[j, c]:
                continue                                    # lost: the latched report ages
            if visible and not (dist and (d.blind[j] or d.miss[j, c])):
                x = gap + NOISE_SIGMA_M * (float(d.z[j, c]) if dist else 0.0)
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
           "appear_m": appear_m}
    if keep:
        res["rows"] = rows
    return res


def _evaluate(job: tuple) -> list[dict]:
    """A dask task: several disturbance sequences through the closed loop."""
    model, enc_name, world, cfg, margin_m, batch = job
    enc = ENCOUNTERS[enc_name]
    return [closed_loop(model, enc, Disturbance.from_lists(d), world, cfg, margin_m) for d in batch]


def evaluate_all(model: str, enc: Encounter, ds: list[Disturbance], world, cfg: Config, margin_m: float,
                 cluster: Cluster, batch: int = 25) -> list[dict]:
    jobs = [(model, enc.name, world, cfg, margin_m, [d.as_lists() for d in ds[i:i + batch]])
            for i in range(0, len(ds), batch)]
    return [r for chunk in map_ordered(_evaluate, jobs, cluster) for r in chunk]


# ----------------------------------------------------------------------------- the search

@dataclass(frozen=True)
class Budget:
    samples: int = 200        # per cross-entropy iteration
    iterations: int = 10
    elite: float = 0.1
    smoothing: float = 0.7
    is_samples: int = 1000    # importance sampling (and naive Monte Carlo) after the search


QUICK = Budget(samples=100, iterations=6, is_samples=400)


def _refit(proposal: Proposal, elites: list[Disturbance], weights: np.ndarray, smoothing: float) -> Proposal:
    """The blindness chain refitted to the elites (weighted); every other event keeps its
    nominal rate: each hides the obstacle from one channel only, which the 2oo2 and 3oo3
    voting answers (six independent misses in one cycle: 1e-8), and adapting 720 more
    parameters would only spread the importance weights."""
    w = weights / weights.sum()

    def blend(est, old, lo=1e-4, hi=0.98):
        return np.clip(smoothing * est + (1 - smoothing) * old, lo, hi)

    p = dict(proposal.p)
    blind = np.stack([e.blind for e in elites]).astype(float)           # (E, WINDOW)
    prev = np.concatenate([np.zeros((len(elites), 1)), blind[:, :-1]], axis=1)
    begins = (w @ (blind * (1 - prev))) / np.maximum(w @ (1 - prev), 1e-12)
    goes_on = (w @ (blind * prev)) / np.maximum(w @ prev, 1e-12)
    seen_prev = (w @ prev) > 0
    p["blind"] = blend(begins, proposal.p["blind"])
    stays = np.where(seen_prev, blend(goes_on, proposal.stays), proposal.stays)
    # the noise keeps its nominal spread and mean: it moves the voted distance by a few
    # sigmas (1 to 2 m) against margins of metres
    return Proposal(p, proposal.mu, stays)


def prune(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, margin_m: float,
          released: bool = False) -> Disturbance:
    """Remove every disturbance the failure does without (greedy): a locally most likely
    failure (with `released`: one that still comes after a released emergency)."""

    def fails(trial: Disturbance) -> bool:
        """still a failure, and a likelier one (ending a blindness in its middle may cost more)"""
        if trial.log_likelihood() <= best.log_likelihood():
            return False
        r = closed_loop(model, enc, trial, world, cfg, margin_m)
        return r["failure"] and (r["released"] or not released)

    best = d.copy()
    quiet = best.copy()
    quiet.z[:] = 0.0
    if fails(quiet):                   # most failures do not need the noise at all
        best = quiet
    changed = True
    while changed:
        changed = False
        for kind in ("ghost", "drop", "miss", "blind"):         # the likeliest events are kept longest
            for where in np.argwhere(getattr(best, kind)):
                trial = best.copy()
                getattr(trial, kind)[tuple(where)] = False
                if fails(trial):
                    best, changed = trial, True
        big = np.argwhere(np.abs(best.z) > 0.5)
        for j, c in big:
            trial = best.copy()
            trial.z[j, c] = 0.0
            if fails(trial):
                best, changed = trial, True
    return best


PRUNED = 8           # failures pruned to find the likeliest


def _likeliest(candidates: list, model: str, enc: Encounter, world, cfg: Config, margin_m: float,
               released: bool = False) -> Optional[dict]:
    """The candidates pruned (prune), the likeliest that still fails (and, with `released`,
    still fails after releasing an emergency), as the JSON of a failure."""
    best = None
    for d in candidates:
        d = prune(model, enc, d, world, cfg, margin_m, released)
        if best is None or d.log_likelihood() > best.log_likelihood():
            best = d
    if best is None:
        return None
    out = closed_loop(model, enc, best, world, cfg, margin_m)
    return {"log_likelihood": round(best.log_likelihood(), 3), "events": best.events(cfg.period_ms),
            "disturbance": best.as_lists(), "closest_m": out["closest_m"], "impact_speed_mps": out["impact_speed_mps"],
            "released_emergency": out["released"]}


def search(model: str, enc: Encounter, *, world=None, cfg: Config = Config(), budget: Budget = Budget(),
           margin_m: float = 0.0, seed: int = 0, cluster: Cluster = Cluster(), progress: Optional[Progress] = None) -> dict:
    """The cross-entropy search, the pruned most likely failure, and the rare-event estimate."""
    say = progress or (lambda msg: None)
    world = world or world_train.corners(cfg)[0]
    t0 = time.perf_counter()
    root = np.random.SeedSequence(seed)
    proposal = NOMINAL.explore()
    failures: list[tuple[float, bool, Disturbance]] = []
    history = []
    sims = 0
    n_elite = max(2, int(budget.elite * budget.samples))
    for it, ss in enumerate(root.spawn(budget.iterations)):
        rng = np.random.default_rng(ss)
        ds = [proposal.sample(rng) for _ in range(budget.samples)]
        res = evaluate_all(model, enc, ds, world, cfg, margin_m, cluster)
        sims += len(ds)
        fail = [i for i, r in enumerate(res) if r["failure"]]
        failures += [(ds[i].log_likelihood(), res[i]["released"], ds[i]) for i in fail]
        order = sorted(range(len(ds)), key=lambda i: (0, -ds[i].log_likelihood()) if res[i]["failure"]
                       else (1, res[i]["closest_m"]))
        elites = [ds[i] for i in order[:n_elite]]
        if len(fail) >= n_elite:        # the failure level is reached: weight elites towards the likeliest
            lw = np.array([log_weight(e, proposal) for e in elites])
            weights = np.exp(lw - lw.max())
        else:
            weights = np.ones(len(elites))
        proposal = _refit(proposal, elites, weights, budget.smoothing)
        best = max((f[0] for f in failures), default=None)
        history.append({"iteration": it, "failures": len(fail), "closest_m": min(r["closest_m"] for r in res),
                        "best_log_likelihood": best})
        say(f"stress {model} {enc.name}: iteration {it + 1}/{budget.iterations}: {len(fail)} of {len(ds)} runs fail, "
            f"closest {history[-1]['closest_m']:.2f} m"
            + (f", likeliest failure so far log-likelihood {best:.1f}" if best is not None else ""))
    most = most_released = None
    if failures:
        say(f"stress {model} {enc.name}: pruning the {min(PRUNED, len(failures))} likeliest failures "
            "(and of those after a released emergency)")
        by_events = sorted(failures, key=lambda f: -f[2].events_log_likelihood())
        most = _likeliest([f[2] for f in by_events[:PRUNED]], model, enc, world, cfg, margin_m)
        rel = [f for f in by_events if f[1]][:PRUNED // 2]
        most_released = _likeliest([f[2] for f in rel], model, enc, world, cfg, margin_m, released=True)
    say(f"stress {model} {enc.name}: importance sampling ({budget.is_samples} runs) and naive Monte Carlo (same budget)")
    rare = rare_events(model, enc, proposal, world, cfg, margin_m, budget.is_samples, root, cluster)
    return {"table": model, "encounter": asdict(enc), "appear_m": enc.appear_m(cfg),
            "world_train": world_train.as_dict(world), "margin_m": margin_m, "seed": seed,
            "budget": asdict(budget), "simulations": sims + 2 * budget.is_samples, "history": history,
            "failures_found": len(failures), "most_likely_failure": most,
            "most_likely_failure_after_release": most_released, "rare_event": rare,
            "seconds": round(time.perf_counter() - t0, 1)}


def rare_events(model: str, enc: Encounter, proposal: Proposal, world, cfg: Config, margin_m: float, n: int,
                root: np.random.SeedSequence, cluster: Cluster) -> dict:
    """P(failure per encounter): importance sampling from the defensive mixture of the nominal
    model and `proposal` (likelihood-ratio weights, at most 1 / DEFENSIVE; 95 % normal
    interval) against naive Monte Carlo from the nominal model at the same budget."""
    is_ss, mc_ss = root.spawn(2)
    rng = np.random.default_rng(is_ss)
    ds = [(NOMINAL if rng.random() < DEFENSIVE else proposal).sample(rng) for _ in range(n)]
    res = evaluate_all(model, enc, ds, world, cfg, margin_m, cluster)

    def weight(d: Disturbance) -> float:            # p / (a p + (1 - a) q): at most 1 / a
        lp, lq = NOMINAL.log_density(d), proposal.log_density(d)
        top = max(lp, lq)
        return math.exp(lp - top) / (DEFENSIVE * math.exp(lp - top) + (1 - DEFENSIVE) * math.exp(lq - top))

    w = np.array([weight(d) if r["failure"] else 0.0 for d, r in zip(ds, res)])
    p_is = float(w.mean())
    half = 1.96 * float(w.std(ddof=1)) / math.sqrt(n) if n > 1 else math.inf
    rng = np.random.default_rng(mc_ss)
    mc = evaluate_all(model, enc, [NOMINAL.sample(rng) for _ in range(n)], world, cfg, margin_m, cluster)
    hits = sum(r["failure"] for r in mc)
    return {"samples": n, "p_importance_sampling": p_is, "ci95": [max(0.0, p_is - half), p_is + half],
            "failures_in_is_samples": int(sum(r["failure"] for r in res)),
            "effective_sample_size": float(w.sum() ** 2 / (w ** 2).sum()) if w.any() else 0.0,
            "naive": {"failures": hits, "p": hits / n, "ci95_upper": wilson_upper(hits, n)}}


# ----------------------------------------------------------------------------- a failure's artefacts

def write_candump(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, path: Path) -> Path:
    """The failure's frames through the real codec (TrainState and every ObstacleReport that
    was not lost, each cycle at its tick) as a candump -L log."""
    import can

    from can_bus.codec import OBSTACLE_IDS, TRAIN_STATE_ID, Sender, report_signals
    from can_bus.logfile import format_line

    rows = closed_loop(model, enc, d, world, cfg, keep=True)["rows"]
    sender = Sender()
    previous = [None] * CHANNELS
    lines = []
    for tick, reports, speed_cms, _demand, _v, _gap in rows:
        ts = tick / 1000.0
        frame = sender.frame(TRAIN_STATE_ID, {"Speed": speed_cms, "TrackCondition": 0, "BrakeStatus": 0})
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
    records, _ = replay_file(_setup(model, cfg), log)
    return [r.demand for r in records[:len(rows)]] == [row[3] for row in rows]


def write_cosim_scenario(model: str, enc: Encounter, d: Disturbance, world, cfg: Config, path: Path) -> Path:
    """The encounter as a `railguard cosim` scenario: the world's train, the obstacle that
    comes into view `appear_m` ahead (the sensors reach that far) about APPEAR_S after the
    start, and the disturbance: a single blindness as the train FMU's `blind` fault; any
    other disturbance listed as comments (the FMU injects one fault)."""
    p = world.fmu_parameters()
    appear = enc.appear_m(cfg)
    lines = [f"# railguard stress: the likeliest failure found for table {model}, encounter {enc.name}",
             f"# ({enc.description}); the disturbances it needs:"]
    lines += [f"#   {json.dumps(e)}" for e in d.events(cfg.period_ms)]
    lines += [f'description = "stress {model} {enc.name}: obstacle comes into view {appear} m ahead at '
              f'{enc.speed_mps:g} m/s (the disturbances are listed above)"', "duration_s = 60.0", f'table = "{model}"',
              "", "[train]", f"initial_speed = {enc.speed_mps}"]
    lines += [f"{k} = {v}" for k, v in p.items() if k not in ("mass",)]
    lines += ["", "[train.obstacle]", "present = true", f"position = {round(appear + enc.speed_mps * APPEAR_S, 1)}", "",
              "[train.sensor]", f"range = {appear}", f"noise_sigma = {NOISE_SIGMA_M}", "seed = 1"]
    blind = np.nonzero(d.blind)[0]
    alone = d.count() == len(blind) and len(blind) and blind[-1] - blind[0] + 1 == len(blind)
    if alone:                           # one blindness and nothing else: the train FMU's `blind` fault is exactly it
        t0 = APPEAR_S + int(blind[0]) * cfg.period_ms / 1000.0
        lines += ["", "[train.fault]", 'kind = "blind"', f"start = {t0:.2f}",
                  f"end = {t0 + len(blind) * cfg.period_ms / 1000.0:.2f}"]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ----------------------------------------------------------------------------- the command and the report

def run(model: str, encounter: str = "edge-30", out_dir: Path = Path("railguard-out/stress"), *, quick: bool = False,
        cfg: Config = Config(), world=None, margin_m: float = 0.0, seed: int = 0, cluster: Cluster = Cluster(),
        progress: Optional[Progress] = None) -> dict:
    """`railguard stress`: the search, then the likeliest failure (if any) written as a
    candump log, checked by replaying it, and as a co-simulation scenario; stress.json."""
    enc = ENCOUNTERS[encounter]
    world = world or world_train.corners(cfg)[0]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result = search(model, enc, world=world, cfg=cfg, budget=QUICK if quick else Budget(), margin_m=margin_m,
                    seed=seed, cluster=cluster, progress=progress)
    files = []
    for key, stem in (("most_likely_failure", "failure"), ("most_likely_failure_after_release", "failure-after-release")):
        f = result[key]
        if f is None:
            continue
        d = Disturbance.from_lists(f["disturbance"])
        log = write_candump(model, enc, d, world, cfg, out / f"{stem}-{model}-{enc.name}.log")
        f["candump"] = str(log)
        f["replay_reproduces"] = replay_matches(model, enc, d, world, cfg, log)
        f["cosim"] = str(write_cosim_scenario(model, enc, d, world, cfg, out / f"{stem}-{model}-{enc.name}.cosim.toml"))
        files += [log, Path(f["cosim"])]
    files.append(plot(result, cfg, out / f"stress-{model}-{enc.name}.png"))
    result["files"] = [str(p) for p in files] + [str(out / "stress.json")]
    (out / "stress.json").write_text(json.dumps(result, indent=1, default=str) + "\n", encoding="utf-8")
    return result


def render(result: dict) -> str:
    enc, rare = result["encounter"], result["rare_event"]
    lines = [f"stress, table {result['table']}, encounter {enc['name']}: {enc['description']} "
             f"(appears {result['appear_m']} m ahead); {result['simulations']:,} closed-loop runs, {result['seconds']:.0f} s",
             f"  world train: {world_train.from_mapping(result['world_train'], 'world').describe()}"]
    for key, title in (("most_likely_failure", "likeliest failure"),
                       ("most_likely_failure_after_release", "likeliest failure after a released emergency")):
        f = result[key]
        if f is None:
            lines.append(f"  {title}: none found")
            continue
        lines.append(f"  {title}: log-likelihood {f['log_likelihood']:.2f} (against the undisturbed run), "
                     f"impact {f['impact_speed_mps']} m/s; {summarise(f['events'])}"
                     + (f"; replay of {f['candump']}: {'reproduces it' if f.get('replay_reproduces') else 'DIFFERS'}"
                        if "candump" in f else ""))
    lines.append(f"  P(collision per encounter): importance sampling {rare['p_importance_sampling']:.3g} "
                 f"(95 % {rare['ci95'][0]:.3g}..{rare['ci95'][1]:.3g}, effective sample size "
                 f"{rare['effective_sample_size']:.0f} of {rare['samples']}); naive Monte Carlo "
                 f"{rare['naive']['failures']} of {rare['samples']} = {rare['naive']['p']:.3g} "
                 f"(95 % upper {rare['naive']['ci95_upper']:.3g})")
    return "\n".join(lines) + "\n"


def summarise(events: list[dict]) -> str:
    """'blind 1.4-2.5 s; miss ch3 at 0.2 s' from a failure's event list."""
    blind = sorted(e["t_after_appearance_s"] for e in events if e["kind"] == "blind")
    parts = []
    if blind:
        runs, start = [], blind[0]
        for a, b in zip(blind, blind[1:] + [None]):
            if b is None or b - a > 0.1 + 1e-9:
                runs.append(f"{start:.1f}-{a + 0.1:.1f} s")
                start = b
        parts.append("every channel blind " + ", ".join(runs) + " after the obstacle appeared")
    others = [e for e in events if e["kind"] != "blind"]
    if others:
        parts.append(", ".join(f"{e['kind']} ch{e['channel']} at {e['t_after_appearance_s']:.1f} s" for e in others[:8])
                     + (f" and {len(others) - 8} more" if len(others) > 8 else ""))
    return "; ".join(parts) or "no disturbance"


def plot(result: dict, cfg: Config, path: Path) -> Path:
    """Speed and gap against time for the likeliest failures and the undisturbed run, blind
    windows shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    enc = ENCOUNTERS[result["encounter"]["name"]]
    world = world_train.from_mapping(result["world_train"], "world")
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    runs = [("undisturbed", Disturbance.none(), "tab:gray")]
    for key, label, color in (("most_likely_failure", "likeliest failure", "tab:red"),
                              ("most_likely_failure_after_release", "likeliest after a release", "tab:orange")):
        if result[key] is not None and (key == "most_likely_failure" or
                                        result[key]["disturbance"] != result["most_likely_failure"]["disturbance"]):
            runs.append((label, Disturbance.from_lists(result[key]["disturbance"]), color))
    for label, d, color in runs:
        rows = closed_loop(result["table"], enc, d, world, cfg, result["margin_m"], keep=True)["rows"]
        t = [r[0] / 1000.0 for r in rows]
        ax1.plot(t, [r[4] for r in rows], color=color, label=label)
        ax2.plot([x for x, r in zip(t, rows) if r[5] is not None], [r[5] for r in rows if r[5] is not None], color=color)
        appear = next((x for x, r in zip(t, rows) if r[5] is not None), None)
        if appear is not None and label != "undisturbed":
            for j in np.nonzero(d.blind)[0]:
                ax1.axvspan(appear + j * cfg.period_ms / 1000, appear + (j + 1) * cfg.period_ms / 1000, color=color,
                            alpha=0.15, lw=0)
    ax1.set_ylabel("speed (m/s)")
    ax2.set_ylabel("gap to the obstacle (m)")
    ax2.set_xlabel("time (s)")
    ax2.axhline(0.0, color="black", lw=0.8)
    ax1.legend(loc="upper right")
    ax1.set_title(f"stress {result['table']} {enc.name}: shaded = every channel blind")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def section(out_dir, quick: bool, progress: Progress, config: Optional[Config] = None, world=None,
            margin_m: float = 0.0, cluster: Cluster = Cluster()) -> Section:
    """Adaptive stress testing and rare events as a report part (both tables, edge-30)."""
    cfg = config or Config()
    out = Path(out_dir)
    checks, rows, figures = [], [], []
    results = {}
    # quick: the m2 table only; full: both, and m2 with every emergency held to standstill
    # (emergency_release = 0), the other side of the release trade-off
    variants = [("m2", "m2", cfg)] if quick else [("m1", "m1", cfg), ("m2", "m2", cfg),
                                                  ("m2", "m2 held", cfg._replace(emergency_release=0))]
    for model, name, run_cfg in variants:
        tag = name.replace(" ", "-")
        r = run(model, "edge-30", out / f"stress-{tag}", quick=quick, cfg=run_cfg, world=world, margin_m=margin_m,
                cluster=cluster, progress=progress)
        results[name] = r
        figures.append(f"stress-{tag}/stress-{model}-edge-30.png")
        for key in ("most_likely_failure", "most_likely_failure_after_release"):
            f = r[key]
            if f is not None:
                checks.append(Check(f"stress {name}: the {key.replace('_', ' ')} replays from its candump log",
                                    bool(f["replay_reproduces"]), f"{f['candump']}: "
                                    + ("same demand every cycle" if f["replay_reproduces"] else "demands differ")))
        rare = r["rare_event"]
        for key, label in (("most_likely_failure", "likeliest"), ("most_likely_failure_after_release", "after a release")):
            f = r[key]
            rows.append([name, label, "none found" if f is None else f"{f['log_likelihood']:.2f}",
                         "-" if f is None else summarise(f["events"])])
        rows.append([name, "P(collision per encounter)",
                     f"IS {rare['p_importance_sampling']:.3g} ({rare['ci95'][0]:.2g}..{rare['ci95'][1]:.2g}, "
                     f"ESS {rare['effective_sample_size']:.0f})",
                     f"naive MC {rare['naive']['failures']}/{rare['samples']} (95 % upper {rare['naive']['ci95_upper']:.2g})"])
    from .hazard import THR_CATASTROPHIC, THR_SIL3

    thr_rows = []
    for name, r in results.items():
        rare = r["rare_event"]
        for how, p, hi in (("importance sampling", rare["p_importance_sampling"], rare["ci95"][1]),
                           ("naive Monte Carlo", rare["naive"]["p"], rare["naive"]["ci95_upper"])):
            thr_rows.append([name, how, f"{p:.3g} /h (95 % upper {hi:.2g})",
                             f"{p / THR_SIL3:.2g}x" if p else "0", f"{p / THR_CATASTROPHIC:.2g}x" if p else "0"])
    md = ("The search (`railguard stress`, cross-entropy method; `verification/stress.py`) looks for the likeliest "
          "disturbance sequence that makes the world's train (the declaration's worst corner) hit an obstacle it could "
          "have stopped for, in the hardest encounter the supervision is built for: a static object appearing one cycle "
          "of travel beyond EBI at 30 m/s. Disturbances per cycle: a common-cause blindness of every channel (begins "
          f"with {DISTURBANCES['blind']:.3g}, goes on with {BLIND_STAYS}: seed 002's p_n = {P_MISS} times a beta factor "
          f"of {BETA}), independent misses ({DISTURBANCES['miss']:.3g} per channel), lost frames "
          f"({DISTURBANCES['drop']}), ghosts ({DISTURBANCES['ghost']}) and {NOISE_SIGMA_M} m distance noise. "
          "Log-likelihoods are against the undisturbed run. The probability of a collision per such encounter is "
          "estimated by importance sampling with the search's proposal (a defensive mixture with the nominal model) "
          "and by naive Monte Carlo at the same budget. These figures hold under this disturbance model only; "
          "its rates are assumptions, not measurements. Against the tolerable hazard rates of the hazard section "
          "(1e-9 /h, CSM-DT catastrophic; 1e-7 /h, SIL 3): at one such encounter per train-hour, the probability per "
          "encounter must stay below those numbers. `m2 held` (full mode) is the same table with every emergency held to "
          "standstill (`emergency_release = 0`): the other side of the release trade-off.\n\n"
          + md_table(["table", "what", "log-likelihood / estimate", "disturbance"], rows)
          + "\nThe rare-event estimates against the hazard section's tolerable hazard rates, at one such encounter "
            "per train-hour (the collision rate per hour is then the probability per encounter):\n\n"
          + md_table(["table", "estimate", "collisions per train-hour", "against THR 1e-7 /h (SIL 3)",
                      "against 1e-9 /h (CSM-DT catastrophic)"], thr_rows)
          + "\n" + "".join(f"![stress {name}]({f})\n" for name, f in zip(results, figures)))
    return Section("Adaptive stress testing and rare events", md, checks, figures,
                   headline={"stress": {m: {"most_likely_failure": r["most_likely_failure"] and
                                            r["most_likely_failure"]["log_likelihood"],
                                            "p_collision_per_encounter": r["rare_event"]["p_importance_sampling"]}
                                        for m, r in results.items()}})
