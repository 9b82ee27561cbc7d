"""A warning confirmed before the table escalates on it (issue 41 item 2: demand changes).

Why: in Model 1 an obstacle enters the line in the emergency zone and reaches the warning
zone only after braking, so from a quiet start a run of "warning" observations is, to the
model, a run of phantoms too rare to price. The compiled table still escalates on it: m1's
brakes after four warnings in a row (node 23 service, then emergency). The world has that
run every time a train that stopped short of an obstacle moves off again: the slow train
sees the obstacle in its warning zone, the table brakes it to a standstill after a few
metres, the standstill clears the zones and the table releases. Measured in seed 000's
world (full size, seed 12): 220 stops per train-hour, 41 demand changes per encounter,
against belief tracking's 168 and 28.8. The model cannot choose how long to wait (10 cycles
move the exact P(hazard) by 0.008 % and the value by 0.0003 %): the world does.

What: on the path that repeated warnings take from the quiet node (where the start settles
under "free"), `cycles` copies of the last node before the first braking one are put in
front of it; each copy acts and reads every other observation as that node does, so a
warning that lasts `cycles` more cycles escalates as before and any other observation leaves
the path as before. The braking curves supervise every cycle in front of the table, whatever
it waits for.

The table header records the paths and the node count before (`undone` restores the table),
with P(hazard within the horizon) and the value before and after, computed exactly.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from .closed_chain import zone_of_observation
from .controller import Controller, evaluate, value_at
from .node_risk import HORIZON_S
from .risk_repair import hazard

WARNING_ZONE = 1


@dataclass(frozen=True)
class Confirmed:
    """A controller with its warning paths lengthened, and what the header records."""

    controller: Controller
    cycles: int
    nodes_before: int
    paths: tuple[tuple[int, int, int], ...]     # (last node before braking, observation, first braking node)

    def entry(self, model, before: Controller, steps: int) -> tuple[dict, np.ndarray]:
        """(the header's `warning_confirmation` entry, the exact values V[n, s] after):
        what it changed, with P(hazard within `steps` cycles) and the value (release cost
        included) of `before` and after, exact."""
        V = evaluate(model, self.controller)
        return {"cycles": self.cycles, "nodes_before": self.nodes_before, "paths": [list(p) for p in self.paths],
                "horizon_s": HORIZON_S, "p_hazard_before": hazard(model, before, steps),
                "p_hazard": hazard(model, self.controller, steps),
                "value_before": value_at(model, before, evaluate(model, before)),
                "value": value_at(model, self.controller, V)}, V


def quiet_node(ctrl: Controller, free: int) -> Optional[int]:
    """Where the start settles when nothing but `free` is observed (None: it never settles)."""
    node = ctrl.start
    for _ in range(ctrl.nodes + 1):
        if ctrl.next[node, free] == node:
            return node if ctrl.action[node] == 0 else None
        node = int(ctrl.next[node, free])
    return None


def warning_path(ctrl: Controller, quiet: int, obs: int) -> Optional[tuple[int, int]]:
    """(last node before the first braking one, that braking node) on the path `obs` repeated
    takes from `quiet`; None when it never brakes."""
    node, seen = quiet, {quiet}
    while True:
        nxt = int(ctrl.next[node, obs])
        if ctrl.action[nxt] > 0:
            return node, nxt
        if nxt in seen:
            return None
        seen.add(nxt)
        node = nxt


def confirm(model, ctrl: Controller, cycles: int) -> Confirmed:
    """The controller with `cycles` copies on each warning observation's path (module
    docstring); unchanged when cycles is 0, the model has no warning zone or the table never
    escalates on warnings alone."""
    if cycles < 0:
        raise ValueError(f"cycles must be >= 0, got {cycles}")
    zones = zone_of_observation(model)
    free = np.flatnonzero(zones == 0)
    quiet = quiet_node(ctrl, int(free[0])) if len(free) else None
    paths = []
    if cycles and quiet is not None:
        for obs in np.flatnonzero(zones == WARNING_ZONE):
            found = warning_path(ctrl, quiet, int(obs))
            if found is not None:
                paths.append((found[0], int(obs), found[1]))
    action, nxt = [ctrl.action], [ctrl.next.copy()]
    count = ctrl.nodes
    for src, obs, dst in paths:
        copies = np.tile(nxt[0][src], (cycles, 1))
        copies[:, obs] = np.r_[np.arange(count + 1, count + cycles), dst]
        nxt[0][src, obs] = count
        action.append(np.full(cycles, ctrl.action[src]))
        nxt.append(copies)
        count += cycles
    out = Controller(np.concatenate(action), np.vstack(nxt), ctrl.start)
    return Confirmed(out, cycles if paths else 0, ctrl.nodes, tuple(paths))


def undone(ctrl: Controller, entry: dict) -> Controller:
    """The controller without the confirmation its header `entry` records."""
    n = int(entry["nodes_before"])
    if not 0 < n <= ctrl.nodes or any(not (0 <= s < n and 0 <= d < n and ctrl.next[s, o] == n + k * entry["cycles"])
                                      for k, (s, o, d) in enumerate(entry["paths"])):
        raise ValueError("the header's warning_confirmation does not describe this controller")
    nxt = ctrl.next[:n].copy()
    for src, obs, dst in entry["paths"]:
        nxt[src, obs] = dst
    return Controller(ctrl.action[:n].copy(), nxt, ctrl.start)


def confirmation_lines(entry: Optional[dict]) -> list[str]:
    """What the confirmation changed and cost, for a person (solve summary, `table show`)."""
    if not entry:
        return []
    return [f"confirmation     a warning alone escalates {entry['cycles']} cycles later ({len(entry['paths'])} path"
            f"{'' if len(entry['paths']) == 1 else 's'}, {entry['cycles'] * len(entry['paths'])} nodes added): "
            f"P(hazard within {entry['horizon_s']:g} s) {entry['p_hazard_before']:.4g} -> {entry['p_hazard']:.4g}, "
            f"value {entry['value_before']:.4f} -> {entry['value']:.4f}"]
