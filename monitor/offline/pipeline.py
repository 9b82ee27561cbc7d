"""Model -> solver -> controller -> table file: the offline job behind `railguard solve`."""
from __future__ import annotations

import hashlib
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from .. import __version__
from ..core import table as table_format
from . import pomdp_file
from .closed_chain import hazard_states
from .confirmation import confirm, confirmation_lines, undone
from .controller import Compiled, Controller, compilation_loss_percent, compile_controller, plain_value
from .layered import ConditionLayer, base_model, compile_monotone
from .models import Plan, rebuild
from .params import ConfigError
from .node_risk import HORIZON_S, node_risk
from .node_risk import describe as describe_risk
from .risk_repair import Repair, monotone_pairs, repair
from .table_view import risk_range
from .pomdp import POMDP
from .relaxation import Relaxation, describe_upper
from .bounds import single_threaded_blas
from .solver import Progress, Solution, solve

TABLE_SUFFIX = ".table.rgt"
ALPHAS_SUFFIX = ".alphas.npz"


def write_alphas(path: Path, sol: Solution, table_sha256: str) -> None:
    """The solver's alpha vectors and their actions, tied to the table solved with them, for
    the online belief-tracking policy (seed 000 eq. 14) that verification compares with."""
    write_alphas_arrays(path, sol.alphas, sol.actions, table_sha256)


def write_alphas_arrays(path: Path, alphas: np.ndarray, actions: np.ndarray, table_sha256: str) -> None:
    np.savez_compressed(path, alphas=alphas, actions=actions, table_sha256=np.array(table_sha256))


def read_alphas(path: Path, table_sha256: str) -> tuple[np.ndarray, np.ndarray]:
    """(alphas, actions) of a table; refuses alpha vectors from another solve."""
    with np.load(path) as data:
        if str(data["table_sha256"]) != table_sha256:
            raise ValueError(f"{path}: alpha vectors belong to table {str(data['table_sha256'])[:12]}, not {table_sha256[:12]}")
        return data["alphas"].copy(), data["actions"].copy()


@dataclass
class Result:
    model: POMDP
    plan: Plan
    solution: Solution
    compiled: Compiled
    table: bytes
    seconds: float
    relaxed: Optional["RelaxedBound"] = None
    plain_value: Optional[float] = None      # the table's value without the release cost (controller.plain_value)
    shipped: Optional[dict] = None           # the shipped table of the same model, if any (against_shipped)
    repair: Optional[dict] = None            # the risk repair's figures (repair_entry), if the plan asks for one
    confirmation: Optional[dict] = None      # the warning confirmation's (confirmation.py), if the plan asks for one

    @property
    def sha256(self) -> str:
        return table_format.decode(self.table).sha256

    @property
    def upper_bound(self) -> float:
        return certified_upper(self.solution, self.relaxed)


@dataclass(frozen=True)
class RelaxedBound:
    """An information relaxation's upper bound at the start belief (relaxation.py): it bounds
    the model's optimum as well as the model's own sawtooth does, often far better."""

    reveals: str
    upper_bound: float
    iterations: int

    def entry(self, model_upper: float) -> dict:
        """The table header's `relaxation` entry, beside the model's own bound."""
        return {"reveals": self.reveals, "upper_bound": self.upper_bound, "iterations": self.iterations,
                "model_upper_bound": model_upper}


def certified_upper(sol: Solution, relaxed: Optional[RelaxedBound]) -> float:
    """The tightest upper bound on the model's optimum at b0 that the run holds."""
    return min(sol.upper_bound, relaxed.upper_bound) if relaxed is not None else sol.upper_bound


def model_digest(model: POMDP) -> str:
    """SHA-256 of a model's names and arrays: ties a table to the exact model it solves."""
    h = hashlib.sha256()
    for names in (model.states, model.actions, model.observations):
        h.update("\x1f".join(names).encode() + b"\x1e")
    for arr in (model.T, model.O, model.R, model.b0):
        h.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
    h.update(repr(model.discount).encode())
    if model.release_cost:
        h.update(b"release_cost" + repr(model.release_cost).encode())
    return h.hexdigest()


