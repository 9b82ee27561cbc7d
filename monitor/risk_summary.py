"""The live risk over a run, summarised and drawn the same way for `railguard run`, `replay`
and `cosim`: peaks, time per seed 001 category, the plot's columns and the printed line.
Pure: the shells hand it the core's per-cycle figures (ppm, category)."""
from __future__ import annotations

from dataclasses import dataclass, field

from .core.risk import CATEGORY_NAMES, PPM

LABELS = ("R1 (seed 000 eq. 16)", "R2 (seed 000 eq. 17)", "table: P(hazard in 30 s | node)")


@dataclass
class RiskTally:
    """Added one cycle (or communication step) at a time, in constant memory."""

    period_ms: int
    peak_r1: int = 0
    peak_r2: int = 0
    peak_table: int = 0
    cycles: list = field(default_factory=lambda: [0] * len(CATEGORY_NAMES))

    def add_values(self, r1_ppm: int, r2_ppm: int, table_risk_ppm: int, category: int) -> None:
        self.peak_r1 = max(self.peak_r1, r1_ppm)
        self.peak_r2 = max(self.peak_r2, r2_ppm)
        self.peak_table = max(self.peak_table, table_risk_ppm)
        self.cycles[min(max(category, 1), len(CATEGORY_NAMES)) - 1] += 1

    def add(self, rec) -> None:
        """A cycle record or Outputs (anything with the core's risk fields)."""
        self.add_values(rec.r1_ppm, rec.r2_ppm, rec.table_risk_ppm, rec.risk_category)

    def as_dict(self) -> dict:
        return {"peak_r1_pct": round(self.peak_r1 / 1e4, 2), "peak_r2_pct": round(self.peak_r2 / 1e4, 2),
                "peak_table_ppm": self.peak_table,
                **{f"{name}_s": n * self.period_ms / 1000 for name, n in zip(CATEGORY_NAMES, self.cycles)}}


def risk_line(risk: dict) -> str:
    """The summary's one printed line."""
    return (f"risk: peak R1 {risk['peak_r1_pct']:g} %, R2 {risk['peak_r2_pct']:g} %, table {risk['peak_table_ppm']:,} ppm; "
            "seed 001 category: " + ", ".join(f"{name} {risk[f'{name}_s']:g} s" for name in CATEGORY_NAMES))


def risk_columns(r1_ppm, r2_ppm, table_risk_ppm, category) -> dict:
    """monitor.plot.plot_run's `risk` keyword: each estimator as a probability per cycle; the
    table's risk (ppm, often below 10^-4) under "log", drawn on a logarithmic axis."""
    return {"risk": {LABELS[0]: [v / PPM for v in r1_ppm], LABELS[1]: [v / PPM for v in r2_ppm],
                     "log": {LABELS[2]: [v / PPM for v in table_risk_ppm]},
                     "category": [int(c) for c in category]}}
