"""Read and write Tony Cassandra's ``.pomdp`` text format.

pomdp-solve and SARSOP read this format, so writing it lets railguard models be
cross-checked by those solvers, and reading it lets their published examples
serve as fixtures. Reading is strict: every problem is a ``PomdpFormatError``
with a one-line ``where:line: what`` message, because a silently mis-read
model would be checked against the wrong physics.

Supported: the preamble (discount, values, states, actions, observations,
all start forms), T/O/R entries at every granularity with ``*`` wildcards,
names or indices, ``uniform``/``identity``. Not supported: solver-specific
extensions, a discount of 1 (``POMDP`` needs < 1), and ``POMDP.params``, which
the format has no place for (dropped on write).
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import NoReturn

import numpy as np

from .pomdp import POMDP, ModelError

SUM_TOLERANCE = 1e-5  # the format's convention for "sums to 1" (SARSOP's tolerance)
EXACT_TOLERANCE = 1e-12  # rows closer to 1 than this are left bit-for-bit alone
MAX_CELLS = 5 * 10**7  # refuse models whose dense arrays would need >400 MB
MAX_NAMES = 10**5  # largest count in a states:/actions:/observations: declaration

_PREAMBLE = ("discount", "values", "states", "actions", "observations")
_KEYWORDS = frozenset(_PREAMBLE + ("start", "T", "O", "R"))
_DIMS = {
    "T": ("actions", "states", "states"),
    "O": ("actions", "states", "observations"),
    "R": ("actions", "states", "states", "observations"),
}
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_TOKEN = re.compile(r"[^\s:]+|:")
_UNSAFE = re.compile(r"[\s:#]")


class PomdpFormatError(ValueError):
    """Text that is not a valid ``.pomdp`` model; ``line`` is where (None if no line applies)."""

    def __init__(self, message: str, line: int | None = None) -> None:
        super().__init__(message)
        self.line = line


# --------------------------------------------------------------------- reading


def read(path) -> POMDP:
    """Parse a ``.pomdp`` file; the model is named after the file stem."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise PomdpFormatError(f"{path}: cannot read file: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise PomdpFormatError(
            f"{path}:{line}: not UTF-8 text (byte 0x{data[exc.start]:02x})", line
        ) from None
    return _Parser(text, str(path)).parse(path.stem)


def loads(text: str, name: str = "pomdp") -> POMDP:
    """Parse ``.pomdp`` text; errors are reported as ``line N: ...``."""
    return _Parser(text, None).parse(name)


