"""Point-based POMDP solvers with a certified gap: HSVI (default), Perseus and PBVI.

The lower bound is a set of alpha vectors; each keeps the belief it was backed up at (its
witness) and its action, which the compiler follows to build a finite-state controller.
The upper bound (monitor/offline/bounds.py) is the fast informed bound, tightened by a
sawtooth point set that HSVI backs up along its trials: the printed gap UB - LB at b0 is
what certifies the table. Perseus and PBVI keep the fast informed bound alone.

HSVI (Smith & Simmons 2004, 2005): trials from b0 descend by the action with the best
upper Q and the observation with the largest weighted excess gap, then back both bounds
up on the way back. It is deterministic; Perseus's belief expansion is the only use of
the seed. The model is used one action at a time (bounds.Dynamics): the (A, Z, S, S)
kernel T*O is never materialised. When the model has a fully observed part (blocks.py) and
is large enough, HSVI splits both bounds by it (momdp.py): the same values, fewer products.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from .blocks import find_blocks
from .bounds import Dynamics, UpperBound, fast_informed_q, single_threaded_blas, truncate
from .lower_bound import LowerBound
from .momdp import BlockLowerBound, BlockUpperBound
from .policy_graph import PolicyGraph
from .pomdp import POMDP

METHODS = ("hsvi", "perseus", "pbvi")

KAPPA = 0.5          # a trial aims to shrink the gap at b0 to KAPPA times what it is
SIGNIFICANT = 0.999  # sawtooth at the likeliest observations covering this mass (rest: FIB)
MAX_DEPTH = 400      # trial depth cap (the gap rule stops far earlier in practice)
SWEEP_EVERY = 10     # trials between lower-bound sweeps over the newest upper-bound points
SWEEP_POINTS = 200
# The split bounds (momdp.py) pay a Python step per live observation to skip the products over
# other blocks; below this many states the skipped products are cheaper than those steps
# (m2's relaxation, 144 states in 36 blocks: 30 trials 11.7 s split, 5.2 s plain; RockSample
# [4,3], 129 states: equal; Tag and RockSample[5,5], 870 and 801 states: 2 to 3 times faster)
MOMDP_MIN_STATES = 256


@dataclass(frozen=True)
class SolverSettings:
    """When to stop and how large the belief sets may grow."""

    target_gap: float = 1e-3        # stop when (upper - lower) <= target_gap * max(1, |upper|)
    time_budget_s: float = 30.0     # stop after this much wall time
    max_iterations: int = 2000      # HSVI: trials; Perseus/PBVI: backups over the belief set
    max_beliefs: int = 400          # belief set handed to the compiler (and Perseus/PBVI's set)
    expand_every: int = 10          # Perseus/PBVI: backups between expansions; HSVI: stall window / 2
    seed: int = 0
    method: str = "hsvi"            # "hsvi", "perseus" (randomised backups) or "pbvi" (every belief)
    batch: int = 16                 # Perseus: beliefs backed up together
    momdp: bool = True              # HSVI: split both bounds by the fully observed part (momdp.py) when it pays

    def check(self) -> None:
        """Refuse settings that cannot run (called after a config file overrides them)."""
        from .params import ConfigError

        if self.method not in METHODS:
            raise ConfigError(f"unknown solver method {self.method!r}; known: {', '.join(METHODS)}")
        for name in ("max_iterations", "max_beliefs", "expand_every", "batch"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.time_budget_s > 0 or not self.target_gap >= 0:
            raise ConfigError("time_budget_s must be > 0 and target_gap >= 0")


@dataclass
class Progress:
    iteration: int
    lower: float
    upper: float
    gap: float
    elapsed: float
    alphas: int
    beliefs: int
    upper_points: int = 0     # sawtooth points of the upper bound
    depth: int = 0            # HSVI: depth of the last trial


@dataclass
class Solution:
    """Alpha vectors (lower bound) with witnesses, the upper bound, the history."""

    alphas: np.ndarray          # (K, S)
    actions: np.ndarray         # (K,) action of each alpha vector
    witnesses: np.ndarray       # (K, S) belief each vector was backed up at
    upper_q: np.ndarray         # (A, S) fast informed bound
    lower_bound: float          # at b0
    upper_bound: float          # at b0: min(sawtooth, FIB)
    iterations: int
    seconds: float
    stop_reason: str            # "target_gap", "time_budget", "converged" or "max_iterations"
    beliefs: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # improvement points for the compiler
    history: list = field(default_factory=list)
    upper: Optional[UpperBound] = None   # corners + sawtooth points (+ FIB)
    graph: Optional[PolicyGraph] = None  # HSVI: every backup as a node (policy_graph.py)
    graph_nodes: Optional[np.ndarray] = None   # (K,) each alpha vector's node in `graph`
    blocks: int = 1                     # HSVI: blocks of the fully observed part it used (1: none)

    @property
    def gap(self) -> float:
        return self.upper_bound - self.lower_bound

    def upper_value(self, beliefs: np.ndarray) -> np.ndarray:
        """The upper bound at any beliefs (N, S): a certificate for a controller's value there."""
        ub = self.upper if self.upper is not None else UpperBound(self.upper_q)
        return ub.value(np.atleast_2d(beliefs))

    def lower_value(self, beliefs: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(beliefs) @ self.alphas.T).max(axis=1)


