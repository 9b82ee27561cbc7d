"""Mutation testing of the safety core: do the tests notice when the core is made wrong?

Python core (`monitor/core/*.py`): mutants are generated from the source with `ast`, one
small change each, with the classic operators:

    cmp        a comparison swapped: < <-> <=, > <-> >=, == <-> !=, is <-> is not, in <-> not in
    bool       and <-> or (the whole chain)
    drop       one operand of an and/or chain dropped (f1 or f2 or f3 -> f1 or f2)
    minmax     min <-> max
    int        an integer constant + 1 and - 1
    arith      + <-> - (binary and augmented)
    not        a `not` removed
    return     the value of a function annotated `-> int` (0, or 1 for a literal 0) or `-> bool`
               (True, False) replaced
    isinstance an isinstance(...) or type(x) is T check replaced by True

Docstrings, annotations, f-strings (error messages) and `__all__` are not mutated. Each
mutant has a stable id `file:line:col:operator:replacement` (1-based line and column of
the changed token), so equivalent mutants can be listed in
`verification/mutation_equivalents.toml` with the reason no test can tell them apart.

Each mutant runs in a fresh process: a fork server (one per job slot, 2 by default)
imports pytest, Hypothesis and numpy once, never the project, and forks a child per
mutant; the child serves the mutated source for the mutated module through an import hook
placed first on `sys.meta_path` (every other module is the real one), derandomises
Hypothesis (no database, no shrinking) and runs the core's fast tests (`PY_TESTS`: nothing
that needs vcan, FMUs, Frama-C or takes more than 10 s) with `pytest -x`: the first
failing test kills the mutant. A mutant whose module fails to import (an import-time
assertion) is killed too; a mutant still running after the per-mutant timeout (5 x the
baseline, at least 60 s) is killed, reported as a timeout and counted as killed.

C core (`--target c`): textual mutants of the same operators (comparison swaps, && <-> ||,
+ <-> -, a removed `!`, integer literals +/- 1) in the decision functions of
`fmu/c/core/rg_core.c` (`C_FUNCTIONS`). Each child copies `fmu/c`, writes the mutated
rg_core.c, refuses it as stillborn if it does not compile with the FMU's flags (warnings
allowed: `a || b && c` warns),
points `fmu.build.C_DIR` at the copy and runs the Python-vs-C comparison test alone
(`tests/test_fmu_equivalence.py`, which builds its FMUs from C_DIR), at C_SEQUENCES
sequences per table instead of its 5000 (its minimum edge hits scaled alike). Stillborn
mutants are left out of the score.

    python -m verification.mutation [--target python|c] [--files ...] [--json] [--list]

prints progress on stderr, then the score (killed / non-equivalent), the survivors (id and
diff) and the equivalent ones with their reasons; `--json` prints one object with keys
`score`, `killed`, `survived`, `equivalent`, `timeouts`, `mutants`.
"""
from __future__ import annotations

import ast
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Optional

ROOT = Path(__file__).resolve().parents[1]
CORE = ROOT / "monitor" / "core"
EQUIVALENTS = Path(__file__).resolve().parent / "mutation_equivalents.toml"
PY_FILES = ("voter.py", "freshness.py", "observation.py", "envelope.py", "cycle.py", "braking.py", "config.py",
            "table.py", "types.py")
# the tests run against every Python mutant, fastest killers first (-x stops at the first failure)
PY_TESTS = ("tests/test_core_mutants.py", "tests/test_core_cycle.py", "tests/test_supervision.py",
            "tests/test_core_tables.py", "tests/test_table.py", "tests/test_core_stateful.py")