class _Parser:
    """Recursive descent over (token, line) pairs.

    The format is whitespace-insensitive, so the text is first cut into tokens
    (``:`` is always its own token); a data block runs until the next keyword
    followed by ``:``. Arrays are painted in file order so later entries win.
    """

    def __init__(self, text: str, source: str | None) -> None:
        self.source = source
        lines = text.split("\n")
        self.last_line = max(1, len(lines) - text.endswith("\n"))  # as editors number them
        self.toks = [
            (m.group(), n)
            for n, line in enumerate(lines, 1)
            for m in _TOKEN.finditer(line.split("#", 1)[0])
        ]
        self.pos = 0
        self.decl: dict[str, int] = {}  # preamble item -> line it was declared on
        self.names: dict[str, tuple[str, ...]] = {}
        self.lookup: dict[str, dict[str, int]] = {}
        self.discount = 0.0
        self.sign = 1.0
        self.b0: np.ndarray | None = None
        self.arrays: dict[str, np.ndarray] = {}  # "T", "O"
        self.lines: dict[str, np.ndarray] = {}  # line each (a, s) row was last written on
        self.rewards: list[tuple[list[np.ndarray], np.ndarray]] = []

    def fail(self, line: int, message: str) -> NoReturn:
        where = f"{self.source}:{line}" if self.source else f"line {line}"
        raise PomdpFormatError(f"{where}: {message}", line)

    # -- token helpers

    def _peek(self, k: int = 0) -> str | None:
        i = self.pos + k
        return self.toks[i][0] if i < len(self.toks) else None

    def _take(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.toks):
            self.fail(self.last_line, f"unexpected end of file, expected {what}")
        self.pos += 1
        return self.toks[self.pos - 1]

    def _colon(self) -> None:
        tok, line = self._take("':'")
        if tok != ":":
            self.fail(line, f"expected ':' but found {tok!r}")

    def _at_entry(self) -> bool:
        word, nxt = self._peek(), self._peek(1)
        return word in _KEYWORDS and nxt == ":" or word == "start" and nxt in ("include", "exclude")

    def _values(self) -> list[tuple[str, int]]:
        """The data tokens up to the next declaration or entry."""
        out = []
        while self.pos < len(self.toks) and not self._at_entry():
            tok, line = self._take("a value")
            if tok == ":":
                if out and not _NUMBER.fullmatch(out[-1][0]):  # e.g. a misspelt keyword
                    self.fail(out[-1][1], f"expected a declaration or entry, found {out[-1][0]!r}")
                self.fail(line, "unexpected ':'")
            out.append((tok, line))
        return out

    def _resolve(self, kind: str, tok: str, line: int) -> np.ndarray:
        """Indices named by a name, an integer index or ``*``."""
        if kind not in self.names:
            self.fail(line, f"{kind[:-1]} {tok!r} used before the '{kind}:' declaration")
        names = self.names[kind]
        if tok == "*":
            return np.arange(len(names))
        if tok in self.lookup[kind]:
            return np.array([self.lookup[kind][tok]])
        if tok.isdigit():
            if int(tok) < len(names):
                return np.array([int(tok)])
            self.fail(line, f"{kind[:-1]} index {tok} out of range (there are {len(names)} {kind})")
        self.fail(line, f"unknown {kind[:-1]} {tok!r}")

    def _number(self, tok: str, line: int, what: str) -> float:
        value = float(tok) if _NUMBER.fullmatch(tok) else float("nan")
        if not np.isfinite(value):
            self.fail(line, f"{what} {tok!r} is not a finite number")
        return value

    # -- top level

    def parse(self, name: str) -> POMDP:
        while self.pos < len(self.toks):
            if not self._at_entry():
                tok, line = self.toks[self.pos]
                self.fail(line, f"expected a declaration or entry, found {tok!r}")
            word, line = self._take("a keyword")
            if word == "start" and self._peek() in ("include", "exclude"):
                word = self._take("include/exclude")[0]
            self._colon()
            if word in _DIMS:
                self._entry(word, line)
            elif word in ("start", "include", "exclude"):
                self._start(word, line)
            else:
                if word in self.decl:
                    self.fail(line, f"'{word}:' declared twice (first on line {self.decl[word]})")
                self.decl[word] = line
                vals = self._values()
                if word == "discount":
                    self._discount(vals, line)
                elif word == "values":
                    self._reward_sign(vals, line)
                else:
                    self._names(word, vals, line)
        return self._finish(name)

    def _discount(self, vals, line) -> None:
        if len(vals) != 1:
            self.fail(line, f"discount: expects one number, found {len(vals)} values")
        self.discount = self._number(*vals[0], "discount")
        if not 0.0 <= self.discount < 1.0:
            self.fail(line, f"discount {self.discount} outside [0, 1)")

    def _reward_sign(self, vals, line) -> None:
        words = [t for t, _ in vals]
        if words not in (["reward"], ["cost"]):
            self.fail(line, f"values: must be 'reward' or 'cost', found {' '.join(words)!r}")
        self.sign = 1.0 if words == ["reward"] else -1.0

    def _names(self, kind, vals, line) -> None:
        words = [t for t, _ in vals]
        if len(words) == 1 and words[0].isdigit():
            count = int(words[0])
            if not 0 < count <= MAX_NAMES:
                self.fail(line, f"{kind}: count {count} must be between 1 and {MAX_NAMES}")
            words = [str(i) for i in range(count)]
        elif not words:
            self.fail(line, f"{kind}: needs a count or a list of names")
        lookup: dict[str, int] = {}
        for w in words:
            if w == "*" or w in lookup:
                self.fail(line, f"{kind}: name {w!r} is {'reserved' if w == '*' else 'repeated'}")
            lookup[w] = len(lookup)
        self.names[kind] = tuple(words)
        self.lookup[kind] = lookup

    def _start(self, word: str, line: int) -> None:
        if "states" not in self.names:
            self.fail(line, "start: before the 'states:' declaration")
        n = len(self.names["states"])
        vals = self._values()
        if not vals:
            self.fail(line, "start: needs a belief, 'uniform' or a state")
        if word in ("include", "exclude"):
            mask = np.zeros(n, dtype=bool)
            for tok, ln in vals:
                mask[self._resolve("states", tok, ln)] = True
            mask = mask if word == "include" else ~mask
            if not mask.any():
                self.fail(line, f"start {word}: leaves no states")
            b0 = mask / mask.sum()
        elif len(vals) == 1 and vals[0][0] == "uniform":
            b0 = np.full(n, 1.0 / n)
        elif len(vals) == 1 and self._names_a_state(vals[0][0], n):
            b0 = np.zeros(n)
            b0[self._resolve("states", *vals[0])] = 1.0
        else:
            if len(vals) != n:
                self.fail(line, f"start: expects {n} probabilities, found {len(vals)}")
            b0 = np.array([self._probability(tok, ln, "start") for tok, ln in vals])
            if abs(b0.sum() - 1.0) > SUM_TOLERANCE:
                self.fail(line, f"start belief sums to {b0.sum():.6g}, not 1")
            if abs(b0.sum() - 1.0) > EXACT_TOLERANCE:  # see _normalise
                b0 = b0 / b0.sum()
        self.b0 = b0

    def _names_a_state(self, tok: str, n: int) -> bool:
        """``start: tok`` is one state unless tok is a probability (only possible when n == 1)."""
        if tok.isdigit():
            return int(tok) < n
        return tok in self.lookup["states"] or not _NUMBER.fullmatch(tok)

    def _probability(self, tok: str, line: int, kind: str) -> float:
        p = self._number(tok, line, f"{kind} probability")
        if p < 0.0:
            self.fail(line, f"negative {kind} probability {tok}")
        if p > 1.0 + SUM_TOLERANCE:
            self.fail(line, f"{kind} probability {tok} is greater than 1")
        return p

    # -- T / O / R entries

    def _allocate(self, kind: str, line: int) -> None:
        """Create the arrays on the first entry; the preamble must be complete by then."""
        for item in ("states", "actions", "observations"):
            if item not in self.names:
                self.fail(line, f"{kind}: entry before the '{item}:' declaration")
        S, A, Z = (len(self.names[k]) for k in ("states", "actions", "observations"))
        if A * S * (S + Z) > MAX_CELLS or S * S * Z > MAX_CELLS:
            self.fail(line, f"model too large to read ({S} states, {A} actions, {Z} observations)")
        self.arrays = {"T": np.zeros((A, S, S)), "O": np.zeros((A, S, Z))}
        self.lines = {"T": np.zeros((A, S), dtype=int), "O": np.zeros((A, S), dtype=int)}

    def _entry(self, kind: str, line: int) -> None:
        if not self.arrays:
            self._allocate(kind, line)
        dims = _DIMS[kind]
        tok, ln = self._take(f"{dims[0][:-1]} after '{kind}:'")
        idx = [self._resolve(dims[0], tok, ln)]
        while len(idx) < len(dims) and self._peek() == ":":
            self.pos += 1
            what = dims[len(idx)]
            idx.append(self._resolve(what, *self._take(f"{what[:-1]} after ':'")))
        if kind == "R" and len(idx) < 2:
            self.fail(line, "R: needs at least 'R: action : state'")
        shape = tuple(len(self.names[d]) for d in dims[len(idx):])
        block, row_lines = self._block(kind, shape, line)
        idx += [np.arange(n) for n in shape]
        if kind == "R":
            self.rewards.append((idx, block))
        else:
            self.arrays[kind][np.ix_(*idx)] = block
            self.lines[kind][np.ix_(*idx[:2])] = row_lines

    def _block(self, kind: str, shape: tuple[int, ...], line: int):
        """The numbers after an entry header, shaped; plus the line of each row."""
        vals = self._values()
        prob = kind != "R"
        if prob and shape and len(vals) == 1 and vals[0][0] in ("uniform", "identity"):
            word, ln = vals[0]
            if word == "uniform":
                return np.full(shape, 1.0 / shape[-1]), ln
            if len(shape) != 2 or shape[0] != shape[1]:
                self.fail(ln, f"{kind}: 'identity' needs a square matrix")
            return np.eye(shape[0]), ln
        count = int(np.prod(shape))
        if len(vals) != count:
            form = "x".join(map(str, shape)) + (" matrix" if len(shape) == 2 else " row")
            expected = f"{count} numbers ({form})" if shape else "1 number"
            self.fail(line, f"{kind}: entry expects {expected}, found {len(vals)}")
        numbers = [
            self._probability(t, ln, kind) if prob else self._number(t, ln, "reward")
            for t, ln in vals
        ]
        row_len = shape[-1] if shape else 1
        row_lines = np.array([vals[i][1] for i in range(0, count, row_len)])
        return np.array(numbers).reshape(shape), row_lines if len(shape) == 2 else row_lines[0]

    # -- assembling the model

    def _normalise(self, kind: str, missing_row: str) -> np.ndarray:
        """Check each row against the format's 1e-5 and divide out the residue.

        Only rows off by more than 1e-12 are divided: a row normalised with
        numpy may sum to 1 +- an ulp, and dividing it again would change its
        last bits, so write-then-read would no longer be bit-identical. Such
        rows already pass ``POMDP``'s 1e-9 check untouched.
        """
        arr, lines = self.arrays[kind], self.lines[kind]
        acts, states = self.names["actions"], self.names["states"]
        missing = np.argwhere(lines == 0)
        if len(missing):
            a, s = missing[0]
            self.fail(self.decl["actions"], missing_row.format(acts[a], states[s]))
        sums = arr.sum(axis=-1)
        bad = np.abs(sums - 1.0) > SUM_TOLERANCE
        if bad.any():
            a, s = np.argwhere(bad & (lines == lines[bad].min()))[0]
            self.fail(
                lines[a, s],
                f"{kind} row for {acts[a]}/{states[s]} sums to {sums[a, s]:.6g}, not 1",
            )
        fix = np.abs(sums - 1.0) > EXACT_TOLERANCE
        arr[fix] /= sums[fix][:, None]
        return arr

    def _reduce_rewards(self, T: np.ndarray, O: np.ndarray) -> np.ndarray:
        """R[s, a] = E[R(a, s, s', o)] over s' ~ T and o ~ O, one action at a time.

        Where R does not vary over o (or s'), its expectation is that constant
        exactly; using it directly keeps ``R: a : s : * : * v`` bit-exact
        instead of picking up rounding from rows that sum to 1 +- an ulp.
        """
        A, S, Z = T.shape[0], T.shape[1], O.shape[2]
        R = np.zeros((S, A))
        for a in range(A):
            entries = [(idx, block) for idx, block in self.rewards if a in idx[0]]
            if not entries:
                continue
            full = np.zeros((S, S, Z))
            for idx, block in entries:
                full[np.ix_(*idx[1:])] = block
            inner = np.einsum("pz,spz->sp", O[a], full)
            inner = np.where((full == full[:, :, :1]).all(axis=2), full[:, :, 0], inner)
            outer = (T[a] * inner).sum(axis=1)
            R[:, a] = np.where((inner == inner[:, :1]).all(axis=1), inner[:, 0], outer)
        return R

    def _finish(self, name: str) -> POMDP:
        for item in ("discount", "states", "actions", "observations"):
            if item not in self.decl:
                self.fail(self.last_line, f"missing '{item}:' declaration")
        if not self.arrays:
            self._allocate("T", self.last_line)
        T = self._normalise("T", "no transition probabilities for action {} from state {}")
        O = self._normalise("O", "no observation probabilities for action {} into state {}")
        R = self.sign * self._reduce_rewards(T, O)
        S = len(self.names["states"])
        b0 = self.b0 if self.b0 is not None else np.full(S, 1.0 / S)
        try:
            return POMDP(
                name, self.names["states"], self.names["actions"], self.names["observations"],
                T, O, R, self.discount, b0,
            )
        except ModelError as exc:  # should not happen after the checks above
            self.fail(self.last_line, str(exc))


