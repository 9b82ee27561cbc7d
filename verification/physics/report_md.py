"""The physics part's section of the verification report (Markdown)."""
from __future__ import annotations

from ..report import md_table


def proofs_md(proofs: list, assumptions: tuple) -> str:
    md = ["Every obligation is a formula whose negation Z3 (nlsat, real arithmetic) finds unsatisfiable; "
          "`refuted` comes with a counterexample, `unknown` (a timeout) does not count as proved. The model "
          "(verification/physics/model.py): reaction (report age + the sampling period + the demand's period + traction cut-off, under traction "
          "and downhill), the rest of the equivalent build-up coasting downhill, braking by speed band at the "
          "guaranteed deceleration times the reported adhesion factors less the downhill pull; every bound a "
          "variable inside the declaration. The integer obligations run the shipped `monitor/core/braking.py` "
          "and the C core's `rg_curves` (fmu/c/core/rg_core.c, preprocessed, parsed and interpreted with C's "
          "semantics) on symbolic numbers (every path).\n\nAssumptions of the model:\n"]
    md += [f"- {a}" for a in assumptions]
    for label, results in proofs:
        by_kind = {}
        for r in results:
            by_kind.setdefault(r.kind, []).append(r)
        md.append(f"\n### {label}\n")
        md.append(md_table(["obligations", "proved", "refuted", "unknown", "time (s)"],
                           [[k, sum(r.proved for r in rs), sum(r.status == "refuted" for r in rs),
                             sum(r.status == "unknown" for r in rs), f"{sum(r.seconds for r in rs):.1f}"]
                            for k, rs in by_kind.items()]))
        bad = [r for r in results if not r.proved]
        for r in bad:
            md.append(f"\n- **{r.status}**: {r.name}: `{r.model}`")
    return "\n".join(md) + "\n"


def weakenings_md(rows: list) -> str:
    md = ["\n### Planted weakenings\n",
          "Each is the same edit to the Python (`monitor/core/braking.py`; for the memory's feed, `cycle.py` or "
          "`memory.py`) and to `fmu/c/core/rg_core.c` (verification/physics/weakenings.py). The proof must fail "
          "on the weakened Python and on the weakened C: a curve's edit fails an integer obligation, a memory "
          "edit the whole cycle's (whole_cycle.py). A curve's counterexample (the fastest playable point where the weakened EBI falls short of the real one "
          "by more than a cycle's travel; for an oncoming obstacle, the largest shortfall) is written as a cosim "
          "scenario on the declaration with speed error 0 (the speed error's own weakening keeps it): the "
          "world's train at the declaration's corner, pulling at full traction until the demand or cruising, "
          "its sensors at the error budget's (the obstacle reported the whole distance accuracy farther and "
          "closing the whole closing accuracy slower than it is), the first reading one cycle's travel inside "
          "the shipped EBI; it is played with a monitor FMU built "
          "from the weakened C and with the shipped one (verification/physics/replay.py says why).\n"]
    table = []
    for r in rows:
        rp = r["replay"]
        if rp is None:                  # why no replay: the report says (issue 40 item 5)
            why = r.get("replay_note") or "no playable point: no obligation on a playable curve failed"
            table.append([r["weakening"], "yes" if r["caught"] else "**no**", len(r["failed"]), why, "-", "-"])
            continue
        table.append([r["weakening"], "yes" if r["caught"] else "**no**", len(r["failed"]),
                      f"{rp['kind']}, {rp['true_speed_mps']:.1f} m/s, EBI {rp['ebi_shipped_m']:.1f} -> "
                      f"{rp['ebi_weakened_m']:.1f} m",
                      _outcome(rp["weakened"]), _outcome(rp["shipped"])])
    md.append(md_table(["weakening", "caught", "obligations failed", "replayed point", "weakened monitor",
                        "shipped monitor"], table))
    return "\n".join(md) + "\n"


def _outcome(o: dict) -> str:
    if o["outcome"] == "collision":
        return f"collision at {o['impact_speed']:.1f} m/s"
    if o["outcome"] == "stopped" and o.get("margin_m") is not None:
        return f"stopped {o['margin_m']:.1f} m short"
    return o["outcome"]

