"""Embarrassingly parallel evidence on dask.distributed: campaign runs, sweeps, Monte Carlo.

`map_ordered(fn, jobs, cluster)` runs `fn(job)` for every job and returns the results in job
order. `Cluster(workers=N)` starts a LocalCluster of N single-threaded worker processes on
this machine (N = 0: one per core); `Cluster(scheduler="tcp://host:8786")` uses a cluster
that is already running (its workers must have railguard installed). `workers=1` without a
scheduler runs in this process: no cluster to start for a single worker.

Jobs must be coarse (tens to hundreds of runs each, DESIGN.md section 13) and must carry
their own seeds: a run's randomness comes from its own key or index, never from which
worker ran it or when, so results (and the campaign's `runs_digest`) are identical for any
number of workers.
"""
from __future__ import annotations

import logging
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Callable, Iterator, Optional, Sequence

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Cluster:
    workers: int = 0                  # 0: one worker process per core
    scheduler: Optional[str] = None   # address of a running dask scheduler

    def size(self) -> int:
        return self.workers or max(1, os.cpu_count() or 1)

    def describe(self) -> str:
        if self.scheduler:
            return f"dask scheduler {self.scheduler}"
        n = self.size()
        return "this process" if n == 1 else f"a local dask cluster of {n} worker processes"


class ClusterError(RuntimeError):
    """The scheduler cannot be reached or the cluster cannot start (one line, for the CLI)."""


# Our tasks are CPU-bound Python: the workers' own threads (the statistical profiler every
# 10 ms, the event-loop tick every 20 ms, the system and memory monitors) take the GIL from
# them. Quieter, 2 workers on 2 cores went from 1.6x to 2.1x the runs/s of one
# (benchmarks/bench_campaign.py, 4,000 runs).
QUIET_WORKERS = {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1000ms",
                 "distributed.admin.system-monitor.interval": "5000ms",
                 "distributed.worker.memory.monitor-interval": "5000ms"}


@contextmanager
def _workers_ignore_ctrl_c() -> Iterator:
    """Worker processes started in here ignore SIGINT (the disposition survives their exec):
    Ctrl-C at the terminal reaches the whole process group, and only this process should
    act on it (cancel the work, one line, exit 130), not every worker with a traceback."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def client(cluster: Cluster) -> Iterator:
    """A dask.distributed Client for `cluster` (a LocalCluster started and stopped here)."""
    from distributed import Client, LocalCluster

    if cluster.scheduler:
        try:
            c = Client(cluster.scheduler, timeout="5s")
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"dask scheduler {cluster.scheduler}: cannot connect ({exc})") from None
        try:
            yield c
        finally:
            c.close()
        return
    import dask

    with dask.config.set(QUIET_WORKERS), _workers_ignore_ctrl_c():
        local = LocalCluster(n_workers=cluster.size(), threads_per_worker=1, processes=True, dashboard_address=":0",
                             silence_logs=logging.CRITICAL)
    c = Client(local)
    try:
        yield c
    finally:
        c.close()
        local.close()


def check(cluster: Cluster) -> None:
    """Fail fast, before any work, if the scheduler of `cluster` cannot be reached."""
    if cluster.scheduler:
        with client(cluster):
            pass


class Bar:
    """Progress of `total` units of work as lines for `progress` (about every 10 %), with a
    bar, the rate and the time left."""

    def __init__(self, progress: Optional[Progress], total: int, label: str, unit: str):
        self.progress, self.total, self.label, self.unit = progress, total, label, unit
        self.done = 0
        self.next_tenth = 1
        self.t0 = time.perf_counter()

    def add(self, n: int) -> None:
        self.done += n
        if self.progress is None or self.total <= 0:
            return
        tenth = self.done * 10 // self.total
        if tenth < self.next_tenth and self.done < self.total:
            return
        self.next_tenth = tenth + 1
        spent = time.perf_counter() - self.t0
        rate = self.done / spent if spent > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else 0.0
        bar = "#" * tenth + "." * (10 - tenth)
        self.progress(f"{self.label}: [{bar}] {self.done:,} of {self.total:,} {self.unit}, {spent:.0f} s, "
                      f"{rate:,.1f} {self.unit}/s" + (f", about {left:.0f} s left" if self.done < self.total else ""))


def map_ordered(fn: Callable, jobs: Sequence, cluster: Cluster = Cluster(), *, progress: Optional[Progress] = None,
                label: str = "work", unit: str = "runs", weight: Optional[Callable] = None,
                on_done: Optional[Callable[[int], None]] = None) -> list:
    """[fn(job) for job in jobs], computed on `cluster`, in job order. `weight(job)` is the
    number of `unit` a job stands for (default 1), for the progress line; `on_done(i)` is
    called as job i's result arrives."""
    on_done = on_done or (lambda i: None)
    jobs = list(jobs)
    weight = weight or (lambda job: 1)
    bar = Bar(progress, sum(weight(j) for j in jobs), label, unit)
    if not jobs:
        return []
    if not cluster.scheduler and cluster.size() == 1:
        out = []
        for i, job in enumerate(jobs):
            out.append(fn(job))
            on_done(i)
            bar.add(weight(job))
        return out
    from distributed import as_completed

    with client(cluster) as c:
        futures = c.map(fn, jobs, pure=False)
        where = {f.key: i for i, f in enumerate(futures)}
        out: list = [None] * len(jobs)
        try:
            for f in as_completed(futures):
                i = where[f.key]
                out[i] = f.result()
                on_done(i)
                bar.add(weight(jobs[i]))
        except KeyboardInterrupt:
            c.cancel(futures)
            raise
    return out
