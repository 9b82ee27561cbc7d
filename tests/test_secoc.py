"""Issue 39 item 1 (first part): key sets, one key per sender, and the secured-frame profile
(CMAC-AES-128 from `cryptography`, a 64-bit freshness value that survives restarts)."""
from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess

import pytest
from cryptography.hazmat.primitives import cmac
from cryptography.hazmat.primitives.ciphers import algorithms

from can_bus import codec, keys, secoc
from can_bus.codec import BRAKE_DEMAND_ID, OBSTACLE_IDS, TRAIN_STATE_ID
from monitor.core.types import PRESENT, Report


def payload(ch: int = 0, counter: int = 0, distance_dm: int = 5000) -> bytes:
    return codec.encode(OBSTACLE_IDS[ch], codec.report_signals(Report(PRESENT, distance_dm, 2000, 0, 0), ch), counter)


# ----------------------------------------------------------------------------- key sets

def test_a_new_key_set_is_owner_only_and_one_key_per_sender(tmp_path):
    folder = tmp_path / "keys"
    ks = keys.new_set(folder, test=True)
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    for sender in keys.SENDERS:
        assert stat.S_IMODE((folder / f"{sender}.key").stat().st_mode) == 0o600
    assert len({ks.keys[s] for s in keys.SENDERS}) == len(keys.SENDERS)          # all different
    loaded = keys.load(folder)
    assert loaded.keys == ks.keys and loaded.test is True
    # the owner of each ID: the six channels, the train, the monitor's four outputs
    assert [loaded.key_for(fid) for fid in OBSTACLE_IDS] == [ks.keys[f"ch{i}"] for i in range(6)]
    assert loaded.key_for(TRAIN_STATE_ID) == ks.keys["train"] and loaded.key_for(BRAKE_DEMAND_ID) == ks.keys["monitor"]
    # a node loads its own key only: channel 2's sensor cannot sign for channel 3 or the monitor
    sensor = keys.load(folder, ["ch2"])
    assert sensor.key_for(OBSTACLE_IDS[2]) == ks.keys["ch2"]
    for fid in (OBSTACLE_IDS[3], BRAKE_DEMAND_ID):
        with pytest.raises(keys.KeyFileError, match="was not loaded"):
            sensor.key_for(fid)


def test_key_sets_refuse_overwriting_exposure_and_foreign_keys(tmp_path):
    folder = tmp_path / "keys"
    keys.new_set(folder)
    with pytest.raises(keys.KeyFileError, match="never overwritten"):
        keys.new_set(folder)
    os.chmod(folder / "ch1.key", 0o640)
    with pytest.raises(keys.KeyFileError, match="readable by others.*chmod 600"):
        keys.load(folder)
    os.chmod(folder / "ch1.key", 0o600)
    other = tmp_path / "other"
    keys.new_set(other)
    shutil.copy(other / "ch1.key", folder / "ch1.key")                 # a key from another set
    os.chmod(folder / "ch1.key", 0o600)
    with pytest.raises(keys.KeyFileError, match="fingerprint"):
        keys.load(folder)
    (folder / "ch1.key").write_text("abcd\n")
    with pytest.raises(keys.KeyFileError, match="16 bytes"):
        keys.load(folder)
    with pytest.raises(keys.KeyFileError, match="no key set here"):
        keys.load(tmp_path / "nothing")


