"""Compile alpha vectors into a finite-state controller and evaluate it exactly.

A controller is `action[node]`, `next[node][obs]` and a start node. It is built by
following witness beliefs (DESIGN.md section 6), improved by re-pointing edges to the
node with the best exact value at the successor belief, pruned to what the start node
reaches and minimised (bisimilar nodes merged). Its value is computed by solving
(I - g P) v = r over (node, state) pairs, so the number we ship is exact, not the
solver's estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pomdp import POMDP
from .solver import Solution, successor_beliefs


@dataclass(frozen=True)
class Controller:
    action: np.ndarray   # (N,) int
    next: np.ndarray     # (N, Z) int
    start: int

    @property
    def nodes(self) -> int:
        return int(self.action.shape[0])


@dataclass(frozen=True)
class Compiled:
    controller: Controller
    values: np.ndarray      # (N, S) exact value of starting in node n, state s
    value: float            # value at the model's start belief
    naive_value: float      # value of the witness-following controller before improvement
    improvement_rounds: int


def closed_loop_matrix(model: POMDP, ctrl: Controller) -> tuple[sp.csr_matrix, np.ndarray]:
    """P[(n, s), (m, s')] and r[(n, s)] of the Markov chain the controller induces.

    Index (n, s) is n * S + s. P sums T[a_n, s, s'] * O[a_n, s', o] over the observations o
    with next[n, o] == m.
    """
    S, A, Z = model.shape
    N = ctrl.nodes
    rows, cols, vals = [], [], []
    for n in range(N):
        a = int(ctrl.action[n])
        # W[s', m] = sum over o with next[n, o] == m of O[a, s', o]
        W = np.zeros((S, N))
        np.add.at(W.T, ctrl.next[n], model.O[a].T)
        s_idx, t_idx = np.nonzero(model.T[a])
        tv = model.T[a][s_idx, t_idx]
        Wt = W[t_idx]                       # (nnzT, N)
        k, m = np.nonzero(Wt)
        rows.append(n * S + s_idx[k])
        cols.append(m * S + t_idx[k])
        vals.append(tv[k] * Wt[k, m])
    P = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N * S, N * S)
    )
    r = model.R[np.tile(np.arange(S), N), np.repeat(ctrl.action, S)]
    return P, r


DIRECT_SOLVE_LIMIT = 6000  # (node, state) pairs up to which a sparse LU is cheaper than GMRES


def evaluate(model: POMDP, ctrl: Controller, tol: float = 1e-12) -> np.ndarray:
    """Exact values V[n, s]: the solution of (I - g P) v = r.

    Small systems use a sparse LU; large ones GMRES on the operator v -> (I - g P) v applied
    without forming P (for Model 2, P has tens of millions of non-zeros). The residual is
    checked either way, so a returned value is a solution to `tol` relative to the rewards.
    """
    S = model.shape[0]
    N = ctrl.nodes
    if N * S <= DIRECT_SOLVE_LIMIT:
        P, r = closed_loop_matrix(model, ctrl)
        M = sp.identity(N * S, format="csc") - model.discount * P.tocsc()
        v = np.asarray(spla.spsolve(M, r))
    else:
        r = model.R[np.tile(np.arange(S), N), np.repeat(ctrl.action, S)]
        T_n = model.T[ctrl.action]                    # (N, S, S)
        O_n = model.O[ctrl.action]                    # (N, S, Z)
        g = model.discount

        def apply(v: np.ndarray) -> np.ndarray:
            V = v.reshape(N, S)
            # W[n, s'] = sum_o O[a_n, s', o] V[next[n, o], s']
            W = np.einsum("nzt,ntz->nt", V[ctrl.next], O_n)
            return v - g * np.matmul(T_n, W[:, :, None]).ravel()

        op = spla.LinearOperator((N * S, N * S), matvec=apply, dtype=np.float64)
        v, info = spla.gmres(op, r, rtol=tol, atol=0.0, restart=200, maxiter=50)
        M = op
    scale = max(1.0, float(np.abs(r).max()))
    residual = float(np.abs(M @ v - r).max())
    if not residual <= 1e-8 * scale:
        raise ArithmeticError(f"controller evaluation did not converge (residual {residual:.3g})")
    return v.reshape(N, S)


def follow_witnesses(model: POMDP, sol: Solution) -> Controller:
    """Node k acts as alpha k; on observation o go to the best alpha at tau(witness_k, a_k, o)."""
    Z = model.shape[2]
    nxt = np.zeros((len(sol.alphas), Z), dtype=np.int64)
    for k, (b, a) in enumerate(zip(sol.witnesses, sol.actions)):
        succ, _ = successor_beliefs(model, b, int(a))
        nxt[k] = (succ @ sol.alphas.T).argmax(axis=1)
    start = int((sol.alphas @ model.b0).argmax())
    return Controller(sol.actions.astype(np.int64), nxt, start)


def improve(model: POMDP, ctrl: Controller, beliefs: np.ndarray, max_rounds: int = 20):
    """Re-point each edge to the node with the best exact value at its successor belief.

    Repeated while the value at b0 rises; the best controller seen is kept.
    Returns (controller, values, rounds).
    """
    V = evaluate(model, ctrl)
    best = (float((V @ model.b0).max()), ctrl, V)
    succ = [successor_beliefs(model, beliefs[n], int(ctrl.action[n]))[0] for n in range(ctrl.nodes)]
    rounds = 0
    for rounds in range(1, max_rounds + 1):
        nxt = np.stack([(succ[n] @ V.T).argmax(axis=1) for n in range(ctrl.nodes)])
        start = int((V @ model.b0).argmax())
        cand = Controller(ctrl.action, nxt, start)
        if np.array_equal(nxt, ctrl.next) and start == ctrl.start:
            break
        ctrl = cand
        V = evaluate(model, ctrl)
        value = float(V[ctrl.start] @ model.b0)
        if value > best[0] + 1e-12 * max(1.0, abs(best[0])):
            best = (value, ctrl, V)
        else:
            break
    return best[1], best[2], rounds


def reachable(ctrl: Controller) -> Controller:
    """Keep the nodes the start node can reach, renumbered in breadth-first order."""
    order = [ctrl.start]
    index = {ctrl.start: 0}
    i = 0
    while i < len(order):
        for m in ctrl.next[order[i]]:
            m = int(m)
            if m not in index:
                index[m] = len(order)
                order.append(m)
        i += 1
    remap = np.vectorize(index.get, otypes=[np.int64])
    return Controller(ctrl.action[order], remap(ctrl.next[order]), 0)


def minimise(ctrl: Controller) -> Controller:
    """Merge nodes that behave the same (Moore partition refinement); start stays node 0."""
    block = ctrl.action.copy()
    while True:
        sig = np.column_stack([block, block[ctrl.next]])
        _, new_block = np.unique(sig, axis=0, return_inverse=True)
        new_block = new_block.ravel()
        if len(np.unique(new_block)) == len(np.unique(block)):
            break
        block = new_block
    # one representative per block, in order of first appearance
    reps, first = np.unique(block, return_index=True)
    order = np.sort(first)
    block_to_new = {int(block[n]): i for i, n in enumerate(order)}
    action = ctrl.action[order]
    nxt = np.vectorize(lambda n: block_to_new[int(block[n])], otypes=[np.int64])(ctrl.next[order])
    return reachable(Controller(action, nxt, block_to_new[int(block[ctrl.start])]))


def occupancy(model: POMDP, ctrl: Controller, iterations: int = 200) -> np.ndarray:
    """Discounted expected visits of each node from (start, b0), by iterating x = e + g P^T x.

    Used only to rank nodes, so a truncated iteration (error g^iterations) is enough.
    """
    S, _, Z = model.shape
    N = ctrl.nodes
    T_n = model.T[ctrl.action]
    O_n = model.O[ctrl.action]                                  # (N, S, Z)
    edges = sp.csr_matrix((np.ones(N * Z), (ctrl.next.ravel(), np.arange(N * Z))), shape=(N, N * Z))
    e = np.zeros((N, S))
    e[ctrl.start] = model.b0
    x = e.copy()
    for _ in range(iterations):
        Y = np.matmul(x[:, None, :], T_n)[:, 0, :]                 # (N, S'): mass after moving
        flows = (Y[:, :, None] * O_n).transpose(0, 2, 1).reshape(N * Z, S)
        x = e + model.discount * (edges @ flows)
    return x.sum(axis=1)


def restrict(model: POMDP, ctrl: Controller, V: np.ndarray, beliefs: np.ndarray, keep: np.ndarray):
    """Keep only the nodes in `keep` (and the start); edges into dropped nodes go to the kept
    node with the best value at the successor belief. Returns (controller, kept node ids)."""
    keep = np.unique(np.append(keep, ctrl.start))
    new_index = {int(n): i for i, n in enumerate(keep)}
    nxt = np.zeros((len(keep), model.shape[2]), dtype=np.int64)
    for i, n in enumerate(keep):
        succ, _ = successor_beliefs(model, beliefs[n], int(ctrl.action[n]))
        best = keep[(succ @ V[keep].T).argmax(axis=1)]
        row = np.where(np.isin(ctrl.next[n], keep), ctrl.next[n], best)
        nxt[i] = [new_index[int(m)] for m in row]
    return Controller(ctrl.action[keep], nxt, new_index[ctrl.start]), keep


def compile_controller(model: POMDP, sol: Solution, improve_rounds: int = 20, max_nodes: int = 255) -> Compiled:
    """Witness-following controller, improved, cut to the `max_nodes` most visited nodes
    (improved again), pruned, minimised and evaluated exactly."""
    naive = follow_witnesses(model, sol)
    naive_V = evaluate(model, naive)
    naive_value = float(naive_V[naive.start] @ model.b0)
    ctrl, V, rounds = improve(model, naive, sol.witnesses, improve_rounds)
    beliefs = sol.witnesses
    if reachable(ctrl).nodes > max_nodes:
        visits = occupancy(model, ctrl)
        keep = np.argsort(-visits, kind="stable")[: max_nodes - 1]
        ctrl, kept = restrict(model, ctrl, V, beliefs, keep)
        ctrl, V, more = improve(model, ctrl, beliefs[kept], improve_rounds)
        rounds += more
    ctrl = minimise(reachable(ctrl))
    V = evaluate(model, ctrl)
    return Compiled(ctrl, V, float(V[ctrl.start] @ model.b0), naive_value, rounds)
