"""Upper bound on V* kept as corner values plus a set of (belief, value) points.

The value at a belief is the sawtooth interpolation (Hauskrecht 2000, as in HSVI2 and
SARSOP) of the points over the corners, capped by the fast informed bound (FIB):

    saw(b) = min( c.b,  min_i  c.b + r_i(b) (v_i - c.b_i) ),   r_i(b) = min_{s in supp b_i} b(s) / b_i(s)

with c[s] >= V*(e_s) the corner values. It is an upper bound because V* is convex: b is
r_i b_i plus a non-negative rest, whose value is at most its corner interpolation. The
solver drops negligible belief entries (`truncate`) before backing a belief up: the point
stored is the truncated belief, with a value backed up at exactly that belief.

Points are stored sparsely (their support only): evaluating N beliefs costs N x the total
support of the points, never a dense (N, P, S) tensor. The model is touched through
`Dynamics`, which does one Bayes step per action without forming T x O for all (a, o).
"""
from __future__ import annotations

import contextlib
import ctypes

import numpy as np
import scipy.sparse as sp

from .pomdp import POMDP

TRUNCATE = 1e-6           # belief entries below this (times the largest) are dropped
EVAL_CHUNK = 4_000_000    # max (beliefs x stored support) products in one block
SPARSE_T_BELOW = 0.15     # per-action T stored sparse when its density is below this


def _openblas_thread_controls() -> list:
    """(get, set) thread-count functions of every OpenBLAS loaded in this process (Linux)."""
    found = []
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            paths = sorted({line.split()[-1] for line in maps if "openblas" in line.lower() and "/" in line})
    except OSError:
        return found
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for suffix in ("64_", "_64_", ""):
            for prefix in ("scipy_openblas", "openblas"):
                get = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
                put = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                if get is not None and put is not None:
                    found.append((get, put))
                    break
            else:
                continue
            break
    return found


@contextlib.contextmanager
def single_threaded_blas():
    """Run the block with one BLAS thread. The solver's products are small (Z x S by S x K):
    a second thread only adds hand-over costs, and on a loaded 2-core machine OpenBLAS's
    spinning threads made one 144 x 144 x 70 product take 8 ms instead of 0.05 ms."""
    controls = _openblas_thread_controls()
    before = [get() for get, _ in controls]
    for _, put in controls:
        put(1)
    try:
        yield
    finally:
        for (_, put), n in zip(controls, before):
            put(max(1, n))


class Dynamics:
    """Per-action products with T and O: one Bayes step and one backward step.

    Memory is O(A S^2) at most (T itself, sparse when it is sparse) plus O(A S Z) for O:
    the (A, Z, S, S) kernel T*O is never formed.
    """

    def __init__(self, model: POMDP):
        S, A, Z = model.shape
        self.S, self.A, self.Z = S, A, Z
        self.g = model.discount
        self.R = np.ascontiguousarray(model.R.T)                      # (A, S)
        self.OT = [np.ascontiguousarray(model.O[a].T) for a in range(A)]   # (Z, S')
        self.O = [model.O[a] for a in range(A)]                       # (S', Z)
        dense = (model.T > 0).mean() >= SPARSE_T_BELOW
        self.T = [model.T[a] if dense else sp.csr_matrix(model.T[a]) for a in range(A)]
        self.TT = [model.T[a].T.copy() if dense else sp.csr_matrix(model.T[a].T) for a in range(A)]

    def predict(self, B: np.ndarray, a: int) -> np.ndarray:
        """B @ T[a] for beliefs B (N, S) or one belief (S,)."""
        return np.asarray((self.TT[a] @ B.T).T)

    def back(self, a: int, W: np.ndarray) -> np.ndarray:
        """T[a] @ W: expected next-state values, W of shape (S,) or (S, K)."""
        return np.asarray(self.T[a] @ W)

    def joint(self, b: np.ndarray, a: int) -> np.ndarray:
        """u[o, s'] = P(s', o | b, a): its rows are p(o) times the successor beliefs."""
        return self.predict(b, a)[None, :] * self.OT[a]


def truncate(B: np.ndarray) -> np.ndarray:
    """Drop negligible entries and renormalise rows (keeps stored supports small)."""
    B = np.where(B > TRUNCATE * B.max(axis=-1, keepdims=True), B, 0.0)
    return B / B.sum(axis=-1, keepdims=True)


