"""Network outputs beside the UDP forwarder, hooked onto a live or replayed session: LSL
(:mod:`bpms.pipeline.lsl`) and the MVN-compatible stream (:mod:`bpms.pipeline.mvn`).

``add_stream_arguments`` gives a command ``--lsl`` and ``--mvn HOST:PORT``;
``start_streams`` attaches them to a :class:`bpms.pipeline.session.LiveSession` (before
``session.start()``, so no frame is missed) and ``stop_streams`` ends them.
"""

from __future__ import annotations

import argparse
import logging
import threading

log = logging.getLogger(__name__)


class MvnBridge:
    """Sends every processed frame of ``session`` as MVN datagrams (own thread, bounded
    subscription)."""

    def __init__(self, session, targets: list[str]) -> None:
        from bpms.pipeline.mvn import MvnSender

        self.session = session
        self.sender = MvnSender(targets)
        self.convention = session.processor.options.joints.convention
        self._sub = session.subscribe(maxlen=3000, lossless=True)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bpms-mvn", daemon=True)

    def start(self) -> MvnBridge:
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._thread.join(timeout)
        self.session.unsubscribe(self._sub)
        self.sender.close()

    def _run(self) -> None:
        from bpms.filter.joints import convert
        from bpms.filter.rotations import finite_dcm_to_quaternion
        from bpms.io.timebase import stream_time

        while True:
            stopping = self._stop.is_set()
            first = self._sub.get(0.1)
            batch = ([first] if first is not None else []) + self._sub.drain()
            for s in batch:
                # every frame: a segment without data (NaN) is sent as NaN (docs/mvn.md)
                q = finite_dcm_to_quaternion(s.C)
                try:
                    self.sender.send(max(s.index, 0), round(stream_time(s.index) * 1000),
                                     q, s.joint_positions,
                                     convert(s.joint_angles, self.convention, "isb"))
                except Exception as exc:  # never take the session down
                    log.warning("MVN send failed: %s", exc)
            if stopping and not batch:
                break


def add_stream_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--lsl", action="store_true",
                   help="also send LSL streams (orientations, joint angles, sensor data, "
                        "events; docs/lsl.md)")
    p.add_argument("--mvn", action="append", default=[], metavar="HOST:PORT",
                   help="also send an MVN-compatible stream (docs/mvn.md; repeatable)")


def start_streams(session, lsl: bool = False, mvn: list[str] | None = None,
                  period: float | None = None) -> list:
    """Attach the requested outputs; LSL also when the options enable it (``lsl.enabled``),
    MVN also to the options' ``mvn.targets``. Raises ValueError for a bad MVN target."""
    bridges: list = []
    targets = list(dict.fromkeys([*(mvn or []), *session.options.mvn.targets]))
    if targets:
        bridges.append(MvnBridge(session, targets).start())
    if lsl or session.options.lsl.enabled:
        from bpms.pipeline.lsl import LslBridge

        try:
            bridges.append(LslBridge(session, period=period).start())
        except ImportError:
            stop_streams(bridges)
            raise ValueError("LSL streaming needs the pylsl package "
                             '(pip install "bpms[lsl]")') from None
    return bridges


def stop_streams(bridges: list) -> None:
    for bridge in bridges:
        bridge.stop()
