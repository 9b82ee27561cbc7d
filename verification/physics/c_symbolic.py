"""Run the shipped C core (fmu/c/core/rg_core.c) on symbolic numbers, so that the integer
obligations are proved about the C as well as about the Python (issue 30 item 3): its curves
(`rg_curves`, the entry points below) and its whole cycle (`rg_step`, c_step.py).

The C is preprocessed with the system's `cpp` (the real rg_core.h and its macros; stand-in
libc headers that only declare types), parsed with pycparser, and run by a small interpreter
of the C subset the core uses (integers, structs, arrays, pointers, file-scope constants, the
statements and operators of rg_step and its callees; `summaries` replace named functions, for
modular proofs). The numbers are symbolic.SymInt, so every branch is followed by
symbolic.explore exactly as for the Python. C semantics where they differ from Python's:

* every expression has its C type (the usual arithmetic conversions, promotions);
* `/` truncates towards zero: a numerator that may be negative is split into its two signs
  (a branch), each side a floor division of a non-negative number; `%`, shifts and bitwise
  operators run on concrete numbers only;
* a struct assignment copies; an array passed or assigned to a pointer is aliased;
* a value that does not fit its type (an unsigned one that would wrap, a concrete overflow)
  is refused, a symbolic unsigned one on the path where it may not; signed symbolic numbers
  are unbounded: the C's overflow freedom is Frama-C EVA's claim (0 alarms on rg_step,
  docs/proof.md), which this run assumes and does not repeat;
* a comparison used as a number (`seen = a == b`) is a branch, 0 or 1 on each side.

Anything outside the subset raises symbolic.Unsupported, never a silent wrong answer. The
curves' entry points are wrappers with braking.curves' and braking.ebi_dm's signatures,
written in C with the core's own macros (RG_SUPERVISED_PERIODS, RG_ZONE_PERIODS) and appended
to the source, so a change to those macros in rg_core.h is seen.
"""
from __future__ import annotations

import copy as _copy
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
    rg_curves(cfg, speed_cms, track, brake, closing_cms, age_ms, service, 1, out);
}

