"""The compiled policy table: a finite-state controller in a versioned, hashed file.

Layout (little-endian):
    magic   8 bytes  b"RGTABLE\\n"
    version u16      FORMAT_VERSION
    hlen    u32      length of the header
    header  hlen     UTF-8 JSON: model, parameters, names, dimensions, values, bounds
    action  N bytes  action[node]
    next    N*Z*w    next[node][obs], w = header["index_bytes"] (1 or 2)
    risk    N*4      u32 risk[node]: P(hazard within header["risk"]["horizon_s"] | node), in
                     parts per million (monitor/offline/node_risk.py; format version 2 on)
    sha256  32 bytes over everything before it

The online core and the C generator both read it through `decode`; a file that fails any
check is refused with a TableError that says what is wrong. Pure: bytes in, values out.
"""
from __future__ import annotations

import hashlib
import json
import struct
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

MAGIC = b"RGTABLE\n"
FORMAT_VERSION = 2
PPM = 1_000_000
NO_RISK = {"unit": "ppm", "source": "none computed: every node at 10^6 ppm, the safe side"}
UPGRADE_HINT = "rebuild it with `railguard table upgrade FILE` (or solve it again with `railguard solve`)"
_PREFIX = struct.Struct("<8sHI")
_DIGEST = 32
REQUIRED = ("model", "states", "actions", "observations", "nodes", "start", "index_bytes")


class TableError(ValueError):
    """A table file that must not be run; the message names the problem."""


@dataclass(frozen=True)
class Table:
    """A decoded, checked controller: node -> action, (node, observation) -> node."""

    header: Mapping[str, Any]
    action: tuple[int, ...]
    next: tuple[tuple[int, ...], ...]
    sha256: str
    risk: tuple[int, ...] = ()

    @property
    def risk_horizon_s(self) -> float | None:
        """The horizon the risk column is about (None: no risk was computed)."""
        h = self.header.get("risk", {}).get("horizon_s")
        return None if h is None else float(h)

    @property
    def model(self) -> str:
        return str(self.header["model"])

    @property
    def nodes(self) -> int:
        return len(self.action)

    @property
    def observations(self) -> tuple[str, ...]:
        return tuple(self.header["observations"])

    @property
    def actions(self) -> tuple[str, ...]:
        return tuple(self.header["actions"])

    @property
    def start(self) -> int:
        return int(self.header["start"])


def encode(header: Mapping[str, Any], action: Sequence[int], nxt: Sequence[Sequence[int]],
           risk: Sequence[int] | None = None, risk_info: Mapping[str, Any] | None = None) -> bytes:
    """Serialise a controller; the caller's header must name model, states, actions, observations.

    `risk` (ppm per node) with `risk_info` (what it means: node_risk.describe) is the solver's
    risk column; without it every node says 10^6 ppm and the header says none was computed,
    so a hand-made table never claims a risk nobody computed."""
    n = len(action)
    z = len(header["observations"])
    width = 1 if n <= 256 else 2
    head = dict(header)
    if risk is None:
        risk, risk_info = [PPM] * n, NO_RISK
    if risk_info is None or len(risk) != n or not all(0 <= int(r) <= PPM for r in risk):
        raise TableError(f"risk column must give {n} values in [0, {PPM}] ppm with what they mean")
    head.update(nodes=n, index_bytes=width, format_version=FORMAT_VERSION, risk=dict(risk_info))
    head.setdefault("start", 0)
    text = json.dumps(head, sort_keys=True, separators=(",", ":"), allow_nan=False).encode("utf-8")
    body = bytearray(_PREFIX.pack(MAGIC, FORMAT_VERSION, len(text)))
    body += text
    body += bytes(int(a) for a in action)
    fmt = "B" if width == 1 else "H"
    for row in nxt:
        if len(row) != z:
            raise TableError(f"next row has {len(row)} entries, expected {z} observations")
        body += struct.pack(f"<{z}{fmt}", *(int(m) for m in row))
    body += struct.pack(f"<{n}I", *(int(r) for r in risk))
    body += hashlib.sha256(body).digest()
    return bytes(body)


