"""Seed 000's simulated world (section V), vectorised over trains and watched by the monitor.

`Scenario` states one world (monitor configuration, the train's braking, obstacles, sensor
noise, phantoms and misses); `simulate` runs many trains of it through
`fastcore.VectorMonitor`, keeping the metrics of all and the full trace of a few, and
`core_agreement` replays those through the real `monitor.core.cycle.step`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import EMERGENCY, R_LATCH, SERVICE
from monitor.offline.models import model1
from monitor.tables import read as read_table

from ..fastcore import VectorMonitor, agrees_with_core, zone_alphas, zone_of
from ..report import Progress
from ..world_metrics import PolicyCost, policy_alone


STATE_NAMES = ("Safe", "ObstacleDetected", "AboutToCrash", "Crash")
ZONE_NAMES = ("free", "warning", "emergency", "critical")
PAPER_REWARDS = (10.0, -10.0, -100.0, -1000.0)   # eq. 13 / Table 1
GAMMA = 0.95                                      # Table 1
DISCOUNT_STEPS = 700                              # 0.95**700 < 3e-16: the rest is below rounding
MAX_DM = 60000                                    # monitor input range (6 km)
# Monitor configuration whose zones at the paper's 40 m/s are exactly the paper's alpha1 = 300 m
# and alpha2 = 100 m: a train that brakes at once, exactly as declared (no build-up, traction
# cut-off, speed error, gradient or margin), one speed band: EBI = one cycle of travel (4 m) +
# v^2 / 2a, with a = 8.334 and 2.703 m/s^2 giving 96 m and 296 m, rounded up to the dm.
PAPER_ZONES = Config(emergency_decel_mms2=8334, emergency_band2_cms=0, service_decel_mms2=2703, emergency_buildup_ms=0,
                     service_buildup_ms=0, traction_cutoff_ms=0, max_accel_mms2=0, speed_error_permille=0,
                     max_gradient_permille=0, standstill_margin_dm=0, warning_margin_dm=2000)


@dataclass(frozen=True)
class Scenario:
    """One simulated world: monitor configuration, train braking, obstacle and sensor model."""

    key: str
    label: str
    config: Config = Config()
    brake_mps2: tuple = (1.0, 3.0)        # nominal, emergency braking of the train (Table 1)
    line_speed_mps: float = 40.0          # Table 1, initial train speed, also the line speed
    traction_mps2: float = 0.5            # ours: how the train regains line speed when not braked
    noise_sigma_m: float = 10.0           # ours (model1 default): sigma of the Gaussian distance noise
    obstacle_fraction: float = 0.2        # section V-B: obstacles about 20 % of the time
    obstacle_duration_s: float = 30.0     # ours (model1 default): mean time an obstacle stays
    appear_offset_m: float = 50.0         # section V-B: U[(a1 + a2) / 2, (a1 + a2) / 2 + 50 m]
    phantom: float = 0.0                  # per-step phantom report with no obstacle (model1: 0.02)
    miss: float = 0.0                     # per-step missed report of a present obstacle (model1: 0.02)
    phantom_module: bool = False          # a phantom is seen by one module (both its channels), not all six
    module0_range_m: float = 0.0          # > 0: module 0 sees only this far (a shorter-ranged module; issue 38 item 4)

    @property
    def dt(self) -> float:
        return self.config.period_ms / 1000.0

    def alphas_at_line_speed_m(self) -> tuple[float, float]:
        v = np.array([int(round(self.line_speed_mps * 100))])
        a1, a2 = zone_alphas(self.config, v, v, 0)      # a static obstacle: closing at the train's speed
        return float(a1[0]) / 10.0, float(a2[0]) / 10.0

    def appear_window_m(self) -> tuple[float, float]:
        a1, a2 = self.alphas_at_line_speed_m()
        lo = 0.5 * (a1 + a2)
        return lo, lo + self.appear_offset_m

    def hazards(self) -> tuple[float, float]:
        """(p_appear, p_clear) per step: mean stay obstacle_duration_s, stationary fraction f."""
        p_clear = min(1.0, self.dt / self.obstacle_duration_s)
        f = self.obstacle_fraction
        return p_clear * f / (1.0 - f), p_clear


SHIPPED = Scenario("shipped", "shipped Config, Table 1 braking (1 and 3 m/s^2)")
PAPER = Scenario("paper_zones", "paper zones: Config with alpha1/alpha2 = 300/100 m at 40 m/s, train braking 2.703 and 8.334 m/s^2",
                 config=PAPER_ZONES, brake_mps2=(PAPER_ZONES.service_decel_mms2 / 1000.0, PAPER_ZONES.emergency_decel_mms2 / 1000.0))
LITERAL = Scenario("paper_literal", "paper as printed: 300/100 m zones, train braking 1 and 3 m/s^2",
                   config=PAPER_ZONES, brake_mps2=(1.0, 3.0))
PHANTOMS = Scenario("shipped_phantoms", "shipped Config (emergency revocable) with the model's 2 % phantoms and 2 % misses",
                    phantom=0.02, miss=0.02)
MODULE_PHANTOMS = Scenario("module_phantoms", "shipped Config with 2 % phantoms, each seen by one module only "
                           "(both its channels; the other two report ABSENT), and 2 % misses",
                           phantom=0.02, miss=0.02, phantom_module=True)
PHANTOMS_HELD = Scenario("phantoms_held", "the same with emergency_release = 0 (an emergency held to standstill)",
                         config=Config(emergency_release=0), phantom=0.02, miss=0.02)

TRACE_KEYS = ("present", "distance_dm", "speed_cms", "demand", "observation", "node", "reasons", "warning", "track_dm",
              "track_cycles", "track_state")
EPISODE_KEYS = ("has", "true_m", "zone", "speed_mps", "reasons", "phantom")


@dataclass
class Run:
    scenario: Scenario
    trains: int
    steps: int
    seed: int
    metrics: dict
    trace: dict                      # (steps, recorded trains) arrays: the core's inputs and outputs
    episode: dict                    # (steps, recorded trains) arrays: ground truth of the same trains
    appear_step: np.ndarray          # first appearance step of each recorded train (-1: none)
    per_train_obstacle: np.ndarray = field(repr=False, default=None)
    cost: PolicyCost = field(repr=False, default=None)

    @property
    def train_seconds(self) -> float:
        return self.trains * self.steps * self.scenario.dt


def _move(v: np.ndarray, decel: np.ndarray, sc: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """(new speed, distance travelled) over one step: eq. 6 with the demanded deceleration;
    braking stops at standstill, traction stops at the line speed (exact piecewise motion)."""
    dt = sc.dt
    braking = decel > 0
    b = np.where(braking, decel, 1.0)
    stops = braking & (v <= b * dt)
    v_brake = np.where(stops, 0.0, v - b * dt)
    s_brake = np.where(stops, v * v / (2.0 * b), v * dt - 0.5 * b * dt * dt)
    a = sc.traction_mps2
    vl = sc.line_speed_mps
    t_up = np.clip((vl - v) / a, 0.0, dt) if a > 0 else np.zeros_like(v)
    v_trac = np.where(v < vl, v + a * t_up, v)
    s_trac = v * t_up + 0.5 * a * t_up * t_up + v_trac * (dt - t_up)
    return np.where(braking, v_brake, v_trac), np.where(braking, s_brake, s_trac)


def simulate(sc: Scenario, trains: int, seconds: float, seed: int, record: int = 24,
             progress: Progress | None = None, table: bytes | None = None, policy=None) -> Run:
    """Run `trains` trains for `seconds` through VectorMonitor; metrics over all of them,
    full inputs/outputs and ground truth for the first `record` trains. `table` (default
    the shipped m1) and `policy` (default: that table; see fastcore.TablePolicy) choose what
    proposes the demand behind the supervision; `Run.cost` counts what it cost per train."""
    setup = cycle.create(sc.config, table if table is not None else read_table("m1"))
    cfg = sc.config
    dt = sc.dt
    steps = int(round(seconds / dt))
    n = trains
    rec = min(record, n)
    rng = np.random.default_rng(seed)
    vm = VectorMonitor(setup, n, policy)
    cost = PolicyCost(n, dt)
    model_R = model1.reward(model1.Model1Params())      # R[s, a] the table was solved for
    paper_r = np.array(PAPER_REWARDS)
    p_appear, p_clear = sc.hazards()
    lo, hi = sc.appear_window_m()
    be = np.array([0.0, sc.brake_mps2[0], sc.brake_mps2[1]])

    v = np.full(n, float(sc.line_speed_mps))
    has = np.zeros(n, dtype=bool)
    d = np.zeros(n)
    prev_demand = np.zeros(n, dtype=np.int64)
    split_run = np.zeros(n, dtype=np.int64)
    ret = np.zeros(n)
    obst_steps = np.zeros(n, dtype=np.int64)
    trace = {k: np.zeros((steps, rec), dtype=bool if k == "present" else np.int64) for k in TRACE_KEYS}
    episode = {k: np.zeros((steps, rec), dtype=float if k in ("true_m", "speed_mps") else
                           (bool if k in ("has", "phantom") else np.int64)) for k in EPISODE_KEYS}
    appear_step = np.full(rec, -1, dtype=np.int64)

    m = {k: 0 for k in ("collisions", "appearances", "clearances", "obstacle_steps", "fp_steps", "fp_base",
                        "fn_steps", "fn_base", "perc_worse", "perc_better", "onsets", "false_onsets",
                        "onsets_no_obstacle", "stopped_steps", "service_steps", "emergency_steps",
                        "brake_no_obstacle", "noise_n", "phantoms", "misses", "held_standstill", "stops",
                        "stops_no_obstacle", "dispute_cycles", "disputes_persisting")}
    m.update(zone_true=np.zeros(4, dtype=np.int64), zone_obs=np.zeros(4, dtype=np.int64),
             reward_paper=0.0, reward_model=0.0, distance_m=0.0, appear_min=math.inf, appear_max=-math.inf,
             appear_sum=0.0, noise_sum=0.0, noise_sq=0.0, r1_first_max=0.0, r2_first_sum=0.0,
             r2_first_min=math.inf, r2_first_max=-math.inf, r2_first_n=0, collision_speeds=[])
    report_every = max(1, steps // 10)

    for k in range(steps):
        # draws in a fixed order every step, so results never depend on which branch is taken
        u_event = rng.random(n)
        u_pos = rng.random(n)
        noise = rng.standard_normal(n) * sc.noise_sigma_m
        u_phantom = rng.random(n)
        u_phantom_pos = rng.random(n)
        u_miss = rng.random(n)

        # 1. obstacle generation (section V-B): appears / clears as a two-state Markov process
        clear = has & (u_event < p_clear)
        new = ~has & (u_event < p_appear)
        has = (has & ~clear) | new
        d = np.where(new, lo + (hi - lo) * u_pos, d)
        m["clearances"] += int(clear.sum())
        m["appearances"] += int(new.sum())
        if new.any():
            pos = d[new]
            m["appear_min"] = min(m["appear_min"], float(pos.min()))
            m["appear_max"] = max(m["appear_max"], float(pos.max()))
            m["appear_sum"] += float(pos.sum())
        fresh_rec = new[:rec] & (appear_step < 0)
        appear_step[fresh_rec] = k

        # 2. perception (section V-A): true distance plus Gaussian noise, in dm, clipped to range
        v_cms = np.rint(v * 100.0).astype(np.int64)
        a1, a2 = zone_alphas(cfg, v_cms, v_cms, 0)     # static obstacles: closing at the train's speed
        true_dm = np.clip(np.rint(d * 10.0), 0, MAX_DM).astype(np.int64)
        zone_true = np.where(has, zone_of(true_dm, a1, a2, cfg.warning_margin_dm), 0)
        meas_dm = np.clip(np.rint((d + noise) * 10.0), 0, MAX_DM).astype(np.int64)
        missed = has & (u_miss < sc.miss)
        phantom = ~has & (u_phantom < sc.phantom)
        phantom_dm = np.rint(u_phantom_pos * (a1 + cfg.warning_margin_dm)).astype(np.int64)
        present = (has & ~missed) | phantom
        dist_dm = np.where(phantom, phantom_dm, np.where(has, meas_dm, 0))
        m["phantoms"] += int(phantom.sum())
        m["misses"] += int(missed.sum())
        far = has & ~missed & (d > 5.0 * sc.noise_sigma_m) & (d + 5.0 * sc.noise_sigma_m < MAX_DM / 10.0)
        err = (meas_dm[far] - np.rint(d[far] * 10.0)) / 10.0
        m["noise_n"] += int(far.sum())
        m["noise_sum"] += float(err.sum())
        m["noise_sq"] += float((err * err).sum())
        if new.any():   # the paper's risk estimators at the first report of each new obstacle
            seen = new & present & (a1 > a2) & (v_cms == int(round(sc.line_speed_mps * 100)))
            dm = dist_dm[seen] / 10.0
            al1, al2 = a1[seen] / 10.0, a2[seen] / 10.0
            r1 = 1.0 - 1.0 / (1.0 + np.exp(-5.0 * dm / al1))
            r2 = np.clip((al1 - dm) / (al1 - al2), 0.0, 1.0)
            if r2.size:
                m["r1_first_max"] = max(m["r1_first_max"], float(r1.max()))
                m["r2_first_sum"] += float(r2.sum())
                m["r2_first_n"] += int(r2.size)
                m["r2_first_min"] = min(m["r2_first_min"], float(r2.min()))
                m["r2_first_max"] = max(m["r2_first_max"], float(r2.max()))

        # 3. the monitor (all six channels repeat this one perception; in module_phantoms a
        #    phantom reaches one module, drawn only there so that the other worlds keep their draws)
        modules = np.where(phantom, 1 << rng.integers(0, 3, n), 7) if sc.phantom_module else None
        if sc.module0_range_m > 0:           # module 0 does not see beyond its shorter range
            modules = np.where(present & (dist_dm > sc.module0_range_m * 10), 6, 7 if modules is None else modules)
        out = vm.step(present, dist_dm, v_cms, closing_cms=v_cms, modules=modules)
        demand = out["demand"]
        obs = out["observation"]
        reasons = out["reasons"]
        # a dispute between modules persisting persistence_cycles while the train moves: what
        # would escalate to SAFE_STOP if module splits escalated as in-module ones do
        split_run = np.where(out["dispute"] & (v_cms > 0), split_run + 1, 0)
        m["dispute_cycles"] += int(out["dispute"].sum())
        m["disputes_persisting"] += int((split_run == cfg.persistence_cycles).sum())

        # 4. bookkeeping of this step (state before moving)
        braking = demand > 0
        held = (reasons & R_LATCH) != 0
        decided = braking & ~held     # braking asked for by this cycle's table or envelope, not the latch
        no_threat = zone_true <= 1
        moving = v_cms > 0
        m["fp_steps"] += int((decided & no_threat & moving).sum())
        m["fp_base"] += int((no_threat & moving).sum())
        m["held_standstill"] += int((braking & ~moving).sum())
        m["fn_steps"] += int((~braking & ~no_threat).sum())
        m["fn_base"] += int((~no_threat).sum())
        m["perc_worse"] += int((obs > zone_true).sum())
        m["perc_better"] += int((obs < zone_true).sum())
        onset = braking & (prev_demand == 0)
        m["onsets"] += int(onset.sum())
        m["false_onsets"] += int((onset & no_threat & moving).sum())
        m["onsets_no_obstacle"] += int((onset & ~has).sum())
        m["brake_no_obstacle"] += int((braking & ~has).sum())
        m["service_steps"] += int((demand == SERVICE).sum())
        m["emergency_steps"] += int((demand == EMERGENCY).sum())
        m["stopped_steps"] += int((v_cms == 0).sum())
        m["obstacle_steps"] += int(has.sum())
        obst_steps += has
        m["zone_true"] += np.bincount(zone_true, minlength=4)
        m["zone_obs"] += np.bincount(obs, minlength=4)
        m["reward_paper"] += float(paper_r[zone_true].sum())
        r_model = model_R[zone_true, demand]
        m["reward_model"] += float(r_model.sum())
        if k < DISCOUNT_STEPS:
            ret += GAMMA ** k * r_model
        prev_demand = demand
        cost.cycle(has, demand, policy_alone(reasons))

        if rec:
            for key, val in (("present", present), ("distance_dm", dist_dm), ("speed_cms", v_cms), ("demand", demand),
                             ("observation", obs), ("node", out["node"]), ("reasons", reasons), ("warning", out["warning"]),
                             *((key, out[key]) for key in ("track_dm", "track_cycles", "track_state"))):
                trace[key][k] = val[:rec]
            for key, val in (("has", has), ("true_m", d), ("zone", zone_true), ("speed_mps", v),
                             ("reasons", reasons), ("phantom", phantom)):
                episode[key][k] = val[:rec]

        # 5. the train moves (eqs. 6, 8, 11) under the demand; a collision removes the obstacle
        v_new, travel = _move(v, be[demand], sc)
        hit = has & (d - travel <= 0.0)
        if hit.any():
            m["collisions"] += int(hit.sum())
            m["collision_speeds"] += [float(x) for x in v[hit]]
        has = has & ~hit
        m["stops"] += int(((v > 0.0) & (v_new == 0.0)).sum())
        m["stops_no_obstacle"] += int(((v > 0.0) & (v_new == 0.0) & ~has).sum())
        cost.moved(v, v_new, new)
        d = d - travel
        v = v_new
        m["distance_m"] += float(travel.sum())
        if progress and (k + 1) % report_every == 0:
            progress(f"seed000 {sc.key}: {k + 1}/{steps} steps of {n} trains")

    m["discounted_return"] = float(ret.mean())
    m["discounted_return_se"] = float(ret.std(ddof=1) / math.sqrt(n)) if n > 1 else 0.0
    return Run(sc, n, steps, seed, m, trace, episode, appear_step, obst_steps, cost)


def expected_obstacle_fraction(sc: Scenario, steps: int) -> float:
    """Mean over steps 1..steps of P(obstacle) for the two-state chain started empty
    (the obstacle is drawn before the first perception)."""
    p_a, p_c = sc.hazards()
    f = p_a / (p_a + p_c)
    lam = 1.0 - p_a - p_c
    k = np.arange(1, steps + 1)
    return float(np.mean(f * (1.0 - lam ** k)))


def core_agreement(run: Run, trains: int) -> tuple[bool, int, int]:
    """(agree, cycles compared, trains compared) for the first `trains` recorded trains."""
    setup = cycle.create(run.scenario.config, read_table("m1"))
    k = min(trains, run.trace["present"].shape[1])
    ok, cycles = agrees_with_core(setup, run.trace, k)
    return ok, cycles, k
