"""Planted weakenings of the curves (issue 30 item 5): the proof must fail on each, and its
counterexample must collide in co-simulation with a monitor FMU built from the weakened C.

Each weakening is the same small edit to the shipped Python (monitor/core/braking.py) and C
(fmu/c/core/rg_core.c), written as text replacements so that the proof runs on the weakened
source itself, not on a model of it. An edit that no longer applies (the shipped code
changed) is an error, never a silent pass.
"""
from __future__ import annotations

import importlib.util
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]
BRAKING_PY = REPO / "monitor" / "core" / "braking.py"
CORE_DIR = REPO / "fmu" / "c" / "core"


class WeakeningError(RuntimeError):
    """A weakening's edit does not apply to the shipped source any more."""


@dataclass(frozen=True)
class Weakening:
    name: str
    what: str
    python: tuple          # ((old, new), ...) in monitor/core/<module>.py
    c: tuple               # ((old, new), ...) in rg_core.c or rg_core.h
    module: str = "braking"    # the Python module edited: braking (the curves), cycle or memory (the memory's feed)
    no_replay: str = ""        # why no playable point can show it (the report says so instead of a replay)

    @property
    def memory(self) -> bool:
        """An edit of what the step feeds the memory: the whole-cycle proof must catch it."""
        return self.module != "braking"


WEAKENINGS = (
    Weakening("traction-dropped", "the traction term of the reaction phase dropped (a1 = g grad only)",
              (("    a1 = cfg.max_accel_mms2 + g\n", "    a1 = g\n"),),
              (("    a1 = (int64_t)cfg->max_accel_mms2 + g;", "    a1 = g;"),)),
    Weakening("speed-error-ignored", "the speed error ignored (v_max = the measured speed)",
              (("    v_max = -(-speed_cms * (1000 + e) // 1000)\n", "    v_max = speed_cms\n"),),
              (("    const int64_t v_max = (v * (1000 + e) + 999) / 1000;", "    const int64_t v_max = v;"),)),
    Weakening("gradient-uphill", "the gradient taken uphill (g grad added to the brakes, taken from traction)",
              (("    g = gradient_accel_mms2(cfg.max_gradient_permille)\n",
                "    g = -gradient_accel_mms2(cfg.max_gradient_permille)\n"),),
              (("    const int64_t g = rg_gradient_accel_mms2(cfg->max_gradient_permille);",
                "    const int64_t g = -rg_gradient_accel_mms2(cfg->max_gradient_permille);"),)),
    Weakening("buildup-halved", "the brake's equivalent build-up halved",
              (("(cfg.service_buildup_ms if service else cfg.emergency_buildup_ms), g",
                "(cfg.service_buildup_ms if service else cfg.emergency_buildup_ms) // 2, g"),),
              (("    const int64_t buildup = service ? cfg->service_buildup_ms : cfg->emergency_buildup_ms;",
                "    const int64_t buildup = (service ? cfg->service_buildup_ms : cfg->emergency_buildup_ms) / 2;"),)),
    # issue 40 item 3: the periods a stalled monitor lets pass before the brakes' receiver times
    # out, left out (the curves of before: sampling + the demand's way, 2 periods, not 4)
    Weakening("stall-ignored", "a stalled monitor's periods left out of the supervision's reaction (two periods, not four)",
              (("SUPERVISED_PERIODS = 4\n", "SUPERVISED_PERIODS = 2\n"),),
              (("#define RG_SUPERVISED_PERIODS 4", "#define RG_SUPERVISED_PERIODS 2"),)),
    Weakening("oncoming-ignored", "the oncoming obstacle's travel left out of EBI",
              (("    ebi = s1 + s2 + s3 + cfg.standstill_margin_dm + obstacle_run_dm(obstacle_cms, t1 + t2 + t3)\n",
                "    ebi = s1 + s2 + s3 + cfg.standstill_margin_dm\n"),),
              (("    ebi = s1 + s2 + s3 + cfg->standstill_margin_dm + rg_obstacle_run_dm(obstacle, t1 + t2 + t3) + near_dm;",
                "    ebi = s1 + s2 + s3 + cfg->standstill_margin_dm + near_dm;"),)),
    # issue 40 item 2: the memory's feed, which the pieces' proofs could not see
    Weakening("memory-moved-at-half", "the caller moves a remembered obstacle at half its closing speed",
              (("t.closing + cfg.closing_accuracy_cms, cfg.period_ms", "t.closing // 2 + cfg.closing_accuracy_cms, cfg.period_ms"),),
              (("(int64_t)next_tracks[i].closing + cfg->closing_accuracy_cms,",
                "(int64_t)next_tracks[i].closing / 2 + cfg->closing_accuracy_cms,"),), module="cycle"),
    Weakening("memory-half-speed", "observe remembers half an oncoming obstacle's speed",
              (("    own = obstacle_cms if obstacle_cms > 0 else 0\n", "    own = obstacle_cms // 2 if obstacle_cms > 0 else 0\n"),),
              (("    const int32_t own = obstacle_cms > 0 ? obstacle_cms : 0;",
                "    const int32_t own = obstacle_cms > 0 ? obstacle_cms / 2 : 0;"),), module="memory"),
    # issue 40 item 3: the error budget, each of its terms left out once
    Weakening("distance-accuracy-ignored", "the sensors' distance accuracy left out of EBI",
              (("    ebi += cfg.distance_accuracy_dm\n", "    ebi += 0\n"),),
              (("rg_obstacle_run_dm(obstacle, t1 + t2 + t3) + near_dm;", "rg_obstacle_run_dm(obstacle, t1 + t2 + t3);"),)),
    Weakening("closing-accuracy-ignored", "the sensors' closing-speed accuracy left out of the curves",
              (("closing_cms + cfg.closing_accuracy_cms, age_ms, service,", "closing_cms, age_ms, service,"),),
              (("(int64_t)closing_cms + (supervised ? cfg->closing_accuracy_cms : 0)", "(int64_t)closing_cms + 0"),)),
    Weakening("memory-accuracy-ignored", "the memory moves a remembered obstacle at its measured closing speed, "
              "without the sensors' accuracy",
              (("t.closing + cfg.closing_accuracy_cms, cfg.period_ms", "t.closing, cfg.period_ms"),),
              (("(int64_t)next_tracks[i].closing + cfg->closing_accuracy_cms,", "(int64_t)next_tracks[i].closing,"),),
              module="cycle"),
    Weakening("passed-accuracy-ignored", "a remembered obstacle counted passed at its reported position, not a "
              "distance accuracy beyond it",
              (("reach = far + cfg.distance_accuracy_dm * UNITS_PER_DM", "reach = far"),),
              (("const int64_t reach = far + (int64_t)cfg->distance_accuracy_dm * RG_UNITS_PER_DM;",
                "const int64_t reach = far;"),), module="cycle",
              no_replay="no playable point: a train passes a remembered obstacle's reported position only if its "
              "curves, which count the distance accuracy, did not stop it first; the one-cycle invariant (whole "
              "cycle) starts from any remembered state, the closed loop never reaches one where this edit matters"),
)


