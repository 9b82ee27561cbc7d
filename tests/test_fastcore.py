"""The vectorised twin (verification/fastcore.py) against the real core, bit for bit.

10,000+ random sequences over several configurations (release revocable or held to
standstill, confirmation 1..12 cycles, one to three speed bands, adverse track and brake
reports, report ages, the shipped, a never-braking and a random table), drawn so that the
distance often sits exactly on a curve (EBI, SBI, warning, the zones' alpha2, alpha1,
alpha1 + margin) or one dm either side, the speed at 0 or 1 cm/s, and the cause of an
emergency gone for exactly the confirmation. Every output of every cycle must be equal;
mutants of the twin one dm or one cycle off must be caught.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest

from monitor.core import braking, cycle
from monitor.core import table as table_mod
from monitor.core.config import Config
from monitor.core.types import (
    EMERGENCY, MAX_CLOSING_CMS, MAX_DISTANCE_DM, MAX_SPEED_CMS, R_ENVELOPE, R_LATCH, R_SBI, R_TABLE, R_WARNING,
)
from monitor.tables import read
from verification import fastcore as fc

STEPS = 40


class Case(NamedTuple):
    name: str
    config: Config
    model: str
    table: str           # "shipped", "never" (never brakes: the ladder and the latch alone) or "random"
    sequences: int
    age_max: int = 0     # report ages drawn from 0..age_max ms
    adverse: float = 0.0  # share of cycles reporting a slippery track / degraded brakes


CASES = (
    Case("m1-default", Config(), "m1", "shipped", 2000),
    Case("m2-held-adverse", Config(emergency_release=0), "m2", "shipped", 2000, adverse=0.4),
    Case("m1-never-confirm1-age", Config(release_confirm_cycles=1), "m1", "never", 1500, age_max=300),
    Case("m2-random-3bands-2oo2", Config(emergency_band2_cms=2000, emergency_band2_mms2=2100, emergency_band3_cms=4000,
                                         emergency_band3_mms2=1900, release_confirm_cycles=12, topology="2oo2"),
         "m2", "random", 1500, age_max=200, adverse=0.5),
    Case("m1-random-oneband-adverse", Config(emergency_band2_cms=0, slippery_permille=500, degraded_permille=600,
                                             max_gradient_permille=10, warning_ms=0, standstill_margin_dm=0,
                                             speed_error_permille=0), "m1", "random", 1500, adverse=0.5),
    Case("m2-never-held-steep", Config(emergency_release=0, max_gradient_permille=30, traction_cutoff_ms=1500,
                                       max_accel_mms2=1200, warning_margin_dm=0), "m2", "never", 1500,
         age_max=300, adverse=0.3),
)


def _table(case: Case) -> bytes:
    data = read(case.model)
    if case.table == "shipped":
        return data
    t = table_mod.decode(data)
    if case.table == "never":
        return table_mod.encode(dict(t.header), (0,) * t.nodes, t.next)
    rng = np.random.default_rng(len(case.name))
    nodes, obs = 12, len(t.observations)
    return table_mod.encode(dict(t.header, start=3), rng.integers(0, 3, nodes).tolist(),
                            rng.integers(0, nodes, (nodes, obs)).tolist())


def _setup(case: Case) -> cycle.Setup:
    return cycle.create(case.config, _table(case))


def _pick(rng, n: int, weights, choices):
    """Per element, one of `choices` (arrays or scalars) drawn with `weights`."""
    u = rng.random(n)
    edges = np.cumsum(weights) / np.sum(weights)
    return np.select([u < e for e in edges[:-1]], list(choices[:-1]), choices[-1])


def random_inputs(case: Case, n: int, steps: int, seed: int) -> dict:
    """(steps, n) inputs of the twin's case, often exactly on a curve or next to it."""
    cfg = case.config
    rng = np.random.default_rng(seed)
    shape = (steps, n)
    out = {k: np.zeros(shape, dtype=bool if k == "present" else np.int64) for k in fc.INPUT_KEYS}
    v = rng.integers(0, MAX_SPEED_CMS + 1, n)
    d = rng.integers(0, MAX_DISTANCE_DM + 1, n)
    present = rng.random(n) < 0.8
    track = (rng.random(n) < case.adverse).astype(np.int64)
    brake = (rng.random(n) < case.adverse).astype(np.int64)
    for k in range(steps):
        v = _pick(rng, n, (8, 4, 8, 80), (0, 1, rng.integers(0, MAX_SPEED_CMS + 1, n),
                                         np.clip(v + rng.integers(-80, 81, n), 0, MAX_SPEED_CMS)))
        present = np.where(rng.random(n) < 0.1, ~present, present)
        flip = rng.random((2, n)) < 0.1
        track = np.where(flip[0], (rng.random(n) < case.adverse).astype(np.int64), track)
        brake = np.where(flip[1], (rng.random(n) < case.adverse).astype(np.int64), brake)
        closing = np.clip(_pick(rng, n, (50, 15, 15, 10, 10), (
            v, v + rng.integers(0, 1500, n), rng.integers(-MAX_CLOSING_CMS, MAX_CLOSING_CMS + 1, n),
            v - rng.integers(0, 1500, n), -rng.integers(0, 3000, n))), -MAX_CLOSING_CMS, MAX_CLOSING_CMS)
        age = rng.integers(0, case.age_max + 1, n) * (rng.random(n) < 0.5)
        c = fc.curves(cfg, v, track, brake, closing, age)
        a1, a2 = fc.zone_alphas(cfg, v, closing, age)
        target = _pick(rng, n, (1,) * 6, (c.ebi_dm, c.sbi_dm, c.warning_dm, a2, a1, a1 + cfg.warning_margin_dm))
        on_curve = target + rng.integers(-1, 2, n)
        d = np.clip(_pick(rng, n, (45, 25, 15, 10, 5), (on_curve, d, rng.integers(0, MAX_DISTANCE_DM + 1, n),
                                                       rng.integers(0, 200, n), MAX_DISTANCE_DM)), 0, MAX_DISTANCE_DM)
        for key, value in (("present", present), ("distance_dm", d), ("speed_cms", v), ("closing_cms", closing),
                           ("obstacle", rng.integers(0, 3, n)), ("track", track), ("brake", brake), ("age_ms", age)):
            out[key][k] = value
    return out


