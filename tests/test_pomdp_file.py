"""Reader/writer for Cassandra's .pomdp format (monitor/offline/pomdp_file.py)."""
from pathlib import Path

import numpy as np
import pytest

from monitor.offline.pomdp import POMDP, normalise_rows
from monitor.offline.pomdp_file import PomdpFormatError, dumps, loads, read, write

TIGER = Path(__file__).resolve().parents[1] / "examples" / "tiger.pomdp"
ARRAYS = ("T", "O", "R", "b0")


def assert_same_model(a: POMDP, b: POMDP) -> None:
    for key in ARRAYS:
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert (a.states, a.actions, a.observations) == (b.states, b.actions, b.observations)
    assert a.discount == b.discount


def random_model(seed: int = 3) -> POMDP:
    rng = np.random.default_rng(seed)
    return POMDP(
        name="random",
        states=tuple(f"s{i}" for i in range(5)),
        actions=("brake", "coast", "hold-speed"),
        observations=tuple(f"gap-{i}" for i in range(4)),
        T=normalise_rows(rng.random((3, 5, 5))),
        O=normalise_rows(rng.random((3, 5, 4))),
        R=rng.normal(scale=10.0, size=(5, 3)),
        discount=float(rng.uniform(0.5, 0.99)),
        b0=normalise_rows(rng.random(5)),
    )


# ------------------------------------------------------------------ tiger


def test_tiger_parses_to_the_textbook_arrays():
    m = read(TIGER)
    L, R_ = m.states.index("tiger-left"), m.states.index("tiger-right")
    listen, open_left, open_right = (m.actions.index(a) for a in ("listen", "open-left", "open-right"))
    assert m.name == "tiger"
    assert m.states == ("tiger-left", "tiger-right")
    assert m.observations == ("tiger-left", "tiger-right")
    assert m.discount == 0.95
    assert np.array_equal(m.b0, [0.5, 0.5])
    assert np.array_equal(m.T[listen], np.eye(2))
    assert np.all(m.T[open_left] == 0.5) and np.all(m.T[open_right] == 0.5)
    assert m.O[listen, L, L] == 0.85 and m.O[listen, L, R_] == 0.15
    assert m.O[listen, R_, R_] == 0.85
    assert np.all(m.O[open_left] == 0.5)
    assert m.R[L, open_left] == -100 and m.R[R_, open_left] == 10
    assert m.R[L, open_right] == 10 and m.R[R_, open_right] == -100
    assert np.all(m.R[:, listen] == -1)


def test_tiger_round_trip(tmp_path):
    m = read(TIGER)
    write(m, tmp_path / "again.pomdp")
    back = read(tmp_path / "again.pomdp")
    assert_same_model(m, back)
    assert back.name == "again"


# ------------------------------------------------------------------ writing


def test_random_model_round_trip_is_bit_identical(tmp_path):
    m = random_model()
    # The seed is chosen so the test bites: some rows do not sum to exactly
    # 1.0, and dividing them by their sum again would change their bits.
    sums = m.T.sum(axis=-1)
    assert np.any(sums != 1.0) and np.any(m.O.sum(axis=-1) != 1.0)
    assert not np.array_equal(m.T / sums[..., None], m.T)

    write(m, tmp_path / "random.pomdp")
    back = read(tmp_path / "random.pomdp")
    assert_same_model(m, back)
    assert_same_model(m, loads(dumps(m)))


def test_written_text_has_header_and_documented_layout():
    text = dumps(random_model())
    lines = text.splitlines()
    assert lines[0].startswith("# written by railguard") and "random" in lines[0]
    assert "values: reward" in lines
    assert "states: s0 s1 s2 s3 s4" in lines  # our names are written unchanged
    assert "T: hold-speed" in lines and "O: brake" in lines
    assert sum(line.startswith("R: ") and line.count(": * : *") == 1 for line in lines) == 15


def test_names_with_whitespace_or_colon_are_made_writable_lossily():
    m = read(TIGER)
    odd = POMDP("odd", ("left side", "right:side"), m.actions, m.observations,
                m.T, m.O, m.R, m.discount, m.b0)
    back = loads(dumps(odd))
    assert back.states == ("left_side", "right_side")
    assert np.array_equal(back.R, m.R)


def test_format_is_whitespace_insensitive():
    text = dumps(random_model())
    one_line = " ".join(line for line in text.splitlines() if not line.startswith("#"))
    assert_same_model(loads(one_line), random_model())


# ------------------------------------------------------------------ reading features

BASE = """\
discount: 0.9
values: reward
states: a b
actions: go stay
observations: x y
"""  # 5 lines; entries start on line 6


