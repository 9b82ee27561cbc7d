"""`railguard table show`: a table's header and its controller, node by node."""
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
    if args.json:
        print(json.dumps(table_view.as_json(table)))
    else:
        sys.stdout.write(table_view.render(table, full=args.full))
    return 0


def register(sub) -> None:
    t = sub.add_parser("table", help="inspect compiled policy tables", description="Inspect compiled policy tables.")
    tsub = t.add_subparsers(dest="table_command", metavar="ACTION")
    tsub.required = True
    s = tsub.add_parser(
        "show",
        help="print a table's header and its controller node by node",
        description="Check a table (magic, version, SHA-256, dimensions) and print its header and, "
                    "for every node, the action and where each observation leads. Each line fits in 160 "
                    "characters: where a node's transitions would not fit (m2's 144 observations), its line "
                    "names the next nodes with how many observations lead to each, most first; --full lists "
                    "every transition, --json gives everything.",
    )
    s.add_argument("file", nargs="?", default=DEFAULT, metavar="m1|m2|FILE",
                   help="a shipped table or a .table.rgt file (default: %(default)s)")
    s.add_argument("--full", action="store_true", help="every transition of every node, however long the line")
    s.add_argument("--json", action="store_true", help="print the header and the controller as JSON")
    s.set_defaults(func=show)
