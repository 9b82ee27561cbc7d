"""The real shell under test and the checks around it.

`MonitorRunner` runs on an in-memory python-can bus (`FrontDoorBus`) with the simulated
clock; `Harness` puts one frame on it (or runs one cycle), lets the runner take it, and checks
the accounting, the reject reason, the kind tally, the latched reports, the core's state and
outputs and the three frames each cycle sends against the reference receiver. A fault stops
the stream (`StreamStop`).
"""
from __future__ import annotations

import traceback
from collections import Counter, deque
from functools import lru_cache
from typing import Optional

import can

from can_bus.clock import SimClock
from can_bus.runner import MonitorRunner
from monitor import tables
from monitor.core import cycle as core
from monitor.core.config import Config
from monitor.core.types import (
    EMERGENCY, INIT, MAX_COUNT, NO_DISTANCE, NO_TRACK, R_INIT, R_LATCH, R_MEMORY, R_SAFE_STOP, R_SYSTEM_ERROR,
    SAFE_STOP, TRACK_CONFIRMING, TRACK_FORGOTTEN, TRACK_HELD, TRACK_PASSED, TRACK_SEEN, Inputs, Report, Train,
)

from .reference import (
    ACCEPTED, BRAKE_DEMAND, FILTERED, FRESHNESS_LOW_BYTES, LAYOUT, MONITOR_RISK, MONITOR_STATUS, MONITOR_TRACK,
    OUTPUTS, OWNER_OF, SECURED_BYTES, UNUSED, ReferenceReceiver, authenticator, e2e_crc, unpack,
)
from .stats import Stats, describe


class StreamStop(Exception):
    """End of a stream: tape used up, frame budget reached, or a fault recorded."""


class FrontDoorBus(can.BusABC):
    """An in-memory python-can bus: the harness puts a frame on it, the runner's drain() takes it."""

    def __init__(self) -> None:
        super().__init__(channel="railguard-fuzz")
        self.channel_info = "railguard fuzz front door"
        self.pending: deque = deque()
        self.sent = 0
        self.last_sent: dict = {}     # frame ID -> the newest frame the runner sent on it
        self.sent_ids: list = []      # the IDs sent, in order (the harness clears it every cycle)

    def _recv_internal(self, timeout):
        return (self.pending.popleft() if self.pending else None), True

    def send(self, msg, timeout=None) -> None:
        self.sent += 1
        self.last_sent[msg.arbitration_id] = msg
        self.sent_ids.append(msg.arbitration_id)


@lru_cache(maxsize=None)
def fuzz_keys() -> dict:
    """The fuzzed secured bus's keys, one per sender, fixed (a stream replays from its tape)."""
    import hashlib

    return {owner: hashlib.sha256(b"railguard fuzz test key " + owner.encode()).digest()[:16]
            for owner in sorted(set(OWNER_OF.values()))}


def fuzz_security(keys: dict, node: str):
    """A can_bus Security holding `keys` in memory (the shell under test, not the reference)."""
    from pathlib import Path

    from can_bus.keys import KeySet
    from can_bus.security import Security

    return Security(KeySet(Path("fuzz-test-keys"), dict(keys), True, {}), node, state=False)


def setup_for(table: str, topology: str) -> core.Setup:
    return core.create(Config(topology=topology), tables.read(table))


_FALLBACK_REASONS = R_SAFE_STOP | R_SYSTEM_ERROR | R_LATCH
_REASON_LIMIT = 1 + next(hi for name, *_, hi in LAYOUT[BRAKE_DEMAND] if name == "Reason")   # the DBC's, 16384
_UNSEEN = (TRACK_HELD, TRACK_CONFIRMING)    # remembered while no channel shows it: its cycles unvoted count
_TRACKED = (TRACK_SEEN, TRACK_HELD, TRACK_CONFIRMING)   # an obstacle remembered after the cycle
_TRACK_AGE_MAX = 65535                      # MonitorTrack.TrackAge saturates at 6553.5 s (0.1 s raw)


