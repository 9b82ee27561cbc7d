"""What every part of `railguard verify` returns, and how the report is written.

A part is a function `section(out_dir, quick, progress) -> Section`: it computes its
figures, saves its PNGs into `out_dir`, and returns Markdown plus a list of checks, each
with a verdict and the figure behind it. `write_report` puts the sections together into
out_dir/report.md; the CLI prints one line per check and exits non-zero if one fails.
"""
from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

Progress = Callable[[str], None]


@dataclass
class Check:
    name: str            # short, unique, e.g. "m1: crash probability exact vs storm"
    passed: bool
    figure: str          # the number behind the verdict, as printed, e.g. "2.1e-12 <= 1e-6"
    details: dict = field(default_factory=dict)   # anything else worth keeping in the JSON

    def line(self) -> str:
        return f"{'PASS' if self.passed else 'FAIL'}  {self.name}: {self.figure}"


@dataclass
class Section:
    title: str
    markdown: str                  # body of the section (tables, text, image links relative to out_dir)
    checks: list[Check] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)   # PNG file names written into out_dir
    seconds: float = 0.0
    headline: dict = field(default_factory=dict)   # the part's headline figures, at the JSON's top level


def timed(fn: Callable[..., Section], *args, **kwargs) -> Section:
    t0 = time.perf_counter()
    sec = fn(*args, **kwargs)
    sec.seconds = time.perf_counter() - t0
    return sec


def md_table(header: list[str], rows: list[list]) -> str:
    """A Markdown table; floats are printed as given (format them before)."""
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c).replace("|", "\\|") for c in row) + " |" for row in rows]
    return "\n".join(out) + "\n"


def write_report(out_dir: Path, sections: list[Section], mode: str, header: str = "") -> Path:
    checks = [c for s in sections for c in s.checks]
    passed = all(c.passed for c in checks)
    lines = [f"# railguard verification report ({mode} mode)\n", header,
             f"**{'All checks passed' if passed else 'SOME CHECKS FAILED'}**: "
             f"{sum(c.passed for c in checks)} of {len(checks)} checks passed.\n",
             md_table(["check", "verdict", "figure", "part"],
                      [[c.name, "pass" if c.passed else "**FAIL**", c.figure, s.title] for s in sections for c in s.checks]),
             md_table(["part", "time (s)"], [[s.title, f"{s.seconds:.1f}"] for s in sections])]
    for s in sections:
        lines.append(f"\n## {s.title}\n\n{s.markdown}\n")
    path = out_dir / "report.md"
    path.write_text("\n".join(lines))
    (out_dir / "report.json").write_text(json.dumps(as_json(sections), indent=1, default=plain))
    return path


def plain(value):
    """JSON for numpy scalars and anything else a part may put in its details."""
    return value.item() if hasattr(value, "item") else str(value)


def as_json(sections: list[Section]) -> dict:
    checks = [dict(json.loads(json.dumps(asdict(c), default=plain)), part=s.title) for s in sections for c in s.checks]
    for c in checks:
        c["passed"] = bool(c["passed"])
    out = {"passed": all(c["passed"] for c in checks), "checks": checks,
           "parts": [{"title": s.title, "seconds": round(s.seconds, 2), "figures": s.figures} for s in sections]}
    for s in sections:
        for key, value in s.headline.items():
            out.setdefault(key, json.loads(json.dumps(value, default=plain)))
    return out