def table_header(model: POMDP, plan: Plan, sol: Solution, comp: Compiled,
                 relaxed: Optional[RelaxedBound] = None, repaired: Optional[dict] = None,
                 confirmed: Optional[dict] = None) -> dict:
    """Everything a reader needs to trust and interpret the table; nothing time-dependent."""
    extra = {} if relaxed is None else {"relaxation": relaxed.entry(sol.upper_bound)}
    if repaired is not None:
        extra["risk_repair"] = repaired
    if confirmed is not None:
        extra["warning_confirmation"] = confirmed
    return {
        "format": "railguard-table",
        "railguard_version": __version__,
        "model": model.name,
        "params": dict(model.params),
        "model_sha256": model_digest(model),
        "discount": model.discount,
        "states": list(model.states),
        "actions": list(model.actions),
        "observations": list(model.observations),
        "start": comp.controller.start,
        "lower_bound": sol.lower_bound,
        "upper_bound": certified_upper(sol, relaxed),
        **extra,
        "controller_value": comp.value,
        "naive_controller_value": comp.naive_value,
        "solver": {
            **asdict(plan.settings),
            "max_nodes": plan.max_nodes,
            **({"monotone_in": list(plan.conditions), "layered_search": plan.layered_search} if plan.conditions else {}),
            "iterations": sol.iterations,
            "stop_reason": sol.stop_reason,
            "alpha_vectors": int(len(sol.alphas)),
        },
    }


SOLVE_SHARE = 0.45    # of the time budget: the solver's part; compilation starts no round after 90 %
COMPILE_SHARE = 0.9
BASE_SHARE = 0.25     # with conditions: the conditions-blind base model's solve; the full model's
                      # (its bounds certify the table) runs on to SOLVE_SHARE
RELAX_SHARE = 0.85    # with a relaxation: its solve uses what compilation left, up to this; the risk
                      # column comes after it (m2, 162 nodes: 10 s), and the run must end in its budget
REPAIR_SHARE = 0.8    # the risk repair starts no round that would end after this (m1: 0.2 s; an m2
                      # round takes about 40 s, so a 60 s solve has none: `railguard table repair`)
RELAXED_COMPILE_SHARE = 0.7   # with a relaxation, compilation starts no round after this: m2's layered
                              # table gains a round (60 s solve: -0.1978 -> -0.1962, 6.21 % -> 4.57 %
                              # below the lower bound without release cost) and the relaxation's bound
                              # loses little (-0.1241 -> -0.1207 against the model's own -0.1190)
MIN_RELAX_S = 2.0     # fewer seconds left than this: the relaxation is not started
RELAX_FLOOR_SHARE = 0.1   # the relaxation's least time: a compile round that overran RELAX_SHARE (a
                          # loaded machine: CI's realtime phase, 2026-12-01) still leaves it this much
                          # of the budget, and the run ends that much late rather than without its bound


def run(model: POMDP, plan: Plan, progress: Optional[Callable[[Progress], None]] = None,
        compile_progress: Optional[Callable[[str], None]] = None) -> Result:
    """Solve, compile and evaluate within `plan.settings.time_budget_s` for the whole run:
    the solver stops at SOLVE_SHARE of it, compilation starts no new round after
    COMPILE_SHARE (the round under way and the final exact evaluation still finish).

    A table that must be monotone in reported conditions (plan.conditions) is built on a
    memory that does not see them (layered.compile_monotone). That memory comes from
    solving the model with the conditions unobserved (layered.base_model), up to BASE_SHARE: following the full
    model's alpha vectors on beliefs that cannot see the conditions lost half the value
    (Model 2: -1.29 against -0.68 at the same weights). The full model is solved after it,
    for the bounds that certify the table and the alpha vectors written beside it."""
    with single_threaded_blas():       # compilation too: on a loaded machine OpenBLAS's spinning threads
        return _run(model, plan, progress, compile_progress)     # made a 90 s m2 run take 111 s


