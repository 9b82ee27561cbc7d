"""Issue 39 items 3 and 5, the C side: the secured-frame functions in C (fmu/c/secoc/, AES-CMAC
from libcrypto) agree with can_bus/secoc.py frame by frame: the same frames, the same
authenticators, the same verdicts and freshness values, on random frames and on every edge
(no frame yet, wrap of the 32 wire bits, the window's bound, one bit changed)."""
from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from can_bus import secoc
from fmu.secoc_c import SecocC, build


@pytest.fixture(scope="module")
def c(tmp_path_factory):
    return SecocC(build(tmp_path_factory.mktemp("secoc-c")))


KEY = bytes(range(16))
keys = st.binary(min_size=16, max_size=16)
ids = st.integers(0, 0x7FF)
payloads = st.binary(min_size=8, max_size=8)
values = st.one_of(st.integers(0, 2**40), st.integers(2**32 - 3, 2**32 + 3), st.integers(2**64 - 2**33, 2**64 - 2**32))
newest = st.one_of(st.none(), values)


@settings(max_examples=300, deadline=None)
@given(keys, ids, payloads, values)
def test_c_protects_as_python_does(c, key, frame_id, payload, fv):
    assert c.protect(key, frame_id, payload, fv) == secoc.protect(key, frame_id, payload, fv)


@settings(max_examples=300, deadline=None)
@given(keys, ids, payloads, values, newest, st.integers(0, 24))
def test_c_judges_as_python_does(c, key, frame_id, payload, fv, last, damage):
    frame = bytearray(secoc.protect(key, frame_id, payload, fv))
    if damage < 20:
        frame[damage] ^= 0x01 << (damage % 8)            # one bit changed somewhere
    elif damage == 20:
        frame = frame[:16]
    data = bytes(frame)
    assert c.check(key, frame_id, data, last) == secoc.check(key, frame_id, data, last)


@pytest.mark.parametrize("last, low", [(None, 0), (None, 65535), (None, 65536), (41, 42), (41, 41),
                                       (2**32 - 1, 0), (2**32 + 5, 5), (2**32 + 5, 6), (2**32 - 2, 2**32 - 1),
                                       (7, 7 + 65536), (7, 7 + 65537)])
def test_c_rebuilds_and_bounds_the_freshness_as_python_does(c, last, low):
    fv = secoc.rebuild(last, low)
    assert c.rebuild(last, low) == fv
    frame = secoc.protect(KEY, 0x20, bytes(8), fv)
    assert c.check(KEY, 0x20, frame, last) == secoc.check(KEY, 0x20, frame, last)


def test_the_three_refusals_and_a_wrong_key(c):
    frame = secoc.protect(KEY, 0x10, b"\x11" * 8, 5)
    assert c.check(KEY, 0x10, frame, 4) == ("ok", 5)
    assert c.check(KEY, 0x10, frame, 5)[0] == "stale_freshness"
    assert c.check(KEY, 0x10, frame[:19], 4)[0] == "wrong_length"
    assert c.check(bytes(16), 0x10, frame, 4)[0] == "bad_mac"
    assert c.check(KEY, 0x11, frame, 4)[0] == "bad_mac"                # another ID: the ID is authenticated
