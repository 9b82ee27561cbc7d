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
R_LATCH = 1 << 3         # a demand held that no current cause asks for (until standstill or its release)
R_INIT = 1 << 4          # not every channel fresh yet
R_SAFE_STOP = 1 << 5     # perceptor error or repeated deadline overruns
R_STALE = 1 << 6         # at least one channel stale, out of range or never heard
R_PERCEPTOR = 1 << 7     # a 2oo2 disagreement persisted
R_DEADLINE = 1 << 8      # deadline overruns reached the limit
R_TRAIN_INPUT = 1 << 9   # train state out of range
R_SBI = 1 << 10          # voted obstacle inside the service intervention curve (SBI): service
R_WARNING = 1 << 11      # voted obstacle inside the warning curve, or a disputed obstacle
R_DISPUTE = 1 << 12      # channels disagree about an obstacle while all are fresh: graded answer
R_MEMORY = 1 << 13       # the curves supervise a remembered obstacle that no channel shows this cycle
R_IMPLAUSIBLE = 1 << 14  # a channel's distance does not move as its closing speed says (counted DEGRADED)
REASON_NAMES = ("table", "envelope", "system_error", "latch", "init", "safe_stop",
                "stale", "perceptor", "deadline", "train_input", "sbi", "warning", "dispute", "memory", "implausible")

# Obstacle memory (monitor/core/memory.py): why the track is what it is this cycle.
TRACK_NONE, TRACK_SEEN, TRACK_HELD, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_PASSED = range(6)
TRACK_NAMES = ("none", "seen", "held", "confirming", "forgotten", "passed")

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


NO_TRACK = -1            # no remembered obstacle
TRACKS = 3               # remembered obstacles kept at once (monitor/core/tracks.py; RG_TRACKS in C)


class Track(NamedTuple):
    """One remembered obstacle (memory.py), positions in 1e-5 m (cm/s x ms)."""

    near: int = NO_TRACK  # worst case (nearest) position; NO_TRACK: the slot is empty
    far: int = NO_TRACK   # the remembered position less the train's least travel (passed: below minus the distance accuracy)
    closing: int = 0      # its own speed towards the train, cm/s (>= 0)
    cycles: int = 0       # cycles since it was last voted
    absent: int = 0       # cycles in a row of positive evidence that it is gone
    strong: bool = False  # confirmed or seen by two modules at once: forget_ms, not forget_single_ms


NO_TRACKS = (Track(),) * TRACKS


class State(NamedTuple):
    mode: int
    node: int
    held: int            # the demand level held (0 none, 1 service, 2 emergency): lowered only on release
    seen: int            # bit i: channel i has been fresh at least once
    disagree: tuple      # per module: ABSENT/PRESENT disagreement cycles not yet cleared by a calm spell
    healthy: int         # consecutive error-free cycles
    cycle: int
    error_cycles: int
    calm: int = 0        # cycles in a row in which the held demand could have been lowered
    agree: tuple = (0, 0, 0)  # per module: consecutive cycles without disagreement (clears `disagree`)
    table_held: int = 0  # the table's demand held while its obstacle is in the table's zones
    tracks: tuple = NO_TRACKS    # the remembered obstacles (tracks.py): TRACKS slots, nearest first, empty last
    kept: bool = False           # an obstacle in sight and closing keeps what is held (envelope.keep_held)
    plaus: tuple = ()            # per channel: plausibility.check's state (NO_REFERENCE while not PRESENT)

    @property
    def track(self) -> Track:
        """The nearest remembered obstacle (an empty Track if none)."""
        return self.tracks[0] if self.tracks else Track()

    track_near = property(lambda self: self.track.near, doc="the nearest track's worst-case position")
    track_far = property(lambda self: self.track.far, doc="the nearest track's least position")
    track_closing = property(lambda self: self.track.closing, doc="the nearest track's own closing speed")
    track_cycles = property(lambda self: self.track.cycles, doc="cycles since the nearest track was voted")
    track_absent = property(lambda self: self.track.absent, doc="the nearest track's evidence cycles")
    track_strong = property(lambda self: self.track.strong, doc="the nearest track is strong")

    @property
    def latched(self) -> bool:
        """An emergency is held (the latch of docs/core.md)."""
        return self.held == 2


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
    track_dm: int = NO_DISTANCE  # remembered obstacle's predicted (worst-case) distance, NO_DISTANCE if none
    track_cycles: int = 0        # cycles since the remembered obstacle was last voted
    track_state: int = 0         # TRACK_NONE / SEEN / HELD / CONFIRMING / FORGOTTEN / PASSED
    r1_ppm: int = 0              # seed 000 eq. 16 at the nearest obstacle (risk.py)
    r2_ppm: int = 0              # seed 000 eq. 17
    risk_score: int = 0          # seed 001 eq. 11, rho
    risk_category: int = 1       # 1 low, 2 moderate, 3 high, 4 critical
    table_risk_ppm: int = 0      # the table's risk column at the node: P(hazard within 30 s | node)
