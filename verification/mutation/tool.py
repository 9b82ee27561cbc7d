"""The whole tool: generate, run and summarize (`run`), and its command line (`main`, which
`python -m verification.mutation` runs).
"""
from __future__ import annotations

import json
import sys
import time
from typing import Iterable, Optional

from .generate_c import c_mutants
from .generate_python import python_mutants
from .mutant import load_equivalents
from .runner import run_c, run_python
from . import scope as scope_mod
from .summary import render, summarize
from .targets import C_FILES, JOBS, PY_FILES, PY_TESTS, Progress


def run(target: str = "python", files: Optional[list[str]] = None, jobs: int = JOBS, timeout: Optional[float] = None,
        progress: Progress = lambda m: None, tests: Optional[Iterable[str]] = None,
        skip_equivalent: bool = False, only: Optional[Iterable[str]] = None, baseline: bool = True,
        scope: Optional[Iterable[str]] = None) -> dict:
    """Generate, run and summarize; with `skip_equivalent` the listed equivalent mutants are
    not run (the full run checks that they survive); `scope` (FILE[:FUNCTION|:FIRST-LAST],
    see scope.py) keeps only the mutants inside one of the scopes."""
    t0 = time.perf_counter()
    scope = list(scope) if scope else None
    equivalents = load_equivalents()
    mutants, every, files = generate(target, files, scope)
    if only:
        wanted = set(only)
        mutants = [m for m in mutants if m.id in wanted]
        unknown = wanted - {m.id for m in mutants}
        if unknown:
            raise ValueError(f"no such mutant: {', '.join(sorted(unknown))}")
    todo = [m for m in mutants if not (skip_equivalent and m.id in equivalents)]
    for m in mutants:
        if m not in todo:
            m.status = "not run"
    where = f" in {', '.join(scope)}" if scope else ""
    progress(f"{len(mutants)} mutants of {len(files or (PY_FILES if target == 'python' else C_FILES))} file(s)"
             f"{where}, {len(todo)} to run")
    if target == "python":
        extra = run_python(todo, tests or PY_TESTS, jobs, timeout, progress, baseline=baseline)
    else:
        extra = run_c(todo, jobs, timeout, progress, baseline=baseline)
    return summarize(mutants, equivalents, time.perf_counter() - t0, {"target": target, **extra},
                     known={m.id for m in every})


def generate(target: str, files: Optional[list[str]] = None,
             scope: Optional[Iterable[str]] = None) -> tuple[list, list, Optional[list[str]]]:
    """(mutants, all, files): the mutants of `files` (default: all of monitor/core, or
    rg_core.c), or of the files the scopes name, kept to the scopes; `all` is every mutant
    of those files (what decides whether a listed equivalent is stale)."""
    scopes = scope_mod.parse(scope, target) if scope else []
    if scopes and not files:
        files = scope_mod.files_of(scopes)
    every = python_mutants(files or PY_FILES) if target == "python" else c_mutants(files)
    return (scope_mod.select(every, scopes) if scopes else every), every, files


def main(argv: Optional[list[str]] = None) -> int:
    import argparse

    from . import __doc__ as package_doc

    ap = argparse.ArgumentParser(prog="python -m verification.mutation", description=package_doc.splitlines()[0])
    ap.add_argument("--target", choices=("python", "c"), default="python")
    ap.add_argument("--files", nargs="+", help="files to mutate (default: all of monitor/core, or rg_core.c)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--list", action="store_true", help="list the mutants (id and diff) without running them")
    ap.add_argument("--jobs", type=int, default=JOBS)
    ap.add_argument("--timeout", type=float, default=None, help="seconds per mutant (default: 5 x the baseline, >= 60)")
    ap.add_argument("--only", nargs="+", metavar="ID", help="run only these mutants (ids as --list prints them)")
    ap.add_argument("--scope", nargs="+", metavar="FILE[:FUNCTION|:FIRST-LAST]",
                    help="only the mutants in these files, functions or line ranges (e.g. memory.py, "
                         "envelope.py:hold, cycle.py:163-209, fmu/c/core/rg_core.c:rg_observe)")
    ap.add_argument("--no-baseline", action="store_true",
                    help="do not first run the tests on the real core (needs --timeout)")
    ap.add_argument("--skip-equivalent", action="store_true",
                    help="do not run the mutants listed as equivalent (the full run checks that they survive)")
    args = ap.parse_args(argv)
    if args.no_baseline and args.timeout is None:
        ap.error("--no-baseline needs --timeout")
    if args.list:
        try:
            ms = generate(args.target, args.files, args.scope)[0]
        except ValueError as exc:               # a scope that names nothing the tool mutates
            print(f"python -m verification.mutation: {exc}", file=sys.stderr)
            return 2
        if args.json:
            print(json.dumps([m.public() for m in ms], indent=1))
        else:
            for m in ms:
                print(m.id)
                print("    " + m.diff().replace("\n", "\n    "))
            print(f"{len(ms)} mutants", file=sys.stderr)
        return 0
    try:
        summary = run(args.target, args.files, args.jobs, args.timeout,
                      progress=lambda msg: print(msg, file=sys.stderr, flush=True),
                      skip_equivalent=args.skip_equivalent, only=args.only, baseline=not args.no_baseline,
                      scope=args.scope)
    except ValueError as exc:                   # an unknown mutant id, or a scope that names nothing
        print(f"python -m verification.mutation: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(render(summary))
    ok = summary["survived"] == 0 and not summary["equivalent_but_killed"] and not summary["errors"]
    return 0 if ok else 1
