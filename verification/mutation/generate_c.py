"""Mutants of the C core, on tokens: comparison swaps, && <-> ||, + <-> - (and += <-> -=),
a `!` removed, integer literals +/- 1, inside the bodies of `C_FUNCTIONS` of rg_core.c only
(comments, the ACSL contracts among them, strings and preprocessor lines are left alone).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Iterable, Optional

from .mutant import Mutant, unique_id
from .targets import C_FILES, C_FUNCTIONS, ROOT


_C_TOKEN = re.compile(r"""
    (?P<comment>/\*.*?\*/|//[^\n]*)
  | (?P<string>"(?:\\.|[^"\\])*"|'(?:\\.|[^'\\])*')
  | (?P<pre>^[ \t]*\#[^\n]*)
  | (?P<number>\b\d+[uUlL]*\b)
  | (?P<ident>[A-Za-z_]\w*)
  | (?P<op><<=|>>=|->|\+\+|--|<<|>>|<=|>=|==|!=|&&|\|\||\+=|-=|[-+*/%<>=!&|^~?:;,.(){}\[\]])
  | (?P<space>\s+)
""", re.S | re.M | re.X)
_C_SWAP = {"<": "<=", "<=": "<", ">": ">=", ">=": ">", "==": "!=", "!=": "==", "&&": "||", "||": "&&",
           "+": "-", "-": "+", "+=": "-=", "-=": "+="}
_C_KIND = {"<": "cmp", "<=": "cmp", ">": "cmp", ">=": "cmp", "==": "cmp", "!=": "cmp", "&&": "bool", "||": "bool",
           "+": "arith", "-": "arith", "+=": "arith", "-=": "arith"}


def c_mutants(files: Optional[Iterable[str]] = None) -> list[Mutant]:
    """Textual mutants of the C core's cycle functions, on tokens: comparison swaps,
    && <-> ||, binary + <-> - (and += <-> -=), a `!` removed, integer literals + 1 and - 1.
    Only the bodies of C_FUNCTIONS are mutated; comments (the ACSL contracts included),
    strings and preprocessor lines are left alone."""
    out: list[Mutant] = []
    for name in files or C_FILES:
        path = Path(name) if Path(name).is_absolute() else ROOT / name
        text = path.read_text()
        rel = path.resolve().relative_to(ROOT).as_posix()
        ranges = []
        for fn in C_FUNCTIONS:
            found = re.search(rf"^(?:static )?[\w ]+?\b{fn}\(", text, re.M)
            if found:
                ranges.append((found.start(), text.index("\n}\n", found.start()) + 2))
        tokens = [(m.lastgroup, m.group(0), m.start()) for m in _C_TOKEN.finditer(text)]
        line_starts = [0] + [i + 1 for i, ch in enumerate(text) if ch == "\n"]

        def pos(off: int) -> tuple[int, int]:
            line = max(i for i, st in enumerate(line_starts) if st <= off)
            return line + 1, off - line_starts[line] + 1

        depth = 0
        prev = None            # the previous significant token (kind, text)
        seen: dict[str, int] = {}
        for kind, tok, off in tokens:
            if kind in ("comment", "space", "pre", "string"):
                continue
            inside = depth > 0 and any(a <= off < b for a, b in ranges)
            edits = []
            if inside:
                operand_before = prev is not None and (prev[0] in ("ident", "number") or prev[1] in (")", "]"))
                if tok in _C_SWAP and (tok not in ("+", "-") or operand_before):
                    edits.append((_C_KIND[tok], _C_SWAP[tok], tok))
                elif tok == "!" and not operand_before:
                    edits.append(("not", "", tok))
                elif kind == "number" and not (prev and prev[1] == "["):
                    digits = re.match(r"\d+", tok).group(0)
                    suffix = tok[len(digits):]
                    for d in (1, -1):
                        value = int(digits) + d
                        if value >= 0:
                            edits.append(("int", f"{value}{suffix}", tok))
            for operator, new, old in edits:
                mutated = text[:off] + new + text[off + len(old):]
                line, col = pos(off)
                mid = unique_id(seen, f"{rel}:{line}:{col}:{operator}:{new}")
                before = text.split("\n")[line - 1]
                after = mutated.split("\n")[line - 1]
                out.append(Mutant(mid, rel, line, col, operator, new, before, after, source=mutated))
            if tok == "{":
                depth += 1
            elif tok == "}":
                depth -= 1
            prev = (kind, tok)
    return out