def fib_apply(dyn: Dynamics, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One FIB backup: (H Q (A, S), greedy choice[a, s, o] of the next action a')."""
    A, S, Z = dyn.A, dyn.S, dyn.Z
    HQ = np.empty_like(Q)
    choice = np.empty((A, S, Z), dtype=np.int64)
    for a in range(A):
        # M[s', o, a'] = O[a, s', o] Q[a', s'];  inner[s, o, a'] = T[a] @ M
        M = dyn.O[a][:, :, None] * Q.T[:, None, :]
        inner = dyn.back(a, M.reshape(S, -1)).reshape(S, Z, A)
        choice[a] = inner.argmax(axis=2)
        HQ[a] = dyn.R[a] + dyn.g * np.take_along_axis(inner, choice[a][:, :, None], axis=2)[:, :, 0].sum(axis=1)
    return HQ, choice


def fib_choice_matrix(dyn: Dynamics, choice: np.ndarray, limit: int = 20_000_000):
    """P[(a, s), (a', s')] = sum of T[a, s, s'] O[a, s', o] over o with choice[a, s, o] = a'
    (sparse), or None when it would hold more than `limit` entries before summing."""
    A, S = dyn.A, dyn.S
    rows, cols, vals, total = [], [], [], 0
    for a in range(A):
        Ta = sp.coo_matrix(dyn.T[a])
        Oa = dyn.O[a][Ta.col]                                  # (nnz, Z)
        total += Oa.size
        if total > limit:
            return None
        v = Ta.data[:, None] * Oa
        keep = v > 0
        rows.append((a * S + np.repeat(Ta.row[:, None], Oa.shape[1], axis=1))[keep])
        cols.append((choice[a][Ta.row] * S + Ta.col[:, None])[keep])
        vals.append(v[keep])
    n = A * S
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))


def fast_informed_q(dyn: Dynamics, tol: float = 1e-7, max_iter: int = 100000, deadline: float | None = None,
                    clock=None) -> np.ndarray:
    """Q[a, s] of the fast informed bound (Hauskrecht 2000), an upper bound on V*.

    Q_a(s) = R(s, a) + g sum_o max_a' sum_s' T(s, a, s') O(s', a, o) Q_a'(s'). It is the
    value of an MDP over (a, s) whose decision picks a' per (a, s, o), so policy iteration
    finds it in a few sparse solves where value iteration needs hundreds of sweeps at
    g = 0.95. The result is certified: if H Q <= Q + d then the fixed point is at most
    Q + d / (1 - g), which is what is returned. Value iteration from Rmax / (1 - g) is the
    fallback (too many entries, no convergence); its iterates stay above the fixed point,
    so stopping at the deadline still gives a valid, looser bound.
    """
    import scipy.sparse.linalg as spla

    A, S, g = dyn.A, dyn.S, dyn.g
    scale = max(1.0, float(np.abs(dyn.R).max()))
    over = (lambda: False) if deadline is None else (lambda: clock() >= deadline)
    Q = np.full((A, S), dyn.R.max() / (1.0 - g))
    HQ, choice = fib_apply(dyn, Q)
    eye = sp.identity(A * S, format="csc")
    for _ in range(60):
        P = fib_choice_matrix(dyn, choice)
        if P is None or over():
            break
        Qp = np.asarray(spla.spsolve((eye - g * P).tocsc(), dyn.R.ravel())).reshape(A, S)
        HQ, new_choice = fib_apply(dyn, Qp)
        Q = Qp
        if np.array_equal(new_choice, choice):
            break
        choice = new_choice
    residual = float((HQ - Q).max())
    Q = Q + max(residual, 0.0) / (1.0 - g)          # H Q <= Q: an upper bound on the fixed point
    if float(np.abs(HQ - Q).max()) <= tol * scale:
        return Q
    for _ in range(max_iter):                          # value iteration from above
        Qn, _ = fib_apply(dyn, Q)
        delta = float(np.abs(Qn - Q).max())
        Q = Qn
        if delta * g / (1.0 - g) <= tol * scale or over():
            break
    return Q