JOBS = 2
C_DIR = ROOT / "fmu" / "c"
C_FILES = ("fmu/c/core/rg_core.c",)
# sequences per table of the comparison test for each C mutant (the test itself runs 5000;
# its minimum edge hits are scaled down with it): a mutant that survives these is reported
# as a survivor even if the full test would kill it, so the score can only be too low
C_SEQUENCES = 1000
# the C mutants are judged by the Python-vs-C comparison alone
C_TESTS = ("tests/test_fmu_equivalence.py",)
# the functions of rg_core.c that are mutated: freshness and range, the voters, the zones,
# the supervision ladder, combine, the latch and the speed class (the decisions the
# Python-vs-C comparison must pin; the curve arithmetic, rg_step's plumbing, the
# configuration and table checks and SHA-256 are not mutated yet)
C_FUNCTIONS = ("rg_in_range", "rg_is_fresh", "rg_effective_status", "rg_vote_2oo2", "rg_disagreement",
               "rg_distances_disagree", "rg_vote_3oo3", "rg_zone", "rg_supervision_demand", "rg_combine", "rg_latch",
               "speed_class")

Progress = Callable[[str], None]


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


# ---------------------------------------------------------------------------- generation

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
        mid = _unique(seen, f"{rel}:{line}:{column}:{operator}:{replacement}")
        out.append(Mutant(mid, rel, line, column, operator, replacement, before, after, source=mutated))
    return out


def _unique(seen: dict, mid: str) -> str:
    """A mutant's id, made unique with #2, #3 ... when two mutants share a place and an edit."""
    seen[mid] = seen.get(mid, 0) + 1
    return mid if seen[mid] == 1 else f"{mid}#{seen[mid]}"


def python_mutants(files: Iterable[str] = PY_FILES) -> list[Mutant]:
    out = []
    for name in files:
        p = Path(name)
        if not p.is_absolute():
            p = CORE / p.name if (CORE / p.name).exists() and len(p.parts) == 1 else ROOT / p
        out += mutants_of(p)
    return out


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
                mid = _unique(seen, f"{rel}:{line}:{col}:{operator}:{new}")
                before = text.split("\n")[line - 1]
                after = mutated.split("\n")[line - 1]
                out.append(Mutant(mid, rel, line, col, operator, new, before, after, source=mutated))
            if tok == "{":
                depth += 1
            elif tok == "}":
                depth -= 1
            prev = (kind, tok)
    return out


def load_equivalents(path: Path = EQUIVALENTS) -> dict[str, str]:
    """{mutant id: reason} from the equivalents file."""
    if not path.exists():
        return {}
    data = tomllib.loads(path.read_text())
    return {str(k): str(v) for k, v in data.get("equivalent", {}).items()}


# ---------------------------------------------------------------------------- running (Python)

