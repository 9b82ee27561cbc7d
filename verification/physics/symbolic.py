"""Run the shipped integer code on symbolic numbers, so that a proof is about that code.

`explore(fn, names, domain)` calls `fn` with `SymInt` arguments instead of integers; every
`+ - * //` builds a Z3 term, every comparison that a branch depends on asks the explorer,
which follows both sides where both are feasible (depth first, one run of `fn` per path).
The result is one `Path` per feasible path: its condition and the value `fn` returned there,
as Z3 terms over the inputs.

Integers are relaxed to reals, soundly: an input ranges over the reals of its interval, and
`x // c` (c > 0) becomes a fresh real q with c q <= x <= c q + c - 1 (the numerator is an
integer in every run of the code, which is what makes C's rounding-up idiom `(x + c - 1) / c`
provably at least x / c). Every integer run of `fn` is one of the relaxed runs, so a property
proved for every relaxed run holds for every integer input; Z3 then works in real arithmetic, which its nlsat procedure decides. (The relaxation
may, in principle, admit a counterexample no integer run has; the counterexample's replay
shows which it is.)

Only what braking.py uses is supported; anything else (a division by a symbolic number that
may be negative, a symbolic index) raises `Unsupported`, never a silent wrong answer.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Callable

import z3


class Unsupported(TypeError):
    """The code did something the symbolic run cannot follow soundly."""


class Explorer:
    """Chooses branch sides; each run of the function follows one path."""

    def __init__(self, domain: list, timeout_ms: int = 20000, cone: bool = False):
        self.domain = list(domain)
        self.cone = cone                     # check a branch against the constraints it depends on only
        self._vars: dict = {}
        self.side_conditions: list = []      # floor-division constraints, path-independent
        self.timeout_ms = timeout_ms
        self.forced: list[tuple[bool, bool, bool]] = []   # the prefix to replay, with its unexplored sides
        # (side taken, other side feasible and unexplored, both sides feasible: the condition is carried)
        self.taken: list[tuple[bool, bool, bool]] = []
        self.condition: list = []
        self._fresh = itertools.count()

    def fresh(self, hint: str) -> z3.ArithRef:
        return z3.Real(f"{hint}!{next(self._fresh)}")

    def variables(self, e) -> frozenset:
        key = e.get_id()
        if key not in self._vars:
            seen, todo, out = set(), [e], set()
            while todo:
                t = todo.pop()
                if t.get_id() in seen:
                    continue
                seen.add(t.get_id())
                if z3.is_const(t) and t.decl().kind() == z3.Z3_OP_UNINTERPRETED:
                    out.add(t.decl().name())
                todo.extend(t.children())
            self._vars[key] = (e, frozenset(out))        # (e kept alive: Z3 reuses a freed term's id)
        return self._vars[key][1]

    def relevant(self, extra) -> list:
        """The constraints that share variables with `extra`, transitively (its cone of
        influence). Leaving the others out can only find more branch sides feasible: an
        extra path, whose full condition the proof then refutes or finds infeasible; sound."""
        pool = [*self.domain, *self.side_conditions, *self.condition]
        names, chosen, grew = set(self.variables(extra)), [], True
        left = list(pool)
        while grew:
            grew, rest = False, []
            for c in left:
                vs = self.variables(c)
                if vs & names:
                    names |= vs
                    chosen.append(c)
                    grew = True
                else:
                    rest.append(c)
            left = rest
        return chosen

    def feasible(self, extra) -> bool:
        s = z3.Solver()
        s.set("timeout", self.timeout_ms)
        s.add(*(self.relevant(extra) if self.cone else [*self.domain, *self.side_conditions, *self.condition]), extra)
        result = s.check()
        if result == z3.unknown:
            return True                      # cannot rule it out: follow it (sound)
        return result == z3.sat

    def decide(self, cond) -> bool:
        i = len(self.taken)
        if i < len(self.forced):
            side, _, needed = self.forced[i]
            self.taken.append(self.forced[i])
        else:
            can_true, can_false = self.feasible(cond), self.feasible(z3.Not(cond))
            if not (can_true or can_false):
                if not self.cone:
                    raise Unsupported("a branch with neither side feasible: the path condition is inconsistent")
                can_true = True              # an infeasible path the cone let in: followed, vacuous
            side = can_true
            needed = can_true and can_false       # else the side taken is implied: no need to carry it
            self.taken.append((side, needed, needed))
        if needed:
            self.condition.append(cond if side else z3.Not(cond))
        return side

    def next_path(self) -> bool:
        """Set up the next run: flip the deepest branch whose other side is still unexplored."""
        for i in range(len(self.taken) - 1, -1, -1):
            side, other, _ = self.taken[i]
            if other:
                self.forced = self.taken[:i] + [(not side, False, True)]
                self.taken, self.condition = [], []
                return True
        return False


def _term(x):
    if isinstance(x, SymInt):
        return x.term
    if isinstance(x, bool):
        raise Unsupported("a bool used as a number")
    if isinstance(x, int):
        return z3.RealVal(x)
    raise Unsupported(f"{type(x).__name__} in symbolic arithmetic")


class SymBool:
    def __init__(self, ex: Explorer, term):
        self.ex, self.term = ex, term

    def __bool__(self) -> bool:
        return self.ex.decide(self.term)

    # a flag compared as a value (a sort key such as `(near == NO_TRACK, near)`): decided first
    def __eq__(self, o): return bool(self) == bool(o)      # type: ignore[override]
    def __ne__(self, o): return bool(self) != bool(o)      # type: ignore[override]
    def __lt__(self, o): return bool(self) < bool(o)
    def __le__(self, o): return bool(self) <= bool(o)
    def __gt__(self, o): return bool(self) > bool(o)
    def __ge__(self, o): return bool(self) >= bool(o)
    __hash__ = None                                           # type: ignore[assignment]


class SymInt:
    """An integer-valued input or intermediate, as a Z3 real term (relaxed, see module doc)."""

    def __init__(self, ex: Explorer, term):
        self.ex, self.term = ex, term

    def _new(self, term) -> "SymInt":
        return SymInt(self.ex, term)

    def __add__(self, o): return self._new(self.term + _term(o))
    def __radd__(self, o): return self._new(_term(o) + self.term)
    def __sub__(self, o): return self._new(self.term - _term(o))
    def __rsub__(self, o): return self._new(_term(o) - self.term)
    def __mul__(self, o): return self._new(self.term * _term(o))
    def __rmul__(self, o): return self._new(_term(o) * self.term)
    def __neg__(self): return self._new(-self.term)
    def __pos__(self): return self

    def __floordiv__(self, o):
        return floor_div(self.ex, self.term, o)

    def __rfloordiv__(self, o):
        return floor_div(self.ex, _term(o), self)

    def __lt__(self, o): return SymBool(self.ex, self.term < _term(o))
    def __le__(self, o): return SymBool(self.ex, self.term <= _term(o))
    def __gt__(self, o): return SymBool(self.ex, self.term > _term(o))
    def __ge__(self, o): return SymBool(self.ex, self.term >= _term(o))
    def __eq__(self, o): return SymBool(self.ex, self.term == _term(o))   # type: ignore[override]
    def __ne__(self, o): return SymBool(self.ex, self.term != _term(o))   # type: ignore[override]
    __hash__ = None                                                       # type: ignore[assignment]

    def __index__(self):
        raise Unsupported("a symbolic number used as an index or a concrete int")

    __int__ = __index__


def floor_div(ex: Explorer, x, d) -> SymInt:
    """x // d for a divisor that is positive on this path: a fresh q with d q <= x < d q + d."""
    if isinstance(d, SymInt):
        if not d > 0:                         # a branch: the path where d <= 0 is refused below
            raise Unsupported("a division by a number that may be zero or negative")
        dt = d.term
    elif isinstance(d, int) and not isinstance(d, bool):
        if d <= 0:
            raise Unsupported(f"a division by {d}")
        dt = z3.RealVal(d)
    else:
        raise Unsupported(f"a division by {type(d).__name__}")
    q = ex.fresh("q")
    # the numerator is an integer in every run of the code: d q <= x <= d q + d - 1
    ex.side_conditions += [dt * q <= x, x <= dt * q + dt - 1]
    return SymInt(ex, q)


