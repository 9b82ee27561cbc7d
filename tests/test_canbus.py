"""Issue 42, the bus model in C (fmu/c/lsbus/): exact frame lengths against a Python reference
written here from ISO 11898-1 (nothing imported from the C), arbitration, a flood at 0x000
starving BrakeDemand 0x010 (and one at 0x7FF not), injected error frames, dropped submissions,
bus load, determinism. The library is compiled for the module: a missing compiler fails."""
from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fmu.canbus_c import EFF, INT64_MAX, CanBusLib, Frame, build

BIT = 2000                      # ns per bit at 500 kbit/s
DBIT = 500                      # ns per bit at 2 Mbit/s
FD_LENS = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64]


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    return CanBusLib(build(tmp_path_factory.mktemp("canbus-c")))


# ---- the reference: bit lists, from the standard's field tables ----

def bits(value: int, n: int) -> list[int]:
    return [(value >> (n - 1 - i)) & 1 for i in range(n)]


def crc(message: list[int], width: int, poly: int, init: int) -> list[int]:
    """The shift register of ISO 11898-1 written as polynomial division: with the register
    starting at `init`, the CRC of n bits M is (M(x) x^w + init x^n) mod G(x)."""
    n = len(message)
    value = 0
    for b in message:
        value = (value << 1) | b
    dividend = (value << width) ^ (init << n)
    g = (1 << width) | poly
    for shift in range(dividend.bit_length() - 1 - width, -1, -1):
        if dividend >> (shift + width) & 1:
            dividend ^= g << shift
    return bits(dividend, width)


def stuff(raw: list[int], after_last: bool) -> tuple[list[int], list[int], int]:
    """A complement after every 5 equal bits (stuff bits count in runs). Returns the stream, the
    position of each raw bit in it, and the number of stuff bits. after_last: whether a stuff bit
    may follow the last raw bit (classic CRC: yes; FD data field: no, a fixed stuff bit follows)."""
    out, where, count, run = [], [], 0, 0
    for i, b in enumerate(raw):
        run = run + 1 if out and out[-1] == b else 1
        where.append(len(out))
        out.append(b)
        if run == 5 and (after_last or i < len(raw) - 1):
            out.append(1 - b)
            count += 1
            run = 1
    return out, where, count


def header(f: Frame) -> tuple[list[int], int]:
    """SOF to the end of DATA, unstuffed; and the index of BRS (-1 for classic)."""
    n = len(f.data)
    dlc = FD_LENS.index(n) if f.fd else n
    if f.ide:
        arb = [0] + bits(f.id >> 18, 11) + [1, 1] + bits(f.id & 0x3FFFF, 18)   # SOF base SRR IDE ext
    else:
        arb = [0] + bits(f.id, 11)
    if not f.fd:
        ctrl = [0, 0, 0]                                       # RTR IDE r0 / RTR r1 r0
        brs_at = -1
    else:
        ctrl = [0, 1, 0] if f.ide else [0, 0, 1, 0]            # RRS (IDE) FDF res
        brs_at = len(arb) + len(ctrl)
        ctrl += [int(f.brs), 0]                                # BRS ESI
    head = arb + ctrl + bits(dlc, 4)
    for byte in f.data:
        head += bits(byte, 8)
    return head, brs_at


def ref_wire(f: Frame) -> tuple[list[int], int]:
    """The bits from SOF to the end of EOF (ACK slot acknowledged), and how many of them go at
    the data bit rate."""
    raw, brs_at = header(f)
    tail = [1, 0, 1] + [1] * 7                                 # CRC delimiter, ACK, ACK delimiter, EOF
    if not f.fd:
        stream, _, _ = stuff(raw + crc(raw, 15, 0x4599, 0), after_last=True)
        return stream + tail, 0
    stream, where, count = stuff(raw, after_last=False)
    sc = count % 8
    gray = sc ^ (sc >> 1)
    parity = bin(gray).count("1") % 2
    width, poly = (17, 0x1685B) if len(f.data) <= 16 else (21, 0x102899)
    seq = bits(gray, 3) + [parity]
    seq += crc(stream + seq, width, poly, 1 << (width - 1))
    field = []
    for i, b in enumerate(seq):
        if i % 4 == 0:
            field.append(1 - (field[-1] if field else stream[-1]))   # fixed stuff bit
        field.append(b)
    total = stream + field
    return total + tail, (len(total) - where[brs_at] - 1 if f.brs else 0)