void rg_verify_zone(const rg_config *cfg, int32_t speed_cms, int32_t track, int32_t brake, int32_t closing_cms,
                    int32_t age_ms, int32_t service, rg_curve_set *out)
{
    rg_curves(cfg, speed_cms, track, brake, closing_cms, age_ms, service, 0, out);
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
    """A struct value: field name -> value (None: not set yet, as in C's automatic storage)."""


class Frame(dict):
    """A scope's variables, with their declared C types (conversions and arithmetic read them)."""

    def __init__(self, *args):
        super().__init__(*args)
        self.types: dict = {}


class _Return(Exception):
    def __init__(self, value):
        self.value = value


# `break` and `continue`: raised by the statement, caught by the innermost loop
_Break, _Continue = type("_Break", (Exception,), {}), type("_Continue", (Exception,), {})


def truth(v) -> bool:
    if isinstance(v, (SymBool, bool, SymInt, int)):
        return bool(v) if isinstance(v, (SymBool, bool)) else bool(v != 0)
    raise Unsupported(f"{type(v).__name__} as a condition")


def number(v):
    """A C int value; a symbolic comparison is 0 or 1 on either side of a branch."""
    if isinstance(v, (bool, SymBool)):
        return int(bool(v))
    if isinstance(v, (int, SymInt)):
        return v
    raise Unsupported(f"{type(v).__name__} as a number")


def concrete(*values) -> None:
    """The operators that would need bit-level terms (% << >> & | ^) run on concrete numbers only."""
    if not all(isinstance(v, int) for v in values):
        raise Unsupported("a bitwise operator, shift or % on a symbolic number")


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


ARITHMETIC = {
    "+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b, "/": c_div,
    "%": lambda a, b: concrete(a, b) or a - c_div(a, b) * b, "&": lambda a, b: concrete(a, b) or a & b,
    "|": lambda a, b: concrete(a, b) or a | b, "^": lambda a, b: concrete(a, b) or a ^ b,
}
COMPARISONS = {
    "<": lambda a, b: a < b, "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b,
    "==": lambda a, b: a == b, "!=": lambda a, b: a != b,
}
# C types: ("int", signed, bits), ("struct", name), ("ptr", target), ("array", element, size), ("void",)
INTEGER_TYPES = {"char": (True, 8), "signed char": (True, 8), "unsigned char": (False, 8), "short": (True, 16),
                 "unsigned short": (False, 16), "int": (True, 32), "unsigned int": (False, 32), "long": (True, 64),
                 "unsigned long": (False, 64), "long long": (True, 64), "unsigned long long": (False, 64)}
INT32, VOID = ("int", True, 32), ("void",)
EXPRESSIONS = ("Assignment", "FuncCall", "UnaryOp", "BinaryOp", "Cast", "TernaryOp", "ID", "Constant")


def promote(t):
    if t[0] != "int":
        raise Unsupported(f"arithmetic on a C {t[0]}")
    return INT32 if t[2] < 32 else t


def common(a, b):
    """C's usual arithmetic conversions."""
    a, b = promote(a), promote(b)
    if a == b or a[1] == b[1]:
        return a if a[2] >= b[2] else b
    u, s = (a, b) if not a[1] else (b, a)
    return u if u[2] >= s[2] else s


def fit(v, t):
    """v as a value of integer type t: out of range is refused, never wrapped (signed
    symbolic values are assumed in range: Frama-C EVA's claim, see the module doc)."""
    signed, bits = t[1], t[2]
    hi = (1 << (bits - 1 if signed else bits)) - 1
    if isinstance(v, int):
        if not (-hi - 1 if signed else 0) <= v <= hi:
            raise Unsupported(f"{v} does not fit {'' if signed else 'u'}int{bits}_t: C would wrap or overflow")
    elif not signed and not (v >= 0 and v <= hi):
        raise Unsupported(f"a symbolic number that may not fit uint{bits}_t: C would wrap")
    return v


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
    """The functions, struct types and file-scope constants of a parsed translation unit, and
    an interpreter. `summaries` (name -> Python callable) replace those functions when called."""

    def __init__(self, ast: c_ast.FileAST):
        self.functions = {n.decl.name: n for n in ast.ext if isinstance(n, c_ast.FuncDef)}
        decls = [n for n in ast.ext if isinstance(n, c_ast.Decl)]
        self.prototypes = {n.name: n.type for n in decls if isinstance(n.type, c_ast.FuncDecl)}
        self.prototypes.update({name: fn.decl.type for name, fn in self.functions.items()})
        self.global_decls = {n.name: n for n in decls if n.name and not isinstance(n.type, c_ast.FuncDecl)}
        self.globals = Frame()
        self.fields = {n.name: {d.name: d.type for d in n.type.type.decls} for n in ast.ext  # struct -> field -> type
                       if isinstance(n, c_ast.Typedef) and isinstance(n.type.type, c_ast.Struct) and n.type.type.decls}
        self.structs = {name: list(fields) for name, fields in self.fields.items()}
        self.typedefs = {n.name: n.type for n in ast.ext if isinstance(n, c_ast.Typedef)       # int32_t -> int
                         and isinstance(n.type.type, c_ast.IdentifierType)}
        self.summaries: dict = {}
        self._memo: dict = {}      # id(AST node) -> its C type, or a constant's (value, type)

    def summarised(self, summaries: dict | None) -> "Program":
        """This program with `summaries` replacing the C functions of those names (the parsed
        program, cached and shared, stays as it is)."""
        clone = _copy.copy(self)
        clone.summaries = dict(summaries or {})
        return clone

    def _memoised(self, key, compute):             # C's types are fixed by the source
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def type_of(self, t):
        """The C type of a declarator."""
        return self._memoised(id(t), lambda: self._type_of(t))

    def _type_of(self, t):
        if isinstance(t, (c_ast.TypeDecl, c_ast.Typename)):
            return self.type_of(t.type)
        if isinstance(t, c_ast.IdentifierType):
            name = " ".join(t.names)
            if name in self.typedefs:
                return self.type_of(self.typedefs[name])
            if name in INTEGER_TYPES:
                return ("int",) + INTEGER_TYPES[name]
            return ("struct", name) if name in self.fields else VOID if name == "void" else ("other", name)
        if isinstance(t, c_ast.PtrDecl):
            return ("ptr", self.type_of(t.type))
        if isinstance(t, c_ast.ArrayDecl):
            return ("array", self.type_of(t.type), None if t.dim is None else number(self.expr(t.dim, [])))
        return ("other", type(t).__name__)

    def field_type(self, struct: str, field: str):
        if field not in self.fields.get(struct, {}):
            raise Unsupported(f"no field {field} in {struct}")
        return self.type_of(self.fields[struct][field])

    def signature(self, name: str):
        """([(parameter, type)], return type) of a function defined or declared."""
        decl = self.prototypes.get(name)
        if decl is None:
            raise Unsupported(f"a call to {name}, which is not defined in rg_core.c")
        params = [(getattr(p, "name", "..."), self.type_of(getattr(p, "type", None)))      # `...`: refused when
                  for p in (decl.args.params if decl.args else [])]                                 # given an argument
        return [p for p in params if not (p[0] is None and p[1] == VOID)], self.type_of(decl.type)   # f(void)

    def blank(self, t, fill=None):
        """A value of type t with every number `fill` (None: not set yet)."""
        if t[0] == "struct":
            return Struct({f: self.blank(self.type_of(ft), fill) for f, ft in self.fields[t[1]].items()})
        if t[0] == "array" and t[2] is not None:
            return [self.blank(t[1], fill) for _ in range(t[2])]
        if t[0] in ("int", "ptr"):
            return fill if t[0] == "int" else None
        raise Unsupported(f"a variable of type {t} (an array of unknown size?)")

    def convert(self, value, t):
        """C's conversion of a value to type t, as on assignment, argument passing and return."""
        if t[0] == "int":
            return fit(number(value), t)
        if t[0] == "struct" and isinstance(value, Struct):
            return self.copy(value, t)
        if t[0] in ("ptr", "array", "void"):
            return None if t == VOID else value
        raise Unsupported(f"a {type(value).__name__} converted to {t}")

    def copy(self, v, t):
        """C's struct assignment: a copy, its arrays too; its pointers point where they did."""
        if t[0] == "struct":
            return Struct({f: self.copy(x, self.field_type(t[1], f)) for f, x in v.items()})
        return [self.copy(x, t[1]) for x in v] if t[0] == "array" else v

    def stype(self, node, scope: list):
        """The C type of an expression (memoised: C's types are lexical)."""
        return self._memoised(id(node), lambda: self._stype(node, scope))

    def _stype(self, node, scope: list):
        kind = type(node).__name__
        if kind == "Constant":
            return self.constant(node)[1]
        if kind == "ID":
            return self.holder(scope, node.name).types[node.name]
        if kind in ("StructRef", "ArrayRef") or (kind == "UnaryOp" and node.op == "*"):
            t = self.stype(node.expr if kind == "UnaryOp" else node.name, scope)
            if kind != "StructRef" or node.type == "->":
                if t[0] not in ("ptr", "array"):
                    raise Unsupported(f"a {kind} of a {t[0]}")
                t = t[1]
            if kind != "StructRef":
                return t
            if t[0] != "struct":
                raise Unsupported(f"a field {node.field.name} of a {t[0]}")
            return self.field_type(t[1], node.field.name)
        if kind == "UnaryOp":
            t = self.stype(node.expr, scope)
            if node.op in ("&", "p++", "p--", "++", "--"):
                return ("ptr", t) if node.op == "&" else t
            return INT32 if node.op == "!" else promote(t)
        if kind == "BinaryOp":
            if node.op in COMPARISONS or node.op in ("&&", "||"):
                return INT32
            left = self.stype(node.left, scope)
            return promote(left) if node.op in ("<<", ">>") else common(left, self.stype(node.right, scope))
        if kind == "TernaryOp":
            a, b = self.stype(node.iftrue, scope), self.stype(node.iffalse, scope)
            return common(a, b) if a[0] == "int" and b[0] == "int" else a
        if kind in ("Cast", "Assignment"):
            return self.type_of(node.to_type) if kind == "Cast" else self.stype(node.lvalue, scope)
        if kind == "FuncCall":
            return self.signature(node.name.name)[1]
        raise Unsupported(f"the type of a C expression {kind}")

    def constant(self, node):
        """(value, type) of an integer constant, typed as C types it (memoised)."""
        return self._memoised(("c", id(node)), lambda: self._constant(node))

    @staticmethod
    def _constant(node):
        if not set(node.type.split()) <= {"int", "long", "unsigned", "signed"}:
            raise Unsupported(f"a constant of type {node.type}")
        digits = node.value.lower().rstrip("ul")
        suffix, decimal = node.value.lower()[len(digits):], not digits.startswith("0") or digits == "0"
        value = int(digits, 8) if digits.startswith("0") and digits[1:2].isdigit() else int(digits, 0)
        bits = 32 if "l" not in suffix and value < 1 << (32 if "u" in suffix or not decimal else 31) else 64
        return value, ("int", not ("u" in suffix or (not decimal and value >= 1 << (bits - 1))), bits)

    def call(self, name: str, args: list):
        """`name`(args) as C calls it: the arguments converted to the parameters' types, then the
        summary of that name if there is one (given them in C's order), else the C itself."""
        params, result = self.signature(name)
        if len(params) != len(args):
            raise Unsupported(f"{name} called with {len(args)} arguments, defined with {len(params)}")
        args = [self.convert(a, t) for a, (_, t) in zip(args, params)]
        if name in self.summaries:
            value = self.summaries[name](*args)
        elif name not in self.functions:
            raise Unsupported(f"a call to {name}, which is not defined in rg_core.c")
        else:
            frame = Frame({p: a for (p, _), a in zip(params, args)})
            frame.types = dict(params)
            try:
                self.statement(self.functions[name].body, [frame])
                value = None
            except _Return as r:
                value = r.value
        return None if result == VOID else self.convert(value, result)

    def holder(self, scope: list, name: str) -> Frame:
        for frame in reversed(scope):
            if name in frame:
                return frame
        if name in self.global_decls:               # a file-scope constant, declared when first read
            if name not in self.globals:
                self.declare(self.global_decls[name], [self.globals], static=True)
            return self.globals
        raise Unsupported(f"an undeclared name {name}")

    def statement(self, node, scope: list) -> None:
        kind = type(node).__name__
        if kind == "Compound":
            inner = scope + [Frame()]
            for item in node.block_items or []:
                self.statement(item, inner)
        elif kind in ("Decl", "DeclList"):
            for d in node.decls if kind == "DeclList" else [node]:
                self.declare(d, scope)
        elif kind == "If":
            if truth(self.expr(node.cond, scope)):
                self.statement(node.iftrue, scope)
            elif node.iffalse is not None:
                self.statement(node.iffalse, scope)
        elif kind in ("For", "While"):
            self.loop(node, scope + [Frame()])
        elif kind == "Return":
            raise _Return(None if node.expr is None else self.expr(node.expr, scope))
        elif kind in ("Break", "Continue"):
            raise _Break() if kind == "Break" else _Continue()
        elif kind in EXPRESSIONS:
            self.expr(node, scope)
        elif kind != "EmptyStatement":
            raise Unsupported(f"a C statement {kind}")

    def loop(self, node, inner: list) -> None:
        if getattr(node, "init", None) is not None:
            self.statement(node.init, inner)
        for _ in range(10000):
            if node.cond is not None and not truth(self.expr(node.cond, inner)):
                return
            try:
                self.statement(node.stmt, inner)
            except _Break:
                return
            except _Continue:
                pass
            if getattr(node, "next", None) is not None:
                self.expr(node.next, inner)
        raise Unsupported("a loop of more than 10000 iterations")

    def declare(self, d: c_ast.Decl, scope: list, static: bool = False) -> None:
        if isinstance(d.type, c_ast.FuncDecl):
            return                                   # a prototype
        static = static or "static" in d.storage
        if static and "const" not in d.quals:
            raise Unsupported(f"a static variable {d.name} that is not const: state kept across calls")
        t = self.type_of(d.type)
        scope[-1][d.name] = self.blank(t, 0 if static else None) if d.init is None else self.initial(t, d.init, scope)
        scope[-1].types[d.name] = t

    def initial(self, t, init, scope: list):
        """A declaration's initialiser; what an initialiser list leaves out is 0, as in C."""
        if not isinstance(init, c_ast.InitList):
            if t[0] == "array":
                raise Unsupported(f"an array initialised by a {type(init).__name__}")
            return self.convert(self.expr(init, scope), t)
        if t[0] == "struct":
            names, parts = list(self.fields[t[1]]), [self.type_of(ft) for ft in self.fields[t[1]].values()]
        elif t[0] == "array":
            names, parts = None, [t[1]] * (t[2] or len(init.exprs))
        else:
            raise Unsupported(f"an initialiser list for a {t[0]}")
        if len(init.exprs) > len(parts):
            raise Unsupported("an initialiser list longer than its object")
        items = [self.initial(pt, e, scope) for pt, e in zip(parts, init.exprs)]
        items += [self.blank(pt, 0) for pt in parts[len(items):]]
        return Struct(zip(names, items)) if names else items

    def expr(self, node, scope: list):
        kind = type(node).__name__
        if kind == "Constant":
            return self.constant(node)[0]
        if kind in ("ID", "StructRef", "ArrayRef"):
            value = self.holder(scope, node.name)[node.name] if kind == "ID" else self.lvalue(node, scope).get()
            if value is None:
                raise Unsupported(f"{node.name if kind == 'ID' else kind} read before it is set")
            return value
        if kind == "BinaryOp":
            if node.op in ("&&", "||"):
                left = truth(self.expr(node.left, scope))
                return left if left == (node.op == "||") else truth(self.expr(node.right, scope))
            return self.binary(node.op, self.expr(node.left, scope), self.expr(node.right, scope),
                               self.stype(node.left, scope), self.stype(node.right, scope))
        if kind == "UnaryOp":
            return self.unary(node, scope)
        if kind == "TernaryOp":
            t = self.stype(node, scope)
            value = self.expr(node.iftrue if truth(self.expr(node.cond, scope)) else node.iffalse, scope)
            return self.convert(value, t) if t[0] == "int" else value
        if kind == "Cast":
            return self.convert(self.expr(node.expr, scope), self.type_of(node.to_type))
        if kind == "Assignment":
            ref, t = self.lvalue(node.lvalue, scope), self.stype(node.lvalue, scope)
            value = self.expr(node.rvalue, scope)
            if node.op != "=":
                value = self.binary(node.op[:-1], ref.get(), value, t, self.stype(node.rvalue, scope))
            ref.set(self.convert(value, t))
            return ref.get()
        if kind == "FuncCall":
            if not isinstance(node.name, c_ast.ID):
                raise Unsupported("a call through a function pointer")
            return self.call(node.name.name, [self.expr(a, scope) for a in (node.args.exprs if node.args else [])])
        raise Unsupported(f"a C expression {kind}")

    def binary(self, op: str, a, b, ta, tb):
        """a op b in C's types: the usual conversions, the result checked to fit its type."""
        a, b = number(a), number(b)
        if op in ("<<", ">>"):
            t = promote(ta)
            concrete(a, b)
            if a < 0 or not 0 <= b < t[2]:
                raise Unsupported(f"a shift of {a} by {b}: undefined or implementation-defined in C")
            return fit(a << b if op == "<<" else a >> b, t)
        t = common(ta, tb)
        if op in COMPARISONS:
            if not t[1]:                              # unsigned: a negative operand would wrap
                a, b = fit(a, t), fit(b, t)
            return COMPARISONS[op](a, b)
        if op not in ARITHMETIC:
            raise Unsupported(f"the operator {op}")
        return fit(ARITHMETIC[op](a, b), t)

    def unary(self, node, scope: list):
        op = node.op
        if op in ("&", "*"):
            ref = self.lvalue(node.expr if op == "&" else node, scope)
            return ref if op == "&" else ref.get()
        if op == "!":
            return not truth(self.expr(node.expr, scope))
        if op in ("-", "+"):
            v = number(self.expr(node.expr, scope))
            return fit(-v if op == "-" else v, promote(self.stype(node.expr, scope)))
        if op in ("p++", "++", "p--", "--"):
            ref, t = self.lvalue(node.expr, scope), self.stype(node.expr, scope)
            old = number(ref.get())
            ref.set(self.convert(old + (1 if "+" in op else -1), t))
            return old if op.startswith("p") else ref.get()
        raise Unsupported(f"the unary operator {op}")

    @staticmethod
    def element(base, index) -> Ref:
        """base[index] for an array (a list), a pointer into one, or a pointer to one object."""
        if isinstance(index, SymInt):
            raise Unsupported("a symbolic array index")
        if isinstance(base, Ref) and not isinstance(base.holder, list) and index == 0:
            return base
        if not isinstance(base, list) and not (isinstance(base, Ref) and isinstance(base.holder, list)):
            raise Unsupported(f"an index {index} into {type(base).__name__}: not an array")
        items, at = (base, index) if isinstance(base, list) else (base.holder, base.key + index)
        if not 0 <= at < len(items):
            raise Unsupported(f"an index {at} out of an array of {len(items)}")
        return Ref(items, at)

    def lvalue(self, node, scope: list) -> Ref:
        kind = type(node).__name__
        if kind == "ID":
            return Ref(self.holder(scope, node.name), node.name)
        if kind == "UnaryOp" and node.op == "*":
            return self.element(self.expr(node.expr, scope), 0)
        if kind == "StructRef":
            base = self.expr(node.name, scope)
            if node.type == "->" and isinstance(base, (Ref, list)):
                base = self.element(base, 0).get()
            if not isinstance(base, (Struct, ConfigView)):
                raise Unsupported(f"a field {node.field.name} of something that is not a struct")
            if isinstance(base, Struct) and node.field.name not in base:
                raise Unsupported(f"no field {node.field.name}")
            return Ref(base, node.field.name)
        if kind == "ArrayRef":
            return self.element(self.expr(node.name, scope), number(self.expr(node.subscript, scope)))
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
