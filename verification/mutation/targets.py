"""What is mutated and what judges it: the Python core's files and fast tests, the C core's
decision functions and the comparison test, the job count, the subsets CI and the quick
report run, and where the repository and the equivalents list are.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable


ROOT = Path(__file__).resolve().parents[2]             # the repository: mutant ids are paths relative to it
CORE = ROOT / "monitor" / "core"
EQUIVALENTS = ROOT / "verification" / "mutation_equivalents.toml"
PY_FILES = ("voter.py", "freshness.py", "observation.py", "envelope.py", "memory.py", "cycle.py", "braking.py",
            "config.py", "table.py", "types.py", "risk.py", "plausibility.py", "tracks.py")
# the tests run against every Python mutant, fastest killers first (-x stops at the first failure)
PY_TESTS = ("tests/test_core_mutants.py", "tests/test_memory_mutants.py", "tests/test_tracks.py", "tests/test_plausibility.py",
            "tests/test_core_memory.py",
            "tests/test_core_cycle.py", "tests/test_supervision.py", "tests/test_core_tables.py", "tests/test_table.py",
            "tests/test_core_stateful.py", "tests/test_risk.py")     # risk.py's killer last: reached only by what the others let through
# per mutated file, the test files that kill most of its mutants, run before the rest of the
# same selection (the set of tests is unchanged, so is the verdict: only a killed mutant's
# time is, the passing files before its killer no longer run first). Measured on CI's
# scopes: memory.py's 52 mutants took 2.1 s each with test_core_mutants.py first, 0.5 s
# after; observation.py's table mutants 4.1 s
KILLERS_FIRST = {"memory.py": ("tests/test_memory_mutants.py", "tests/test_tracks.py"),
                 "observation.py": ("tests/test_core_tables.py",)}


def tests_for(mutated: str, tests: tuple[str, ...]) -> tuple[str, ...]:
    """`tests` with the mutated file's usual killers first (those of them that are selected)."""
    first = tuple(t for t in KILLERS_FIRST.get(Path(mutated).name, ()) if t in tests)
    return first + tuple(t for t in tests if t not in first)
JOBS = 2
C_DIR = ROOT / "fmu" / "c"
C_FILES = ("fmu/c/core/rg_core.c",)
# sequences per table of the comparison test for each C mutant (the test itself runs 5000;
# its minimum edge hits are scaled down with it): a mutant that survives these is reported
# as a survivor even if the full test would kill it, so the score can only be too low
C_SEQUENCES = 1000
# the C mutants are judged by the Python-vs-C comparison alone
C_TESTS = ("tests/test_fmu_equivalence.py",)
# the functions of rg_core.c that are mutated: freshness and range, the voters, the zones,
# the supervision ladder, combine, the hold (the latch's successor), the table's hold, the
# supervision of voted and remembered obstacle and the decision (issue 29), the obstacle
# memory (prediction, observation, forgetting, the remembered distance), the speed class,
# the plausibility check and the several tracks (issue 38: relation, assign, absorb, merge,
# order, insert, each track's supervision)
# (the decisions the Python-vs-C comparison must pin; the curve arithmetic, rg_step's
# plumbing, the configuration and table checks and SHA-256 are not mutated yet)
C_FUNCTIONS = ("rg_in_range", "rg_is_fresh", "rg_effective_status", "rg_vote_2oo2", "rg_disagreement",
               "rg_distances_disagree", "rg_vote_3oo3", "rg_zone", "rg_supervision_demand", "rg_combine", "rg_hold",
               "rg_table_hold", "rg_supervised_demand", "rg_decide", "rg_accel_run", "rg_near_travel",
               "rg_far_travel", "rg_observe", "rg_forget", "rg_seen_beyond", "rg_track_dm", "speed_class", "rg_plaus_anchor",
               "rg_plaus_continues", "rg_plausibility", "rg_relation", "rg_assign", "rg_absorbed", "rg_merge",
               "rg_order_pair", "rg_ordered", "rg_insert_full", "rg_insert", "rg_remembered_demand")

Progress = Callable[[str], None]

# the subsets: CI's (tests/test_mutation.py: CI_SCOPES, `--scope` of these) and `railguard
# verify --quick`'s; CI's holds the voters, freshness, observation, the envelope (zones,
# ladder, combine, the holds) and the obstacle memory's decisions (observe, forget)
CI_FILES = ("voter.py", "freshness.py", "observation.py", "envelope.py")
CI_SCOPES = CI_FILES + ("memory.py:observe", "memory.py:seen_beyond", "memory.py:forget")   # (plausibility.py: the full run and --scope)
REPORT_QUICK_FILES = ("voter.py",)     # `railguard verify --quick`: the voters (tests/test_mutation.py runs CI_SCOPES)
