"""Mutants of the Python core, generated from the source with `ast`.

One edit each, on the token itself (ast columns are UTF-8 byte offsets): comparisons
swapped, and/or swapped, an and/or operand dropped, min/max, integer constants +/- 1,
+/-, a `not` removed, int/bool return values replaced, type checks replaced by True.
Docstrings, annotations, f-strings and `__all__` are left alone; a mutant that does not
parse is dropped.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Iterable, Optional

from .mutant import Mutant, unique_id
from .targets import CORE, PY_FILES, ROOT


class _Source:
    """A file's bytes with (line, col) <-> offset conversions (ast columns are UTF-8 byte offsets)."""

    def __init__(self, text: str):
        self.text = text
        self.data = text.encode("utf-8")
        self.starts = [0]
        for i, b in enumerate(self.data):
            if b == 0x0A:
                self.starts.append(i + 1)

    def off(self, line: int, col: int) -> int:
        return self.starts[line - 1] + col

    def pos(self, off: int) -> tuple[int, int]:
        """(1-based line, 1-based column in characters) of a byte offset."""
        line = max(i for i, s in enumerate(self.starts) if s <= off)
        col = len(self.data[self.starts[line]:off].decode("utf-8"))
        return line + 1, col + 1

    def span(self, node: ast.AST) -> tuple[int, int]:
        return self.off(node.lineno, node.col_offset), self.off(node.end_lineno, node.end_col_offset)

    def segment(self, a: int, b: int) -> str:
        return self.data[a:b].decode("utf-8")

    def lines_of(self, data: bytes, first: int, count: int) -> str:
        lines = data.decode("utf-8").split("\n")
        return " ".join(x.strip() for x in lines[first - 1:first - 1 + count])


_OPS = {
    ast.Lt: ("<", r"<(?!=)"), ast.LtE: ("<=", r"<="), ast.Gt: (">", r">(?!=)"), ast.GtE: (">=", r">="),
    ast.Eq: ("==", r"=="), ast.NotEq: ("!=", r"!="), ast.Is: ("is", r"\bis\b(?!\s+not\b)"),
    ast.IsNot: ("is not", r"\bis\s+not\b"), ast.In: ("in", r"(?<!not )\bin\b"), ast.NotIn: ("not in", r"\bnot\s+in\b"),
    ast.Add: ("+", r"\+"), ast.Sub: ("-", r"-"), ast.And: ("and", r"\band\b"), ast.Or: ("or", r"\bor\b"),
}
_SWAP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq, ast.NotEq: ast.Eq,
         ast.Is: ast.IsNot, ast.IsNot: ast.Is, ast.In: ast.NotIn, ast.NotIn: ast.In, ast.Add: ast.Sub, ast.Sub: ast.Add,
         ast.And: ast.Or, ast.Or: ast.And}
_LOOSE = (ast.BoolOp, ast.IfExp, ast.NamedExpr, ast.Lambda)


def _mask_comments(gap: str) -> str:
    return re.sub(r"#[^\n]*", lambda m: " " * len(m.group(0)), gap)


def _find_op(src: _Source, a: int, b: int, op: type) -> Optional[tuple[int, int]]:
    """Byte span of the one operator token `op` between offsets a and b, or None."""
    gap = _mask_comments(src.segment(a, b))
    hits = list(re.finditer(_OPS[op][1], gap))
    if len(hits) != 1:
        return None
    prefix = len(gap[:hits[0].start()].encode("utf-8"))
    return a + prefix, a + prefix + len(hits[0].group(0).encode("utf-8"))


def _short(text: str, limit: int = 40) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


