"""Write the crafted-log corpus (issue 13): small candump -L logs, one hostile class each.

Every log is a few seconds of healthy railguard traffic, timestamped in epoch seconds like
a real candump recording, with ONE hostile class superimposed. The healthy traffic, every
100 ms period k (t = T0 + k * 0.1 s):

    +0 ms  TrainState 0x030         20 m/s, normal track and brakes
    +1..6  ObstacleReport 0x020-25  channel i of module i // 2, ABSENT

each frame with a correct E2E profile 2 CRC and its own alive counter stepping by one. The
expected behaviour of the monitor on each file is listed in tests/corpus/README.md and
checked by tests/test_log_corpus.py, which also checks that the committed files are exactly
what this script writes (so they cannot drift from it).

    python tests/corpus/make_corpus.py            # (re)write the corpus next to this file
    python tests/corpus/make_corpus.py --check    # exit 1 if a committed file differs
    python tests/corpus/make_corpus.py --keys DIR # the secured_*.log files' TEST key set, for --keys

Deterministic: no randomness, no clock; the only inputs are the DBC (via can_bus.codec,
which encodes the payloads) and this file.
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path
from typing import Callable, Optional

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))        # run as a script from anywhere

from can_bus.codec import (  # noqa: E402
    BRAKE_DEMAND_ID, MONITOR_STATUS_ID, OBSTACLE_IDS, TRAIN_STATE_ID, Sender, encode, report_signals,
)
from can_bus.secoc import protect  # noqa: E402
from monitor.core.types import ABSENT, PRESENT, STATIC, Report  # noqa: E402

T0_US = 1_700_000_000_000_000      # 2023-11-14 22:13:20 UTC, in microseconds
MS = 1_000
PERIOD = 100 * MS
SPEED_CMS = 2000                   # 20 m/s
CLEAR = Report(ABSENT, 0, 0, STATIC, 0)
FAULT = range(10, 20)              # periods 10..19 (1.0 s .. 1.9 s): the usual fault window
PERIODS = 50                       # 5 s: long enough to see the monitor recover after the fault
IFACE = "vcan0"


def stamp(t_us: int) -> str:
    return f"({t_us // 1_000_000}.{t_us % 1_000_000:06d})"


def line(t_us: int, ident: str, body: str, direction: str = "") -> str:
    return f"{stamp(t_us)} {IFACE} {ident}#{body}" + (f" {direction}" if direction else "")


def std(fid: int) -> str:
    return f"{fid:03X}"


def fd_line(t_us: int, fid: int, data: bytes, direction: str = "") -> str:
    """A CAN FD frame in candump -L: ID##, the flags digit (1: bit-rate switch), the data."""
    return line(t_us, std(fid), "#1" + bytes(data).hex().upper(), direction)


def noise(tag: str, n: int) -> bytes:
    """n deterministic pseudo-random bytes named by tag."""
    out = b""
    i = 0
    while len(out) < n:
        out += hashlib.sha256(f"{tag}/{i}".encode()).digest()
        i += 1
    return out[:n]


def t_of(k: int, slot_ms: int = 0) -> int:
    return T0_US + k * PERIOD + slot_ms * MS


# ----------------------------------------------------------------------------- the secured bus (issue 39)
# The secured_*.log files are recorded on a secured bus with this fixed TEST key set (never a
# real one): `python tests/corpus/make_corpus.py --keys DIR` writes it as a key set folder
# (railguard replay FILE --keys DIR); the keys are derived from their names, so nothing secret
# is committed and every run writes the same set.
def corpus_keys() -> dict:
    from can_bus.keys import SENDERS

    return {s: hashlib.sha256(f"railguard corpus test key {s}".encode()).digest()[:16] for s in SENDERS}


