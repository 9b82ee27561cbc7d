"""Run the shipped C curves (fmu/c/core/rg_core.c, `rg_curves`) on symbolic numbers, so that
the integer obligations are proved about the C as well as about the Python (issue 30 item 3).

The C is preprocessed with the system's `cpp` (the real rg_core.h and its macros; stand-in
libc headers that only declare types), parsed with pycparser, and run by a small interpreter
of the C subset the curves use: integer declarations, structs, arrays of structs, pointers to
locals and structs, `if`, `for`, `?:`, `&& || !`, `+ - * /`, comparisons, calls. The numbers
are symbolic.SymInt, so every branch is followed by symbolic.explore exactly as for the
Python. C semantics where they differ from Python's:

* `/` truncates towards zero: a numerator that may be negative is split into its two signs
  (a branch), each side a floor division of a non-negative number;
* integer types are unbounded here: the C's overflow freedom is Frama-C EVA's claim (0 alarms
  on rg_step, docs/proof.md), which this run assumes and does not repeat.

Anything outside the subset raises symbolic.Unsupported, never a silent wrong answer. The
entry points are wrappers with braking.curves' and braking.ebi_dm's signatures, written in C
with the core's own macros (RG_SUPERVISED_PERIODS, RG_ZONE_PERIODS) and appended to the
source, so a change to those macros in rg_core.h is seen.
"""
from __future__ import annotations

import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Callable

from pycparser import c_ast, c_parser

from monitor.core.braking import Curves

from .symbolic import SymBool, SymInt, Unsupported

REPO = Path(__file__).resolve().parents[2]
CORE_DIR = REPO / "fmu" / "c" / "core"

# Stand-in libc headers: types only; nothing the curves use comes from libc.
FAKE_LIBC = {
    "stdint.h": "typedef signed char int8_t; typedef short int16_t; typedef int int32_t; typedef long long int64_t;\n"
                "typedef unsigned char uint8_t; typedef unsigned short uint16_t; typedef unsigned int uint32_t;\n"
                "typedef unsigned long long uint64_t;\n",
    "stddef.h": "typedef unsigned long size_t;\n#define NULL ((void *)0)\n",
    "stdio.h": "typedef unsigned long size_t;\nint snprintf(char *s, size_t n, const char *f, ...);\n",
}

# braking.curves(cfg, speed_cms, track, brake, closing_cms, age_ms, service) and
# braking.ebi_dm(...) as the C core computes them, with its own macros.
ENTRY_POINTS = """
void rg_verify_curves(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
                      int32_t age_ms, int32_t service, rg_curve_set *out)
{
    rg_curves(cfg, speed_cms, track, brake, closing_cms, age_ms, service, RG_SUPERVISED_PERIODS, out);
}

void rg_verify_zone(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
                    int32_t age_ms, int32_t service, rg_curve_set *out)
{
    rg_curves(cfg, speed_cms, track, brake, closing_cms, age_ms, service, RG_ZONE_PERIODS, out);
}
"""


def preprocess(core_dir: Path) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in FAKE_LIBC.items():
            (Path(tmp) / name).write_text(text)
        source = (Path(core_dir) / "rg_core.c").read_text() + ENTRY_POINTS
        try:
            run = subprocess.run(["cpp", "-P", "-nostdinc", "-I", tmp, "-I", str(core_dir), "-"], input=source,
                                 capture_output=True, text=True)
        except FileNotFoundError:
            raise Unsupported("no C preprocessor: the physics proof of the C core needs cpp (apt-get install gcc)")
        if run.returncode != 0:
            raise Unsupported(f"cpp failed on {core_dir}/rg_core.c: {run.stderr.strip().splitlines()[:1]}")
        return run.stdout


@lru_cache(maxsize=8)
def _program(core_dir: str, source: str) -> "Program":
    return Program(c_parser.CParser().parse(source, filename=f"{core_dir}/rg_core.c"))


def program(core_dir: Path = CORE_DIR) -> "Program":
    """The parsed core of `core_dir` (cached per source text)."""
    return _program(str(core_dir), preprocess(Path(core_dir)))


