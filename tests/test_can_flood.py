"""The monitor on a real SocketCAN vcan0 while cangen floods the bus at full speed (issue 13).

One sandbox boot (can_bus.vcan, DESIGN.md section 7) runs tests/vcan_flood.sh: canplayer
replays valid input traffic (six clear channels and TrainState at 10 Hz) so that the monitor
has a calm baseline with no demand; candump records the frames with ID 010 and a heartbeat
(kernel filters); the monitor runs (`python -m railguard run ... --duration D --json`,
ended by SIGTERM); after the calm start cangen floods the bus, a few seconds each:

1. `random`: random IDs, lengths and data;
2. `channel0`: ID 020 (obstacle channel 0, monitored) with random data;
3. `mix`: CAN FD, extended and remote frames mixed (`cangen -m`);
4. `foreign`: ID 010, the monitor's own BrakeDemand, from another sender (a valid-looking
   'no braking' frame with a cycle number the monitor never reaches).

The offered rate of each flood is read from vcan0's tx_packets counter. On the host the
recorded BrakeDemand frames must show a frame every cycle under every flood (largest gap
at most two cycles: the issue's acceptance criterion, the one timing assertion; on a host
whose hypervisor took a share f of the CPU, two cycles of the sandbox's time, 200 ms / (1 - f)), no frame
lost (alive counter and cycle number step by one), valid CRCs; the monitor exits 0 with
its JSON summary, refuses the flooded channel (`rate_exceeded`) and brakes while it is
flooded, and notices the foreign sender (`foreign_output`).

The sandbox is a user-mode Linux: when its host is busy, the whole sandbox stops for a
moment, monitor and bus alike. A heartbeat (cangen sending every 10 ms, a C program that
does nothing else) shows such stalls; their time is not counted against the monitor's
gaps; a session that stalled too much (or whose host's hypervisor took more than 10 % of the
CPU) is run once more, and the quieter of the two is judged. Under CI=true a sandbox that
cannot be set up is a failure, not a skip.
"""
from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from cantools.autosar.end_to_end import check_profile2_crc

from can_bus import vcan
from can_bus.codec import BRAKE_DEMAND_ID, OBSTACLE_IDS, TRAIN_STATE_ID, Sender, encode, report_signals
from host_load import MAX_STEAL, host_cpu, steal_between
from monitor.core.types import ABSENT, REASON_NAMES, Report

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "tests" / "vcan_flood.sh"
FLOOD_S = 3
CALM_S = 2
KINDS = ("random", "channel0", "mix", "foreign")
MAX_GAP_MS = 200                 # two 100 ms cycles
MIN_FLOOD_FRAMES = 3000          # per flood: >= 1,000 frames/s, 14 times the bus's nominal 70 frames/s
SPOOF_CYCLE = 0xFFFFFFF0         # the foreign sender's BrakeDemand cycle number: the monitor never gets there
OWN_CYCLE_LIMIT = 1000           # the monitor's cycle numbers in this run (about 250 cycles) stay below
HEARTBEAT_ID = 0x7FF
HEARTBEAT = bytes.fromhex("5A5A5A5A5A5A5A5A")
STALL_MS = 50                    # a heartbeat gap longer than this (5 periods): the sandbox stood still
MAX_STALLED_SHARE = 0.04         # more stalled time than this: the run cannot judge the monitor


def spoof_payload() -> bytes:
    """A valid-looking foreign BrakeDemand: 'no braking', correct CRC."""
    return encode(BRAKE_DEMAND_ID, {"Level": 0, "Cycle": SPOOF_CYCLE}, 5)


def write_feed(path: Path, seconds: int = 64) -> None:
    """A candump log of the calm input traffic: six clear channels and TrainState (standstill)
    every 100 ms, alive counters stepping (64 s = 40 x 16 frames per ID: loops seamlessly)."""
    sender = Sender()
    lines = []
    for k in range(seconds * 10):
        t = k * 0.1
        lines.append(f"({t:.6f}) vcan0 {TRAIN_STATE_ID:03X}#{sender.frame(TRAIN_STATE_ID, {'Speed': 0}).hex().upper()}")
        for ch, fid in enumerate(OBSTACLE_IDS):
            data = sender.frame(fid, report_signals(Report(ABSENT, 0, 0, 0, 0), ch))
            lines.append(f"({t + 0.001 * (ch + 1):.6f}) vcan0 {fid:03X}#{data.hex().upper()}")
    path.write_text("\n".join(lines) + "\n")