def ref_bits(f: Frame) -> tuple[int, int]:
    """(nominal, data-rate) bits from SOF to the end of EOF."""
    wire, data = ref_wire(f)
    return len(wire) - data, data


def test_reference_crcs_give_the_catalogue_check_values():
    msg = [b for byte in b"123456789" for b in bits(byte, 8)]
    assert crc(msg, 15, 0x4599, 0) == bits(0x059E, 15)       # CRC-15/CAN
    assert crc(msg, 17, 0x1685B, 0) == bits(0x04F03, 17)     # CRC-17/CAN-FD
    assert crc(msg, 21, 0x102899, 0) == bits(0x0ED841, 21)   # CRC-21/CAN-FD


def test_reference_stuffing_by_hand():
    assert stuff([0] * 5, True)[0] == [0, 0, 0, 0, 0, 1]
    assert stuff([0] * 5, False)[0] == [0] * 5
    assert stuff([0] * 9, True)[0] == [0, 0, 0, 0, 0, 1, 0, 0, 0, 0]   # the stuff bit starts a run
    assert stuff([0, 0, 0, 0, 0, 1, 1, 1, 1], True)[2] == 2


# ---- frame lengths ----

byte_values = st.one_of(st.integers(0, 255), st.sampled_from([0x00, 0xFF, 0x55, 0xAA, 0x0F, 0xF0, 0x80, 0x01]))


@st.composite
def frames(draw):
    fd = draw(st.booleans())
    ide = draw(st.booleans())
    fid = draw(st.one_of(st.integers(0, 0x1FFFFFFF if ide else 0x7FF), st.sampled_from([0, 0x10, 0x7FF])))
    n = draw(st.sampled_from(FD_LENS if fd else list(range(9))))
    data = bytes(draw(st.lists(byte_values, min_size=n, max_size=n)))
    return Frame(fid, data, ide=ide, fd=fd, brs=fd and draw(st.booleans()))


@settings(max_examples=500, deadline=None)
@given(frames())
def test_frame_bits_equal_the_reference(lib, f):
    assert lib.frame_bits(f) == ref_bits(f)
    wire = lib.frame_wire(f)
    assert wire == ref_wire(f)[0] and len(wire) <= 768           # the CRC values too (FD: fixed length)


@pytest.mark.parametrize("fd", [False, True])
def test_every_length_and_pattern(lib, fd):
    rng = random.Random(42)
    for n in (FD_LENS if fd else range(9)):
        for fill in (0x00, 0xFF, 0x55, None):
            data = bytes(rng.randrange(256) if fill is None else fill for _ in range(n))
            for f in (Frame(0x000, data, fd=fd), Frame(0x7FF, data, fd=fd, brs=fd),
                      Frame(0x1FFFFFFF, data, ide=True, fd=fd, brs=fd), Frame(0, data, ide=True, fd=fd)):
                assert lib.frame_bits(f) == ref_bits(f), f
                assert lib.frame_wire(f) == ref_wire(f)[0], f


