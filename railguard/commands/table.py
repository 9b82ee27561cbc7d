"""`railguard table show`: a table's header and its controller, node by node;
`railguard table upgrade`: an older table file given the risk column format 2 requires;
`railguard table repair`: a table's actions raised where they buy hazard cheaply (risk_repair.py);
`railguard table confirm`: a warning alone confirmed for some cycles before the table escalates
on it (confirmation.py)."""
from __future__ import annotations

import argparse
import json
import sys

from monitor.tables import DEFAULT


def show(args: argparse.Namespace) -> int:
    from monitor.core.table import decode
    from monitor.offline import table_view

    from ..setup import table_bytes

    if args.file in ("m1", "m2"):
        table = decode(table_bytes(args.file))
    else:
        table = table_view.read(args.file)
    figures = table_view.compilation(table)
    if args.json:
        print(json.dumps({**table_view.as_json(table), **figures}))
    else:
        from monitor.offline.confirmation import confirmation_lines
        from monitor.offline.pipeline import repair_lines

        loop = None if args.full else table_view.closed_loop(table)
        extra = (table_view.compilation_text(figures) + repair_lines(table.header.get("risk_repair"))
                 + confirmation_lines(table.header.get("warning_confirmation")))
        sys.stdout.write(table_view.render(table, full=args.full, loop=loop, extra=extra))
    return 0


def upgrade(args: argparse.Namespace) -> int:
    from pathlib import Path

    from monitor.offline.pipeline import with_risk
    from monitor.offline.table_view import risk_range

    from monitor.core.table import TableError, decode

    src = Path(args.file)
    try:
        new_bytes, old = with_risk(src.read_bytes())
    except OSError as exc:
        raise TableError(f"{src}: cannot read: {exc.strerror or exc}") from None
    except (TableError, ValueError) as exc:
        raise TableError(f"{src}: {exc}") from None
    new = decode(new_bytes)
    out = Path(args.out) if args.out else src
    out.write_bytes(new_bytes)
    print(f"{out}: format {old.header.get('format_version')} -> {new.header['format_version']}, {new.nodes} nodes, "
          f"risk column {risk_range(new)}; SHA-256 {old.sha256[:12]} -> {new.sha256[:12]}")
    tie_alphas(src, out, old.sha256, new.sha256, "upgraded")
    return 0


def tie_alphas(src, out, old_sha: str, new_sha: str, what: str, say=print) -> None:
    """The alpha vectors beside `src` (NAME.alphas.npz, tied to `old_sha`), written beside
    `out` tied to `new_sha`: a re-encoded table keeps the vectors belief tracking runs on."""
    from monitor.offline.pipeline import ALPHAS_SUFFIX, TABLE_SUFFIX, read_alphas, write_alphas_arrays

    def alphas_of(path):
        stem = path.name[:-len(TABLE_SUFFIX)] if path.name.endswith(TABLE_SUFFIX) else path.stem
        return path.with_name(stem + ALPHAS_SUFFIX)

    if alphas_of(src).is_file():
        alphas, actions = read_alphas(alphas_of(src), old_sha)
        write_alphas_arrays(alphas_of(out), alphas, actions, new_sha)
        say(f"{alphas_of(out)}: alpha vectors tied to the {what} table")


def _source(spec: str):
    """(path, bytes, decoded table, shipped?) of a shipped table name or a table file."""
    from importlib import resources
    from pathlib import Path

    from monitor.core.table import TableError, decode
    from monitor.offline.pipeline import TABLE_SUFFIX

    shipped = spec in ("m1", "m2")
    src = Path(str(resources.files("monitor.tables").joinpath(spec + TABLE_SUFFIX))) if shipped else Path(spec)
    try:
        data = src.read_bytes()
        return src, data, decode(data), shipped
    except OSError as exc:
        raise TableError(f"{src}: cannot read: {exc.strerror or exc}") from None
    except TableError as exc:
        raise TableError(f"{src}: {exc}") from None