# ----------------------------------------------------------------------------- shared pieces

def fast_informed_bound(model: POMDP, tol: float = 1e-7, max_iter: int = 100000) -> np.ndarray:
    """Q[a, s] of the fast informed bound (Hauskrecht 2000), an upper bound on V*."""
    return fast_informed_q(Dynamics(model), tol, max_iter)


def blind_policy_alphas(model: POMDP) -> np.ndarray:
    """Value of always taking each action: a valid lower bound to start from."""
    S, A, _ = model.shape
    eye = np.eye(S)
    return np.stack([np.linalg.solve(eye - model.discount * model.T[a], model.R[:, a]) for a in range(A)])


class Clock:
    """Elapsed time and the stop time (budget or the caller's deadline, whichever first)."""

    def __init__(self, budget_s: float, deadline: Optional[float]):
        self.start = time.perf_counter()
        self.stop = self.start + budget_s if deadline is None else min(self.start + budget_s, deadline)

    def now(self) -> float:
        return time.perf_counter()

    def over(self) -> bool:
        return time.perf_counter() >= self.stop

    def elapsed(self) -> float:
        return time.perf_counter() - self.start


def dedupe(alphas: np.ndarray, actions: np.ndarray, witnesses: np.ndarray):
    """Drop duplicate vectors (same action, same values to 1e-9), keeping the first witness."""
    key = np.round(alphas, 9)
    _, first = np.unique(np.column_stack([actions, key]), axis=0, return_index=True)
    first.sort()
    return alphas[first], actions[first], witnesses[first]


def solve(
    model: POMDP,
    settings: SolverSettings = SolverSettings(),
    progress: Optional[Callable[[Progress], None]] = None,
    deadline: Optional[float] = None,
) -> Solution:
    """Solve until the gap at b0 meets the target, the iteration count, the time budget or
    the `deadline` (an absolute time.perf_counter() value) ends, or nothing moves any more."""
    settings.check()
    clock = Clock(settings.time_budget_s, deadline)
    with single_threaded_blas():
        if settings.method == "hsvi":
            return hsvi(model, settings, progress, clock)
        return pbvi_family(model, settings, progress, clock)


# ----------------------------------------------------------------------------- HSVI

def backup_at(dyn: Dynamics, ub: UpperBound, lb: LowerBound, b: np.ndarray):
    """Back up both bounds at b and store the results: (upper Q (A,), joints, upper and lower
    p(o)-weighted successor values, per action)."""
    q, joints, uj = ub.backup(dyn, b, SIGNIFICANT)
    ub.add(b, float(q.max()))
    vec, act, val, lj, pick = lb.backup(dyn, b, joints)
    if val > lb.value(b) + 1e-12 * max(1.0, abs(val)):
        lb.add(vec, act, b, pick)
    return q, joints, uj, lj


