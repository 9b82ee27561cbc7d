"""The whole cycle proved about what it feeds the memory and the supervision (issue 40 item 2).

release.py proves the release rule's one-cycle invariant about its pieces (`near_travel`,
`observe`, `merge`), each on the inputs it is given. What `cycle.step` (and `rg_step`, the C)
passes them was tested, not proved: the caller could move a remembered obstacle at half its
closing speed, or remember half a sighting's speed, and every piece would still prove. Here
the shipped step itself runs on symbolic numbers (symbolic.explore; the C through
c_step.step_runner), on every feasible path, for each picture the sensors can give, and on
each path the invariant is proved about what the step produced:

    (M) covered: the world has an obstacle at true gap x now, closing at its own speed w0
        (static 0, receding < 0 and free to stop, oncoming > 0). Before the cycle it was
        remembered (a track with near - a <= x and closing + c_a >= w0, a and c_a the sensors'
        declared distance and closing accuracy: the error budget) or it is sighted now (the
        reported distance within a of its gap when measured, the reported closing speed
        within c_a of the train's true speed then plus w0). After the cycle some track lies at
        most a beyond the obstacle's gap at the next cycle, whatever the train does inside the
        declaration (its travel bounded by the reaction phase's dI bound over the period and
        the report's age), and remembers at least its speed less c_a.
    (S) supervised: some braking curve of this cycle counts at least the obstacle's own speed
        (its closing argument plus c_a less the train's least speed is at least w0), so the
        curves' sufficiency (obligations.py) is about this obstacle.

The curves themselves are replaced by their proved contract (modular verification): each
call returns fresh numbers, and what it was given is recorded; the integer obligations prove
the curves for every argument. The papers' risk figures (r1, r2) are replaced by 0: nothing
the memory or the demand reads. The type guards of `channel_status` (a report field that is
not an int counts as DEGRADED) and of `cycle._train` are bypassed, since the symbolic numbers
are not ints: for int fields they are `effective_status` and `cycle.train_in_range`, which
run as shipped.

What is fixed on each run (named in the results): the channels' statuses, the same distance
and closing speed in every PRESENT channel (each within the declared accuracy of the truth;
channels that differ are the voter's business, proved piecewise by its contracts), at most
one remembered track before the cycle, fresh
plausibility references, the mode NORMAL at the table's start node, and the held demand.
"""
from __future__ import annotations

import importlib.util
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Callable, Optional

import z3

from monitor.core.braking import Curves
from monitor.core.config import Config
from monitor.core.types import (ABSENT, DEGRADED, MAINTAIN, MAX_CLOSING_CMS, MAX_SPEED_CMS, NO_TRACK, NORMAL, PRESENT,
                                TRACKS, Inputs, Report, State, Track, Train)

from . import symbolic
from .obligations import EXPLORE_TIMEOUT_MS, TIMEOUT_MS, Result, refute, value

REPO = Path(__file__).resolve().parents[2]
CORE_PY = REPO / "monitor" / "core"
TICK = 1_000_000                     # the cycle's tick: only differences to it matter
MAX_NEAR = 600_000_000               # a track's position, 1e-5 m (6 km)
P, A, D = PRESENT, ABSENT, DEGRADED

# (name, the six channels' statuses (None: never heard), a track before the cycle); the blind
# picture first: what the memory does alone is where most of its planted edits show, and a
# weakening's run stops at its first refuted picture (whole_cycle_results(first_failure=True))
PICTURES = (
    ("every channel blind, remembered", (D,) * 6, True),
    ("every channel sees it", (P,) * 6, False),
    ("every channel sees it, remembered before", (P,) * 6, True),
    ("one module sees it, two miss it", (P, P, A, A, A, A), False),
    ("one module sees it, remembered before", (P, P, A, A, A, A), True),
    ("one channel alone sees it, remembered before", (P, A, A, A, A, A), True),
    ("every channel silent, remembered", (None,) * 6, True),
    ("every channel misses it, remembered", (A,) * 6, True),
)
HELD = (MAINTAIN,)          # the held demand feeds neither the memory nor the curves' arguments


