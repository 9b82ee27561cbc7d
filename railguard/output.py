"""How every command talks: figures on stdout (text, or one JSON object with --json),
progress and status lines on stderr, and at the end the list of every file written."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Callable, Iterable, Optional


def wrote(files: Iterable, stream=None) -> None:
    """The closing list of every file a command wrote, one per line."""
    names = [str(f) for f in files if f is not None]
    if names:
        print("wrote " + "\n      ".join(names), file=stream or sys.stdout)


def files_of(*paths) -> list[str]:
    return [str(p) for p in paths if p is not None]


def stderr_lines(quiet: bool = False) -> Optional[Callable[[str], None]]:
    """Progress messages on stderr, stamped with the seconds since the command started."""
    if quiet:
        return None
    started = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - started:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def status_printer(quiet: bool) -> Optional[Callable[[str], None]]:
    """A live status line: refreshed in place on a terminal, one line each otherwise."""
    if quiet:
        return None
    tty = sys.stderr.isatty()

    def show(text: str) -> None:
        sys.stderr.write(("\r" + text) if tty else text + "\n")
        sys.stderr.flush()

    return show


def summary(values: dict, as_json: bool, tty_line: bool = False) -> None:
    """A run's summary: aligned key/value lines, or one JSON object."""
    if tty_line:
        sys.stderr.write("\n")
    if as_json:
        print(json.dumps(values))
        return
    width = max(len(k) for k in values)
    for key, value in values.items():
        if isinstance(value, dict):
            value = ", ".join(f"{k} {v}" for k, v in value.items()) or "-"
        elif isinstance(value, list):
            value = ", ".join(map(str, value)) or "-"
        elif value is None:
            value = "-"
        print(f"{key:<{width}}  {value}")


def write_json(path: Path, data) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return path