def _run(model: POMDP, plan: Plan, progress: Optional[Callable[[Progress], None]],
         compile_progress: Optional[Callable[[str], None]]) -> Result:
    start = time.perf_counter()
    budget = plan.settings.time_budget_s
    say = compile_progress or (lambda text: None)
    relax = plan.relaxation(model) if plan.relaxation else None
    deadline = start + (RELAXED_COMPILE_SHARE if relax is not None else COMPILE_SHARE) * budget
    if relax is not None:
        relax.check(model)            # before any solving: a bad relaxation must not cost the run
    if plan.conditions:
        layer = ConditionLayer.of(model.observations, plan.conditions)
        say("base: solving the model with the conditions unobserved")
        base_sol = solve(base_model(model, layer, plan.layered_search), plan.settings, progress, deadline=start + BASE_SHARE * budget)
        say("solving the full model (its bounds certify the table)")
        sol = solve(model, plan.settings, progress, deadline=start + SOLVE_SHARE * budget)
        comp = compile_monotone(model, base_sol, layer, max_nodes=plan.max_nodes, progress=compile_progress,
                                deadline=deadline, search=plan.layered_search)
    else:
        sol = solve(model, plan.settings, progress, deadline=start + SOLVE_SHARE * budget)
        comp = compile_controller(model, sol, max_nodes=plan.max_nodes, progress=compile_progress, deadline=deadline)
    repaired = None
    if plan.hazard_price > 0 and len(hazard_states(model)):
        fixed = repair(model, comp.controller, horizon_cycles(model), plan.hazard_price,
                       layer if plan.conditions else None, say, deadline=start + REPAIR_SHARE * budget)
        comp, repaired = replace(comp, controller=fixed.controller, values=fixed.values, value=fixed.value), \
            repair_entry(fixed, plan.hazard_price)
    confirmation = None
    if plan.warning_confirmation:
        part: dict = {}
        try:
            ctrl, entry, V = _confirmed(model, part, comp.controller, plan.warning_confirmation,
                                        layer if plan.conditions else None)
        except ValueError as exc:
            raise ConfigError(f"[solver] warning_confirmation: {exc}") from None
        if "warning_confirmation" in part:
            confirmation, comp = entry, replace(comp, controller=ctrl, values=V, value=entry["value"])
    relaxed = relaxed_bound(relax, plan, relax_deadline(start, budget), say) if relax else None
    ctrl = comp.controller
    say("risk column: each node's P(hazard within the horizon) on the exact closed loop")
    data = encode_with_risk(table_header(model, plan, sol, comp, relaxed, repaired, confirmation), model, ctrl)
    plain = plain_value(model, ctrl) if model.release_cost else comp.value     # (no release cost: the same value)
    return Result(model, plan, sol, comp, data, time.perf_counter() - start, relaxed, plain, against_shipped(model),
                  repaired, confirmation)


def horizon_cycles(model: POMDP) -> int:
    """The cycles of the hazard horizon (HORIZON_S) at the model's time step."""
    return int(round(HORIZON_S / time_step_of(model)))


def repair_entry(fixed: Repair, price: float) -> dict:
    """The table header's `risk_repair` entry: what the repair bought and paid."""
    return {"hazard_price": price, "horizon_s": HORIZON_S, "p_hazard_before": fixed.p_before,
            "p_hazard": fixed.p_hazard, "value_before": fixed.value_before, "value": fixed.value,
            "raised": fixed.raised()}


def as_compiled(table: table_format.Table) -> Controller:
    """The table's controller as compiled, before its risk repair and warning confirmation (the
    header's entries undone): the controller the same alpha vectors gave, which guides belief
    tracking's sharp hazard estimate (a guide much safer than the policy it guides is not one)."""
    ctrl = Controller.of_table(table)
    if "warning_confirmation" in table.header:
        try:
            ctrl = undone(ctrl, table.header["warning_confirmation"])
        except ValueError:
            return ctrl               # a header copied onto another controller: nothing to undo
    raised = table.header.get("risk_repair", {}).get("raised", [])
    if not all(0 <= n < ctrl.nodes and ctrl.action[n] == after for n, _before, after in raised):
        return ctrl
    action = ctrl.action.copy()
    for node, before, _after in raised:
        action[node] = before
    return Controller(action, ctrl.next, ctrl.start)