class Decided(Exception):
    """The step reached its decisions (whole_cycle follows it up to there)."""


@dataclass
class Call:
    """One call of the curves during a symbolic run: what it was given, what it returned."""
    closing: object
    age: object
    zone: bool
    result: Curves


class CurveContract:
    """The curves as their proved contract: fresh numbers per call, the arguments recorded."""

    def __init__(self, ex: symbolic.Explorer):
        self.ex = ex
        self.calls: list[Call] = []
        self.next_tracks = None          # what the step remembers for the next cycle

    def decided(self, *args):
        """The first thing the step decides from the curves: the memory and every curve's
        arguments are final here, and the run stops (what follows is the demand)."""
        raise Decided

    def _fresh(self, speed, closing, age, zone: bool) -> Curves:
        ex = self.ex
        out = Curves(*(symbolic.SymInt(ex, ex.fresh(n)) for n in ("ebd", "ebi", "sbi", "warning")))
        self.calls.append(Call(closing, age, zone, out))
        return out

    def curves(self, cfg, speed_cms, track, brake, closing_cms, age_ms, service=False):
        return self._fresh(speed_cms, closing_cms, age_ms, False)

    def ebi_dm(self, cfg, speed_cms, track, brake, closing_cms, age_ms, service=False):
        return self._fresh(speed_cms, closing_cms, age_ms, True).ebi_dm


