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


def risk_range(table: Table) -> str:
    """The risk column in a phrase: its range and median, or that none was computed."""
    info = table.header.get("risk", {})
    if not table.risk or info.get("horizon_s") is None:
        return "none computed (every node at 10^6 ppm, the safe side)"
    r = sorted(table.risk)
    return (f"P(hazard within {info['horizon_s']:g} s | node) {r[0]:,} .. {r[-1]:,} ppm, "
            f"median {r[len(r) // 2]:,} ppm")


def _risk(table: Table, n: int) -> str:
    return f"{table.risk[n]:>9,}" if table.risk else f"{'-':>9}"


def _node_line(table: Table, n: int, full: bool, max_observations: int, successors=None) -> str:
    """A node's action, risk and where it goes next. `full`: every transition. Otherwise, with
    the closed loop's `successors` (N x N probabilities), the next nodes likeliest first;
    without them, every transition when it fits in WIDTH, else the next nodes with how many
    observations lead to each, most first."""
    head = f"{n:>4}  {table.actions[table.action[n]]:<18} {_risk(table, n)}  "
    groups = _group_edges(table, n)
    if full or successors is None:
        edges = []
        for target, obs in groups:
            shown = ", ".join(obs[:max_observations]) + (f", ... (+{len(obs) - max_observations})" if len(obs) > max_observations else "")
            edges.append(f"{target} <- {shown}")
        line = head + "; ".join(edges)
        if full or len(line) <= WIDTH:
            return line
        ranked = [f"{target} <- {len(obs)} obs" for target, obs in sorted(groups, key=lambda g: (-len(g[1]), g[0]))]
    else:
        row = successors[n]
        order = [int(m) for m in sorted({t for t, _ in groups}, key=lambda m: (-row[m], m))]
        ranked = [f"{m} {_percent(row[m])}" for m in order]

    def shown(k: int) -> str:                 # the first k successors and how many are left out
        return head + "; ".join(ranked[:k]) + (f"; +{len(ranked) - k} more (--full)" if k < len(ranked) else "")

    k = len(ranked)
    while k > 1 and len(shown(k)) > WIDTH:
        k -= 1
    return shown(k)


def _percent(p: float) -> str:
    """A successor probability in few characters; 'never' for one the model never takes."""
    if p <= 0:
        return "never"
    return f"{100 * p:.0f} %" if p >= 0.1 else f"{100 * p:.2g} %"


def closed_loop(table: Table):
    """The closed loop's view of the table (node_risk.NodeRisk) when the model it names can be
    rebuilt, else None (a hand-made table: the view falls back to observation counts)."""
    from .controller import Controller
    from .models import rebuild
    from .node_risk import analyse
    from .params import ConfigError
    from .pipeline import time_step_of

    try:
        model = rebuild(dict(table.header))
    except (ConfigError, ValueError, KeyError):
        return None
    ctrl = Controller.of_table(table)
    return analyse(model, ctrl, time_step_of(model))


def compilation(table: Table) -> dict:
    """The table's value without the release cost and its compilation loss against the header's
    lower bound (as `railguard solve --json` names them), on the model the table names,
    rebuilt; {} for a hand-made table or one without a lower bound."""
    from .controller import Controller, compilation_loss_percent, plain_value
    from .models import rebuild
    from .params import ConfigError

    try:
        model = rebuild(dict(table.header))
    except (ConfigError, ValueError, KeyError):
        return {}
    if "lower_bound" not in table.header:
        return {}
    plain = plain_value(model, Controller.of_table(table))
    return {"release_cost": model.release_cost, "controller_value_without_release_cost": plain,
            "compilation_loss_percent": compilation_loss_percent(table.header["lower_bound"], plain)}


def compilation_text(figures: dict) -> list[str]:
    """compilation()'s figures as the solve summary prints them."""
    from .pipeline import compilation_lines

    if not figures:
        return []
    return compilation_lines(figures["controller_value_without_release_cost"], figures["release_cost"],
                             figures["compilation_loss_percent"])


def compilation_sentence(table) -> str:
    """The shipped table's two values side by side (issue 41, item 3): what it is worth on its
    own objective, with the release cost, and on the alpha vectors' objective, without it,
    against their lower bound; the pair nobody should mix up."""
    f = compilation(table)
    h = table.header
    if not f:
        return f"Compilation: no lower bound in the table's header ({table.model} {table.sha256[:12]})."
    loss = f["compilation_loss_percent"]
    paid = (f"{h['controller_value']:.4f} with the release cost ({f['release_cost']:g} per release, its own objective), "
            if f["release_cost"] else "")
    return (f"Compilation ({table.nodes} nodes): the table is worth {paid}"
            f"{f['controller_value_without_release_cost']:.4f} without it, on the objective of the alpha vectors' lower "
            f"bound {h['lower_bound']:.4f}: {abs(loss):.2f} % {'below' if loss > 0 else 'above'} it "
            "(`railguard table show`).")


def render(table: Table, max_observations: int = 6, full: bool = False, loop=None, extra: tuple = ()) -> str:
    """The table for a person: header, then a line per node. By default each line fits in
    WIDTH characters: with the closed loop's view (`loop`, closed_loop()) the next nodes
    likeliest first, else the transitions or their observation counts; `full` lists every
    transition."""
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
    lines += list(extra)
    lines.append(f"{'risk':<16} {risk_range(table)}")
    info = h.get("risk", {})
    if "hazard" in info:
        lines += _wrap("", [f"hazard: {' / '.join(_hazard_names(info['hazard']))}", f"weighting: {info.get('weighting')}",
                            f"supervision: {info.get('supervised')}"])
    if "params" in h:
        items = [f"{k}={v}" for k, v in h["params"].items()]
        lines += _wrap("parameters", items) if not full else ["parameters       " + ", ".join(items)]
    lines.append("")
    if full or loop is None:
        lines.append("node  action              risk ppm  next node on observation" + (
            "" if full else " (a long line: next node <- how many observations, most first)"))
    else:
        lines.append("node  action              risk ppm  next node and its probability, likeliest first "
                     "(the model's closed loop; --full: every transition)")
    succ = None if loop is None else loop.successors
    lines += [_node_line(table, n, full, max_observations, succ) for n in range(table.nodes)]
    return "\n".join(lines) + "\n"


def _hazard_names(states: list[str]) -> list[str]:
    """Hazard states in a few words: Model 2's 36 critical states as their common prefix."""
    if len(states) <= 3:
        return states
    prefix = states[0].split("-")[0]
    return [f"{prefix}* ({len(states)} states)"] if all(s.startswith(prefix) for s in states) else states[:3] + ["..."]


def as_json(table: Table) -> dict:
    return {
        "sha256": table.sha256,
        "header": dict(table.header),
        "action": [table.actions[a] for a in table.action],
        "next": [list(row) for row in table.next],
        "risk_ppm": list(table.risk),
    }