def _opened(data: bytes) -> tuple[table_format.Table, POMDP, Controller, dict, Optional[dict],
                                  Optional[ConditionLayer]]:
    """(table, its model, its controller without a warning confirmation, its own header without
    that entry, the entry, the condition layer it is monotone in)."""
    old = table_format.decode(data)
    model = rebuild(dict(old.header))
    header = own_header(old)
    ctrl = Controller.of_table(old)
    entry = header.pop("warning_confirmation", None)
    if entry:
        ctrl = undone(ctrl, entry)
    monotone_in = old.header.get("solver", {}).get("monotone_in")
    layer = ConditionLayer.of(model.observations, tuple(monotone_in)) if monotone_in else None
    return old, model, ctrl, header, entry, layer


def _confirmed(model: POMDP, header: dict, ctrl: Controller, cycles: int,
               layer: Optional[ConditionLayer]) -> tuple[Controller, dict, np.ndarray]:
    """(the controller with its warnings confirmed `cycles` cycles, the entry, its exact values);
    refused where adverse conditions would lower the demand; the header's entry and controller
    value follow."""
    conf = confirm(model, ctrl, cycles)
    pairs = monotone_pairs(conf.controller, layer)
    if pairs is not None and (conf.controller.action[pairs[:, 1]] < conf.controller.action[pairs[:, 0]]).any():
        raise ValueError(f"a {cycles}-cycle confirmation would let adverse reported conditions lower the demand "
                         "(the table must stay monotone in them)")
    entry, values = conf.entry(model, ctrl, horizon_cycles(model))
    if conf.paths:
        header["warning_confirmation"] = entry
    header["controller_value"] = entry["value"]
    return conf.controller, entry, values


def repaired(data: bytes, price: float, say: Callable[[str], None] = lambda text: None,
             deadline: Optional[float] = None) -> tuple[bytes, Repair]:
    """A table file with its actions raised by the risk repair at `price` (`railguard table
    repair`): the header's controller value and `risk_repair` entry follow, the risk column is
    recomputed; the rest of the header (bounds, solver) is the solve's. A warning confirmation
    is undone before and redone after, as `railguard solve` orders them (the model prices the
    wait it adds as a free raise)."""
    old, model, ctrl, header, confirmation, layer = _opened(data)
    fixed = repair(model, ctrl, horizon_cycles(model), price, layer, say, deadline=deadline)
    first = old.header.get("risk_repair", {})
    entry = repair_entry(fixed, price)
    if first:                                 # a table repaired before: the figures run from its compile
        compiled = as_compiled(old).action
        entry.update(p_hazard_before=first["p_hazard_before"], value_before=first["value_before"],
                     raised=[[int(n), int(compiled[n]), int(a)]
                             for n, a in enumerate(fixed.controller.action) if a != compiled[n]])
    header.update(controller_value=fixed.value, risk_repair=entry)
    ctrl = fixed.controller
    if confirmation:
        ctrl = _confirmed(model, header, ctrl, confirmation["cycles"], layer)[0]
    return encode_with_risk(header, model, ctrl), fixed


def confirmed(data: bytes, cycles: int) -> tuple[bytes, dict]:
    """A table file whose warnings are confirmed `cycles` cycles (`railguard table confirm`):
    a confirmation the header records is undone first, so 0 gives the table without one.
    The header's controller value and `warning_confirmation` entry follow (the entry's
    figures run from the unconfirmed table), the risk column is recomputed."""
    _old, model, ctrl, header, _entry, layer = _opened(data)
    ctrl, entry, _values = _confirmed(model, header, ctrl, cycles, layer)
    return encode_with_risk(header, model, ctrl), entry


def own_header(table: table_format.Table) -> dict:
    """A decoded table's header without what encoding derives (size, index width, format, risk)."""
    return {k: v for k, v in table.header.items() if k not in ("nodes", "index_bytes", "format_version", "risk")}


def encode_with_risk(header: dict, model: POMDP, ctrl: Controller) -> bytes:
    """A table file of the controller with its risk column computed on the model's exact chain."""
    step = time_step_of(model)
    return table_format.encode(header, ctrl.action.tolist(), ctrl.next.tolist(), node_risk(model, ctrl, step).tolist(),
                               describe_risk(model, step))


