"""The papers' models by name, with their default solver settings.

`load("m2", "my.toml")` builds a model with the file's overrides: top-level keys set model
parameters, a `[solver]` table sets solver settings and `max_nodes`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Optional

from ..layered import SEARCHES
from ..params import ConfigError, override, read_toml
from ..pomdp import POMDP
from ..relaxation import Relaxation
from ..solver import SolverSettings
from . import model1, model2


@dataclass(frozen=True)
class Plan:
    """How to solve and compile: solver settings, the compiler's node budget (a warning
    confirmation adds its nodes after it), the
    observation components (by position in the names) whose adverse levels must never
    lower the demand (empty: no such constraint), and an information relaxation whose
    upper bound may certify the table more tightly than the model's own (none: no such);
    `layered_search`: how a table monotone in the conditions is improved (layered.SEARCHES);
    `hazard_price`: the value the compiled table may give up per unit of P(hazard within
    30 s) removed by raising its actions (risk_repair.py; 0: not repaired);
    `warning_confirmation`: cycles a warning alone must last longer before the table escalates
    on it (confirmation.py; 0: as compiled)."""

    settings: SolverSettings
    max_nodes: int = 255
    conditions: tuple[int, ...] = ()
    relaxation: Optional[Callable[[POMDP], Relaxation]] = None
    layered_search: str = "actions"
    hazard_price: float = 0.0
    warning_confirmation: int = 0


# Model 1's hazard price: |R(Crash)| / (1 - discount) = 1000 / 0.05, a hazard anywhere in the
# 30 s horizon priced as the model prices one reached now and held (its discount prices one 10 s
# away at 0.6 % of that). Measured (issue 41): the 7 raises it buys take P(hazard) from 9.06e-4
# to 3.72e-5 for 1.12 of value, and in the seed 000 world leave needless braking as it was.
# Model 2 is not repaired: at 10,000 per unit its raises take P(hazard) from 3.14e-5 to only
# 2.81e-5 (belief tracking: 2.41e-5) and brake needlessly more in its world (+0.0013, quick).
M1_HAZARD_PRICE = 20_000.0
# Model 1's warning confirmation, in 0.1 s cycles: the least of 0, 5, 10, 20, 40 whose demand
# changes per encounter are better than belief tracking's in seed 000's world at full size (seed
# 12, paired one-sided test at 5 %; 5: -0.40 +- 1.4, indistinguishable; 10: -2.82 +- 1.5) with
# needless braking not worse than belief tracking's and the threshold rule's (docs/models.md
# section 9). P(hazard within 30 s) 3.7214e-5 -> 3.7217e-5, value -0.0004, both exact.
M1_WARNING_CONFIRMATION = 10


@dataclass(frozen=True)
class ModelSpec:
    title: str
    params: Any
    build: Callable[[Any], POMDP]
    plan: Plan


MODELS = {
    "m1": ModelSpec(
        "seed 000: 4-state anti-collision POMDP (zones)",
        model1.Model1Params(),
        model1.build,
        Plan(SolverSettings(max_beliefs=200, max_iterations=400, expand_every=10), max_nodes=32,
             hazard_price=M1_HAZARD_PRICE, warning_confirmation=M1_WARNING_CONFIRMATION),
    ),
    "m2": ModelSpec(
        "seed 001: 144-state anti-collision POMDP (distance, speed, type, track, brake)",
        model2.Model2Params(),
        model2.build,
        Plan(SolverSettings(max_beliefs=500, max_iterations=100000, expand_every=5, time_budget_s=60.0, target_gap=0.001),
             max_nodes=255,
             conditions=model2.CONDITIONS,
             relaxation=model2.relaxation),
    ),
}


def plan_from(config: dict, plan: Plan) -> Plan:
    """Apply a `[solver]` table to a plan (unknown keys refused)."""
    solver = config.get("solver", {})
    if not isinstance(solver, dict):
        raise ConfigError("[solver] must be a table")
    solver = dict(solver)
    max_nodes = solver.pop("max_nodes", plan.max_nodes)
    if isinstance(max_nodes, bool) or not isinstance(max_nodes, int) or not 1 <= max_nodes <= 65535:
        raise ConfigError(f"max_nodes must be a whole number in 1..65535, got {max_nodes!r}")
    search = solver.pop("layered_search", plan.layered_search)
    if search not in SEARCHES:
        raise ConfigError(f"layered_search must be one of {', '.join(SEARCHES)}, got {search!r}")
    price = solver.pop("hazard_price", plan.hazard_price)
    if isinstance(price, bool) or not isinstance(price, (int, float)) or not 0 <= price < float("inf"):
        raise ConfigError(f"hazard_price must be a number >= 0 (value per unit of P(hazard); 0: no repair), got {price!r}")
    cycles = solver.pop("warning_confirmation", plan.warning_confirmation)
    if isinstance(cycles, bool) or not isinstance(cycles, int) or not 0 <= cycles <= 1000:
        raise ConfigError(f"warning_confirmation must be a whole number of cycles in 0..1000 (0: none), got {cycles!r}")
    return replace(plan, settings=override(plan.settings, solver), max_nodes=max_nodes, layered_search=search,
                   hazard_price=float(price), warning_confirmation=cycles)


def load(name: str, config_path: Optional[str | Path] = None) -> tuple[POMDP, Plan]:
    """Build a named model, applying a TOML file's overrides if one is given."""
    if name not in MODELS:
        raise ConfigError(f"unknown model {name!r}; known: {', '.join(MODELS)}")
    spec = MODELS[name]
    config = read_toml(config_path) if config_path else {}
    params = {k: v for k, v in config.items() if k != "solver"}
    try:
        p = override(spec.params, params)
    except ConfigError as exc:
        raise ConfigError(f"{config_path}: {exc}") from None
    try:
        plan = plan_from(config, spec.plan)
    except ConfigError as exc:
        raise ConfigError(f"{config_path}: {exc}") from None
    return spec.build(p), plan


