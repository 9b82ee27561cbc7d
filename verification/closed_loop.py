"""Closed-loop analysis of the shipped tables: the Markov chain over (controller node x model
state), solved exactly and cross-checked with Storm.

For each table: the probability of reaching the hazard (m1: the Crash state; m2: any
state at the critical distance level) within a horizon, by bounded reachability (repeated
sparse products), and the expected discounted reward from the start belief, by a linear
solve. Storm (stormpy) computes the same two numbers on the same chain built as a sparse
DTMC: `P=? [F<=H "crash"]`, and the discounted reward as the total reward until an
absorbing stop state entered with probability 1 - discount each step
(`R=? [F "stop"]`, exact by the sparse LU of Eigen). Baselines run on the same chain:
always maintain, always emergency, a threshold rule on the observed zone, and the online
belief-tracking policy with the solver's alpha vectors (seed 000 eq. 14), which is not a
finite-state controller: its reward by a vectorised Monte Carlo, its P(hazard) by the sharp
estimator (sharp_hazard: conditional Monte Carlo guided by the table's exact values), both
with 95 % intervals.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from importlib import resources

import numpy as np
import scipy.sparse as sp

from monitor.core.table import decode
from monitor.offline.closed_chain import bounded_reach, hazard_states, hazard_target, two_phase_chain
from monitor.offline.controller import Controller, evaluate
from monitor.offline.controller import rewards as controller_rewards
from monitor.offline.models import load
from monitor.offline.node_risk import HORIZON_S
from monitor.offline.pipeline import ALPHAS_SUFFIX, model_digest, read_alphas
from monitor.tables import read

from . import sharp_hazard
from .report import Check, Progress, Section, md_table

AGREE = 1e-6


@dataclass
class Figures:
    value: float              # expected discounted reward from the start belief
    crash: float              # P(hazard within the horizon)
    value_ci: float = 0.0     # half-width of a 95 % interval (Monte Carlo only)
    crash_ci: float = 0.0


def table_controller(name: str):
    """(model, controller, table) of a shipped table; the model is rebuilt from the table's
    parameters and must hash to the table's model_sha256."""
    table = decode(read(name))
    model, _ = load(name)
    if model_digest(model) != table.header.get("model_sha256"):
        raise ValueError(f"{name}: the model built today does not hash to the one the table was solved for")
    ctrl = Controller.of_table(table)
    return model, ctrl, table


def hazard_within(model, ctrl: Controller, steps: int) -> tuple[float, sp.csr_matrix, np.ndarray]:
    """(P(hazard within `steps` cycles) from the start node and belief, two-phase chain,
    hazard labels), by bounded reachability."""
    S = model.shape[0]
    P = two_phase_chain(model, ctrl)
    target = hazard_target(model, ctrl.nodes)
    x = bounded_reach(P, target, 2 * steps)
    return float(model.b0 @ x[ctrl.start * S:(ctrl.start + 1) * S]), P, target


def exact(model, ctrl: Controller, steps: int) -> tuple[Figures, sp.csr_matrix, np.ndarray]:
    """(figures, two-phase chain, hazard labels): the value by the exact evaluation the
    compiler uses (a linear solve), the crash probability by bounded reachability."""
    crash, P, target = hazard_within(model, ctrl, steps)
    V = evaluate(model, ctrl)
    return Figures(float(model.b0 @ V[ctrl.start]), crash), P, target