_SERVER = r"""
# A fork server: imports what every run needs (pytest, Hypothesis, numpy; never the project),
# then forks one fresh child per job. The child serves the mutated source for the mutated
# module through an import hook placed first on sys.meta_path and runs pytest.
import importlib, importlib.abc, importlib.util, json, os, signal, sys, time
import numpy, pytest, _pytest.python, _pytest.runner, hypothesis, hypothesis.strategies, hypothesis.stateful
from hypothesis import Phase, settings
settings.register_profile("mutation", derandomize=True, database=None, deadline=None, print_blob=False,
                          phases=[Phase.explicit, Phase.reuse, Phase.generate], report_multiple_bugs=False)
settings.load_profile("mutation")


class Mutated(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, job):
        self.job = job

    def find_spec(self, name, path=None, target=None):
        if name == self.job["module"]:
            return importlib.util.spec_from_file_location(name, self.job["path"], loader=self)
        return None

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        exec(compile(self.job["source"], self.job["path"], "exec"), module.__dict__)


def child(job, out):
    result = {"status": "survived", "detail": ""}

    def finish():
        with open(out, "w") as f:
            json.dump(result, f)
        os._exit(0)

    log = os.open(job["log"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(log, 1)
    os.dup2(log, 2)
    if job.get("c_source"):
        # a C mutant: the FMUs the comparison test builds are built from a copy of fmu/c
        # whose rg_core.c is the mutant; one that does not compile is stillborn
        import shutil, subprocess, tempfile
        import fmu.build
        c_dir = os.path.join(tempfile.mkdtemp(prefix="rg-cmut-"), "c")
        shutil.copytree(job["c_dir"], c_dir)
        with open(os.path.join(c_dir, "core", "rg_core.c"), "w") as f:
            f.write(job["c_source"])
        flags = [f for f in fmu.build.CFLAGS if f != "-Werror"]     # a mutant may warn (a || b && c)
        cc = subprocess.run([fmu.build.compiler(), *flags, "-c", "-o", os.devnull,
                             os.path.join(c_dir, "core", "rg_core.c")], capture_output=True, text=True)
        if cc.returncode != 0:
            result.update(status="stillborn", detail=(cc.stderr.strip().splitlines() or ["?"])[0][:200])
            finish()
        fmu.build.C_DIR = type(fmu.build.C_DIR)(c_dir)
        # the FMUs are built without optimisation (3 builds per mutant); the -O2 build
        # above decided that the mutant compiles (warnings allowed: a mutant may warn)
        fmu.build.CFLAGS = [f for f in flags if f != "-O2"] + ["-O0"]
    if job["module"]:
        sys.meta_path.insert(0, Mutated(job))
        try:
            importlib.import_module(job["module"])
        except BaseException as exc:
            result.update(status="killed", detail="import fails: %s: %s" % (type(exc).__name__, str(exc)[:200]))
            finish()

    class Record:
        def pytest_collection_modifyitems(self, items):
            # C mutants: the comparison test at a reduced size (sequences per table and
            # the edge-hit minimum scaled together); 0 keeps the test as it is
            n = job.get("c_sequences") or 0
            for item in items:
                mod = getattr(item, "module", None)
                if n and mod is not None and hasattr(mod, "SEQUENCES_PER_TABLE") and hasattr(mod, "MIN_HITS"):
                    mod.MIN_HITS = max(1, mod.MIN_HITS * n // mod.SEQUENCES_PER_TABLE)
                    mod.SEQUENCES_PER_TABLE = n

        def pytest_runtest_logreport(self, report):
            if report.failed and not result["detail"]:
                result["detail"] = report.nodeid

        def pytest_collectreport(self, report):
            if report.failed and not result["detail"]:
                result["detail"] = "collection: " + report.nodeid

    code = int(pytest.main(["-x", "-q", "-p", "no:cacheprovider", "--rootdir", job["root"], *job["tests"]],
                           plugins=[Record()]))
    if code == 1 or (code == 2 and result["detail"]):
        result["status"] = "killed"
    elif code != 0:
        result.update(status="error", detail="pytest exit code %d %s" % (code, result["detail"]))
    finish()


for line in sys.stdin:
    job = json.loads(line)
    out = job["log"] + ".result"
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        try:
            os.setpgid(0, 0)
            child(job, out)
        finally:
            os._exit(3)
    status = None
    while time.perf_counter() - t0 < job["timeout"]:
        done, st = os.waitpid(pid, os.WNOHANG)
        if done:
            status = st
            break
        time.sleep(0.02)
    if status is None:
        for target in (-pid, pid):
            try:
                os.kill(target, signal.SIGKILL)
            except OSError:
                pass
        os.waitpid(pid, 0)
        res = {"status": "timeout", "detail": "no verdict after %.0f s (counts as killed)" % job["timeout"]}
    else:
        try:
            with open(out) as f:
                res = json.load(f)
            os.unlink(out)
        except (OSError, ValueError):
            res = {"status": "killed", "detail": "the test process died (wait status %d)" % status}
    try:
        os.killpg(pid, signal.SIGKILL)     # anything the tests left behind
    except OSError:
        pass
    if res["status"] != "error":
        try:
            os.unlink(job["log"])
        except OSError:
            pass
    res["seconds"] = time.perf_counter() - t0
    sys.stdout.write(json.dumps(res) + "\n")
    sys.stdout.flush()
"""


def _module_name(rel: str) -> str:
    return rel[:-3].replace("/", ".")


