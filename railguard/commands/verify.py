"""`railguard verify`: the evidence (closed-loop probabilities, the voter's hazard rate,
the papers reproduced, the campaign, stress, fuzzing, the proof, mutation scores) and its
report. The tools each part needs are checked before any work starts."""
from __future__ import annotations

import argparse
import json
import time

from .. import options, output
from ..errors import UserError
from ..setup import braking_config

# what a part needs beyond the package's own dependencies, and how to get it
PYTHON_NEEDS = {"closed_loop": ("stormpy",), "hazard": ("stormpy",), "mutation": ("pytest", "hypothesis")}
INSTALL = {"closed_loop": "pip install -e '.[verify]'", "hazard": "pip install -e '.[verify]'",
           "mutation": "pip install -e '.[test]'",
           "proof": "apt-get install frama-c-base why3 z3 cvc4 gcc && why3 config detect",
           "physics": "apt-get install gcc (its cpp preprocesses the C core; gcc builds the replays' FMUs)"}


def missing_tools(parts: tuple[str, ...]) -> list[str]:
    """One line per part whose tools are missing: what is missing and how to install it."""
    import importlib.util
    import shutil

    lines = []
    for part in parts:
        if part == "proof":
            from verification.proof import missing_tools as proof_missing

            gone = proof_missing() + ([] if shutil.which("gcc") else ["gcc"])
        elif part == "physics":
            gone = [t for t in ("cpp", "gcc") if shutil.which(t) is None]
        else:
            gone = [n for n in PYTHON_NEEDS.get(part, ()) if importlib.util.find_spec(n) is None]
        if gone:
            lines.append(f"part {part} needs {', '.join(gone)} ({INSTALL[part]})")
    return lines


def run_parts(args: argparse.Namespace, parts: tuple[str, ...]) -> int:
    """Run verification parts, print one line per check (or JSON), exit 1 if one fails."""
    from verification import run

    gone = missing_tools(parts)
    if gone:
        raise UserError("missing tools: " + "; ".join(gone) + "; or leave the part out with --skip PART")
    world = None
    if getattr(args, "world_train", None):
        from verification.world_train import load

        world = load(args.world_train)
    cluster = None
    if getattr(args, "workers", None) is not None or getattr(args, "scheduler", None):
        from ..setup import cluster as make_cluster

        cluster = make_cluster(args)
    say = output.stderr_lines(args.json)
    started = time.time()
    sections, report = run.run(args.out, args.quick, say or (lambda _: None), parts, config=braking_config(args),
                               world=world, margin_m=getattr(args, "unsafe_margin", 0.0), cluster=cluster)
    checks = [c for s in sections for c in s.checks]
    passed = all(c.passed for c in checks)
    if args.json:
        from verification.report import as_json, plain

        data = as_json(sections)
        data["report"] = str(report)
        print(json.dumps(data, default=plain))
        return 0 if passed else 1
    for c in checks:
        print(c.line())
    for s in sections:
        if "runs_digest" in s.headline:
            h = s.headline
            print(f"{s.title}: {h['runs']:,} runs, {h['unsafe']} unsafe, {h['collisions']} collisions; "
                  f"runs digest {h['runs_digest']}")
    print(f"{'passed' if passed else 'FAILED'}: {sum(c.passed for c in checks)} of {len(checks)} checks")
    output.wrote(sorted(p for p in report.parent.rglob("*") if p.is_file() and p.stat().st_mtime >= started - 1))
    return 0 if passed else 1


def verify(args: argparse.Namespace) -> int:
    from verification import run

    parts = tuple(p for p in (tuple(args.part) if args.part else run.default_parts(args.quick))
                  if p not in (args.skip or ()))
    if not parts:
        raise UserError("--skip leaves no part to run")
    return run_parts(args, parts)


def register(sub) -> None:
    from verification.run import PARTS

    v = sub.add_parser(
        "verify",
        help="compute the evidence: closed-loop probabilities, voter hazard rate, the papers reproduced, ...",
        description="Run every verification part and write a report (Markdown, JSON and PNG figures, and the "
                    "logs of the proof and the campaign) into --out: the closed-loop Markov analysis of the shipped "
                    "tables (exact and Storm), the tables against the simple rules, the 2oo2/3oo3 voter's hazard rate "
                    "against tolerable rates, the simulations of seed 000 and seed 001 through the monitor core, "
                    "their risk figures (Fig. 7c, risk accuracy) read back from the MonitorRisk frames of recorded "
                    "runs (live_risk), the fault campaign, stress testing, receive-path fuzzing, the Frama-C proof of the C core, the Z3 "
                    "proof that the braking curves are enough for the physics of every train inside the braking "
                    "declaration (physics: one line per proof obligation) and mutation testing. Prints one line per check; exit status 1 if any check fails. The tools each "
                    "part needs are checked first: stormpy (closed_loop, hazard: pip install -e '.[verify]'), "
                    "frama-c, why3, z3, cvc4 and gcc (proof: apt-get install frama-c-base why3 z3 cvc4 gcc, then "
                    "why3 config detect), cpp and gcc (physics); a missing one stops with one line naming it, exit 2.",
    )
    v.add_argument("--quick", action="store_true",
                   help="smaller Monte Carlo runs and grids, the declaration in force only, and without the long "
                        "parts proof and mutation unless named with --part (their own tests run them in CI): "
                        "about 3 minutes (default: the full report)")
    options.add_out(v, "railguard-out/verify", "report folder")
    v.add_argument("--part", action="append", choices=PARTS, metavar="PART",
                   help=f"run only this part, repeatable: {', '.join(PARTS)} (default: every part)")
    v.add_argument("--skip", action="append", choices=PARTS, metavar="PART",
                   help="leave this part out, repeatable (default: none)")
    v.add_argument("--braking", metavar="FILE.toml",
                   help=options.BRAKING_HELP + "; the physics part proves the curves for it (without it: for the "
                        "papers' train and examples/braking-one-band.toml, examples/braking-three-bands.toml), the "
                        "campaign and stress parts run with it")
    options.add_json(v, 'print {"passed": bool, "checks": [{"name", "passed", "figure", ...}], ...}')
    v.set_defaults(func=verify)
