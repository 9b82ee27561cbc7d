"""The shipped policy tables (m1, m2) and how to read one by name or path."""
from __future__ import annotations

from importlib import resources
from pathlib import Path

SHIPPED = ("m1", "m2")
DEFAULT = "m2"        # the one default table of every command (Model 2: seed 001, 144 states)


class TableNotFound(OSError):
    """A table spec that names neither a shipped table nor a readable file."""


def read(spec: str) -> bytes:
    """The bytes of a shipped table by model name (m1, m2) or of a table file by path."""
    if spec in SHIPPED:
        return resources.files(__name__).joinpath(f"{spec}.table.rgt").read_bytes()
    try:
        return Path(spec).read_bytes()
    except OSError as exc:
        raise TableNotFound(f"{spec}: cannot read table: {exc.strerror or exc} (shipped tables: {', '.join(SHIPPED)})") from None
