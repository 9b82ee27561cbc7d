"""Values that flow through one cycle of the monitor. Integers only (DESIGN.md section 4):
distance in decimetres, speed in cm/s, deceleration in mm/s^2, time in integer ticks (ms).
"""
from __future__ import annotations

from typing import NamedTuple

# Channel and module status, ordered so that the maximum is the safe side (seed 002, sec. 2).
ABSENT, PRESENT, DEGRADED = 0, 1, 2
STATUS_NAMES = ("ABSENT", "PRESENT", "DEGRADED")

# Obstacle types (seed 001: static object, dynamic object, another train).
STATIC, DYNAMIC, TRAIN = 0, 1, 2
# Track condition and brake status of the train.
TRACK_NORMAL, TRACK_SLIPPERY = 0, 1
BRAKE_NORMAL, BRAKE_DEGRADED = 0, 1

# Brake demand levels, the table's action indices.
MAINTAIN, SERVICE, EMERGENCY = 0, 1, 2
DEMAND_NAMES = ("none", "service", "emergency")

# Modes (documented in docs/core.md).
INIT, NORMAL, DEGRADED_MODE, SAFE_STOP = 0, 1, 2, 3
MODE_NAMES = ("INIT", "NORMAL", "DEGRADED", "SAFE_STOP")

# Reason bits: which rules asked for the demand.
R_TABLE = 1 << 0         # the policy table asked for braking
R_ENVELOPE = 1 << 1      # voted obstacle inside the emergency intervention curve (EBI)
R_SYSTEM_ERROR = 1 << 2  # 2oo2 flag, 3oo3 disagreement or degraded module
R_LATCH = 1 << 3         # emergency latched until standstill
R_INIT = 1 << 4          # not every channel fresh yet
R_SAFE_STOP = 1 << 5     # perceptor error or repeated deadline overruns
R_STALE = 1 << 6         # at least one channel stale, out of range or never heard
R_PERCEPTOR = 1 << 7     # a 2oo2 disagreement persisted
R_DEADLINE = 1 << 8      # deadline overruns reached the limit
R_TRAIN_INPUT = 1 << 9   # train state out of range
R_SBI = 1 << 10          # voted obstacle inside the service intervention curve (SBI): service
R_WARNING = 1 << 11      # voted obstacle inside the warning curve, or a disputed obstacle
R_DISPUTE = 1 << 12      # channels disagree about an obstacle while all are fresh: graded answer
REASON_NAMES = ("table", "envelope", "system_error", "latch", "init", "safe_stop",
                "stale", "perceptor", "deadline", "train_input", "sbi", "warning", "dispute")

# Documented input ranges; anything outside counts as DEGRADED (or as a train-input error).
MAX_DISTANCE_DM = 60000      # 6 km
MAX_CLOSING_CMS = 15000      # |closing speed| up to 150 m/s
MAX_SPEED_CMS = 12000        # 432 km/h
MAX_TICK = (1 << 62) - 1
NO_DISTANCE = 65535          # no obstacle distance to report
MAX_COUNT = (1 << 31) - 1    # counters saturate here (32-bit FMI Integer outputs, the C core)


class Report(NamedTuple):
    """The newest valid report of one sensor channel, with the tick it was received."""

    status: int          # ABSENT / PRESENT / DEGRADED
    distance_dm: int     # distance to the obstacle, 0..MAX_DISTANCE_DM
    closing_cms: int     # relative speed, positive when closing
    obstacle: int        # STATIC / DYNAMIC / TRAIN
    tick: int            # tick the report was received


class Train(NamedTuple):
    speed_cms: int = 0
    track: int = TRACK_NORMAL
    brake: int = BRAKE_NORMAL


class Inputs(NamedTuple):
    """What the shell hands the core each cycle. `reports[i]` is None if channel i was never heard."""

    reports: tuple
    train: Train = Train()
    overruns: int = 0    # consecutive deadline overruns counted by the shell


class State(NamedTuple):
    mode: int
    node: int
    latched: bool
    seen: int            # bit i: channel i has been fresh at least once
    disagree: tuple      # per module: consecutive cycles of ABSENT/PRESENT disagreement
    healthy: int         # consecutive error-free cycles
    cycle: int
    error_cycles: int
    calm: int = 0        # cycles in a row without an emergency cause while the emergency is held


class Outputs(NamedTuple):
    demand: int
    reasons: int
    distance_dm: int     # voted distance, NO_DISTANCE if none
    node: int
    mode: int
    module_flags: int    # bit m: module m raised its 2oo2 flag
    system_error: bool
    observation: int
    cycle: int
    error_cycles: int
    warning: bool = False  # the supervision warns (obstacle inside the warning curve, or disputed)