@dataclass
class Path:
    condition: list          # Z3 booleans over the inputs (and the division variables)
    side: list               # the floor-division constraints this path's terms use
    value: object            # what fn returned, with SymInt replaced by Z3 terms


def _unwrap(v):
    if isinstance(v, SymInt):
        return v.term
    if isinstance(v, tuple):
        return type(v)(*(_unwrap(x) for x in v)) if hasattr(v, "_fields") else tuple(_unwrap(x) for x in v)
    if isinstance(v, int) and not isinstance(v, bool):
        return z3.RealVal(v)
    return v


def explore(fn: Callable, inputs: dict, domain: list, max_paths: int = 4096, timeout_ms: int = 20000,
            cone: bool = False) -> list[Path]:
    """Every feasible path of fn(**args), where `inputs` maps argument names to Z3 reals or to
    concrete values and `domain` constrains the reals (their ranges). `cone`: decide each
    branch on the constraints it depends on (Explorer.relevant): more paths, each cheaper."""
    ex = Explorer(domain, timeout_ms, cone)
    paths = []
    while True:
        ex.side_conditions = []
        ex._fresh = itertools.count()        # the same names along a shared prefix: paths comparable
        args = {k: SymInt(ex, v) if isinstance(v, z3.ArithRef) else v for k, v in inputs.items()}
        value = fn(**args)
        paths.append(Path(list(ex.condition), list(ex.side_conditions), _unwrap(value)))
        if len(paths) > max_paths:
            raise Unsupported(f"more than {max_paths} paths")
        if not ex.next_path():
            return paths