class Server:
    """One fork server subprocess (see _SERVER); `run` sends it one job and waits for its verdict."""

    def __init__(self, workdir: Path):
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1", PYTHONHASHSEED="0")
        self.workdir = workdir
        self.proc = subprocess.Popen([sys.executable, "-c", _SERVER], cwd=workdir, env=env, text=True,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.count = 0

    def run(self, module: str, path: str, source: str, tests: Iterable[str], timeout: float,
            c_source: str = "") -> tuple[str, str, float]:
        self.count += 1
        log = str(self.workdir / f"job-{id(self)}-{self.count}.log")
        job = {"module": module, "path": path, "source": source, "root": str(ROOT), "log": log,
               "tests": [str(ROOT / t) for t in tests], "timeout": timeout, "c_source": c_source,
               "c_dir": str(C_DIR), "c_sequences": C_SEQUENCES if c_source else 0}
        self.proc.stdin.write(json.dumps(job) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the mutation fork server died")
        res = json.loads(line)
        detail = res["detail"] + (f" (log: {log})" if res["status"] == "error" else "")
        return res["status"], detail, res["seconds"]

    def close(self) -> None:
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()


def run_python(mutants: list[Mutant], tests: Iterable[str] = PY_TESTS, jobs: int = JOBS,
               timeout: Optional[float] = None, progress: Progress = lambda m: None, baseline: bool = True) -> dict:
    """Baseline first (every selected test must pass on the real core), then every mutant,
    `jobs` at a time, each in a fresh process forked from one of `jobs` servers."""
    return _run_all(mutants, tests, jobs, timeout, progress, c=False, baseline=baseline)


def run_c(mutants: list[Mutant], jobs: int = JOBS, timeout: Optional[float] = None,
          progress: Progress = lambda m: None, tests: Iterable[str] = C_TESTS, baseline: bool = True) -> dict:
    """The C mutants against the Python-vs-C comparison test alone (C_TESTS): each one's
    FMUs are built from a copy of fmu/c with the mutated rg_core.c."""
    return _run_all(mutants, tests, jobs, timeout, progress, c=True, baseline=baseline)


def _run_all(mutants: list[Mutant], tests: Iterable[str], jobs: int, timeout: Optional[float],
             progress: Progress, c: bool, baseline: bool = True) -> dict:
    """Without `baseline` the selected tests are not first run on the real core (CI runs
    them anyway) and the per-mutant timeout must be given."""
    import queue
    import threading

    tests = tuple(tests)
    with tempfile.TemporaryDirectory(prefix="rg-mutation-") as tmp:
        work = Path(tmp)
        servers = [Server(work) for _ in range(max(1, jobs))]
        try:
            base = 0.0
            if baseline:
                status, detail, base = servers[0].run("", "", "", tests, 1800,
                                                      c_source=(C_DIR / "core" / "rg_core.c").read_text() if c else "")
                if status != "survived":
                    raise RuntimeError(f"the selected tests fail on the real core ({status}: {detail})")
                progress(f"baseline: the {len(tests)} test files pass on the real core in {base:.1f} s")
            limit = timeout if timeout is not None else max(60.0, 5 * base)
            todo: queue.Queue = queue.Queue()
            for m in mutants:
                todo.put(m)
            done = [0]
            lock = threading.Lock()
            failure: list[BaseException] = []

            def worker(server: Server) -> None:
                while not failure:
                    try:
                        m = todo.get_nowait()
                    except queue.Empty:
                        return
                    try:
                        if c:
                            m.status, m.detail, m.seconds = server.run("", "", "", tests, limit, c_source=m.source)
                        else:
                            m.status, m.detail, m.seconds = server.run(_module_name(m.file), str(ROOT / m.file),
                                                                       m.source, tests, limit)
                    except BaseException as exc:  # noqa: BLE001 - reported after the threads stop
                        failure.append(exc)
                        return
                    with lock:
                        done[0] += 1
                        progress(f"[{done[0]}/{len(mutants)}] {m.status:8s} {m.id}  ({m.seconds:.1f} s)")

            threads = [threading.Thread(target=worker, args=(s,)) for s in servers]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            if failure:
                raise failure[0]
        finally:
            for s in servers:
                s.close()
    return {"baseline_seconds": round(base, 2), "timeout_seconds": round(limit, 1)}


# ---------------------------------------------------------------------------- summary

def summarize(mutants: list[Mutant], equivalents: dict[str, str], seconds: float, extra: Optional[dict] = None) -> dict:
    ids = {m.id for m in mutants}
    for m in mutants:
        m.equivalent = m.id in equivalents
    stillborn = [m for m in mutants if m.status == "stillborn"]      # C: does not compile cleanly
    non_eq = [m for m in mutants if not m.equivalent and m.status != "stillborn"]
    killed = [m for m in non_eq if m.status in ("killed", "timeout")]
    survived = [m for m in non_eq if m.status not in ("killed", "timeout")]
    eq = [m for m in mutants if m.equivalent]
    wrong_eq = [m.id for m in eq if m.status in ("killed", "timeout")]
    score = len(killed) / len(non_eq) if non_eq else 1.0
    return {
        "score": score,
        "total": len(mutants) - len(stillborn),
        "stillborn": len(stillborn),
        "killed": len(killed),
        "survived": len(survived),
        "equivalent": len(eq),
        "timeouts": sum(m.status == "timeout" for m in mutants),
        "errors": sum(m.status == "error" for m in mutants),
        "seconds": round(seconds, 1),
        "survivors": [{"id": m.id, "diff": m.diff(), "status": m.status, "detail": m.detail} for m in survived],
        "equivalents": [{"id": m.id, "reason": equivalents[m.id]} for m in eq],
        "equivalent_but_killed": wrong_eq,
        "stale_equivalents": sorted(k for k in equivalents if k not in ids and k.split(":", 1)[0] in {m.file for m in mutants}),
        "by_file": _by_file(mutants),
        "mutants": [_public(m, equivalents) for m in mutants],
        **(extra or {}),
    }


def _public(m: Mutant, equivalents: dict[str, str]) -> dict:
    d = m.public()
    if m.equivalent:
        d["detail"] = (f"listed as equivalent but killed by {m.detail}" if m.status in ("killed", "timeout")
                       else equivalents[m.id])
    return d


def _by_file(mutants: list[Mutant]) -> dict:
    out: dict[str, dict] = {}
    for m in mutants:
        d = out.setdefault(m.file, {"total": 0, "killed": 0, "survived": 0, "equivalent": 0, "timeouts": 0})
        if m.status == "stillborn":
            continue
        d["total"] += 1
        if m.equivalent:
            d["equivalent"] += 1
        elif m.status in ("killed", "timeout"):
            d["killed"] += 1
        else:
            d["survived"] += 1
        d["timeouts"] += m.status == "timeout"
    return out


def run(target: str = "python", files: Optional[list[str]] = None, jobs: int = JOBS, timeout: Optional[float] = None,
        progress: Progress = lambda m: None, tests: Optional[Iterable[str]] = None,
        skip_equivalent: bool = False, only: Optional[Iterable[str]] = None, baseline: bool = True) -> dict:
    """Generate, run and summarize; with `skip_equivalent` the listed equivalent mutants are
    not run (the full run checks that they survive)."""
    t0 = time.perf_counter()
    equivalents = load_equivalents()
    if target == "python":
        mutants = python_mutants(files or PY_FILES)
    else:
        mutants = c_mutants(files)
    if only:
        wanted = set(only)
        mutants = [m for m in mutants if m.id in wanted]
        unknown = wanted - {m.id for m in mutants}
        if unknown:
            raise ValueError(f"no such mutant: {', '.join(sorted(unknown))}")
    todo = [m for m in mutants if not (skip_equivalent and m.id in equivalents)]
    for m in mutants:
        if m not in todo:
            m.status = "not run"
    progress(f"{len(mutants)} mutants of {len(files or (PY_FILES if target == 'python' else C_FILES))} file(s), "
             f"{len(todo)} to run")
    if target == "python":
        extra = run_python(todo, tests or PY_TESTS, jobs, timeout, progress, baseline=baseline)
    else:
        extra = run_c(todo, jobs, timeout, progress, baseline=baseline)
    return summarize(mutants, equivalents, time.perf_counter() - t0, {"target": target, **extra})


def render(summary: dict) -> str:
    lines = [f"mutation score: {summary['killed']}/{summary['total'] - summary['equivalent']} = "
             f"{100 * summary['score']:.1f} % of the non-equivalent mutants killed "
             f"({summary['total']} mutants, {summary['equivalent']} equivalent, {summary['survived']} survived, "
             f"{summary['timeouts']} timeouts counted as killed"
             + (f", {summary['stillborn']} stillborn (do not compile) left out" if summary.get("stillborn") else "")
             + f", {summary['seconds']:.0f} s)"]
    if summary["survivors"]:
        lines.append("\nsurvivors:")
        for s in summary["survivors"]:
            lines.append(f"  {s['id']}  [{s['status']}{': ' + s['detail'] if s['detail'] else ''}]")
            lines += ["      " + x for x in s["diff"].splitlines()]
    if summary["equivalents"]:
        lines.append("\nequivalent:")
        for e in summary["equivalents"]:
            lines.append(f"  {e['id']}: {e['reason']}")
    if summary["equivalent_but_killed"]:
        lines.append("\nlisted as equivalent but killed (remove from the list): " + ", ".join(summary["equivalent_but_killed"]))
    if summary["stale_equivalents"]:
        lines.append("\nlisted as equivalent but no such mutant: " + ", ".join(summary["stale_equivalents"]))
    return "\n".join(lines)


CI_FILES = ("voter.py", "freshness.py", "observation.py", "envelope.py")
REPORT_QUICK_FILES = ("voter.py",)     # `railguard verify --quick`: the voters (tests/test_mutation.py runs CI_FILES)


def _score_rows(summary: dict) -> list[list]:
    rows = []
    for f, d in sorted(summary["by_file"].items()):
        non_eq = d["total"] - d["equivalent"]
        rows.append([f"`{f}`", d["total"], d["killed"], d["equivalent"], d["survived"], d["timeouts"],
                     f"{100 * d['killed'] / non_eq:.1f} %" if non_eq else "-"])
    return rows


def section(out_dir, quick: bool, progress: Progress, config=None):
    """Mutation testing as a report part: the Python core (quick: REPORT_QUICK_FILES,
    the listed equivalent mutants not run; full: all of monitor/core and the listed
    equivalents run to show that they survive). `config` is accepted for the report's
    uniform signature; the mutants run the core's own tests, which set their configurations."""
    from verification.report import Section, md_table

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = list(REPORT_QUICK_FILES if quick else PY_FILES)
    summary = run("python", files, progress=progress, skip_equivalent=quick)
    (out / "mutation.json").write_text(json.dumps(summary, indent=1))
    header = ["file", "mutants", "killed", "equivalent", "survived", "timeouts (killed)", "score"]
    rows = _score_rows(summary)
    rows.append(["**all**", summary["total"], summary["killed"], summary["equivalent"], summary["survived"],
                 summary["timeouts"], f"{100 * summary['score']:.1f} %"])
    md = [f"`python -m verification.mutation` ({'quick: ' + ', '.join(files) if quick else 'all of monitor/core'}): "
          f"{summary['total']} mutants (comparison swaps, and/or, a dropped operand of an and/or chain, min/max, "
          f"integer constants +/-1, +/-, a removed `not`, int/bool return values, type checks removed), each run "
          f"in a fresh process against the core's fast tests ({', '.join(f'`{t}`' for t in PY_TESTS)}); "
          f"a timeout counts as killed. Score = killed / non-equivalent mutants. Baseline "
          f"{summary.get('baseline_seconds', 0):.1f} s, whole run {summary['seconds']:.0f} s.\n",
          md_table(header, rows)]
    if summary["survivors"]:
        md.append("\nSurvivors:\n")
        md += [f"- `{x['id']}`: `{x['diff'].splitlines()[1][2:]}`" for x in summary["survivors"]]
    eq = load_equivalents()
    md.append("\nThe C core's decision functions are mutated by `python -m verification.mutation --target c` "
              "and judged by the Python-vs-C comparison test alone (`tests/test_mutation.py` runs a subset).\n")
    md.append(f"\nEquivalent mutants ({len([k for k in eq if k.split(':', 1)[0] in summary['by_file']])} in these "
              f"files, `verification/mutation_equivalents.toml`):\n")
    md += [f"- `{k}`: {v}" for k, v in eq.items() if k.split(":", 1)[0] in summary["by_file"]]
    checks = [_score_check("python core", summary, files)]
    seconds = summary["seconds"]
    if not quick:                   # the C core's decision functions, judged by the comparison test alone
        c = run("c", progress=progress)
        (out / "mutation-c.json").write_text(json.dumps(c, indent=1))
        seconds += c["seconds"]
        md.append(f"\n**C core** (`python -m verification.mutation --target c`: the decision functions of "
                  f"`rg_core.c`, each mutant compiled and judged by `{', '.join(C_TESTS)}` alone, {C_SEQUENCES:,} "
                  f"sequences per table): {c['total']} mutants, {c['killed']} killed, {c['equivalent']} equivalent, "
                  f"{c['survived']} survived, score {100 * c['score']:.1f} %, {c['seconds']:.0f} s.\n")
        md += [f"- `{x['id']}` survived" for x in c["survivors"]]
        checks.append(_score_check("C core (by the Python-vs-C comparison alone)", c, list(C_FILES)))
    return Section("Mutation testing of the core", "\n".join(md) + "\n", checks, [], seconds)


def _score_check(what: str, summary: dict, files: list):
    """100 % of the non-equivalent mutants killed, no error, no listed equivalent killed, no stale id."""
    from verification.report import Check

    non_eq = summary["total"] - summary["equivalent"]
    ok = (summary["survived"] == 0 and summary["errors"] == 0 and not summary["equivalent_but_killed"]
          and not summary["stale_equivalents"])
    return Check(f"mutation score {what}: killed/non-equivalent = 100 %", ok,
                 f"{summary['killed']}/{non_eq} = {100 * summary['score']:.1f} %"
                 + (f"; {len(summary['equivalent_but_killed'])} listed equivalent but killed" if summary["equivalent_but_killed"] else "")
                 + (f"; {len(summary['stale_equivalents'])} stale equivalent ids" if summary["stale_equivalents"] else "")
                 + (f"; {summary['errors']} errors" if summary["errors"] else ""),
                 {"total": summary["total"], "equivalent": summary["equivalent"], "survived": summary["survived"],
                  "timeouts": summary["timeouts"], "files": files})


def main(argv: Optional[list[str]] = None) -> int:
    import argparse

    ap = argparse.ArgumentParser(prog="python -m verification.mutation", description=__doc__.splitlines()[0])
    ap.add_argument("--target", choices=("python", "c"), default="python")
    ap.add_argument("--files", nargs="+", help="files to mutate (default: all of monitor/core, or rg_core.c)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--list", action="store_true", help="list the mutants (id and diff) without running them")
    ap.add_argument("--jobs", type=int, default=JOBS)
    ap.add_argument("--timeout", type=float, default=None, help="seconds per mutant (default: 5 x the baseline, >= 60)")
    ap.add_argument("--only", nargs="+", metavar="ID", help="run only these mutants (ids as --list prints them)")
    ap.add_argument("--no-baseline", action="store_true",
                    help="do not first run the tests on the real core (needs --timeout)")
    ap.add_argument("--skip-equivalent", action="store_true",
                    help="do not run the mutants listed as equivalent (the full run checks that they survive)")
    args = ap.parse_args(argv)
    if args.no_baseline and args.timeout is None:
        ap.error("--no-baseline needs --timeout")
    if args.list:
        ms = python_mutants(args.files or PY_FILES) if args.target == "python" else c_mutants()
        if args.json:
            print(json.dumps([m.public() for m in ms], indent=1))
        else:
            for m in ms:
                print(m.id)
                print("    " + m.diff().replace("\n", "\n    "))
            print(f"{len(ms)} mutants", file=sys.stderr)
        return 0
    summary = run(args.target, args.files, args.jobs, args.timeout,
                  progress=lambda msg: print(msg, file=sys.stderr, flush=True), skip_equivalent=args.skip_equivalent,
                  only=args.only, baseline=not args.no_baseline)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(render(summary))
    ok = summary["survived"] == 0 and not summary["equivalent_but_killed"] and not summary["errors"]
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