def directed_inputs(case: Case) -> dict:
    """A moving train: an obstacle at EBI, then gone (absent) for confirm - 1, confirm and
    confirm + 1 cycles, then back at EBI; and one held between EBI and SBI, then beyond SBI."""
    cfg = case.config
    v, rows = 2000, []
    c = braking.curves(cfg, v, 0, 0, v, 0)
    for gone in (cfg.release_confirm_cycles - 1, cfg.release_confirm_cycles, cfg.release_confirm_cycles + 1):
        rows.append([(True, c.ebi_dm)] * 2 + [(False, 0)] * gone + [(True, c.ebi_dm)] * 2)
    rows.append([(True, c.ebi_dm), (True, c.ebi_dm + 1), (True, c.sbi_dm), (True, c.sbi_dm + 1)]
                + [(True, c.warning_dm + 1)] * (cfg.release_confirm_cycles + 1) + [(True, c.warning_dm)])
    steps = max(len(r) for r in rows)
    rows = [r + [(False, 0)] * (steps - len(r)) for r in rows]
    present = np.array([[p for p, _ in r] for r in rows]).T
    dist = np.array([[x for _, x in r] for r in rows], dtype=np.int64).T
    return {"present": present, "distance_dm": dist, "speed_cms": np.full(present.shape, v, dtype=np.int64)}


@pytest.fixture(scope="module", params=CASES, ids=[c.name for c in CASES])
def compared(request):
    case = request.param
    setup = _setup(case)
    inputs = random_inputs(case, case.sequences, STEPS, seed=1000 + CASES.index(case))
    trace = fc.twin_trace(setup, inputs)
    bad, cycles = fc.first_mismatch(setup, trace, case.sequences)
    return case, setup, trace, bad, cycles


def test_enough_sequences():
    assert sum(c.sequences for c in CASES) >= 10_000


def test_twin_equals_core_on_random_sequences(compared):
    case, _, trace, bad, cycles = compared
    assert bad is None, bad
    assert cycles == case.sequences * STEPS


def test_random_sequences_reach_every_boundary_and_rule(compared):
    """The sequences are worth comparing: each curve is hit exactly and one dm beyond, the
    speed is 0 and 1 cm/s, every reason bit of the twin's case appears, and an emergency is
    released while moving exactly when the configuration allows it."""
    case, _, t, _, _ = compared
    cfg = case.config
    present, d, v = t["present"], t["distance_dm"], t["speed_cms"]
    c = fc.curves(cfg, v, t["track"], t["brake"], t["closing_cms"], np.where(present, t["age_ms"], 0))
    a1, a2 = fc.zone_alphas(cfg, v, t["closing_cms"], np.where(present, t["age_ms"], 0))
    for name, edge in (("EBI", c.ebi_dm), ("SBI", c.sbi_dm), ("warning", c.warning_dm), ("alpha2", a2),
                       ("alpha1", a1), ("alpha1 + margin", a1 + cfg.warning_margin_dm)):
        for off in (0, 1):
            assert (present & (d == edge + off) & (edge + off <= MAX_DISTANCE_DM)).sum() >= 20, (name, off)
    assert (present & (v == 0)).sum() >= 100 and (present & (v == 1)).sum() >= 100
    reasons = t["out_reasons"]
    bits = [R_ENVELOPE, R_SBI, R_WARNING] + ([R_TABLE] if case.table != "never" else [])
    if cfg.emergency_release == 0 or cfg.release_confirm_cycles > 1:    # confirm 1: released on the first calm cycle
        bits.append(R_LATCH)
    for bit in bits:
        assert (reasons & bit).any(), bit
    demand = t["out_demand"]
    released = (demand[:-1] == EMERGENCY) & (demand[1:] != EMERGENCY) & (v[:-1] > 0) & (v[1:] > 0)
    assert released.any() == (cfg.emergency_release == 1)


