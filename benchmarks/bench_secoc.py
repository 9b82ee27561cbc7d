"""Cost of authenticating a frame (issue 39 item 5): sign (`secoc.protect`, with the
freshness counter) and verify (`secoc.check`) per frame in CPython, median and p99, and the
check of a frame with a bad authenticator (the work a flood of forged frames can cause) and
of a stale one (refused before any CMAC). The profile: CMAC-AES-128 from `cryptography`
over a 20-byte CAN FD frame (docs/can.md, "Authenticated frames").

The same in C (`--c`): rg_secoc.c with libcrypto's AES-CMAC, timed by a small C program
built here (clock_gettime around each call; no Python in the loop), median and p99.

Run: python benchmarks/bench_secoc.py [--frames N] [--c] [--json]
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


C_TIMER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "rg_secoc.h"
static long long ns(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec * 1000000000LL + t.tv_nsec; }
static int cmp(const void *a, const void *b) { long long x = *(const long long *)a, y = *(const long long *)b; return (x > y) - (x < y); }
static void report(const char *name, long long *d, int n) {
    qsort(d, (size_t)n, sizeof *d, cmp);
    printf("%s %.3f %.3f\n", name, d[n / 2] / 1000.0, d[(int)(0.99 * (n - 1))] / 1000.0);
}
int main(int argc, char **argv) {
    int n = argc > 1 ? atoi(argv[1]) : 20000, i;
    uint8_t key[16], payload[8] = {1, 2, 3, 4, 5, 6, 7, 8}, frame[RG_SECOC_FRAME], bad[RG_SECOC_FRAME];
    uint64_t fv;
    long long *d = malloc(sizeof(long long) * (size_t)n), t;
    for (i = 0; i < 16; i++) key[i] = (uint8_t)i;
    for (i = 0; i < n; i++) { t = ns(); rg_secoc_protect(key, 0x20, payload, (uint64_t)i, frame); d[i] = ns() - t; }
    report("sign", d, n);
    for (i = 0; i < n; i++) { rg_secoc_protect(key, 0x20, payload, (uint64_t)i, frame);
        t = ns(); if (rg_secoc_check(key, 0x20, frame, RG_SECOC_FRAME, i > 0, (uint64_t)i - 1, &fv) != RG_SECOC_OK) return 1; d[i] = ns() - t; }
    report("verify", d, n);
    memcpy(bad, frame, sizeof bad); bad[RG_SECOC_FRAME - 1] ^= 1;
    for (i = 0; i < n; i++) { t = ns(); if (rg_secoc_check(key, 0x20, bad, RG_SECOC_FRAME, 1, (uint64_t)n - 2, &fv) != RG_SECOC_BAD_MAC) return 1; d[i] = ns() - t; }
    report("verify_bad_mac", d, n);
    for (i = 0; i < n; i++) { t = ns(); if (rg_secoc_check(key, 0x20, frame, RG_SECOC_FRAME, 1, (uint64_t)n, &fv) != RG_SECOC_STALE) return 1; d[i] = ns() - t; }
    report("verify_stale", d, n);
    free(d);
    return 0;
}
"""


def c_figures(frames: int) -> dict:
    """The C functions timed by a C program (built with the project's flags and -lcrypto)."""
    import subprocess
    import tempfile
    from pathlib import Path

    from fmu.build import CFLAGS, compiler
    from fmu.secoc_c import SECOC_DIR

    with tempfile.TemporaryDirectory() as tmp:
        src, exe = Path(tmp) / "timer.c", Path(tmp) / "timer"
        src.write_text(C_TIMER)
        flags = [f for f in CFLAGS if f not in ("-fPIC", "-pedantic")]
        subprocess.run([compiler(), *flags, "-D_POSIX_C_SOURCE=199309L", f"-I{SECOC_DIR}", str(src),
                        str(SECOC_DIR / "rg_secoc.c"), "-o", str(exe), "-lcrypto"], check=True)
        lines = subprocess.run([str(exe), str(frames)], check=True, capture_output=True, text=True).stdout.split("\n")
    return {name: {"median_us": float(med), "p99_us": float(p99)}
            for name, med, p99 in (ln.split() for ln in lines if ln.strip())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--c", action="store_true", help="also the C functions (fmu/c/secoc, libcrypto)")
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
    if a.c:
        out["c"] = c_figures(a.frames)
    if a.json:
        print(json.dumps(out))
        return
    print(f"secured frames, CPython {out['python']} on {out['machine']}, {a.frames:,} frames each")
    for k in ("sign", "verify", "verify_bad_mac", "verify_stale"):
        print(f"  {k:<15} median {out[k]['median_us']:7.2f} us   p99 {out[k]['p99_us']:7.2f} us")
    if a.c:
        print("the same in C (rg_secoc.c, libcrypto AES-CMAC)")
        for k in ("sign", "verify", "verify_bad_mac", "verify_stale"):
            print(f"  {k:<15} median {out['c'][k]['median_us']:7.2f} us   p99 {out['c'][k]['p99_us']:7.2f} us")


if __name__ == "__main__":
    main()
