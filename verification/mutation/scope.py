"""Restricting a run to part of a file: `--scope FILE[:FUNCTION|:FIRST-LAST]`.

A scope names a file (as `--files` does: `cycle.py` is monitor/core's, a path is relative
to the repository) and optionally a function (Python: any `def` of that name, decorators
included; C: a function definition of rg_core.c, which must be one of C_FUNCTIONS to have
mutants) or a line range (1-based, inclusive). A mutant is in scope if it is in one of the
scopes; a scope that names no file, no function or no line the tool mutates is an error.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Iterable

from .mutant import Mutant
from .targets import CORE, ROOT


def resolve(name: str, target: str) -> str:
    """A file name as --files takes it -> its path relative to the repository."""
    p = Path(name)
    if not p.is_absolute():
        p = CORE / p.name if target == "python" and len(p.parts) == 1 and (CORE / p.name).exists() else ROOT / p
    if not p.exists():
        raise ValueError(f"--scope {name}: no such file")
    if p.suffix != (".py" if target == "python" else ".c"):
        raise ValueError(f"--scope {name}: not a {'Python' if target == 'python' else 'C'} file of the target "
                         f"(--target {'c' if target == 'python' else 'python'}?)")
    return p.resolve().relative_to(ROOT).as_posix()


def _function_lines(path: Path, function: str, target: str) -> list[tuple[int, int]]:
    text = path.read_text()
    if target == "python":
        out = []
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == function:
                first = min([node.lineno] + [d.lineno for d in node.decorator_list])
                out.append((first, node.end_lineno))
        return out
    found = re.search(rf"^(?:static )?[\w ]+?\b{re.escape(function)}\(", text, re.M)
    if not found:
        return []
    end = text.index("\n}\n", found.start()) + 2
    return [(text.count("\n", 0, found.start()) + 1, text.count("\n", 0, end))]


def parse(scopes: Iterable[str], target: str) -> list[tuple[str, list[tuple[int, int]] | None]]:
    """[(file relative to the repository, [(first, last line)] or None for the whole file)]."""
    out = []
    for scope in scopes:
        name, _, part = scope.partition(":")
        rel = resolve(name, target)
        if not part:
            out.append((rel, None))
            continue
        lines = re.fullmatch(r"(\d+)-(\d+)", part)
        if lines:
            first, last = int(lines.group(1)), int(lines.group(2))
            if not 1 <= first <= last:
                raise ValueError(f"--scope {scope}: the line range must be FIRST-LAST with 1 <= FIRST <= LAST")
            out.append((rel, [(first, last)]))
            continue
        spans = _function_lines(ROOT / rel, part, target)
        if not spans:
            raise ValueError(f"--scope {scope}: no function {part!r} in {rel}")
        out.append((rel, spans))
    return out


def files_of(scopes: list[tuple[str, list | None]]) -> list[str]:
    """The files the scopes name, each once, in order."""
    return list(dict.fromkeys(rel for rel, _ in scopes))


def select(mutants: list[Mutant], scopes: list[tuple[str, list | None]]) -> list[Mutant]:
    """The mutants inside any of the scopes; each scope must hold at least one."""
    def inside(m: Mutant, rel: str, spans) -> bool:
        return m.file == rel and (spans is None or any(a <= m.line <= b for a, b in spans))

    for rel, spans in scopes:
        if not any(inside(m, rel, spans) for m in mutants):
            where = rel if spans is None else f"{rel} lines {', '.join(f'{a}-{b}' for a, b in spans)}"
            raise ValueError(f"--scope: no mutant in {where} (for C: is the function in C_FUNCTIONS?)")
    return [m for m in mutants if any(inside(m, rel, spans) for rel, spans in scopes)]