def trial(dyn: Dynamics, ub: UpperBound, lb: LowerBound, b0: np.ndarray, eps: float, clock: Clock) -> int:
    """One HSVI trial from b0; returns its depth. Every backup is valid on its own, so a
    trial cut short by the clock leaves correct bounds."""
    g = dyn.g
    path = []
    b = b0
    for t in range(MAX_DEPTH + 1):
        q, joints, uj, lj = backup_at(dyn, ub, lb, b)
        gap = float(ub.value(b[None, :])[0]) - lb.value(b)
        if gap <= eps * g ** (-t) or t == MAX_DEPTH or clock.over():
            break
        a = int(np.flatnonzero(q >= q.max() - 1e-12 * max(1.0, abs(q.max())))[-1])
        p = joints[a].sum(axis=1)
        excess = uj[a] - lj[a] - p * eps * g ** (-(t + 1))
        o = int(excess.argmax())
        if not excess[o] > 0:
            break
        path.append(b)
        b = truncate(joints[a][o] / p[o])
    for b in reversed(path):
        if clock.over():
            break
        backup_at(dyn, ub, lb, b)
    return len(path)


def lower_sweep(dyn: Dynamics, lb: LowerBound, beliefs: np.ndarray, clock: Clock) -> int:
    """Back the lower bound up at stored beliefs, newest first (as Perseus does over its
    set): trials improve the vectors along one path, a sweep spreads that to the beliefs
    around it at the cost of alpha backups only (no sawtooth). Returns vectors added."""
    added = 0
    for b in beliefs[::-1]:
        if clock.over():
            break
        joints = lb.joints(dyn, b)
        vec, act, val, _, pick = lb.backup(dyn, b, joints)
        if val > lb.value(b) + 1e-12 * max(1.0, abs(val)):
            lb.add(vec, act, b, pick)
            added += 1
    return added


def compiler_points(b0: np.ndarray, ub: UpperBound, lb: LowerBound, cap: int) -> np.ndarray:
    """b0, the witnesses, then the newest upper-bound points: the beliefs the trials found
    worth backing up, at most `cap`, no duplicates."""
    pts = np.vstack([b0[None, :], lb.witnesses, ub.beliefs[::-1]])
    _, first = np.unique(np.round(pts, 12), axis=0, return_index=True)
    return pts[np.sort(first)[:cap]]


def hsvi(model: POMDP, settings: SolverSettings, progress, clock: Clock) -> Solution:
    S, A, _ = model.shape
    dyn = Dynamics(model)
    Q = fast_informed_q(dyn, deadline=clock.stop, clock=clock.now)
    b0 = model.b0
    blocks = find_blocks(model) if settings.momdp and S >= MOMDP_MIN_STATES else None
    if blocks is None or blocks.count == 1:
        blocks = None
        ub = UpperBound(Q)
        lb = LowerBound(blind_policy_alphas(model), np.arange(A), np.tile(b0, (A, 1)), model.shape[2])
    else:
        ub = BlockUpperBound(Q, blocks)
        lb = BlockLowerBound(blind_policy_alphas(model), np.arange(A), np.tile(b0, (A, 1)), model.shape[2], blocks)
    history: list[Progress] = []
    lower, upper = lb.value(b0), float(ub.value(b0[None, :])[0])
    stop_reason, it, last = "max_iterations", 0, (lower, upper)
    stalled, pruned_at = 0, (lb.n, ub.size)
    if clock.over():
        stop_reason = "time_budget"
    else:
        for it in range(1, settings.max_iterations + 1):
            scale = max(1.0, abs(upper))
            eps = max(settings.target_gap * scale, KAPPA * (upper - lower), 1e-12 * scale)
            depth = trial(dyn, ub, lb, b0, eps, clock)
            if it % SWEEP_EVERY == 0:
                lower_sweep(dyn, lb, ub.beliefs[-SWEEP_POINTS:], clock)
            if lb.n >= 2 * pruned_at[0] or ub.size >= 2 * max(32, pruned_at[1]):
                ub.prune()
                lb.prune(np.vstack([b0[None, :], ub.beliefs]))
                pruned_at = (max(lb.n, 32), max(ub.size, 32))
            lower = max(lower, lb.value(b0))
            upper = min(upper, float(ub.value(b0[None, :])[0]))
            entry = Progress(it, lower, upper, upper - lower, clock.elapsed(), lb.n, ub.size, ub.size, depth)
            history.append(entry)
            if progress is not None:
                progress(entry)
            moved = (lower, upper) != last
            stalled, last = (0 if moved else stalled + 1), (lower, upper)
            if upper - lower <= settings.target_gap * max(1.0, abs(upper)):
                stop_reason = "target_gap"
                break
            if clock.over():
                stop_reason = "time_budget"
                break
            if upper - lower <= 1e-12 * max(1.0, abs(upper)) or stalled >= 2 * settings.expand_every:
                stop_reason = "converged"
                break
    return Solution(
        alphas=lb.alphas.copy(), actions=lb.actions.copy(), witnesses=lb.witnesses.copy(), upper_q=Q,
        lower_bound=lower, upper_bound=upper, iterations=it, seconds=clock.elapsed(), stop_reason=stop_reason,
        beliefs=compiler_points(b0, ub, lb, settings.max_beliefs), history=history,
        upper=ub if blocks is None else ub.merged(), graph=lb.graph, graph_nodes=lb.nodes.copy(),
        blocks=1 if blocks is None else blocks.count,
    )


