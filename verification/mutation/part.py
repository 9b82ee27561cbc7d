"""Mutation testing as a verification part: `section(out_dir, quick, progress)` runs the
Python core (quick: the voters, the listed equivalents not run; full: all of monitor/core
and then the C core) and checks that every non-equivalent mutant is killed.
"""
from __future__ import annotations

import json
from pathlib import Path

from .mutant import load_equivalents
from .targets import C_FILES, C_SEQUENCES, C_TESTS, PY_FILES, PY_TESTS, Progress, REPORT_QUICK_FILES
from .tool import run


def _score_rows(summary: dict) -> list[list]:
    rows = []
    for f, d in sorted(summary["by_file"].items()):
        non_eq = d["total"] - d["equivalent"]
        rows.append([f"`{f}`", d["total"], d["killed"], d["equivalent"], d["survived"], d["timeouts"],
                     f"{100 * d['killed'] / non_eq:.1f} %" if non_eq else "-"])
    return rows


def section(out_dir, quick: bool, progress: Progress, config=None):
    """Mutation testing as a report part: the Python core (quick: REPORT_QUICK_FILES,
    the listed equivalent mutants not run; full: all of monitor/core and the listed
    equivalents run to show that they survive). `config` is accepted for the report's
    uniform signature; the mutants run the core's own tests, which set their configurations."""
    from verification.report import Section, md_table

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = list(REPORT_QUICK_FILES if quick else PY_FILES)
    summary = run("python", files, progress=progress, skip_equivalent=quick)
    (out / "mutation.json").write_text(json.dumps(summary, indent=1))
    header = ["file", "mutants", "killed", "equivalent", "survived", "timeouts (killed)", "score"]
    rows = _score_rows(summary)
    rows.append(["**all**", summary["total"], summary["killed"], summary["equivalent"], summary["survived"],
                 summary["timeouts"], f"{100 * summary['score']:.1f} %"])
    md = [f"`python -m verification.mutation` ({'quick: ' + ', '.join(files) if quick else 'all of monitor/core'}): "
          f"{summary['total']} mutants (comparison swaps, and/or, a dropped operand of an and/or chain, min/max, "
          f"integer constants +/-1, +/-, a removed `not`, int/bool return values, type checks removed), each run "
          f"in a fresh process against the core's fast tests ({', '.join(f'`{t}`' for t in PY_TESTS)}); "
          f"a timeout counts as killed. Score = killed / non-equivalent mutants. Baseline "
          f"{summary.get('baseline_seconds', 0):.1f} s, whole run {summary['seconds']:.0f} s.\n",
          md_table(header, rows)]
    if summary["survivors"]:
        md.append("\nSurvivors:\n")
        md += [f"- `{x['id']}`: `{x['diff'].splitlines()[1][2:]}`" for x in summary["survivors"]]
    eq = load_equivalents()
    md.append("\nThe C core's decision functions are mutated by `python -m verification.mutation --target c` "
              "and judged by the Python-vs-C comparison test alone (`tests/test_mutation.py` runs a subset).\n")
    md.append(f"\nEquivalent mutants ({len([k for k in eq if k.split(':', 1)[0] in summary['by_file']])} in these "
              f"files, `verification/mutation_equivalents.toml`):\n")
    md += [f"- `{k}`: {v}" for k, v in eq.items() if k.split(":", 1)[0] in summary["by_file"]]
    checks = [_score_check("python core", summary, files)]
    seconds = summary["seconds"]
    if not quick:                   # the C core's decision functions, judged by the comparison test alone
        c = run("c", progress=progress)
        (out / "mutation-c.json").write_text(json.dumps(c, indent=1))
        seconds += c["seconds"]
        md.append(f"\n**C core** (`python -m verification.mutation --target c`: the decision functions of "
                  f"`rg_core.c`, each mutant compiled and judged by `{', '.join(C_TESTS)}` alone, {C_SEQUENCES:,} "
                  f"sequences per table): {c['total']} mutants, {c['killed']} killed, {c['equivalent']} equivalent, "
                  f"{c['survived']} survived, score {100 * c['score']:.1f} %, {c['seconds']:.0f} s.\n")
        md += [f"- `{x['id']}` survived" for x in c["survivors"]]
        checks.append(_score_check("C core (by the Python-vs-C comparison alone)", c, list(C_FILES)))
    return Section("Mutation testing of the core", "\n".join(md) + "\n", checks, [], seconds)


def _score_check(what: str, summary: dict, files: list):
    """100 % of the non-equivalent mutants killed, no error, no listed equivalent killed, no stale id."""
    from verification.report import Check

    non_eq = summary["total"] - summary["equivalent"]
    ok = (summary["survived"] == 0 and summary["errors"] == 0 and not summary["equivalent_but_killed"]
          and not summary["stale_equivalents"])
    return Check(f"mutation score {what}: killed/non-equivalent = 100 %", ok,
                 f"{summary['killed']}/{non_eq} = {100 * summary['score']:.1f} %"
                 + (f"; {len(summary['equivalent_but_killed'])} listed equivalent but killed" if summary["equivalent_but_killed"] else "")
                 + (f"; {len(summary['stale_equivalents'])} stale equivalent ids" if summary["stale_equivalents"] else "")
                 + (f"; {summary['errors']} errors" if summary["errors"] else ""),
                 {"total": summary["total"], "equivalent": summary["equivalent"], "survived": summary["survived"],
                  "timeouts": summary["timeouts"], "files": files})