def test_keys_cli_as_users_run_it(tmp_path):
    exe = shutil.which("railguard")
    assert exe, "the railguard entry point is not installed (pip install -e .)"
    folder = tmp_path / "site-keys"
    p = subprocess.run([exe, "keys", "new", str(folder), "--test", "--json"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    s = json.loads(p.stdout)
    assert s["test"] is True and set(s["senders"]) == set(keys.SENDERS) and "TEST KEYS" in s["note"]
    assert all(len(f) == 16 for f in s["senders"].values())
    assert not any(open(folder / f"{x}.key").read().strip() in p.stdout for x in keys.SENDERS)   # never a key
    again = subprocess.run([exe, "keys", "new", str(folder)], capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and again.stderr.count("\n") == 1 and "never overwritten" in again.stderr
    os.chmod(folder / "train.key", 0o644)
    bad = subprocess.run([exe, "keys", "show", str(folder)], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and "chmod 600" in bad.stderr


# ----------------------------------------------------------------------------- the profile

def test_the_cmac_is_aes_cmac_of_nist_sp_800_38b():
    """The primitive on the published example (SP 800-38B D.1, AES-128, 16-byte message)."""
    key = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")
    c = cmac.CMAC(algorithms.AES(key))
    c.update(bytes.fromhex("6bc1bee22e409f96e93d7e117393172a"))
    assert c.finalize().hex() == "070a16b46b4d4144f79bdd9dd04a287c"
    # and the authenticator is its first 64 bits over ID (2 bytes), payload and the full freshness
    msg = bytes.fromhex("0123") + bytes(range(8)) + (0x0102030405060708).to_bytes(8, "big")
    c = cmac.CMAC(algorithms.AES(key))
    c.update(msg)
    assert secoc.authenticator(key, 0x123, bytes(range(8)), 0x0102030405060708) == c.finalize()[:8]


def test_a_secured_frame_verifies_and_every_change_is_refused():
    key, other = bytes(range(16)), bytes(range(1, 17))
    fid, data = OBSTACLE_IDS[0], payload()
    frame = secoc.protect(key, fid, data, 41)
    assert len(frame) == secoc.FRAME_LENGTH == 20 and frame[:8] == data
    assert secoc.check(key, fid, frame, 40) == ("ok", 41)
    for bit in range(8 * len(frame)):                      # any single bit: payload, freshness or MAC
        bad = bytearray(frame)
        bad[bit // 8] ^= 1 << (bit % 8)
        assert secoc.check(key, fid, bytes(bad), 40)[0] in ("bad_mac", "stale_freshness"), bit
    assert secoc.check(other, fid, frame, 40)[0] == "bad_mac"                   # another sender's key
    assert secoc.check(key, OBSTACLE_IDS[1], frame, 40)[0] == "bad_mac"       # the same bytes on another ID
    assert secoc.check(key, fid, frame[:16], 40)[0] == "wrong_length"
    # freshness: the same frame again, or an older one, is refused before any CMAC; too far ahead too
    assert secoc.check(key, fid, frame, 41)[0] == "stale_freshness"
    far = secoc.protect(key, fid, data, 41 + secoc.WINDOW + 1)
    assert secoc.check(key, fid, far, 40)[0] == "stale_freshness"
    assert secoc.check(key, fid, secoc.protect(key, fid, data, 40 + secoc.WINDOW), 40)[0] == "ok"


def test_the_full_freshness_value_is_rebuilt_across_the_wire_bits_wrap():
    wrap = secoc.FV_MODULUS
    assert secoc.rebuild(None, 0) == 0 and secoc.rebuild(None, 7) == 7
    assert secoc.rebuild(wrap - 1, 0) == wrap                      # the low 32 bits wrapped
    assert secoc.rebuild(5 * wrap + 10, 3) == 6 * wrap + 3         # not newer with these bits: the next round
    key, fid = bytes(16), TRAIN_STATE_ID
    frame = secoc.protect(key, fid, bytes(8), wrap + 2)
    assert secoc.check(key, fid, frame, wrap - 3) == ("ok", wrap + 2)


def test_freshness_survives_restarts_and_an_earlier_session_is_refused(tmp_path):
    key, fid, data = bytes(range(16)), OBSTACLE_IDS[4], payload(4)
    sender_state, receiver_state = tmp_path / "sender.json", tmp_path / "receiver.json"
    tx, rx = secoc.FreshnessCounter(sender_state), secoc.FreshnessWindow(receiver_state)
    session1 = [secoc.protect(key, fid, data, tx.take(fid)) for _ in range(25)]
    assert [rx.accept(key, fid, f) for f in session1] == ["ok"] * 25
    rx.save()
    # both restart (crash of the sender: what it reserved is skipped, never reused)
    tx2, rx2 = secoc.FreshnessCounter(sender_state), secoc.FreshnessWindow(receiver_state)
    assert tx2.take(fid) == secoc.RESERVE
    assert [rx2.accept(key, fid, f) for f in session1] == ["stale_freshness"] * 25      # the recording is refused
    assert rx2.accept(key, fid, secoc.protect(key, fid, data, secoc.RESERVE)) == "ok"
    # a receiver that crashed between saves starts SAVE_EVERY above what it saved
    rx3 = secoc.FreshnessWindow(receiver_state)
    assert rx3.newest[fid] >= 24 + secoc.FreshnessWindow.SAVE_EVERY
    receiver_state.write_text("{not json")
    with pytest.raises(ValueError, match="not a freshness state file"):
        secoc.FreshnessWindow(receiver_state)