class Ref:
    """A C pointer: to a variable of a scope, to an element of an array, or to a struct."""

    def __init__(self, holder, key):
        self.holder, self.key = holder, key

    def get(self):
        return self.holder[self.key]

    def set(self, value):
        self.holder[self.key] = value


class Struct(dict):
    """A struct value: field name -> value."""


class _Return(Exception):
    def __init__(self, value):
        self.value = value


def truth(v) -> bool:
    if isinstance(v, SymBool):
        return bool(v)
    if isinstance(v, SymInt):
        return bool(v != 0)
    if isinstance(v, bool):
        return v
    if isinstance(v, int):
        return v != 0
    raise Unsupported(f"{type(v).__name__} as a condition")


def number(v):
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, (int, SymInt)):
        return v
    if isinstance(v, SymBool):
        raise Unsupported("a symbolic comparison used as a number")
    raise Unsupported(f"{type(v).__name__} as a number")


def c_div(x, d):
    """C's `/`: truncation towards zero."""
    x, d = number(x), number(d)
    if isinstance(x, int) and isinstance(d, int):
        if d == 0:
            raise Unsupported("a division by zero")
        q = abs(x) // abs(d)
        return q if (x >= 0) == (d > 0) else -q
    if isinstance(d, int) and d < 0:
        return -c_div(x, -d)
    if truth(x >= 0):
        return x // d
    return -((-x) // d)


BINARY = {
    "+": lambda a, b: number(a) + number(b),
    "-": lambda a, b: number(a) - number(b),
    "*": lambda a, b: number(a) * number(b),
    "/": c_div,
    "<": lambda a, b: number(a) < number(b),
    "<=": lambda a, b: number(a) <= number(b),
    ">": lambda a, b: number(a) > number(b),
    ">=": lambda a, b: number(a) >= number(b),
    "==": lambda a, b: number(a) == number(b),
    "!=": lambda a, b: number(a) != number(b),
}
INTEGER_TYPES = {"int8_t", "int16_t", "int32_t", "int64_t", "uint8_t", "uint16_t", "uint32_t", "uint64_t", "int"}


class ConfigView:
    """`const rg_config *cfg` over a monitor.core.config.Config: the fields read by name."""

    def __init__(self, cfg):
        self.cfg = cfg

    def __getitem__(self, name):
        value = getattr(self.cfg, name, None)
        if not isinstance(value, int) or isinstance(value, bool):
            raise Unsupported(f"rg_config.{name} has no integer counterpart in Config")
        return value

    def __setitem__(self, name, value):
        raise Unsupported(f"a write to the const rg_config.{name}")


class Program:
    """The functions and struct types of a parsed translation unit, and an interpreter."""

    def __init__(self, ast: c_ast.FileAST):
        self.functions = {n.decl.name: n for n in ast.ext if isinstance(n, c_ast.FuncDef)}
        self.structs = {}
        for n in ast.ext:
            if isinstance(n, c_ast.Typedef) and isinstance(n.type.type, c_ast.Struct) and n.type.type.decls:
                self.structs[n.name] = [d.name for d in n.type.type.decls]

    # ------------------------------------------------------------------ calls

    def call(self, name: str, args: list):
        fn = self.functions.get(name)
        if fn is None:
            raise Unsupported(f"a call to {name}, which is not defined in rg_core.c")
        params = fn.decl.type.args.params if fn.decl.type.args else []
        params = [p for p in params if not (isinstance(p.type, c_ast.TypeDecl) and p.name is None)]   # f(void)
        if len(params) != len(args):
            raise Unsupported(f"{name} called with {len(args)} arguments, defined with {len(params)}")
        scope = [{p.name: a for p, a in zip(params, args)}]
        try:
            self.statement(fn.body, scope)
        except _Return as r:
            return r.value
        return None

    # ------------------------------------------------------------------ scopes

    @staticmethod
    def holder(scope: list, name: str) -> dict:
        for frame in reversed(scope):
            if name in frame:
                return frame
        raise Unsupported(f"an undeclared name {name}")

    # ------------------------------------------------------------------ statements

    def statement(self, node, scope: list) -> None:
        kind = type(node).__name__
        if kind == "Compound":
            inner = scope + [{}]
            for item in node.block_items or []:
                self.statement(item, inner)
        elif kind == "Decl":
            self.declare(node, scope)
        elif kind == "DeclList":
            for d in node.decls:
                self.declare(d, scope)
        elif kind == "If":
            if truth(self.expr(node.cond, scope)):
                self.statement(node.iftrue, scope)
            elif node.iffalse is not None:
                self.statement(node.iffalse, scope)
        elif kind == "For":
            inner = scope + [{}]
            if node.init is not None:
                self.statement(node.init, inner)
            for _ in range(10000):
                if node.cond is not None and not truth(self.expr(node.cond, inner)):
                    return
                self.statement(node.stmt, inner)
                if node.next is not None:
                    self.expr(node.next, inner)
            raise Unsupported("a loop of more than 10000 iterations")
        elif kind == "Return":
            raise _Return(None if node.expr is None else self.expr(node.expr, scope))
        elif kind == "EmptyStatement":
            pass
        elif kind in ("Assignment", "FuncCall", "UnaryOp", "BinaryOp"):
            self.expr(node, scope)
        else:
            raise Unsupported(f"a C statement {kind}")

    def declare(self, d: c_ast.Decl, scope: list) -> None:
        t = d.type
        if isinstance(t, c_ast.ArrayDecl):
            size = self.expr(t.dim, scope)
            struct = self.struct_name(t.type)
            items = [Struct({f: 0 for f in self.structs[struct]}) if struct else 0 for _ in range(number(size))]
            if isinstance(d.init, c_ast.InitList):
                for i, e in enumerate(d.init.exprs):
                    if struct and isinstance(e, c_ast.InitList):
                        for f, v in zip(self.structs[struct], e.exprs):
                            items[i][f] = self.expr(v, scope)
                    else:
                        items[i] = self.expr(e, scope)
            elif d.init is not None:
                raise Unsupported(f"an array initialiser {type(d.init).__name__}")
            scope[-1][d.name] = items
        elif isinstance(t, c_ast.TypeDecl):
            struct = self.struct_name(t)
            if struct:
                if d.init is not None:
                    raise Unsupported("an initialised struct variable")
                scope[-1][d.name] = Struct({f: 0 for f in self.structs[struct]})
            else:
                self.integer_type(t)
                scope[-1][d.name] = None if d.init is None else number(self.expr(d.init, scope))
        else:
            raise Unsupported(f"a declaration of {type(t).__name__}")

    def struct_name(self, t):
        if isinstance(t, c_ast.TypeDecl) and isinstance(t.type, c_ast.IdentifierType):
            name = " ".join(t.type.names)
            return name if name in self.structs else None
        return None

    @staticmethod
    def integer_type(t) -> None:
        names = " ".join(t.type.names) if isinstance(t.type, c_ast.IdentifierType) else ""
        if names not in INTEGER_TYPES:
            raise Unsupported(f"a variable of type {names or type(t.type).__name__}")

    # ------------------------------------------------------------------ expressions

    def expr(self, node, scope: list):
        kind = type(node).__name__
        if kind == "Constant":
            if node.type not in ("int", "long", "long long", "unsigned int", "unsigned long", "unsigned long long"):
                raise Unsupported(f"a constant of type {node.type}")
            return int(node.value.rstrip("uUlL"), 0)
        if kind == "ID":
            value = self.holder(scope, node.name)[node.name]
            if value is None:
                raise Unsupported(f"{node.name} read before it is set")
            return value
        if kind == "BinaryOp":
            if node.op == "&&":
                return truth(self.expr(node.left, scope)) and truth(self.expr(node.right, scope))
            if node.op == "||":
                return truth(self.expr(node.left, scope)) or truth(self.expr(node.right, scope))
            op = BINARY.get(node.op)
            if op is None:
                raise Unsupported(f"the operator {node.op}")
            return op(self.expr(node.left, scope), self.expr(node.right, scope))
        if kind == "UnaryOp":
            return self.unary(node, scope)
        if kind == "TernaryOp":
            chosen = node.iftrue if truth(self.expr(node.cond, scope)) else node.iffalse
            return self.expr(chosen, scope)
        if kind == "Cast":
            self.integer_type(node.to_type.type)       # widening casts only: see the module doc
            return number(self.expr(node.expr, scope))
        if kind == "Assignment":
            ref = self.lvalue(node.lvalue, scope)
            value = self.expr(node.rvalue, scope)
            if node.op == "=":
                ref.set(value if isinstance(value, (Struct, list, Ref, ConfigView)) else number(value))
            elif node.op in ("+=", "-=", "*="):
                ref.set(BINARY[node.op[0]](ref.get(), value))
            else:
                raise Unsupported(f"the assignment {node.op}")
            return ref.get()
        if kind in ("StructRef", "ArrayRef"):
            return self.lvalue(node, scope).get()
        if kind == "FuncCall":
            args = [self.expr(a, scope) for a in (node.args.exprs if node.args else [])]
            return self.call(node.name.name, args)
        raise Unsupported(f"a C expression {kind}")

    def unary(self, node, scope: list):
        op = node.op
        if op == "&":
            return self.lvalue(node.expr, scope)
        if op == "*":
            return self.lvalue(node, scope).get()
        if op == "-":
            return -number(self.expr(node.expr, scope))
        if op == "!":
            return not truth(self.expr(node.expr, scope))
        if op in ("p++", "++", "p--", "--"):
            ref = self.lvalue(node.expr, scope)
            old = number(ref.get())
            new = old + (1 if "+" in op else -1)
            ref.set(new)
            return old if op.startswith("p") else new
        raise Unsupported(f"the unary operator {op}")

    def lvalue(self, node, scope: list) -> Ref:
        kind = type(node).__name__
        if kind == "ID":
            return Ref(self.holder(scope, node.name), node.name)
        if kind == "UnaryOp" and node.op == "*":
            pointer = self.expr(node.expr, scope)
            if not isinstance(pointer, Ref):
                raise Unsupported("a dereference of something that is not a pointer")
            return pointer
        if kind == "StructRef":
            base = self.expr(node.name, scope)
            if node.type == "->":
                if isinstance(base, Ref):
                    base = base.get()
            if not isinstance(base, (Struct, ConfigView)):
                raise Unsupported(f"a field {node.field.name} of something that is not a struct")
            field = node.field.name
            if isinstance(base, Struct) and field not in base:
                raise Unsupported(f"no field {field}")
            return Ref(base, field)
        if kind == "ArrayRef":
            base = self.expr(node.name, scope)
            index = number(self.expr(node.subscript, scope))
            if isinstance(index, SymInt):
                raise Unsupported("a symbolic array index")
            if not isinstance(base, list) or not 0 <= index < len(base):
                raise Unsupported(f"an index {index} out of an array")
            return Ref(base, index)
        raise Unsupported(f"an lvalue {kind}")


def _entry(name: str, prog: "Program") -> Callable:
    def run(cfg, speed_cms, track, brake, closing_cms, age_ms, service=False):
        out = Struct({f: 0 for f in prog.structs["rg_curve_set"]})
        prog.call(name, [ConfigView(cfg), speed_cms, int(track), int(brake), closing_cms, age_ms, int(service),
                         Ref({"o": out}, "o")])
        return Curves(out["ebd_dm"], out["ebi_dm"], out["sbi_dm"], out["warning_dm"])
    run.__name__ = "rg_curves"
    return run


def curves(prog: "Program") -> Callable:
    """braking.curves, as the parsed rg_core.c (`program`) computes it (RG_SUPERVISED_PERIODS)."""
    return _entry("rg_verify_curves", prog)


def ebi_dm(prog: "Program") -> Callable:
    """braking.ebi_dm, as the parsed rg_core.c computes it (RG_ZONE_PERIODS): the table's zone limits."""
    run = _entry("rg_verify_zone", prog)

    def zone(cfg, speed_cms, track, brake, closing_cms, age_ms, service=False):
        return run(cfg, speed_cms, track, brake, closing_cms, age_ms, service).ebi_dm
    zone.__name__ = "rg_curves"
    return zone
