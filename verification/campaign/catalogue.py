"""The fault catalogue: every fault kind the campaign injects, how it is injected and which
diagnostic shows that the monitor detected it. The kinds are grouped by where they act
(a channel's values, its frames, the table file), which decides how each piece injects them.
"""
from __future__ import annotations

from dataclasses import dataclass


CHANNEL_KINDS = ("silence", "stuck", "noise_burst", "missed_detection", "bad_crc", "counter_freeze",
                 "counter_jump", "wrong_length", "babble", "contradiction", "stale_timestamp")
VALUE_KINDS = ("stuck", "noise_burst", "missed_detection", "contradiction")
FRAME_KINDS = ("bad_crc", "counter_freeze", "counter_jump", "wrong_length", "babble")
TABLE_KINDS = ("table_corrupted", "table_mismatch")
KINDS = CHANNEL_KINDS + ("deadline_overrun",) + TABLE_KINDS
PLAYER_KINDS = CHANNEL_KINDS            # what can_bus.player injects on a bus

# the rejects that show a frame fault; a frozen counter with changing content is what a second
# sender looks like (issue 39), with unchanged content a duplicate
REJECT_OF = {"bad_crc": ("bad_crc",), "counter_freeze": ("repeated_counter", "second_sender"),
             "counter_jump": ("counter_jump",), "wrong_length": ("wrong_length",), "babble": ("rate_exceeded",)}


@dataclass(frozen=True)
class FaultKind:
    name: str
    label: str
    injection: str      # how the campaign injects it
    diagnostic: str     # what shows that the monitor detected it
    short: str = ""     # the diagnostic in a few words (check names)


CATALOGUE = {f.name: f for f in (
    FaultKind("silence", "channel silence", "the channel sends nothing during the window",
              "reason bit `stale`: the channel ages into DEGRADED after `timeout_cycles`", "stale"),
    FaultKind("stuck", "stuck-at value", "the channel repeats the report it had when the fault began (the player's `stuck`)",
              "`module_flags` bit of the channel's module (2oo2: ABSENT/PRESENT disagreement or distances more than "
              "`distance_tolerance_dm` apart)", "module flag"),
    FaultKind("noise_burst", "noise burst", "distance noise sigma x 50 (0.5 m -> 25 m) on the channel",
              "`module_flags` bit of the channel's module (distances more than `distance_tolerance_dm` apart)", "module flag"),
    FaultKind("missed_detection", "missed detection", "the channel reports ABSENT while the obstacle is in range",
              "`module_flags` bit of the channel's module (ABSENT/PRESENT disagreement)", "module flag"),
    FaultKind("bad_crc", "CRC corruption", "one byte (or 2-4 bytes) of each real frame XORed after the CRC was applied",
              "codec reject `bad_crc`, then reason bit `stale`", "bad_crc reject, stale"),
    FaultKind("counter_freeze", "counter freeze", "the alive counter repeats (the player's `counter_freeze`)",
              "codec reject `repeated_counter` (the same frame again) or `second_sender` (the same counter, other "
              "content: the channel refused for 1 s), then reason bit `stale`", "repeated_counter/second_sender reject, stale"),
    FaultKind("counter_jump", "counter jump", "the alive counter skips 1..14 values on every frame",
              "codec reject `counter_jump`, then reason bit `stale`", "counter_jump reject, stale"),
    FaultKind("wrong_length", "wrong frame length", "frames cut to 0..7 bytes",
              "codec reject `wrong_length`, then reason bit `stale`", "wrong_length reject, stale"),
    FaultKind("babble", "babbling at high rate", "4, 8 or 20 valid frames per period from the channel",
              "codec reject `rate_exceeded` (quarantine, report withdrawn), then reason bit `stale`", "rate_exceeded reject, stale"),
    FaultKind("contradiction", "contradiction within a module",
              "the channel's status flipped: PRESENT -> ABSENT, ABSENT -> a phantom obstacle at 30..900 m",
              "`module_flags` bit of the channel's module at once (with every channel fresh a dispute: reason bits "
              "`dispute` and `warning`); and reason bit `perceptor` (mode SAFE_STOP) once the disagreement has "
              "persisted `persistence_cycles` cycles in a row", "module flag, perceptor if it persists"),
    FaultKind("stale_timestamp", "stale timestamps",
              "the report handed to the core carries a tick older than the timeout, or one from the future",
              "reason bit `stale` (a report from the past or the future counts as DEGRADED)", "stale"),
    FaultKind("deadline_overrun", "deadline overrun",
              "the shell reports consecutive overruns (`Inputs.overruns`); a late cycle's demand reaches the brakes one period late",
              "reason bit `deadline` (mode SAFE_STOP after `max_overruns` in a row)", "deadline, SAFE_STOP"),
    FaultKind("table_corrupted", "corrupted table file", "a flipped byte, a flipped digest byte, a truncated file or bad magic",
              "`ConfigurationError` from `cycle.create`: the monitor refuses to start, the train is held under emergency", "ConfigurationError"),
    FaultKind("table_mismatch", "mismatched table file",
              "the other model's table (expect_model), a period that is not the table's time step, a re-hashed table "
              "claiming the other model, or one with its observations reordered",
              "`ConfigurationError` from `cycle.create`: the monitor refuses to start, the train is held under emergency", "ConfigurationError"),
)}
assert tuple(CATALOGUE) == KINDS

# A hostile node on the bus (issue 39; can_bus/hostile.py): played on the virtual bus only,
# each in a detection run of its own; not crossed with the scenarios like the faults above.
HOSTILE_KINDS = ("forge_absent", "forge_brake_none")
HOSTILE = {f.name: f for f in (
    FaultKind("forge_absent", "forged absent in step",
              "a second node sends ObstacleReport ABSENT on all six channel IDs, valid CRC, the counter each genuine "
              "frame is about to carry, just before it",
              "codec reject `second_sender` (the ID refused, the channel withdrawn), then reason bit `stale`",
              "second_sender reject, stale"),
    FaultKind("forge_brake_none", "forged brake release in step",
              "a second node sends BrakeDemand 'none' with the monitor's next counter and cycle, just before the monitor's frame",
              "the reference brake receiver's `second_sender` emergency, held to standstill", "brake receiver second_sender"),
)}
