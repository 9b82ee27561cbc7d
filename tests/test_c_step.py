"""The shipped C cycle `rg_step` run by the C interpreter (verification/physics/c_step.py): the
same State and Outputs as the Python cycle, cycle by cycle, on scripted sequences; whole
symbolic runs that end on finitely many paths (with the curves and the risk summarised); and
refusals of what the interpreter cannot follow soundly (never a silent wrong answer)."""
from __future__ import annotations

import time

import pytest
import z3
from pycparser import c_parser

from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import (
    ABSENT, DEGRADED, DEGRADED_MODE, DYNAMIC, EMERGENCY, INIT, MAINTAIN, NO_DISTANCE, NO_TRACK, NORMAL, PRESENT,
    R_STALE, SAFE_STOP, SERVICE, STATIC, TRACK_FORGOTTEN, TRACK_HELD, TRACK_PASSED, TRACK_SEEN, TRAIN, Inputs, Report,
    State, Track, Train,
)
from monitor.tables import read
from verification.physics import c_step, c_symbolic, symbolic

TICK = 1_000_000           # a symbolic run's tick: only differences to it matter
CURVES = ("ebd_dm", "ebi_dm", "sbi_dm", "warning_dm")


@pytest.fixture(scope="module")
def prog():
    return c_symbolic.program()


class Script:
    """Builds (tick, Inputs) pairs 100 ms apart; `see` and `miss` make six channels' reports."""

    def __init__(self, speed: int):
        self.steps, self.speed = [], speed

    def now(self):
        return 100 * len(self.steps)

    def see(self, d, closing=None, obstacle=STATIC, age=0, n=6):
        closing = self.speed if closing is None else closing
        return tuple(Report(PRESENT, d, closing, obstacle, self.now() - age) for _ in range(n))

    def miss(self, n=6, status=ABSENT):
        return tuple(Report(status, 0, 0, STATIC, self.now()) for _ in range(n))

    def add(self, reports, train=None, overruns=0, times=1):
        for _ in range(times):
            r = reports() if callable(reports) else reports
            self.steps.append((self.now(), Inputs(r, train or Train(self.speed), overruns)))


def _faults() -> list:
    """Start-up, channel faults, blindness, an oncoming train, braking, bad inputs, SAFE_STOP and back."""
    s = Script(2000)
    s.add((None,) * 6)                                        # INIT, blind, nothing remembered
    s.add(s.see(2620)[:1] + (None,) * 5)                      # INIT: one channel heard
    s.add(s.see(2600)); s.add(s.see(2600, age=100)); s.add(s.see(2560))   # the same report again, then fresh
    s.add(s.see(2540)[:4] + s.miss(2))                        # one module misses it: a dispute
    s.add(s.see(2530)[:4] + s.miss(1) + s.see(2530)[:1])      # one channel misses it: a 2oo2 flag
    s.add(s.see(2520)[:5] + s.miss(1, DEGRADED))              # one channel degraded
    s.add(s.see(2500)[:1] + s.see(2300)[:1] + s.see(2500)[2:])   # distances disagree
    s.add(s.miss(2) + s.see(2430)[:1] + s.see(2480)[:1] + s.see(2400)[:2])   # within tolerance; modules differ
    s.add(lambda: s.miss(status=DEGRADED), times=2)           # every channel blind
    s.add((None,) * 6)                                        # never heard
    s.add(s.see(2400, age=900))                               # stale
    for d in (4000, 3930, 3860, 1500):                        # an oncoming train, then something nearer
        s.add(s.see(d, closing=5000, obstacle=TRAIN))
    for v, d in ((1600, 1480), (1200, 1465), (800, 1455), (400, 1450), (0, 1450), (0, 1450)):
        s.speed = v
        s.add(s.see(d, obstacle=DYNAMIC), Train(v, 1, 1))     # braking, slippery and degraded
    s.add(s.miss())
    s.add(s.see(1450, age=-500), Train(20000))                # from the future; a bad train speed
    s.add(s.see(1450), overruns=3)                            # deadline overruns: SAFE_STOP
    s.add(lambda: s.see(1450), times=11)                      # at standstill, healthy: NORMAL again
    s.speed = 500
    s.add(lambda: s.see(1450)[:1] + s.miss(5), times=10)      # a channel alone sees it: the perceptor fails
    return s.steps


