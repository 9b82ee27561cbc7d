"""Hypothesis stateful test of the monitor cycle: arbitrary channel behaviour, train speeds and
deadline overruns, with the core's safety invariants checked after every cycle.

The expectations are computed here from the inputs, independently of the core's helpers
(only the braking curves `monitor.core.braking.curves`, tested on their own against exact
fractions in test_core_cycle.py, are reused).
"""
from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, rule, run_state_machine_as_test

import monitor
from monitor.core.config import Config
from monitor.core.cycle import create, initial_state, step
from monitor.core.braking import curves, ebi_dm
from monitor.core.observation import M2_OBSERVATIONS
from monitor.core.types import (
    DEGRADED, DEGRADED_MODE, EMERGENCY, INIT, NO_DISTANCE, NORMAL, PRESENT, R_DEADLINE, R_DISPUTE, R_INIT,
    R_SAFE_STOP, R_STALE, R_IMPLAUSIBLE, R_SYSTEM_ERROR, R_TRAIN_INPUT, SAFE_STOP, Inputs, Report, Train,
)

TABLES = Path(monitor.__file__).resolve().parent / "tables"
TABLE_BYTES = {m: (TABLES / f"{m}.table.rgt").read_bytes() for m in ("m1", "m2")}

# Documented ranges, written out here on purpose (not imported from the core).
MAX_DIST = 60000
MAX_CLOSING = 15000
MAX_SPEED = 12000

M2_NAMES = (
    ("far", "medium", "close", "critical"),
    ("away", "slow", "fast"),
    ("static", "dynamic", "train"),
    ("normal", "slippery"),
    ("normal", "degraded"),
)

# --------------------------------------------------------------------------- strategies

statuses = st.one_of(st.integers(0, 2), st.integers(0, 2), st.sampled_from([-1, 3, 7, 255]))
distances = st.one_of(
    st.integers(0, MAX_DIST),
    st.integers(0, 12000),
    st.sampled_from([0, 1, 2866, 2867, 2868, 8200, 8201, 10200, 10201, MAX_DIST, MAX_DIST + 1, -1, 10 ** 7]),
)
closings = st.one_of(
    st.integers(-MAX_CLOSING, MAX_CLOSING),
    st.sampled_from([-1, 0, 1, 1999, 2000, 2001, MAX_CLOSING, MAX_CLOSING + 1, -MAX_CLOSING - 1, 10 ** 6]),
)
obstacles = st.one_of(st.integers(0, 2), st.integers(0, 2), st.sampled_from([-1, 3, 7]))
# how old the report is when the next cycle runs (ms): fresh, at the edge, stale, or from the future
ages = st.one_of(
    st.sampled_from([0, 0, 0, 50, 100, 299, 300]),
    st.sampled_from([301, 400, 10 ** 6, -1, -100]),
)
speeds = st.one_of(
    st.integers(0, MAX_SPEED),
    st.sampled_from([0, 0, 1, 4000, MAX_SPEED, MAX_SPEED + 1, -1, -4000, 10 ** 9]),
)
junk = st.sampled_from([None, "1", "x", 1.5j, b"\x01", (1,)])


def is_int(x) -> bool:
    return type(x) is int


def channel_effective(report, now: int, timeout: int) -> int:
    """Independent freshness/range check: the status the voter must see."""
    if report is None:
        return DEGRADED
    fields = (report.status, report.distance_dm, report.closing_cms, report.obstacle, report.tick)
    if not all(is_int(f) for f in fields):
        return DEGRADED
    if not (0 <= now - report.tick <= timeout):
        return DEGRADED
    if not (0 <= report.status <= 2 and 0 <= report.distance_dm <= MAX_DIST
            and -MAX_CLOSING <= report.closing_cms <= MAX_CLOSING and 0 <= report.obstacle <= 2):
        return DEGRADED
    return report.status


