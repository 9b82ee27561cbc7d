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


WIDTH = 160          # a summary line fits a terminal a person reads (railguard table show)


def _wrap(label: str, items: list[str], width: int = WIDTH) -> list[str]:
    """`label` and comma-separated items, wrapped at `width` under the first item."""
    lines, line = [], f"{label:<16} "
    for i, item in enumerate(items):
        piece = item + ("," if i < len(items) - 1 else "")
        if len(line) + len(piece) + 1 > width and line.strip() != label:
            lines.append(line.rstrip())
            line = " " * 17
        line += piece + " "
    lines.append(line.rstrip())
    return lines


def _node_line(table: Table, n: int, full: bool, max_observations: int) -> str:
    """A node's action and where its observations lead: every transition (full, or when it
    fits in WIDTH), else its successors with how many observations lead to each, most first."""
    head = f"{n:>4}  {table.actions[table.action[n]]:<18}  "
    groups = _group_edges(table, n)
    edges = []
    for target, obs in groups:
        shown = ", ".join(obs[:max_observations]) + (f", ... (+{len(obs) - max_observations})" if len(obs) > max_observations else "")
        edges.append(f"{target} <- {shown}")
    line = head + "; ".join(edges)
    if full or len(line) <= WIDTH:
        return line
    ranked = [f"{target} <- {len(obs)} obs" for target, obs in sorted(groups, key=lambda g: (-len(g[1]), g[0]))]

    def shown(k: int) -> str:                 # the first k successors and how many are left out
        return head + "; ".join(ranked[:k]) + (f"; +{len(ranked) - k} more (--full)" if k < len(ranked) else "")

    k = len(ranked)
    while k > 1 and len(shown(k)) > WIDTH:
        k -= 1
    return shown(k)


def render(table: Table, max_observations: int = 6, full: bool = False) -> str:
    """The table for a person: header, then a line per node. By default each line fits in
    WIDTH characters (the successors with their observation counts where every transition
    would not fit); `full` lists every transition."""
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
        items = [f"{k}={v}" for k, v in h["params"].items()]
        lines += _wrap("parameters", items) if not full else ["parameters       " + ", ".join(items)]
    lines.append("")
    lines.append("node  action              next node on observation" + (
        "" if full else " (a long line: next node <- how many observations, most first)"))
    lines += [_node_line(table, n, full, max_observations) for n in range(table.nodes)]
    return "\n".join(lines) + "\n"


def as_json(table: Table) -> dict:
    return {
        "sha256": table.sha256,
        "header": dict(table.header),
        "action": [table.actions[a] for a in table.action],
        "next": [list(row) for row in table.next],
    }
