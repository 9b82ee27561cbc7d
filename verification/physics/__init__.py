"""`railguard verify --part physics`: the braking curves proved sufficient for the physics
(issue 30), for every train inside the braking declaration, with Z3.

* model.py: the world's train as a hybrid model, its phases' differential invariants, and
  the curves in exact real arithmetic;
* symbolic.py: the shipped monitor/core/braking.py run on symbolic numbers;
* obligations.py: the proof obligations (dI, sufficiency, integer >= real) and their check;
* weakenings.py: planted weakenings of the Python and the C, which the proof must catch;
* replay.py: a refuted obligation as a cosim scenario that collides.

The part proves the declaration in force (`--braking`, default the papers' train) and, when
none is given, also the example declarations with one and three speed bands; then it plants
each weakening, requires the proof to fail on it, and replays the counterexamples in FMPy.
"""
from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Callable, Optional

from monitor.core.config import Config

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = ("examples/braking-one-band.toml", "examples/braking-three-bands.toml")


def declarations(config: Optional[Config], quick: bool = False) -> list[tuple[str, Config]]:
    """(label, Config) of every declaration the part proves: the one given, else the papers'
    train and (full mode) the examples with one and three speed bands."""
    if config is not None and config != Config():
        return [("the declaration given", config)]
    if quick:
        return [("papers' train (shipped)", Config())]
    from monitor.declaration import apply, load

    out = [("papers' train (shipped)", Config())]
    for path in EXAMPLES:
        out.append((path, apply(Config(), load(REPO / path), path)))
    return out


def prove(cfg: Config, progress: Callable[[str], None] = lambda _: None, braking=None, whole: bool = True):
    """Every obligation for `cfg` on the shipped code (or the `braking` module given);
    `whole`: with the whole cycle's (whole_cycle.py)."""
    from monitor.core import braking as shipped

    from . import obligations

    return obligations.check_all(cfg, braking or shipped, progress=progress, whole=whole)


def weakening_runs(cfg: Config, out_dir: Path, progress: Callable[[str], None], replay_all: bool = True,
                   cluster=None) -> list[dict]:
    """Each planted weakening: the obligation it fails, and its counterexample replayed in
    co-simulation against the weakened and the shipped monitor (one dask task each)."""
    from ..scale import Cluster, map_ordered
    from . import weakenings

    jobs = [(w.name, cfg, Path(out_dir), replay_all) for w in weakenings.WEAKENINGS]
    rows = map_ordered(weakening_run, jobs, cluster or Cluster(), progress=progress, label="physics: weakenings",
                       unit="weakenings")
    for row in rows:
        progress(f"physics: weakening {row['weakening']}: {'caught' if row['caught'] else 'NOT caught'}"
                 + (f", replay {row['replay']['weakened']['outcome']}" if row["replay"] else ""))
    return rows