def _memory() -> list:
    """Remembered obstacles: created ahead and beyond, merged, absorbed, passed, forgotten; implausible."""
    s = Script(3000)
    s.add(s.miss, times=2)
    for d in (15000, 6000, 4500, 3500):                       # ever nearer: new tracks ahead, the last merged
        s.add(s.see(d))
    s.add(s.miss, times=2)
    s.add(s.see(2000)); s.add(s.see(3200))                    # farther than it can be: implausible
    s.add(s.miss()); s.add(s.see(3100, closing=5000)); s.add(s.miss()); s.add(s.see(2150))   # beyond, absorbed
    s.add(s.see(2200, closing=-500))                          # receding
    s.add(s.see(2100)[:4] + s.miss(2))                        # disputed, farther than remembered
    s.add(s.see(15)); s.add(s.miss, times=19)                 # passed: 1.5 m + the 50 m distance accuracy (~2.9 m a cycle)
    s.add(lambda: s.see(300)[:1] + s.see(450)[:1] + s.miss(4), times=2)   # one module, in dispute: a weak track
    s.add(s.miss, times=12)                                   # forgotten
    return s.steps


def _supervision() -> list:
    """The curves and the hold: the safe reaction released, warning, SBI, EBI, standstill."""
    s = Script(1000)
    s.add(s.miss, times=2)
    s.add(s.see(12000)[:5] + s.miss(1, DEGRADED))             # far off, a channel degraded: the safe reaction
    s.add(lambda: s.see(12000), times=6)                      # far off: released after the confirm cycles
    for d in (2000, 900, 850, 600, 560, 400):                 # warning, SBI, EBI
        s.add(s.see(d))
    s.add(s.miss, times=7)                                    # out of sight: remembered, still held
    s.speed = 0
    s.add(s.see(300)); s.add(s.see(300))                      # at standstill
    return s.steps


def _same_cycles(setup, run, script) -> list:
    """Python's and the interpreted C's State and Outputs, equal after every cycle."""
    py = c = cycle.initial_state(setup)
    outs = []
    for k, (tick, inputs) in enumerate(script):
        want, got = cycle.step(setup, py, inputs, tick), run(setup, c, inputs, tick)
        assert got == want, f"cycle {k} at tick {tick}:\nPython {want}\nC      {got}"
        assert [type(x) for x in got[1]] == [type(x) for x in want[1]], k      # bool flags as bool
        (py, out), c = want, got[0]
        outs.append((py, out))
    return outs


@pytest.mark.parametrize("table, cfg", [("m1", Config()), ("m2", Config()),
                                        ("m1", Config(topology="2oo2", emergency_release=0))])
def test_the_interpreted_c_step_is_the_python_cycle_cycle_by_cycle(prog, table, cfg):
    """The interpreter runs the shipped rg_step as the C does: it agrees with cycle.step (which the
    compiled C agrees with bit for bit), so a proof through it is about rg_step."""
    setup = cycle.create(cfg, read(table))
    run = c_step.step_runner(prog)
    seen = [c for script in (_faults(), _memory(), _supervision()) for c in _same_cycles(setup, run, script)]
    # the scripts reach what they are for: every mode, demands raised and released, several remembered
    # obstacles, a passed and a forgotten one, table nodes, warnings, the risk
    assert {o.mode for _, o in seen} == {INIT, NORMAL, DEGRADED_MODE, SAFE_STOP}
    assert {o.demand for _, o in seen} >= {MAINTAIN, EMERGENCY} and any(o.warning for _, o in seen)
    assert max(sum(t.near != NO_TRACK for t in s.tracks) for s, _ in seen) == 3
    assert {o.track_state for _, o in seen} >= {TRACK_SEEN, TRACK_HELD, TRACK_FORGOTTEN, TRACK_PASSED}
    assert len({o.node for _, o in seen}) >= 3 and len({o.r1_ppm for _, o in seen}) >= 5
    # a state no cycle produces (its node outside the table): both fall back to SAFE_STOP alike
    bad = cycle.initial_state(setup)._replace(mode=NORMAL, node=setup.table.nodes)
    inputs = _faults()[2][1]
    assert run(setup, bad, inputs, 200) == cycle.step(setup, bad, inputs, 200)
    assert run(setup, bad, inputs, 200)[1].mode == SAFE_STOP


def _fresh(ex, names):
    """Fresh symbolic numbers in [0, 10^6], in order (ebd <= ebi <= sbi <= warning; alpha2 <= alpha1):
    the contract the curves are proved to (obligations.py), cut to what this test needs."""
    terms = [ex.fresh(n) for n in names]
    ex.side_conditions += [0 <= terms[0], terms[-1] <= 1_000_000] + [a <= b for a, b in zip(terms, terms[1:])]
    return [symbolic.SymInt(ex, x) for x in terms]


