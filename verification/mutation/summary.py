"""The verdict over many mutants: score (killed / non-equivalent; timeouts count as
killed, stillborn C mutants are left out), survivors, equivalents (and those wrongly listed
or stale), figures by file (`summarize`), and the text the command prints (`render`).
"""
from __future__ import annotations

from typing import Optional

from .mutant import Mutant


def summarize(mutants: list[Mutant], equivalents: dict[str, str], seconds: float, extra: Optional[dict] = None,
              known: Optional[set] = None) -> dict:
    """`known`: every mutant id of the files run (default: those of `mutants`), so that a run
    of part of a file (--scope, --only) does not call the rest of its listed equivalents stale."""
    ids = {m.id for m in mutants} if known is None else known
    for m in mutants:
        m.equivalent = m.id in equivalents
    stillborn = [m for m in mutants if m.status == "stillborn"]      # C: does not compile cleanly
    non_eq = [m for m in mutants if not m.equivalent and m.status != "stillborn"]
    killed = [m for m in non_eq if m.status in ("killed", "timeout")]
    survived = [m for m in non_eq if m.status not in ("killed", "timeout")]
    eq = [m for m in mutants if m.equivalent]
    wrong_eq = [m.id for m in eq if m.status in ("killed", "timeout")]
    score = len(killed) / len(non_eq) if non_eq else 1.0
    return {
        "score": score,
        "total": len(mutants) - len(stillborn),
        "stillborn": len(stillborn),
        "killed": len(killed),
        "survived": len(survived),
        "equivalent": len(eq),
        "timeouts": sum(m.status == "timeout" for m in mutants),
        "errors": sum(m.status == "error" for m in mutants),
        "seconds": round(seconds, 1),
        "survivors": [{"id": m.id, "diff": m.diff(), "status": m.status, "detail": m.detail} for m in survived],
        "equivalents": [{"id": m.id, "reason": equivalents[m.id]} for m in eq],
        "equivalent_but_killed": wrong_eq,
        "stale_equivalents": sorted(k for k in equivalents if k not in ids and k.split(":", 1)[0] in {m.file for m in mutants}),
        "by_file": _by_file(mutants),
        "mutants": [_public(m, equivalents) for m in mutants],
        **(extra or {}),
    }


def _public(m: Mutant, equivalents: dict[str, str]) -> dict:
    d = m.public()
    if m.equivalent:
        d["detail"] = (f"listed as equivalent but killed by {m.detail}" if m.status in ("killed", "timeout")
                       else equivalents[m.id])
    return d


def _by_file(mutants: list[Mutant]) -> dict:
    out: dict[str, dict] = {}
    for m in mutants:
        d = out.setdefault(m.file, {"total": 0, "killed": 0, "survived": 0, "equivalent": 0, "timeouts": 0})
        if m.status == "stillborn":
            continue
        d["total"] += 1
        if m.equivalent:
            d["equivalent"] += 1
        elif m.status in ("killed", "timeout"):
            d["killed"] += 1
        else:
            d["survived"] += 1
        d["timeouts"] += m.status == "timeout"
    return out


def render(summary: dict) -> str:
    lines = [f"mutation score: {summary['killed']}/{summary['total'] - summary['equivalent']} = "
             f"{100 * summary['score']:.1f} % of the non-equivalent mutants killed "
             f"({summary['total']} mutants, {summary['equivalent']} equivalent, {summary['survived']} survived, "
             f"{summary['timeouts']} timeouts counted as killed"
             + (f", {summary['stillborn']} stillborn (do not compile) left out" if summary.get("stillborn") else "")
             + f", {summary['seconds']:.0f} s)"]
    if summary["survivors"]:
        lines.append("\nsurvivors:")
        for s in summary["survivors"]:
            lines.append(f"  {s['id']}  [{s['status']}{': ' + s['detail'] if s['detail'] else ''}]")
            lines += ["      " + x for x in s["diff"].splitlines()]
    if summary["equivalents"]:
        lines.append("\nequivalent:")
        for e in summary["equivalents"]:
            lines.append(f"  {e['id']}: {e['reason']}")
    if summary["equivalent_but_killed"]:
        lines.append("\nlisted as equivalent but killed (remove from the list): " + ", ".join(summary["equivalent_but_killed"]))
    if summary["stale_equivalents"]:
        lines.append("\nlisted as equivalent but no such mutant: " + ", ".join(summary["stale_equivalents"]))
    return "\n".join(lines)