def _no_constant(name: str):
    raise ValueError(f"{name} is not allowed in a table header")


def decode(data: bytes, expect_model: str | None = None) -> Table:
    """Check and decode a table file's bytes; refuse anything inconsistent."""
    return _decode(data, expect_model, upgrading=False)


def decode_for_upgrade(data: bytes) -> Table:
    """A format-1 table (no risk column) decoded with the same checks, for `railguard table
    upgrade` to add the column; never for running (its risk is empty)."""
    return _decode(data, None, upgrading=True)


def _decode(data: bytes, expect_model: str | None, upgrading: bool) -> Table:
    if len(data) < _PREFIX.size + _DIGEST:
        raise TableError(f"too short to be a table ({len(data)} bytes)")
    magic, version, hlen = _PREFIX.unpack_from(data)
    if magic != MAGIC:
        raise TableError("not a railguard table (bad magic bytes)")
    legacy = version == 1 and upgrading
    if version == 1 and not legacy:
        raise TableError(f"table format version 1 has no risk column: {UPGRADE_HINT}")
    if version != FORMAT_VERSION and not legacy:
        raise TableError(f"table format version {version} is not supported (this build reads {FORMAT_VERSION})")
    digest = hashlib.sha256(data[:-_DIGEST]).digest()
    if digest != data[-_DIGEST:]:
        raise TableError("corrupted: SHA-256 over the content does not match the one stored in the file")
    start = _PREFIX.size
    try:
        header = json.loads(data[start:start + hlen].decode("utf-8"), parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError) as exc:
        raise TableError(f"header is not valid JSON: {exc}") from None
    if not isinstance(header, dict):
        raise TableError("header is not a JSON object")
    missing = [k for k in REQUIRED if k not in header]
    if missing:
        raise TableError(f"header lacks {', '.join(missing)}")
    for key in ("states", "actions", "observations"):
        names = header[key]
        if not isinstance(names, list) or not names or not all(isinstance(x, str) for x in names):
            raise TableError(f"header {key!r} must be a non-empty list of names")
    n, z, width = header["nodes"], len(header["observations"]), header["index_bytes"]
    n_actions = len(header["actions"])
    if not (isinstance(n, int) and n > 0) or width not in (1, 2):
        raise TableError(f"bad dimensions: nodes={n!r}, index_bytes={width!r}")
    body = data[start + hlen:-_DIGEST]
    risk_bytes = 0 if legacy else 4 * n
    if len(body) != n + n * z * width + risk_bytes:
        raise TableError(f"body is {len(body)} bytes, expected {n + n * z * width + risk_bytes} for {n} nodes x {z} observations")
    if not legacy and (not isinstance(header.get("risk"), dict) or header["risk"].get("unit") != "ppm"):
        raise TableError(f"header lacks the risk column's description: {UPGRADE_HINT}")
    action = tuple(body[:n])
    if any(a >= n_actions for a in action):
        raise TableError(f"an action index is >= the {n_actions} actions")
    fmt = "B" if width == 1 else "H"
    flat = struct.unpack_from(f"<{n * z}{fmt}", body, n)
    if any(m >= n for m in flat):
        raise TableError(f"a next-node index is >= the {n} nodes")
    nxt = tuple(flat[i * z:(i + 1) * z] for i in range(n))
    risk = () if legacy else struct.unpack_from(f"<{n}I", body, n + n * z * width)
    if any(r > PPM for r in risk):
        raise TableError(f"a node's risk is above {PPM} ppm")
    if not (isinstance(header["start"], int) and 0 <= header["start"] < n):
        raise TableError(f"start node {header['start']!r} out of range")
    if expect_model is not None and header["model"] != expect_model:
        raise TableError(f"table is for model {header['model']!r}, expected {expect_model!r}")
    return Table(header=header, action=action, next=nxt, sha256=digest.hex(), risk=risk)