def _symbolic_run(prog, blind: bool):
    """rg_step on a symbolic speed, distance and closing speed (every channel alike) and one
    symbolic remembered track; the curves, zone limits and risk summarised. Returns (paths,
    each run's (State, Outputs), the curves' calls, seconds, the speed, distance and closing terms)."""
    cfg = Config()
    setup = cycle.create(cfg, read("m1"))
    calls = []

    def rg_curves(cfg_view, speed, track, brake, closing, age, service, supervised, out):
        calls.append((cfg_view, speed, track, brake, closing, age, service, supervised, out))
        for field, value in zip(CURVES, _fresh(speed.ex, CURVES)):
            out.get()[field] = value

    def zone_limits(cfg_view, speed, toward, age, alpha1, alpha2):
        a2, a1 = _fresh(speed.ex, ("alpha2", "alpha1"))
        alpha1.set(a1)
        alpha2.set(a2)

    run = c_step.step_runner(prog, {"rg_curves": rg_curves, "zone_limits": zone_limits,
                                    "rg_r1_ppm": lambda *args: 0, "rg_r2_ppm": lambda *args: 0})
    runs = []

    def one(speed, distance, closing, near, own):
        report = Report(DEGRADED, 0, 0, STATIC, TICK) if blind else Report(PRESENT, distance, closing, STATIC, TICK)
        state = State(NORMAL, setup.table.start, MAINTAIN, 63, (0,) * 3, 5, 5, 0, 0, (5,) * 3, MAINTAIN,
                      (Track(near, near, own, 0, 0, True), Track(), Track()), False, ((-1, 0, 0, 0, 0, 0, 0),) * 6)
        runs.append(run(setup, state, Inputs((report,) * 6, Train(speed), 0), TICK))
        return runs[-1]

    v, d, c, n, w = z3.Reals("speed distance closing near own")
    domain = [1 <= v, v <= 12000, 0 <= d, d <= 60000, 0 <= c, c <= 15000, 0 <= n, n <= 600_000_000, 0 <= w,
              w <= 15000]
    if not blind:    # the track where the sighting measures it again (rg_relation's window, 2 x 500 dm)
        domain += [d * 10000 - n <= 10_000_000, n - d * 10000 <= 10_000_000]
    t0 = time.perf_counter()
    paths = symbolic.explore(one, {"speed": v, "distance": d, "closing": c, "near": n, "own": w}, domain)
    return paths, runs, calls, time.perf_counter() - t0, (v, d, c)


def test_the_c_step_runs_symbolically_on_finitely_many_paths_with_a_sighting(prog):
    """The whole C cycle on symbolic inputs ends (no Unsupported, finitely many paths), with the
    summaries given the arguments as C passes them: what a modular proof needs."""
    paths, runs, calls, seconds, (v, d, c) = _symbolic_run(prog, blind=False)
    note = f"{len(paths)} paths in {seconds:.1f} s"
    assert 1 < len(paths) == len(runs) < 4096, note
    for state, out in runs:
        # the voted distance is the reported one, and the obstacle stays remembered
        assert isinstance(out.distance_dm, symbolic.SymInt) and out.distance_dm.term.eq(d), note
        assert not (isinstance(state.tracks[0].near, int) and state.tracks[0].near == NO_TRACK), note
        assert out.demand in (MAINTAIN, SERVICE, EMERGENCY) and isinstance(out.warning, bool), note
    # the summary is given rg_curves' arguments in C's order: cfg, speed, track, brake, closing, age, ...
    # (supervised = 1: the supervised curves, RG_SUPERVISED_PERIODS and the sensors' error budget)
    cfg_view, speed, track, brake, closing, age, service, supervised, out = calls[0]
    assert isinstance(cfg_view, c_symbolic.ConfigView) and isinstance(out, c_symbolic.Ref), note
    assert speed.term.eq(v) and closing.term.eq(c) and (track, brake, service, supervised) == (0, 0, 0, 1), note
    assert age == 0, note
    print(note)