def write_keys(folder: Path) -> Path:
    """The corpus key set as a key set folder (owner-only files, manifest marked test)."""
    import os

    from can_bus.keys import FORMAT, MANIFEST, fingerprint

    folder = Path(folder)
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(folder, 0o700)
    keys = corpus_keys()
    for sender, key in keys.items():
        path = folder / f"{sender}.key"
        path.write_text(key.hex() + "\n", encoding="ascii")
        os.chmod(path, 0o600)
    lines = [f"format = {FORMAT}", "test = true", 'created = "corpus"', "[senders]"]
    lines += [f'{s} = "{fingerprint(k)}"' for s, k in keys.items()]
    (folder / MANIFEST).write_text("\n".join(lines) + "\n", encoding="ascii")
    os.chmod(folder / MANIFEST, 0o600)
    return folder


def corpus_security(node: str = "corpus"):
    from can_bus.keys import KeySet
    from can_bus.security import Security

    return Security(KeySet(Path("corpus-test-keys"), corpus_keys(), True, {}), node, state=False)


class Log:
    """Lines of one log, and one alive counter per sender (frame ID); `secured`: every frame
    the log's senders write is a secured CAN FD frame under the corpus keys."""

    def __init__(self, secured: bool = False) -> None:
        self.lines: list[str] = []
        self.security = corpus_security() if secured else None
        self.sender = Sender(self.security)

    def frame(self, t_us: int, fid: int, signals: dict, direction: str = "") -> bytes:
        """The sender's next frame on fid (counter + 1, correct CRC)."""
        data = self.sender.frame(fid, signals)
        self.lines.append(fd_line(t_us, fid, data, direction) if self.security else
                          line(t_us, std(fid), data.hex().upper(), direction))
        return data

    def skip(self, fid: int) -> None:
        """The sender counts a frame it never got onto the bus (the monitor will see a jump)."""
        self.sender.counters[fid] = (self.sender.counters.get(fid, -1) + 1) & 0xF

    def next_counter(self, fid: int) -> int:
        return (self.sender.counters.get(fid, -1) + 1) & 0xF

    def raw(self, text: str) -> None:
        self.lines.append(text)

    def text(self) -> str:
        return "".join(s + "\n" for s in self.lines)


Hook = Callable[[Log, int, int, int, dict], bool]   # (log, k, fid, t_us, signals) -> handled?


def traffic(log: Log, periods: range, *, hook: Optional[Hook] = None,
            report: Optional[Callable[[int, int], Report]] = None,
            speed: Optional[Callable[[int], int]] = None, direction: str = "") -> None:
    """The healthy schedule over `periods`; `hook` may replace any frame (return True)."""
    for k in periods:
        frames = [(TRAIN_STATE_ID, t_of(k), {"Speed": SPEED_CMS if speed is None else speed(k)})]
        for ch, fid in enumerate(OBSTACLE_IDS):
            r = CLEAR if report is None else report(k, ch)
            frames.append((fid, t_of(k, ch + 1), report_signals(r, ch)))
        for fid, t, signals in frames:
            if hook is None or not hook(log, k, fid, t, signals):
                log.frame(t, fid, signals, direction)


# ----------------------------------------------------------------------------- the files
# Each function returns the file's text. Keep them small (< 100 kB) and the hostile part in
# the middle: the first and the last line are healthy frames, so a hostile file and its
# healthy twin start and end at the same time.

def healthy() -> str:
    log = Log()
    traffic(log, range(PERIODS))
    return log.text()


