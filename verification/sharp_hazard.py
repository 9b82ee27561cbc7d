"""A sharp estimate of P(hazard within the horizon) for a policy that is not a finite-state
controller (belief tracking), on the model's closed loop with the supervision in front.

Two variance reductions, each unbiased on its own:

1. Conditional Monte Carlo (survival conditioning). Every episode carries a weight W, at
   the start the probability that it has not hit the hazard. Each cycle, in state s under
   the applied action a, the probability that the next state is a hazard state,
   p = sum over hazard states h of T[a, s, h], is known exactly: the episode adds W * p to
   its figure Y, moves to a next state drawn from T[a, s, .] conditioned on not being a
   hazard state, and W becomes W * (1 - p). E[Y] = P(hazard within the horizon): the
   conditioned path is prod(1 - p_k) times more likely than under the plain chain, and W
   carries exactly that factor.

2. Importance sampling guided by a finite-state controller's exact values (the zero-
   variance change of measure, approximated). A guide controller (the table the policy is
   compared with) runs beside the episode on the same observations; closed_loop's two-
   phase chain gives, for every remaining number of cycles j, the guide's exact hazard
   probability from each (node, state) before it reads the observation (X_B) and after
   (X_A). The next state is drawn from q = (1 - LAMBDA) t + LAMBDA t g / <t, g>, t the
   conditioned next-state row, g = X_B[j](node, .); the observation likewise from its row
   O[a, s', .] tilted by X_A[j](next[node, o], s'); W is multiplied by the likelihood
   ratio t / q of each draw. The mixture with t bounds every ratio by 1 / (1 - LAMBDA).
   Run on the guide itself with LAMBDA = 1 every episode returns the exact figure (zero
   variance); run on belief tracking, whose demands are close to the table's, most of the
   spread goes: the episodes are steered to the few paths (an obstacle reaching the close
   level, a misperceived distance there) that carry the hazard, instead of one episode in
   hundreds finding them.

Both are unbiased whatever the guide; the interval, mean(Y) +- 1.96 sd(Y) / sqrt(n) over
independent episodes, is trustworthy only where the guide is not much safer than the policy
in the situations that carry its hazard (there the draws avoid those paths and the rare
episode that takes one carries a weight the sample seldom shows). Measured on m2 (1,000
episodes): threshold (P 0.00135) guided by the table (4.1e-5) came out near 0.0002 with a
narrow interval; the table guided by threshold, or by never, within its interval. Belief
tracking is guided by the table compiled from its own alpha vectors, and its estimate is
the same guided by threshold (a riskier guide, 3 to 5 times wider): `railguard verify`
checks that agreement, and that the estimator reproduces the table's exact figure guided by
threshold (evaluate.estimator_checks); tests/test_evaluate.py checks exact figures guided by
safer, riskier and no controllers, and that dropping the likelihood ratios is caught.
"""
from __future__ import annotations

import ctypes
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable

import numpy as np

from monitor.offline.controller import Controller

from monitor.offline.closed_chain import hazard_states, two_phase_chain
from .policies import BeliefTracking, supervised, supervision_floor

Z95 = 1.96
# A sharp estimate's 95 % half-width is at most this share of the estimate
RELATIVE_HALF_WIDTH = 0.25
LAMBDA = 0.9
METHOD = "conditional Monte Carlo (exact next-step hazard, survival-weighted)"
GUIDED = " with importance sampling guided by the table's exact hazard values"


@dataclass(frozen=True)
class Sharp:
    """An estimate of P(hazard) with its 95 % half-width, and what it took."""

    p: float
    ci: float
    episodes: int
    seconds: float
    method: str = METHOD

    @property
    def relative(self) -> float:
        return self.ci / self.p if self.p > 0 else (0.0 if self.ci == 0 else math.inf)

    def as_dict(self) -> dict:
        return {"p": self.p, "ci": self.ci, "low": max(0.0, self.p - self.ci), "high": self.p + self.ci,
                "episodes": self.episodes, "seconds": round(self.seconds, 2), "method": self.method,
                "relative_half_width": self.relative}


