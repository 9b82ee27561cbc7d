"""Compile alpha vectors into a finite-state controller and evaluate it exactly.

A controller is `action[node]`, `next[node][obs]` and a start node; during compilation
each node also carries the belief it stands for. The compiler

1. follows witness beliefs (DESIGN.md section 6): node k acts as alpha k and on
   observation o goes to the best alpha at the Bayes successor of its witness;
2. improves it by point-based policy iteration: evaluate exactly, re-point every edge to
   the node with the best exact value at the successor belief, add a backed-up node
   wherever a one-step lookahead on the exact values beats every node (at the solver's
   belief points and at the beliefs the nodes are really visited with), prune to what the
   start node reaches, cut to a node budget by visit frequency, merge bisimilar nodes;
   a round is kept only if the exact value at b0 rises;
3. evaluates the result exactly: (I - g P) v = r over (node, state) pairs.

So the value we ship is exact, never the solver's estimate.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .pomdp import POMDP
from .solver import Solution

CHUNK = 64  # beliefs per vectorised lookahead block (bounds memory at CHUNK x Z x N)


@dataclass(frozen=True)
class Controller:
    action: np.ndarray                     # (N,) int
    next: np.ndarray                       # (N, Z) int
    start: int
    beliefs: Optional[np.ndarray] = None   # (N, S) belief each node stands for (compile time only)

    @property
    def nodes(self) -> int:
        return int(self.action.shape[0])

    @classmethod
    def of_table(cls, table) -> "Controller":
        """The controller a compiled table (monitor.core.table.Table) runs: its actions, next
        nodes and start node, without the compile-time beliefs."""
        return cls(np.asarray(table.action, dtype=np.int64), np.asarray(table.next, dtype=np.int64), int(table.start))

    def subset(self, order: np.ndarray, remap: np.ndarray, start: int) -> "Controller":
        """Nodes `order` (old ids) renumbered by `remap[old] = new`."""
        beliefs = None if self.beliefs is None else self.beliefs[order]
        return Controller(self.action[order], remap[self.next[order]], start, beliefs)


@dataclass(frozen=True)
class Compiled:
    controller: Controller
    values: np.ndarray      # (N, S) exact value of starting in node n, state s
    value: float            # value at the model's start belief
    naive_value: float      # value of the witness-following controller before improvement
    improvement_rounds: int


# ----------------------------------------------------------------------------- evaluation

DIRECT_SOLVE_LIMIT = 6000  # (node, state) pairs up to which a sparse LU is cheaper than GMRES


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
        W = np.zeros((S, N))  # W[s', m] = sum of O[a, s', o] over o with next[n, o] == m
        np.add.at(W.T, ctrl.next[n], model.O[a].T)
        s_idx, t_idx = np.nonzero(model.T[a])
        tv = model.T[a][s_idx, t_idx]
        Wt = W[t_idx]
        k, m = np.nonzero(Wt)
        rows.append(n * S + s_idx[k])
        cols.append(m * S + t_idx[k])
        vals.append(tv[k] * Wt[k, m])
    P = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N * S, N * S)
    )
    return P, rewards(model, ctrl)


def rewards(model: POMDP, ctrl: Controller) -> np.ndarray:
    """r[(n, s)]: R[s, a_n], less the model's release cost (paid one step later, so
    discounted) times the probability that the next node demands less."""
    S = model.shape[0]
    r = model.R[np.tile(np.arange(S), ctrl.nodes), np.repeat(ctrl.action, S)]
    if model.release_cost:
        changes = ctrl.action[ctrl.next] < ctrl.action[:, None]                      # (N, Z)
        p = np.stack([model.T[a] @ (model.O[a] @ changes[n]) for n, a in enumerate(ctrl.action)])
        r = r - model.discount * model.release_cost * p.ravel()
    return r


def release_penalty(model: POMDP, node_action: Optional[np.ndarray], a: int) -> Optional[np.ndarray]:
    """(N,) cost of moving to each node after acting a: the release cost where the node
    demands less than a (None: no release cost)."""
    if not model.release_cost or node_action is None:
        return None
    return model.release_cost * (np.asarray(node_action) < a)


@dataclass(frozen=True)
class EdgeWeights:
    """The controller's edges aggregated by target: for each (node n, next node m) pair l,
    w[l, s'] = sum of O[a_n, s', o] over the observations o with next[n, o] == m.

    Nodes reach few distinct next nodes, so the L pairs are far fewer than N x Z edges:
    this makes one application of P (or P^T) cost L x S instead of N x Z x S.
    """

    src: np.ndarray     # (L,) node n, sorted
    dst: np.ndarray     # (L,) next node m
    w: np.ndarray       # (L, S)
    src_starts: np.ndarray  # reduceat offsets of each node's pairs

    @staticmethod
    def of(model: POMDP, ctrl: Controller) -> "EdgeWeights":
        S = model.shape[0]
        src, dst, w = [], [], []
        for n in range(ctrl.nodes):
            targets, inverse = np.unique(ctrl.next[n], return_inverse=True)
            wn = np.zeros((len(targets), S))
            np.add.at(wn, inverse.ravel(), model.O[ctrl.action[n]].T)
            src.append(np.full(len(targets), n))
            dst.append(targets)
            w.append(wn)
        src_a, dst_a = np.concatenate(src), np.concatenate(dst)
        return EdgeWeights(src_a, dst_a, np.vstack(w), np.flatnonzero(np.r_[True, src_a[1:] != src_a[:-1]]))


def _by_action(model: POMDP, ctrl: Controller, X: np.ndarray, transpose: bool) -> np.ndarray:
    """Row n of X times T[a_n] (transpose=False: X @ T, mass moving) or T[a_n] @ row (values)."""
    out = np.empty_like(X)
    for a in np.unique(ctrl.action):
        idx = ctrl.action == a
        out[idx] = X[idx] @ (model.T[a].T if transpose else model.T[a])
    return out


def evaluate(model: POMDP, ctrl: Controller, tol: float = 1e-12, guess: Optional[np.ndarray] = None) -> np.ndarray:
    """Exact values V[n, s]: the solution of (I - g P) v = r.

    Small systems use a sparse LU; large ones GMRES on the operator v -> (I - g P) v applied
    without forming P (for Model 2, P has tens of millions of non-zeros). The residual is
    checked either way, so a returned value solves the system to 1e-8 of the reward scale.
    `guess` (N, S), the values of a controller that differs little, starts GMRES near the answer.
    """
    S = model.shape[0]
    N = ctrl.nodes
    r = rewards(model, ctrl)
    if N * S <= DIRECT_SOLVE_LIMIT:
        P, _ = closed_loop_matrix(model, ctrl)
        M = sp.identity(N * S, format="csc") - model.discount * P.tocsc()
        v = np.asarray(spla.spsolve(M, r))
    else:
        E = EdgeWeights.of(model, ctrl)
        g = model.discount

        def apply(v: np.ndarray) -> np.ndarray:
            V = v.reshape(N, S)
            W = np.add.reduceat(E.w * V[E.dst], E.src_starts, axis=0)   # (N, S')
            return v - g * _by_action(model, ctrl, W, transpose=True).ravel()

        M = spla.LinearOperator((N * S, N * S), matvec=apply, dtype=np.float64)
        x0 = None if guess is None else guess.ravel()
        v, _ = spla.gmres(M, r, x0=x0, rtol=tol, atol=0.0, restart=200, maxiter=50)
    scale = max(1.0, float(np.abs(r).max()))
    residual = float(np.abs(M @ v - r).max())
    if not residual <= 1e-8 * scale:
        raise ArithmeticError(f"controller evaluation did not converge (residual {residual:.3g})")
    return v.reshape(N, S)


def plain_value(model: POMDP, ctrl: Controller) -> float:
    """The exact value at b0 on the objective the alpha vectors (and SARSOP) optimise: the
    model's rewards without the release cost the table pays on top. The lower bound is
    compared with this value, never with the table's own (issue 41: the compilation loss)."""
    plain = replace(model, release_cost=0.0) if model.release_cost else model
    return value_at(plain, ctrl, evaluate(plain, ctrl))