def bad_crc() -> str:
    """Channel 2 (0x022): CRC byte inverted in periods 10..19."""
    def hook(log, k, fid, t, sig):
        if fid == 0x022 and k in FAULT:
            data = bytearray(log.sender.frame(fid, sig))
            data[0] ^= 0xFF
            log.raw(line(t, std(fid), bytes(data).hex().upper()))
            return True
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def repeated_counter() -> str:
    """Channel 3 (0x023) freezes in periods 10..19: it repeats its last frame (same counter,
    same CRC), then goes on counting from where it stopped."""
    last: dict = {}

    def hook(log, k, fid, t, sig):
        if fid != 0x023:
            return False
        if k in FAULT:
            log.raw(line(t, std(fid), last[fid]))
        else:
            last[fid] = log.frame(t, fid, sig).hex().upper()
        return True
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def counter_jump() -> str:
    """Channel 1 (0x021) counts in steps of 2 in periods 10..19 (every frame a jump)."""
    def hook(log, k, fid, t, sig):
        if fid == 0x021 and k in FAULT:
            log.skip(fid)
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def wrong_dlc() -> str:
    """Channel 4 (0x024): 7 data bytes instead of 8 in periods 10..14, 0 bytes in 15..19
    (CRC and counter otherwise right: the frame is only truncated)."""
    def hook(log, k, fid, t, sig):
        if fid == 0x024 and k in FAULT:
            data = log.sender.frame(fid, sig)
            log.raw(line(t, std(fid), (data[:7] if k < 15 else b"").hex().upper()))
            return True
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


UNKNOWN_IDS = (0x000, 0x011, 0x026, 0x031, 0x041, 0x7FF)


def unknown_id() -> str:
    """Periods 10..29: one frame on each of six IDs the DBC does not define (0x000, 0x011,
    0x026 next to the last channel, 0x031, 0x041, 0x7FF), 8 noise bytes, at +50..55 ms."""
    log = Log()
    for k in range(PERIODS):
        traffic(log, range(k, k + 1))
        if 10 <= k < 30:
            for i, uid in enumerate(UNKNOWN_IDS):
                log.raw(line(t_of(k, 50 + i), std(uid), noise(f"unknown/{k}/{uid}", 8).hex().upper()))
    return log.text()


OBSTACLE_50M = Report(PRESENT, 500, SPEED_CMS, STATIC, 0)


def injected(kind: str) -> str:
    """Healthy traffic plus, in periods 10..29 at +50 ms, frames of one non-classical kind
    that carry a valid-looking report of an obstacle 50 m ahead (PRESENT, 20 m/s closing,
    correct CRC, the counter the channel's next frame will have): if the monitor latched
    one of them it would brake, and the channel's next real frame would be a repeat."""
    log = Log()
    for k in range(PERIODS):
        traffic(log, range(k, k + 1))
        if not 10 <= k < 30:
            continue
        ch = k % 6
        fid = OBSTACLE_IDS[ch]
        data = encode(fid, report_signals(OBSTACLE_50M, ch), log.next_counter(fid))
        t = t_of(k, 50)
        if kind == "extended":
            log.raw(line(t, f"{fid:08X}", data.hex().upper()))
            if k % 5 == 0:           # and a TrainState saying 'standstill' on 29 bits
                ts = encode(TRAIN_STATE_ID, {"Speed": 0}, log.next_counter(TRAIN_STATE_ID))
                log.raw(line(t + MS, f"{TRAIN_STATE_ID:08X}", ts.hex().upper()))
        elif kind == "fd":
            flags = k % 2                                   # bit-rate switch on every other
            log.raw(line(t, std(fid), f"#{flags:X}{data.hex().upper()}"))
            if k % 5 == 0:           # the same report padded to 64 bytes, the longest FD frame
                log.raw(line(t + MS, std(fid), "#1" + (data + bytes(56)).hex().upper()))
        else:
            raise ValueError(kind)
    return log.text()


def remote_frames() -> str:
    """Periods 10..29 at +50 ms: remote requests on a monitored input (0x020 + k % 6, no
    length), on TrainState (length 8), on BrakeDemand 0x010 (every 4th period) and on the
    unmonitored 0x123 (every 5th)."""
    log = Log()
    for k in range(PERIODS):
        traffic(log, range(k, k + 1))
        if 10 <= k < 30:
            log.raw(line(t_of(k, 50), std(OBSTACLE_IDS[k % 6]), "R"))
            log.raw(line(t_of(k, 51), std(TRAIN_STATE_ID), "R8"))
            if k % 4 == 0:
                log.raw(line(t_of(k, 52), std(BRAKE_DEMAND_ID), "R"))
            if k % 5 == 0:
                log.raw(line(t_of(k, 53), "123", "R"))
    return log.text()