class Harness:
    """The real runner on the in-memory bus, the reference receiver beside it, and the checks.

    `feed(t, msg, kind)` puts one frame on the bus at time t (running every cycle whose tick
    is before t first), lets the runner drain it and checks; `cycle()` runs the next cycle
    and checks. Both raise StreamStop after recording an exception or a violation.
    """

    def __init__(self, setup: core.Setup, stats: Stats, budget: Optional[int] = None, label: Optional[dict] = None,
                 secured: bool = False):
        self.setup = setup
        self.stats = stats
        self.budget = budget
        self.label = label or {}
        self.clock = SimClock()
        self.bus = FrontDoorBus()
        # a secured bus (issue 39): the runner holds every key; `sealer` signs the traffic's frames
        self.keys = fuzz_keys() if secured else None
        self.sealer = None if self.keys is None else fuzz_security(self.keys, "fuzz-senders")
        self.runner = MonitorRunner(self.bus, setup, self.clock,
                                    security=None if self.keys is None else fuzz_security(self.keys, "fuzz-monitor"))
        self.rx = self.runner.receiver
        self.tally = self.runner.monitor.tally
        cfg = setup.config
        self.channels = cfg.channels
        self.modules = cfg.modules
        self.period = cfg.period_ms
        self.model = ReferenceReceiver(cfg.channels, cfg.period_ms, self.keys)
        self._out_freshness: dict = {}      # output ID -> the freshness value of the last secured frame sent
        self.n_nodes = setup.table.nodes
        self.n_obs = len(setup.table.observations)
        self.all_seen = (1 << cfg.channels) - 1
        self.shadow: Counter = Counter()    # the receiver's reject counts as of the last frame
        self.shadow_total = 0
        self.shadow_kinds: Counter = Counter()   # the runner's kind tally as of the last frame
        self.filtered = 0                   # frames the reference expected to be filtered
        self.frames = 0
        self.cycles = 0
        self.failed = False
        self._checked: list = [None] * cfg.channels   # report objects already found in their domain
        self._out_counters: dict = {}       # output ID -> the E2E alive counter of the last frame sent on it

    # ------------------------------------------------------------------ faults
    def _fault(self, kind: str, what: str, msg: Optional[can.Message] = None, **extra) -> None:
        self.failed = True
        if kind == "exception":
            self.stats.exceptions += 1
        else:
            self.stats.violations[kind] += 1
        detail = dict(self.label, what=what, frame_index=self.frames, cycle_index=self.cycles,
                      now_ms=self.clock.now_ms(), **extra)
        if msg is not None:
            detail["frame"] = describe(msg)
        self.stats.record(kind, detail)
        raise StreamStop

    # ------------------------------------------------------------------ frames
    def feed(self, t: int, msg: can.Message, kind: str) -> str:
        if self.failed or (self.budget is not None and self.frames >= self.budget):
            raise StreamStop
        runner = self.runner
        while runner.next_tick < t:
            self.cycle()
        self.clock.sleep_until_ms(t)
        now = self.clock.now_ms()
        # the runner stamps a frame no later than the next tick, nor than its bus timestamp
        # says (the simulated clock has none: None)
        tick = min(now, runner.next_tick)
        stamped = self.clock.tick_of_stamp(msg.timestamp)
        if stamped is not None:
            tick = min(tick, stamped)
        frame_kind_, expected = self.model.expect(msg, tick)
        rx, tally = self.rx, self.tally
        accepted0, received0, filtered0 = rx.accepted, runner.frames_received, tally.filtered
        self.bus.pending.append(msg)
        self.frames += 1
        self.stats.frames += 1
        self.stats.kinds[kind] += 1
        self.stats.expected[expected] += 1
        try:
            runner.drain()
        except Exception as exc:  # noqa: BLE001 - what the fuzzing is looking for
            self._fault("exception", f"runner.drain raised {type(exc).__name__}: {exc}", msg,
                        traceback=traceback.format_exc(limit=-3), expected=expected)
        # accounting: exactly one counter moved, by exactly one
        rejected = rx.rejected
        total = sum(rejected.values())
        if expected == ACCEPTED:
            ok = rx.accepted == accepted0 + 1 and total == self.shadow_total and tally.filtered == filtered0
        elif expected == FILTERED:
            ok = rx.accepted == accepted0 and total == self.shadow_total and tally.filtered == filtered0 + 1
        else:
            ok = (rx.accepted == accepted0 and total == self.shadow_total + 1 and tally.filtered == filtered0
                  and rejected[expected] == self.shadow[expected] + 1)
        ok = ok and runner.frames_received == received0 + 1 and not self.bus.pending
        if not ok:
            moved = {k: v - self.shadow[k] for k, v in rejected.items() if v != self.shadow[k]}
            if rx.accepted != accepted0:
                moved[ACCEPTED] = rx.accepted - accepted0
            if tally.filtered != filtered0:
                moved[FILTERED] = tally.filtered - filtered0
            counted = sum(moved.values())
            kind_ = "reason" if counted == 1 and runner.frames_received == received0 + 1 else "accounting"
            if kind_ == "accounting":
                self.stats.accounting_errors += 1
            self._fault(kind_, f"expected {expected}, counters moved {moved or 'none'}"
                        f" (frames_received +{runner.frames_received - received0})", msg,
                        expected=expected, moved=moved)
        if expected == ACCEPTED:
            self.stats.accepted_ids[msg.arbitration_id] += 1
        elif expected == FILTERED:
            self.filtered += 1
        else:
            self.shadow[expected] += 1
            self.shadow_total += 1
            if expected == "foreign_output":
                self.stats.foreign_ids[msg.arbitration_id] += 1
        # the kind tally: one more of this frame's kind, nothing else
        kinds, shadow_kinds = tally.kinds, self.shadow_kinds
        if kinds[frame_kind_] != shadow_kinds[frame_kind_] + 1 or sum(kinds.values()) != sum(shadow_kinds.values()) + 1:
            moved = {k: kinds[k] - shadow_kinds[k] for k in set(kinds) | set(shadow_kinds)
                     if kinds[k] != shadow_kinds[k]}
            self._fault("kind", f"a {frame_kind_} frame, the kind tally moved {moved or 'none'}", msg,
                        expected=expected)
        shadow_kinds[frame_kind_] += 1
        if frame_kind_ == "error" and (tally.bus_state != self.model.bus_state
                                       or tally.bus_events != self.model.bus_events):
            self._fault("bus_state", f"bus state {tally.bus_state} {dict(tally.bus_events)}, reference "
                        f"{self.model.bus_state} {dict(self.model.bus_events)}", msg, expected=expected)
        # what is latched: within its domain, and what the reference receiver latched
        problem = self._latched_problem(now)
        if problem:
            self._fault("domain", problem, msg, expected=expected)
        if rx.reports != self.model.reports or rx.train != self.model.train or rx.train_tick != self.model.train_tick:
            self._fault("latched", "latched reports/train differ from the reference receiver's", msg,
                        expected=expected, receiver=repr((rx.reports, rx.train, rx.train_tick)),
                        reference=repr((self.model.reports, self.model.train, self.model.train_tick)))
        return expected

    def _latched_problem(self, now: int) -> str:
        reports = self.rx.reports
        if len(reports) != self.channels:
            return f"{len(reports)} report slots for {self.channels} channels"
        checked = self._checked
        for i, r in enumerate(reports):
            if r is None or r is checked[i]:     # absent, or the same object found in its domain before
                continue
            if not (type(r) is Report and all(type(x) is int for x in r)):
                return f"channel {i}: latched {r!r} is not a Report of integers"
            if not (0 <= r.status <= 2 and 0 <= r.distance_dm <= 60000 and -15000 <= r.closing_cms <= 15000
                    and 0 <= r.obstacle <= 2 and 0 <= r.tick <= now):
                return f"channel {i}: latched {r!r} outside its domain (now {now})"
            checked[i] = r
        tr = self.rx.train
        if tr is not None:
            if not (type(tr) is Train and all(type(x) is int for x in tr)
                    and 0 <= tr.speed_cms <= 12000 and tr.track in (0, 1) and tr.brake in (0, 1)):
                return f"train: latched {tr!r} outside its domain"
            if not (type(self.rx.train_tick) is int and 0 <= self.rx.train_tick <= now):
                return f"train tick {self.rx.train_tick!r} outside 0..now ({now})"
        return ""

    # ------------------------------------------------------------------ cycles
    def cycle(self):
        runner, rx = self.runner, self.rx
        if self.failed:
            raise StreamStop
        tick = runner.next_tick
        self.clock.sleep_until_ms(tick)
        before, overruns = runner.state, runner.overruns
        counts = (rx.accepted, sum(rx.rejected.values()), runner.frames_received, self.tally.filtered)
        sent0 = self.bus.sent
        self.bus.sent_ids.clear()
        try:
            rec = runner.cycle()
        except Exception as exc:  # noqa: BLE001
            self._fault("exception", f"runner.cycle raised {type(exc).__name__}: {exc}",
                        traceback=traceback.format_exc(limit=-3), tick=tick)
        self.cycles += 1
        state, out = runner.state, runner.outputs
        if out.mode == SAFE_STOP and out.reasons == _FALLBACK_REASONS and out.distance_dm == NO_DISTANCE \
                and out.module_flags == 0 and out.observation == 0:
            # the shape of step()'s fail-safe result: did the cycle raise inside?
            train = rx.train if rx.train_tick is not None and tick - rx.train_tick <= self.setup.timeout_ticks else None
            try:
                core._step(self.setup, before, Inputs(tuple(rx.reports), train, overruns), tick)
            except Exception as exc:  # noqa: BLE001
                self._fault("exception", f"core step raised inside (caught by its fail-safe) "
                            f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc(limit=-3), tick=tick)
        if (rx.accepted, sum(rx.rejected.values()), runner.frames_received, self.tally.filtered) != counts:
            self.stats.accounting_errors += 1
            self._fault("accounting", "a cycle changed the frame counters", tick=tick)
        problem = self._latched_problem(tick) or self._core_problem(before, state, out)
        if problem:
            self._fault("domain", problem, tick=tick, state=repr(state), outputs=repr(out))
        foreign = self.model.foreign(tick, self.period)
        problem = self._record_problem(tick, rec, out, foreign) or self._sent_problem(sent0, out, foreign)
        if problem:
            self._fault("cycle", problem, tick=tick, record=repr(rec), outputs=repr(out))
        self.stats.cycles += 1
        self.stats.modes[state.mode] += 1
        self.stats.demands[out.demand] += 1
        self.stats.foreign_cycles += foreign
        return out

    def _secured_sent(self, fid: int, m: can.Message) -> tuple:
        """(bytes 0..7, "") of a frame the monitor sent on a secured bus, or (b"", the problem): a
        CAN FD frame of 20 bytes, its freshness value one on from the last on the ID (from 0),
        its authenticator right under the monitor's key (the reference's own CMAC)."""
        data = bytes(m.data)
        if not m.is_fd or len(data) != SECURED_BYTES:
            return b"", f"sent frame 0x{fid:02X} {data.hex()} is not a 20-byte secured CAN FD frame"
        value = self._out_freshness.get(fid, -1) + 1
        if int.from_bytes(data[8:8 + FRESHNESS_LOW_BYTES], "little") != value & 0xFFFFFFFF:
            return b"", f"sent frame 0x{fid:02X} carries freshness {data[8:12].hex()}, not {value}"
        if authenticator(self.keys[OWNER_OF[fid]], fid, data[:8], value) != data[8 + FRESHNESS_LOW_BYTES:]:
            return b"", f"sent frame 0x{fid:02X} {data.hex()}: its authenticator fails under the monitor's key"
        self._out_freshness[fid] = value
        return data[:8], ""

    def _record_problem(self, tick: int, rec, out, foreign: bool) -> str:
        """The CycleRecord `cycle()` returned: the cycle's outputs, the TrainState speed the
        core was given (none once older than the timeout) and the ForeignOutput diagnostic."""
        if rec is None or rec is not (self.runner.records[-1] if self.runner.records else None):
            return f"cycle() returned {rec!r}, not the cycle's record"
        if rec.tick != tick:
            return f"record tick {rec.tick!r} for the cycle at {tick}"
        if (rec.demand, rec.reasons, rec.mode, rec.node, rec.distance_dm, rec.module_flags, rec.system_error,
                rec.warning, rec.track_dm, rec.track_cycles, rec.track_state) != (
                out.demand, out.reasons, out.mode, out.node, out.distance_dm, out.module_flags, out.system_error,
                out.warning, out.track_dm, out.track_cycles, out.track_state):
            return "the record disagrees with runner.outputs"
        m = self.model
        fresh = m.train is not None and tick - m.train_tick <= self.setup.timeout_ticks
        speed = m.train.speed_cms if fresh else None
        if rec.speed_cms != speed:
            return f"record speed {rec.speed_cms!r}, the reference's fresh TrainState gives {speed!r}"
        if rec.foreign_output is not foreign:
            return (f"ForeignOutput {rec.foreign_output!r}, reference {foreign} "
                    f"(last foreign frame at {m.foreign_tick}, cycle at {tick})")
        return ""

    def _sent_problem(self, sent0: int, out, foreign: bool) -> str:
        """The three frames the cycle sent, BrakeDemand, MonitorStatus and MonitorTrack in this
        order, read with the reference's own CRC and unpacking: valid 8-byte E2E frames, each
        alive counter one on from the last cycle's, the bits no signal uses 0 (MonitorTrack's
        reserved 48-63 among them); BrakeDemand's level and reasons, MonitorStatus's mode and
        ForeignOutput, and MonitorTrack's fields as the core's outputs give them (TrackAge: the
        track's unvoted cycles times the period, to the nearest 0.1 s, saturating)."""
        bus = self.bus
        if bus.sent != sent0 + len(OUTPUTS) or bus.sent_ids != list(OUTPUTS):
            return (f"the cycle sent {[f'0x{i:02X}' for i in bus.sent_ids]}, not BrakeDemand, MonitorStatus, "
                    f"MonitorTrack and MonitorRisk")
        values = {}
        for fid in OUTPUTS:
            m = bus.last_sent[fid]
            data = bytes(m.data)
            if self.keys is not None:
                data, problem = self._secured_sent(fid, m)
                if problem:
                    return problem
            if m.is_extended_id or len(data) != 8 or e2e_crc(data, fid) != data[0]:
                return f"sent frame 0x{fid:02X} {data.hex()} is not a valid 8-byte E2E frame"
            if int.from_bytes(data, "little") & UNUSED[fid]:
                return f"sent frame 0x{fid:02X} {data.hex()} sets bits no signal uses"
            values[fid] = v = unpack(fid, data)
            last = self._out_counters.get(fid)
            if last is not None and v["Counter"] != (last + 1) & 0xF:
                return f"sent frame 0x{fid:02X} has alive counter {v['Counter']} after {last}"
            self._out_counters[fid] = v["Counter"]
        d, st, tr = values[BRAKE_DEMAND], values[MONITOR_STATUS], values[MONITOR_TRACK]
        if d["Level"] != out.demand or d["Reason"] != out.reasons or st["Mode"] != out.mode:
            return (f"sent Level {d['Level']} / Reason {d['Reason']} / Mode {st['Mode']} for demand {out.demand} / "
                    f"reasons {out.reasons} / mode {out.mode}")
        if st["ForeignOutput"] != foreign:
            return f"sent ForeignOutput {st['ForeignOutput']}, reference {int(foreign)}"
        age_ms = min(out.track_cycles * self.period, _TRACK_AGE_MAX * 100)    # to the nearest 0.1 s
        memory = int(bool(out.reasons & R_MEMORY))
        if (tr["TrackState"], tr["Memory"], tr["TrackDistance"]) != (out.track_state, memory, out.track_dm) \
                or abs(tr["TrackAge"] * 100 - age_ms) > 50:
            return (f"sent MonitorTrack {tr} for track state {out.track_state}, distance {out.track_dm}, "
                    f"{out.track_cycles} cycles unvoted, reasons {out.reasons}")
        rk = values[MONITOR_RISK]       # the outputs in the DBC's units, rounded up (0.1 % from ppm)
        want = (out.risk_category, out.risk_score, -(-out.r1_ppm // 1000), -(-out.r2_ppm // 1000), out.table_risk_ppm)
        if (rk["RiskCategory"], rk["RiskScore"], rk["R1"], rk["R2"], rk["TableRisk"]) != want:
            return f"sent MonitorRisk {rk} for the core's risk {want}"
        if rk["Unsecured"] != int(self.runner.security is None):      # (the fuzzed bus is unsecured)
            return f"sent MonitorRisk Unsecured {rk['Unsecured']} on a bus secured: {self.runner.security is not None}"
        return ""

    def _core_problem(self, before, s, out) -> str:
        if not (type(s.mode) is int and 0 <= s.mode <= 3):
            return f"mode {s.mode!r}"
        if not (type(s.node) is int and 0 <= s.node < self.n_nodes):
            return f"node {s.node!r} not < {self.n_nodes}"
        if not (type(s.held) is int and 0 <= s.held <= 2 and s.latched is (s.held == EMERGENCY)):
            return f"held {s.held!r} (latched {s.latched!r})"
        if not (type(s.seen) is int and 0 <= s.seen <= self.all_seen and s.seen & before.seen == before.seen):
            return f"seen {s.seen!r} (before {before.seen!r})"
        if not (type(s.disagree) is tuple and len(s.disagree) == self.modules
                and all(type(d) is int and 0 <= d <= MAX_COUNT for d in s.disagree)):
            return f"disagree {s.disagree!r}"
        if not (type(s.healthy) is int and 0 <= s.healthy <= MAX_COUNT):
            return f"healthy {s.healthy!r}"
        if s.cycle != min(before.cycle + 1, MAX_COUNT):
            return f"cycle {s.cycle!r} after {before.cycle!r}"
        if not (type(s.error_cycles) is int and before.error_cycles <= s.error_cycles <= before.error_cycles + 1
                and s.error_cycles <= s.cycle):
            return f"error_cycles {s.error_cycles!r} after {before.error_cycles!r}"
        if not (type(out.demand) is int and 0 <= out.demand <= 2):
            return f"demand {out.demand!r}"
        if not (type(out.reasons) is int and 0 <= out.reasons < _REASON_LIMIT):
            return f"reasons {out.reasons!r}"
        if not (type(out.distance_dm) is int and (0 <= out.distance_dm <= 60000 or out.distance_dm == NO_DISTANCE)):
            return f"distance {out.distance_dm!r}"
        if not (type(out.observation) is int and 0 <= out.observation < self.n_obs):
            return f"observation {out.observation!r} not < {self.n_obs}"
        if not (type(out.module_flags) is int and 0 <= out.module_flags < 1 << self.modules):
            return f"module flags {out.module_flags!r}"
        if type(out.system_error) is not bool:
            return f"system_error {out.system_error!r}"
        if type(out.warning) is not bool:
            return f"warning {out.warning!r}"
        if not (type(s.calm) is int and 0 <= s.calm < self.setup.config.release_confirm_cycles):
            return f"calm {s.calm!r}"
        if (out.node, out.mode, out.cycle, out.error_cycles) != (s.node, s.mode, s.cycle, s.error_cycles):
            return "outputs disagree with the state (node, mode, cycle, error_cycles)"
        if s.mode == INIT and not (out.demand == EMERGENCY and out.reasons & R_INIT):
            return "INIT without emergency demand and the init reason"
        if s.mode == SAFE_STOP and not (out.demand == EMERGENCY and out.reasons & R_SAFE_STOP):
            return "SAFE_STOP without emergency demand and the safe_stop reason"
        if out.demand < s.held:      # an emergency held demands emergency, a service held at least service
            return f"demand {out.demand} below the level held {s.held}"
        return self._track_problem(before, s, out)

    def _track_problem(self, before, s, out) -> str:
        """The obstacle memory: the track state 0..5; a distance (0..60000 dm) exactly when an
        obstacle is remembered after the cycle (the nearest is seen, held or confirming; or it
        was forgotten or passed and another, farther one is remembered: issue 38's several
        tracks), in the outputs and the state alike; its unvoted cycles at least 1 and at most
        one more than any track had while held or confirming, 0 otherwise; the memory reason
        whenever the nearest remembered obstacle is not shown (held, confirming), and never
        without a remembered obstacle (beside a seen nearest one it is a farther one's)."""
        if not all(type(x) is int for x in (out.track_state, out.track_dm, out.track_cycles, s.track_near,
                                            s.track_cycles)):
            return f"track outputs {out.track_state!r}, {out.track_dm!r}, {out.track_cycles!r} not integers"
        if not 0 <= out.track_state <= 5:
            return f"track state {out.track_state}"
        remembered = s.track_near != NO_TRACK
        tracked = out.track_state in _TRACKED or (out.track_state in (TRACK_FORGOTTEN, TRACK_PASSED) and remembered)
        if not (0 <= out.track_dm <= 60000 if tracked else out.track_dm == NO_DISTANCE):
            return f"track distance {out.track_dm} in track state {out.track_state}"
        if remembered is not tracked or any(t.near < NO_TRACK for t in s.tracks):
            return f"state track_near {s.track_near} in track state {out.track_state}"
        most = min(max(t.cycles for t in before.tracks) + 1, MAX_COUNT) if before.tracks else 1
        if not (1 <= out.track_cycles <= most if out.track_state in _UNSEEN else out.track_cycles == 0):
            return f"track cycles {out.track_cycles} in track state {out.track_state}, at most {most - 1} before"
        memory = bool(out.reasons & R_MEMORY)
        if (memory and not remembered) or (out.track_state in _UNSEEN and not memory):
            return (f"reason memory {memory} in track state {out.track_state} (system error {out.system_error}), "
                    f"track {out.track_dm}, voted {out.distance_dm}")
        return ""

    def finish(self) -> None:
        """Run the cycles up to the last frame's time and one more, then the stream's totals."""
        rx = self.rx
        if not self.failed:
            try:
                while self.runner.next_tick <= self.clock.now_ms():
                    self.cycle()
                self.cycle()
            except StreamStop:
                pass
        if not self.failed:
            total = rx.accepted + sum(rx.rejected.values()) + self.tally.filtered
            if not (total == self.frames == self.runner.frames_received == sum(self.tally.kinds.values())):
                self.stats.accounting_errors += 1
                try:
                    self._fault("accounting", f"frames in {self.frames}, received {self.runner.frames_received}, "
                                f"accepted + rejected + filtered {total}, by kind {sum(self.tally.kinds.values())}")
                except StreamStop:
                    pass
        self.stats.accepted += rx.accepted
        self.stats.rejected.update(rx.rejected)
        self.stats.filtered += self.tally.filtered
        self.stats.frame_kinds.update(self.tally.kinds)
        self.stats.bus_states.update(self.tally.bus_events)
        self.bus.shutdown()