def compilation_loss_percent(lower_bound: float, plain: float) -> float:
    """How far below the alpha policy's guaranteed value (the lower bound at b0) the table is,
    in % of |lower bound|, on the same objective; negative when the table is worth more."""
    return 100.0 * (lower_bound - plain) / max(1e-12, abs(lower_bound))


def value_at(model: POMDP, ctrl: Controller, V: np.ndarray) -> float:
    return float(V[ctrl.start] @ model.b0)


def occupancy(model: POMDP, ctrl: Controller, iterations: int = 80, guess: Optional[np.ndarray] = None) -> np.ndarray:
    """Discounted expected visits x[n, s] of (node, state) from (start, b0): x = e + g P^T x.

    Used to rank nodes and to find the belief a node is really visited with, so a truncated
    iteration (relative error g^iterations, 1.6 % for Model 1's and 2's g = 0.95) is enough.
    From `guess` (the visits of a controller that differs little) it stops once no entry
    moves by 1e-4 of the largest.
    """
    S = model.shape[0]
    N = ctrl.nodes
    E = EdgeWeights.of(model, ctrl)
    e = np.zeros((N, S))
    e[ctrl.start] = model.b0
    x = e.copy() if guess is None else guess
    into = sp.csr_matrix((np.full(len(E.dst), model.discount), (E.dst, np.arange(len(E.dst)))), shape=(N, len(E.dst)))
    for _ in range(iterations):
        Y = _by_action(model, ctrl, x, transpose=False)           # mass after moving, (N, S')
        last, x = x, e + into @ (Y[E.src] * E.w)
        if guess is not None and np.abs(x - last).max() <= 1e-4 * np.abs(x).max():
            break
    return x