ERR = 0x20000000


def error_frames() -> str:
    """The monitor's controller reports its error states: error-passive (controller error
    0x004, data[1] = 0x10 RX passive) at 1.0105 s, TX passive (data[1] = 0x20) at
    1.2105 s, bus-off (0x040) at 1.5105 s; then the controller is off the bus: no frame is
    received (the senders go on counting); restarted (0x100) at 2.5105 s, traffic resumes
    at 2.6 s. Periods 15..25 are missing."""
    log = Log()
    events = {10: (0x004, 0x10), 12: (0x004, 0x20), 15: (0x040, 0x00), 25: (0x100, 0x00)}
    for k in range(PERIODS):
        if 15 <= k <= 25:
            log.skip(TRAIN_STATE_ID)
            for fid in OBSTACLE_IDS:
                log.skip(fid)
        else:
            traffic(log, range(k, k + 1))
        if k in events:
            cls, detail = events[k]
            data = bytes([0, detail, 0, 0, 0, 0, 0, 0])
            log.raw(line(t_of(k, 10) + 500, f"{ERR | cls:08X}", data.hex().upper()))
    return log.text()


def time_backwards_small() -> str:
    """Period 20: channel 5's frame (+6 ms) is stamped 40 ms early, before the frames
    written above it (a recorder's timestamp jitter)."""
    def hook(log, k, fid, t, sig):
        if k == 20 and fid == 0x025:
            log.frame(t - 40 * MS, fid, sig)
            return True
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def time_backwards_large() -> str:
    """From period 20 on, the recorder's clock is one hour behind (an NTP step)."""
    log = Log()
    traffic(log, range(20))
    shifted = Log()
    shifted.sender = log.sender
    traffic(shifted, range(20, PERIODS))
    for s in shifted.lines:
        ts, rest = s.split(") ", 1)
        us = round(float(ts[1:]) * 1e6) - 3600 * 1_000_000
        log.raw(f"{stamp(us)} {rest}")
    return log.text()


def forward_gap() -> str:
    """After period 19 the recording pauses for 120 s (more than the 60 s --max-gap)
    and goes on; the senders' counters go on where they stopped."""
    log = Log()
    traffic(log, range(20))
    traffic(log, range(20 + 1200, PERIODS + 1200))
    return log.text()


def stray_zero_timestamp() -> str:
    """One frame of period 20 (channel 0) stamped (0.000000) in the epoch-time log."""
    def hook(log, k, fid, t, sig):
        if k == 20 and fid == 0x020:
            data = log.sender.frame(fid, sig)
            log.raw(f"(0.000000) {IFACE} {std(fid)}#{data.hex().upper()}")
            return True
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def bad_timestamp(text: str) -> str:
    """Healthy, but the timestamp of line 101 (period 14, channel 2) is `text`."""
    log = Log()
    traffic(log, range(PERIODS))
    ts, rest = log.lines[100].split(") ", 1)
    log.lines[100] = f"({text}) {rest}"
    return log.text()


def duplicated_frames() -> str:
    """Periods 10..19: every frame is written twice (same line, same timestamp)."""
    def hook(log, k, fid, t, sig):
        if k in FAULT:
            log.frame(t, fid, sig)
            log.raw(log.lines[-1])
            return True
        return False
    log = Log()
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def flapping_channel() -> str:
    """Channel 0 (0x020) alternates PRESENT (obstacle 150 m ahead, closing at 20 m/s) and
    ABSENT on every frame in periods 10..29; its module partner and the other modules say
    ABSENT. Valid frames all along: only the content flaps."""
    def report(k, ch):
        if ch == 0 and 10 <= k < 30 and k % 2 == 0:
            return Report(PRESENT, 1500, SPEED_CMS, STATIC, 0)
        return CLEAR
    log = Log()
    traffic(log, range(PERIODS), report=report)
    return log.text()


