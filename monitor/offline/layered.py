"""Tables monotone in the reported conditions: layered controllers (issue 11), and their
improvement (issue 12).

A layered controller's node is (m, q): base node m, which moves on the base part of each
observation only (distance, speed, type for Model 2), and a memory q of the reported
conditions. Two runs whose reports differ only by conditions raised on the second are then
always in (m, q) and (m, q') with q' at least q, and demanding at least as much in q' as in
q, node by node, makes the whole table monotone (docs/models.md section 6).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np

from .controller import (
    Candidate, Compiled, Controller, EdgeWeights, _by_action, candidates, evaluate, minimise, node_beliefs, occupancy,
    out_of_time, value_at,
)
from .hysteresis import with_last_demand
from .pomdp import POMDP
from .solver import Solution


@dataclass(frozen=True)
class ConditionLayer:
    """Observations split into a base part and reported conditions (Model 2: track, brake),
    and the memory a layered controller keeps of the conditions: the newest report.

    `base[o]` is the column of o's base part; memory q is a combination of conditions (bit
    k set: condition k adverse), `step[q, o]` the memory after observing o (o's combination),
    `below[q, q2]` says every condition adverse in q is adverse in q2 as well.
    """

    base: np.ndarray    # (Z,) column of the observation's base part, 0..B-1
    step: np.ndarray    # (Q, Z) memory after the observation
    below: np.ndarray   # (Q, Q) bool

    @property
    def memories(self) -> int:
        return int(self.below.shape[0])

    @property
    def bases(self) -> int:
        return int(self.base.max()) + 1

    @staticmethod
    def of(observations: tuple[str, ...], positions: tuple[int, ...]) -> "ConditionLayer":
        """From observation names joined with `-`: the components at `positions` are two-level
        conditions, the level of the first observation being the normal one."""
        parts = [name.split("-") for name in observations]
        if any(len({p[i] for p in parts}) != 2 for i in positions):
            raise ValueError("a condition component must have exactly two levels")
        bits = 1 << np.arange(len(positions))[::-1]
        combo = np.array([[p[i] != parts[0][i] for i in positions] for p in parts]) @ bits   # (Z,)
        keys = ["-".join(x for k, x in enumerate(p) if k not in positions) for p in parts]
        base = np.unique(keys, return_inverse=True)[1].ravel().astype(np.int64)
        q = np.arange(1 << len(positions))
        below = (q[:, None] & ~q[None, :]) == 0
        return ConditionLayer(base, np.tile(combo.astype(np.int64), (len(q), 1)), below)


def reduced_model(model: POMDP, layer: ConditionLayer) -> POMDP:
    """The model with the conditions unobserved: observation = the base part only."""
    O = np.zeros((model.shape[1], model.shape[0], layer.bases))
    np.add.at(O.transpose(2, 0, 1), layer.base, model.O.transpose(2, 0, 1))
    first = np.unique(layer.base, return_index=True)[1]
    return POMDP(model.name, model.states, model.actions, tuple(model.observations[o] for o in first), model.T, O,
                 model.R, model.discount, model.b0, model.params, release_cost=model.release_cost)


def raise_monotone(action: np.ndarray, layer: ConditionLayer) -> np.ndarray:
    """Each (m, q) demands at least what any (m, q') with q' below q demands."""
    A = action.reshape(-1, layer.memories)
    return np.max(np.where(layer.below.T[None, :, :], A[:, None, :], -1), axis=2).ravel()


def fixed_edge_q(model: POMDP, ctrl: Controller, V: np.ndarray, beliefs: np.ndarray) -> np.ndarray:
    """q[n, a]: at node n's belief, act a now and then follow n's own edges (values V)."""
    S, A, Z = model.shape
    q = np.zeros((ctrl.nodes, A))
    for a in range(A):
        W = np.einsum("so,nos->ns", model.O[a], V[ctrl.next])    # (N, S'): value after o, weighted
        if model.release_cost:
            changes = (ctrl.action[ctrl.next] < a).astype(float)                   # (N, Z)
            W = W - model.release_cost * changes @ model.O[a].T                     # (N, S')
        q[:, a] = beliefs @ model.R[:, a] + model.discount * np.einsum("ns,ns->n", beliefs @ model.T[a], W)
    return q


def strongest_best(q: np.ndarray) -> np.ndarray:
    """Each row's best action, ties going to the stronger braking (the later action)."""
    tol = 1e-12 * np.maximum(1.0, np.abs(q).max(axis=1, keepdims=True))
    return np.where(q >= q.max(axis=1, keepdims=True) - tol, np.arange(q.shape[1])[None, :], -1).max(axis=1)


SEARCHES = ("actions", "exact")   # how a layered controller is improved (compile_monotone)


def base_model(model: POMDP, layer: ConditionLayer, search: str = "actions") -> POMDP:
    """The model a layered controller's memory is solved and compiled on: the conditions
    unobserved; with search "exact" and a release cost, also the last demand in the state, so
    the memory is built knowing what lowering the demand costs (hysteresis.py)."""
    reduced = reduced_model(model, layer)
    return with_last_demand(reduced) if search == "exact" and model.release_cost else reduced


def demand_before(model: POMDP, ctrl: Controller, x: np.ndarray) -> np.ndarray:
    """share[n, p]: of the visits x to node n, the share that arrives from a node demanding p
    (the start arrives from the weakest demand, as a controller's first step pays no release)."""
    S, A, _ = model.shape
    E = EdgeWeights.of(model, ctrl)
    moved = _by_action(model, ctrl, x, transpose=False)                      # (N, S') mass after moving
    flow = model.discount * np.einsum("ls,ls->l", moved[E.src], E.w)          # mass along each edge pair
    into = np.zeros((ctrl.nodes, A))
    np.add.at(into, (E.dst, ctrl.action[E.src]), flow)
    into[ctrl.start, 0] += 1.0
    return into / np.maximum(into.sum(axis=1, keepdims=True), 1e-300)


@dataclass(frozen=True)
class Layered:
    """A layered controller as its parts: the base edges (M, B) shared by every memory, the
    (M x Q) actions and the start node; `controller` builds the table's controller."""

    layer: ConditionLayer
    edges: np.ndarray
    action: np.ndarray
    start: int

    @property
    def controller(self) -> Controller:
        Q = self.layer.memories
        nxt = self.edges[:, self.layer.base][:, None, :] * Q + self.layer.step[None, :, :]    # (M, Q, Z)
        return Controller(self.action.astype(np.int64), nxt.reshape(-1, nxt.shape[2]), self.start)

    def changed(self, kind: str, idx: np.ndarray, want: np.ndarray) -> "Layered":
        """With "actions" idx (nodes) or "edges" idx (flattened base edges) set to `want`'s
        entries; actions are raised to monotone."""
        if kind == "actions":
            action = self.action.copy()
            action[idx] = want[idx]
            return replace(self, action=raise_monotone(action, self.layer))
        edges = self.edges.copy().ravel()
        edges[idx] = want[idx]
        return replace(self, edges=edges.reshape(self.edges.shape))


def first_gain(model: POMDP, best: float, order: np.ndarray, make: Callable[[np.ndarray], Layered],
               V: np.ndarray) -> Optional[tuple[Layered, float, int, np.ndarray]]:
    """Apply the changes order[:k] for k = all, half, a quarter, ... and keep the first that
    raises the exact value at b0: (layered, value, k, its values), or None if even the first
    change does not. V, the values before the change, starts each evaluation."""
    k = len(order)
    while k >= 1:
        cand = make(order[:k])
        cand_V = evaluate(model, cand.controller, guess=V)
        value = value_at(model, cand.controller, cand_V)
        if value > best + 1e-9 * max(1.0, abs(best)):
            return cand, value, k, cand_V
        k //= 2
    return None


def action_values(model: POMDP, ctrl: Controller, V: np.ndarray, x: np.ndarray) -> np.ndarray:
    """q[n, a]: the value of node n acting a, its edges fixed, at the belief it is visited
    with (visits x, values V).

    With a release cost, q counts the cost of arriving from a stronger demand as well as
    that of leaving to a weaker one: left out, every change moved its predecessors' release
    costs unseen, and m2's rounds lost value (-0.206 against -0.184 from the same solutions).
    So q is the node's exact action value on the model with the last demand in the state
    (hysteresis.py), where the cost is part of the reward."""
    mass = x.sum(axis=1)
    q = fixed_edge_q(model, ctrl, V, x / np.maximum(mass, 1e-300)[:, None])
    if model.release_cost:
        before = demand_before(model, ctrl, x)                                      # (N, A)
        stronger = np.cumsum(before[:, ::-1], axis=1)[:, ::-1]                       # share arriving from >= p
        q = q - model.release_cost * np.hstack([stronger[:, 1:], np.zeros((len(q), 1))])   # from > a
    return q


def action_changes(model: POMDP, lay: Layered, V: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nodes ordered by the gain of their best action (action_values), weighted by their
    visits; that action). Ties go to the stronger braking."""
    q = action_values(model, lay.controller, V, x)
    want = strongest_best(q)
    rows = np.arange(len(want))
    gain = (q[rows, want] - q[rows, lay.action]) * x.sum(axis=1)
    order = np.argsort(-gain, kind="stable")
    return order[gain[order] > 1e-12], want


def edge_values(model: POMDP, lay: Layered, V: np.ndarray, x: np.ndarray) -> np.ndarray:
    """worth[m, b, m2]: the visits-weighted value of sending base edge (m, b) to base node m2.
    An edge of the base serves every memory q of node m and every observation whose base part
    is b, so its worth sums over them, less the release cost into a weaker demand."""
    layer, ctrl = lay.layer, lay.controller
    Q, (M, B) = layer.memories, lay.edges.shape
    V_by = V.reshape(M, Q, -1)
    A_by = ctrl.action.reshape(M, Q)
    worth = np.zeros((M, B, M))          # worth[m, b, m2]: visits-weighted value of sending (m, b) to m2
    for n in np.flatnonzero(x.sum(axis=1) > 1e-12):
        a, (m, q) = int(ctrl.action[n]), divmod(n, Q)
        after = (x[n] @ model.T[a])[:, None] * model.O[a]                     # (S', Z): mass after each o
        for q2 in np.unique(layer.step[q]):
            obs = np.flatnonzero(layer.step[q] == q2)
            gained = after[:, obs].T @ V_by[:, q2, :].T                         # (obs, M)
            if model.release_cost:
                gained = gained - model.release_cost * after[:, obs].sum(axis=0)[:, None] * (A_by[:, q2] < a)[None, :]
            np.add.at(worth[m], layer.base[obs], gained)
    return worth


def edge_changes(model: POMDP, lay: Layered, V: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(base edges (m, b), flattened, ordered by the gain of their best target; that target)."""
    worth = edge_values(model, lay, V, x)
    now = np.take_along_axis(worth, lay.edges[:, :, None], axis=2)[:, :, 0]
    gain = (worth.max(axis=2) - now).ravel()
    order = np.argsort(-gain, kind="stable")
    return order[gain[order] > 1e-12 * max(1.0, float(np.abs(now).max()))], worth.argmax(axis=2).ravel()


def improve_layered(model: POMDP, lay: Layered, rounds: int, say: Callable[[str], None],
                    deadline: Optional[float]) -> tuple[Layered, int]:
    """Point-based policy iteration within the layering: each round changes the actions, then
    the base edges, where the visits-weighted one-step gain on the exact values is positive,
    the most promising first (first_gain); a change is kept only if the exact value at b0
    rises, and every action is raised to monotone. Stops when nothing gains or at `deadline`."""
    V = evaluate(model, lay.controller)
    best, x = value_at(model, lay.controller, V), None
    done = 0
    for done in range(1, rounds + 1):
        if done > 1 and out_of_time(deadline):
            say(f"monotone: time budget reached, stopping before round {done}")
            return lay, done - 1
        moved = []
        start = int((V @ model.b0).argmax())           # any node may start: the best at b0
        if float(V[start] @ model.b0) > best + 1e-9 * max(1.0, abs(best)):
            lay, best = replace(lay, start=start), float(V[start] @ model.b0)
            moved.append("start")
        for kind in ("actions", "edges"):
            if kind == "edges" and out_of_time(deadline):
                break
            x = occupancy(model, lay.controller, guess=x)
            order, want = (action_changes if kind == "actions" else edge_changes)(model, lay, V, x)
            found = first_gain(model, best, order, lambda idx, lay=lay, kind=kind, want=want: lay.changed(kind, idx, want),
                               V) if len(order) else None
            if found:
                lay, best, k, V = found
                moved.append(f"{k} {kind}")
        say(f"monotone: round {done}, " + (", ".join(moved) if moved else "nothing gained")
            + f", exact value {best:.4f}")
        if not moved:
            break
    return lay, done


def improve_actions(model: POMDP, lay: Layered, fallback: np.ndarray, rounds: int, say: Callable[[str], None],
                    deadline: Optional[float]) -> tuple[Layered, int]:
    """Search "actions" (the shipped tables were compiled so): each round every node takes its
    best action with its edges fixed at the belief it is visited with (`fallback` where it is
    never visited), raised to monotone; the release cost only counted on leaving the node.
    The round is kept if the exact value at b0 rises, else the search stops."""
    V = evaluate(model, lay.controller)
    lay = replace(lay, start=int((V @ model.b0).argmax()))
    best = value_at(model, lay.controller, V)
    done = 0
    for done in range(1, rounds + 1):
        if done > 1 and out_of_time(deadline):    # the first round always runs: it makes the layered table
            say(f"monotone: time budget reached, stopping before round {done}")
            return lay, done - 1
        ctrl = lay.controller
        beliefs, mass = node_beliefs(model, ctrl)
        q = fixed_edge_q(model, ctrl, V, np.where(mass[:, None] > 1e-9, beliefs, fallback))
        cand = replace(lay, action=raise_monotone(strongest_best(q), lay.layer))
        if np.array_equal(cand.action, lay.action):
            break
        cand_V = evaluate(model, cand.controller)
        cand = replace(cand, start=int((cand_V @ model.b0).argmax()))
        value = value_at(model, cand.controller, cand_V)
        gained = value > best + 1e-9 * max(1.0, abs(best))
        say(f"monotone: round {done}, {int((cand.action != lay.action).sum())} actions changed, "
            f"exact value {value:.4f}" + ("" if gained else " (no gain, stop)"))
        if not gained:
            break
        lay, V, best = cand, cand_V, value
    return lay, done


def compile_monotone(model: POMDP, sol: Solution, layer: ConditionLayer, max_nodes: int = 255, rounds: int = 12,
                     progress: Optional[Callable[[str], None]] = None, deadline: Optional[float] = None,
                     search: str = "actions") -> Compiled:
    """A controller whose demand never falls when conditions are reported adverse.

    1. compile the base controller on the model with the conditions unobserved, from `sol`,
       the solution of base_model(model, layer) (its alpha vectors are the ones whose
       witnesses the base follows);
    2. layer it: node (m, q) moves like m on the base part and keeps the condition memory q;
    3. improve it, keeping the layering, every action raised to the largest action of any
       (m, q') with q' below q; then merge bisimilar nodes. `search`:
       - "actions" (improve_actions; the shipped tables): all nodes' best actions at once,
         the release cost counted on leaving a node only;
       - "exact" (improve_layered): actions, then base edges, the most promising first, each
         change kept only if the exact value at b0 rises, the release cost counted both ways;
         the base is solved and compiled with the last demand in the state (base_model).
         From the same 60 s budget its tables are worth more in the model (m2: -0.182
         against -0.206) but brake needlessly more in the world at the shipped weights
         (docs/models.md section 5).

    The base gets max_nodes // 2 nodes first (merging usually leaves far fewer than
    base x Q); if the result is still over budget, max_nodes // Q, which always fits.
    """
    from .params import ConfigError

    say = progress or (lambda text: None)
    Q = layer.memories
    if max_nodes < Q:
        raise ConfigError(f"max_nodes must be at least {Q} to keep the demand monotone in the conditions, "
                          f"got {max_nodes}")
    if search not in SEARCHES:
        raise ConfigError(f"unknown layered search {search!r}; known: {', '.join(SEARCHES)}")
    comp = layered_compile(model, sol, layer, max_nodes // 2, rounds, say, deadline, search)
    if comp.controller.nodes > max_nodes:
        say(f"monotone: {comp.controller.nodes} nodes are over the budget of {max_nodes}, base budget lowered")
        comp = layered_compile(model, sol, layer, max_nodes // Q, rounds, say, deadline, search)   # base x Q <= max_nodes
    return comp


def layered_compile(model: POMDP, sol: Solution, layer: ConditionLayer, base_nodes: int, rounds: int,
                    say: Callable[[str], None], deadline: Optional[float] = None, search: str = "actions") -> Compiled:
    """compile_monotone with a base of at most `base_nodes` nodes: every base the compiler
    may start from (controller.candidates: the re-pointed witnesses, the solver's policy
    graph), best first, is layered and improved while time is left, and the best final
    table is kept. The best base does not always make the best table (m2, base solved 75 s:
    the witnesses' base -0.2066 against the graph's -0.2192 ends -0.1973 against -0.2176;
    solved 15 s, the graph's base ends -0.1962 against -0.2072)."""
    bmodel = base_model(model, layer, search)
    found, _ = candidates(bmodel, sol, base_nodes, lambda text: say(f"base {text}"))
    best: Optional[Compiled] = None
    for i, cand in enumerate(found):
        if i and out_of_time(deadline):
            say(f"monotone: time budget reached, the base from the {cand.origin} is not layered")
            break
        comp = layer_and_improve(model, bmodel, cand, layer, rounds, say, deadline, search)
        if best is None or comp.value > best.value:
            best = comp
    return best


def layer_and_improve(model: POMDP, bmodel: POMDP, cand: Candidate, layer: ConditionLayer, rounds: int,
                      say: Callable[[str], None], deadline: Optional[float], search: str) -> Compiled:
    """One base controller layered (node (m, q)) and improved by `search`, merged."""
    Q = layer.memories
    b = cand.controller
    lay = Layered(layer, b.next, np.repeat(b.action, Q), b.start * Q)
    start_value = value_at(model, lay.controller, evaluate(model, lay.controller))
    say(f"monotone: the base from the {cand.origin} layered, {b.nodes} x {Q} nodes, exact value {start_value:.4f}")
    if search == "exact":
        lay, done = improve_layered(model, lay, rounds, say, deadline)
    else:
        # nodes never visited: the base node's belief, weighted by how likely each state reports q
        reports_q = (layer.step == np.arange(Q)[:, None]).astype(float) @ model.O[0].T        # (Q, S)
        beliefs, mass = node_beliefs(bmodel, b)
        seen = np.where(mass[:, None] > 1e-9, beliefs, model.b0)          # the base model here is the reduced one
        fallback = np.repeat(seen, Q, axis=0) * np.tile(reports_q, (b.nodes, 1))
        fallback /= np.maximum(fallback.sum(axis=1, keepdims=True), 1e-300)
        lay, done = improve_actions(model, lay, fallback, rounds, say, deadline)
    ctrl = minimise(lay.controller)
    V = evaluate(model, ctrl)
    value = value_at(model, ctrl, V)
    say(f"monotone: final controller from the {cand.origin}, {ctrl.nodes} nodes, exact value {value:.4f}")
    return Compiled(ctrl, V, value, start_value, done)