class Guide:
    """A finite-state controller's exact hazard values over its two-phase chain with the
    supervision in front (`supervision=False`: the bare table, as closed_loop analyses it):
    X_A[j][node, s] = P(hazard within j cycles) after the node has read its observation in
    state s, X_B[j][node, s'] the same before reading (the world has just moved to s'),
    j = 0 .. steps."""

    def __init__(self, model, ctrl: Controller, steps: int, supervision: bool = True):
        self.ctrl = supervised(ctrl, supervision_floor(model)) if supervision else ctrl
        S = model.shape[0]
        N = self.ctrl.nodes
        NS = N * S
        P = two_phase_chain(model, self.ctrl)
        x = np.zeros(2 * NS)
        target = np.zeros(2 * NS, dtype=bool)
        for s in hazard_states(model):
            target[s:NS:S] = True
        x[target] = 1.0
        self.A = np.empty((steps + 1, N, S), dtype=np.float32)
        self.B = np.empty((steps + 1, N, S), dtype=np.float32)
        self.A[0] = x[:NS].reshape(N, S)
        for j in range(steps + 1):
            x = P @ x
            x[target] = 1.0
            self.B[j] = x[NS:].reshape(N, S)
            if j < steps:
                x = P @ x
                x[target] = 1.0
                self.A[j + 1] = x[:NS].reshape(N, S)
        self.exact = float(model.b0 @ self.A[steps][self.ctrl.start])


@contextmanager
def one_blas_thread():
    """OpenBLAS on one thread while the episodes run: belief tracking's products are a few
    hundred rows by 144, where OpenBLAS's threads cost more than they give, and on a loaded
    machine (2 cores shared) ten times more (measured: 1.4 us a row on one thread, 3 to 20
    on two). Restored afterwards; a no-op where numpy's OpenBLAS cannot be found."""
    lib = get = put = None
    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            path = next((line.split()[-1] for line in maps if "openblas" in line.lower() and ".so" in line), None)
        if path:
            lib = ctypes.CDLL(path)
            for prefix, suffix in (("scipy_openblas", "64_"), ("openblas", "64_"), ("scipy_openblas", ""), ("openblas", "")):
                if hasattr(lib, f"{prefix}_set_num_threads{suffix}"):
                    get = getattr(lib, f"{prefix}_get_num_threads{suffix}")
                    put = getattr(lib, f"{prefix}_set_num_threads{suffix}")
                    break
    except OSError:
        put = None
    if put is None:
        yield
        return
    before = int(get())
    put(1)
    try:
        yield
    finally:
        put(before)


def _tables(model):
    """(hazard mask, P(next state is a hazard | a, s) as (A, S), next-state rows
    conditioned on no hazard as (A, S, S))."""
    T = np.asarray(model.T, dtype=float)
    hazard = np.zeros(T.shape[1], dtype=bool)
    hazard[hazard_states(model)] = True
    p_hit = T[:, :, hazard].sum(axis=2)
    safe = np.where(hazard[None, None, :], 0.0, T)
    norm = safe.sum(axis=2, keepdims=True)
    return hazard, p_hit, safe / np.where(norm > 0, norm, 1.0)