# ----------------------------------------------------------------------------- lookahead

def lookahead(model: POMDP, V: np.ndarray, beliefs: np.ndarray, a: int,
              node_action: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """For action a at each belief: (one-step value on V, best next node per observation).

    Observations impossible at a belief go to the best node for the predicted belief.
    With the nodes' actions given, moving to a node that demands less pays the model's
    release cost.
    """
    S, A, Z = model.shape
    q = np.zeros(len(beliefs))
    nxt = np.zeros((len(beliefs), Z), dtype=np.int64)
    penalty = release_penalty(model, node_action, a)
    for lo in range(0, len(beliefs), CHUNK):
        b = beliefs[lo:lo + CHUNK]
        pred = b @ model.T[a]                                   # (P, S)
        unnorm = pred[:, None, :] * model.O[a].T[None, :, :]    # (P, Z, S): p(o) * tau(b, a, o)
        vals = (unnorm.reshape(-1, S) @ V.T).reshape(len(b), Z, -1)  # p(o) * value of each node
        if penalty is not None:
            vals = vals - unnorm.sum(axis=2)[:, :, None] * penalty[None, None, :]
        pick = vals.argmax(axis=2)
        impossible = unnorm.sum(axis=2) <= 0.0
        if impossible.any():
            fallback = (pred @ V.T).argmax(axis=1)
            pick = np.where(impossible, fallback[:, None], pick)
        nxt[lo:lo + CHUNK] = pick
        q[lo:lo + CHUNK] = b @ model.R[:, a] + model.discount * vals.max(axis=2).sum(axis=1)
    return q, nxt


def backup_nodes(model: POMDP, V: np.ndarray, beliefs: np.ndarray,
                 node_action: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best (action, edges, value) at each belief; ties go to the later, stronger-braking action."""
    best_q = np.full(len(beliefs), -np.inf)
    best_a = np.zeros(len(beliefs), dtype=np.int64)
    best_n = np.zeros((len(beliefs), model.shape[2]), dtype=np.int64)
    for a in range(model.shape[1]):
        q, nxt = lookahead(model, V, beliefs, a, node_action)
        better = q >= best_q - 1e-12 * np.maximum(1.0, np.abs(q))
        best_q = np.where(better, q, best_q)
        best_a[better] = a
        best_n[better] = nxt[better]
    return best_a, best_n, best_q


# ----------------------------------------------------------------------------- structure

def follow_witnesses(model: POMDP, sol: Solution) -> Controller:
    """Node k acts as alpha k; on observation o go to the best alpha at tau(witness_k, a_k, o)."""
    start = int((sol.alphas @ model.b0).argmax())
    ctrl = Controller(sol.actions.astype(np.int64), np.zeros((len(sol.alphas), model.shape[2]), dtype=np.int64),
                      start, sol.witnesses)
    return replace(ctrl, next=lookahead_all(model, sol.alphas, ctrl)[1])


# the policy graph is compiled only while its closure has at most this many (node, state)
# pairs: choosing its nodes needs the visits of each (m2's full model, 30 s: 10,969 nodes x
# 144 states, 18 s of occupancy)
GRAPH_PAIRS_LIMIT = 4_000_000


def graph_controller(model: POMDP, sol: Solution, max_nodes: int) -> tuple[Optional[Controller], str]:
    """The solver's policy graph from the node of the best vector at b0 (policy_graph.py: worth
    at least the lower bound there), merged; beyond `max_nodes`, the nodes whose loss would
    cost most kept (select_nodes) and edges into the others re-pointed by the nodes' vectors.
    (None, why) if the solver keeps no graph or it is too large to compile."""
    if sol.graph is None or sol.graph_nodes is None:
        return None, "this solver method keeps none"
    start = sol.graph_nodes[int((sol.alphas @ model.b0).argmax())]
    action, nxt, ids = sol.graph.closure(int(start))
    if len(action) * model.shape[0] > GRAPH_PAIRS_LIMIT:
        return None, f"{len(action)} nodes, over {GRAPH_PAIRS_LIMIT:,} (node, state) pairs: not used"
    ctrl = Controller(action, nxt, 0)
    if len(action) > max_nodes:
        ctrl = select_nodes(model, ctrl, sol.graph.vectors(ids), sol.graph.witnesses(ids), max_nodes)
    ctrl = minimise(ctrl)
    return replace(ctrl, beliefs=node_beliefs(model, ctrl)[0]), ""


def select_nodes(model: POMDP, ctrl: Controller, vectors: np.ndarray, witnesses: np.ndarray,
                 max_nodes: int) -> Controller:
    """At most `max_nodes` nodes of a policy graph, chosen greedily: each node stands for the
    belief it is visited with (its witness if never visited), and the next node kept is the
    one whose visits x (its vector's value there - the best kept vector's value there) is
    largest. Edges into dropped nodes go to the kept node whose vector is best at the
    successor belief. Cutting by visits alone keeps only the busy no-brake nodes (m2: a
    table that never brakes, -17.0 against a lower bound of -0.15)."""
    beliefs, mass = node_beliefs(model, ctrl)
    beliefs = np.where(mass[:, None] > 1e-9, beliefs, witnesses)
    own = np.einsum("ns,ns->n", vectors, beliefs)
    keep, best = [ctrl.start], beliefs @ vectors[ctrl.start]
    while len(keep) < max_nodes:
        loss = mass * (own - best)
        n = int(np.argmax(loss))
        if loss[n] <= 1e-12 * max(1.0, abs(float(own[n]))):
            break
        keep.append(n)
        best = np.maximum(best, beliefs @ vectors[n])
    keep = np.sort(np.array(keep, dtype=np.int64))
    remap = np.full(ctrl.nodes, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    kept = Controller(ctrl.action[keep], ctrl.next[keep], int(remap[ctrl.start]), beliefs[keep])
    _, repointed = lookahead_all(model, vectors[keep], kept)
    stay = remap[kept.next] >= 0
    return reachable(replace(kept, next=np.where(stay, remap[kept.next], repointed)))


def lookahead_all(model: POMDP, V: np.ndarray, ctrl: Controller) -> tuple[np.ndarray, np.ndarray]:
    """At each node's belief, acting as the node does: (one-step value on V (N,), the best
    next node per observation (N, Z))."""
    value, nxt = np.zeros(ctrl.nodes), ctrl.next.copy()
    for a in np.unique(ctrl.action):
        idx = np.flatnonzero(ctrl.action == a)
        value[idx], nxt[idx] = lookahead(model, V, ctrl.beliefs[idx], int(a), ctrl.action)
    return value, nxt


def repoint(model: POMDP, ctrl: Controller, V: np.ndarray) -> Controller:
    """Every edge to the node with the best exact value at its node's successor belief."""
    return replace(ctrl, next=lookahead_all(model, V, ctrl)[1], start=int((V @ model.b0).argmax()))