class Story:
    """Independent witness of a channel's plausibility: the PRESENT samples (tick, distance,
    closing) since its reference; the obstacle ran at least the sum of the lower closing
    speed of each consecutive pair times their time apart. A sample farther than the
    reference less that, beyond twice the distance accuracy plus the closing accuracy over the
    span, is implausible until a whole window of samples agrees."""

    def __init__(self):
        self.samples, self.bad = [], False

    def see(self, present: bool, report, cfg: Config) -> bool:
        if not present:
            self.samples, self.bad = [], False
            return False
        t, d, c = report.tick, report.distance_dm, report.closing_cms
        if self.samples and t == self.samples[-1][0]:
            return self.bad
        if not self.samples or not 0 <= t - self.samples[-1][0] <= cfg.plausibility_ms:
            self.samples = [(t, d, c)]
            return self.bad
        self.samples.append((t, d, c))
        pairs = list(zip(self.samples, self.samples[1:]))
        least = sum(min(a[2], b[2]) * (b[0] - a[0]) for a, b in pairs) / 1e5      # metres
        most = sum(max(a[2], b[2]) * (b[0] - a[0]) for a, b in pairs) / 1e5
        t0, d0 = self.samples[0][0], self.samples[0][1] / 10
        span_s = (t - t0) / 1000
        allowed = 2 * cfg.distance_accuracy_dm / 10 + cfg.closing_accuracy_cms / 100 * span_s
        if d / 10 - (d0 - least) > allowed + 1e-9:
            self.samples, self.bad = [(t, d, c)], True
        elif (d0 - most) - d / 10 > allowed + 1e-9:
            self.samples = [(t, d, c)]
        elif t - t0 >= cfg.plausibility_ms:
            self.samples, self.bad = [(t, d, c)], False
        return self.bad


def train_valid(train) -> bool:
    if not isinstance(train, Train):
        return False
    v, k, b = train
    return is_int(v) and 0 <= v <= MAX_SPEED and k in (0, 1) and b in (0, 1) and is_int(k) and is_int(b)


