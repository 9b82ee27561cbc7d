"""The monitor's table files as the campaign hands them over: the shipped ones (and their
setups, one per process), and the corrupted or mismatched ones a table fault stands for,
which `cycle.create` must refuse.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Optional

from monitor.core import cycle
from monitor.core import table as table_mod
from monitor.core.config import Config

from .specs import Fault


@lru_cache(maxsize=None)
def shipped_table(model: str) -> bytes:
    from monitor.tables import read

    return read(model)


def faulty_table(fault: Fault, model: str, cfg: Config) -> tuple[bytes, Optional[str], Config]:
    """(table bytes, expect_model, config) for a table fault; cycle.create must refuse them."""
    good = shipped_table(model)
    other = "m2" if model == "m1" else "m1"
    how = fault.variant[0]
    if fault.kind == "table_corrupted":
        pos = int(fault.variant[1] * (len(good) - 1))
        if how == "flip":                                # a byte of the content: SHA-256 mismatch
            pos = min(pos, len(good) - 33)
            data = bytearray(good)
            data[pos] ^= 0x01 << (pos % 8)
            return bytes(data), None, cfg
        if how == "digest":
            data = bytearray(good)
            data[len(good) - 1 - pos % 32] ^= 0x80
            return bytes(data), None, cfg
        if how == "truncate":
            return good[: max(0, pos)], None, cfg
        data = bytearray(good)
        data[0:8] = b"RGTABLX\n"
        return bytes(data), None, cfg
    if how == "expect_model":
        return shipped_table(other), model, cfg
    if how == "period":
        return good, None, cfg._replace(period_ms=2 * cfg.period_ms)
    t = table_mod.decode(good)
    header = dict(t.header)
    if how == "relabel":                                 # valid hash, claims the other model
        header["model"] = other
    else:                                                # valid hash, observations reordered
        header["observations"] = list(reversed(header["observations"]))
    return table_mod.encode(header, t.action, t.next), None, cfg


@lru_cache(maxsize=8)
def shipped_setup(model: str, cfg: Config) -> cycle.Setup:
    """cycle.create of a shipped table (pure, so one per process is enough)."""
    return cycle.create(cfg, shipped_table(model))