def extreme_values() -> str:
    """Limits accepted, then values outside the DBC ranges.

    periods  8..12  at the limits, all valid: ch0 closing +150.00 m/s, ch1 closing -150.00,
                    ch5 distance 6000.0 m (all ABSENT), TrainState 120.00 m/s
    periods 20..29  out of range: ch0 distance 6553.5 m (raw 0xFFFF, 'no distance'),
                    ch2 closing +150.01, ch3 closing -150.01, ch4 closing -327.68 (raw
                    -32768), TrainState 120.01 m/s (20..24) and 655.35 m/s (25..29)
    """
    def report(k, ch):
        if 8 <= k <= 12:
            return {0: Report(ABSENT, 0, 15000, STATIC, 0), 1: Report(ABSENT, 0, -15000, STATIC, 0),
                    5: Report(ABSENT, 60000, 0, STATIC, 0)}.get(ch, CLEAR)
        if 20 <= k <= 29:
            return {0: Report(ABSENT, 65535, 0, STATIC, 0), 2: Report(ABSENT, 0, 15001, STATIC, 0),
                    3: Report(ABSENT, 0, -15001, STATIC, 0), 4: Report(ABSENT, 0, -32768, STATIC, 0)}.get(ch, CLEAR)
        return CLEAR

    def speed(k):
        if 8 <= k <= 12:
            return 12000
        if 20 <= k <= 24:
            return 12001
        if 25 <= k <= 29:
            return 65535
        return SPEED_CMS
    log = Log()
    traffic(log, range(60), report=report, speed=speed)
    return log.text()


def spoofed_brake_demand() -> str:
    """A log recorded on the monitor's host with `candump -L -x`: frames this host sent end
    in ` T`, received ones in ` R`. The recorded monitor sends BrakeDemand 0x010 at +8 ms
    and MonitorStatus 0x040 at +9 ms each period (emergency in cycle 0, INIT; then none,
    NORMAL). Another node spoofs: in periods 10..29 at +50 ms a BrakeDemand 'none' with a
    correct CRC and the counter of the monitor's last frame; every 4th of those periods a
    MonitorStatus 'NORMAL' at +51 ms with a wrong CRC."""
    log = Log()
    own = Sender()
    spoof = Sender()
    for k in range(PERIODS):
        traffic(log, range(k, k + 1), direction="R")
        level = 2 if k == 0 else 0
        mode = 0 if k == 0 else 1
        bd = own.frame(BRAKE_DEMAND_ID, {"Level": level, "Reason": 0x10 if k == 0 else 0, "Cycle": k + 1})
        log.raw(line(t_of(k, 8), std(BRAKE_DEMAND_ID), bd.hex().upper(), "T"))
        ms = own.frame(MONITOR_STATUS_ID, {"Mode": mode, "Node": 0, "VotedDistance": 65535})
        log.raw(line(t_of(k, 9), std(MONITOR_STATUS_ID), ms.hex().upper(), "T"))
        if 10 <= k < 30:
            fake = encode(BRAKE_DEMAND_ID, {"Level": 0, "Cycle": 0xFFFFFFF0 + k % 16}, bd[1] & 0xF)
            log.raw(line(t_of(k, 50), std(BRAKE_DEMAND_ID), fake.hex().upper(), "R"))
            if k % 4 == 0:
                st = bytearray(spoof.frame(MONITOR_STATUS_ID, {"Mode": 1, "VotedDistance": 65535}))
                st[0] ^= 0x5A
                log.raw(line(t_of(k, 51), std(MONITOR_STATUS_ID), bytes(st).hex().upper(), "R"))
    return log.text()