def _written(src, new_bytes: bytes, old, shipped: bool, out_arg, what: str, say):
    """Write a derived table (default: over FILE; a shipped table to railguard-out/), tie its
    alpha vectors; return (path, decoded table)."""
    from pathlib import Path

    from monitor.core.table import decode

    new = decode(new_bytes)
    out = Path(out_arg) if out_arg else (Path("railguard-out") / src.name if shipped else src)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(new_bytes)
    tie_alphas(src, out, old.sha256, new.sha256, what, say=say)
    return out, new


def repair(args: argparse.Namespace) -> int:
    import time

    from monitor.core.table import TableError
    from monitor.offline.models import MODELS
    from monitor.offline.params import ConfigError
    from monitor.offline.pipeline import repaired, repair_lines
    from monitor.offline.table_view import risk_range

    src, data, old, shipped = _source(args.file)
    spec = MODELS.get(str(old.header.get("model")))
    price = args.price if args.price is not None else (spec.plan.hazard_price if spec else 0.0)
    if not price > 0:
        raise ConfigError(f"{src}: no hazard price for model {old.header.get('model')!r}: give --price "
                          "(value per unit of P(hazard within 30 s))")
    deadline = time.perf_counter() + args.time_budget if args.time_budget else None
    say = (lambda text: None) if args.json else (lambda text: print(text, file=sys.stderr, flush=True))
    try:
        new_bytes, fixed = repaired(data, price, say, deadline)
    except (ConfigError, ValueError) as exc:
        raise TableError(f"{src}: {exc}") from None
    out, new = _written(src, new_bytes, old, shipped, args.out, "repaired", say)
    if args.json:
        print(json.dumps({"table": str(out), "sha256_before": old.sha256, "sha256": new.sha256,
                          **new.header["risk_repair"], "rounds": fixed.as_dict()["rounds"]}))
        return 0
    print("\n".join(repair_lines(new.header["risk_repair"])))
    print(f"{out}: {new.nodes} nodes, risk column {risk_range(new)}; SHA-256 {old.sha256[:12]} -> {new.sha256[:12]}")
    return 0


def confirm(args: argparse.Namespace) -> int:
    from monitor.core.table import TableError
    from monitor.offline.confirmation import confirmation_lines
    from monitor.offline.models import MODELS
    from monitor.offline.params import ConfigError
    from monitor.offline.pipeline import confirmed
    from monitor.offline.table_view import risk_range

    src, data, old, shipped = _source(args.file)
    spec = MODELS.get(str(old.header.get("model")))
    cycles = args.cycles if args.cycles is not None else (spec.plan.warning_confirmation if spec else 0)
    if not 0 <= cycles <= 1000:
        raise ConfigError(f"--cycles must be in 0..1000, got {cycles}")
    try:
        new_bytes, entry = confirmed(data, cycles)
    except (ConfigError, ValueError) as exc:
        raise TableError(f"{src}: {exc}") from None
    say = (lambda text: None) if args.json else (lambda text: print(text, file=sys.stderr, flush=True))
    out, new = _written(src, new_bytes, old, shipped, args.out, "confirmed", say)
    if args.json:
        print(json.dumps({"table": str(out), "sha256_before": old.sha256, "sha256": new.sha256, "nodes": new.nodes,
                          **entry}))
        return 0
    print("\n".join(confirmation_lines(new.header.get("warning_confirmation"))
                    or [f"confirmation     none: {'cycles 0' if not cycles else 'no warning path escalates'}"
                        f" (value {entry['value']:.4f}, P(hazard within {entry['horizon_s']:g} s) {entry['p_hazard']:.4g})"]))
    print(f"{out}: {new.nodes} nodes, risk column {risk_range(new)}; SHA-256 {old.sha256[:12]} -> {new.sha256[:12]}")
    return 0


def _derived_table_arguments(p) -> None:
    """FILE, --out and --json of the commands that write a table derived from another."""
    p.add_argument("file", metavar="m1|m2|FILE", help="a shipped table or a .table.rgt file")
    p.add_argument("--out", metavar="PATH",
                   help="write here (default: over FILE; a shipped table goes to railguard-out/NAME.table.rgt)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON (no progress)")