# --------------------------------------------------------------------- writing


def _writable(names: tuple[str, ...], kind: str) -> tuple[str, tuple[str, ...]]:
    """The ``kind:`` declaration and the names to reference in entries.

    Names are written as given except that whitespace, ':' and '#' (which would
    end a token or start a comment) become '_', and a name that is '*' or all
    digits gets a '_' prefix so it cannot be read as a wildcard or an index.
    Both are lossy; railguard's own names avoid them. Names "0".."n-1" are
    written as a count.
    """
    if names == tuple(str(i) for i in range(len(names))):
        return str(len(names)), names
    safe = tuple(
        "_" + n if n == "*" or n.isdigit() else _UNSAFE.sub("_", n) or "_" for n in names
    )
    if len(set(safe)) != len(safe):
        raise ValueError(f"{kind} names collide once made writable: {safe}")
    return " ".join(safe), safe


def dumps(model: POMDP) -> str:
    """The model as ``.pomdp`` text; floats use repr so reading back is bit-exact."""
    def num(x) -> str:
        return repr(float(x))

    def matrix(m) -> list[str]:
        return [" ".join(num(x) for x in row) for row in m]

    decls, refs = {}, {}
    for kind in ("states", "actions", "observations"):
        decls[kind], refs[kind] = _writable(getattr(model, kind), kind)
    title = " ".join(str(model.name).split())
    out = [
        f"# written by railguard: model {title}",
        "# R(s, a) is the expected immediate reward, written as R: a : s : * : *",
        *([f"# railguard's controllers also pay {num(model.release_cost)} each time they lower the action (not in this format)"]
          if model.release_cost else []),
        f"discount: {num(model.discount)}",
        "values: reward",
        *(f"{kind}: {decls[kind]}" for kind in decls),
        "start: " + " ".join(num(p) for p in model.b0),
    ]
    for a, act in enumerate(refs["actions"]):
        out += ["", f"T: {act}", *matrix(model.T[a])]
    for a, act in enumerate(refs["actions"]):
        out += ["", f"O: {act}", *matrix(model.O[a])]
    out.append("")
    for a, act in enumerate(refs["actions"]):
        for s, state in enumerate(refs["states"]):
            out.append(f"R: {act} : {state} : * : * {num(model.R[s, a])}")
    return "\n".join(out) + "\n"


def write(model: POMDP, path) -> None:
    """Write ``dumps(model)`` to ``path`` as UTF-8."""
    Path(path).write_text(dumps(model), encoding="utf-8")