def _draw(rng, t: np.ndarray, gs: list, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """(index drawn per row, likelihood ratio t / q of the draw): rows t (n, K) of a
    distribution, tilted by each g in `gs` ((n, K) >= 0) in the mixture
    q = (1 - lam) t + lam / len(gs) * sum over g of t g / <t, g> (a g with <t, g> = 0 on a
    row gives t there; no g: q = t, ratio 1)."""
    n, K = t.shape
    if not gs or lam <= 0:
        q = t
    else:
        q = (1.0 - lam) * t
        for g in gs:
            tg = t * g
            G = tg.sum(axis=1, keepdims=True)
            q = q + (lam / len(gs)) * np.where(G > 0, tg / np.where(G > 0, G, 1.0), t)
    cum = np.cumsum(q, axis=1)
    u = rng.random(n) * cum[:, -1]
    idx = np.minimum((u[:, None] > cum).sum(axis=1), K - 1)
    rows = np.arange(n)
    qi = q[rows, idx]
    return idx, np.where(qi > 0, t[rows, idx] / np.where(qi > 0, qi, 1.0), 0.0)


def episode_figures(model, policy, first_action: int, steps: int, episodes: int, rng: np.random.Generator,
                    guides: tuple = (), lam: float = LAMBDA, supervision: bool = True) -> np.ndarray:
    """Y per episode (see the module doc) for `episodes` episodes run together; `policy` has
    TablePolicy's `step(obs, applied) -> (proposed, _)` and proposes `first_action` before
    any observation (as the table's start node and belief tracking's b0 do); the braking
    curves' floor in front unless `supervision` is False."""
    S, _, Z = model.shape
    hazard, p_hit, t_safe = _tables(model)
    O = np.asarray(model.O, dtype=float)
    floor = supervision_floor(model) if supervision else np.zeros(Z, dtype=np.int64)
    b0 = np.asarray(model.b0, dtype=float)
    y = np.full(episodes, float(b0[hazard].sum()))         # the start itself is a hazard
    start = np.where(hazard, 0.0, b0)
    if start.sum() <= 0:
        return y
    W = np.full(episodes, 1.0 - y[0])
    nodes = [np.full(episodes, g.ctrl.start, dtype=np.int64) for g in guides]
    state, ratio = _draw(rng, np.tile(start / start.sum(), (episodes, 1)),
                         [g.A[steps][n] for g, n in zip(guides, nodes)], lam)
    W *= ratio
    a = np.full(episodes, first_action, dtype=np.int64)
    for k in range(steps):
        left = steps - k - 1                                 # cycles after this one
        p = p_hit[a, state]
        y += W * p
        W *= 1.0 - p
        state, ratio = _draw(rng, t_safe[a, state], [g.B[left][n] for g, n in zip(guides, nodes)], lam)
        W *= ratio
        col = state[:, None]
        obs, ratio = _draw(rng, O[a, state], [g.A[left][g.ctrl.next[n], col] for g, n in zip(guides, nodes)], lam)
        W *= ratio
        nodes = [g.ctrl.next[n, obs] for g, n in zip(guides, nodes)]
        proposed, _ = policy.step(obs, a)
        a = np.maximum(proposed, floor[obs])
    return y


def estimate(model, make_policy: Callable[[int], tuple[object, int]], steps: int, episodes: int, seed: int,
             guides: tuple = (), lam: float = LAMBDA, batch: int = 5000, supervision: bool = True) -> Sharp:
    """The sharp estimate of P(hazard within `steps` cycles) over `episodes` episodes
    (batches of `batch`); `make_policy(n)` gives (policy for n episodes, its first action);
    `supervision` as in episode_figures (the guides must be built alike)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    ys = []
    with one_blas_thread():
        for lo in range(0, episodes, batch):
            n = min(batch, episodes - lo)
            policy, first = make_policy(n)
            ys.append(episode_figures(model, policy, first, steps, n, rng, tuple(guides), lam, supervision))
    y = np.concatenate(ys)
    ci = Z95 * float(y.std(ddof=1)) / math.sqrt(len(y)) if len(y) > 1 else math.inf
    return Sharp(float(y.mean()), ci, len(y), time.perf_counter() - t0, METHOD + (GUIDED if guides else ""))


def episodes_for(model, episodes: int) -> int:
    """Episodes of a sharp estimate sized `episodes` for a large model: ten times more for
    small ones (Model 1's four states cost nothing per episode)."""
    return episodes * (10 if model.shape[0] <= 16 else 1)


def belief_tracking(model, alphas: np.ndarray, actions: np.ndarray):
    """make_policy for belief tracking (seed 000 eq. 14 with these alpha vectors): the
    model's start belief is b0, the first demand that of its best alpha vector."""
    first = int(actions[int(np.argmax(np.asarray(alphas) @ model.b0))])

    def make(n: int):
        tracker = BeliefTracking(model, alphas, actions, n)
        tracker.started = True                   # the model's start belief is already b0
        return tracker, first
    return make


def controller(ctrl: Controller):
    """make_policy for a finite-state controller (its start node's action first)."""
    from .fastcore import TablePolicy

    return lambda n: (TablePolicy(ctrl.action, ctrl.next, ctrl.start, n), int(ctrl.action[ctrl.start]))