def weakening_run(job: tuple) -> dict:
    """One weakening (a dask task): caught by which obligations, and its replay."""
    from fmu import build
    from fmu.acceptance import curves_only_table
    from monitor.tables import read

    from . import obligations, replay, weakenings
    from .model import Declaration

    name, cfg, out_dir, replay_all = job
    w = weakenings.by_name(name)
    t0 = time.perf_counter()
    module = weakenings.weakened_braking(w)
    folder = out_dir / "physics" / w.name
    core = weakenings.weakened_core(w, folder / "core")
    d = Declaration.of(cfg)
    if w.memory:                    # the memory's feed: the whole cycle, Python and C (whole_cycle.py)
        from .whole_cycle import whole_cycle_results

        failed = [r for r in whole_cycle_results(cfg, sources=weakenings.weakened_sources(w), languages=("Python",),
                                                 first_failure=True) if not r.proved]
        failed_c = [r for r in whole_cycle_results(cfg, c_core=core, languages=("C",), first_failure=True)
                    if not r.proved]
    else:
        # (up to the first brake and condition that fails: caught needs one, the replay the first)
        failed = [r for r in obligations.integer_results(cfg, d, module, first_failure=True) if not r.proved]
        failed_c = [r for r in obligations.integer_results(cfg, d, obligations.c_code(core), first_failure=True)
                    if not r.proved]
    # caught only when the proof fails on the weakened Python and on the weakened C alike
    row = {"weakening": w.name, "what": w.what, "caught": bool(failed) and bool(failed_c),
           "failed": [r.name for r in failed + failed_c], "replay": None}
    if w.memory:
        if w.no_replay:
            row["replay_note"] = w.no_replay
        elif replay_all:
            row["replay"] = memory_replay(w, cfg, core, folder)
        row["seconds"] = time.perf_counter() - t0
        return row
    # the replay's declaration (replay.replay_declaration): worst_point finds the point where
    # the weakened curve falls short of the real one on it (a counterexample there too), or none
    played = replay.replay_declaration(cfg, w.name)
    target = next((r for r in failed if r.context["curve"] == "ebi" and not r.context["service"]
                   and not r.context["track"] and not r.context["brake"]), None)
    row["replay_declaration"] = {"speed_error_permille": played.speed_error_permille}
    if target is not None and replay_all:
        table = curves_only_table(read("m1"))            # the scenarios' table too (replay.write_scenario)
        fmu = build.build_monitor(table, 2, folder, name="weakened-monitor.fmu", core_dir=core)
        shipped = build.build_monitor(table, 2, folder, name="shipped-monitor.fmu")
        train = build.build_train(folder)
        points = [(oncoming, replay.worst_point(played, module, target, oncoming=oncoming))
                  for oncoming in (False, True)]
        tries = [(oncoming, point, pulling) for oncoming, point in points if point is not None
                 for pulling in replay.PULLING]
        for oncoming, point, pulling in tries:
            kind = ("oncoming" if oncoming else "static") + ("" if pulling else ", cruising")
            name = f"{w.name}-{kind.replace(', ', '-')}"
            title = f"{w.name} ({w.what}): {target.name}, {kind} obstacle"
            path, figures = replay.write_scenario(played, point, module, title, folder / f"{name}.toml", pulling)
            # the timing contract's worst for the weakened monitor: it stalls at the cycle where,
            # running, it first demands an emergency (its last cycle was its last one outside its
            # own EBI) and the brakes' receiver brakes at its timeout
            weak = replay.play(path, fmu, train)
            if weak["first_emergency_s"] is not None:
                path, figures = replay.write_scenario(played, point, module, title, folder / f"{name}.toml", pulling,
                                                      stall_s=weak["first_emergency_s"])
                weak = replay.play(path, fmu, train)
            sound = replay.play(path, shipped, train)
            entry = {"scenario": str(path), "kind": kind, "point": point, **figures, "weakened": weak,
                     "shipped": sound, "command": f"railguard cosim {path} --monitor-fmu {fmu}"}
            # kept: the first collision, else the replay where the weakened monitor stops nearest
            # (struck at standstill by an oncoming obstacle is no stop margin of the train's)
            if row["replay"] is None or replay_rank(entry) < replay_rank(row["replay"]):
                row["replay"] = entry
            if replay_rank(entry)[0] == 0:
                break
    row["seconds"] = time.perf_counter() - t0
    return row