def test_the_hand_checked_figures(lib):
    """An 8-byte classic frame: 108 bits SOF..EOF (111 with the intermission) before stuffing,
    at most 24 stuff bits ((34 + 64 - 1) // 4), about 0.25 ms at 500 kbit/s."""
    raw, _ = header(Frame(0x010, bytes(8)))
    assert len(raw) + 15 + 10 == 108 and (len(raw) + 15 - 1) // 4 == 24
    # 0x010, zeros: SOF and 6 ID zeros (1 stuff bit), 4 ID zeros + RTR IDE r0 (1), DLC 1000 and
    # 64 zeros (67 zeros: 13), and one in the CRC: 16 stuff bits
    zeros, fives = Frame(0x010, bytes(8)), Frame(0x010, bytes([0x55] * 8))
    assert lib.frame_bits(zeros) == ref_bits(zeros) == (124, 0)
    assert lib.frame_bits(fives) == ref_bits(fives) == (111, 0)
    assert lib.frame_bits(Frame(0x000, bytes(8))) == (124, 0)
    bus = lib.bus(2)
    assert bus.frame_ns(zeros) == 124 * BIT == 248_000
    assert bus.frame_ns(fives) == 111 * BIT
    fd20 = Frame(0x010, bytes(range(20)), fd=True, brs=True)
    nom, dat = lib.frame_bits(fd20)
    assert (nom, dat) == ref_bits(fd20) == (FD20_NOM, FD20_DAT)
    assert bus.frame_ns(fd20) == nom * BIT + dat * DBIT == FD20_NS


FD20_NOM, FD20_DAT = 29, 212                 # 164,000 ns at 500k/2M
FD20_NS = FD20_NOM * BIT + FD20_DAT * DBIT


def test_invalid_frames_are_refused(lib):
    bus = lib.bus(2)
    for f in (Frame(0x800), Frame(0x10, bytes(9)), Frame(0x10, bytes(10), fd=True), Frame(0x10, brs=True),
              Frame(0x20000000, ide=True)):
        with pytest.raises(ValueError):
            lib.frame_bits(f)
        assert not bus.submit(0, f, 0)
    assert not bus.submit(5, Frame(0x10), 0)                   # no such node
    assert bus.stats()[0x10].dropped == 4
    assert [e.kind for e in bus.run(1)] == ["dropped"] * 6
    assert bus.next_ns() == INT64_MAX


# ---- the bus ----

def ns(f: Frame) -> int:
    nom, dat = ref_bits(f)
    return nom * BIT + dat * DBIT


def test_arbitration_lowest_id_first_back_to_back(lib):
    bus = lib.bus(3)
    frames_ = {0x030: Frame(0x030, b"\x03" * 8), 0x010: Frame(0x010, b"\x01" * 8), 0x020: Frame(0x020, b"\x02" * 8)}
    for node, fid in enumerate((0x030, 0x010, 0x020)):
        assert bus.submit(node, frames_[fid], 0)
    assert bus.next_ns() == ns(frames_[0x010])
    events = bus.run(10_000_000)
    assert [(e.kind, e.frame.id, e.node) for e in events] == [("delivered", 0x010, 1), ("delivered", 0x020, 2),
                                                              ("delivered", 0x030, 0)]
    t = 0
    for e in events:
        assert (e.queued_ns, e.start_ns, e.end_ns) == (0, t, t + ns(frames_[e.frame.id]))
        t = e.end_ns + 3 * BIT
    assert bus.stats()[0x030].max_delay_ns == events[2].start_ns
    assert bus.busy_ns() == t and bus.next_ns() == INT64_MAX


def test_same_instant_arbitrates_together_and_a_started_frame_is_not_preempted(lib):
    bus = lib.bus(2)
    bus.submit(0, Frame(0x020), 1000)
    assert bus.advance(1000) == []                             # starts at 1000: still undecided
    bus.submit(1, Frame(0x010), 1000)
    assert bus.run(1001) == []
    bus.submit(0, Frame(0x001), 1001)                          # 0x010 is on the bus since 1000
    ids = [(e.frame.id, e.start_ns) for e in bus.run(10**7)]
    first = 1000 + ns(Frame(0x010)) + 3 * BIT
    assert ids == [(0x010, 1000), (0x001, first), (0x020, first + ns(Frame(0x001)) + 3 * BIT)]


def test_equal_ids_on_two_nodes_go_to_the_lowest_node_first(lib):
    bus = lib.bus(3)
    bus.submit(2, Frame(0x010, b"\x02"), 0)
    bus.submit(1, Frame(0x010, b"\x01"), 0)
    assert [e.node for e in bus.run(10**8)] == [1, 2]