def test_the_c_step_runs_symbolically_on_finitely_many_paths_every_channel_blind(prog):
    """Blind, with a remembered obstacle: every path ends in the safe reaction."""
    paths, runs, calls, seconds, _ = _symbolic_run(prog, blind=True)
    note = f"{len(paths)} paths in {seconds:.1f} s"
    assert 1 < len(paths) == len(runs) < 4096, note
    for state, out in runs:        # blind: a system error with a stale channel, the safe reaction (emergency)
        assert (out.distance_dm, out.demand, state.mode) == (NO_DISTANCE, EMERGENCY, DEGRADED_MODE), note
        assert out.reasons & R_STALE, note
    assert calls and all(call[7] == 1 for call in calls), note       # only the remembered track's curves (supervised)
    print(note)


def test_the_runner_refuses_inputs_the_c_cannot_hold(prog):
    """A float or a bool in an input: the Python reads it as no int (DEGRADED, an invalid
    train); the C has no such value, so the run refuses rather than convert it."""
    setup = cycle.create(Config(), read("m1"))
    run, state = c_step.step_runner(prog), cycle.initial_state(setup)
    assert run(setup, state, Inputs((None,) * 6, Train(0)), 0) == cycle.step(setup, state, Inputs((None,) * 6), 0)
    for inputs in (Inputs((Report(PRESENT, 100.5, 0, STATIC, 0),) * 6), Inputs((None,) * 6, Train(True))):
        with pytest.raises(symbolic.Unsupported, match="integers only"):
            run(setup, state, inputs, 0)


def _c(text: str) -> c_symbolic.Program:
    return c_symbolic.Program(c_parser.CParser().parse(c_symbolic.FAKE_LIBC["stdint.h"] + text))


def test_the_interpreter_refuses_what_c_would_wrap_or_it_cannot_follow():
    """A wrong answer would be silent; a refusal says what the run cannot follow."""
    x = z3.Real("x")
    shift = _c("int32_t f(int32_t x) { return x << 1; }")
    assert shift.call("f", [3]) == 6
    with pytest.raises(symbolic.Unsupported, match="symbolic"):
        symbolic.explore(lambda x: shift.call("f", [x]), {"x": x}, [0 <= x, x <= 5])
    unsigned = _c("uint32_t f(int32_t x) { return (uint32_t)x; }")
    paths = symbolic.explore(lambda x: unsigned.call("f", [x]), {"x": x}, [0 <= x, x <= 5])
    assert len(paths) == 1 and paths[0].value.eq(x)            # provably >= 0 on its path: the identity
    with pytest.raises(symbolic.Unsupported, match="wrap"):     # may be negative: refused, never wrapped
        symbolic.explore(lambda x: unsigned.call("f", [x]), {"x": x}, [-1 <= x, x <= 5])
    for bad, arg in (("uint32_t f(int32_t x) { return 1u - (uint32_t)x; }", 2),     # an unsigned wrap
                     ("int32_t f(int32_t x) { return x << 31; }", 1),                # a signed overflow
                     ("int32_t f(int32_t x) { return x >> 1; }", -4),                # implementation-defined
                     ("int32_t f(int32_t x) { uint32_t u = 1; return u < x; }", -1)):  # -1 compared as unsigned
        with pytest.raises(symbolic.Unsupported):
            _c(bad).call("f", [arg])


def test_the_interpreter_copies_structs_and_runs_loops_summaries_and_constants_as_c_does():
    """What rg_step relies on, each where a Python-minded interpreter would differ from C."""
    prog = _c("""
        typedef struct { int32_t a; int32_t b[2]; } pair;
        static const pair K = {7, {1, 2}};
        int32_t g(int32_t x);
        int32_t copied(void) { pair p = K, q; q = p; q.a = 2; q.b[1] = 9; return p.a * 10 + p.b[1] + K.b[1]; }
        int32_t loop(void) {
            int32_t i, s = 0;
            for (i = 0; i < 10; i++) { if (i % 2 == 0) continue; if (i > 7) break; s += i; }
            while (s > 14) s -= 5;
            return s;
        }
        int32_t calls(int32_t x) { (void)g(x); return g(x) + 1; }
    """)
    assert prog.call("copied", []) == 74        # an aliasing copy gives 20 + 9 + 9
    assert prog.call("loop", []) == 11          # 1 + 3 + 5 + 7, less 5; without the break 10, the continue 13
    given = []
    summarised = prog.summarised({"g": lambda x: given.append(x) or 2 * x})
    assert summarised.call("calls", [5]) == 11 and given == [5, 5]
    with pytest.raises(symbolic.Unsupported, match="not defined"):      # the shared program is left unsummarised
        prog.call("calls", [5])