def memory_replay(w, cfg: Config, core: Path, folder: Path) -> dict:
    """A memory weakening played (replay.memory_scenario_text): an oncoming train seen once,
    then every channel blind, with the weakened and the shipped monitor FMU."""
    from fmu import build
    from fmu.acceptance import curves_only_table
    from monitor.tables import read

    from . import replay

    played = replay.replay_declaration(cfg, w.name)
    table = curves_only_table(read("m1"))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "curves-only.rgt").write_bytes(table)
    fmu = build.build_monitor(table, 2, folder, name="weakened-monitor.fmu", core_dir=core)
    shipped = build.build_monitor(table, 2, folder, name="shipped-monitor.fmu")
    train = build.build_train(folder)
    text, figures = replay.memory_scenario_text(played, f"{w.name} ({w.what}): an oncoming train seen once, then "
                                                "every channel blind", (folder / "curves-only.rgt").resolve())
    path = folder / f"{w.name}-oncoming-blind.toml"
    path.write_text(text)
    return {"scenario": str(path), "kind": "oncoming, then blind", "point": replay.MEMORY_REPLAY, **figures,
            "weakened": replay.play(path, fmu, train), "shipped": replay.play(path, shipped, train),
            "command": f"railguard cosim {path} --monitor-fmu {fmu}"}


def replay_rank(entry: dict) -> tuple:
    """Order of replays: a collision of the weakened monitor where the shipped one does not
    collide first, then the weakened monitor's stop margin (smallest first)."""
    weak, sound = entry["weakened"], entry["shipped"]
    if weak["outcome"] == "collision" and sound["outcome"] != "collision":
        return (0, 0.0)
    return (1, weak["margin_m"] if weak["outcome"] == "stopped" else float("inf"))


def prove_task(job: tuple) -> list:
    """One declaration's obligations (a dask task)."""
    return prove(job[1], whole=job[2])


def markdown(proofs: list[tuple[str, list]], weak: list[dict]) -> str:
    from .model import ASSUMPTIONS
    from .report_md import proofs_md, weakenings_md

    return proofs_md(proofs, ASSUMPTIONS) + weakenings_md(weak)


def section(out_dir, quick: bool, progress, config: Optional[Config] = None):
    """The `railguard verify` part: the declaration in force, every weakening caught (quick
    mode, about 30 s); also the example declarations and the replays in FMPy (full mode and
    `--part physics`, about two minutes)."""
    from ..report import Check, Section

    from ..scale import Cluster, map_ordered

    out_dir = Path(out_dir)
    checks, proofs = [], []
    # the whole cycle (whole_cycle.py) for the declaration in force; the examples show the curves'
    # proofs for other band shapes (the memory's feed reads no band)
    todo = [(label, cfg, i == 0) for i, (label, cfg) in enumerate(declarations(config, quick))]
    cluster = Cluster(min(len(todo), Cluster().size()))
    for (label, _, _), results in zip(todo, map_ordered(prove_task, todo, cluster, progress=progress,
                                                     label="physics: declarations", unit="declarations")):
        progress(f"physics: {label}: {sum(r.proved for r in results)} of {len(results)} obligations proved "
                 f"({sum(r.seconds for r in results):.1f} s of Z3)")
        proofs.append((label, results))
        for r in results:
            checks.append(Check(f"physics [{label}] {r.name}", r.proved, f"{r.status} in {r.seconds:.2f} s",
                                {"kind": r.kind, "phase": r.phase, "status": r.status, "seconds": round(r.seconds, 3),
                                 "counterexample": r.model, "declaration": label}))
    weak = weakening_runs(config or Config(), out_dir, progress, replay_all=not quick)   # a worker per core
    for row in weak:
        checks.append(Check(f"physics: planted weakening {row['weakening']} is caught", row["caught"],
                            "fails " + (row["failed"][0] if row["failed"] else "nothing"), row))
    (out_dir / "physics").mkdir(parents=True, exist_ok=True)
    (out_dir / "physics" / "physics.json").write_text(json.dumps(
        {"declarations": [{"declaration": label, "obligations": [r.__dict__ for r in results]} for label, results in proofs],
         "weakenings": weak}, indent=1, default=str))
    proved = sum(r.proved for _, rs in proofs for r in rs)
    total = sum(len(rs) for _, rs in proofs)
    return Section("Physics: the curves proved sufficient (Z3)", markdown(proofs, weak), checks,
                   headline={"obligations": total, "proved": proved})
