"""What a live session forwards over UDP after each processed batch, besides the raw frames
(docs/udp.md): one POSE datagram per frame, and the Reset Zero in force as a ZERO datagram at
each capture and once a second, so that a client joining later shows the sender's segment
angles."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from bpms.io.events import FrameEvent
from bpms.io.timebase import stream_time
from bpms.io.udp.codec import ZeroMessage
from bpms.io.udp.sender import UdpForwarder

if TYPE_CHECKING:
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.filter.result import Result

#: Frames between two ZERO datagrams repeating the Reset Zero in force (1 s at 50 Hz).
ZERO_RESEND_FRAMES = 50


def forward_poses(forwarder: UdpForwarder, events: list[FrameEvent], result: Result) -> None:
    """One pose datagram for every frame (docs/udp.md): the segment orientations after Reset
    Zero, the joint angles and positions, the disturbance flags and which segments carry data.
    A segment without data (its IMU failed, or no Reset Zero yet) goes as NaN and flagged in
    the validity block, and so does every angle and position needing it: one dead IMU costs
    its segments, never the frame."""
    quats = result.segment_quaternions.astype(np.float32)
    angles, positions, dist = result.joint_angles, result.joint_positions, result.disturbance
    valid = np.isfinite(quats).all(axis=2)
    for k, e in enumerate(events):
        forwarder.send_pose(quats[k], angles[k].astype(np.float32),
                            stream_time(e.index), positions[k], result.convention,
                            None if dist is None else (dist.mag[k], dist.acc[k]), valid[k])


class ZeroForwarding:
    """Sends the processor's Reset Zero in force at each capture and every
    :data:`ZERO_RESEND_FRAMES` frames; never the one-frame provisional capture at the start
    of a stream (a client makes its own, and waits for a real one)."""

    def __init__(self) -> None:
        self._sent_at = -1  # frames processed when it was last sent
        self._processed = 0

    def after(self, forwarder: UdpForwarder, processor: BodyPoseProcessor,
              events: list[FrameEvent], result: Result) -> str | None:
        """Call after each processed batch; returns a problem to note (None: none)."""
        self._processed += len(events)
        zero = processor.pose.zero
        captured = any(z.source != "provisional" for z in result.zeros)
        if zero is None or zero.source == "provisional" or (
                not captured and self._processed - self._sent_at < ZERO_RESEND_FRAMES):
            return None
        self._sent_at = self._processed
        first = processor.frames - len(events)  # the processor's frame number of events[0]
        index = events[0].index + zero.frame - first
        try:
            forwarder.send_zero(ZeroMessage(zero.R0, zero.yaw0, zero.source, zero.heading,
                                            zero.window), stream_time(index))
        except ValueError as exc:
            return f"Reset Zero not forwarded: {exc}"
        return None