class CoreMachine(RuleBasedStateMachine):
    """One monitor, fed by channels whose latest reports the rules change between cycles."""

    def __init__(self, model: str, cfg: Config):
        super().__init__()
        self.cfg = cfg
        self.model = model
        self.setup = create(cfg, TABLE_BYTES[model])
        self.table = self.setup.table
        self.n = cfg.channels
        self.state = initial_state(self.setup)
        self.now = 0
        self.reports: list = [None] * self.n
        self.train = Train(0)
        self.overruns = 0
        # model of the past, kept by the test itself
        self.prev_demand = 0
        self.e_run = 0
        self.prev_moving = False
        self.prev_node = self.table.start
        self.prev_mode = INIT
        self.seen = [False] * self.n
        self.disagree = [0] * cfg.modules
        self.cycles = 0
        self.stories = [Story() for _ in range(self.n)]

    # ------------------------------------------------------------------ rules: channels

    @property
    def next_tick(self) -> int:
        return self.now + self.cfg.period_ms

    @rule(ch=st.integers(0, 5), status=statuses, distance=distances, closing=closings,
          obstacle=obstacles, age=ages)
    def report(self, ch, status, distance, closing, obstacle, age):
        self.reports[ch % self.n] = Report(status, distance, closing, obstacle, self.next_tick - age)

    @rule(ch=st.integers(0, 5), field=st.sampled_from(Report._fields), value=junk)
    def corrupt_field(self, ch, field, value):
        ch %= self.n
        base = self.reports[ch] or Report(0, 0, 0, 0, self.next_tick)
        self.reports[ch] = base._replace(**{field: value})

    @rule(ch=st.integers(0, 5))
    def forget(self, ch):
        """The channel is lost: never heard from (None)."""
        self.reports[ch % self.n] = None

    @rule()
    def refresh_all(self):
        """Every channel repeats its latest report (ABSENT if none), fresh for the next cycle."""
        self.reports = [(r if r is not None and is_int(getattr(r, "tick", None)) else Report(0, 0, 0, 0, 0))
                        ._replace(tick=self.next_tick) for r in self.reports]

    @rule(status=st.integers(0, 1), distance=distances, closing=closings, obstacle=st.integers(0, 2),
          spread=st.integers(0, 3))
    def all_agree(self, status, distance, closing, obstacle, spread):
        """A healthy picture: every channel reports the same (distances may differ a little)."""
        self.reports = [Report(status, max(0, distance + i * spread), closing, obstacle, self.next_tick)
                        for i in range(self.n)]

    @rule(offset=st.integers(-3, 3), ch=st.integers(0, 5), others=st.sampled_from(["same", "absent", "stale"]))
    def obstacle_near_envelope(self, offset, ch, others):
        """Channel ch (and maybe the others) sees an obstacle right at the emergency braking distance."""
        valid = train_valid(self.train)
        v = self.train.speed_cms if valid else 0
        track, brake = (self.train.track, self.train.brake) if valid else (0, 0)
        d = max(0, curves(self.cfg, v, track, brake, 100, 0).ebi_dm + offset)
        t = self.next_tick
        for i in range(self.n):
            if others == "same" or i == ch % self.n:
                self.reports[i] = Report(PRESENT, d, 100, 0, t)
            elif others == "absent":
                self.reports[i] = Report(0, 0, 0, 0, t)
            else:
                self.reports[i] = Report(0, 0, 0, 0, t - 10 ** 4)

    # ------------------------------------------------------------------ rules: train, deadline

    @rule(v=speeds, track=st.sampled_from([0, 1, 0, 2]), brake=st.sampled_from([0, 1, 0, -1]))
    def set_train(self, v, track, brake):
        self.train = Train(v, track, brake)

    @rule(bad=st.sampled_from([None, "train", Train(None), Train("0"), Train(True), (4000, 0, 0)]))
    def bad_train(self, bad):
        self.train = bad

    @rule(k=st.one_of(st.just(0), st.integers(0, 5)))
    def set_overruns(self, k):
        self.overruns = k

    # ------------------------------------------------------------------ the cycle

    @rule(times=st.integers(1, 4))
    def advance(self, times):
        for _ in range(times):
            self.cycle()

    def cycle(self):
        self.now = self.next_tick
        cfg, now = self.cfg, self.now
        inputs = Inputs(tuple(self.reports), self.train, self.overruns)
        self.state, out = step(self.setup, self.state, inputs, now)   # must never raise
        self.cycles += 1

        # ---- independent expectations
        timeout = cfg.timeout_cycles * cfg.period_ms
        eff = [channel_effective(r, now, timeout) for r in self.reports]
        implausible = [self.stories[i].see(s == PRESENT, self.reports[i], cfg) for i, s in enumerate(eff)]
        eff = [DEGRADED if bad else s for s, bad in zip(eff, implausible)]
        for i, s in enumerate(eff):
            if s != DEGRADED:
                self.seen[i] = True
        present = [i for i, s in enumerate(eff) if s == PRESENT]
        dmin = min((self.reports[i].distance_dm for i in present), default=NO_DISTANCE)
        modules = [max(eff[2 * m], eff[2 * m + 1]) for m in range(cfg.modules)]
        flags = [eff[2 * m] != eff[2 * m + 1] or DEGRADED in eff[2 * m:2 * m + 2]
                 or (eff[2 * m] == eff[2 * m + 1] == PRESENT
                     and abs(self.reports[2 * m].distance_dm - self.reports[2 * m + 1].distance_dm) > cfg.distance_tolerance_dm)
                 for m in range(cfg.modules)]
        split = len(set(modules)) > 1
        any_degraded = DEGRADED in eff
        for m in range(cfg.modules):
            pair = {eff[2 * m], eff[2 * m + 1]}
            self.disagree[m] = self.disagree[m] + 1 if pair == {0, 1} else 0
        perceptor = max(self.disagree) >= cfg.persistence_cycles
        overrun = self.overruns >= cfg.max_overruns
        valid = train_valid(self.train)
        moving = (not valid) or self.train.speed_cms > 0
        ctx = (f"cycle {self.cycles} now={now} eff={eff} reports={self.reports} train={self.train} "
               f"overruns={self.overruns} -> {out}")

        # ---- ranges
        assert out.demand in (0, 1, 2), ctx
        assert out.mode in (0, 1, 2, 3), ctx
        assert 0 <= out.node < self.table.nodes, ctx
        assert 0 <= out.observation < len(self.table.observations), ctx
        assert out.cycle == self.cycles, ctx

        # ---- voting
        if present:
            assert out.distance_dm != NO_DISTANCE or out.system_error, ctx
        assert out.distance_dm == dmin, "voted distance is not the shortest fresh PRESENT report: " + ctx
        assert out.module_flags == sum(1 << m for m, f in enumerate(flags) if f), ctx
        if any(flags) or split or any_degraded:
            assert out.system_error, ctx
            assert out.reasons & R_SYSTEM_ERROR, ctx
            if any_degraded:       # a lost channel: the safe reaction (INIT's emergency covers it)
                assert out.demand >= cfg.safe_reaction, ctx
            elif valid:            # channels disagree, all fresh: a dispute, answered by a warning
                assert out.warning and out.reasons & R_DISPUTE, ctx
        if any_degraded:
            assert out.reasons & R_STALE, ctx
        else:
            assert not out.reasons & R_STALE, ctx
        assert bool(out.reasons & R_IMPLAUSIBLE) == any(implausible), ctx
        if not valid:
            assert out.system_error and out.reasons & R_TRAIN_INPUT, ctx
            assert out.demand >= cfg.safe_reaction, ctx
        if not (any(flags) or split or any_degraded or not valid):
            assert not out.system_error, ctx

        # ---- curves: the supervision on the voted (shortest) distance
        if present:
            closing = max(self.reports[i].closing_cms for i in present)
            age = max(now - self.reports[i].tick for i in present)
        if valid and dmin != NO_DISTANCE:
            v = self.train.speed_cms
            c = curves(cfg, v, self.train.track, self.train.brake, closing, age)
            if dmin <= c.ebi_dm:
                assert out.demand == EMERGENCY, "obstacle inside EBI: " + ctx
            elif dmin <= c.sbi_dm:
                assert out.demand >= 1, "obstacle inside SBI: " + ctx
            if dmin <= c.warning_dm:
                assert out.warning, ctx

        # ---- latch: an emergency demanded while moving holds while still moving, until
        #      standstill (held) or for at least release_confirm_cycles (revocable)
        if self.prev_demand == EMERGENCY and self.prev_moving and moving and self.prev_mode != INIT:
            if cfg.emergency_release == 0:
                assert out.demand == EMERGENCY, "emergency latch released while moving: " + ctx
            elif out.demand != EMERGENCY:
                assert self.e_run >= cfg.release_confirm_cycles, "emergency released too soon: " + ctx
        self.e_run = self.e_run + 1 if out.demand == EMERGENCY and moving else 0

        # ---- modes
        if overrun or perceptor:
            assert out.mode == SAFE_STOP, ctx
            assert out.demand == EMERGENCY and out.reasons & R_SAFE_STOP, ctx
        if overrun:
            assert out.reasons & R_DEADLINE, ctx
        if out.mode == SAFE_STOP:
            assert out.demand == EMERGENCY, ctx
        if self.prev_mode == SAFE_STOP and (moving or any_degraded or split or any(flags)):
            assert out.mode == SAFE_STOP, "SAFE_STOP left while moving or unhealthy: " + ctx
        if not all(self.seen):
            assert out.mode in (INIT, SAFE_STOP), ctx
            assert out.demand == EMERGENCY, ctx
            if out.mode == INIT:
                assert out.reasons & R_INIT, ctx
        else:
            assert out.mode != INIT, ctx
        if out.mode == NORMAL:
            assert not out.system_error and not any_degraded, ctx
        if out.system_error and out.mode != SAFE_STOP:
            assert out.mode in (INIT, DEGRADED_MODE), ctx

        # ---- table (it holds its node during any system error)
        if out.mode == INIT:
            assert out.node == self.table.start, ctx
        elif out.system_error and out.mode != SAFE_STOP:
            assert out.node == self.prev_node, ctx
            assert out.demand >= self.table.action[out.node], ctx
        else:
            assert out.node == self.table.next[self.prev_node][out.observation], ctx
            assert out.demand >= self.table.action[out.node], ctx

        # ---- observation from the voted picture (valid train only: the speed is known)
        if valid:
            v = self.train.speed_cms
            if out.distance_dm != NO_DISTANCE:     # the table's zones: normal conditions
                a2 = ebi_dm(cfg, v, 0, 0, closing, age)                   # zone limits: braking.ebi_dm
                a1 = max(a2, ebi_dm(cfg, v, 0, 0, closing, age, service=True))
                d = out.distance_dm
                zone = 3 if d <= a2 else 2 if d <= a1 else 1 if d <= a1 + cfg.warning_margin_dm else 0
            else:
                zone = 3 if any_degraded else 0
            if self.model == "m1":
                assert out.observation == zone, ctx
            else:
                name = M2_OBSERVATIONS[out.observation].split("-")
                assert name[0] == M2_NAMES[0][zone], ctx
                assert name[3] == M2_NAMES[3][self.train.track], ctx
                assert name[4] == M2_NAMES[4][self.train.brake], ctx
                if present:
                    closing = max(self.reports[i].closing_cms for i in present)
                    cls = 0 if closing < 0 else 1 if closing < cfg.fast_closing_cms else 2
                    kind = max(self.reports[i].obstacle for i in present)
                    assert name[1] == M2_NAMES[1][cls], ctx
                    assert name[2] == M2_NAMES[2][kind], ctx

        self.prev_demand = out.demand
        self.prev_moving = moving
        self.prev_node = out.node
        self.prev_mode = out.mode


SETTINGS = settings(deadline=None, max_examples=60, stateful_step_count=40, database=None,
                    suppress_health_check=[HealthCheck.too_slow])

CASES = {
    "m1-3oo3": ("m1", Config()),
    "m2-3oo3": ("m2", Config()),
    "m1-2oo2-service": ("m1", Config(topology="2oo2", safe_reaction=1, timeout_cycles=2,
                                     persistence_cycles=2, recovery_cycles=3, max_overruns=2)),
    "m2-3oo3-service": ("m2", Config(safe_reaction=1, recovery_cycles=2, persistence_cycles=1)),
    "m1-3oo3-held": ("m1", Config(emergency_release=0, persistence_cycles=3)),
    "m2-3oo3-quick-release": ("m2", Config(release_confirm_cycles=1, max_gradient_permille=0, emergency_band2_cms=0)),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_core_state_machine(case):
    model, cfg = CASES[case]
    run_state_machine_as_test(lambda: CoreMachine(model, cfg), settings=SETTINGS)