def load_core_module(name: str, source: str) -> ModuleType:
    """monitor.core.<name> from `source` (the shipped text or a planted edit), as a private
    module of the monitor.core package, so its relative imports are the shipped modules."""
    spec = importlib.util.spec_from_loader(f"monitor.core._proof_{name}", loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "monitor.core"
    module.__file__ = str(CORE_PY / f"{name}.py")
    exec(compile(source, module.__file__, "exec"), module.__dict__)
    return module


def python_step(sources: Optional[dict] = None) -> Callable:
    """A runner(contract) -> step(setup, state, inputs, tick) of the shipped cycle.py (or
    `sources`: {module name: text} of cycle.py and memory.py with an edit planted), with the
    curves replaced by the contract."""
    sources = dict(sources or {})
    texts = {n: sources.get(n) or (CORE_PY / f"{n}.py").read_text() for n in ("cycle", "memory")}

    def runner(contract: CurveContract):
        cycle = load_core_module("cycle", texts["cycle"])
        memory = load_core_module("memory", texts["memory"])
        for name in ("observe", "near_travel", "far_travel", "forget", "distance_dm", "seen_beyond"):
            setattr(cycle, name, getattr(memory, name))
        cycle.curves, cycle.ebi_dm = contract.curves, contract.ebi_dm
        cycle.r1_ppm = cycle.r2_ppm = lambda *args: 0
        effective = cycle.__dict__["channel_status"].__globals__["effective_status"]
        cycle.channel_status = lambda r, now, timeout: D if r is None else effective(
            r.status, r.distance_dm, r.closing_cms, r.obstacle, r.tick, now, timeout)
        cycle._train = lambda t: cycle.train_in_range(t.speed_cms, t.track, t.brake)
        shipped_move = cycle.moved_tracks

        def moved(*args):
            contract.next_tracks = shipped_move(*args)
            return contract.next_tracks
        cycle.moved_tracks = moved
        cycle._zone_limits = cycle.zone = cycle.supervision_demand = contract.decided
        return cycle._step
    return runner


def c_step(core_dir=None) -> Callable:
    """The same runner for the C core's rg_step (c_step.step_runner), rg_curves by contract."""
    from . import c_step as c_runner, c_symbolic

    prog = c_symbolic.program(core_dir or c_symbolic.CORE_DIR)

    def runner(contract: CurveContract):
        def rg_curves(cfg, speed, track, brake, closing, age, service, periods, out):
            got = contract.curves(cfg, speed, track, brake, closing, age)
            holder = out.get()
            for field, v in zip(("ebd_dm", "ebi_dm", "sbi_dm", "warning_dm"), got):
                holder[field] = v

        def rg_ordered(tracks, ages, states):
            # the shipped C, recorded: its last call before the decisions orders next_tracks
            prog.call("rg_ordered", [tracks, ages, states])
            contract.next_tracks = [_slot(tracks, i) for i in range(TRACKS)]
        decided = {name: contract.decided for name in ("zone_limits", "rg_zone", "rg_remembered_demand")}
        return c_runner.step_runner(prog, {"rg_curves": rg_curves, "rg_ordered": rg_ordered,
                                           "rg_r1_ppm": lambda *a: 0, "rg_r2_ppm": lambda *a: 0, **decided})
    return runner


def _slot(pointer, i: int) -> Track:
    """Track i of a C array of rg_track_slot that `pointer` points into."""
    slot = pointer[i] if isinstance(pointer, list) else pointer.holder[pointer.key + i]
    return Track(*(slot[f] for f in ("near", "far", "closing", "cycles", "absent", "strong")))


def _budget(cfg: Config) -> tuple[int, int]:
    """(distance accuracy in 1e-5 m, closing accuracy in cm/s): the error budget, in the step's
    units, as the world's constraints and the invariant count it."""
    return cfg.distance_accuracy_dm * 10000, cfg.closing_accuracy_cms


def _world(cfg: Config, v, age, sighted: bool, remembered: bool, near0, far0, closing0, dist, closing):
    """The world's constraints in code units (cm/s, ms, 1e-5 m) and its next gap: (constraints,
    x_next, w0, named)."""
    e, period = cfg.speed_error_permille, cfg.period_ms
    far_units, faster = _budget(cfg)
    v0, v0m, w0, x, xa, xp, xq, grad = z3.Reals(
        "true_speed true_speed_at_report obstacle_cms gap travel_age travel_period travel_last_period grad")
    a_plus = z3.If(cfg.max_accel_mms2 + grad * z3.RealVal("981/100") > 0,
                   cfg.max_accel_mms2 + grad * z3.RealVal("981/100"), 0)          # mm/s^2 (grad per mille)
    tau = age + period
    c = [1000 * v0 >= v * (1000 - e), 1000 * v0 <= v * (1000 + e), 1000 * v0m >= v * (1000 - e),
         1000 * v0m <= v * (1000 + e), -60 <= grad, grad <= cfg.max_gradient_permille,
         -2 * MAX_CLOSING_CMS <= w0, w0 <= 2 * MAX_CLOSING_CMS, 0 <= xa, 0 <= xp,
         # the reaction phase's dI bound over the report's age and the period, and the period alone
         xa + xp <= v0 * tau + a_plus * tau * tau / 20000, xp <= v0 * period + a_plus * period * period / 20000]
    ahead = z3.If(w0 > 0, w0, 0)
    if remembered:
        # near <= x, and x no farther than far less the train's travel in the period that ends
        # now (at least what its measured speed less the error and the acceleration explain)
        c += [x >= near0 - far_units, closing0 + faster >= w0, x + xq <= far0 + far_units, xq >= 0,
              1000 * xq >= v * (1000 - e) * period - 1000 * a_plus * period * period / 20000]
    if sighted:
        # the report within the sensors' declared accuracy of the truth when it was measured
        c += [x >= dist * 10000 - far_units - xa - ahead * age, x <= dist * 10000 + far_units - xa,
              closing - faster <= v0m + w0, v0m + w0 <= closing + faster]
    named = {"measured_speed": v, "true_speed": v0, "obstacle_cms": w0, "gap_now": x, "report_age": age,
             "travel_in_period": xp, "travel_last_period": xq, **({"remembered_own_cms": closing0} if remembered else {})}
    return c, x - xp - ahead * period, w0, xp, named


def CURVE_VALUES(ex: symbolic.Explorer, c) -> set:
    """The names in `c` of numbers the curve contract returned (fresh ebd/ebi/sbi/warning)."""
    return {n for n in ex.variables(c) if n.split("!")[0] in ("ebd", "ebi", "sbi", "warning")}


def _term(x):
    return x.term if isinstance(x, symbolic.SymInt) else z3.RealVal(int(x))


def _is_const(term, n: int) -> bool:
    """A term the run left concrete, equal to n (an empty track slot: NO_TRACK)."""
    t = z3.simplify(term)
    return z3.is_rational_value(t) and t.as_fraction() == n


@dataclass
class Case:
    picture: str
    statuses: tuple
    remembered: bool
    held: int


def cases() -> list[Case]:
    return [Case(name, st, rem, held) for name, st, rem in PICTURES for held in HELD]


def prove_case(cfg: Config, setup, runner: Callable, case: Case, label: str,
               timeout_ms: int = TIMEOUT_MS) -> list[Result]:
    """(M) and (S) on every feasible path of the step for one picture and held demand."""
    v, dist, closing, age, near0, far0, closing0 = z3.Reals("speed_cms distance_dm closing_cms age_ms near far closing0")
    sighted = any(s == PRESENT for s in case.statuses)
    domain = [0 <= v, v <= MAX_SPEED_CMS, 0 <= dist, dist <= 60000, -MAX_CLOSING_CMS <= closing,
              closing <= MAX_CLOSING_CMS, 0 <= age, age <= cfg.timeout_cycles * cfg.period_ms]
    if case.remembered:
        domain += [0 <= near0, near0 <= far0, far0 <= MAX_NEAR, 0 <= closing0, closing0 <= MAX_CLOSING_CMS]
    contracts: list[CurveContract] = []

    def run(speed, distance, closing_cms, report_age, near, far, own):
        contract = CurveContract(speed.ex)
        contracts.append(contract)
        reports = tuple(None if s is None else Report(s, distance if s == PRESENT else 0,
                                                      closing_cms if s == PRESENT else 0, 0, TICK - report_age)
                        for s in case.statuses)
        track = Track(near, far, own, 0, 0, True) if case.remembered else Track()
        modules = (0,) * cfg.modules
        state = State(NORMAL, setup.table.start, case.held, (1 << cfg.channels) - 1, modules, 0, 0, 0, 0, modules,
                      MAINTAIN, (track, Track(), Track()), False, ((-1, 0, 0, 0, 0, 0, 0),) * cfg.channels)
        try:
            new_state, _ = runner(contract)(setup, state, Inputs(reports, Train(speed, 0, 0), 0), TICK)
            return tuple(new_state.tracks)
        except Decided:
            if contract.next_tracks is None:
                raise symbolic.Unsupported("the step decided from its curves before it moved its memory")
            return tuple(contract.next_tracks)

    t0 = time.perf_counter()
    name = f"{case.picture}, held {('none', 'service', 'emergency')[case.held]}"
    covered = Result(f"whole cycle ({label}), {name}: the obstacle stays remembered at or before its gap, at least "
                     "as fast", "release", "cycle.step" if label == "Python" else "rg_step",
                     context={"picture": case.picture, "held": case.held, "code": label})
    supervised = Result(f"whole cycle ({label}), {name}: a curve counts the obstacle's own speed", "release",
                        covered.phase, context=covered.context)
    try:
        paths = symbolic.explore(run, {"speed": v, "distance": dist, "closing_cms": closing, "report_age": age,
                                       "near": near0, "far": far0, "own": closing0}, domain,
                                 timeout_ms=EXPLORE_TIMEOUT_MS, cone=True)
    except symbolic.Unsupported as exc:
        for r in (covered, supervised):
            r.status, r.model = "unknown", {"unsupported": str(exc)}
        return [covered, supervised]
    explored = time.perf_counter() - t0
    covered.status = supervised.status = "proved"
    names = symbolic.Explorer([])
    done = set()
    for path, contract in zip(paths, contracts):
        next_tracks = path.value
        world, x_next, w0, xp, named = _world(cfg, v, age, sighted, case.remembered, near0, far0, closing0, dist,
                                              closing)
        # what the curves returned is left out of the hypotheses (weaker, so sound): paths that
        # differ only in the demand then share one check
        kept = [c for c in (*path.condition, *path.side) if not CURVE_VALUES(names, c)]
        base = [*domain, *kept, *world]
        tracks = [t for t in next_tracks if not _is_const(t.near, NO_TRACK)]
        # the error budget: a track may lie the distance accuracy beyond the obstacle, and
        # remembers its measured speed, which the memory and the curves count plus the accuracy
        far_units, faster = _budget(cfg)
        cover = z3.Or([z3.And(t.near - far_units <= x_next, t.closing + faster >= w0,
                              x_next + xp <= t.far + far_units) for t in tracks]) if tracks else z3.BoolVal(False)
        # the real curves count w = max(0, closing + accuracy - v (1 - e)) (model.real_curves): at least w0
        counted = z3.Or([w0 <= 0] + [1000 * (_term(c.closing) + faster) - v * (1000 - cfg.speed_error_permille)
                                     >= 1000 * w0 for c in contract.calls if not c.zone])
        key = (frozenset(c.sexpr() for c in kept), z3.And(z3.Not(cover)).sexpr(),
               tuple(_term(c.closing).sexpr() for c in contract.calls if not c.zone))
        if key in done:
            continue
        done.add(key)
        # (M) and (S) at once first: on a path where neither can fail, one solver call proves both
        if refute(z3.And(*base, z3.Or(z3.And(x_next >= 0, z3.Not(cover)), z3.Not(counted))), timeout_ms)[0] == "proved":
            continue
        if covered.proved:
            st, m = refute(z3.And(*base, x_next >= 0, z3.Not(cover)), timeout_ms)
            if st != "proved":
                covered.status = st
                covered.model = {k: value(m, t) for k, t in named.items()} if m is not None else {}
        if supervised.proved:
            st, m = refute(z3.And(*base, z3.Not(counted)), timeout_ms)
            if st != "proved":
                supervised.status = st
                supervised.model = {k: value(m, t) for k, t in named.items()} if m is not None else {}
    seconds = time.perf_counter() - t0
    for r in (covered, supervised):
        r.seconds = seconds / 2
        r.context = {**r.context, "paths": len(paths), "checked": len(done), "explore_s": round(explored, 2)}
    return [covered, supervised]


def whole_cycle_results(cfg: Config, table: str = "m1", c_core=None, sources: Optional[dict] = None,
                        timeout_ms: int = TIMEOUT_MS, languages=("Python", "C"), first_failure: bool = False) -> list[Result]:
    """(M) and (S) for every picture, on the Python step and the C rg_step; `first_failure`:
    stop at the first picture that does not prove (a planted weakening needs one)."""
    from monitor.core import cycle
    from monitor.tables import read

    setup = cycle.create(cfg, read(table))
    runners = {"Python": python_step(sources), "C": c_step(c_core) if "C" in languages else None}
    out = []
    for label in languages:
        for case in cases():
            out += prove_case(cfg, setup, runners[label], case, label, timeout_ms)
            if first_failure and not all(r.proved for r in out[-2:]):
                break
    return out


if __name__ == "__main__":                      # a quick look: python -m verification.physics.whole_cycle
    for r in whole_cycle_results(Config(), languages=tuple(sys.argv[1:]) or ("Python",)):
        print(r.line(), r.context.get("paths"), r.model or "")