def test_a_node_offers_its_lowest_id_fifo_among_equals(lib):
    bus = lib.bus(2)
    for i, fid in enumerate((0x300, 0x100, 0x100, 0x200)):
        bus.submit(0, Frame(fid, bytes([i])), 0)
    bus.submit(1, Frame(0x150), 0)
    got = [(e.frame.id, e.frame.data) for e in bus.run(10**8)]
    assert got == [(0x100, b"\x01"), (0x100, b"\x02"), (0x150, b""), (0x200, b"\x03"), (0x300, b"\x00")]


def test_extended_ids_arbitrate_by_base_bits_then_ide(lib):
    bus = lib.bus(4)
    bus.submit(0, Frame((0x010 << 18) | 5, ide=True), 0)
    bus.submit(1, Frame(0x010), 0)
    bus.submit(2, Frame((0x010 << 18) | 4, ide=True), 0)
    bus.submit(3, Frame(0x011), 0)
    got = [(e.frame.id, e.frame.ide) for e in bus.run(10**8)]
    assert got == [(0x010, False), ((0x010 << 18) | 4, True), ((0x010 << 18) | 5, True), (0x011, False)]
    assert bus.stats()[EFF | (0x010 << 18) | 4].frames == 1


def flood_run(lib, flood_id):
    """A co-simulation at 1 ms steps: node 0 floods flood_id over [0, 50 ms), node 1 sends
    BrakeDemand 0x010 at 1 ms."""
    bus = lib.bus(2)
    bus.flood(0, flood_id, 0, 50_000_000)
    events = []
    for step in range(0, 60):
        now = step * 1_000_000
        if step == 1:
            assert bus.submit(1, Frame(0x010, b"\x01" * 8), now)
        events += bus.run(now)
    return bus, events


