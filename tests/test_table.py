"""The binary policy table format (monitor/core/table.py) and the shipped tables."""
from __future__ import annotations

import hashlib
import json
import struct

import numpy as np
import pytest

from conftest import TABLES
from monitor.core.table import FORMAT_VERSION, MAGIC, PPM, Table, TableError, decode, encode

PREFIX = struct.Struct("<8sHI")


def small_header(**changes) -> dict:
    h = {
        "model": "toy",
        "states": ["near", "far"],
        "actions": ["coast", "brake"],
        "observations": ["o-near", "o-far", "o-none"],
        "start": 1,
        "note": "caf\u00e9",
    }
    h.update(changes)
    return h


SMALL_ACTION = [0, 1, 1]
SMALL_NEXT = [[0, 1, 2], [2, 2, 0], [1, 0, 1]]
SMALL_RISK = [0, 123_456, PPM]
RISK_INFO = {"unit": "ppm", "horizon_s": 30.0}


@pytest.fixture
def small() -> bytes:
    return encode(small_header(), SMALL_ACTION, SMALL_NEXT, SMALL_RISK, RISK_INFO)


def rehash(body: bytes) -> bytes:
    """A file whose checksum is right for its (possibly malformed) content."""
    return body + hashlib.sha256(body).digest()


def craft(header, body: bytes, version: int = FORMAT_VERSION, magic: bytes = MAGIC) -> bytes:
    text = json.dumps(header).encode("utf-8")
    return rehash(PREFIX.pack(magic, version, len(text)) + text + body)


# ------------------------------------------------------------------ round trip


def test_round_trip(small):
    t = decode(small)
    assert isinstance(t, Table)
    assert t.model == "toy"
    assert t.action == tuple(SMALL_ACTION)
    assert t.next == tuple(tuple(r) for r in SMALL_NEXT)
    assert t.nodes == 3
    assert t.start == 1
    assert t.actions == ("coast", "brake")
    assert t.observations == ("o-near", "o-far", "o-none")
    assert t.header["note"] == "caf\u00e9"
    assert t.header["index_bytes"] == 1
    assert t.header["nodes"] == 3
    assert t.header["format_version"] == FORMAT_VERSION
    assert t.risk == tuple(SMALL_RISK) and t.risk_horizon_s == 30.0


def test_a_table_made_without_a_risk_column_claims_none():
    """encode without the solver's risk: every node at 10^6 ppm and the header says so, so a
    hand-made table never shows a risk nobody computed."""
    t = decode(encode(small_header(), SMALL_ACTION, SMALL_NEXT))
    assert t.risk == (PPM,) * 3 and t.risk_horizon_s is None
    assert "none computed" in t.header["risk"]["source"]
    with pytest.raises(TableError, match="risk column"):
        encode(small_header(), SMALL_ACTION, SMALL_NEXT, [0, 0, PPM + 1], RISK_INFO)
    with pytest.raises(TableError, match="risk column"):
        encode(small_header(), SMALL_ACTION, SMALL_NEXT, [0, 0], RISK_INFO)


def test_layout_is_as_documented(small):
    magic, version, hlen = PREFIX.unpack_from(small)
    assert magic == MAGIC == b"RGTABLE\n"
    assert version == FORMAT_VERSION
    header = json.loads(small[PREFIX.size:PREFIX.size + hlen])
    assert header["model"] == "toy"
    body = small[PREFIX.size + hlen:-32]
    assert list(body[:3]) == SMALL_ACTION
    assert list(body[3:12]) == [m for row in SMALL_NEXT for m in row]
    assert list(struct.unpack("<3I", body[12:])) == SMALL_RISK


def test_encoding_is_deterministic_and_ignores_header_key_order():
    h = small_header()
    a = encode(h, SMALL_ACTION, SMALL_NEXT)
    b = encode(dict(reversed(list(h.items()))), SMALL_ACTION, SMALL_NEXT)
    assert a == b


def test_sha256_property_is_hash_of_everything_but_the_digest(small):
    t = decode(small)
    assert t.sha256 == hashlib.sha256(small[:-32]).hexdigest()
    assert small[-32:] == hashlib.sha256(small[:-32]).digest()


def test_default_start_is_zero():
    h = small_header()
    del h["start"]
    assert decode(encode(h, SMALL_ACTION, SMALL_NEXT)).start == 0


def test_next_row_of_wrong_length_is_refused_when_encoding():
    with pytest.raises(TableError):
        encode(small_header(), SMALL_ACTION, [[0, 1], [2, 2, 0], [1, 0, 1]])


# ------------------------------------------------------------------ corruption