class UpperBound:
    """Corner values, FIB Q and a growing set of sparse (belief, value) points."""

    def __init__(self, fib_q: np.ndarray):
        self.fib_q = np.asarray(fib_q, dtype=np.float64)
        self.corner = self.fib_q.max(axis=0).copy()       # V(e_s) <= max_a Q_FIB(a, s)
        self.S = self.corner.shape[0]
        self._reset([], [])

    # ------------------------------------------------------------------ storage

    def _reset(self, beliefs: list, values: list) -> None:
        """Rebuild the packed supports: idx (nnz,), inv = 1 / b_i(s) (nnz,), starts (P,)."""
        self._beliefs, self._values = list(beliefs), list(values)
        supp = [np.flatnonzero(b) for b in self._beliefs]
        self._idx = np.concatenate(supp) if supp else np.zeros(0, dtype=np.int64)
        self._inv = np.concatenate([1.0 / b[s] for b, s in zip(self._beliefs, supp)]) if supp else np.zeros(0)
        self._starts = np.cumsum([0] + [len(x) for x in supp[:-1]]).astype(np.int64) if supp else np.zeros(0, np.int64)
        self._nnz = len(self._idx)
        self._slack = np.array(self._values) - (np.array(self._beliefs) @ self.corner if supp else 0.0)

    def _append(self, b: np.ndarray, value: float) -> None:
        """Add one point to the packed arrays (amortised doubling, no repacking)."""
        nz = np.flatnonzero(b)
        need = self._nnz + len(nz)
        if need > len(self._idx):
            grow = max(need, 2 * len(self._idx), 1024)
            self._idx = np.concatenate([self._idx[: self._nnz], np.zeros(grow - self._nnz, dtype=np.int64)])
            self._inv = np.concatenate([self._inv[: self._nnz], np.zeros(grow - self._nnz)])
        self._idx[self._nnz:need] = nz
        self._inv[self._nnz:need] = 1.0 / b[nz]
        self._starts = np.append(self._starts, self._nnz)
        self._nnz = need
        self._slack = np.append(self._slack, value - float(b @ self.corner))
        self._beliefs.append(np.array(b, dtype=np.float64))
        self._values.append(float(value))

    @property
    def size(self) -> int:
        return len(self._values)

    @property
    def beliefs(self) -> np.ndarray:
        return np.array(self._beliefs) if self._beliefs else np.zeros((0, self.S))

    @property
    def values(self) -> np.ndarray:
        return np.array(self._values)

    def over(self, beliefs, values) -> "UpperBound":
        """The same corners and fast informed bound over other (belief, value) points."""
        other = UpperBound(self.fib_q)
        other.corner = self.corner.copy()
        other._reset(list(beliefs), list(values))
        return other

    def add(self, b: np.ndarray, value: float) -> bool:
        """Store (b, value) if it tightens the bound at b; a one-hot b tightens a corner."""
        now = float(self.value(b[None, :])[0])
        if not value < now - 1e-12 * max(1.0, abs(now)):
            return False
        nz = np.flatnonzero(b)
        if len(nz) == 1:
            self.corner[nz[0]] = value
            self._reset(self._beliefs, self._values)           # every slack v_i - c.b_i moves
        else:
            self._append(b, value)
        return True

    # ------------------------------------------------------------------ evaluation

    def ratios(self, B: np.ndarray) -> np.ndarray:
        """r[n, i] = min over supp(b_i) of B[n, s] / b_i(s), in blocks of bounded size."""
        N, nnz = B.shape[0], self._nnz
        idx, inv = self._idx[:nnz], self._inv[:nnz]
        out = np.empty((N, self.size))
        step = max(1, EVAL_CHUNK // max(1, nnz))
        for lo in range(0, N, step):
            block = B[lo:lo + step][:, idx]
            block *= inv
            out[lo:lo + step] = np.minimum.reduceat(block, self._starts, axis=1)
        return out

    def sawtooth(self, B: np.ndarray) -> np.ndarray:
        """Sawtooth interpolation of the points over the corners at beliefs B (N, S)."""
        B = np.atleast_2d(B)
        base = B @ self.corner
        if self.size == 0:
            return base
        return np.minimum(base, base + (self.ratios(B) * self._slack[None, :]).min(axis=1))

    def fib(self, B: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(B) @ self.fib_q.T).max(axis=1)

    def value(self, B: np.ndarray) -> np.ndarray:
        """The upper bound: the smaller of the sawtooth and the fast informed bound."""
        return np.minimum(self.sawtooth(B), self.fib(B))

    def joint_value(self, U: np.ndarray, sig: float = 1.0) -> np.ndarray:
        """p(o) * upper(b_o) for rows U[o] = p(o) b_o (unnormalised successors).

        The sawtooth is evaluated at the likeliest rows covering all but 1 - `sig` of the
        mass; the rest get the (looser, still valid) FIB and corner bounds, which are linear
        and so cost nothing to scale by p(o).
        """
        p = U.sum(axis=1)
        out = np.minimum(U @ self.corner, (U @ self.fib_q.T).max(axis=1))
        live = np.flatnonzero(p > 0)
        if self.size == 0 or len(live) == 0:
            return out
        if sig < 1.0:
            order = live[np.argsort(-p[live], kind="stable")]
            mass = np.cumsum(p[order])
            keep = order[: int(np.searchsorted(mass, sig * mass[-1])) + 1]
        else:
            keep = live
        out[keep] = np.minimum(out[keep], p[keep] * self.sawtooth(U[keep] / p[keep, None]))
        return out

    def backup(self, dyn: "Dynamics", b: np.ndarray, sig: float = 1.0):
        """upper_backup at b (the solver calls the bound's own, momdp.py has another)."""
        return upper_backup(dyn, self, b, sig)

    # ------------------------------------------------------------------ maintenance

    def prune(self) -> int:
        """Drop points the others (with corners and FIB) already bound as tightly; returns
        how many were dropped. Points are tested newest first against the survivors."""
        if self.size < 2:
            return 0
        vals = np.array(self._values)
        B = np.array(self._beliefs)
        keep = np.ones(self.size, dtype=bool)
        R = self.ratios(B)                                   # R[i, j]: point j evaluated at b_i
        base = B @ self.corner
        lin = np.minimum(base, self.fib(B))
        for i in range(self.size - 1, -1, -1):               # newest first
            others = keep.copy()
            others[i] = False
            cand = base[i] + (R[i, others] * self._slack[others]).min() if others.any() else np.inf
            if min(cand, lin[i]) <= vals[i] + 1e-12 * max(1.0, abs(vals[i])):
                keep[i] = False
        dropped = int((~keep).sum())
        if dropped:
            self._reset([b for b, k in zip(self._beliefs, keep) if k], [v for v, k in zip(self._values, keep) if k])
        return dropped


def upper_backup(dyn: Dynamics, ub: UpperBound, b: np.ndarray, sig: float = 1.0):
    """Q_upper(b, a) = R(b, a) + g sum_o p(o) upper(b_o) for every a, with the pieces.

    Returns (q (A,), joints [U_a], upper_joint [(Z,)]).
    """
    q = np.empty(dyn.A)
    joints, uj = [], []
    for a in range(dyn.A):
        U = dyn.joint(b, a)
        v = ub.joint_value(U, sig)
        q[a] = float(b @ dyn.R[a]) + dyn.g * float(v.sum())
        joints.append(U)
        uj.append(v)
    return q, joints, uj


def lower_backup(dyn: Dynamics, alphas: np.ndarray, b: np.ndarray, joints: list):
    """Point-based Bellman backup of the alpha vectors at b: (vector, action, value, lower
    joints, the vector chosen per observation for that action).

    For each action the observation's best vector is the argmax of alpha . U[o]; the new
    vector is R_a + g T_a (sum_o O[a, :, o] * alpha_{k_o}). Ties go to the later action.
    """
    best = (None, -1, -np.inf, None)
    lj = []
    for a in range(dyn.A):
        scores = joints[a] @ alphas.T                       # (Z, K)
        pick = scores.argmax(axis=1)
        lj.append(scores[np.arange(len(pick)), pick])
        W = (dyn.O[a] * alphas[pick].T).sum(axis=1)         # (S',)
        vec = dyn.R[a] + dyn.g * dyn.back(a, W)
        val = float(b @ vec)
        if val >= best[2] - 1e-12 * max(1.0, abs(best[2])):
            best = (vec, a, val, pick)
    return best[0], best[1], best[2], lj, best[3]
