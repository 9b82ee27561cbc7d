"""What goes into the runner: a Hypothesis byte string read as a traffic program.

`Tape` reads the bytes (XORed with a fixed pad); `Traffic` turns them into nominal cycles
with persistent faults, valid, mutated, random and hostile frames, signals out of range,
babbling bursts, replays, time steps, cycles and silences, in the proportions of a traffic
profile (`PROFILES`).
"""
from __future__ import annotations

import random
from collections import deque

import can

from can_bus import codec, secoc

from .harness import Harness, StreamStop
from .reference import (
    BRAKE_DEMAND, CAN_ERR_FLAG, DBC_IDS, ERR_BUSOFF, ERR_CRTL, ERR_RESTARTED, MONITOR_RISK, MONITOR_TRACK, MONITORED, OBSTACLES,
    OUTPUTS, TRAIN_STATE,
)


TAPE_BYTES = 7900            # one Hypothesis example: this many bytes of traffic program


class TapeEnd(StreamStop):
    pass


_PAD = int.from_bytes(random.Random(0x5EED).randbytes(TAPE_BYTES), "little")


class Tape:
    """Reads the Hypothesis byte string; running out of it ends the stream.

    The bytes are XORed with a fixed pad first, so that Hypothesis's simplest example (all
    zeros) is an ordinary mixed program rather than thousands of identical nominal cycles."""

    __slots__ = ("buf", "pos")

    def __init__(self, raw: bytes) -> None:
        n = len(raw)
        pad = _PAD & ((1 << (8 * n)) - 1) if n <= TAPE_BYTES else _PAD
        self.buf = (int.from_bytes(raw, "little") ^ pad).to_bytes(n, "little")
        self.pos = 0

    def u8(self) -> int:
        if self.pos >= len(self.buf):
            raise TapeEnd
        v = self.buf[self.pos]
        self.pos += 1
        return v

    def u16(self) -> int:
        return self.u8() | self.u8() << 8

    def u32(self) -> int:
        return self.u16() | self.u16() << 16

    def below(self, n: int) -> int:
        return (self.u8() if n <= 256 else self.u16()) % n

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.buf):
            raise TapeEnd
        b = self.buf[self.pos:self.pos + n]
        self.pos += n
        return b


PROFILES = {   # traffic profile -> relative weights of the instructions (a nominal cycle is 7 frames)
    "mixed": dict(nominal=8, valid=16, mutated=18, random=12, shell=8, out_of_range=6, burst=1, replay=6,
                  advance=14, cycle=10, silence=1),
    "nominal with faults": dict(nominal=60, valid=3, mutated=4, random=3, shell=2, out_of_range=2, burst=1,
                                replay=2, advance=3, cycle=1, silence=1),
    "junk": dict(nominal=3, valid=10, mutated=30, random=30, shell=10, out_of_range=8, burst=2, replay=6,
                 advance=6, cycle=5),
    "babbling": dict(nominal=12, valid=12, burst=10, mutated=8, shell=3, replay=5, advance=20, cycle=8, silence=2),
    "hostile": dict(nominal=10, valid=8, shell=24, burst=6, mutated=8, random=4, replay=4, advance=16, cycle=8,
                    silence=1),
}
PROFILE_NAMES = tuple(PROFILES)


def _op_table(weights: dict) -> tuple:
    total = sum(weights.values())
    table = []
    for name, w in weights.items():
        table += [name] * round(256 * w / total)
    return tuple((table + [table[-1]] * 256)[:256])


OP_TABLES = {name: _op_table(w) for name, w in PROFILES.items()}
SPEEDS = (0, 0, 300, 1500, 4000, 8000, 12000)
FD_LENGTHS = (12, 16, 20, 24, 32, 48, 64)
MONITORED_IDS = tuple(sorted(MONITORED))
UNMONITORED_NEIGHBOURS = (0x000, 0x00F, 0x011, 0x01F, 0x026, 0x02F, 0x031, 0x03F, 0x043, 0x410, 0x420, 0x7FF)
ERROR_CLASSES = (ERR_CRTL, ERR_CRTL, ERR_CRTL, ERR_BUSOFF, ERR_RESTARTED, ERR_CRTL | ERR_RESTARTED,
                 0x001, 0x002, 0x008, 0x010, 0x020, 0x080, 0x200)     # the rest: TX timeout, arbitration, ...