def against_shipped(model: POMDP) -> Optional[dict]:
    """The shipped table solved for this very model (same name and model digest), as its
    header and `table show` value it: what a quick solve is measured against (issue 41 item
    4: the shipped tables may take 30 minutes, the solve users and CI run 60 s). None when
    no shipped table was solved for this model (other parameters, a .pomdp file)."""
    from ..tables import SHIPPED, read
    from .controller import Controller

    if model.name not in SHIPPED:
        return None
    table = table_format.decode(read(model.name))
    if table.header.get("model_sha256") != model_digest(model):
        return None
    # the same model: valued on it directly, not rebuilt from the header as `table show` must
    plain = plain_value(model, Controller.of_table(table)) if model.release_cost else table.header["controller_value"]
    return {"sha256": table.sha256, "nodes": table.nodes, "controller_value": table.header["controller_value"],
            "controller_value_without_release_cost": plain, "lower_bound": table.header["lower_bound"]}


def time_step_of(model: POMDP) -> float:
    """The model's cycle in seconds (the papers' 0.1 s when a test model does not say)."""
    return float(model.params.get("time_step_s", 0.1))


def with_risk(data: bytes) -> tuple[bytes, table_format.Table]:
    """A table file (format 1 or 2) re-encoded in the current format with its risk column
    recomputed; the controller is unchanged, so only the header's risk and the digest move."""
    old = table_format.decode_for_upgrade(data)
    return encode_with_risk(own_header(old), rebuild(dict(old.header)), Controller.of_table(old)), old


def relax_deadline(start: float, budget: float) -> float:
    """When the relaxation's solve stops: at RELAX_SHARE of the budget, but never less than
    RELAX_FLOOR_SHARE of it from now."""
    return max(start + RELAX_SHARE * budget, time.perf_counter() + RELAX_FLOOR_SHARE * budget)


def relaxed_bound(relax: Relaxation, plan: Plan, deadline: float, say: Callable[[str], None]) -> Optional[RelaxedBound]:
    """Solve a checked information relaxation until `deadline` for its upper bound at b0;
    None when too little time is left."""
    left = deadline - time.perf_counter()
    if left < MIN_RELAX_S:
        say(f"upper bound: no time left for the information relaxation ({left:.1f} s)")
        return None
    say(f"upper bound: solving the information relaxation ({relax.label}) for {left:.0f} s")

    def tick(p: Progress) -> None:
        if p.iteration % 25 == 0:
            say(f"  relaxation iter {p.iteration:4d}  upper {p.upper:.4f}  {p.elapsed:5.1f} s")

    rs = solve(relax.model, plan.settings, tick, deadline=deadline)
    say(f"upper bound: relaxation {rs.upper_bound:.4f} after {rs.iterations} iterations")
    return RelaxedBound(relax.label, rs.upper_bound, rs.iterations)