def reachable(ctrl: Controller) -> Controller:
    """Keep the nodes the start node can reach, renumbered in breadth-first order."""
    order = [ctrl.start]
    seen = np.full(ctrl.nodes, -1, dtype=np.int64)
    seen[ctrl.start] = 0
    i = 0
    while i < len(order):
        for m in np.unique(ctrl.next[order[i]]):
            if seen[m] < 0:
                seen[m] = len(order)
                order.append(int(m))
        i += 1
    return ctrl.subset(np.array(order), seen, 0)


def minimise(ctrl: Controller) -> Controller:
    """Merge nodes that behave the same (Moore partition refinement); start becomes node 0."""
    block = np.unique(ctrl.action, return_inverse=True)[1].ravel()
    while True:
        sig = np.column_stack([block, block[ctrl.next]])
        new_block = np.unique(sig, axis=0, return_inverse=True)[1].ravel()
        if new_block.max() == block.max():
            break
        block = new_block
    _, first = np.unique(block, return_index=True)
    order = np.sort(first)                       # one representative per block
    block_to_new = np.empty(len(order), dtype=np.int64)
    block_to_new[block[order]] = np.arange(len(order))
    merged = ctrl.subset(order, block_to_new[block], int(block_to_new[block[ctrl.start]]))
    return reachable(merged)


