"""`railguard`: the one command, with a subcommand per job.

Errors a user can cause (bad file, bad value, unknown name) print one line on stderr and
exit with code 2; Ctrl-C prints one line and exits with 130; nothing else is allowed to
escape as a traceback.
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import Sequence

from . import __version__
from .commands import ALL
from .errors import EXIT_INTERRUPTED, EXIT_USAGE, one_line, user_errors


class HelpFormatter(argparse.HelpFormatter):
    """Descriptions wrapped as usual; an epilog written in lines (a listing) kept as written."""

    def _fill_text(self, text, width, indent):
        if "\n" in text:
            return "".join(indent + line + "\n" for line in text.splitlines())
        return super()._fill_text(text, width, indent)


class Parser(argparse.ArgumentParser):
    """Usage errors in one line too, with where to read more, exit 2."""

    def format_help(self) -> str:
        if callable(self.epilog):          # a listing read from files: only when help is shown
            self.epilog = self.epilog()
        return super().format_help()

    def error(self, message: str):
        self.exit(EXIT_USAGE, f"railguard: error: {self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="railguard", formatter_class=HelpFormatter,
        description="Railway anti-collision safety monitor: offline POMDP tables, online cyclic monitor. "
                    "Every command writes under railguard-out (or --out) and lists the files it wrote.",
    )
    parser.add_argument("--version", action="version", version=f"railguard {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    add = sub.add_parser

    def add_parser(*a, **kw):
        kw.setdefault("formatter_class", HelpFormatter)
        return add(*a, **kw)

    sub.add_parser = add_parser  # type: ignore[method-assign]
    for command in ALL:
        command.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except BrokenPipeError:   # output piped into `head` and the like: not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("railguard: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except user_errors() as exc:
        print(f"railguard: error: {one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE


def entry() -> None:
    sys.exit(main())


if __name__ == "__main__":
    entry()