def storm(model, ctrl: Controller, P: sp.csr_matrix, target: np.ndarray, steps: int) -> Figures:
    """The same two figures by Storm on sparse DTMCs built from the two-phase chain."""
    import stormpy

    S = model.shape[0]
    NS = ctrl.nodes * S
    g = model.discount
    r = controller_rewards(model, ctrl)     # R[s, a_n], less the expected release cost
    shift = max(0.0, -float(r.min()))       # Storm's reachability rewards want r >= 0

    def dtmc(matrix: sp.csr_matrix, labels: dict, rewards=None):
        matrix = matrix.tocsr()
        matrix.sort_indices()
        m = matrix.shape[0]
        b = stormpy.datastructures.SparseMatrixBuilder(rows=m, columns=m, entries=matrix.nnz)
        rows = np.repeat(np.arange(m), np.diff(matrix.indptr))
        chunk = 2_000_000
        for i in range(0, matrix.nnz, chunk):
            b.add_next_values(rows[i:i + chunk].tolist(), matrix.indices[i:i + chunk].tolist(),
                              matrix.data[i:i + chunk].tolist(), [])
        lab = stormpy.models.StateLabeling(m)
        for name, states in labels.items():
            lab.add_label(name)
            for s in np.flatnonzero(states):
                lab.add_label_to_state(name, int(s))
        reward_models = {} if rewards is None else {"r": stormpy.models.SparseRewardModel(optional_state_reward_vector=rewards)}
        comp = stormpy.models.SparseModelComponents(transition_matrix=b.build(), state_labeling=lab, reward_models=reward_models)
        return stormpy.models.SparseDtmc(comp)

    env = stormpy.Environment()
    solver = env.solver()
    solver.set_linear_equation_solver_type(stormpy.environments.EquationSolverType.NATIVE)
    native = solver.native()
    native.method = stormpy.environments.NativeLinearEquationSolverMethod.GAUSS_SEIDEL
    native.precision = stormpy.Rational("1e-12")
    native.relative_termination_criterion = False
    start = range(ctrl.start * S, (ctrl.start + 1) * S)
    chain = dtmc(P, {"crash": target})
    res = stormpy.model_checking(chain, stormpy.parse_properties(f'P=? [F<={2 * steps} "crash"]')[0], environment=env)
    crash = sum(model.b0[i] * res.get_value(s) for i, s in enumerate(start))
    # discounting as a stop probability on the A states: total reward until "stop" = discounted reward
    n = P.shape[0]
    scale = sp.diags(np.r_[np.full(NS, g), np.ones(NS)])
    leave = sp.csr_matrix((np.full(NS, 1.0 - g), (np.arange(NS), np.zeros(NS, dtype=int))), shape=(n, 1))
    stop = sp.vstack([sp.hstack([scale @ P, leave]), sp.csr_matrix(([1.0], ([0], [n])), shape=(1, n + 1))]).tocsr()
    rewards = np.r_[r + shift, np.zeros(NS), 0.0]
    chain = dtmc(stop, {"stop": np.r_[np.zeros(n, dtype=bool), True]}, list(rewards))
    res = stormpy.model_checking(chain, stormpy.parse_properties('R{"r"}=? [F "stop"]')[0], environment=env)
    value = sum(model.b0[i] * res.get_value(s) for i, s in enumerate(start)) - shift / (1.0 - g)
    return Figures(float(value), float(crash))