def cut(model: POMDP, ctrl: Controller, V: np.ndarray, max_nodes: int) -> Controller:
    """Keep the `max_nodes` most visited nodes; edges into dropped nodes are re-pointed to the
    kept node with the best value at the successor belief."""
    visits = occupancy(model, ctrl).sum(axis=1)
    keep = np.unique(np.append(np.argsort(-visits, kind="stable")[: max_nodes - 1], ctrl.start))
    remap = np.full(ctrl.nodes, -1, dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    kept = Controller(ctrl.action[keep], ctrl.next[keep], int(remap[ctrl.start]), ctrl.beliefs[keep])
    sub = repoint(model, kept, V[keep])
    # edges that already led to a kept node stay as they were
    stay = remap[kept.next] >= 0
    return replace(sub, next=np.where(stay, remap[kept.next], sub.next), start=int(remap[ctrl.start]))


def grow(model: POMDP, ctrl: Controller, V: np.ndarray, points: np.ndarray) -> tuple[Controller, int]:
    """Add a backed-up node at every point where a one-step lookahead on the exact values
    beats every node (Hansen-style policy improvement, at points). Its successors are old
    nodes, whose values do not change, so the value at that point rises."""
    now = (points @ V.T).max(axis=1)
    act, nxt, q = backup_nodes(model, V, points, ctrl.action)
    better = np.flatnonzero(q > now + 1e-9 * np.maximum(1.0, np.abs(now)))
    if len(better) == 0:
        return ctrl, 0
    _, first = np.unique(np.column_stack([act[better], nxt[better]]), axis=0, return_index=True)
    chosen = better[np.sort(first)]
    grown = Controller(
        np.concatenate([ctrl.action, act[chosen]]),
        np.vstack([ctrl.next, nxt[chosen]]),
        ctrl.start,
        np.vstack([ctrl.beliefs, points[chosen]]),
    )
    return grown, len(chosen)


def node_beliefs(model: POMDP, ctrl: Controller) -> tuple[np.ndarray, np.ndarray]:
    """(the belief each node is really visited with: its normalised discounted occupancy,
    the node's visit mass); rows of nodes never visited are zero."""
    x = occupancy(model, ctrl)
    mass = x.sum(axis=1)
    return x / np.maximum(mass, 1e-300)[:, None], mass


def visited_beliefs(model: POMDP, ctrl: Controller) -> np.ndarray:
    """The beliefs of the nodes that are visited at all."""
    beliefs, mass = node_beliefs(model, ctrl)
    return beliefs[mass > 1e-6]


def settle(model: POMDP, ctrl: Controller, max_nodes: int) -> tuple[Controller, np.ndarray]:
    """Re-point, prune, cut to budget and minimise; returns the controller and its exact values."""
    V = evaluate(model, ctrl)
    ctrl = reachable(repoint(model, ctrl, V))
    V = evaluate(model, ctrl)
    if ctrl.nodes > max_nodes:
        ctrl = reachable(cut(model, ctrl, V, max_nodes))
        V = evaluate(model, ctrl)
    ctrl = minimise(ctrl)
    return ctrl, evaluate(model, ctrl)


def out_of_time(deadline: Optional[float]) -> bool:
    return deadline is not None and time.perf_counter() >= deadline


@dataclass(frozen=True)
class Candidate:
    """A controller the compiler may start from, with its exact values and how it was made."""

    value: float
    controller: Controller
    values: np.ndarray
    origin: str


def candidates(model: POMDP, sol: Solution, max_nodes: int, say: Callable[[str], None]) -> tuple[list[Candidate], float]:
    """The controllers compilation starts from, best first: the witness-following controller
    re-pointed within the budget (or tidied, when it fits and is worth more), and the solver's
    policy graph within the budget (graph_controller); and the witness controller's value."""
    naive = follow_witnesses(model, sol)
    naive_V = evaluate(model, naive)
    naive_value = value_at(model, naive, naive_V)
    say(f"compile: witness controller, {naive.nodes} nodes, exact value {naive_value:.4f}")
    ctrl, V = settle(model, naive, max_nodes)
    found = [Candidate(value_at(model, ctrl, V), ctrl, V, "witnesses")]
    say(f"compile: re-pointed within {max_nodes} nodes: {ctrl.nodes} nodes, exact value {found[0].value:.4f}")
    if naive.nodes <= max_nodes and naive_value > found[0].value:
        # pruning and merging keep the value exactly: the witness controller, tidied, is the start
        tidy = minimise(reachable(naive))
        tidy_V = evaluate(model, tidy)
        found[0] = Candidate(value_at(model, tidy, tidy_V), tidy, tidy_V, "witnesses")
    graph, why = graph_controller(model, sol, max_nodes)
    if graph is None:
        say(f"compile: the solver's policy graph: {why}")
    else:
        graph_V = evaluate(model, graph)
        found.append(Candidate(value_at(model, graph, graph_V), graph, graph_V, "policy graph"))
        say(f"compile: the solver's policy graph, {graph.nodes} nodes, exact value {found[-1].value:.4f}")
    return sorted(found, key=lambda c: -c.value), naive_value


def compile_controller(model: POMDP, sol: Solution, max_nodes: int = 255, rounds: int = 12,
                       progress: Optional[Callable[[str], None]] = None, deadline: Optional[float] = None) -> Compiled:
    """The best of the candidates, improved by point-based policy iteration within the
    node budget; every round is kept only if the exact value at b0 rises. `progress`
    receives one line per step. No new round starts after `deadline` (time.perf_counter()):
    the best controller so far is kept, so a time budget bounds the compilation too."""
    say = progress or (lambda text: None)
    found, naive_value = candidates(model, sol, max_nodes, say)
    best = (found[0].value, found[0].controller, found[0].values)
    done = 0
    for done in range(1, rounds + 1):
        if out_of_time(deadline):
            say(f"compile: time budget reached, stopping before round {done}")
            done -= 1
            break
        ctrl, V = best[1], best[2]
        points = np.vstack([model.b0[None, :], sol.beliefs, visited_beliefs(model, ctrl)])
        grown, added = grow(model, ctrl, V, points)
        if not added:
            break
        cand, cand_V = settle(model, grown, max_nodes)
        value = value_at(model, cand, cand_V)
        gained = value > best[0] + 1e-9 * max(1.0, abs(best[0]))
        say(f"compile: round {done}, {added} nodes added, {cand.nodes} kept, exact value {value:.4f}"
            + ("" if gained else " (no gain, stop)"))
        if not gained:
            break
        best = (value, cand, cand_V)
    value, ctrl, V = best
    say(f"compile: final controller, {ctrl.nodes} nodes, exact value {value:.4f}")
    return Compiled(replace(ctrl, beliefs=None), V, value, naive_value, done)
