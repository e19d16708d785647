"""The takeover and freshness rules (bpms/io/udp/gate.py, docs/udp.md "One sender at a time"
and "Freshness") on hand-made timelines: no sockets, no waiting. Real sockets and processes
are in tests/test_udp_takeover.py."""

from __future__ import annotations

from bpms.io.udp.gate import Admission, SessionGate, SessionKey

A = Admission
REAL = SessionKey(0xA, sender=7, epoch=2_000)
OTHER = SessionKey(0xB, sender=8, epoch=5_000)


def stream(gate: SessionGate, key: SessionKey, t0: float, n: int, seq0: int = 0,
           dt: float = 0.02) -> list[Admission]:
    return [gate.admit(key, seq0 + k, t0 + k * dt) for k in range(n)]


def test_one_datagram_during_a_pause_changes_nothing():
    gate = SessionGate()
    assert stream(gate, REAL, 0.0, 50) == [A.FIRST] + [A.ACTIVE] * 49
    # 3 s of silence, one datagram of an unknown session: foreign, not a takeover
    assert gate.admit(OTHER, 0, 3.98) == A.FOREIGN
    assert stream(gate, REAL, 4.0, 50, seq0=50) == [A.ACTIVE] * 50
    assert gate.active == REAL and gate.takeovers == 0


def test_a_takeover_needs_five_seconds_of_silence_and_25_datagrams_in_a_row():
    gate = SessionGate()
    stream(gate, REAL, 0.0, 10)  # the last datagram at 0.18 s
    # 25 in a row, but the real sender has been silent for less than 5 s: foreign
    assert stream(gate, OTHER, 1.0, 25) == [A.FOREIGN] * 25
    assert gate.admit(OTHER, 25, 5.17) == A.FOREIGN  # 4.99 s of silence
    assert gate.admit(OTHER, 26, 5.19) == A.TAKEOVER  # 5.01 s, and 27 in a row
    assert gate.active == OTHER and gate.takeovers == 1
    took = gate.last_takeover
    assert (took.old, took.new, not took.newer_run) == (REAL, OTHER, True)
    assert abs(took.silent_s - 5.01) < 1e-9
    assert gate.admit(REAL, 10, 5.2) == A.STALE  # the replaced session's late datagram


def test_a_newcomer_whose_numbers_skip_starts_its_count_again():
    gate = SessionGate()
    stream(gate, REAL, 0.0, 10)
    got = [gate.admit(OTHER, seq, 10.0 + k * 0.02)
           for k, seq in enumerate([*range(20), *range(30, 54)])]  # 20, a gap, then 24
    assert got == [A.FOREIGN] * 44 and gate.active == REAL
    assert gate.admit(OTHER, 54, 11.0) == A.TAKEOVER  # the 25th in a row


def test_interleaved_newcomers_each_need_their_own_run():
    gate = SessionGate()
    stream(gate, REAL, 0.0, 10)
    third = SessionKey(0xC)
    for k in range(24):
        assert gate.admit(OTHER, k, 10.0 + k * 0.02) == A.FOREIGN
        assert gate.admit(third, k, 10.01 + k * 0.02) == A.FOREIGN
    assert gate.admit(third, 24, 10.6) == A.TAKEOVER and gate.active == third


def test_without_a_key_the_epoch_is_not_trusted():
    gate = SessionGate(keyed=False)
    stream(gate, REAL, 0.0, 10)
    older = SessionKey(0xD, sender=7, epoch=1_000)  # claims an earlier run: no matter
    assert stream(gate, older, 6.0, 25)[-1] == A.TAKEOVER
    newer = SessionKey(0xE, sender=7, epoch=9_000)  # claims a newer run: no shortcut either
    assert gate.admit(newer, 0, 6.6) == A.FOREIGN


