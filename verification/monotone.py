"""Adverse conditions are monotone (issue 11, deliverable 3): an exhaustive check of a table.

Model 2's observation carries the track condition and the brake status the train reports.
Whatever the history, answering it with slippery track or degraded brakes reported must
never give a lower demand than answering the same history with normal ones. The check runs
the table's controller against a copy of itself: from (start, start), the first copy reads
o and the second o', where o' is o with the track and/or the brake raised to adverse (every
such pair, o' = o included, so conditions may come and go). Every reachable pair of nodes
(n, n') must have action[n'] >= action[n]. The search is breadth-first, so a violation is
reported with a shortest history that shows it. A table without condition components
(Model 1) pairs each observation only with itself and passes trivially.
"""
from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from monitor.core.observation import M2_COMPONENTS
from monitor.core.table import Table, TableError, decode

from .report import Check, Progress, Section, md_table

# (position in an observation name split on "-", normal level, adverse level)
CONDITIONS = ((3, M2_COMPONENTS[3][0], M2_COMPONENTS[3][1]), (4, M2_COMPONENTS[4][0], M2_COMPONENTS[4][1]))


@dataclass(frozen=True)
class Step:
    """One cycle of a history: what each run observed and the node it moved to."""

    normal: str
    adverse: str
    normal_node: int
    adverse_node: int


@dataclass(frozen=True)
class Result:
    """The check's verdict; on a violation, a shortest history ending in it."""

    table: str                  # model name and short hash
    nodes: int
    observation_pairs: int
    pairs_reached: int
    violations: int             # reachable node pairs with action[n'] < action[n]
    history: tuple[Step, ...]   # empty when monotone
    demands: tuple[str, str] = ("", "")   # (normal, adverse) demand at the history's end

    @property
    def monotone(self) -> bool:
        return self.violations == 0

    def describe(self) -> str:
        """A one-line verdict, or the counterexample history cycle by cycle."""
        head = (f"{self.table}: {self.pairs_reached} node pairs reached over {self.observation_pairs} "
                f"observation pairs, {self.violations} violating")
        if self.monotone:
            return head + "; monotone"
        lines = [head + f"; a shortest history ({len(self.history)} cycles), normal | adverse:"]
        for i, s in enumerate(self.history, 1):
            lines.append(f"  {i:3d}. {s.normal:<36} -> node {s.normal_node:3d} | "
                         f"{s.adverse:<36} -> node {s.adverse_node:3d}")
        lines.append(f"  demand: {self.demands[0]} with normal conditions, {self.demands[1]} with adverse ones")
        return "\n".join(lines)


def raised(name: str) -> list[str]:
    """Every observation name that is `name` with some condition components raised to adverse
    (`name` itself included)."""
    parts = name.split("-")
    out = [parts]
    for pos, normal, adverse in CONDITIONS:
        if pos < len(parts) and parts[pos] == normal:
            out = out + [p[:pos] + [adverse] + p[pos + 1:] for p in out]
    return ["-".join(p) for p in out]


def observation_pairs(observations: tuple[str, ...]) -> np.ndarray:
    """(P, 2) index pairs (o, o') with o' = o raised to adverse in any condition components."""
    index = {name: i for i, name in enumerate(observations)}
    pairs = [(i, index[r]) for i, name in enumerate(observations) for r in raised(name) if r in index]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def check(table: Table) -> Result:
    """Breadth-first over the product controller; see the module docstring."""
    action = np.array(table.action, dtype=np.int64)
    nxt = np.array(table.next, dtype=np.int64)
    N = len(action)
    obs = observation_pairs(table.observations)
    start = table.start * N + table.start          # a pair (n, n') is the id n * N + n'
    came_from = {start: (start, -1)}               # pair -> (predecessor, observation pair used)
    frontier = np.array([start], dtype=np.int64)
    violations, shallowest = 0, None
    while len(frontier):
        bad = frontier[action[frontier % N] < action[frontier // N]]
        violations += len(bad)
        if shallowest is None and len(bad):
            shallowest = int(bad[0])
        succ = (nxt[frontier // N][:, obs[:, 0]] * N + nxt[frontier % N][:, obs[:, 1]]).ravel()
        ids, first = np.unique(succ, return_index=True)
        new = np.array([i not in came_from for i in ids.tolist()], dtype=bool)
        for pair, k in zip(ids[new].tolist(), first[new].tolist()):
            came_from[pair] = (int(frontier[k // len(obs)]), k % len(obs))
        frontier = ids[new]
    history: list[Step] = []
    demands = ("", "")
    if shallowest is not None:
        p = shallowest
        demands = (table.actions[action[p // N]], table.actions[action[p % N]])
        while p != start:
            prev, k = came_from[p]
            history.append(Step(table.observations[obs[k, 0]], table.observations[obs[k, 1]], p // N, p % N))
            p = prev
        history.reverse()
    return Result(f"{table.model} {table.sha256[:12]}", N, len(obs), len(came_from), violations,
                  tuple(history), demands)


def check_bytes(data: bytes) -> Result:
    return check(decode(data))


def section(out_dir: Path, quick: bool, progress: Progress) -> Section:
    """`railguard verify` part: the exhaustive check on each shipped table (quick or not:
    the check is exhaustive and takes well under a second)."""
    from monitor import tables

    rows, checks, texts = [], [], []
    for name in tables.SHIPPED:
        progress(f"monotone: {name}")
        res = check_bytes(tables.read(name))
        rows.append([name, res.nodes, res.observation_pairs, res.pairs_reached, res.violations])
        checks.append(Check(f"{name}: adverse conditions never lower the table's demand", res.monotone,
                            f"{res.violations} violating of {res.pairs_reached} reachable node pairs",
                            {"history": [asdict(s) for s in res.history]}))
        if not res.monotone:
            texts.append("```\n" + res.describe() + "\n```\n")
    md = ("The table's controller run against itself, one copy reading the observation with normal "
          "conditions and the other the same observation with slippery track and/or degraded brakes "
          "reported; every reachable pair of nodes must demand at least as much on the adverse side.\n\n"
          + md_table(["table", "nodes", "observation pairs", "node pairs reached", "violating"], rows)
          + "".join(texts))
    return Section("Adverse conditions are monotone", md, checks)


def main(argv: Optional[list[str]] = None) -> int:
    """`python -m verification.monotone [TABLE ...]`: the verdict for each table (default:
    the shipped ones); exit 1 if one fails the check, 2 if one cannot be read."""
    from monitor import tables

    specs = (argv if argv is not None else sys.argv[1:]) or list(tables.SHIPPED)
    ok = True
    for spec in specs:
        try:
            res = check_bytes(tables.read(spec))
        except (OSError, TableError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(res.describe())
        ok &= res.monotone
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