@dataclass
class Flood:
    kind: str
    t0: float
    t1: float
    tx_frames: int
    rx_frames: int

    @property
    def offered_rate(self) -> float:
        return self.tx_frames / (self.t1 - self.t0)


@dataclass
class Demand:
    t: float
    data: bytes

    @property
    def level(self) -> int:
        return (self.data[1] >> 4) & 0x3

    @property
    def counter(self) -> int:
        return self.data[1] & 0xF

    @property
    def reasons(self) -> list[str]:
        bits = int.from_bytes(self.data[2:4], "little")
        return [name for i, name in enumerate(REASON_NAMES) if bits >> i & 1]

    @property
    def cycle(self) -> int:
        return int.from_bytes(self.data[4:8], "little")


def read_candump(path: Path) -> tuple[list[tuple[float, int, str]], list[str]]:
    """(timestamp, id, data field) of every frame in a candump -L file, and the other lines
    (candump -d writes DROPCOUNT lines when its socket lost frames)."""
    frames, other = [], []
    for line in path.read_text(errors="replace").splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[0].startswith("(") and "#" in parts[2]:
            fid, _, data = parts[2].partition("#")
            frames.append((float(parts[0][1:-1]), int(fid, 16), data))
        elif line.strip():
            other.append(line)
    return frames, other


def payload(data: str) -> bytes | None:
    """Eight data bytes of a classical data frame, else None (remote `R`, FD `#...`, short)."""
    if len(data) != 16 or not all(c in "0123456789abcdefABCDEF" for c in data):
        return None
    return bytes.fromhex(data)


def own_demands(frames: list[tuple[float, int, str]], spoof: bytes) -> list[Demand]:
    """The monitor's BrakeDemand frames among everything recorded on ID 010: eight data bytes,
    not the foreign sender's payload, a cycle number the run can reach (the random floods hit
    010 now and then; their frames fail this with near certainty, and the CRC check below)."""
    out = []
    for t, fid, data in frames:
        d = payload(data) if fid == BRAKE_DEMAND_ID else None
        if d is not None and d != spoof and Demand(t, d).cycle < OWN_CYCLE_LIMIT:
            out.append(Demand(t, d))
    return out


def stalls(frames: list[tuple[float, int, str]]) -> list[tuple[float, float]]:
    """Intervals in which the heartbeat was silent for more than STALL_MS."""
    beats = [t for t, fid, data in frames if fid == HEARTBEAT_ID and payload(data) == HEARTBEAT]
    return [(a, b) for a, b in zip(beats, beats[1:]) if (b - a) * 1000 > STALL_MS]


def overlap(a: float, b: float, intervals: list[tuple[float, float]]) -> float:
    return sum(max(0.0, min(b, y) - max(a, x)) for x, y in intervals)


