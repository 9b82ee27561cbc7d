"""Cost of authenticating a frame (issue 39 item 5): sign (`secoc.protect`, with the
freshness counter) and verify (`secoc.check`) per frame in CPython, median and p99, and the
check of a frame with a bad authenticator (the work a flood of forged frames can cause) and
of a stale one (refused before any CMAC). The profile: CMAC-AES-128 from `cryptography`
over a 20-byte CAN FD frame (docs/can.md, "Authenticated frames").

Run: python benchmarks/bench_secoc.py [--frames N] [--json]
"""
from __future__ import annotations

import argparse
import json
import platform
import statistics
import time

from can_bus import codec, secoc
from monitor.core.types import PRESENT, Report


def timed(fn, n: int) -> list:
    out = []
    for i in range(n):
        t = time.perf_counter_ns()
        fn(i)
        out.append(time.perf_counter_ns() - t)
    return out


def figures(ns: list) -> dict:
    ns = sorted(ns)
    return {"median_us": round(statistics.median(ns) / 1000, 2), "p99_us": round(ns[int(0.99 * (len(ns) - 1))] / 1000, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    key, fid = bytes(range(16)), 0x20
    payload = codec.encode(fid, codec.report_signals(Report(PRESENT, 5000, 2000, 0, 0), 0), 0)
    counter = secoc.FreshnessCounter()
    frames = [secoc.protect(key, fid, payload, fv) for fv in range(a.frames)]
    forged = bytearray(frames[-1])
    forged[-1] ^= 1
    out = {
        "frames": a.frames, "python": platform.python_version(), "machine": platform.machine(),
        "sign": figures(timed(lambda i: secoc.protect(key, fid, payload, counter.take(fid)), a.frames)),
        "verify": figures(timed(lambda i: secoc.check(key, fid, frames[i], i - 1), a.frames)),
        "verify_bad_mac": figures(timed(lambda i: secoc.check(key, fid, bytes(forged), a.frames - 2), a.frames)),
        "verify_stale": figures(timed(lambda i: secoc.check(key, fid, frames[0], a.frames), a.frames)),
    }
    if a.json:
        print(json.dumps(out))
        return
    print(f"secured frames, CPython {out['python']} on {out['machine']}, {a.frames:,} frames each")
    for k in ("sign", "verify", "verify_bad_mac", "verify_stale"):
        print(f"  {k:<15} median {out[k]['median_us']:7.2f} us   p99 {out[k]['p99_us']:7.2f} us")


if __name__ == "__main__":
    main()