def baselines(model) -> dict[str, Controller]:
    """Finite-state baselines: constant actions and a threshold rule on the observed zone
    (emergency braking when the last observation is the emergency or critical zone)."""
    A, Z = model.shape[1], model.shape[2]
    zone = np.array([o if model.name == "m1" else o // (len(model.observations) // 4) for o in range(Z)])
    out = {}
    for a, name in ((0, "always maintain"), (A - 1, "always emergency")):
        out[name] = Controller(np.array([a]), np.zeros((1, Z), dtype=np.int64), 0)
    # node z = "the last observed zone was z" (0 free .. 3 critical), node 4 = start
    action = np.array([0, 0, A - 1, A - 1, 0])
    nxt = np.tile(zone, (5, 1))
    out["threshold on zone"] = Controller(action, nxt, 4)
    return out


def belief_policy(model, alphas: np.ndarray, actions: np.ndarray, steps: int, episodes: int, seed: int = 0) -> Figures:
    """The online POMDP policy: belief by eq. 14, action of the best alpha vector, simulated
    for `episodes` runs at once; discounted reward truncated at `steps` (error below
    discount^steps * max|R| / (1 - discount)) and hazard within `steps`."""
    rng = np.random.default_rng(seed)
    S = model.shape[0]
    T, O, R, g = model.T, model.O, model.R, model.discount
    state = rng.choice(S, size=episodes, p=model.b0)
    belief = np.tile(model.b0, (episodes, 1))
    hazard = np.zeros(S, dtype=bool)
    hazard[hazard_states(model)] = True
    hit = hazard[state].copy()
    total = np.zeros(episodes)
    disc = 1.0
    cumT = np.cumsum(T, axis=2)
    cumO = np.cumsum(O, axis=2)
    for _ in range(steps):
        a = actions[np.argmax(belief @ alphas.T, axis=1)]
        total += disc * R[state, a]
        disc *= g
        u = rng.random(episodes)
        nxt = (u[:, None] > cumT[a, state]).sum(axis=1)
        nxt = np.minimum(nxt, S - 1)
        u = rng.random(episodes)
        obs = np.minimum((u[:, None] > cumO[a, nxt]).sum(axis=1), O.shape[2] - 1)
        # eq. 14 for every episode: b'(s') ~ O[a, s', o] * sum_s b(s) T[a, s, s']
        pred = np.empty_like(belief)
        for act in range(T.shape[0]):
            rows = a == act
            if rows.any():
                pred[rows] = belief[rows] @ T[act]
        post = pred * O[a, :, obs]          # (episodes, S): O[a_e, :, o_e]
        norm = post.sum(axis=1, keepdims=True)
        belief = np.where(norm > 0, post / np.where(norm > 0, norm, 1.0), belief)
        state = nxt
        hit |= hazard[state]
    ci = lambda x: 1.96 * float(np.std(x, ddof=1)) / math.sqrt(len(x))  # noqa: E731
    return Figures(float(total.mean()), float(hit.mean()), ci(total), ci(hit.astype(float)))


def _figure(out_dir, results: dict) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(results), figsize=(6 * len(results), 7), constrained_layout=True, squeeze=False)
    for j, (model, rows) in enumerate(results.items()):
        names = list(rows)
        for i, (key, label) in enumerate((("value", "expected discounted reward"), ("crash", f"P(hazard within {HORIZON_S:g} s)"))):
            ax = axes[i, j]
            vals = [getattr(rows[n], key) for n in names]
            errs = [getattr(rows[n], key + "_ci") for n in names]
            colors = ["tab:blue" if n == "table" else "tab:gray" for n in names]
            ax.barh(names, vals, xerr=errs, color=colors)
            ax.set_title(f"{model}: {label}")
            ax.invert_yaxis()
    name = "closed_loop.png"
    fig.savefig(out_dir / name, dpi=90)
    plt.close(fig)
    return name


SHARP_SEED = 12


def sharp_episodes(model, quick: bool) -> int:
    """Episodes of the sharp estimate (full: evaluate's sizes). Quick: m2's 250 give about
    +-12 %, inside the 25 % the check asks."""
    return sharp_hazard.episodes_for(model, 250 if quick else 4000)


def section(out_dir, quick: bool, progress: Progress) -> Section:
    steps = int(round(HORIZON_S / 0.1))
    episodes = 2000 if quick else 20000
    checks: list[Check] = []
    results: dict = {}
    md = [f"The closed loop of each shipped table and its model, as a Markov chain over (controller "
          f"node, model state). Hazard: m1's Crash state; m2's critical distance level. Horizon "
          f"{HORIZON_S:g} s ({steps} cycles). Exact figures: bounded reachability by repeated sparse "
          "products, discounted reward by the compiler's linear solve. Storm: the same chain as a sparse "
          "DTMC, `P=? [F<=H \"crash\"]` and the discounted reward as the total reward until a stop state "
          "entered with probability 1 - discount (Gauss-Seidel to 1e-12). The belief-tracking policy "
          "(seed 000 eq. 14 with the solver's alpha vectors) is not a finite-state controller: its reward is "
          f"simulated over {episodes} episodes of {steps} cycles, its P(hazard) by the sharp estimator "
          "(conditional Monte Carlo with the exact next-step hazard, importance sampling guided by the table's "
          "exact values: verification/sharp_hazard.py), both with 95 % intervals. As everywhere in this section, "
          "no supervision in front: the bare policies.\n"]
    for name in ("m1", "m2"):
        progress(f"closed loop {name}: exact")
        model, ctrl, table = table_controller(name)
        t0 = time.perf_counter()
        ex, P, target = exact(model, ctrl, steps)
        t_exact = time.perf_counter() - t0
        progress(f"closed loop {name}: storm ({P.nnz:,} transitions)")
        t0 = time.perf_counter()
        try:
            st = storm(model, ctrl, P, target, steps)
            storm_error = None
        except ImportError as exc:
            st, storm_error = None, f"stormpy not importable: {exc}"
        t_storm = time.perf_counter() - t0
        header_value = float(table.header["controller_value"])
        checks.append(Check(f"closed loop {name}: exact value equals the table header's", abs(ex.value - header_value) <= 1e-9,
                            f"{ex.value:.9f} vs {header_value:.9f}"))
        if st is None:
            checks.append(Check(f"closed loop {name}: Storm cross-check", False, storm_error))
        else:
            dc, dv = abs(st.crash - ex.crash), abs(st.value - ex.value)
            checks.append(Check(f"closed loop {name}: Storm agrees on P(hazard within {HORIZON_S:g} s)", dc <= AGREE,
                                f"|{st.crash:.12f} - {ex.crash:.12f}| = {dc:.1e} <= {AGREE:g}", {"storm": st.crash, "exact": ex.crash}))
            checks.append(Check(f"closed loop {name}: Storm agrees on the discounted reward", dv <= AGREE,
                                f"|{st.value:.10f} - {ex.value:.10f}| = {dv:.1e} <= {AGREE:g}", {"storm": st.value, "exact": ex.value}))
        rows = {"table": ex}
        for bname, bctrl in baselines(model).items():
            progress(f"closed loop {name}: baseline {bname}")
            rows[bname], _, _ = exact(model, bctrl, steps)
        progress(f"closed loop {name}: belief-tracking policy, {episodes} episodes")
        alphas, actions = read_alphas(resources.files("monitor.tables").joinpath(f"{name}{ALPHAS_SUFFIX}"), table.sha256)
        online = belief_policy(model, alphas, actions, steps, episodes)
        progress(f"closed loop {name}: belief-tracking policy, sharp P(hazard)")
        sharp = sharp_hazard.estimate(model, sharp_hazard.belief_tracking(model, alphas, actions), steps,
                                      sharp_episodes(model, quick), SHARP_SEED,
                                      guides=(sharp_hazard.Guide(model, ctrl, steps, supervision=False),),
                                      supervision=False)
        rows["belief tracking (online)"] = Figures(online.value, sharp.p, online.value_ci, sharp.ci)
        results[name] = rows
        worse = [b for b in ("always maintain", "always emergency", "threshold on zone") if rows[b].value > ex.value]
        checks.append(Check(f"closed loop {name}: the table beats every finite-state baseline on its objective", not worse,
                            "beaten: none" if not worse else f"better than the table: {', '.join(worse)}"))
        trunc = model.discount ** steps * float(np.abs(model.R).max()) / (1 - model.discount)
        md.append(f"\n### {name} ({ctrl.nodes} nodes x {model.shape[0]} states; exact {t_exact:.1f} s, "
                  f"Storm {t_storm:.1f} s)\n")
        md.append(md_table(["policy", "expected discounted reward", f"P(hazard within {HORIZON_S:g} s)", "how"],
                           [[p, f"{f.value:.4f}" + (f" ± {f.value_ci:.3f}" if f.value_ci else ""),
                             f"{f.crash:.6f}" + (f" ± {f.crash_ci:.2g}" if f.crash_ci else ""),
                             "Monte Carlo (reward), sharp estimate (P)" if f.value_ci else "exact"]
                            for p, f in rows.items()]))
        if st is not None:
            md.append(f"\nStorm: reward {st.value:.10f}, P(hazard) {st.crash:.12f}.")
        md.append(f" The Monte Carlo reward is truncated at {steps} cycles (bias at most {trunc:.2g}).\n")
        frozen = rows["belief tracking (online)"]
        md.append(f"\nBelief tracking's P(hazard): sharp {sharp.p:.4g} ± {sharp.ci:.2g} ({sharp.relative:.1%} of the "
                  f"estimate, {sharp.episodes:,} episodes, {sharp.seconds:.1f} s); plain Monte Carlo over the "
                  f"{episodes:,} reward episodes {online.crash:.4g} ± {online.crash_ci:.2g}.\n")
        # the plain interval; with no hit in n episodes, the rule of three's 95 % upper bound 3 / n
        lo, hi = max(0.0, online.crash - online.crash_ci), max(online.crash + online.crash_ci, 3.0 / episodes)
        checks.append(Check(f"closed loop {name}: belief tracking's sharp P(hazard) agrees with plain Monte Carlo",
                            sharp.p - sharp.ci <= hi and sharp.p + sharp.ci >= lo
                            and sharp.ci <= sharp_hazard.RELATIVE_HALF_WIDTH * sharp.p,
                            f"{sharp.p:.4g} ± {sharp.ci:.2g} meets [{lo:.3g}, {hi:.3g}]; "
                            f"half-width {sharp.relative:.1%} <= {sharp_hazard.RELATIVE_HALF_WIDTH:.0%}",
                            {"sharp": sharp.as_dict(), "plain": online.crash, "plain_ci": online.crash_ci}))
        md.append(f"\nPrice of freezing the policy into {ctrl.nodes} nodes: online belief tracking "
                  f"{frozen.value:.3f} ± {frozen.value_ci:.3f} against the table's {ex.value:.3f}.\n")
    fig = _figure(out_dir, results)
    md.append(f"\n![policies compared]({fig})\n")
    return Section("Closed-loop analysis of the shipped tables", "".join(md), checks, [fig])