@dataclass
class FloodRun:
    out: Path
    rc: int
    stdout: str
    summary: dict
    floods: list
    demands: list
    stalls: list
    started: float
    other_lines: list
    seconds: float
    host_steal: float = 0.0

    def stalled(self) -> float:
        return sum(b - a for a, b in self.stalls)

    def span(self) -> float:
        """Seconds from the monitor's first recorded demand to its last (0 with fewer than two)."""
        return self.demands[-1].t - self.demands[0].t if len(self.demands) > 1 else 0.0

    def stalled_share(self) -> float:
        """Share of the monitor's sending time in which the whole sandbox stood still."""
        return self.stalled() / self.span() if self.span() > 0 else 0.0

    def quiet(self) -> bool:
        """The sandbox ran steadily: little stalled time (the heartbeat) and little CPU taken by
        the host's hypervisor. A monitor that sent (almost) nothing counts as quiet: the tests judge it."""
        return self.host_steal <= MAX_STEAL and self.stalled_share() <= MAX_STALLED_SHARE

    def allowed_gap_ms(self) -> float:
        """Two cycles of the sandbox's own time: MAX_GAP_MS, stretched by the share of the CPU the
        host's hypervisor took (steal: time in which the sandbox did not run at all, spread in
        slices too short for the heartbeat to show as stalls). Exactly MAX_GAP_MS on a quiet host."""
        return MAX_GAP_MS / (1.0 - min(self.host_steal, 0.5))

    def stalled_text(self) -> str:
        return (f"stood still {self.stalled():.1f} s of {self.span():.1f} s in {len(self.stalls)} stalls, "
                f"host CPU steal {self.host_steal:.0%}")

    def gaps(self, t0: float = float("-inf"), t1: float = float("inf")) -> list[tuple[float, float, float]]:
        """(gap ms, gap ms less the sandbox's stalls within it, start) of consecutive demands
        whose gap overlaps [t0, t1]."""
        d = self.demands
        return [((b.t - a.t) * 1000, (b.t - a.t - overlap(a.t, b.t, self.stalls)) * 1000, a.t)
                for a, b in zip(d, d[1:]) if b.t >= t0 and a.t <= t1]

    def context(self) -> str:
        rows = []
        for f in self.floods:
            levels = "".join(str(d.level) for d in self.demands if f.t0 <= d.t <= f.t1)
            gaps = self.gaps(f.t0, f.t1)
            rows.append(f"{f.kind}: {f.offered_rate:.0f} frames/s offered ({f.tx_frames} frames), "
                        f"max gap {max((g[0] for g in gaps), default=float('inf')):.0f} ms "
                        f"(less stalls {max((g[1] for g in gaps), default=float('inf')):.0f} ms), levels {levels}")
        return ("; ".join(rows) + f"; sandbox {self.stalled_text()}; "
                f"summary rejects {self.summary.get('rejects')}, deadline misses {self.summary.get('deadline_misses')}, "
                f"max_send_gap_ms {self.summary.get('max_send_gap_ms')}")


def sandbox_available() -> None:
    if shutil.which("apt-get") is None and not (vcan.cache_dir() / "root/usr/bin/linux.uml").is_file():
        if os.environ.get("CI") == "true":
            pytest.fail("no apt-get to fetch user-mode-linux, and no cached sandbox")
        pytest.skip("needs apt-get (Debian) for the user-mode-linux sandbox")


def session(out: Path) -> FloodRun:
    feed = out / "feed.log"
    write_feed(feed)
    spoof = spoof_payload()
    t, cpu0 = time.monotonic(), host_cpu()
    res = vcan.run(["sh", str(SCRIPT), str(out), str(feed), spoof.hex().upper(), str(FLOOD_S), str(CALM_S), " ".join(KINDS)],
                   timeout=150, cwd=ROOT, env={"PYTHONPATH": str(ROOT)})
    seconds, cpu1 = time.monotonic() - t, host_cpu()
    assert not res.timed_out, res.console[-2000:]

    def text(name: str) -> str:
        p = out / name
        return p.read_text(errors="replace") if p.exists() else ""

    try:
        summary = json.loads(text("monitor.json").strip().splitlines()[-1])
    except (ValueError, IndexError):
        summary = {}
    floods = []
    for line in text("floods.txt").splitlines():
        kind, t0, t1, tx, rx = line.split()
        floods.append(Flood(kind, float(t0), float(t1), int(tx), int(rx)))
    frames, other = read_candump(out / "bd.log")
    steal = steal_between(cpu0, cpu1)
    return FloodRun(out, res.returncode, res.stdout + res.stderr + text("monitor.err"), summary, floods,
                    own_demands(frames, spoof), stalls(frames), float(text("started.txt") or "nan"), other, seconds, steal)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """One session; a second one if the first was not quiet (its host was busy: the heartbeat
    and the host's CPU steal say so, not the monitor's results), and the quieter of the two is
    judged. The timing checks take the sandbox's own stalls out of every gap, so a busy host
    does not fail the monitor; every message gives the stalls and the steal."""
    sandbox_available()
    first = session(tmp_path_factory.mktemp("flood"))
    if first.quiet():
        return first
    second = session(tmp_path_factory.mktemp("flood"))
    return min(first, second, key=lambda r: (r.stalled_share(), r.host_steal))