def by_name(name: str) -> Weakening:
    for w in WEAKENINGS:
        if w.name == name:
            return w
    raise WeakeningError(f"no weakening {name!r}; known: {', '.join(w.name for w in WEAKENINGS)}")


def edit(text: str, edits: tuple, where: str) -> str:
    for old, new in edits:
        if text.count(old) != 1:
            raise WeakeningError(f"{where}: the weakening's edit does not apply (expected once: {old.strip()!r})")
        text = text.replace(old, new)
    return text


def weakened_sources(w: Weakening) -> dict:
    """{module: edited text} of a memory weakening, for whole_cycle.python_step."""
    path = REPO / "monitor" / "core" / f"{w.module}.py"
    return {w.module: edit(path.read_text(), w.python, f"monitor/core/{w.module}.py")}


def weakened_braking(w: Weakening) -> ModuleType:
    """monitor/core/braking.py with the weakening applied, as a module of its own package
    (its relative imports resolve as the shipped one's do)."""
    if w.memory:                        # the curves are the shipped ones
        from monitor.core import braking
        return braking
    name = f"monitor.core._braking_{w.name.replace('-', '_')}"
    spec = importlib.util.spec_from_loader(name, loader=None, origin=str(BRAKING_PY))
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "monitor.core"
    source = edit(BRAKING_PY.read_text(), w.python, "monitor/core/braking.py")
    sys.modules[name] = module
    exec(compile(source, f"{BRAKING_PY} ({w.name})", "exec"), module.__dict__)   # noqa: S102 - our own source, edited
    return module


def weakened_core(w: Weakening, folder: Path) -> Path:
    """A copy of fmu/c/core with the weakening applied: each C edit to the one file of
    rg_core.c and rg_core.h that holds its text."""
    folder.mkdir(parents=True, exist_ok=True)
    for path in CORE_DIR.glob("*.[ch]"):
        shutil.copy(path, folder / path.name)
    files = [folder / "rg_core.c", folder / "rg_core.h"]
    for old, new in w.c:
        holders = [f for f in files if old in f.read_text()]
        if len(holders) != 1:
            raise WeakeningError(f"fmu/c/core: the weakening's edit does not apply (expected in one file: {old.strip()!r})")
        holders[0].write_text(edit(holders[0].read_text(), ((old, new),), f"fmu/c/core/{holders[0].name}"))
    return folder