def rebuild(header: dict) -> POMDP:
    """The model a table was solved for, rebuilt from its header's parameters; refused
    unless it hashes to the header's model_sha256 (the table answers exactly this model)."""
    from ..pipeline import model_digest

    name = header.get("model")
    if name not in MODELS:
        raise ConfigError(f"the table's model {name!r} is not one of the papers' models ({', '.join(MODELS)})")
    spec = MODELS[name]
    params = dict(header.get("params", {}))
    params.setdefault("zones", "paper")      # tables solved before the monitor's zones were the default
    try:
        model = spec.build(override(spec.params, params))
    except (ConfigError, ValueError) as exc:
        raise ConfigError(f"the table's model parameters cannot be rebuilt: {exc}") from None
    if model_digest(model) != header.get("model_sha256"):
        raise ConfigError(f"{name} rebuilt from the table's parameters does not hash to its model_sha256 "
                          "(solved with another version of the model)")
    return model


def plan_for_pomdp_file(config_path: Optional[str | Path]) -> Plan:
    """Settings for a model read from a .pomdp file: only a [solver] table is allowed."""
    if not config_path:
        return default_plan()
    config = read_toml(config_path)
    extra = [k for k in config if k != "solver"]
    if extra:
        raise ConfigError(f"{config_path}: a .pomdp model takes only a [solver] table, not {', '.join(map(repr, extra))}")
    try:
        return plan_from(config, default_plan())
    except ConfigError as exc:
        raise ConfigError(f"{config_path}: {exc}") from None


def default_plan() -> Plan:
    """Settings for a model read from a .pomdp file."""
    return Plan(SolverSettings(), max_nodes=255)


__all__ = ["MODELS", "Plan", "load", "plan_from", "plan_for_pomdp_file", "default_plan", "rebuild"]