# ----------------------------------------------------------------------------- Perseus and PBVI

def project(dyn: Dynamics, alphas: np.ndarray) -> list[np.ndarray]:
    """gao[a][o, k, s] = g sum_s' T[a, s, s'] O[a, s', o] alpha_k(s'), one product per action."""
    S, Z, K = dyn.S, dyn.Z, alphas.shape[0]
    out = []
    for a in range(dyn.A):
        M = (dyn.OT[a][:, None, :] * alphas[None, :, :]).reshape(Z * K, S)   # (Z*K, S')
        out.append(dyn.g * np.asarray(dyn.back(a, M.T)).T.reshape(Z, K, S))
    return out


def backup_with(dyn: Dynamics, gaos: list[np.ndarray], beliefs: np.ndarray):
    """Point-based Bellman backup of each belief against projected vectors: (alphas, actions).

    Ties go to the later (stronger-braking) action: on the safe side.
    """
    S, Z = dyn.S, dyn.Z
    N = beliefs.shape[0]
    best_val = np.full(N, -np.inf)
    best_vec = np.zeros((N, S))
    best_act = np.zeros(N, dtype=np.int64)
    for a, gao in enumerate(gaos):
        K = gao.shape[1]
        scores = (beliefs @ gao.reshape(Z * K, S).T).reshape(N, Z, K)
        pick = scores.argmax(axis=2)  # (N, Z)
        vec = dyn.R[a][None, :] + gao[np.arange(Z)[None, :], pick].sum(axis=1)
        val = np.einsum("ns,ns->n", beliefs, vec)
        better = val >= best_val - 1e-12 * np.maximum(1.0, np.abs(best_val))
        best_val = np.where(better, val, best_val)
        best_vec[better] = vec[better]
        best_act[better] = a
    return best_vec, best_act


def perseus_step(dyn, alphas, actions, witnesses, beliefs, rng, batch, clock):
    """One Perseus iteration (Spaan & Vlassis 2005): back up random beliefs, in batches, until
    every belief's value is at least what it was; a belief whose backup is worse keeps its
    old best vector."""
    gaos = project(dyn, alphas)
    old_values = beliefs @ alphas.T
    v_old = old_values.max(axis=1)
    new_vec, new_act, new_wit = [], [], []
    v_new = np.full(len(beliefs), -np.inf)
    todo = np.ones(len(beliefs), dtype=bool)
    while todo.any():
        open_idx = np.flatnonzero(todo)
        idx = rng.choice(open_idx, size=min(batch, len(open_idx)), replace=False)
        vecs, acts = backup_with(dyn, gaos, beliefs[idx])
        vals = np.einsum("ns,ns->n", beliefs[idx], vecs)
        for j, n in enumerate(idx):
            if vals[j] >= v_old[n] - 1e-12 * max(1.0, abs(v_old[n])):
                new_vec.append(vecs[j]); new_act.append(acts[j]); new_wit.append(beliefs[n])
            else:
                k = int(old_values[n].argmax())
                new_vec.append(alphas[k]); new_act.append(actions[k]); new_wit.append(witnesses[k])
        added = np.array(new_vec[-len(idx):])
        v_new = np.maximum(v_new, (beliefs @ added.T).max(axis=1))
        todo &= v_new < v_old - 1e-12 * np.maximum(1.0, np.abs(v_old))
        todo[idx] = False
        if clock.over():
            # keep every old vector a belief still needs: the set stays a valid lower bound
            keep = np.unique(old_values[todo].argmax(axis=1)) if todo.any() else np.zeros(0, dtype=np.int64)
            new_vec.extend(alphas[keep]); new_act.extend(actions[keep]); new_wit.extend(witnesses[keep])
            break
    return np.array(new_vec), np.array(new_act, dtype=np.int64), np.array(new_wit)