CTRL_BYTES = (0x04, 0x08, 0x10, 0x20, 0x40, 0x14, 0x00, 0x01, 0x02)
FAULTS = ("none",) * 6 + ("disagree", "offset", "silent", "degraded", "train_silent", "train_bad", "far")


class Traffic:
    """Turns a byte string into frames and time steps and feeds them to the harness."""

    def __init__(self, harness: Harness, tape: Tape, profile: str) -> None:
        self.h = harness
        self.tape = tape
        self.ops = tuple(getattr(self, "op_" + name) for name in OP_TABLES[profile])
        self.sender = codec.Sender()     # the codec's encoder: correct CRC and alive counter per ID
        self.now = 0
        self.history: deque = deque(maxlen=64)
        self.secured_history: dict = {}     # ID -> the last secured frames sent on it (secured bus)
        self.channels = harness.channels
        self.period = harness.period
        self.world = dict(present=True, distance=30000, closing=500, obstacle=0, speed=4000, track=0, brake=0,
                          fault="none", target=0)

    def run(self) -> None:
        ops = self.ops
        tape = self.tape
        while True:
            ops[tape.u8()]()

    # ------------------------------------------------------------------ helpers
    def send(self, frame_id: int, data: bytes, kind: str, *, extended=False, remote=False, error=False, fd=False,
             dlc=None) -> None:
        if self.h.sealer is not None and not (extended or remote or error or fd) and dlc is None \
                and len(data) == 8 and frame_id in DBC_IDS:
            data, fd = self.sealed(frame_id, data)
        msg = can.Message(timestamp=self.now / 1000, arbitration_id=frame_id, data=data, is_extended_id=extended,
                          is_remote_frame=remote, is_error_frame=error, is_fd=fd, bitrate_switch=fd, dlc=dlc,
                          check=False)
        self.history.append(msg)
        self.h.feed(self.now, msg, kind)

    def sealed(self, frame_id: int, data: bytes) -> tuple:
        """A secured bus (issue 39): an 8-byte frame as a sender would put it there, (bytes,
        fd). Mostly sealed under its owner's key with the next freshness value; else with a
        bit of the freshness or authenticator flipped, under another sender's key, an earlier
        secured frame of the ID again (a replay), or left classical (an unsecured sender)."""
        b = self.tape.u8()
        sealer = self.h.sealer
        if b >= 240:
            return data, False
        if b >= 225:
            old = self.secured_history.get(frame_id)
            if old:
                return old[self.tape.below(len(old))], True
        if b >= 215:
            wrong = bytes(k ^ 0x5A for k in sealer.keyset.key_for(frame_id))     # a key that is not the owner's
            return secoc.protect(wrong, frame_id, data, sealer.tx.take(frame_id)), True
        out = bytearray(sealer.seal(frame_id, data))
        if b >= 200:
            p = self.tape.below(8 * 12)
            out[8 + p // 8] ^= 1 << (p % 8)
        self.secured_history.setdefault(frame_id, deque(maxlen=8)).append(bytes(out))
        return bytes(out), True

    def valid(self, frame_id: int, signals: dict) -> bytes:
        return self.sender.frame(frame_id, signals)

    def pick(self, lo: int, hi: int) -> int:
        """A value in lo..hi: often a bound or next to one, else uniform."""
        b = self.tape.u8()
        if b < 48:
            return (lo, hi, min(lo + 1, hi), max(hi - 1, lo), max(lo, min(hi, 0)), (lo + hi) // 2)[b % 6]
        return lo + self.tape.u16() % (hi - lo + 1) if hi - lo < 65536 else lo + self.tape.u32() % (hi - lo + 1)

    def signals(self, frame_id: int) -> dict:
        t = self.tape
        if frame_id in OBSTACLES:
            ch = frame_id - OBSTACLES[0]
            b = t.u8()
            return {"Status": b % 3, "ObstacleType": (b >> 2) % 3, "Distance": self.pick(0, 60000),
                    "ClosingSpeed": self.pick(-15000, 15000), "Module": ch // 2, "Channel": ch % 2}
        if frame_id == TRAIN_STATE:
            b = t.u8()
            return {"Speed": self.pick(0, 12000), "TrackCondition": b & 1, "BrakeStatus": (b >> 1) & 1}
        if frame_id == BRAKE_DEMAND:
            return {"Level": t.u8() % 3, "Warning": t.u8() % 2, "Reason": self.pick(0, 32767), "Cycle": t.u32()}
        if frame_id == MONITOR_TRACK:
            b = t.u8()
            return {"TrackState": b % 6, "Memory": (b >> 3) & 1, "TrackDistance": self.pick(0, 65535),
                    "TrackAge": t.u16()}
        if frame_id == MONITOR_RISK:
            return {"RiskCategory": 1 + t.u8() % 4, "RiskScore": t.u8() % 21, "R1": self.pick(0, 500),
                    "R2": self.pick(0, 1000), "TableRisk": self.pick(0, 1000000)}
        return {"Mode": t.u8() & 3, "Node": t.u16() & 1023, "ErrorFlags": t.u8() & 63, "VotedDistance": t.u16(),
                "TableHash": t.u16() & 4095, "DeadlineMisses": t.u8() & 15}

    def pick_id(self) -> int:
        b = self.tape.u8()
        if b < 200:      # mostly what the monitor reads
            return (OBSTACLES + (TRAIN_STATE,))[b % 7]
        return DBC_IDS[b % len(DBC_IDS)]

    def crc(self, frame_id: int, data: bytearray) -> bytearray:
        """The CRC recomputed for frame_id, as a sender would (cantools' AUTOSAR profile 2)."""
        return bytearray(codec.apply_profile2_crc(bytes(data), codec.data_id(frame_id)))

    # ------------------------------------------------------------------ instructions
    def op_valid(self) -> None:
        fid = self.pick_id()
        self.send(fid, self.valid(fid, self.signals(fid)), "valid")

    def op_mutated(self) -> None:
        t = self.tape
        fid = self.pick_id()
        data = bytearray(self.valid(fid, self.signals(fid)))
        flags = dict(extended=False, remote=False, error=False, fd=False, dlc=None)
        recrc = None
        for _ in range(1 + t.u8() % 3):
            m = t.u8() % 13
            if m == 0 and data:                      # bit flip
                p = t.below(8 * len(data))
                data[p // 8] ^= 1 << (p % 8)
            elif m == 1 and data:                    # byte change
                data[t.below(len(data))] = t.u8()
            elif m == 2 and data:                    # truncation
                data = data[:t.below(len(data))]
            elif m == 3:                             # extension (CAN FD sizes too)
                b = t.u8()
                n = 1 + b % 8 if b < 160 else FD_LENGTHS[b % 7] - len(data)
                data += t.take(max(0, n))
                flags["fd"] = len(data) > 8 and b & 1 == 1
            elif m == 4 and len(data) > 1:           # counter replay (the previous frame's counter)
                data[1] = (data[1] & 0xF0) | ((data[1] - 1) & 0xF)
                recrc = True
            elif m == 5 and len(data) > 1:           # counter jump
                data[1] = (data[1] & 0xF0) | ((data[1] + 2 + t.u8() % 14) & 0xF)
                recrc = True
            elif m == 6:                             # ID swapped for another DBC message
                fid = DBC_IDS[t.u8() % len(DBC_IDS)]
            elif m == 7:                             # ID swapped for a random 11-bit ID
                fid = t.u16() & 0x7FF
            elif m == 8:                             # the same ID, 29-bit
                flags["extended"] = True
                fid = fid if t.u8() & 1 else t.u32() & 0x1FFFFFFF
            elif m == 9:                             # remote or error frame
                flags["remote" if t.u8() & 1 else "error"] = True
            elif m == 10:                            # CAN FD flag on a classic length
                flags["fd"] = True
            elif m == 11 and len(data) == 8:         # payload replaced, CRC made to fit
                data[1:] = t.take(7)
                recrc = True
            elif m == 12:                            # DLC that disagrees with the data
                flags["dlc"] = t.u8() % 16
        if recrc is None:
            recrc = t.u8() & 1 == 1
        if recrc and len(data) == 8:
            data = self.crc(fid, data)
        self.send(fid, bytes(data), "mutated", **flags)

    def op_random(self) -> None:
        t = self.tape
        b = t.u8()
        mode = b & 3
        extended = False
        if mode == 0:
            fid = t.u16() & 0x7FF
        elif mode == 1:
            fid, extended = t.u32() & 0x1FFFFFFF, True
        elif mode == 2:
            fid = DBC_IDS[(b >> 2) % len(DBC_IDS)]
            extended = b >> 6 == 3
        else:                                        # out-of-spec: an 11-bit frame with a wider ID
            fid = DBC_IDS[(b >> 2) % len(DBC_IDS)] | (1 << (11 + t.u8() % 18))
        f = t.u8()
        n = t.u8()
        length = n % 9 if n < 176 else (FD_LENGTHS[n % 7] if n < 240 else n % 65)
        data = t.take(length)
        self.send(fid, data, "random", extended=extended, remote=f < 16, error=16 <= f < 24,
                  fd=length > 8 or f >= 224, dlc=(f % 16) if 200 <= f < 224 else None)

    def op_out_of_range(self) -> None:
        t = self.tape
        b = t.u8()
        if b < 180:
            fid = OBSTACLES[b % 6]
            ch = fid - OBSTACLES[0]
            sig = self.signals(fid)
            which = t.u8() % 7
            if which == 0:
                sig["Status"] = 3
            elif which == 1:
                sig["ObstacleType"] = 3
            elif which == 2:
                sig["Distance"] = 60001 + t.u16() % 5535
            elif which == 3:
                sig["ClosingSpeed"] = 15001 + t.u16() % 17767
            elif which == 4:
                sig["ClosingSpeed"] = -15001 - t.u16() % 17768
            elif which == 5:
                sig["Module"] = 3 if t.u8() & 1 else (ch // 2 + 1) % 3
            else:
                sig["Channel"] = 1 - ch % 2
        elif b < 230:
            fid = TRAIN_STATE
            sig = self.signals(fid)
            sig["Speed"] = 12001 + t.u16() % 53535
        else:
            fid = BRAKE_DEMAND
            sig = self.signals(fid)
            if b & 1:
                sig["Level"] = 3
            else:
                sig["Reason"] = 16384 + t.u16() % 49152
        self.send(fid, self.valid(fid, sig), "out_of_range")

    def op_burst(self) -> None:
        """A babbling sender: valid frames, or with bad CRCs or wrong lengths among them (the rate
        policing counts every frame on the ID), or with FD/remote frames on the same ID among
        them (refused before the policing: they do not count)."""
        t = self.tape
        fid = (OBSTACLES + (TRAIN_STATE,))[t.u8() % 7]
        n = 4 + t.u8() % 20
        gap = t.u8() % 40
        style = t.u8() % 4
        sig = self.signals(fid)
        for _ in range(n):
            data = self.valid(fid, sig)
            b = t.u8() if style else 0
            if style == 1 and b & 1:                   # CRC broken
                self.send(fid, bytes([data[0] ^ (1 + (b >> 1))]) + data[1:], "burst")
            elif style == 2 and b & 1:                 # wrong length
                self.send(fid, data[:b % 8] if b & 2 else data + bytes(1 + b % 8), "burst")
            elif style == 3 and b & 1:                 # an FD or remote frame on the same ID
                if b & 2:
                    self.send(fid, data, "burst", fd=True)
                else:
                    self.send(fid, b"", "burst", remote=True, dlc=8)
            else:
                self.send(fid, data, "burst")
            self.now += gap

    def op_shell(self) -> None:
        """A frame the shell refuses or drops before the codec: CAN FD, remote, error frames,
        frames on the monitor's own output IDs, 29-bit or unmonitored 11-bit IDs."""
        t = self.tape
        b = t.u8()
        what = b % 8
        fid = MONITORED_IDS[t.u8() % len(MONITORED_IDS)]
        if what == 0:                                  # CAN FD on a monitored ID: a valid payload, or longer
            data = codec.encode(fid, self.signals(fid), t.u8())
            if b & 0x80:
                data += t.take(FD_LENGTHS[t.u8() % len(FD_LENGTHS)] - 8)
            self.send(fid, data, "fd", fd=True)
        elif what == 1:                                # a remote request
            self.send(fid, b"", "remote", remote=True, dlc=t.u8() % 9, extended=b & 0x80 == 0x80)
        elif what in (2, 3):                           # a controller error frame
            cls = ERROR_CLASSES[t.u8() % len(ERROR_CLASSES)] | (t.u8() & 0x3 if b & 0x80 else 0)
            n = 8 if b & 0x40 == 0 else t.u8() % 3
            data = bytearray(t.take(n))
            if n >= 2:
                data[1] = CTRL_BYTES[t.u8() % len(CTRL_BYTES)]
            self.send(cls | (CAN_ERR_FLAG if b & 0x20 else 0), bytes(data), "error", error=True,
                      extended=True)
        elif what in (4, 5):                           # on the monitor's own output IDs
            out = OUTPUTS[(b >> 3) % len(OUTPUTS)]
            if b & 0x40:
                data = self.valid(out, self.signals(out))
            else:
                data = t.take(t.u8() % 9)
            self.send(out, data, "foreign")
        elif what == 6:                                # a monitored ID, 29-bit
            self.send(fid, codec.encode(fid, self.signals(fid), t.u8()), "filtered", extended=True)
        else:                                          # an 11-bit ID next to the monitored ones
            self.send(UNMONITORED_NEIGHBOURS[t.u8() % len(UNMONITORED_NEIGHBOURS)], t.take(8), "filtered")

    def op_replay(self) -> None:
        if not self.history:
            return
        old = self.history[-1 - self.tape.below(len(self.history))]
        self.send(old.arbitration_id, bytes(old.data), "replay", extended=old.is_extended_id,
                  remote=old.is_remote_frame, error=old.is_error_frame, fd=old.is_fd, dlc=old.dlc)

    def op_advance(self) -> None:
        self.now += self.tape.u8() % 50

    def op_cycle(self) -> None:
        self.now = max(self.now, self.h.runner.next_tick)
        while self.h.runner.next_tick <= self.now:
            self.h.cycle()

    def op_silence(self) -> None:
        b = self.tape.u8()
        self.now = self.h.runner.next_tick + self.period * (b % 8 if b < 224 else b % 40)
        self.op_cycle()

    def op_nominal(self) -> None:
        """Every channel and the TrainState once, consistent up to the world's fault, then the cycle."""
        t, w = self.tape, self.world
        b = t.u8()
        if b < 16:                                   # a new situation
            w.update(present=t.u8() < 170, distance=self.pick(0, 60000), closing=self.pick(-3000, 3000),
                     obstacle=t.u8() % 3, speed=SPEEDS[t.u8() % 7], track=b & 1, brake=(b >> 1) & 1)
        elif b < 26:                                 # a new persistent fault (or its end)
            w["fault"] = FAULTS[t.u8() % len(FAULTS)]
            w["target"] = t.u8()
        elif w["present"]:
            w["distance"] = max(0, w["distance"] - w["speed"] // 100)
        noise = t.u8()
        order = list(range(self.channels)) + [None]
        rot = noise % len(order)
        order = order[rot:] + order[:rot]
        fault, target = w["fault"], w["target"]
        for ch in order:
            if ch is None:
                if fault == "train_silent":
                    continue
                speed = 12000 + 1 + target if fault == "train_bad" else w["speed"]
                self.send(TRAIN_STATE, self.valid(TRAIN_STATE, {"Speed": speed, "TrackCondition": w["track"],
                                                               "BrakeStatus": w["brake"]}), "nominal")
                continue
            status = 1 if w["present"] else 0
            distance = min(60000, w["distance"] + (noise >> 4) * (1 if ch & 1 else -1) // 2) if status else 0
            distance = max(0, distance)
            m = ch // 2
            if fault == "disagree" and m == target % (self.channels // 2) and ch % 2 == 1:
                status = 1 - status
            elif fault == "offset" and ch == target % self.channels:
                distance = min(60000, distance + 3000)
            elif fault == "silent" and ch == target % self.channels:
                continue
            elif fault == "degraded" and ch == target % self.channels:
                status = 2
            elif fault == "far" and ch == target % self.channels:
                distance = 60000
            fid = OBSTACLES[ch]
            self.send(fid, self.valid(fid, {"Status": status, "ObstacleType": w["obstacle"], "Distance": distance,
                                            "ClosingSpeed": w["closing"], "Module": m, "Channel": ch % 2}),
                      "nominal")
            self.now += (noise >> ch) & 3
        self.now = max(self.now, self.h.runner.next_tick)
        self.op_cycle()