def test_with_a_key_an_earlier_run_of_the_sender_is_refused_whatever_the_silence():
    gate = SessionGate(keyed=True)
    stream(gate, REAL, 0.0, 10)
    earlier = SessionKey(0x9, sender=7, epoch=1_000)  # recorded during an earlier run
    assert stream(gate, earlier, 1.0, 5) == [A.REPLAYED] * 5
    assert stream(gate, earlier, 60.0, 100) == [A.REPLAYED] * 100  # a minute of silence
    assert gate.active == REAL and gate.takeovers == 0
    # another computer's run is not older or newer than this one's: the takeover rule
    assert stream(gate, OTHER, 61.0, 25)[-1] == A.TAKEOVER
    assert gate.admit(REAL, 10, 61.6) == A.STALE


def test_with_a_key_a_newer_run_of_the_same_sender_takes_over_at_once():
    gate = SessionGate(keyed=True)
    stream(gate, REAL, 0.0, 10)
    restarted = SessionKey(0xF, sender=7, epoch=3_000)
    assert gate.admit(restarted, 0, 0.3) == A.TAKEOVER
    assert gate.last_takeover.newer_run
    # the old run's datagrams are now older than the newest run followed: replayed
    assert gate.admit(REAL, 10, 0.31) == A.REPLAYED


def test_a_receiver_started_late_follows_the_first_sender_it_hears():
    """The documented limit: a receiver's memory of epochs starts with it."""
    gate = SessionGate(keyed=True)
    earlier = SessionKey(0x9, sender=7, epoch=1_000)
    assert gate.admit(earlier, 500, 0.0) == A.FIRST  # a replay reached it first
    assert gate.admit(REAL, 0, 0.5) == A.TAKEOVER  # the real, newer run takes over at once
    assert gate.admit(earlier, 501, 0.52) == A.REPLAYED


def test_the_replaced_sender_comes_back_at_once_when_the_newcomer_is_quiet():
    """Issue 45.2: a takeover never locks the real sender out."""
    gate = SessionGate()
    stream(gate, REAL, 0.0, 100)  # last datagram 1.98 s
    assert stream(gate, OTHER, 7.58, 70)[24] == A.TAKEOVER  # 5.6 s of silence, then 25
    # the stranger's last at 8.96 s; the real sender resumes at 9.48 s, its numbers go on
    assert gate.admit(REAL, 100, 9.48) == A.RETURN
    assert gate.active == REAL and gate.takeovers == 2 and gate.last_takeover.returned
    assert stream(gate, REAL, 9.5, 10, seq0=101) == [A.ACTIVE] * 10
    # the stranger now needs the takeover rule again: no quick return for it
    assert stream(gate, OTHER, 9.51, 30, seq0=70) == [A.STALE] * 30


def test_a_return_needs_the_real_senders_own_numbers():
    gate = SessionGate()
    stream(gate, REAL, 0.0, 100)
    stream(gate, OTHER, 7.58, 30)
    # numbers the real session already sent (a replay of it, or late datagrams): stale
    assert stream(gate, REAL, 10.0, 20, seq0=50) == [A.STALE] * 20
    assert gate.active == OTHER
    # with the newcomer still streaming, the real sender's 10th datagram in a row returns
    got = []
    for k in range(10):
        assert gate.admit(OTHER, 30 + k, 10.49 + k * 0.02) == A.ACTIVE
        got.append(gate.admit(REAL, 100 + k, 10.5 + k * 0.02))
    assert got == [A.STALE] * 9 + [A.RETURN]


def test_with_a_key_a_known_session_never_has_a_number_accepted_twice():
    gate = SessionGate(keyed=True)
    stream(gate, REAL, 0.0, 100)
    stream(gate, OTHER, 7.58, 30)  # another computer with the key
    assert gate.active == OTHER
    # the real session's old numbers, replayed: refused as replayed, not merely stale
    assert stream(gate, REAL, 10.0, 40, seq0=0) == [A.REPLAYED] * 40
    assert gate.admit(REAL, 100, 10.9) == A.RETURN  # its own next number: back