def test_wildcards_then_specific_overrides():
    m = loads("""\
discount: 0.9
states: 3
actions: 2
observations: 2
T: * : * : * 0.0
T: * : * : 0 1.0
T: 1 : 2 : 0 0.0
T: 1 : 2 : 2 1.0
O: * uniform
O: 0 : 1
0.2 0.8
R: * : * : * : * 5
R: 1 : 2 : * : * -3
""")
    assert np.array_equal(m.T[0], [[1, 0, 0]] * 3)
    assert np.array_equal(m.T[1], [[1, 0, 0], [1, 0, 0], [0, 0, 1]])
    assert np.array_equal(m.O[0, 1], [0.2, 0.8]) and np.array_equal(m.O[0, 0], [0.5, 0.5])
    assert np.array_equal(m.O[1], np.full((3, 2), 0.5))
    expected_R = np.full((3, 2), 5.0)
    expected_R[2, 1] = -3
    assert np.array_equal(m.R, expected_R)


def test_integer_counts_give_index_names_and_accept_index_references():
    m = loads(BASE.replace("states: a b", "states: 3").replace("observations: x y", "observations: 2")
              + "T: * identity\nT: go : 2\n0 1 0\nO: * : * : 1 1\nstart: 2\n")
    assert m.states == ("0", "1", "2") and m.observations == ("0", "1")
    assert np.array_equal(m.T[0, 2], [0, 1, 0])
    assert np.array_equal(m.O[:, :, 1], np.ones((2, 3)))
    assert np.array_equal(m.b0, [0, 0, 1])
    assert "states: 3" in dumps(m).splitlines()
    assert_same_model(loads(dumps(m)), m)


def test_values_cost_negates_rewards():
    tiger = TIGER.read_text()
    assert "values: reward" in tiger
    cost = loads(tiger.replace("values: reward", "values: cost"))
    assert np.array_equal(cost.R, -read(TIGER).R)
    assert cost.R[0, 0] == 1.0  # listening costs 1, i.e. rewards +1 when read as cost


def test_reward_is_expected_over_next_state_and_observation():
    m = loads("""\
discount: 0.5
states: s0 s1
actions: a
observations: z0 z1
T: a
0.3 0.7
1.0 0.0
O: a
0.2 0.8
0.5 0.5
R: a : * : * : * 1
R: a : * : s1 : z0 5
R: a : s1 : s0
2 4
""")
    # s0: 0.3 * 1 + 0.7 * (0.5*5 + 0.5*1) = 2.4;  s1: 1.0 * (0.2*2 + 0.8*4) = 3.6
    assert m.R[:, 0] == pytest.approx([2.4, 3.6], abs=1e-12)


@pytest.mark.parametrize("start, b0", [
    ("", [0.5, 0.5]),
    ("start: uniform", [0.5, 0.5]),
    ("start: 0.25 0.75", [0.25, 0.75]),
    ("start: tiger-right", [0, 1]),
    ("start: 1", [0, 1]),
    ("start include: tiger-left", [1, 0]),
    ("start exclude: tiger-left", [0, 1]),
])
def test_start_forms(start, b0):
    m = loads(TIGER.read_text().replace("start: uniform", start))
    assert np.array_equal(m.b0, b0)


def test_rows_within_format_tolerance_are_renormalised_exactly():
    m = loads(BASE + "T: * identity\nT: go : a\n0.3333333 0.6666666\nO: * uniform\n")
    row = np.array([0.3333333, 0.6666666])
    assert np.array_equal(m.T[0, 0], row / row.sum())  # divided, not left at 0.9999999
    assert abs(m.T[0, 0].sum() - 1.0) <= 1e-15


# ------------------------------------------------------------------ errors

GOOD_REST = "T: * identity\nO: * uniform\n"


@pytest.mark.parametrize("text, line, fragment", [
    (BASE + "T: go : a : c 1.0\n" + GOOD_REST, 6, "unknown state 'c'"),
    (BASE + "T: jump identity\n" + GOOD_REST, 6, "unknown action 'jump'"),
    (BASE + "T: go : 7 : a 1\n" + GOOD_REST, 6, "index 7 out of range"),
    (BASE + GOOD_REST + "T: go : a\n0.5 0.4\n", 9, "T row for go/a sums to 0.9, not 1"),
    (BASE + GOOD_REST + "O: stay\n0.5 0.5\n0.5\n0.4\n", 10, "O row for stay/b sums to 0.9"),
    (BASE + "T: go\n1 0 0\n" + GOOD_REST, 6, "expects 4 numbers (2x2 matrix), found 3"),
    (BASE + "T: go : a\n1 0 0\n" + GOOD_REST, 6, "expects 2 numbers"),
    (BASE + GOOD_REST + "T: go : a : b abc\n", 8, "'abc' is not a finite number"),
    (BASE + GOOD_REST + "T: go : a : b nan\n", 8, "not a finite number"),
    (BASE + GOOD_REST + "T: go : a\n-0.5 1.5\n", 9, "negative T probability -0.5"),
    (BASE + "O: * uniform\nT: go identity\n", 4, "no transition probabilities for action stay from state a"),
    (BASE + "T: * identity\nO: go uniform\n", 4, "no observation probabilities for action stay into state a"),
    (BASE.replace("states: a b\n", "") + GOOD_REST, 5, "before the 'states:' declaration"),
    (BASE.replace("discount: 0.9\n", "") + GOOD_REST, 6, "missing 'discount:'"),
    (BASE.replace("0.9", "1.5") + GOOD_REST, 1, "discount 1.5 outside [0, 1)"),
    (BASE.replace("reward", "money") + GOOD_REST, 2, "'reward' or 'cost'"),
    (BASE + "states: c d\n" + GOOD_REST, 6, "declared twice"),
    (BASE + "start: 0.5 0.6\n" + GOOD_REST, 6, "start belief sums to 1.1"),
    (BASE + "start: c\n" + GOOD_REST, 6, "unknown state 'c'"),
    (BASE.replace("states: a b", "states: 1000000"), 3, "count 1000000 must be"),
    (BASE.replace("states: a b", "states: 20000"), 5, "model too large to read"),
    (BASE + GOOD_REST + "Q: go 1\n", 8, "expected a declaration or entry, found 'Q'"),
    ("\x00\x01 garbage\n" + BASE + GOOD_REST, 1, "found '\\x00\\x01'"),
    (BASE + GOOD_REST + "R: go 1\n", 8, "R: needs at least"),
    (BASE + GOOD_REST + "T: go : a :", 8, "unexpected end of file"),
    ("", 1, "missing 'discount:'"),
])
def test_bad_text_raises_format_error_with_line(text, line, fragment):
    with pytest.raises(PomdpFormatError) as info:
        loads(text)
    message = str(info.value)
    assert message.startswith(f"line {line}: "), message
    assert fragment in message
    assert "\n" not in message
    assert info.value.line == line