def write(result: Result, out_dir: str | Path) -> dict[str, Path]:
    """Write the table, the model as .pomdp and a readable summary; return their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = result.model.name
    paths = {
        "table": out / f"{name}{TABLE_SUFFIX}",
        "pomdp": out / f"{name}.pomdp",
        "summary": out / f"{name}.summary.txt",
        "alphas": out / f"{name}{ALPHAS_SUFFIX}",
    }
    paths["table"].write_bytes(result.table)
    write_alphas(paths["alphas"], result.solution, result.sha256)
    pomdp_file.write(result.model, paths["pomdp"])
    paths["summary"].write_text(summary_text(result), encoding="utf-8")
    return paths


def figures(result: Result) -> dict:
    """The numbers `railguard solve --json` reports (paths are added by the caller)."""
    S, A, Z = result.model.shape
    sol, comp, upper = result.solution, result.compiled, result.upper_bound
    return {
        "model": result.model.name,
        "states": S,
        "actions": A,
        "observations": Z,
        "nodes": comp.controller.nodes,
        "lower_bound": sol.lower_bound,
        "upper_bound": upper,
        "model_upper_bound": sol.upper_bound,
        "relaxation_upper_bound": result.relaxed.upper_bound if result.relaxed else None,
        "gap": upper - sol.lower_bound,
        "certified_gap": upper - comp.value,
        "certified_gap_percent": gap_percent(upper, comp.value),
        "controller_value": comp.value,
        "naive_controller_value": comp.naive_value,
        "release_cost": result.model.release_cost,
        "controller_value_without_release_cost": result.plain_value,
        "compilation_loss_percent": (None if result.plain_value is None
                                     else compilation_loss_percent(sol.lower_bound, result.plain_value)),
        "shipped": result.shipped,
        "risk_repair": result.repair,
        "warning_confirmation": result.confirmation,
        "iterations": sol.iterations,
        "stop_reason": sol.stop_reason,
        "seconds": result.seconds,
        "time_budget_s": result.plan.settings.time_budget_s,
        "peak_rss_mb": peak_rss_mb(),
        "table_bytes": len(result.table),
        "sha256": result.sha256,
    }


def compilation_lines(plain: Optional[float], release_cost: float, loss: Optional[float]) -> list[str]:
    """The table's value on the lower bound's objective and the compilation loss, for a person
    (the solve summary and `railguard table show`)."""
    if plain is None or loss is None:
        return []
    paid = f"the value above pays {release_cost:g} per release; " if release_cost else ""
    return [f"compilation      {plain:.4f}   ({paid}without release cost, the lower bound's objective: "
            f"{abs(loss):.2f} % {'below' if loss > 0 else 'above'} the lower bound)"]


def shipped_lines(f: dict) -> list[str]:
    """How this table compares with the shipped one of the same model, for a person."""
    ship = f.get("shipped")
    if not ship:
        return []
    diff = f["controller_value"] - ship["controller_value"]
    plain = ("" if f["controller_value_without_release_cost"] is None or not f["release_cost"] else
             f", {f['controller_value_without_release_cost'] - ship['controller_value_without_release_cost']:+.4f}"
             " without the release cost")
    return [f"shipped table    {ship['controller_value']:.4f}   ({ship['nodes']} nodes, {ship['sha256'][:12]}; "
            f"this table {diff:+.4f}{plain}: {'better' if diff > 0 else 'not better'} than the shipped one)"]


def repair_lines(entry: Optional[dict]) -> list[str]:
    """What the risk repair bought and paid, for a person (the solve summary, `table repair`)."""
    if not entry:
        return []
    n = len(entry["raised"])
    return [f"risk repair      P(hazard within {entry['horizon_s']:g} s) {entry['p_hazard_before']:.3g} -> "
            f"{entry['p_hazard']:.3g} for {entry['value_before'] - entry['value']:.4f} of value ({n} node"
            f"{'' if n == 1 else 's'} raised, each round at most {entry['hazard_price']:g} per unit of probability)"]


def gap_percent(upper: float, value: float) -> float:
    """(upper - value) as a percentage of |upper|: how the solver's and the table's gaps are printed."""
    return 100.0 * (upper - value) / max(1e-12, abs(upper))


def peak_rss_mb() -> float:
    """This process's peak resident memory so far (Linux reports ru_maxrss in KiB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def summary_text(result: Result) -> str:
    f, own = figures(result), result.solution.upper_bound
    gap_to_ub = f["upper_bound"] - f["controller_value"]
    lines = [
        f"model            {f['model']}  ({f['states']} states, {f['actions']} actions, {f['observations']} observations)",
        f"solver           {result.plan.settings.method}, {f['iterations']} iterations, stopped on {f['stop_reason']}, "
        f"{f['seconds']:.1f} s (solve + compile, budget {f['time_budget_s']:g} s), peak memory {f['peak_rss_mb']:.0f} MB",
        f"lower bound      {f['lower_bound']:.4f}   (alpha vectors at the start belief)",
        f"upper bound      {f['upper_bound']:.4f}   ({describe_upper(own, result.relaxed and result.relaxed.entry(own))})",
        f"controller value {f['controller_value']:.4f}   (exact, {f['nodes']} nodes; witness-following before improvement: {f['naive_controller_value']:.4f})",
        *compilation_lines(f["controller_value_without_release_cost"], f["release_cost"], f["compilation_loss_percent"]),
        *repair_lines(f["risk_repair"]),
        *confirmation_lines(f["warning_confirmation"]),
        f"remaining gap    {gap_to_ub:.4f}   (upper bound - controller value: {f['certified_gap_percent']:.2f} % of |upper bound|;"
        " the table is within this of the optimum)",
        f"table            {f['table_bytes']} bytes, sha256 {f['sha256']}",
        f"risk             {risk_range(table_format.decode(result.table))}",
        *shipped_lines(f),
    ]
    return "\n".join(lines) + "\n"
