"""A mutant: one small change of one source file, with a stable id
`file:line:col:operator:replacement` (made unique with #2, #3 ...), its verdict, and the
equivalents list that names the mutants no test can tell from the original, with the reason.
"""
from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .targets import EQUIVALENTS


@dataclass
class Mutant:
    id: str
    file: str            # path relative to the repository
    line: int
    col: int
    operator: str
    replacement: str
    before: str          # the changed line(s), original
    after: str           # the same line(s), mutated
    status: str = "pending"   # killed / survived / timeout / equivalent (and survived) / error
    detail: str = ""          # what killed it (test id), or the equivalence reason
    seconds: float = 0.0
    equivalent: bool = False
    source: str = field(default="", repr=False)   # the whole mutated file

    def diff(self) -> str:
        return f"- {self.before.strip()}\n+ {self.after.strip()}"

    def public(self) -> dict:
        d = asdict(self)
        d.pop("source")
        d["diff"] = self.diff()
        return d


def unique_id(seen: dict, mid: str) -> str:
    """A mutant's id, made unique with #2, #3 ... when two mutants share a place and an edit."""
    seen[mid] = seen.get(mid, 0) + 1
    return mid if seen[mid] == 1 else f"{mid}#{seen[mid]}"


def load_equivalents(path: Path = EQUIVALENTS) -> dict[str, str]:
    """{mutant id: reason} from the equivalents file."""
    if not path.exists():
        return {}
    data = tomllib.loads(path.read_text())
    return {str(k): str(v) for k, v in data.get("equivalent", {}).items()}