def successor_beliefs(dyn: Dynamics, b: np.ndarray, a: int):
    """All successors of b under a: (beliefs (Z, S), probabilities (Z,))."""
    unnorm = dyn.joint(b, a)
    pred = unnorm.sum(axis=0)
    p = unnorm.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        succ = np.where(p[:, None] > 0, unnorm / np.where(p > 0, p, 1.0)[:, None], pred[None, :])
    return succ, p


def expand_beliefs(dyn: Dynamics, beliefs: np.ndarray, rng: np.random.Generator, cap: int) -> np.ndarray:
    """Grow the belief set (Pineau et al.'s stochastic simulation with exploratory actions):
    for each belief, take its successors (all of them when actions x observations <= 64,
    else one sampled observation per action) and keep the one farthest (L1) from the set."""
    A, Z = dyn.A, dyn.Z
    exhaustive = A * Z <= 64
    pool = beliefs
    for b in beliefs:
        if len(pool) >= cap:
            break
        cands = []
        for a in range(A):
            succ, p = successor_beliefs(dyn, b, a)
            total = p.sum()
            if total <= 0:
                continue
            if exhaustive:
                cands.extend(succ[p > 0])
            else:
                cands.append(succ[rng.choice(Z, p=p / total)])
        if not cands:
            continue
        cands = np.array(cands)
        dist = np.abs(cands[:, None, :] - pool[None, :, :]).sum(axis=2).min(axis=1)
        i = int(dist.argmax())
        if dist[i] > 1e-6:
            pool = np.vstack([pool, cands[i][None, :]])
    return pool


def pbvi_family(model: POMDP, settings: SolverSettings, progress, clock: Clock) -> Solution:
    """Perseus or PBVI over an expanding belief set; the upper bound is the FIB alone."""
    rng = np.random.default_rng(settings.seed)
    S, A, Z = model.shape
    dyn = Dynamics(model)
    Q = fast_informed_q(dyn, deadline=clock.stop, clock=clock.now)
    upper = float((Q @ model.b0).max())
    alphas = blind_policy_alphas(model)
    actions = np.arange(A)
    witnesses = np.tile(model.b0, (A, 1))
    beliefs = model.b0[None, :].copy()
    history: list[Progress] = []
    lower = float((alphas @ model.b0).max())
    stop_reason = "max_iterations"
    stalled = idle_expansions = it = 0
    for it in range(1, settings.max_iterations + 1):
        if (it - 1) % settings.expand_every == 0:
            before = len(beliefs)
            if before < settings.max_beliefs:
                beliefs = expand_beliefs(dyn, beliefs, rng, settings.max_beliefs)
            idle_expansions = 0 if len(beliefs) > before else idle_expansions + 1
        if settings.method == "pbvi":
            new_alphas, new_actions = backup_with(dyn, project(dyn, alphas), beliefs)
            alphas, actions, witnesses = dedupe(new_alphas, new_actions, beliefs)
        else:
            alphas, actions, witnesses = dedupe(
                *perseus_step(dyn, alphas, actions, witnesses, beliefs, rng, settings.batch, clock))
        new_lower = float((alphas @ model.b0).max())
        stalled = stalled + 1 if abs(new_lower - lower) <= 1e-12 * max(1.0, abs(lower)) else 0
        lower = max(lower, new_lower)
        gap = upper - lower
        entry = Progress(it, lower, upper, gap, clock.elapsed(), len(alphas), len(beliefs))
        history.append(entry)
        if progress is not None:
            progress(entry)
        if gap <= settings.target_gap * max(1.0, abs(upper)):
            stop_reason = "target_gap"
            break
        if clock.over():
            stop_reason = "time_budget"
            break
        if stalled >= 2 * settings.expand_every and idle_expansions >= 3:
            stop_reason = "converged"
            break
    return Solution(
        alphas=alphas, actions=actions, witnesses=witnesses, upper_q=Q, lower_bound=lower, upper_bound=upper,
        iterations=it, seconds=clock.elapsed(), stop_reason=stop_reason, beliefs=beliefs, history=history,
        upper=UpperBound(Q),
    )