class _Collector(ast.NodeVisitor):
    def __init__(self, src: _Source):
        self.src = src
        self.edits: list[tuple[int, int, str, str, str]] = []   # (start, end, new text, operator, replacement)
        self.returns: list[str] = []                             # annotation of the enclosing function

    def add(self, a: int, b: int, new: str, operator: str, replacement: str) -> None:
        self.edits.append((a, b, new, operator, replacement))

    # --- what is not mutated
    def visit_Expr(self, node: ast.Expr) -> None:
        if isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            return                                                   # docstring
        self.generic_visit(node)

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        return                                                       # f-strings: message text

    def visit_arg(self, node: ast.arg) -> None:
        return                                                       # annotations

    def visit_AnnAssign(self, node: ast.AnnAssign) -> None:
        if node.value is not None:
            self.visit(node.value)

    def visit_Assign(self, node: ast.Assign) -> None:
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            return
        self.generic_visit(node)

    def _function(self, node) -> None:
        for d in node.decorator_list:
            self.visit(d)
        self.visit(node.args)
        ann = node.returns.id if isinstance(node.returns, ast.Name) else ""
        self.returns.append(ann)
        for stmt in node.body:
            self.visit(stmt)
        self.returns.pop()

    visit_FunctionDef = _function
    visit_AsyncFunctionDef = _function

    def visit_arguments(self, node: ast.arguments) -> None:
        for d in node.defaults + [d for d in node.kw_defaults if d is not None]:
            self.visit(d)

    # --- operators
    def visit_Compare(self, node: ast.Compare) -> None:
        left = node.left
        if (len(node.ops) == 1 and isinstance(node.ops[0], ast.Is) and isinstance(left, ast.Call)
                and isinstance(left.func, ast.Name) and left.func.id == "type"):
            a, b = self.src.span(node)
            self.add(a, b, "True", "isinstance", "True")
        for op, right in zip(node.ops, node.comparators):
            t = _find_op(self.src, self.src.span(left)[1], self.src.span(right)[0], type(op))
            if t is not None:
                new = _OPS[_SWAP[type(op)]][0]
                self.add(t[0], t[1], new, "cmp", new)
            left = right
        self.generic_visit(node)

    def visit_BinOp(self, node: ast.BinOp) -> None:
        if type(node.op) in (ast.Add, ast.Sub):
            t = _find_op(self.src, self.src.span(node.left)[1], self.src.span(node.right)[0], type(node.op))
            if t is not None:
                new = _OPS[_SWAP[type(node.op)]][0]
                self.add(t[0], t[1], new, "arith", new)
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        if type(node.op) in (ast.Add, ast.Sub):
            gap_a, gap_b = self.src.span(node.target)[1], self.src.span(node.value)[0]
            gap = self.src.segment(gap_a, gap_b)
            sym = _OPS[type(node.op)][0] + "="
            i = gap.find(sym)
            if i >= 0:
                a = gap_a + len(gap[:i].encode("utf-8"))
                new = _OPS[_SWAP[type(node.op)]][0] + "="
                self.add(a, a + 2, new, "arith", new)
        self.generic_visit(node)

    def visit_BoolOp(self, node: ast.BoolOp) -> None:
        spans = []
        for x, y in zip(node.values, node.values[1:]):
            t = _find_op(self.src, self.src.span(x)[1], self.src.span(y)[0], type(node.op))
            if t is None:
                spans = None
                break
            spans.append(t)
        if spans:
            new = _OPS[_SWAP[type(node.op)]][0]
            # one edit per connector, applied together: an edit list in one entry
            self.edits.append((spans, None, new, "bool", new))
        a, b = self.src.span(node)
        for i, dropped in enumerate(node.values):
            rest = node.values[:i] + node.values[i + 1:]
            repl = ast.unparse(rest[0] if len(rest) == 1 else ast.BoolOp(op=node.op, values=rest))
            self.add(a, b, repl, "drop", _short(ast.unparse(dropped)))
        self.generic_visit(node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        if isinstance(node.op, ast.Not):
            a, b = self.src.span(node)
            inner = self.src.segment(*self.src.span(node.operand))
            if isinstance(node.operand, _LOOSE):
                inner = f"({inner})"
            self.add(a, b, inner, "not", "")
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        f = node.func
        if isinstance(f, ast.Name) and f.id in ("min", "max"):
            a, b = self.src.span(f)
            new = "max" if f.id == "min" else "min"
            self.add(a, b, new, "minmax", new)
        if isinstance(f, ast.Name) and f.id == "isinstance":
            a, b = self.src.span(node)
            self.add(a, b, "True", "isinstance", "True")
        self.generic_visit(node)

    def visit_Constant(self, node: ast.Constant) -> None:
        if type(node.value) is int:
            a, b = self.src.span(node)
            for d in (1, -1):
                new = str(node.value + d)
                self.add(a, b, new, "int", new)

    def visit_Return(self, node: ast.Return) -> None:
        ann = self.returns[-1] if self.returns else ""
        if node.value is not None and ann in ("int", "bool"):
            a, b = self.src.span(node.value)
            v = node.value
            if ann == "bool":
                for new in ("True", "False"):
                    if not (isinstance(v, ast.Constant) and repr(v.value) == new):
                        self.add(a, b, new, "return", new)
            else:
                new = "1" if isinstance(v, ast.Constant) and v.value == 0 else "0"
                self.add(a, b, new, "return", new)
        self.generic_visit(node)


def mutants_of(path: Path, root: Path = ROOT) -> list[Mutant]:
    """Every mutant of one Python file, in source order, with unique ids."""
    text = path.read_text()
    src = _Source(text)
    col = _Collector(src)
    col.visit(ast.parse(text))
    rel = path.resolve().relative_to(root).as_posix() if path.resolve().is_relative_to(root) else path.name
    out: list[Mutant] = []
    seen: dict[str, int] = {}
    for a, b, new, operator, replacement in col.edits:
        spans = a if b is None else [(a, b)]
        data = src.data
        for x, y in sorted(spans, reverse=True):
            data = data[:x] + new.encode("utf-8") + data[y:]
        try:
            mutated = data.decode("utf-8")
            ast.parse(mutated)
        except SyntaxError:
            continue
        first = spans[0][0]
        line, column = src.pos(first)
        end_line = src.pos(max(y for _, y in spans))[0]
        count = end_line - line + 1
        before = src.lines_of(src.data, line, count)
        after_count = count + mutated.count("\n") - text.count("\n")
        after = src.lines_of(data, line, max(1, after_count))
        mid = unique_id(seen, f"{rel}:{line}:{column}:{operator}:{replacement}")
        out.append(Mutant(mid, rel, line, column, operator, replacement, before, after, source=mutated))
    return out


def python_mutants(files: Iterable[str] = PY_FILES) -> list[Mutant]:
    out = []
    for name in files:
        p = Path(name)
        if not p.is_absolute():
            p = CORE / p.name if (CORE / p.name).exists() and len(p.parts) == 1 else ROOT / p
        out += mutants_of(p)
    return out