def register(sub) -> None:
    t = sub.add_parser("table", help="inspect compiled policy tables", description="Inspect compiled policy tables.")
    tsub = t.add_subparsers(dest="table_command", metavar="ACTION")
    tsub.required = True
    s = tsub.add_parser(
        "show",
        help="print a table's header and its controller node by node",
        description="Check a table (magic, version, SHA-256, dimensions) and print its header and, "
                    "for every node its action, its risk (P(hazard within 30 s | the monitor is in the node), "
                    "ppm, from the table's risk column) and its next nodes, likeliest first with their "
                    "probabilities on the closed loop of the model the table names (a few seconds for m2). "
                    "Each line fits in 160 characters; --full lists every transition (observation -> next "
                    "node) instead, --json gives everything.",
    )
    s.add_argument("file", nargs="?", default=DEFAULT, metavar="m1|m2|FILE",
                   help="a shipped table or a .table.rgt file (default: %(default)s)")
    s.add_argument("--full", action="store_true", help="every transition of every node, however long the line")
    s.add_argument("--json", action="store_true", help="print the header and the controller as JSON")
    s.set_defaults(func=show)
    u = tsub.add_parser(
        "upgrade",
        help="give an older table file the risk column (format 2)",
        description="Re-encode a table file in the current format: its controller unchanged, each node's "
                    "risk (P(hazard within 30 s | node), ppm) recomputed from the exact closed loop of the model "
                    "its header names, which must rebuild to the header's model_sha256. The SHA-256 changes; "
                    "the alpha vectors beside the file (NAME.alphas.npz) are tied to the new digest.",
    )
    u.add_argument("file", metavar="FILE", help="a .table.rgt file (format 1 or 2)")
    u.add_argument("--out", metavar="PATH", help="write here instead of over FILE (default: over FILE)")
    u.set_defaults(func=upgrade)
    r = tsub.add_parser(
        "repair",
        help="raise a table's actions where they remove hazard cheaply (P(hazard within 30 s))",
        description="The risk repair `railguard solve` runs after compiling, on a table file: while some stronger "
                    "action at some node removes P(hazard within 30 s) (exact closed loop, the curves in front) "
                    "for less than PRICE of the model's value per unit of probability, raise it (a batch per "
                    "round, each checked exactly; actions only rise, and stay monotone in the reported "
                    "conditions). The header records what it bought and paid; the risk column is recomputed; "
                    "the alpha vectors beside the file are tied to the new digest. An m2 round takes about 40 s.",
    )
    _derived_table_arguments(r)
    r.add_argument("--price", type=float, metavar="PRICE",
                   help="value per unit of P(hazard) (default: the model's plan, m1 20000; m2 has none)")
    r.add_argument("--time-budget", type=float, metavar="S", help="start no round that would end after S seconds (default: no limit)")
    r.set_defaults(func=repair)
    c = tsub.add_parser(
        "confirm",
        help="make a warning alone last CYCLES more cycles before the table escalates on it",
        description="The warning confirmation `railguard solve` runs after the risk repair (m1: 10 cycles), on a "
                    "table file: on the path repeated warning-zone observations take from the node a quiet start "
                    "settles in, CYCLES copies of the last node before the first braking one are put in front of "
                    "it (each acts and reads every other observation as that node does). A confirmation the "
                    "header records is undone first, so --cycles 0 gives the table without one. The header "
                    "records the paths and P(hazard within 30 s) and the value before and after (exact, the "
                    "curves in front); the risk column is recomputed; the alpha vectors beside the file are "
                    "tied to the new digest. Judge the result in the world with `railguard evaluate FILE`.",
    )
    _derived_table_arguments(c)
    c.add_argument("--cycles", type=int, metavar="CYCLES",
                   help="0.1 s cycles a warning alone must last longer (0..1000; 0: none; default: the model's plan, "
                        "m1 10, m2 0)")
    c.set_defaults(func=confirm)
