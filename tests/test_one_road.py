"""One road for every change (issue 44 item 1): a scripted set of changes made to a live
session on the simulated suit (gains, filter, alignment and its toggle, Reset Zero from two
sources), each queued as its typed event and applied by ``BodyPoseProcessor.apply_event``,
and the session's raw recording fed back through both replay roads — the door of the analysis
commands and the API (``process_file``) and a replayed session (``bpms replay``, GUI
playback) — give the live numbers bit for bit: every DCM, segment orientation, output angle
and joint angle of every frame.

The test would see a second road: a change applied live that the recording does not carry
(planted in the settings queue), or a recorded change replayed differently (planted in the
door's event plan), each by one part in 10¹², makes the numbers differ.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from bpms.filter import door
from bpms.filter.door import open_for_processing, process_file
from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.options import Options, SerialOptions
from bpms.io.raw_reader import RawFrames
from bpms.io.rawfile import read_raw
from bpms.io.replay import ReplaySource
from bpms.io.session_events import SessionEvent
from bpms.pipeline.session import LiveSession
from bpms.pipeline.settings_queue import SettingsQueue
from bpms.pipeline.sources import SuitFrameSource

N = 250  # frames compared (5 s)
NUMBERS = ("R", "C", "euler_output", "joint_angles")

#: (source frame index reached, the change made then through the session's API)
SCRIPT: list[tuple[int, Callable[[LiveSession], None]]] = [
    (30, lambda s: s.set_gains(kp_yaw=0.6, ki_yaw=0.0001)),
    (55, lambda s: s.set_corrected_output(False)),
    (75, lambda s: s.reset_zero("manual")),
    (95, lambda s: s.set_corrected_output(True)),
    (115, lambda s: s.select_filter("observer")),
    (140, lambda s: s.set_gains(observer_k_incl=0.3)),
    (160, lambda s: s.reset_zero("3d-view")),
    (185, lambda s: s.select_filter("mahony")),
    (210, lambda s: s.set_corrected_output(None)),  # the `v` key: a toggle
]


def _collect(session: LiveSession, n: int, script=()) -> list:
    """``n`` processed samples of ``session`` (started here), making each scripted change
    once the session has processed its frame."""
    sub = session.subscribe(maxlen=10 * n, lossless=True)
    todo = list(script)
    samples: list = []
    session.start()
    deadline = time.monotonic() + 60
    while len(samples) < n and time.monotonic() < deadline:
        sample = sub.get(0.2)
        if sample is None:
            if session.source.status().state == "ended":
                break
            continue
        samples.append(sample)
        while todo and sample.index >= todo[0][0]:
            todo.pop(0)[1](session)
    assert not todo, f"the session stopped at frame {samples[-1].index if samples else -1}"
    return samples


def _live(folder: Path) -> tuple[list, Path]:
    """The live session on the simulated suit (in real time, 50 frames a second): its
    samples and its raw recording."""
    arbiter = Arbiter(MotionSource.simulated(seed=3, duration_s=30.0))
    with TcpServer(arbiter) as server:
        session = LiveSession(SuitFrameSource(server.url, SerialOptions()), Options(),
                              recording_dir=folder)
        session.source.connect()
        status = session.start_logging(raw=True, filtered=False, name="road")
        try:
            samples = _collect(session, N + 20, SCRIPT)
        finally:
            session.stop_logging()
            session.stop()
    assert status.raw_path is not None
    return samples, status.raw_path


def _stack(samples: list, name: str) -> np.ndarray:
    return np.stack([getattr(s, name) for s in samples])


def _same(live: list, replayed, n: int = N) -> bool:
    """Whether every number of the first ``n`` frames agrees bit for bit (NaN = NaN)."""
    get = ((lambda name: _stack(replayed, name)) if isinstance(replayed, list)
           else (lambda name: getattr(replayed, name)))
    return all(np.array_equal(_stack(live[:n], name), get(name)[:n], equal_nan=True)
               for name in NUMBERS)


@pytest.fixture(scope="module")
def session_run(tmp_path_factory):
    return _live(tmp_path_factory.mktemp("road"))


def test_the_recording_holds_every_scripted_change(session_run):
    samples, raw = session_run
    rec = read_raw(raw)
    assert len(rec) >= N
    for k in range(N):  # the recording's frames are the frames processed live, in order
        assert rec.frame_bytes(k) == samples[k].frame
    kinds = [(e.kind, e.data.get("source")) for _, e in rec.events if e.frame < N]
    frames = [e.frame for _, e in rec.events if e.frame >= 0 and e.data.get("source") is None
              and e.kind in ("gains", "filter", "alignment")]
    # each applied between two frames, a few frames after the one it was asked at
    assert all(a < b for a, b in itertools.pairwise(frames)), frames
    assert kinds.count(("gains", None)) == 2 and kinds.count(("filter", None)) == 2
    assert kinds.count(("alignment", None)) == 3
    assert ("reset_zero", "manual") in kinds and ("reset_zero", "3d-view") in kinds
    algorithms = [e.data["algorithm"] for _, e in rec.events if e.kind == "filter"]
    assert algorithms == ["mahony", "observer", "mahony"]  # (in force, then the two)


def test_the_door_gives_the_live_numbers_bit_for_bit(session_run):
    samples, raw = session_run
    assert _same(samples, process_file(raw))


def test_a_replayed_session_gives_the_live_numbers_bit_for_bit(session_run):
    samples, raw = session_run
    opened = open_for_processing(raw)
    frames = RawFrames(raw)
    source = ReplaySource(frames, speed=None, events=opened.replay_events(frames.events))
    replayed = _collect(LiveSession(source, opened.processor.options, opened.processor), N)
    assert len(replayed) == N
    assert _same(samples, replayed)


def test_a_second_road_in_the_replay_is_seen(session_run, monkeypatch):
    """Planted: the door's event plan replays each recorded gain change 1e-12 off."""
    samples, raw = session_run
    planned = door.planned_events

    def off(*args, **kwargs):
        out = planned(*args, **kwargs)
        for i, (slot, event) in enumerate(out):
            if event.kind == "gains" and event.data.get("source") is None:
                values = {k: v * (1 + 1e-12) for k, v in event.data["values"].items()}
                out[i] = (slot, SessionEvent("gains", event.frame, event.time,
                                             {"values": values}))
        return out

    monkeypatch.setattr(door, "planned_events", off)
    assert not _same(samples, process_file(raw))


def test_a_second_road_in_the_live_session_is_seen(tmp_path, monkeypatch):
    """Planted: the settings queue also turns kp_yaw 1e-12 up, a change no event carries."""
    apply = SettingsQueue.apply

    def also(self, processor, on_error=None):
        done = apply(self, processor, on_error)
        if any(e.kind == "gains" for e in done):
            processor.set_gains(kp_yaw=processor.options.filter.kp_yaw * (1 + 1e-12))
        return done

    monkeypatch.setattr(SettingsQueue, "apply", also)
    samples, raw = _live(tmp_path)
    assert not _same(samples, process_file(raw))
