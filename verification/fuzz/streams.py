"""Driving the fuzzing: one stream per Hypothesis example, many per worker job, jobs over processes.

`run_stream` is one stream on a fresh runner (and how a recorded failure is replayed: the
same table, topology, profile and tape give the same frames); `fuzz_chunk` draws Hypothesis
examples until a job's frames are done; `run` spreads the jobs and adds up their figures.
"""
from __future__ import annotations

import math
import os
import time
import traceback
from typing import Optional

from ..report import Progress
from .harness import Harness, StreamStop, setup_for
from .reference import ACCEPTED, FILTERED
from .stats import Stats
from .traffic import PROFILE_NAMES, TAPE_BYTES, Tape, Traffic


STREAM_FRAMES = 2500         # one stream: at most this many frames (many varied streams rather than a few long ones)
CHUNK_FRAMES = 50_000        # frames per worker job
MAX_FAULTS = 50              # a worker job stops after this many faults (the verdict is FAIL anyway)
SECURED_EVERY = 3            # every third stream runs on the secured bus (issue 39), the others unsecured


def run_stream(table: str, topology: str, profile: str, tape: bytes, stats: Stats,
               budget: Optional[int] = None, label: Optional[dict] = None, secured: bool = False) -> Harness:
    """One stream: a fresh runner fed by the traffic program in `tape` (also how a failure is
    replayed: the same five values give the same frames); `secured`: on the secured bus."""
    bus = "secured" if secured else "unsecured"
    h = Harness(setup_for(table, topology), stats, budget,
                dict(label or {}, table=table, topology=topology, profile=profile, bus=bus), secured=secured)
    stats.streams += 1
    stats.stream_kinds[f"{table}/{topology}/{profile}/{bus}"] += 1
    kept = len(stats.examples)
    try:
        Traffic(h, Tape(tape), profile).run()
    except StreamStop:
        pass
    except Exception as exc:  # noqa: BLE001 - a fault of this harness, not of the product
        stats.harness_errors += 1
        stats.record("harness", dict(h.label, what=f"{type(exc).__name__}: {exc}",
                                     traceback=traceback.format_exc(limit=-4)))
        h.failed = True
    if len(stats.examples) > kept:
        stats.examples[kept]["tape"] = tape.hex()   # with table, topology and profile: the stream again
    h.finish()
    return h


# ----------------------------------------------------------------------------- Hypothesis
def stream_strategy():
    from hypothesis import strategies as st

    return st.tuples(st.sampled_from(("m1", "m2")), st.sampled_from(("3oo3", "3oo3", "3oo3", "2oo2")),
                     st.sampled_from(PROFILE_NAMES), st.binary(min_size=TAPE_BYTES, max_size=TAPE_BYTES))


def _hypothesis_batch(stats: Stats, target: int, seed: int, examples: int) -> None:
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as fixed_seed

    counter = [0]

    @fixed_seed(seed)
    @settings(max_examples=examples, database=None, deadline=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck), report_multiple_bugs=False)
    @given(stream_strategy())
    def one_stream(params):
        counter[0] += 1
        if stats.frames >= target or stats.faults() >= MAX_FAULTS:
            return
        table, topology, profile, tape = params
        run_stream(table, topology, profile, tape, stats, budget=min(STREAM_FRAMES, target - stats.frames),
                   label={"hypothesis_seed": seed, "example": counter[0]}, secured=counter[0] % SECURED_EVERY == 0)

    one_stream()


def fuzz_chunk(job: tuple) -> dict:
    """Hypothesis streams until `frames` frames went through the receive path (one worker job)."""
    seed, frames = job
    stats = Stats()
    t0 = time.perf_counter()
    batch = 0
    while stats.frames < frames and stats.faults() < MAX_FAULTS and batch < 10_000:
        left = frames - stats.frames
        _hypothesis_batch(stats, frames, seed * 1_000_003 + batch, max(2, min(60, left // 1000 + 2)))
        batch += 1
    stats.seconds = time.perf_counter() - t0
    return stats.as_dict()


def run(frames: int, progress: Progress, seed: int = 0, workers: Optional[int] = None) -> dict:
    """Fuzz the receive path with at least `frames` frames; the figures as a dict:
    frames, accepted, rejected (by reason), exceptions, violations, seconds, frames_per_s, ..."""
    t0 = time.perf_counter()
    if workers is None:
        workers = 1 if frames <= CHUNK_FRAMES else max(1, min(2, os.cpu_count() or 1))
    n_jobs = max(1, math.ceil(frames / CHUNK_FRAMES))
    jobs = [(seed * 1000 + i, frames // n_jobs + (1 if i < frames % n_jobs else 0)) for i in range(n_jobs)]
    total = Stats()
    if workers <= 1 or n_jobs == 1:
        for job in jobs:
            total.merge(fuzz_chunk(job))
            progress(f"fuzz: {total.frames:,} of {frames:,} frames")
    else:
        import multiprocessing as mp

        methods = mp.get_all_start_methods()
        ctx = mp.get_context("fork" if "fork" in methods else "spawn")
        with ctx.Pool(workers) as pool:
            for d in pool.imap_unordered(fuzz_chunk, jobs):
                total.merge(d)
                progress(f"fuzz: {total.frames:,} of {frames:,} frames")
    seconds = time.perf_counter() - t0
    result = total.as_dict()
    rejected_total = sum(result["rejected"].values())
    expected = dict(result["expected"])
    result.update(
        target=frames, seed=seed, workers=workers, seconds=seconds,
        frames_per_s=result["frames"] / seconds if seconds > 0 else 0.0,
        rejected_total=rejected_total,
        accounting_exact=(result["accounting_errors"] == 0
                          and result["frames"] == result["accepted"] + rejected_total + result["filtered"]
                          == sum(result["frame_kinds"].values())),
        reference_agrees=(expected.pop(ACCEPTED, 0) == result["accepted"]
                          and expected.pop(FILTERED, 0) == result["filtered"]
                          and {k: v for k, v in expected.items() if v}
                          == {k: v for k, v in result["rejected"].items() if v}),
    )
    return result
