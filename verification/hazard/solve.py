"""P[FN] of the module chain, exactly: a sparse linear solve on the embedded jump chain
(`p_fn`), eq. (4) the long way round (`eq4`), back substitution in topological order for
many parameter sets at once (`p_fn_many`, `p_fn_grid`), and seed 002's eq. (5) for the
3oo3 hazard rate (`hazard_rate`).
"""
from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .ctmc import ACTIONS, Chain, ModuleParams, build_chain
from .numbers import LAMBDA_OD, P_RANGE


def _embedded(chain: Chain, p: ModuleParams) -> sp.csr_matrix:
    """Jump-chain probabilities P[s, s'] = R[s, s'] / E(s) (absorbing rows stay zero)."""
    f = p.factors()
    fv = np.array([f[k] for k in chain.keys])[chain.key_idx]
    rv = np.array([p.rate(a) for a in chain.action])
    n = len(chain.states)
    R = sp.csr_matrix((rv * fv, (chain.src, chain.dst)), shape=(n, n))
    exit_rate = np.asarray(R.sum(axis=1)).ravel()
    inv = np.divide(1.0, exit_rate, out=np.zeros(n), where=exit_rate > 0)
    return sp.diags(inv) @ R


def reach_fin(p: ModuleParams) -> tuple[np.ndarray, Chain]:
    """x[s] = probability of eventually reaching a fin state from s (linear solve)."""
    chain = build_chain(p.guards, p.degraded, p.fin)
    P = _embedded(chain, p).tocsr()
    T = np.flatnonzero(~chain.absorbing)
    b = np.asarray(P[T][:, np.flatnonzero(chain.fin)].sum(axis=1)).ravel()
    A = sp.identity(len(T), format="csc") - P[T][:, T].tocsc()
    x = np.zeros(len(chain.states))
    x[chain.fin] = 1.0
    x[T] = spla.spsolve(A, b)
    return x, chain


def p_fn(p: ModuleParams) -> float:
    """P[FN] = P(F fin) from the initial state."""
    x, _ = reach_fin(p)
    return float(x[0])


def eq4(p: ModuleParams) -> tuple[float, float]:
    """Seed 002 eq. (4): sum over S_od of P(s0 -> F s) * P(s -> F fin), and P(s0 -> F fin)."""
    x, chain = reach_fin(p)
    P = _embedded(chain, p).tocsr()
    T = np.flatnonzero(~chain.absorbing)
    A = sp.identity(len(T), format="csc") - P[T][:, T].tocsc()
    e0 = np.zeros(len(T))
    e0[0] = 1.0
    visits = spla.spsolve(A.T.tocsc(), e0)         # expected visits = P(reach) in this acyclic chain
    pos = {s: k for k, s in enumerate(T)}
    total = sum(visits[pos[s]] * x[s] for s in chain.od)
    return float(total), float(x[0])


def grid_values(n: int) -> list[Fraction]:
    lo, hi = P_RANGE
    return [lo + (hi - lo) * Fraction(k, n - 1) for k in range(n)]


def _topological(chain: Chain) -> list[int] | None:
    """States in topological order (Kahn), or None if the chain has a cycle."""
    n = len(chain.states)
    indeg = np.bincount(chain.dst, minlength=n)
    succ: list[list[int]] = [[] for _ in range(n)]
    for a, b in zip(chain.src, chain.dst):
        succ[a].append(b)
    todo = [s for s in range(n) if indeg[s] == 0]
    order = []
    while todo:
        s = todo.pop()
        order.append(s)
        for t in succ[s]:
            indeg[t] -= 1
            if indeg[t] == 0:
                todo.append(t)
    return order if len(order) == n else None


def p_fn_many(points: list[ModuleParams]) -> np.ndarray:
    """P[FN] for many parameter sets sharing one chain structure, all at once.

    The chain is acyclic (stages only increase), so (I - P_TT) x = P_T,fin is triangular in
    topological order: back substitution, vectorised over the parameter sets. Falls back to
    one sparse solve per point if the structure has a cycle.
    """
    p0 = points[0]
    chain = build_chain(p0.guards, p0.degraded, p0.fin)
    order = _topological(chain)
    if order is None:
        return np.array([p_fn(p) for p in points])
    fvals = np.array([[p.factors()[k] for k in chain.keys] for p in points]).T     # keys x G
    act_idx = np.array([ACTIONS.index(a) for a in chain.action])
    rates = np.array([[p.rate(a) for a in ACTIONS] for p in points]).T[act_idx]   # E x G
    W = rates * fvals[chain.key_idx]                                                # E x G
    n = len(chain.states)
    exit_rate = np.zeros((n, len(points)))
    np.add.at(exit_rate, chain.src, W)
    W = W / exit_rate[chain.src]
    by_src = np.argsort(chain.src, kind="stable")
    starts = np.searchsorted(chain.src[by_src], np.arange(n + 1))
    x = np.zeros((n, len(points)))
    x[chain.fin] = 1.0
    for s in reversed(order):
        e = by_src[starts[s]:starts[s + 1]]
        if len(e):
            x[s] = (W[e] * x[chain.dst[e]]).sum(axis=0)
    return x[0]


def p_fn_grid(pn: list, pc: list, base: ModuleParams = ModuleParams()) -> np.ndarray:
    """Z[i, j] = P[FN] at p_n = pn[j], p_c = pc[i] (rows: p_c, columns: p_n)."""
    pts = [replace(base, p_n=float(nn), p_c=float(c)) for c in pc for nn in pn]
    return p_fn_many(pts).reshape(len(pc), len(pn))


def hazard_rate(pfn, lam: float = LAMBDA_OD):
    """Seed 002 eq. (5): HR(3oo3) = lambda_od * P[FN]^3."""
    return lam * np.asarray(pfn) ** 3 if isinstance(pfn, np.ndarray) else lam * pfn ** 3
