"""How much of this machine's CPU its hypervisor took while a sandbox session ran.

The vcan tests run the monitor in a user-mode Linux on one CPU. When the virtual machine
under it loses its CPUs to other guests (CPU steal in /proc/stat), the whole sandbox runs in
fits and starts: cycles slip. The timing tests then run a second session and judge the quieter
of the two, quoting the steal in their messages (the player itself no longer bursts after a
stall: it moves the train through missed periods without sending them).
"""
from __future__ import annotations

from pathlib import Path

MAX_STEAL = 0.10   # more than 10 % of the CPU time taken by the hypervisor: try for a quieter session


def host_cpu() -> tuple[int, int]:
    """(steal, total) jiffies of the host from the first line of /proc/stat."""
    try:
        fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    except (OSError, ValueError):
        return 0, 0
    return (fields[7] if len(fields) > 7 else 0), sum(fields[:8])


def steal_between(before: tuple[int, int], after: tuple[int, int]) -> float:
    """Share of CPU time stolen between two host_cpu() readings."""
    return (after[0] - before[0]) / max(1, after[1] - before[1])
