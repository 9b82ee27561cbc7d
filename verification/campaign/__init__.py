"""Fault-injection campaign: every single fault and every pair of faults from a catalogue,
crossed with obstacle scenarios, through the monitor core, the real runner and codec on the
virtual bus, and real SocketCAN vcan0 in the user-mode-Linux sandbox.

Core-level runs (the bulk, >= 10,000 in full mode, two processes): a small simulated world
(a train that brakes as its braking declaration guarantees at worst, six sensor channels
with Gaussian distance noise, the obstacle scenario) drives `monitor.core.cycle` directly.
Each fault acts where it acts in the product:

* value faults (stuck, noise burst, missed detection, contradiction) change a channel's report
  before it is framed, exactly as `can_bus.player.Player` does;
* frame faults (CRC corruption, counter freeze and jump, wrong length, babbling) are injected
  into real frames (`can_bus.codec.Sender`) that go through the real `can_bus.codec.Receiver`
  from shortly before the fault until after it (healthy frames are latched directly: the
  receiver accepts every one of them), so the reject counters are the codec's own;
* silence: no frame; stale timestamps: the report handed to the core carries a tick from the
  past (older than the timeout) or from the future; deadline overrun: `Inputs.overruns`
  counts consecutive late cycles and the late cycle's demand reaches the brakes one period
  late; a corrupted or mismatched table: `cycle.create` must refuse it (ConfigurationError),
  and the train is then held at the entry under an emergency demand.

Each run counts an *unsafe outcome* (at some cycle a voted obstacle, or a true obstacle at
the true speed, inside the emergency intervention curve EBI of `monitor.core.braking.curves`
with the run's configuration while the monitor demands less than emergency at that cycle and
at the next one), crashes (any exception, in the harness, the codec's receive path or
swallowed by the core's fail-safe), collisions, *false braking* (a brake demand while no true
obstacle is within sensor range that is not the reaction to a fault the monitor diagnosed)
and, the wider measure, *braking without an obstacle* (any such demand, fault reactions and
trains held at the entry included). Every fault kind is shown detected by its named
diagnostic in every single-fault run in which it manifested. Ghost runs (a 0.3 s phantom on
one channel beyond SBI, clear track, 40 m/s) must never bring the train to a standstill.

`run(quick, progress, config=cfg)` and `section(out_dir, quick, progress, config=cfg)` take
the monitor's Config (a braking declaration applied: `monitor.declaration`); the world's
train brakes as that declaration guarantees.

The pieces, one concept each: `catalogue` (the fault kinds, their injection and diagnostic),
`scenarios` (the worlds and their sensors), `specs` (the plan: combinations x scenarios x
seeds, each run's faults), `tables` (shipped and faulty table files), `world` (one
core-level run in the simulated world), `judge` (false braking, detection, the verdict on a
bus run), `runs` (core-level jobs on the cluster, the ghost runs), `bus` (the virtual-bus
sample through the real runner), `sandbox` (vcan0 in the user-mode-Linux sandbox),
`counts` (aggregates and the runs digest), `summary` (`run`: the whole campaign), `report`
(the Markdown and its tables), `figures` (the heatmap) and `part` (`section`, its checks,
`main`; `__main__` runs it). This package re-exports their public names (and `_work`, the
core-level job the benchmark times), so `from verification import campaign` reads as before.
"""
from __future__ import annotations

from .catalogue import (
    CATALOGUE, CHANNEL_KINDS, FRAME_KINDS, HOSTILE, HOSTILE_KINDS, KINDS, PLAYER_KINDS, REJECT_OF, TABLE_KINDS, VALUE_KINDS,
    FaultKind,
)
from .scenarios import (
    GHOST_NAME, GHOST_SCENARIO, NOISE_SIGMA_M, PERIOD_MS, RANGE_M, SCENARIOS, SCENARIO_BY_NAME, SCENARIO_NAMES,
    UNAVOIDABLE, world_scenario,
)
from .specs import SEEDS, Fault, RunSpec, combos, instantiate, plan
from .tables import faulty_table, shipped_setup, shipped_table
from .judge import (
    FAULT_REACTION, bus_detection, evaluate_bus, false_braking_cycles, first_diagnostic, reaction_to_fault,
)
from .world import BURST_FACTOR, OBSTACLE_TYPES, ROUTE_AFTER_S, ROUTE_BEFORE_S, SETTLE_S, core_step, simulate
from .runs import CHUNK, GHOST_S, _work, ghost_plan, ghost_summary, run_core, run_ghosts
from .bus import BusSpec, bus_plan, bus_run, bus_scenario, bus_work, counting_core
from .sandbox import VCAN_SCENARIO, vcan_guest, vcan_plan, vcan_sample
from .counts import OUTCOME_KEYS, aggregate, bus_summary, runs_digest, vruns_detail
from .summary import run
from .report import BEFORE_QUICK, faults_by_scenarios_table, faults_table, markdown, pct
from .figures import heatmap
from .part import FALSE_BRAKING_LIMIT, checks, main, section

__all__ = [
    "CATALOGUE", "CHANNEL_KINDS", "FRAME_KINDS", "HOSTILE", "HOSTILE_KINDS", "KINDS", "PLAYER_KINDS", "REJECT_OF",
    "TABLE_KINDS", "VALUE_KINDS",
    "FaultKind", "GHOST_NAME", "GHOST_SCENARIO", "NOISE_SIGMA_M", "PERIOD_MS", "RANGE_M", "SCENARIOS",
    "SCENARIO_BY_NAME", "SCENARIO_NAMES", "UNAVOIDABLE", "world_scenario", "SEEDS", "Fault", "RunSpec", "combos",
    "instantiate", "plan", "faulty_table", "shipped_setup", "shipped_table", "FAULT_REACTION", "bus_detection",
    "evaluate_bus", "false_braking_cycles", "first_diagnostic", "reaction_to_fault", "BURST_FACTOR", "OBSTACLE_TYPES",
    "ROUTE_AFTER_S", "ROUTE_BEFORE_S", "SETTLE_S", "core_step", "simulate", "CHUNK", "GHOST_S", "_work", "ghost_plan",
    "ghost_summary", "run_core", "run_ghosts", "BusSpec", "bus_plan", "bus_run", "bus_scenario", "bus_work",
    "counting_core", "VCAN_SCENARIO", "vcan_guest", "vcan_plan", "vcan_sample", "OUTCOME_KEYS", "aggregate",
    "bus_summary", "runs_digest", "vruns_detail", "run", "BEFORE_QUICK", "faults_by_scenarios_table", "faults_table",
    "markdown", "pct", "heatmap", "FALSE_BRAKING_LIMIT", "checks", "main", "section",
]