def babbling_channel() -> str:
    """Channel 2 (0x022) babbles in periods 10..14: five frames per period (+3, +23, ...,
    +83 ms), valid CRC and counter, more than the 3 per 100 ms a sender may send."""
    babble = range(10, 15)

    def hook(log, k, fid, t, sig):
        if fid == 0x022 and k in babble:
            log.frame(t_of(k, 3), fid, sig)
            return True
        return False
    log = Log()
    for k in range(PERIODS):
        traffic(log, range(k, k + 1), hook=hook)
        if k in babble:
            for j in range(1, 5):
                log.frame(t_of(k, 3 + 20 * j), 0x022, report_signals(CLEAR, 2))
    return log.text()


APPROACH_START = 10              # first period the obstacle is seen
APPROACH_FROM_DM = 4000          # 400 m
APPROACH_PERIODS = 185           # ends 30 m ahead: 400 m - 185 * 2 m


def obstacle_approach() -> str:
    """A static obstacle appears 400 m ahead in period 10 on all six channels; the train
    keeps 20 m/s (the log is open loop: it records what the sensors said, not what the
    brakes then did), so the distance falls 2 m per period until 30 m."""
    def report(k, ch):
        if k < APPROACH_START:
            return CLEAR
        return Report(PRESENT, APPROACH_FROM_DM - 20 * (k - APPROACH_START), SPEED_CMS, STATIC, 0)
    log = Log()
    traffic(log, range(APPROACH_START + APPROACH_PERIODS + 1), report=report)
    return log.text()


FORGED_FROM_DM = 20000             # forged_absent_in_step: the obstacle every channel reports, 2,000 m ahead
FORGED_CHANNELS = (2, 3)           # module 1's two channels
FORGED = range(10, 20)             # periods 10..19


