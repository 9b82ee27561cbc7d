"""Read a table file and show it to a person: header first, then node by node."""
from __future__ import annotations

from pathlib import Path

from ..core.table import Table, TableError, decode
from .relaxation import describe_upper


def read(path: str | Path, expect_model: str | None = None) -> Table:
    """Decode a table file; an unreadable file is a TableError like any other bad table."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise TableError(f"{p}: cannot read: {exc.strerror or exc}") from None
    try:
        return decode(data, expect_model)
    except TableError as exc:
        raise TableError(f"{p}: {exc}") from None


def _group_edges(table: Table, node: int) -> list[tuple[int, list[str]]]:
    """(target node, observations leading there), targets in order of first observation."""
    groups: dict[int, list[str]] = {}
    for obs, target in zip(table.observations, table.next[node]):
        groups.setdefault(target, []).append(obs)
    return list(groups.items())


def render(table: Table, max_observations: int = 6) -> str:
    h = table.header
    lines = [
        f"railguard table  format {h.get('format_version')}  model {table.model}",
        f"sha256           {table.sha256}",
        f"dimensions       {len(h['states'])} states, {len(table.actions)} actions, "
        f"{len(table.observations)} observations, {table.nodes} nodes (start node {table.start})",
    ]
    for key, label in (("controller_value", "controller value"), ("lower_bound", "lower bound"), ("upper_bound", "upper bound")):
        if key in h:
            lines.append(f"{label:<16} {h[key]:.4f}")
    if "relaxation" in h and "upper_bound" in h:
        lines[-1] += f"   ({describe_upper(h['relaxation']['model_upper_bound'], h['relaxation'])})"
    if "params" in h:
        lines.append("parameters       " + ", ".join(f"{k}={v}" for k, v in h["params"].items()))
    lines.append("")
    lines.append("node  action              next node on observation")
    for n in range(table.nodes):
        edges = []
        for target, obs in _group_edges(table, n):
            shown = ", ".join(obs[:max_observations]) + (f", ... (+{len(obs) - max_observations})" if len(obs) > max_observations else "")
            edges.append(f"{target} <- {shown}")
        lines.append(f"{n:>4}  {table.actions[table.action[n]]:<18}  " + "; ".join(edges))
    return "\n".join(lines) + "\n"


def as_json(table: Table) -> dict:
    return {
        "sha256": table.sha256,
        "header": dict(table.header),
        "action": [table.actions[a] for a in table.action],
        "next": [list(row) for row in table.next],
    }