@pytest.mark.parametrize("case", [c for c in CASES if c.table == "never"], ids=lambda c: c.name)
def test_release_after_exactly_the_confirmation(case):
    """Directed sequences: twin == core, and the core releases on the confirm-th calm cycle
    (revocable) or never while moving (held), and holds inside SBI."""
    setup = _setup(case)
    trace = fc.twin_trace(setup, directed_inputs(case))
    bad, _ = fc.first_mismatch(setup, trace, trace["present"].shape[1])
    assert bad is None, bad
    demand = trace["out_demand"]
    confirm = case.config.release_confirm_cycles
    revocable = case.config.emergency_release == 1
    assert (demand[:2 + confirm - 1, 0] == EMERGENCY).all()                  # gone confirm - 1 cycles: held
    assert (demand[2 + confirm - 1, 1] == EMERGENCY) != revocable             # gone confirm cycles: released
    assert (demand[:3, 3] == EMERGENCY).all()                                # inside SBI while held: emergency
    assert (demand[3:3 + confirm - 1, 3] == EMERGENCY).all()                 # beyond SBI, fewer than confirm cycles
    assert (demand[3 + confirm - 1, 3] == EMERGENCY) != revocable             # beyond SBI, confirm cycles


def test_twin_curves_equal_the_core_curves():
    """Single points, edges included: 0 and 1 cm/s, band edges +-1, the top speed."""
    rng = np.random.default_rng(3)
    for case in CASES:
        cfg = case.config
        edges = [0, 1, 2, MAX_SPEED_CMS - 1, MAX_SPEED_CMS]
        for band in (cfg.emergency_band2_cms, cfg.emergency_band3_cms):
            edges += [band - 1, band, band + 1] if band else []
        v = np.concatenate([edges, rng.integers(0, MAX_SPEED_CMS + 1, 1500)])
        n = v.size
        k, b = rng.integers(0, 2, n), rng.integers(0, 2, n)
        cl = np.where(rng.random(n) < 0.5, v, rng.integers(-MAX_CLOSING_CMS, MAX_CLOSING_CMS + 1, n))
        age = rng.integers(0, 301, n)
        for service in (False, True):
            got = fc.curves(cfg, v, k, b, cl, age, service)
            for i in range(n):
                want = braking.curves(cfg, int(v[i]), int(k[i]), int(b[i]), int(cl[i]), int(age[i]), service)
                assert tuple(int(x[i]) for x in got) == tuple(want), (case.name, i, service)


def _mutant_caught(monkeypatch, name: str, wrapper) -> bool:
    monkeypatch.setattr(fc, name, wrapper(getattr(fc, name)))
    case = CASES[0]
    setup = _setup(case)
    trace = fc.twin_trace(setup, random_inputs(case, 300, STEPS, seed=5))
    monkeypatch.undo()
    return fc.first_mismatch(setup, trace, 300)[0] is not None


def test_a_twin_one_dm_off_is_caught(monkeypatch):
    def ebi_plus_one(curves):
        def mutant(*args, **kwargs):
            c = curves(*args, **kwargs)
            return c._replace(ebi_dm=c.ebi_dm + 1)
        return mutant
    assert _mutant_caught(monkeypatch, "curves", ebi_plus_one)


def test_a_twin_releasing_one_cycle_late_is_caught(monkeypatch):
    def late(latch):
        return lambda latched, calm, demand, speed, revocable, confirm: latch(latched, calm, demand, speed, revocable, confirm + 1)
    assert _mutant_caught(monkeypatch, "latch", late)


def test_a_twin_with_a_strict_sbi_is_caught(monkeypatch):
    def strict(supervision):
        return lambda present, d, c, held: supervision(present, d, c._replace(sbi_dm=c.sbi_dm - 1), held)
    assert _mutant_caught(monkeypatch, "supervision", strict)