@pytest.mark.parametrize("cut, line, fragment", [
    ("T: listen\nidentity\n\nT: open-left\nuni", 16, "expects 4 numbers"),  # mid-word
    ("O: listen\n0.85 0.15\n0.15", 22, "expects 4 numbers (2x2 matrix), found 3"),
    ("R: listen : * :", 32, "unexpected end of file"),
    ("actions: listen open-left open-right\n", 9, "missing 'observations:'"),
])
def test_truncated_tiger_is_reported_at_the_right_line(tmp_path, cut, line, fragment):
    text = TIGER.read_text()
    truncated = text[: text.index(cut) + len(cut)]
    path = tmp_path / "tiger.pomdp"
    path.write_text(truncated)
    with pytest.raises(PomdpFormatError) as info:
        read(path)
    assert str(info.value).startswith(f"{path}:{line}: "), str(info.value)
    assert fragment in str(info.value)


def test_read_names_the_file_in_errors(tmp_path):
    path = tmp_path / "tiger.pomdp"
    path.write_text(TIGER.read_text().replace("R: open-left : tiger-left", "R: opn-left : tiger-left"))
    with pytest.raises(PomdpFormatError, match=r"tiger\.pomdp:33: unknown action 'opn-left'$"):
        read(path)


def test_non_utf8_bytes_are_a_format_error_with_line(tmp_path):
    path = tmp_path / "bad.pomdp"
    path.write_bytes(b"discount: 0.9\nstates: caf\xe9 bar\n")
    with pytest.raises(PomdpFormatError, match=r"bad\.pomdp:2: not UTF-8 text \(byte 0xe9\)"):
        read(path)


def test_binary_garbage_is_a_format_error(tmp_path):
    path = tmp_path / "garbage.pomdp"
    path.write_bytes(bytes(range(256)))  # first invalid UTF-8 byte (0x80) is on line 2
    with pytest.raises(PomdpFormatError, match=r"garbage\.pomdp:2: "):
        read(path)
    path.write_bytes(b"\x00\x01\x02\x03 T: 1\n")  # valid UTF-8 but not the format
    with pytest.raises(PomdpFormatError, match=r"garbage\.pomdp:1: expected a declaration or entry, found '\\x00\\x01\\x02\\x03'$"):
        read(path)


def test_missing_file_is_a_format_error_naming_the_path(tmp_path):
    path = tmp_path / "nowhere.pomdp"
    with pytest.raises(PomdpFormatError) as info:
        read(path)
    assert str(path) in str(info.value) and "cannot read" in str(info.value)
    assert info.value.line is None  # no line exists; the path is the location


def test_mangled_files_only_ever_raise_format_errors():
    """Deterministic fuzz: delete, insert and truncate; nothing but PomdpFormatError escapes."""
    import random

    rng = random.Random(7)
    sources = [TIGER.read_text(), dumps(read(TIGER))]
    pieces = list(": *#\n0123456789.-e") + ["listen", "uniform", "identity", "T:", "R:", "\x00"]
    errors = 0
    for _ in range(500):
        text = rng.choice(sources)
        for _ in range(rng.randint(1, 3)):
            k = rng.randrange(len(text) + 1)
            text = rng.choice([text[:k] + rng.choice(pieces) + text[k:], text[:k] + text[k + 5:], text[:k]])
        try:
            loads(text)
        except PomdpFormatError as exc:
            assert str(exc).startswith("line ") and "\n" not in str(exc)
            errors += 1
    assert errors > 250  # most mangled files are rejected rather than silently accepted