def test_every_flood_ran_at_flood_level(run):
    assert [f.kind for f in run.floods] == list(KINDS), run.stdout
    print(f"sandbox session {run.seconds:.1f} s; " + run.context())
    for f in run.floods:
        assert f.tx_frames >= MIN_FLOOD_FRAMES, f"{f.kind}: only {f.tx_frames} frames offered; {run.context()}"


def test_monitor_exits_cleanly_with_its_summary(run):
    assert run.rc == 0, run.stdout
    assert "Traceback" not in run.stdout
    assert run.summary, f"no JSON summary: {run.stdout}"
    for key in ("frames_received", "frames_rejected", "deadline_misses", "faults_detected", "cycles"):
        assert key in run.summary, key
    assert run.summary["frames_received"] > 0


def test_recording_is_complete(run):
    # candump's own socket must not have lost frames, or the checks below prove nothing
    assert not [line for line in run.other_lines if "DROP" in line.upper()], run.other_lines[:5]
    assert len(run.demands) >= 10 * (2 * CALM_S + len(KINDS) * FLOOD_S), run.context()


def test_brake_demand_leaves_every_cycle_under_every_flood(run):
    gaps = run.gaps()
    worst = max(gaps, key=lambda g: g[1])
    allowed = run.allowed_gap_ms()
    late = [(round(g[0]), round(g[1]), round(g[2] - run.started, 2)) for g in gaps if g[1] > allowed]
    assert not late, (f"BrakeDemand gaps over {allowed:.0f} ms (gap, less sandbox stalls, s after start): {late}; "
                      f"largest {worst[0]:.0f} ms; {run.context()}")


def test_no_brake_demand_lost_and_every_crc_checks(run):
    d = run.demands
    bad_crc = [x.data.hex() for x in d if not check_profile2_crc(x.data, BRAKE_DEMAND_ID & 0xFF)]
    assert not bad_crc, bad_crc[:5]
    jumps = [(i, a.counter, b.counter) for i, (a, b) in enumerate(zip(d, d[1:])) if (b.counter - a.counter) % 16 != 1]
    assert not jumps, f"alive counter must step by one: {jumps[:5]}; {run.context()}"
    cycles = [x.cycle for x in d]
    assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), "cycle numbers must step by one"
    # one frame per cycle and the last emergency demand: nothing the monitor sent is missing
    assert cycles[0] == 1 and cycles[-1] == run.summary["cycles"] + 1, (cycles[:3], cycles[-3:], run.summary.get("cycles"))
    assert d[-1].level == 2, "SIGTERM: the last word is an emergency demand"


def test_calm_start_demands_nothing(run):
    """Without this baseline, braking during the channel flood would prove nothing. A stall
    of the whole sandbox delays the calm traffic too; the monitor then rightly sees stale
    channels, so the second after a stall is not judged."""
    first = run.floods[0].t0
    calm = [x for x in run.demands if run.started + 1.0 <= x.t < first
            and not any(a - 0.1 <= x.t <= b + 1.0 for a, b in run.stalls)]
    braking = [(round(x.t - run.started, 2), x.level, x.reasons) for x in calm if x.level != 0]
    assert len(calm) >= 5 and not braking, f"calm demands {braking}; {run.context()}"


def test_flooded_channel_is_refused_and_the_monitor_brakes(run):
    flood = next(f for f in run.floods if f.kind == "channel0")
    during = [x.level for x in run.demands if flood.t0 + 0.5 <= x.t <= flood.t1]   # cangen starts within 0.5 s
    assert during and set(during) == {2}, f"levels while channel 0 is flooded: {during}; {run.context()}"
    assert run.summary["rejects"]["rate_exceeded"] > 0, run.summary


def test_foreign_sender_on_the_demand_id_is_noticed(run):
    assert run.summary["rejects"]["foreign_output"] > 0, run.summary


def test_monitor_measures_its_own_send_gap(run):
    """The monitor's own view of the criterion. Its clock runs on through a sandbox stall, so
    the longest stall is allowed on top (and the host's steal, as for the recorded gaps)."""
    allowed = run.allowed_gap_ms() + max(((b - a) * 1000 for a, b in run.stalls), default=0)
    assert 0 < run.summary["max_send_gap_ms"] <= allowed, f"allowed {allowed:.0f} ms; {run.context()}"
