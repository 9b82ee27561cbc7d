"""Point-based value iteration (PBVI) with witness beliefs and a fast informed upper bound.

Each alpha vector keeps the belief it was backed up at (its witness) and its action: the
compiler follows witnesses to turn the vector set into a finite-state controller.
Everything is vectorised over states and observations; randomness comes only from the
seeded generator used to expand the belief set, so a seed fixes the result.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from .pomdp import POMDP


METHODS = ("perseus", "pbvi")


@dataclass(frozen=True)
class SolverSettings:
    """When to stop and how large the belief set may grow."""

    target_gap: float = 1e-3        # stop when (upper - lower) <= target_gap * max(1, |upper|)
    time_budget_s: float = 30.0     # stop after this much wall time
    max_iterations: int = 2000      # backups over the belief set
    max_beliefs: int = 400          # belief set size cap
    expand_every: int = 10          # backups between belief-set expansions
    seed: int = 0
    method: str = "perseus"         # "perseus" (randomised backups) or "pbvi" (back up every belief)
    batch: int = 16                 # Perseus: beliefs backed up together

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


@dataclass
class Solution:
    """Alpha vectors (lower bound) with witnesses, the informed upper bound Q, the history."""

    alphas: np.ndarray          # (K, S)
    actions: np.ndarray         # (K,) action of each alpha vector
    witnesses: np.ndarray       # (K, S) belief each vector was backed up at
    upper_q: np.ndarray         # (A, S) fast informed bound
    lower_bound: float
    upper_bound: float
    iterations: int
    seconds: float
    stop_reason: str
    beliefs: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # the final belief set
    history: list = field(default_factory=list)

    @property
    def gap(self) -> float:
        return self.upper_bound - self.lower_bound


def observation_kernels(model: POMDP) -> np.ndarray:
    """K[a, o, s, s'] = T[a, s, s'] * O[a, s', o]: one Bayes step without normalisation."""
    return np.einsum("ast,ato->aost", model.T, model.O)


def fast_informed_bound(model: POMDP, tol: float = 1e-7, max_iter: int = 100000) -> np.ndarray:
    """Q[a, s] of the fast informed bound (Hauskrecht 2000), an upper bound on V*.

    Q_a(s) = R(s, a) + g * sum_o max_a' sum_s' T(s, a, s') O(s', a, o) Q_a'(s').
    Starts above V* and iterates the contraction to tolerance (relative to the reward scale).
    """
    S, A, Z = model.shape
    g = model.discount
    R = model.R.T  # (A, S)
    scale = max(1.0, float(np.abs(R).max()))
    Q = np.full((A, S), R.max() / (1.0 - g) if g < 1 else R.max())
    # KT[a] is (S * Z, S'): T[a, s, s'] * O[a, s', o], rows ordered (o, s)
    KT = observation_kernels(model).reshape(A, Z * S, S)
    for _ in range(max_iter):
        # inner[a, s, o, a'] = sum_s' T[a, s, s'] O[a, s', o] Q[a', s']
        inner = (KT @ Q.T).reshape(A, Z, S, A).transpose(0, 2, 1, 3)
        Qn = R + g * inner.max(axis=3).sum(axis=2)
        delta = float(np.abs(Qn - Q).max())
        Q = Qn
        if delta * g / (1.0 - g) <= tol * scale:
            break
    return Q


def blind_policy_alphas(model: POMDP) -> np.ndarray:
    """Value of always taking each action: a valid lower bound to start PBVI from."""
    S, A, _ = model.shape
    eye = np.eye(S)
    return np.stack([np.linalg.solve(eye - model.discount * model.T[a], model.R[:, a]) for a in range(A)])


def project(model: POMDP, kernels: np.ndarray, alphas: np.ndarray) -> list[np.ndarray]:
    """gao[a][o, k, s] = g * sum_s' T[a, s, s'] O[a, s', o] alpha_k(s'), one BLAS product per action."""
    S, A, Z = model.shape
    K = alphas.shape[0]
    g = model.discount
    return [g * (kernels[a].reshape(Z * S, S) @ alphas.T).reshape(Z, S, K).transpose(0, 2, 1) for a in range(A)]


def backup_with(model: POMDP, gaos: list[np.ndarray], beliefs: np.ndarray):
    """Point-based Bellman backup of each belief against projected vectors: (alphas, actions).

    Ties go to the later (stronger-braking) action: on the safe side.
    """
    S, A, Z = model.shape
    N = beliefs.shape[0]
    best_val = np.full(N, -np.inf)
    best_vec = np.zeros((N, S))
    best_act = np.zeros(N, dtype=np.int64)
    for a, gao in enumerate(gaos):
        K = gao.shape[1]
        # scores[n, o, k] = b_n . gao[o, k]
        scores = (beliefs @ gao.reshape(Z * K, S).T).reshape(N, Z, K)
        pick = scores.argmax(axis=2)  # (N, Z)
        vec = model.R[:, a][None, :] + gao[np.arange(Z)[None, :], pick].sum(axis=1)
        val = np.einsum("ns,ns->n", beliefs, vec)
        better = val >= best_val - 1e-12 * np.maximum(1.0, np.abs(best_val))
        best_val = np.where(better, val, best_val)
        best_vec[better] = vec[better]
        best_act[better] = a
    return best_vec, best_act


def backup(model: POMDP, kernels: np.ndarray, alphas: np.ndarray, beliefs: np.ndarray):
    """PBVI: back up every belief of the set."""
    return backup_with(model, project(model, kernels, alphas), beliefs)


def perseus_step(model, kernels, alphas, actions, witnesses, beliefs, rng, batch):
    """One Perseus iteration (Spaan & Vlassis 2005): back up random beliefs, in batches, until
    every belief's value is at least what it was; a belief whose backup is worse keeps its
    old best vector. Cheaper than PBVI because the projections are computed once and most
    beliefs are improved by a vector backed up elsewhere."""
    gaos = project(model, kernels, alphas)
    old_values = beliefs @ alphas.T
    v_old = old_values.max(axis=1)
    new_vec, new_act, new_wit = [], [], []
    v_new = np.full(len(beliefs), -np.inf)
    todo = np.ones(len(beliefs), dtype=bool)
    while todo.any():
        open_idx = np.flatnonzero(todo)
        idx = rng.choice(open_idx, size=min(batch, len(open_idx)), replace=False)
        vecs, acts = backup_with(model, gaos, beliefs[idx])
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
    return np.array(new_vec), np.array(new_act, dtype=np.int64), np.array(new_wit)


def successor_beliefs(model: POMDP, b: np.ndarray, a: int):
    """All successors of b under a: (beliefs (Z, S), probabilities (Z,))."""
    pred = b @ model.T[a]
    unnorm = pred[None, :] * model.O[a].T  # (Z, S)
    p = unnorm.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        succ = np.where(p[:, None] > 0, unnorm / np.where(p > 0, p, 1.0)[:, None], pred[None, :])
    return succ, p


def expand_beliefs(model: POMDP, beliefs: np.ndarray, rng: np.random.Generator, cap: int) -> np.ndarray:
    """Grow the belief set (Pineau et al.'s stochastic simulation with exploratory actions):
    for each belief, take its successors (all of them when actions x observations <= 64,
    else one sampled observation per action) and keep the one farthest (L1) from the set."""
    S, A, Z = model.shape
    exhaustive = A * Z <= 64
    pool = beliefs
    for b in beliefs:
        if len(pool) >= cap:
            break
        cands = []
        for a in range(A):
            succ, p = successor_beliefs(model, b, a)
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
) -> Solution:
    """Run point-based value iteration until the gap at b0 meets the target, the iteration
    count or time budget ends, or neither the value nor the belief set moves any more."""
    settings.check()
    start = time.perf_counter()
    rng = np.random.default_rng(settings.seed)
    S, A, Z = model.shape
    kernels = observation_kernels(model)
    Q = fast_informed_bound(model)
    upper = float((Q @ model.b0).max())

    alphas = blind_policy_alphas(model)
    actions = np.arange(A)
    witnesses = np.tile(model.b0, (A, 1))
    beliefs = model.b0[None, :].copy()
    history: list[Progress] = []
    lower = float((alphas @ model.b0).max())
    stop_reason = "max_iterations"
    stalled = 0
    idle_expansions = 0
    it = 0
    for it in range(1, settings.max_iterations + 1):
        if (it - 1) % settings.expand_every == 0:
            before = len(beliefs)
            if before < settings.max_beliefs:
                beliefs = expand_beliefs(model, beliefs, rng, settings.max_beliefs)
            idle_expansions = 0 if len(beliefs) > before else idle_expansions + 1
        if settings.method == "pbvi":
            new_alphas, new_actions = backup(model, kernels, alphas, beliefs)
            alphas, actions, witnesses = dedupe(new_alphas, new_actions, beliefs)
        else:
            alphas, actions, witnesses = dedupe(
                *perseus_step(model, kernels, alphas, actions, witnesses, beliefs, rng, settings.batch))
        new_lower = float((alphas @ model.b0).max())
        stalled = stalled + 1 if abs(new_lower - lower) <= 1e-12 * max(1.0, abs(lower)) else 0
        lower = max(lower, new_lower)
        elapsed = time.perf_counter() - start
        gap = upper - lower
        entry = Progress(it, lower, upper, gap, elapsed, len(alphas), len(beliefs))
        history.append(entry)
        if progress is not None:
            progress(entry)
        if gap <= settings.target_gap * max(1.0, abs(upper)):
            stop_reason = "target_gap"
            break
        if elapsed >= settings.time_budget_s:
            stop_reason = "time_budget"
            break
        if stalled >= 2 * settings.expand_every and idle_expansions >= 3:
            stop_reason = "converged"
            break
    return Solution(
        alphas=alphas,
        actions=actions,
        witnesses=witnesses,
        upper_q=Q,
        lower_bound=lower,
        upper_bound=upper,
        iterations=it,
        seconds=time.perf_counter() - start,
        stop_reason=stop_reason,
        beliefs=beliefs,
        history=history,
    )
