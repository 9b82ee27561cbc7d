"""The CAN runner on the host's in-process virtual bus, in real time (wall clock).

1. Sustained input rate: a sender thread offers valid ObstacleReport and TrainState frames
   (seven senders, round robin, correct counters and CRCs) at a fixed rate for a few
   seconds while the runner runs its 100 ms cycle; a rate passes if every frame is accepted
   (no counter jump, i.e. none lost or reordered) and no deadline is missed. The babbling
   check is switched off for this measurement (see throughput()).
2. Latency: at a random phase of the cycle all six channels report an obstacle inside the
   emergency braking distance; the time from that frame to the BrakeDemand frame with
   level 2 is measured (bus timestamps). Between trials the train stands still for two
   cycles so that the emergency latch releases.

3. Flood, in process (`--flood`): on the virtual bus, flood threads offer frames as fast as
   Python can (`random`: random 11-bit IDs, lengths and data; `channel0`: the monitored
   obstacle channel 0x020 with random data; `foreign`: a valid-looking 'no braking' frame on
   the monitor's own BrakeDemand ID 0x010) while a feeder sends valid input traffic at 10 Hz
   and the runner runs in real time. The monitor's connection has a bounded receive queue
   (MONITOR_QUEUE frames, as a socket buffer: when full, new frames are dropped); a third
   connection listens for BrakeDemand. Printed per flood: offered rate, handled rate
   (runner.frames_received per second of flood), largest gap between two BrakeDemand
   frames (bus timestamps, over calm, flood and tail), deadline misses, the share of
   emergency demands during the flood, the monitor's rejects.
4. Flood on a real vcan0 (`--vcan`): tests/vcan_flood.sh in the user-mode Linux sandbox
   (can_bus.vcan), one boot per flood kind (`random`, `channel0`, `mix`: FD/extended/remote
   frames, `foreign`), cangen at full speed (`-g 0 -i`); the monitor is the real
   `python -m railguard run` process with kernel receive filters. Printed per flood:
   offered rate (vcan0 tx_packets per second), handled rate (the monitor's frames_received
   per second of flood, calm traffic subtracted), largest BrakeDemand gap over the run
   (candump, kernel timestamps), the same less the sandbox's own stalls (a 10 ms cangen
   heartbeat shows when the whole user-mode Linux stood still because its host was busy),
   the monitor's own max_send_gap_ms, deadline misses, emergency share, rejects.
   The sandbox has one CPU shared by cangen, candump, canplayer and the monitor, and every
   system call costs about 15 us there: its rates are not the host's.

Run: python benchmarks/bench_can.py [--json] [--rates 4000 8000 ...] [--trials N]
     python benchmarks/bench_can.py --flood [--flood-seconds S] [--flood-threads N] [--json]
     python benchmarks/bench_can.py --vcan [--flood-seconds S] [--json]
--flood and --vcan run those sections instead of the default ones (both may be given);
--json prints one JSON object with the sections run ("flood", "vcan").
Targets (issue 4): >= 8,000 frames/s sustained; latency p99 <= one cycle + 5 ms.
Target (issue 13): under every flood the BrakeDemand gap stays <= two cycles (200 ms).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import tempfile
import threading
import time
from importlib import resources
from pathlib import Path

import can

from can_bus.clock import WallClock
from can_bus.codec import BRAKE_DEMAND_ID, OBSTACLE_IDS, TRAIN_STATE_ID, Sender, encode, report_signals
from can_bus.runner import MonitorRunner
from monitor.core import cycle
from monitor.core.config import Config
from monitor.core.types import ABSENT, PRESENT, Report


def setup() -> cycle.Setup:
    return cycle.create(Config(), resources.files("monitor.tables").joinpath("m1.table.rgt").read_bytes())


def run_runner(runner: MonitorRunner, stop: threading.Event) -> None:
    while not stop.is_set():
        runner.drain(runner.next_tick)
        runner.clock.sleep_until_ms(runner.next_tick)
        runner.cycle()


def throughput(rate: int, seconds: float, channel: str) -> dict:
    mon = can.Bus(interface="virtual", channel=channel)
    tx = can.Bus(interface="virtual", channel=channel)
    runner = MonitorRunner(mon, setup(), WallClock())
    # Six senders cannot fill a bus at their nominal 10 frames/s; offered this fast they would
    # (rightly) be quarantined as babbling. Switch the rate check off to measure the capacity
    # of the receive path itself: CRC, counters, ranges, latching, the cycle.
    runner.receiver.rate_window_ms = 0
    sender = Sender()
    # pre-encode 16 frames per channel (one per counter value) so that the sender is cheap
    frames = []
    for ch, fid in enumerate(OBSTACLE_IDS):
        rep = report_signals(Report(ABSENT, 0, 0, 0, 0), ch)
        frames.append([can.Message(arbitration_id=fid, data=sender.frame(fid, rep), is_extended_id=False)
                       for _ in range(16)])
    train = [can.Message(arbitration_id=TRAIN_STATE_ID, data=sender.frame(TRAIN_STATE_ID, {"Speed": 0}),
                         is_extended_id=False) for _ in range(16)]
    stop = threading.Event()
    worker = threading.Thread(target=run_runner, args=(runner, stop), daemon=True)
    worker.start()
    sent = 0
    t0 = time.perf_counter()
    total = int(rate * seconds)
    k = 0
    while sent < total:
        due = int((time.perf_counter() - t0) * rate)
        while sent < min(due, total):
            ch = sent % 7
            msgs = train if ch == 6 else frames[ch]
            tx.send(msgs[(sent // 7) % 16])
            sent += 1
        k += 1
        time.sleep(0.0005)
    time.sleep(0.3)
    stop.set()
    worker.join()
    offered_s = time.perf_counter() - t0 - 0.3
    rx = runner.receiver
    res = {"rate_offered": rate, "frames_sent": sent, "accepted": rx.accepted, "rejected": dict(rx.rejected),
           "deadline_misses": runner.deadline_misses, "achieved_rate": round(sent / offered_s),
           "lossless": rx.accepted == sent and rx.rejected_total == 0 and runner.deadline_misses == 0}
    mon.shutdown()
    tx.shutdown()
    return res


def latency(trials: int, channel: str, seed: int = 1, secured: bool = False) -> dict:
    """Obstacle frame to emergency BrakeDemand frame; `secured`: every frame signed and
    verified (a test key set in a temporary folder, its freshness state written as it goes)."""
    mon_sec = player_sec = None
    if secured:
        mon_sec, player_sec = secured_pair()
    mon = can.Bus(interface="virtual", channel=channel)
    tx = can.Bus(interface="virtual", channel=channel)
    listen = can.Bus(interface="virtual", channel=channel)
    runner = MonitorRunner(mon, setup(), WallClock(), security=mon_sec)
    period = runner.period / 1000
    sender = Sender(player_sec)
    rng = random.Random(seed)
    stop = threading.Event()
    worker = threading.Thread(target=run_runner, args=(runner, stop), daemon=True)
    worker.start()

    def send_all(status: int, distance_dm: int, speed_cms: int) -> float:
        tx.send(can.Message(arbitration_id=TRAIN_STATE_ID, is_extended_id=False, is_fd=secured,
                            data=sender.frame(TRAIN_STATE_ID, {"Speed": speed_cms})))
        msgs = [can.Message(arbitration_id=fid, is_extended_id=False, is_fd=secured,
                            data=sender.frame(fid, report_signals(Report(status, distance_dm, 0, 0, 0), ch)))
                for ch, fid in enumerate(OBSTACLE_IDS)]
        first = time.time()          # the virtual bus stamps received copies with time.time()
        for msg in msgs:
            tx.send(msg)
        return first

    def settle(cycles: int, speed: int) -> None:
        for _ in range(cycles):
            send_all(ABSENT, 0, speed)
            time.sleep(period)

    samples = []
    settle(5, 0)
    for _ in range(trials):
        settle(2, 3000)                              # clear track, moving at 30 m/s
        while listen.recv(timeout=0) is not None:    # forget older demands
            pass
        time.sleep(rng.uniform(0, period))           # random phase within the cycle
        t_obstacle = send_all(PRESENT, 50, 3000)     # 5 m ahead: inside the envelope
        t_end = time.time() + 3 * period
        while time.time() < t_end:
            msg = listen.recv(timeout=0.01)
            if msg is not None and msg.arbitration_id == 0x10 and (msg.data[1] >> 4) & 0x3 == 2 \
                    and msg.timestamp >= t_obstacle:
                samples.append((msg.timestamp - t_obstacle) * 1000)
                break
        settle(3, 0)                                 # standstill: the latch releases
    stop.set()
    worker.join()
    for b in (mon, tx, listen):
        b.shutdown()
    samples.sort()
    q = lambda p: samples[min(len(samples) - 1, int(p * len(samples)))]  # noqa: E731
    return {"secured": secured, "trials": trials, "answered": len(samples), "p50_ms": round(q(0.5), 2),
            "p99_ms": round(q(0.99), 2), "max_ms": round(samples[-1], 2), "mean_ms": round(statistics.mean(samples), 2),
            "target_p99_ms": runner.period + (10 if secured else 5), "rejected": dict(runner.receiver.rejected)}


# ---------------------------------------------------------------------------------- floods
ROOT = Path(__file__).resolve().parents[1]
FLOOD_SCRIPT = ROOT / "tests" / "vcan_flood.sh"
MONITOR_QUEUE = 2048             # frames the monitor's in-process connection holds, as a socket buffer would
SPOOF_CYCLE = 0xFFFFFFF0         # the foreign sender's cycle number: the monitor never gets there
CALM_RATE = 70                   # frames/s of valid input traffic (six channels and TrainState at 10 Hz)
INPROCESS_KINDS = ("random", "channel0", "foreign", "bad_mac")   # bad_mac: against a secured monitor
VCAN_KINDS = ("random", "channel0", "mix", "foreign")


def largest(gaps_ms: list) -> float | None:
    """The largest gap in ms, None without two BrakeDemand frames (JSON has no infinity)."""
    return round(max(gaps_ms), 1) if gaps_ms else None


def spoof_payload() -> bytes:
    """A valid-looking foreign BrakeDemand: 'no braking', correct CRC (as tests/test_can_flood.py)."""
    return encode(BRAKE_DEMAND_ID, {"Level": 0, "Cycle": SPOOF_CYCLE}, 5)


def calm_frames(sender: Sender) -> list[can.Message]:
    """One period of valid input traffic: TrainState at standstill, six clear channels (secured
    CAN FD frames if the sender has a Security)."""
    fd = sender.security is not None
    msgs = [can.Message(arbitration_id=TRAIN_STATE_ID, data=sender.frame(TRAIN_STATE_ID, {"Speed": 0}),
                        is_extended_id=False, is_fd=fd)]
    for ch, fid in enumerate(OBSTACLE_IDS):
        msgs.append(can.Message(arbitration_id=fid, is_extended_id=False, is_fd=fd,
                                data=sender.frame(fid, report_signals(Report(ABSENT, 0, 0, 0, 0), ch))))
    return msgs


def secured_pair():
    """(monitor's, feeder's) Security on a fresh test key set in a temporary folder."""
    from can_bus.keys import SENDERS
    from can_bus.security import for_node, made_test_keys

    folder = made_test_keys(Path(tempfile.mkdtemp()) / "keys")
    return for_node(folder, "monitor", SENDERS), for_node(folder, "bench", SENDERS)


def flood_frames(kind: str, rng: random.Random, n: int = 4096) -> list[can.Message]:
    if kind == "random":
        return [can.Message(arbitration_id=rng.randrange(0x800), is_extended_id=False,
                            data=rng.randbytes(rng.randrange(9))) for _ in range(n)]
    if kind == "channel0":
        return [can.Message(arbitration_id=OBSTACLE_IDS[0], is_extended_id=False, data=rng.randbytes(8))
                for _ in range(n)]
    if kind == "foreign":
        return [can.Message(arbitration_id=BRAKE_DEMAND_ID, is_extended_id=False, data=spoof_payload())]
    if kind == "bad_mac":   # secured frames on channel 0 whose freshness is new (so each costs a CMAC), keyless
        return [can.Message(arbitration_id=OBSTACLE_IDS[0], is_extended_id=False, is_fd=True,
                            data=rng.randbytes(8) + (i % 65536).to_bytes(4, "little") + rng.randbytes(8))
                for i in range(n)]
    raise ValueError(kind)


def send_only_bus(channel: str) -> can.BusABC:
    """A virtual-bus connection that only sends: its receive queue is taken off the channel,
    so that frames never pile up there (python-can's virtual bus has no send-only mode, and a
    bounded queue would block the runner's own sends once full)."""
    from can.interfaces import virtual

    bus = can.Bus(interface="virtual", channel=channel)
    with virtual.channels_lock:
        bus.channel.remove(bus.queue)
    return bus


def shutdown_send_only(bus: can.BusABC) -> None:
    from can.interfaces import virtual

    with virtual.channels_lock:
        bus.channel.append(bus.queue)
    bus.shutdown()


def flood_inprocess(kind: str, seconds: float, threads: int, calm: float = 1.0, tail: float = 0.5) -> dict:
    """One flood on the in-process virtual bus against the runner in real time."""
    channel = f"bench-flood-{kind}"
    mon = can.Bus(interface="virtual", channel=channel, rx_queue_size=MONITOR_QUEUE)
    listen = can.Bus(interface="virtual", channel=channel)                  # unbounded: misses nothing
    feed_bus = send_only_bus(channel)
    flood_buses = [send_only_bus(channel) for _ in range(threads)]
    mon_sec, feed_sec = secured_pair() if kind == "bad_mac" else (None, None)
    runner = MonitorRunner(mon, setup(), WallClock(), security=mon_sec)
    spoof = spoof_payload()
    stop, stop_flood = threading.Event(), threading.Event()
    demands: list[tuple[float, int]] = []
    offered = [0] * threads

    def send(bus: can.BusABC, msg: can.Message) -> None:
        try:
            bus.send(msg, timeout=0)
        except can.CanError:          # the monitor's queue was full: dropped there only, as by a socket
            pass

    def feeder() -> None:
        sender = Sender(feed_sec)
        nxt = time.monotonic()
        while not stop.is_set():
            for msg in calm_frames(sender):
                send(feed_bus, msg)
            nxt += runner.period / 1000
            time.sleep(max(0.0, nxt - time.monotonic()))

    def listener() -> None:
        while True:
            msg = listen.recv(timeout=0.05)
            if msg is None:
                if stop.is_set():
                    return
                continue
            if msg.arbitration_id == BRAKE_DEMAND_ID and len(msg.data) in (8, 20) and bytes(msg.data) != spoof:
                demands.append((msg.timestamp, (msg.data[1] >> 4) & 0x3))

    def flooder(i: int) -> None:
        msgs = flood_frames(kind, random.Random(i))
        bus, k, n = flood_buses[i], len(msgs), 0
        while not stop_flood.is_set():
            send(bus, msgs[n % k])
            n += 1
        offered[i] = n

    workers = [threading.Thread(target=f, daemon=True) for f in (lambda: run_runner(runner, stop), feeder, listener)]
    for w in workers:
        w.start()
    time.sleep(calm)
    floods = [threading.Thread(target=flooder, args=(i,), daemon=True) for i in range(threads)]
    r0, m0, t0 = runner.frames_received, runner.deadline_misses, time.time()
    for f in floods:
        f.start()
    time.sleep(seconds)
    stop_flood.set()
    for f in floods:
        f.join()
    r1, t1 = runner.frames_received, time.time()
    time.sleep(tail)
    stop.set()
    for w in workers:
        w.join()
    for b in (feed_bus, *flood_buses):       # first: the channel must still exist
        shutdown_send_only(b)
    for b in (mon, listen):
        b.shutdown()
    ts = [t for t, _ in demands]
    during = [lvl for t, lvl in demands if t0 + 0.3 <= t <= t1]
    return {"kind": kind, "threads": threads, "seconds": round(t1 - t0, 2),
            "offered_rate": round(sum(offered) / (t1 - t0)), "handled_rate": round((r1 - r0) / (t1 - t0)),
            "max_gap_ms": largest([(b - a) * 1000 for a, b in zip(ts, ts[1:])]),
            "deadline_misses": runner.deadline_misses, "deadline_misses_in_flood": runner.deadline_misses - m0,
            "max_send_gap_ms": runner.max_send_gap_ms,
            "emergency_share": round(during.count(2) / len(during), 2) if during else None,
            "demands": len(demands), "rejects": dict(runner.receiver.rejected)}


def flood_vcan(kind: str, seconds: float, calm: float = 2.0) -> dict:
    """One flood on the sandbox's vcan0 against the real monitor process: tests/vcan_flood.sh,
    read with the helpers of tests/test_can_flood.py (same feed, spoof, parsing, stalls)."""
    import sys

    from can_bus import vcan

    sys.path.insert(0, str(ROOT / "tests"))
    import test_can_flood as ft

    spoof = ft.spoof_payload()
    with tempfile.TemporaryDirectory(prefix="bench-vcan-") as tmp:
        out = Path(tmp)
        ft.write_feed(out / "feed.log")
        t = time.monotonic()
        res = vcan.run(["sh", str(FLOOD_SCRIPT), str(out), str(out / "feed.log"), spoof.hex().upper(), str(seconds),
                        str(calm), kind], timeout=180, cwd=ROOT, env={"PYTHONPATH": str(ROOT)})
        wall = time.monotonic() - t
        if res.timed_out or not (out / "floods.txt").exists():
            return {"kind": kind, "error": f"sandbox rc {res.returncode}: {(res.stdout + res.stderr)[-500:]}"}
        _, t0, t1, tx, _ = (out / "floods.txt").read_text().split()
        t0, t1 = float(t0), float(t1)
        try:
            summary = json.loads((out / "monitor.json").read_text().strip().splitlines()[-1])
        except (ValueError, IndexError):
            summary = {}
        frames, other = ft.read_candump(out / "bd.log")
    demands = ft.own_demands(frames, spoof)
    stalls = ft.stalls(frames)
    gaps = [((b.t - a.t) * 1000, (b.t - a.t - ft.overlap(a.t, b.t, stalls)) * 1000) for a, b in zip(demands, demands[1:])]
    during = [d.level for d in demands if t0 + 0.3 <= d.t <= t1]
    cycles = summary.get("cycles", 0)
    received = summary.get("frames_received")
    handled = None if received is None else round(max(0.0, received - CALM_RATE * (cycles / 10 - (t1 - t0))) / (t1 - t0))
    return {"kind": kind, "seconds": round(t1 - t0, 2), "offered_rate": round(int(tx) / (t1 - t0)),
            "handled_rate": handled, "max_gap_ms": largest([g[0] for g in gaps]),
            "max_gap_less_stalls_ms": largest([g[1] for g in gaps]),
            "sandbox_stalls_ms": round(sum(b - a for a, b in stalls) * 1000),
            "max_send_gap_ms": summary.get("max_send_gap_ms"), "deadline_misses": summary.get("deadline_misses"),
            "emergency_share": round(during.count(2) / len(during), 2) if during else None,
            "demands": len(demands), "candump_drops": sum("DROP" in line for line in other),
            "monitor_rc": res.returncode, "rejects": summary.get("rejects"), "sandbox_s": round(wall, 1)}


def print_floods(title: str, rows: list[dict]) -> None:
    sandbox = any("max_gap_less_stalls_ms" in r for r in rows)
    print(title)
    print(f"{'flood':>10}{'offered/s':>11}{'handled/s':>11}{'max gap ms':>12}"
          + (f"{'less stalls':>13}" if sandbox else "") + f"{'own gap ms':>12}{'misses':>8}{'emergency':>11}  rejects")
    for r in rows:
        if "error" in r:
            print(f"{r['kind']:>10}  {r['error']}")
            continue
        share = "-" if r["emergency_share"] is None else f"{r['emergency_share']:.0%}"
        rejects = ", ".join(f"{k} {v}" for k, v in sorted((r.get("rejects") or {}).items())) or "-"
        print(f"{r['kind']:>10}{r['offered_rate']:>11}{str(r['handled_rate']):>11}{r['max_gap_ms']:>12}"
              + (f"{r['max_gap_less_stalls_ms']:>13}" if sandbox else "")
              + f"{str(r['max_send_gap_ms']):>12}{str(r['deadline_misses']):>8}{share:>11}  {rejects}")
    key = "max_gap_less_stalls_ms" if sandbox else "max_gap_ms"
    worst = max((r[key] for r in rows if "error" not in r and r[key] is not None), default=None)
    print(f"largest BrakeDemand gap over all floods: {worst} ms"
          + (" (less the sandbox's own stalls, seen in a 10 ms heartbeat: "
             + ", ".join(f"{r['kind']} {r['sandbox_stalls_ms']} ms" for r in rows if "error" not in r) + ")" if sandbox else "")
          + "; target <= 200 ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=int, nargs="+", default=[2000, 4000, 8000, 12000, 16000])
    ap.add_argument("--seconds", type=float, default=4.0, help="duration per rate")
    ap.add_argument("--trials", type=int, default=100, help="latency trials")
    ap.add_argument("--flood", action="store_true", help="floods on the in-process virtual bus (instead of the default sections)")
    ap.add_argument("--vcan", action="store_true", help="floods with cangen on a real vcan0 in the sandbox (instead of the default sections)")
    ap.add_argument("--flood-kinds", nargs="+", choices=INPROCESS_KINDS, default=list(INPROCESS_KINDS), metavar="KIND",
                    help=f"which in-process floods (--flood): {', '.join(INPROCESS_KINDS)} (default: all; bad_mac: "
                         "keyless secured frames with new freshness values against a secured monitor)")
    ap.add_argument("--flood-seconds", type=float, default=4.0, help="duration per flood")
    ap.add_argument("--flood-threads", type=int, default=2, help="flood threads (--flood)")
    ap.add_argument("--latency-only", action="store_true",
                    help="only the obstacle-to-brake latency, unsecured and secured (issue 39: p99 <= 110 ms)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if args.latency_only:
        rows = [latency(args.trials, f"bench-latency-{k}", secured=k) for k in (False, True)]
        if args.json:
            print(json.dumps(rows))
            return
        for lat in rows:
            print(f"{'secured  ' if lat['secured'] else 'unsecured'} obstacle frame -> emergency BrakeDemand: "
                  f"p50 {lat['p50_ms']} ms, p99 {lat['p99_ms']} ms, max {lat['max_ms']} ms over "
                  f"{lat['answered']}/{lat['trials']} trials (target p99 <= {lat['target_p99_ms']} ms); rejected "
                  f"{sum(lat['rejected'].values())}")
        return
    if args.flood or args.vcan:
        result = {}
        if args.flood:
            result["flood"] = [flood_inprocess(k, args.flood_seconds, args.flood_threads) for k in args.flood_kinds]
        if args.vcan:
            result["vcan"] = [flood_vcan(k, args.flood_seconds) for k in VCAN_KINDS]
        if args.json:
            print(json.dumps(result))
            return
        if "flood" in result:
            print_floods(f"floods, in-process virtual bus, runner in real time ({args.flood_threads} flood threads, "
                         f"monitor queue {MONITOR_QUEUE} frames, {os.cpu_count()} CPUs)", result["flood"])
        if "vcan" in result:
            print_floods("floods, cangen on a real vcan0 (user-mode Linux sandbox, one CPU), "
                         "the monitor process with kernel receive filters", result["vcan"])
        return
    rates = [throughput(r, args.seconds, f"bench-rate-{r}") for r in args.rates]
    lat = latency(args.trials, "bench-latency")
    best = max([r["rate_offered"] for r in rates if r["lossless"]], default=0)
    if args.json:
        print(json.dumps({"throughput": rates, "max_lossless_rate": best, "latency": lat}))
        return
    print("sustained input rate (virtual bus, real time, 100 ms cycle)")
    print(f"{'offered/s':>10}{'achieved/s':>12}{'sent':>8}{'accepted':>10}{'rejected':>10}{'misses':>8}  lossless")
    for r in rates:
        print(f"{r['rate_offered']:>10}{r['achieved_rate']:>12}{r['frames_sent']:>8}{r['accepted']:>10}"
              f"{sum(r['rejected'].values()):>10}{r['deadline_misses']:>8}  {r['lossless']}")
    print(f"highest lossless rate: {best} frames/s (target >= 8000)")
    print(f"obstacle frame -> emergency BrakeDemand: p50 {lat['p50_ms']} ms, p99 {lat['p99_ms']} ms, "
          f"max {lat['max_ms']} ms over {lat['answered']}/{lat['trials']} trials (target p99 <= {lat['target_p99_ms']} ms)")


if __name__ == "__main__":
    main()