@pytest.mark.parametrize("mask", [0x01, 0x80, 0xFF])
def test_every_single_byte_flip_is_refused(small, mask):
    for i in range(len(small)):
        bad = bytearray(small)
        bad[i] ^= mask
        with pytest.raises(TableError):
            decode(bytes(bad))


@pytest.mark.parametrize("length", [0, 1, 8, 13, 14, 40, 45, 46, "header", "body", "-1", "-32", "-33"])
def test_truncation_is_refused(small, length):
    hlen = PREFIX.unpack_from(small)[2]
    cut = {"header": PREFIX.size + hlen // 2, "body": PREFIX.size + hlen + 2,
           "-1": len(small) - 1, "-32": len(small) - 32, "-33": len(small) - 33}.get(length, length)
    with pytest.raises(TableError):
        decode(small[:cut])


def test_extra_bytes_are_refused(small):
    with pytest.raises(TableError):
        decode(small + b"\x00")
    with pytest.raises(TableError):
        decode(b"\x00" + small)


def test_bad_magic(small):
    bad = b"RGTABLX\n" + small[8:]
    with pytest.raises(TableError, match="magic"):
        decode(bad)
    with pytest.raises(TableError, match="magic"):
        decode(rehash(bad[:-32]))


@pytest.mark.parametrize("version", [0, 3, 0xFFFF])
def test_wrong_version(small, version):
    body = bytearray(small[:-32])
    struct.pack_into("<H", body, 8, version)
    with pytest.raises(TableError, match=f"version {version}"):
        decode(rehash(bytes(body)))  # refused for the version, not just the checksum


def test_a_format_1_file_is_refused_with_the_way_to_rebuild_it(small):
    body = bytearray(small[:-32])
    struct.pack_into("<H", body, 8, 1)
    with pytest.raises(TableError, match="version 1 has no risk column: rebuild it with `railguard table upgrade FILE`"):
        decode(rehash(bytes(body)))


def test_expect_model_mismatch_names_both_models(small):
    assert decode(small, expect_model="toy").model == "toy"
    with pytest.raises(TableError) as info:
        decode(small, expect_model="m2")
    assert "toy" in str(info.value) and "m2" in str(info.value)


# well-formed checksums over malformed content: the checks behind the checksum must hold too
BASE = dict(model="x", states=["a"], actions=["p", "q"], observations=["o1", "o2"], nodes=2, start=0, index_bytes=1,
            risk=RISK_INFO)
RISK_BYTES = struct.pack("<2I", 5, PPM)
GOOD_BODY = bytes([0, 1, 0, 1, 1, 0]) + RISK_BYTES


@pytest.mark.parametrize(
    "header, body, what",
    [
        (BASE, GOOD_BODY[:-1], "body"),
        (BASE, GOOD_BODY + b"\x00", "body"),
        (BASE, bytes([0, 2, 0, 1, 1, 0]) + RISK_BYTES, "action"),
        (BASE, bytes([0, 1, 0, 2, 1, 0]) + RISK_BYTES, "next"),
        (BASE, bytes([0, 1, 0, 1, 1, 0]) + struct.pack("<2I", 5, PPM + 1), "risk is above"),
        ({k: v for k, v in BASE.items() if k != "risk"}, GOOD_BODY, "risk column"),
        (dict(BASE, risk={"unit": "percent"}), GOOD_BODY, "risk column"),
        (dict(BASE, start=2), GOOD_BODY, "start"),
        (dict(BASE, start=-1), GOOD_BODY, "start"),
        (dict(BASE, start="0"), GOOD_BODY, "start"),
        (dict(BASE, nodes=0), b"", "dimensions"),
        (dict(BASE, nodes="2"), GOOD_BODY, "dimensions"),
        (dict(BASE, index_bytes=3), GOOD_BODY, "dimensions"),
        ({k: v for k, v in BASE.items() if k != "model"}, GOOD_BODY, "model"),
        ({k: v for k, v in BASE.items() if k != "observations"}, GOOD_BODY, "observations"),
        ([1, 2, 3], GOOD_BODY, "object"),
    ],
)
def test_consistent_checksum_but_inconsistent_content_is_refused(header, body, what):
    with pytest.raises(TableError, match=what):
        decode(craft(header, body))


def test_header_that_is_not_json_is_refused():
    text = b"\xff{not json"
    with pytest.raises(TableError, match="JSON"):
        decode(rehash(PREFIX.pack(MAGIC, FORMAT_VERSION, len(text)) + text + GOOD_BODY))


def test_header_length_beyond_the_file_is_refused():
    with pytest.raises(TableError):
        decode(rehash(PREFIX.pack(MAGIC, FORMAT_VERSION, 10**6) + b'{"model": "x"}'))


