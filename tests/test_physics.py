"""Issue 30: the braking curves proved sufficient for the physics with Z3 (verification/physics).

Each proof is also shown able to fail: a wrong invariant, a curve computed from a weaker
declaration, a weakened braking.py; and a refuted obligation replays as a collision in FMPy.
The whole `railguard verify --part physics` runs once, as users run it (test_verify_physics_cli).
"""
from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from fractions import Fraction

import pytest
import z3

from monitor.core import braking
from monitor.core.config import Config
from verification.physics import model, obligations, symbolic, weakenings
from verification.physics.model import Declaration


# ------------------------------------------------------------------ the symbolic run


def test_symbolic_run_follows_every_feasible_path_and_only_those():
    def f(x, y):
        if x < 10:
            return x + y if y > 0 else -(-x // 3)
        return x * 2 if x < 5 else x - 1          # x < 5 cannot hold here: one path, not two

    x, y = z3.Reals("x y")
    paths = symbolic.explore(f, {"x": x, "y": y}, [0 <= x, x <= 20, -5 <= y, y <= 5])
    assert len(paths) == 3
    # the ceiling's relaxation: every path value is sound for the integers it stands for
    ceil_path = next(p for p in paths if any("Not" in str(c) and "y" in str(c) for c in p.condition))
    s = z3.Solver()
    s.add(0 <= x, x <= 20, x == 7, *ceil_path.condition, *ceil_path.side)
    s.add(ceil_path.value < Fraction(7, 3))                     # ceil(7/3) = 3 >= 7/3: no model below 7/3
    assert s.check() == z3.unsat


def test_symbolic_run_refuses_what_it_cannot_follow():
    x = z3.Real("x")
    with pytest.raises(symbolic.Unsupported):
        symbolic.explore(lambda x: [1, 2][x], {"x": x}, [0 <= x, x <= 1])
    with pytest.raises(symbolic.Unsupported):
        symbolic.explore(lambda x: 7 // x, {"x": x}, [-1 <= x, x <= 1])


def _c_program(text: str):
    from pycparser import c_parser

    from verification.physics import c_symbolic

    return c_symbolic.Program(c_parser.CParser().parse("typedef int int32_t; typedef long long int64_t;\n" + text))


def test_the_c_interpreter_divides_as_c_does_and_refuses_what_it_cannot_follow():
    """C's `/` truncates towards zero: (1 - 5) / 3 is -1 in C (Python's // gives -2); a
    numerator of either sign is two paths, each exact."""
    prog = _c_program("int32_t f(int32_t x) { int64_t y = x - 5; return y / 3; }")
    x = z3.Real("x")
    paths = symbolic.explore(lambda x: prog.call("f", [x]), {"x": x}, [0 <= x, x <= 10])
    assert len(paths) == 2
    for at, c_value, floor_value in ((1, -1, -2), (8, 1, None)):
        path = next(p for p in paths if z3.Solver().check(x == at, *p.condition) == z3.sat)
        # C's value is one of the path's (sound); Python's floor is not (the semantics is C's)
        assert z3.Solver().check(x == at, *path.condition, *path.side, path.value == c_value) == z3.sat
        if floor_value is not None:
            assert z3.Solver().check(x == at, *path.condition, *path.side, path.value == floor_value) == z3.unsat
    assert prog.call("f", [1]) == -1 and prog.call("f", [-10]) == -5
    for bad in ("int32_t f(int32_t x) { return x % 3; }", "int32_t f(int32_t x) { return g(x); }",
                "int32_t f(int32_t x) { int32_t a[2] = {0, 0}; return a[x]; }"):
        with pytest.raises(symbolic.Unsupported):
            symbolic.explore(lambda x: _c_program(bad).call("f", [x]), {"x": x}, [0 <= x, x <= 1])


def test_the_c_curves_are_the_shipped_c_and_a_c_only_weakening_fails_the_proof(tmp_path):
    """The integer obligations run on rg_core.c itself: its curves equal braking.py's on a
    sample (the interpreter follows the C), and a rounding turned down in the C alone, which the
    Python's proof cannot see, is refuted."""
    import random

    from verification.physics import c_symbolic

    cfg = Config()
    shipped_c = obligations.c_code()
    rnd = random.Random(30)
    for _ in range(300):
        args = (cfg, rnd.randint(0, 12000), rnd.randint(0, 1), rnd.randint(0, 1), rnd.randint(-15000, 27000),
                rnd.randint(0, 300))
        service = rnd.random() < 0.3
        assert shipped_c.curves(*args, service) == braking.curves(*args, service=service), args
        assert shipped_c.ebi_dm(*args, service) == braking.ebi_dm(*args, service=service), args
    d = Declaration.of(cfg)
    only_normal = [c for c in obligations.CONDITIONS if c[2] == "normal"]
    down = weakenings.Weakening("c-rounding-down", "rg_run_dm rounded down", (),
                                (("    return (num + 199999999) / 200000000;", "    return num / 200000000;"),))
    core = weakenings.weakened_core(down, tmp_path / "core")
    import verification.physics.obligations as ob
    saved, ob.CONDITIONS = ob.CONDITIONS, only_normal
    try:
        weak = {r.name.split(" (")[0]: r for r in ob.integer_results(cfg, d, ob.c_code(core))}
        sound = {r.name.split(" (")[0]: r for r in ob.integer_results(cfg, d, shipped_c)}
    finally:
        ob.CONDITIONS = saved
    assert all(r.proved for r in sound.values()), [r.line() for r in sound.values()]
    refuted = [n for n, r in weak.items() if r.status == "refuted"]
    assert "integer C EBI >= real, normal" in refuted, [r.line() for r in weak.values()]
    assert weak["integer C EBI >= real, normal"].phase == "rg_core.c rg_curves(service=0, RG_SUPERVISED_PERIODS).ebi_dm"
    # the Python, untouched, still proves: only the C's own proof sees this edit
    assert braking.curves(cfg, 3000, 0, 0, 3000, 0) == shipped_c.curves(cfg, 3000, 0, 0, 3000, 0)
    weak_c = c_symbolic.curves(c_symbolic.program(core))
    assert weak_c(cfg, 3001, 0, 0, 3000, 0).ebi_dm < braking.curves(cfg, 3001, 0, 0, 3000, 0).ebi_dm


# ---------------------------------------------------------------- the model's invariants


def test_differential_invariants_hold_and_a_wrong_one_is_refuted():
    d = Declaration.of(Config())
    invs = model.phase_invariants(d)
    assert {i.phase for i in invs} == {"reaction", "build-up", "braking"}
    for inv in invs:
        assert obligations.refute(model.invariant_obligation(inv))[0] == "proved", inv.name
    # travel <= v0 t forgets the acceleration: its derivative can be negative
    v0 = z3.Real("v0")
    wrong = model.Invariant("wrong", "reaction", v0 * model.T - model.X, [model.ACC <= 1, model.V >= 0],
                            [model.X == 0, model.V == v0, model.T == 0])
    assert obligations.refute(model.invariant_obligation(wrong))[0] == "refuted"
    # a cubic in t is not a polynomial the Lie-derivative check covers: refused, not proved
    cubic = model.Invariant("cubic", "reaction", model.T * model.T * model.T, [], [model.X == 0, model.T == 0])
    assert obligations.refute(model.invariant_obligation(cubic))[0] == "refuted"
    # issue 40 item 5: -t^2 >= 0 is false for t > 0; with its own bound in the constraint, dI
    # used to prove it (the derivative -2t is >= 0 wherever -t^2 >= 0, i.e. at t = 0): refused
    false = model.Invariant("-t^2", "reaction", -model.T * model.T, [-model.T * model.T >= 0], [model.T == 0])
    assert model.circular(false)
    assert obligations.refute(model.invariant_obligation(false))[0] == "refuted"
    # the same without the circular constraint is refuted on its own merits; the shipped ones are not circular
    honest = model.Invariant("-t^2", "reaction", -model.T * model.T, [model.T >= 0], [model.T == 0])
    assert not model.circular(honest) and obligations.refute(model.invariant_obligation(honest))[0] == "refuted"
    assert not any(model.circular(inv) for inv in invs)


# ---------------------------------------------------------------------- sufficiency


@pytest.mark.parametrize("weaker", [
    {"max_accel": Fraction(0)},                                     # traction forgotten
    {"emergency_buildup": Fraction(1, 2)},                          # build-up halved
    {"max_gradient": Fraction(0)},                                  # level line assumed
    {"speed_error": Fraction(0)},                                   # speed error ignored
])
def test_a_curve_from_a_weaker_declaration_is_refuted_against_the_real_train(weaker):
    d = Declaration.of(Config())
    lemmas = obligations.Lemmas(d, False, 0, 0, curve_d=replace(d, **weaker))
    verdicts = {name: obligations.refute(f)[0] for name, _, f in lemmas.steps() + lemmas.kind_steps("static")}
    assert "refuted" in verdicts.values(), verdicts
    assert all(v != "unknown" for v in verdicts.values())


def test_oncoming_obstacle_left_out_of_the_curve_is_refuted():
    d = Declaration.of(Config())
    lemmas = obligations.Lemmas(d, False, 0, 0)
    lemmas.real.phases["w"] = z3.RealVal(0)                  # the curve's obstacle term dropped
    verdicts = {name: obligations.refute(f)[0] for name, _, f in lemmas.kind_steps("oncoming")}
    assert "refuted" in verdicts.values()
    assert all(obligations.refute(f)[0] == "proved" for _, _, f in lemmas.kind_steps("static"))


# ----------------------------------------------------------- integer code and weakenings


def test_weakened_braking_is_the_shipped_source_edited_and_refuses_stale_edits():
    w = weakenings.by_name("buildup-halved")
    weak = weakenings.weakened_braking(w)
    cfg = Config()
    assert weak.curves(cfg, 3000, 0, 0, 3000, 0).ebi_dm < braking.curves(cfg, 3000, 0, 0, 3000, 0).ebi_dm
    assert weak.curves(cfg, 3000, 0, 0, 3000, 0).ebd_dm == braking.curves(cfg, 3000, 0, 0, 3000, 0).ebd_dm
    with pytest.raises(weakenings.WeakeningError):
        weakenings.edit("nothing to edit", w.python, "braking.py")
    with pytest.raises(weakenings.WeakeningError):
        weakenings.by_name("no-such-weakening")


def test_every_weakening_edits_the_c_core_too(tmp_path):
    for w in weakenings.WEAKENINGS:
        core = weakenings.weakened_core(w, tmp_path / w.name)
        text = (core / "rg_core.c").read_text() + (core / "rg_core.h").read_text()
        assert all(new in text for _, new in w.c), w.name


# --------------------------------------------------------- the part, as users run it


@pytest.fixture(scope="module")
def physics_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("physics")
    proc = subprocess.run([sys.executable, "-m", "railguard", "verify", "--part", "physics", "--json", "--out", str(out)],
                          capture_output=True, text=True, timeout=900)
    return proc, out


def test_verify_physics_cli_proves_everything_and_catches_every_weakening(physics_run):
    proc, out = physics_run
    assert proc.returncode == 0, proc.stderr[-3000:]
    data = json.loads(proc.stdout)
    assert data["passed"] is True
    names = [c["name"] for c in data["checks"]]
    obligations_run = [c for c in data["checks"] if c["name"].startswith("physics [")]
    assert len(obligations_run) > 150                        # three declarations, every obligation one entry
    assert {c["details"]["kind"] for c in obligations_run} == {"dI", "sufficiency", "release", "integer"}
    assert {c["details"]["declaration"] for c in obligations_run} == {
        "papers' train (shipped)", "examples/braking-one-band.toml", "examples/braking-three-bands.toml"}
    # (the three-band example's bands each have their own braking steps)
    assert any("band 3 from" in c["name"] and "three-bands" in c["details"]["declaration"] for c in obligations_run)
    for w in weakenings.WEAKENINGS:
        assert f"physics: planted weakening {w.name} is caught" in names
    saved = json.loads((out / "physics" / "physics.json").read_text())
    replays = {w["weakening"]: w["replay"] for w in saved["weakenings"]}
    # two weakenings collide where the shipped core stops (replayed on the declaration with a
    # perfect speedometer, the fastest point that falls short by more than a cycle's travel)
    for name in ("gradient-uphill", "oncoming-ignored"):
        assert replays[name]["weakened"]["outcome"] == "collision", replays[name]
        assert replays[name]["shipped"]["outcome"] != "collision", replays[name]
    # three shorten EBI by 24 to 34 m at 110 m/s: replayed at the timing contract's worst for the
    # weakened monitor (stalled at its first emergency, the receiver braking at its timeout) they
    # stop nearer than the shipped monitor, but outside the margin: the service curve's demand,
    # made a cycle earlier, was already braking (issue 40 item 3: the 4-period contract)
    for name in ("traction-dropped", "buildup-halved", "stall-ignored"):
        weak, sound = replays[name]["weakened"], replays[name]["shipped"]
        assert weak["outcome"] == sound["outcome"] == "stopped", replays[name]
        assert weak["margin_m"] < sound["margin_m"] - 20, replays[name]
        assert replays[name]["weakened"]["first_emergency_s"] is None          # stalled before it
    weak, sound = replays["speed-error-ignored"]["weakened"], replays["speed-error-ignored"]["shipped"]
    assert weak["outcome"] == sound["outcome"] == "stopped" and weak["margin_m"] < sound["margin_m"] - 5
    assert {w["weakening"]: w["replay_declaration"]["speed_error_permille"] for w in saved["weakenings"]
            if "replay_declaration" in w} == {
        w.name: 20 if w.name == "speed-error-ignored" else 0 for w in weakenings.WEAKENINGS if not w.memory}
    # issue 40 item 2: the two memory edits the pieces' proofs let through fail the whole cycle, in
    # Python and in C, and replay as collisions where the shipped monitor stands (an oncoming
    # train seen once, then every channel blind)
    rows = {w["weakening"]: w for w in saved["weakenings"]}
    for name in ("memory-moved-at-half", "memory-half-speed"):
        assert rows[name]["caught"], rows[name]
        assert any("whole cycle (Python)" in f for f in rows[name]["failed"]), rows[name]["failed"]
        assert any("whole cycle (C)" in f for f in rows[name]["failed"]), rows[name]["failed"]
        assert rows[name]["replay"]["weakened"]["outcome"] == "collision", rows[name]["replay"]
        assert rows[name]["replay"]["shipped"]["outcome"] == "struck_at_standstill", rows[name]["replay"]
    # issue 40 item 3: each term of the sensors' error budget left out fails the proof; the distance
    # accuracy's replay (the sensors at the budget's corner) collides where the shipped monitor stands
    for name in ("distance-accuracy-ignored", "closing-accuracy-ignored", "memory-accuracy-ignored",
                 "passed-accuracy-ignored"):
        assert rows[name]["caught"], rows[name]
    assert replays["distance-accuracy-ignored"]["weakened"]["outcome"] == "collision", replays["distance-accuracy-ignored"]
    assert replays["distance-accuracy-ignored"]["shipped"]["outcome"] != "collision"
    for name in ("closing-accuracy-ignored", "memory-accuracy-ignored"):      # played, no collision: the note says
        assert replays[name]["shipped"]["outcome"] != "collision", replays[name]
    assert replays["passed-accuracy-ignored"] is None and "no playable point" in rows["passed-accuracy-ignored"]["replay_note"]
    assert any("whole cycle (C)" in f for f in rows["passed-accuracy-ignored"]["failed"])
    whole = [c for c in obligations_run if "whole cycle" in c["name"]]
    assert len(whole) == 32 and all(c["passed"] for c in whole)          # the declaration in force
    assert {c["details"]["declaration"] for c in whole} == {"papers' train (shipped)"}
    assert sum("build-up" == c["details"]["phase"] and c["details"]["kind"] == "dI" for c in obligations_run) >= 3 * 41
    # every replayed scenario plays in `railguard cosim` as the report says
    r = replays["gradient-uphill"]
    fmu = r["command"].split("--monitor-fmu ")[1]
    cosim = subprocess.run([sys.executable, "-m", "railguard", "cosim", r["scenario"], "--monitor-fmu", fmu, "--json",
                            "--no-plot", "--out", str(out / "cosim")], capture_output=True, text=True, timeout=300)
    assert cosim.returncode == 0, cosim.stderr
    assert json.loads(cosim.stdout)["outcome"] == "collision"     # (the shipped monitor's stop: the replay above)


def test_verify_physics_refuses_a_bad_declaration_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[braking]\nemergency_decel = 0.2\nservice_decel = 0.1\nemergency_buildup_s = 1\n"
                   "service_buildup_s = 2\ntraction_cutoff_s = 0.8\nmax_accel = 0.5\nspeed_error = 0.02\n"
                   "slippery_factor = 0.7\ndegraded_factor = 0.8\nmax_downhill_gradient = 40\n"
                   "standstill_margin_m = 5\n")
    proc = subprocess.run([sys.executable, "-m", "railguard", "verify", "--part", "physics", "--braking", str(bad),
                           "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert "gradient" in proc.stderr or "decel" in proc.stderr


# ----------------------------------------------------- the release rule (issue 30 item 4)


def test_the_release_rule_s_memory_and_ebd_steps_are_proved_and_can_fail():
    """The one-cycle invariant's steps that hold for the shipped declaration: the memory never
    places an obstacle beyond where it can be (real step, and the shipped near_travel and
    distance_dm run symbolically), and a train outside EBI at one cycle is still outside EBD
    at its true speed one period later. The memory step fails when a sighting's report age is
    not counted where the position is moved (the rule before this session: the remembered
    curves counted the age at every later, perhaps slower, speed); the near-travel step fails
    with too little acceleration (0.6 < 0.5 + 9.81 x 0.02 m/s^2)."""
    from verification.physics import release

    cfg = Config()
    d = Declaration.of(cfg)
    results = release.release_results(cfg, d)
    assert results and all(r.proved for r in results), [r.line() for r in results if not r.proved]
    assert {r.kind for r in results} == {"release", "integer"}
    assert len([r for r in results if "after a free period" in r.name]) == 8          # two per condition
    assert len([r for r in results if "stops short (remembered obstacle)" in r.name]) == 4
    assert release.memory_step(d, Fraction(697, 1000), count_age=False).status == "refuted"
    assert release.near_travel_results(cfg, d, 600)[0].status == "refuted"


def test_the_sampling_period_is_what_keeps_a_remembered_obstacle_safe():
    """The one-cycle step "outside EBI at one cycle, an emergency at the next stops margin
    short of a remembered obstacle" is proved because the curves count the sampling period;
    with curves that count one period (as before this issue) Z3 refutes it under every
    reported condition: the memory's closing speed has none of a measured one's slack (a
    remembered static obstacle at 40 m/s ended 0.63 m beyond it, 11.6 m at 120 m/s)."""
    d = Declaration.of(Config())
    for track, brake, _ in obligations.CONDITIONS:
        one = obligations.Lemmas(d, False, track, brake, curve_d=replace(d, period=d.period / 2), remembered=True)
        assert obligations.refute(one.ends_short_of(0))[0] == "refuted"
        now = obligations.Lemmas(d, False, track, brake, remembered=True)
        assert all(obligations.refute(f)[0] == "proved" for _, _, f in now.steps() + now.kind_steps("remembered"))


def test_a_declaration_without_speed_error_collides_one_period_late_without_the_sampling_period():
    """Last session's finding: without speed error (nothing else to absorb it) curves that
    count one period collide with a voted static obstacle one period late (Z3 finds a train
    state above 10 m/s); the shipped curves count two and stop margin short."""
    exact = Declaration.of(Config()._replace(speed_error_permille=0))
    late = obligations.Lemmas(exact, False, 0, 0, curve_d=replace(exact, period=exact.period / 2))
    status, found = obligations.refute(late.ends_short_of(0, "static"))
    assert status == "refuted" and found is not None
    assert obligations.value(found, late.v) > 10                  # a real train speed, m/s
    shipped = obligations.Lemmas(exact, False, 0, 0)
    assert all(obligations.refute(f)[0] == "proved" for _, _, f in shipped.steps() + shipped.kind_steps("static"))


def test_the_several_tracks_keep_every_obstacle_at_or_before_its_position_and_can_fail(monkeypatch):
    """Issue 38 item 2: the release invariant's (M) through what the memory does to its tracks,
    proved on the shipped observe and merge run symbolically; an observe that remembers half
    an oncoming obstacle's speed, or that moves a track to the sighting plus one unit, and a
    merge that keeps the farther position, are refuted."""
    from monitor.core import memory, tracks
    from verification.physics import release

    assert all(r.proved for r in release.tracks_results())
    real_observe, real_merge = memory.observe, tracks.merge

    def half_speed(near, far, closing, distance_dm, obstacle_cms, age_now, confirmed, sighted):
        return real_observe(near, far, closing, distance_dm, obstacle_cms // 2 if obstacle_cms > 0 else obstacle_cms,
                            age_now, confirmed, sighted)

    def one_beyond(*args, **kw):
        n, f, c, a = real_observe(*args, **kw)
        return (n + 1 if n != -1 else n), f, c, a

    def farther(a, b):
        m = real_merge(a, b)
        return m._replace(near=a.near if a.near > b.near else b.near)

    for name, fake, module in (("observe", half_speed, memory), ("observe", one_beyond, memory),
                               ("merge", farther, tracks)):
        monkeypatch.setattr(module, name, fake)
        assert any(r.status == "refuted" for r in release.tracks_results()), fake.__name__
        monkeypatch.undo()


PLANTED_SAMPLING = """
from monitor.core import braking
braking.SUPERVISED_PERIODS = 3                 # the edit, in the shipped module, before anything reads it
from monitor.core.config import Config
from verification.physics import obligations
from verification.physics.model import Declaration
cfg = Config()
results = obligations.integer_results(cfg, Declaration.of(cfg), braking)
print(" ".join(r.status for r in results if r.context["curve"] == "ebi" and not r.context["service"]))
"""


def test_the_sampling_period_left_out_of_the_shipped_code_fails_the_proof():
    """Issue 40 item 1: the physics states its timing from the monitor's timing contract
    (model.CONTRACT_PERIODS), never from braking.py. `SUPERVISED_PERIODS = 1` planted in the
    shipped module itself, before the proof imports it (a fresh process), proved 151 of 151
    while the reference imported the constant and shrank with it. The contract now counts a
    stalled monitor (item 3: the last frame's period + the receiver's 3-period timeout = 4);
    one period short of it, planted the same way, the curves fall short of what the physics
    needs and Z3 refutes EBI under every reported condition."""
    assert model.CONTRACT_PERIODS == 1 + model.RECEIVER_TIMEOUT_PERIODS == 4 and model.CONTRACT_ZONE_PERIODS == 1
    proc = subprocess.run([sys.executable, "-c", PLANTED_SAMPLING], capture_output=True, text=True, timeout=600,
                          cwd=weakenings.REPO)
    assert proc.returncode == 0, proc.stderr[-2000:]
    statuses = proc.stdout.split()
    assert len(statuses) == len(obligations.CONDITIONS) and set(statuses) == {"refuted"}, proc.stdout


def test_the_brakes_receivers_keep_the_timing_contract():
    """Issue 40 item 3: the contract's stalled-monitor bound holds only if the brakes time out
    within RECEIVER_TIMEOUT_PERIODS: the CAN reference receiver and the train FMU's default
    alive timeout do (the model states the figure; the code is checked against it)."""
    from can_bus.brake_receiver import TIMEOUT_PERIODS
    from fmu.variables import TRAIN

    assert TIMEOUT_PERIODS <= model.RECEIVER_TIMEOUT_PERIODS
    timeout = next(v.start for v in TRAIN if v.name == "brake_timeout")
    assert 0 < timeout <= model.RECEIVER_TIMEOUT_PERIODS * Config().period_ms / 1000


def test_the_steps_glued_in_one_theorem_prove_and_are_tight():
    # issue 40 item 5: the chain's steps glued by one formula Z3 checks; it proves for every kind,
    # and asking for one metre more than the curve's margin is refuted (the glue is not vacuous)
    d = Declaration.of(Config())
    for kind in obligations.KINDS:
        assert obligations.refute(obligations.Lemmas(d, False, 1, 1).theorem(kind))[0] == "proved", kind
    greedy = obligations.Lemmas(replace(d, margin=d.margin + 1), False, 0, 0, curve_d=d)
    assert obligations.refute(greedy.theorem("static"))[0] == "refuted"


def test_the_rolling_obstacle_figure_is_the_stop_time_s_and_breaks_on_the_line_s_gradient():
    """The assumption that an obstacle keeps its speed, with the figure that breaks it
    (issue 40 item 3): a static obstacle rolling towards the train at a closes a t^2 / 2 more
    over the stop time t; the margin is gone at 2 margin / t^2. Worked by hand at 10 m/s (one
    band, fresh report, normal conditions): t = 4 periods + cut-off + the rest of the build-up
    + braking from v2 at 2.4 - g grad."""
    d = Declaration.of(Config())
    g = Fraction(981, 100) * Fraction(20, 1000)
    v1 = Fraction(102, 10) + (Fraction(1, 2) + g) * Fraction(12, 10)
    v2 = v1 + g * Fraction(2, 10)
    t = Fraction(14, 10) + v2 / (Fraction(24, 10) - g)
    stop, accel = model.rolling_limit(d, Fraction(10))
    assert abs(stop - t) < Fraction(1, 10**9) and accel == 2 * d.margin / (stop * stop)
    # a vehicle rolling free down the line's declared 20 per mille breaks it from 20 m/s on
    assert model.rolling_limit(d, Fraction(10))[1] > g > model.rolling_limit(d, Fraction(20))[1]
    assert any("rolling_limit" in a for a in model.ASSUMPTIONS)
