"""Mutation testing of the safety core: do the tests notice when the core is made wrong?

Python core (`monitor/core/*.py`): mutants are generated from the source with `ast`, one
small change each, with the classic operators:

    cmp        a comparison swapped: < <-> <=, > <-> >=, == <-> !=, is <-> is not, in <-> not in
    bool       and <-> or (the whole chain)
    drop       one operand of an and/or chain dropped (f1 or f2 or f3 -> f1 or f2)
    minmax     min <-> max
    int        an integer constant + 1 and - 1
    arith      + <-> - (binary and augmented)
    not        a `not` removed
    return     the value of a function annotated `-> int` (0, or 1 for a literal 0) or `-> bool`
               (True, False) replaced
    isinstance an isinstance(...) or type(x) is T check replaced by True

Docstrings, annotations, f-strings (error messages) and `__all__` are not mutated. Each
mutant has a stable id `file:line:col:operator:replacement` (1-based line and column of
the changed token), so equivalent mutants can be listed in
`verification/mutation_equivalents.toml` with the reason no test can tell them apart.

Each mutant runs in a fresh process: a fork server (one per job slot, 2 by default)
imports pytest, Hypothesis and numpy once, never the project, and forks a child per
mutant; the child serves the mutated source for the mutated module through an import hook
placed first on `sys.meta_path` (every other module is the real one), derandomises
Hypothesis (no database, no shrinking) and runs the core's fast tests (`PY_TESTS`: nothing
that needs vcan, FMUs, Frama-C or takes more than 10 s) with `pytest -x`: the first
failing test kills the mutant. A mutant whose module fails to import (an import-time
assertion) is killed too; a mutant still running after the per-mutant timeout (5 x the
baseline, at least 60 s) is killed, reported as a timeout and counted as killed.

C core (`--target c`): textual mutants of the same operators (comparison swaps, && <-> ||,
+ <-> -, a removed `!`, integer literals +/- 1) in the decision functions of
`fmu/c/core/rg_core.c` (`C_FUNCTIONS`). Each child copies `fmu/c`, writes the mutated
rg_core.c, refuses it as stillborn if it does not compile with the FMU's flags (warnings
allowed: `a || b && c` warns),
points `fmu.build.C_DIR` at the copy and runs the Python-vs-C comparison test alone
(`tests/test_fmu_equivalence.py`, which builds its FMUs from C_DIR), at C_SEQUENCES
sequences per table instead of its 5000 (its minimum edge hits scaled alike). Stillborn
mutants are left out of the score.

    python -m verification.mutation [--target python|c] [--files ...] [--scope ...] [--json] [--list]

`--scope FILE[:FUNCTION|:FIRST-LAST] ...` keeps the mutants of part of the files (a function,
a line range; `scope`), e.g. the code a change touched; the equivalents listed for the rest
of those files are not reported as stale.

prints progress on stderr, then the score (killed / non-equivalent), the survivors (id and
diff) and the equivalent ones with their reasons; `--json` prints one object with keys
`score`, `killed`, `survived`, `equivalent`, `timeouts`, `mutants`.

The pieces, one concept each: `targets` (what is mutated, what judges it), `mutant` (a
mutant, its id, the equivalents list), `generate_python` and `generate_c` (the operators),
`scope` (--scope),
`runner` (the fork servers, one fresh process per mutant), `summary` (score and report
text), `tool` (`run` and the command line; `__main__` runs it) and `part` (`section`).
This package re-exports their public names, so `from verification import mutation` reads
as before.
"""
from __future__ import annotations

from .targets import (
    CI_FILES, CI_SCOPES, CORE, C_DIR, C_FILES, C_FUNCTIONS, C_SEQUENCES, C_TESTS, EQUIVALENTS, JOBS, PY_FILES,
    PY_TESTS, REPORT_QUICK_FILES, ROOT, Progress,
)
from .mutant import Mutant, load_equivalents
from .generate_python import mutants_of, python_mutants
from .generate_c import c_mutants
from .runner import Server, run_c, run_python
from .summary import render, summarize
from .tool import main, run
from .part import section

__all__ = [
    "CI_FILES", "CI_SCOPES", "CORE", "C_DIR", "C_FILES", "C_FUNCTIONS", "C_SEQUENCES", "C_TESTS", "EQUIVALENTS", "JOBS",
    "PY_FILES", "PY_TESTS", "REPORT_QUICK_FILES", "ROOT", "Progress", "Mutant", "load_equivalents", "mutants_of",
    "python_mutants", "c_mutants", "Server", "run_c", "run_python", "render", "summarize", "main", "run", "section",
]