def in_step_forgery(channels: tuple, key: Optional[bytes] = None) -> str:
    """Every channel reports a static obstacle from 2,000 m on (2 m closer per period at
    20 m/s, far beyond any curve). A second node forges `channels` in periods 10..19: ABSENT
    with a correct CRC and the counter the genuine frame is about to carry, 0.5 ms before it
    (issue 39). With `key` the bus is secured: the forged frame also carries the freshness
    value the genuine one is about to carry and an authenticator under `key`, which is not the
    ID owner's."""
    def report(k, ch):
        return Report(PRESENT, FORGED_FROM_DM - 20 * k, SPEED_CMS, STATIC, 0)

    def hook(log, k, fid, t, sig):
        ch = fid - OBSTACLE_IDS[0]
        if k in FORGED and ch in channels:
            forged = encode(fid, report_signals(CLEAR, ch), log.next_counter(fid))
            if key is None:
                log.raw(line(t - MS // 2, std(fid), forged.hex().upper()))
            else:
                log.raw(fd_line(t - MS // 2, fid, protect(key, fid, forged, log.security.tx.next.get(fid, 0))))
        return False
    log = Log(secured=key is not None)
    traffic(log, range(PERIODS), hook=hook, report=report)
    return log.text()


def forged_absent_in_step() -> str:
    """Module 1's channels (0x022, 0x023) forged on the classic bus."""
    return in_step_forgery(FORGED_CHANNELS)


def secured_healthy() -> str:
    """The healthy traffic on the secured bus: every frame a 20-byte CAN FD frame, its
    freshness value counting from 0 per ID, its authenticator under its sender's key."""
    log = Log(secured=True)
    traffic(log, range(PERIODS))
    return log.text()


def secured_forged_absent() -> str:
    """The same on the secured bus, by a node holding no key (a key of its own)."""
    return in_step_forgery(FORGED_CHANNELS, noise("forger key", 16))


def secured_stolen_key() -> str:
    """The forger holds channel 0's sensor key (a sensor node taken over) and forges channel 1
    (0x021) with it: a real sensor's authenticator under the wrong key for the ID."""
    return in_step_forgery((1,), corpus_keys()["ch0"])


def secured_replay() -> str:
    """Healthy secured traffic; in periods 10..19 a node sends every channel's genuine frame
    of ten periods earlier again, byte for byte, 0.5 ms before the genuine one (a replay: the
    authenticators are genuine, the freshness values old)."""
    sent: dict = {}

    def hook(log, k, fid, t, sig):
        if k in FORGED and fid in OBSTACLE_IDS:
            log.raw(fd_line(t - MS // 2, fid, sent[(fid, k - 10)]))
        data = log.frame(t, fid, sig)
        sent[(fid, k)] = data
        return True
    log = Log(secured=True)
    traffic(log, range(PERIODS), hook=hook)
    return log.text()


def garbage_line() -> str:
    """A text line in the middle of a good log (line 151)."""
    log = Log()
    traffic(log, range(PERIODS))
    log.lines.insert(150, "recorder restarted -- please ignore the next frames")
    return log.text()


def empty() -> str:
    return ""


BINARY = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03" + noise("binary", 4086)   # a gzip header and noise


CORPUS: dict[str, Callable[[], object]] = {
    "healthy.log": healthy,
    "bad_crc.log": bad_crc,
    "repeated_counter.log": repeated_counter,
    "counter_jump.log": counter_jump,
    "wrong_dlc.log": wrong_dlc,
    "unknown_id.log": unknown_id,
    "extended_id.log": lambda: injected("extended"),
    "fd_frame.log": lambda: injected("fd"),
    "remote_frames.log": remote_frames,
    "error_frames.log": error_frames,
    "time_backwards_small.log": time_backwards_small,
    "time_backwards_large.log": time_backwards_large,
    "stray_zero_timestamp.log": stray_zero_timestamp,
    "nan_timestamp.log": lambda: bad_timestamp("nan"),
    "inf_timestamp.log": lambda: bad_timestamp("inf"),
    "forward_gap.log": forward_gap,
    "duplicated_frames.log": duplicated_frames,
    "flapping_channel.log": flapping_channel,
    "extreme_values.log": extreme_values,
    "spoofed_brake_demand.log": spoofed_brake_demand,
    "babbling_channel.log": babbling_channel,
    "forged_absent_in_step.log": forged_absent_in_step,
    "garbage_line.log": garbage_line,
    "empty.log": empty,
    "binary.log": lambda: BINARY,
    "obstacle_approach.log": obstacle_approach,
    "secured_healthy.log": secured_healthy,
    "secured_forged_absent.log": secured_forged_absent,
    "secured_stolen_key.log": secured_stolen_key,
    "secured_replay.log": secured_replay,
}
SECURED = tuple(n for n in CORPUS if n.startswith("secured_"))   # replayed with --keys (write_keys)


def content(name: str) -> bytes:
    """The bytes the generator writes for one corpus file."""
    value = CORPUS[name]()
    return value if isinstance(value, bytes) else value.encode("ascii")


def write(folder: Path = HERE) -> list[Path]:
    paths = []
    for name in CORPUS:
        p = folder / name
        p.write_bytes(content(name))
        paths.append(p)
    return paths


def main(argv: list[str]) -> int:
    if argv[:1] == ["--keys"] and len(argv) == 2:
        print(f"wrote the corpus TEST key set in {write_keys(Path(argv[1]))}")
        return 0
    if argv[:1] == ["--check"]:
        bad = [n for n in CORPUS if not (HERE / n).is_file() or (HERE / n).read_bytes() != content(n)]
        for n in bad:
            print(f"{HERE / n}: differs from what make_corpus.py writes", file=sys.stderr)
        return 1 if bad else 0
    for p in write():
        print(f"{p.stat().st_size:7d}  {p.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