def test_a_flood_at_0x000_starves_brake_demand_until_it_ends(lib):
    bus, events = flood_run(lib, 0x000)
    period = ns(Frame(0x000, bytes(8))) + 3 * BIT
    brake = [e for e in events if e.frame.id == 0x010]
    assert len(brake) == 1
    start = -(-50_000_000 // period) * period                  # the first idle at or after 50 ms
    assert brake[0].start_ns == start > 50_000_000
    assert bus.stats()[0x010].max_delay_ns == start - 1_000_000
    floods = [e for e in events if e.frame.id == 0x000]
    assert all(e.end_ns < start for e in floods)
    assert [e.start_ns for e in floods] == [k * period for k in range(len(floods))]
    assert bus.stats()[0x000].max_delay_ns == 3 * BIT           # the babbler re-queues at each EOF
    assert bus.busy_ns() == start + ns(Frame(0x010, b"\x01" * 8)) + 3 * BIT   # a full bus until then


def test_a_flood_at_0x7ff_costs_brake_demand_at_most_one_frame(lib):
    bus, events = flood_run(lib, 0x7FF)
    brake = [e for e in events if e.frame.id == 0x010]
    assert len(brake) == 1 and brake[0].start_ns < 2_000_000
    assert 0 < bus.stats()[0x010].max_delay_ns <= ns(Frame(0x7FF, bytes(8))) + 3 * BIT


def test_the_victims_queue_overflows_during_a_flood(lib):
    bus = lib.bus(2)
    bus.flood(0, 0x000, 0, 50_000_000)
    ok = [bus.submit(1, Frame(0x010, bytes([i % 256])), 1_000_000 + i * 100_000) for i in range(40)]
    assert ok == [True] * 32 + [False] * 8
    assert bus.pending(1) == 32
    events = bus.run(100_000_000)
    assert [e.start_ns for e in events if e.kind == "dropped"] == [1_000_000 + i * 100_000 for i in range(32, 40)]
    s = bus.stats()[0x010]
    assert (s.frames, s.dropped) == (32, 8) and bus.pending(1) == 0


@pytest.mark.parametrize("frame", [Frame(0x010, b"\x01" * 8), Frame(0x010, bytes(range(20)), fd=True, brs=True)])
def test_an_injected_error_costs_the_destroyed_part_and_17_bits(lib, frame):
    bus = lib.bus(2)
    bus.error_next(0x010, 1)
    bus.submit(1, frame, 0)
    nom, dat = ref_bits(frame)
    destroyed = (nom - 7) * BIT + dat * DBIT                   # up to the ACK delimiter
    assert bus.next_ns() == destroyed + 14 * BIT
    events = bus.run(10**8)
    assert [e.kind for e in events] == ["bus_error", "delivered"]
    assert (events[0].start_ns, events[0].end_ns) == (0, destroyed + 14 * BIT)
    assert events[1].start_ns == destroyed + 17 * BIT
    assert events[1].end_ns - ns(frame) == destroyed + 17 * BIT   # the extra time
    s = bus.stats()[0x010]
    assert (s.frames, s.errors, s.max_delay_ns) == (1, 1, destroyed + 17 * BIT)
    assert bus.busy_ns() == events[1].end_ns + 3 * BIT


def test_errors_hit_only_their_id_and_the_retry_rearbitrates(lib):
    bus = lib.bus(3)
    bus.error_next(0x020, 2)
    bus.submit(0, Frame(0x020), 0)
    bus.submit(1, Frame(0x030), 0)
    first = bus.run(10**8)
    assert [(e.kind, e.frame.id) for e in first] == [("bus_error", 0x020), ("bus_error", 0x020),
                                                     ("delivered", 0x020), ("delivered", 0x030)]
    bus.submit(2, Frame(0x020), first[-1].end_ns + 10**6)
    assert [e.kind for e in bus.run(10**9)] == ["delivered"]


def test_bus_load_from_busy_time(lib):
    bus = lib.bus(2)
    f = Frame(0x100, b"\x5a" * 8)
    for k in range(100):                                       # one frame per ms for 100 ms
        assert bus.submit(k % 2, f, k * 1_000_000)
        bus.run(k * 1_000_000)
    bus.run(100_000_000)
    assert bus.busy_ns() == 100 * (ns(f) + 3 * BIT)
    load_pct = bus.busy_ns() * 100 // 100_000_000
    assert load_pct == (ns(f) + 3 * BIT) * 100 // 1_000_000 == 22   # 0.228 ms of each ms
    assert bus.stats()[0x100].max_delay_ns == 0


def test_the_event_buffer_limit_loses_nothing(lib):
    bus = lib.bus(1)
    for i in range(10):
        bus.submit(0, Frame(0x100 + i), 0)
    got = []
    while len(got) < 10:
        batch = bus.advance(10**9, max_events=3)
        assert 0 < len(batch) <= 3
        got += batch
    assert [e.frame.id for e in got] == [0x100 + i for i in range(10)]
    assert bus.advance(10**9) == []


def scripted(lib, seed):
    rng = random.Random(seed)
    bus = lib.bus(4, 500_000, 2_000_000)
    bus.flood(3, 0x050, 5_000_000, 9_000_000)
    bus.error_next(0x100, 3)
    out = []
    for step in range(200):
        now = step * 100_000
        for _ in range(rng.randrange(3)):
            fd = rng.random() < 0.5
            n = rng.choice(FD_LENS if fd else range(9))
            f = Frame(rng.choice([0x010, 0x100, 0x200, rng.randrange(0x800)]), bytes(rng.randrange(256) for _ in range(n)),
                      fd=fd, brs=fd and rng.random() < 0.5)
            bus.submit(rng.randrange(4), f, now)
        out += bus.run(now)
    return out, bus.stats(), bus.busy_ns()


def test_deterministic_and_time_ordered(lib):
    a, b = scripted(lib, 7), scripted(lib, 7)
    assert a == b
    events = [e for e in a[0] if e.kind != "dropped"]
    assert len(events) > 50 and {e.kind for e in a[0]} == {"delivered", "bus_error", "dropped"}
    assert any(e.frame.id == 0x050 for e in events)                # the flood got its turns
    for prev, e in zip(events, events[1:]):
        assert e.start_ns >= prev.end_ns + 3 * BIT              # one frame at a time, intermission kept
        assert e.end_ns - e.start_ns in (ns(e.frame), (ref_bits(e.frame)[0] + 7) * BIT + ref_bits(e.frame)[1] * DBIT)