@pytest.mark.parametrize("field", ["observations", "actions"])
def test_names_that_are_not_lists_are_refused_as_table_errors(field):
    """A header whose name list is a number must be a TableError (the CLI shows those as one
    line), not a TypeError escaping from len()."""
    with pytest.raises(TableError):
        decode(craft(dict(BASE, **{field: 2}), GOOD_BODY))


# ------------------------------------------------------------------ index width


def chain(n: int, z: int = 3) -> tuple[list[int], list[list[int]]]:
    action = [i % 2 for i in range(n)]
    nxt = [[(i + k) % n for k in range(z)] for i in range(n)]
    nxt[0][0] = n - 1  # the largest index appears
    return action, nxt


def test_256_nodes_fit_one_byte_indices():
    action, nxt = chain(256)
    data = encode(small_header(start=255), action, nxt)
    t = decode(data)
    assert t.header["index_bytes"] == 1
    assert t.action == tuple(action) and t.next == tuple(tuple(r) for r in nxt)
    assert t.start == 255


@pytest.mark.parametrize("n", [257, 300, 1000])
def test_more_than_256_nodes_use_two_byte_indices(n):
    action, nxt = chain(n)
    data = encode(small_header(start=n - 1), action, nxt)
    t = decode(data)
    assert t.header["index_bytes"] == 2
    assert t.nodes == n
    assert t.action == tuple(action)
    assert t.next == tuple(tuple(r) for r in nxt)
    assert t.start == n - 1
    hlen = PREFIX.unpack_from(data)[2]
    assert len(data) == PREFIX.size + hlen + n + n * 3 * 2 + 4 * n + 32


def test_two_byte_table_byte_flips_are_refused():
    action, nxt = chain(300)
    data = encode(small_header(), action, nxt)
    rng = np.random.default_rng(0)
    for i in sorted(set(rng.integers(0, len(data), 200).tolist()) | {0, 8, 10, len(data) - 1}):
        bad = bytearray(data)
        bad[i] ^= 0x10
        with pytest.raises(TableError):
            decode(bytes(bad))


# ------------------------------------------------------------------ shipped tables

SHIPPED = {"m1": (4, 4), "m2": (144, 144)}  # name: (states, observations)


def shipped_bytes(name: str) -> bytes:
    path = TABLES / f"{name}.table.rgt"
    assert path.is_file(), f"{path} is missing (run `railguard solve --model {name} --out monitor/tables`)"
    return path.read_bytes()


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_table_decodes_with_the_right_dimensions(name):
    data = shipped_bytes(name)
    t = decode(data, expect_model=name)
    states, observations = SHIPPED[name]
    assert t.model == name
    assert len(t.header["states"]) == states
    assert len(t.observations) == observations
    assert t.actions == ("maintain", "nominal_braking", "emergency_braking")
    assert 1 <= t.nodes <= 65535
    assert t.header["index_bytes"] == (1 if t.nodes <= 256 else 2)
    assert all(len(row) == observations for row in t.next)
    assert all(0 <= m < t.nodes for row in t.next for m in row)
    assert all(0 <= a < 3 for a in t.action)
    assert 0 <= t.start < t.nodes
    assert t.sha256 == hashlib.sha256(data[:-32]).hexdigest()
    assert t.header["lower_bound"] <= t.header["upper_bound"]
    assert t.header["controller_value"] <= t.header["upper_bound"] + 1e-9


def test_shipped_m2_table_fits_in_64_kib():
    assert len(shipped_bytes("m2")) <= 64 * 1024


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_table_is_for_the_current_model(name):
    """The table's model digest must be that of the model `models.load(name)` builds now;
    otherwise the shipped controller solves a different model than the one documented."""
    from monitor.offline.models import load
    from monitor.offline.pipeline import model_digest

    t = decode(shipped_bytes(name))
    model, _ = load(name)
    assert t.header["states"] == list(model.states)
    assert t.header["observations"] == list(model.observations)
    assert t.header["model_sha256"] == model_digest(model)


def test_shipped_m1_byte_flips_are_refused():
    data = shipped_bytes("m1")
    for i in range(len(data)):
        bad = bytearray(data)
        bad[i] ^= 0x04
        with pytest.raises(TableError):
            decode(bytes(bad))


def test_shipped_m2_byte_flips_are_refused():
    data = shipped_bytes("m2")
    hlen = PREFIX.unpack_from(data)[2]
    rng = np.random.default_rng(1)
    positions = set(rng.integers(0, len(data), 200).tolist())
    positions |= {0, 7, 8, 9, 10, 13, PREFIX.size, PREFIX.size + hlen - 1, PREFIX.size + hlen,
                  len(data) - 33, len(data) - 32, len(data) - 1}
    for i in sorted(positions):
        bad = bytearray(data)
        bad[i] ^= 0x01
        with pytest.raises(TableError):
            decode(bytes(bad))
