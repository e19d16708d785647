"""Pose calibration ("Reset Zero", docs/body-model.md): DCMs → calibrated segment orientations.

At a capture, ``R0_i`` = the DCM of IMU i averaged over the still window that ends at the
capture frame (the matrices are averaged and re-orthonormalised by the polar decomposition,
via SVD); ψ0 = the yaw of the hip IMU (id 6) of its averaged ``R0`` (docs/body-model.md; option
``pose.heading_reference = "mean"`` takes the circular mean of all IMUs' yaws instead, which
averages out the hip IMU's mounting yaw error). From then on

    ``C_i = R_i @ R0_i^T @ Rz(ψ0)``

so in the calibration pose every segment reads ``Rz(ψ0)`` (the figure faces the hip's
magnetic heading) and every joint angle is 0. An IMU with no finite DCM in the window (not
yet initialised) keeps its previous zero (NaN before its first one); the same holds for ψ0
when the hip has no data.

When captures happen (:class:`PoseCalibrator`, the same rules live and in batch, so a file
filtered in one call and the same frames pushed one by one give identical outputs):

1. *provisional*: on the first frame where all 18 IMUs are initialised, a one-frame capture, so
   that segment orientations exist from the start of the stream;
2. *automatic*: at frame ``settle + window - 1`` of the stream (defaults: 0.5 s settling after
   the filters initialise, then the 0.5 s ``Options.pose.reset_window_s`` window, i.e. the
   capture completes 1.0 s into the stream), averaged over the window;
3. *on request* (Reset Zero pressed, or ``zero_at`` frames on replayed data): at the next frame,
   averaged over the window that ends there.

Reset Zero only changes filtered outputs; raw data and the filter states are untouched.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from bpms.filter.body_model import joint_positions
from bpms.filter.joints import joint_angles
from bpms.filter.rotations import dcm_to_euler, rot_z
from bpms.io.options import BodyOptions

HIP_IMU = 6


def average_dcm(Rs: np.ndarray) -> np.ndarray:
    """Mean rotation of ``Rs[W, ..., 3, 3]`` over axis 0: the element-wise mean (NaN frames
    ignored) projected onto SO(3) by the polar decomposition (SVD). NaN where no frame is
    finite."""
    Rs = np.asarray(Rs, dtype=np.float64)
    finite = np.isfinite(Rs).all(axis=(-1, -2))
    count = finite.sum(axis=0)
    total = np.where(finite[..., None, None], Rs, 0.0).sum(axis=0)
    mean = total / np.maximum(count, 1)[..., None, None]
    U, _, Vt = np.linalg.svd(mean)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= d[..., None]
    out = U @ Vt
    out[count == 0] = np.nan
    return out


@dataclass
class Zero:
    """One capture: ``R0[18, 3, 3]``, hip yaw ``yaw0`` rad, and ``offset = R0^T Rz(ψ0)``."""

    R0: np.ndarray
    yaw0: float
    frame: int  # stream frame index of the capture

    @cached_property
    def offset(self) -> np.ndarray:
        # once per capture, not once per frame (a capture is never changed after it is made)
        return np.swapaxes(self.R0, -1, -2) @ rot_z(self.yaw0)


HEADING_REFERENCES = ("hip", "mean")


def body_heading(R0: np.ndarray, reference: str = "hip", hip: int = HIP_IMU) -> float | None:
    """The body's heading ψ0 (rad) at a capture, from the captured DCMs ``R0[18, 3, 3]``:
    ``"hip"``, the hip IMU's yaw (docs/body-model.md); ``"mean"``, the circular mean of the yaws of
    every IMU (each is level in the calibration pose, so each yaw is the body heading plus that
    IMU's mounting yaw error, which averages out). None when no IMU it needs has data."""
    finite = np.isfinite(R0).all(axis=(-1, -2))
    if reference == "hip":
        return float(dcm_to_euler(R0[hip])[2]) if finite[hip] else None
    if reference != "mean":
        raise ValueError(f"heading reference must be one of {HEADING_REFERENCES}")
    if not finite.any():
        return None
    yaws = dcm_to_euler(R0[finite])[:, 2]
    return float(np.arctan2(np.sin(yaws).sum(), np.cos(yaws).sum()))


def capture_zero(R_window: np.ndarray, previous: Zero | None = None, frame: int = 0,
                 hip: int = HIP_IMU, heading: str = "hip") -> Zero:
    """A capture from the DCMs ``R_window[W, 18, 3, 3]`` (see the module docstring);
    ``heading``: where ψ0 comes from (:func:`body_heading`)."""
    R0 = average_dcm(R_window)
    missing = ~np.isfinite(R0).all(axis=(-1, -2))
    if previous is not None:
        R0[missing] = previous.R0[missing]
    yaw0 = body_heading(R0, heading, hip)
    if yaw0 is None:
        yaw0 = previous.yaw0 if previous is not None else 0.0
    return Zero(R0, yaw0, frame)


def segment_orientations(R: np.ndarray, zero: Zero | None) -> np.ndarray:
    """``C[..., 18, 3, 3] = R @ R0^T @ Rz(ψ0)``; NaN without a zero."""
    if zero is None:
        return np.full(np.shape(R), np.nan)
    return np.asarray(R, dtype=np.float64) @ zero.offset


def segment_angles(C: np.ndarray) -> np.ndarray:
    """``[..., 18, 3]`` rad: roll, pitch, yaw of the segment orientations ``C[..., 18, 3, 3]``
    (NaN where C is)."""
    return dcm_to_euler(C)


def body_outputs(C: np.ndarray, body: BodyOptions | None = None, convention: str = "isb",
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(joint angles ``[..., 28]`` rad in ``convention`` (docs/joint-angles.md), joint positions
    ``[..., 21, 3]`` m, lowest foot on the ground) from segment orientations ``C``."""
    return joint_angles(C, convention), joint_positions(C, body, on_ground=True)


class PoseCalibrator:
    """Decides when Reset Zero captures happen and turns DCMs into segment orientations.

    ``window`` frames per averaged capture (≥ 1), ``settle`` frames before the automatic
    capture window starts; ``auto`` enables the provisional and automatic captures.
    """

    def __init__(self, window: int = 25, settle: int = 25, auto: bool = True,
                 hip: int = HIP_IMU, heading: str = "hip") -> None:
        self.window = max(1, int(window))
        self.settle = max(0, int(settle))
        self.auto = auto
        self.hip = hip
        self.heading = heading
        self.restart()

    def restart(self) -> None:
        """A new stream: forget the zero and the frame count (auto captures run again)."""
        self.zero: Zero | None = None
        self.frames = 0  # frames seen in this stream
        # the last window-1 frames of R, a ring: frame by frame costs one copy of a frame
        self._ring: np.ndarray | None = None
        self._held = 0  # frames in the ring
        self._next = 0  # where the next frame goes (the oldest, once the ring is full)
        self._provisional_done = False
        self._requested = False
        self.captures: list[Zero] = []

    def request(self) -> None:
        """Reset Zero pressed: capture at the next frame over the window ending there."""
        self._requested = True

    @property
    def auto_frame(self) -> int:
        """Stream frame index of the automatic capture."""
        return self.settle + self.window - 1

    @property
    def _buffer(self) -> np.ndarray | None:
        """The frames of R remembered from earlier batches, oldest first (None: none)."""
        if self._ring is None or not self._held:
            return None
        if self._held < len(self._ring):  # not full yet: filled in order from the start
            return self._ring[:self._held]
        return np.concatenate((self._ring[self._next:], self._ring[:self._next]))

    def _remember(self, R: np.ndarray) -> None:
        """Keep the last ``window - 1`` frames of the stream, ``R`` being its newest."""
        keep = self.window - 1
        n = len(R)
        if keep == 0 or n == 0:
            return
        if self._ring is None or self._ring.shape[1:] != R.shape[1:]:
            self._ring, self._held, self._next = np.empty((keep, *R.shape[1:])), 0, 0
        if n >= keep:
            self._ring[:] = R[n - keep:]
            self._held, self._next = keep, 0
            return
        if n == 1:  # a live frame
            self._ring[self._next] = R[0]
        else:
            self._ring[(self._next + np.arange(n)) % keep] = R
        self._advance(n)

    def _advance(self, n: int) -> None:
        keep = len(self._ring)
        self._next = (self._next + n) % keep
        self._held = min(self._held + n, keep)

    def _window_ending_at(self, R: np.ndarray, k: int) -> np.ndarray:
        """The last ``window`` frames up to batch frame ``k``, reaching into earlier batches."""
        lo = k - self.window + 1
        earlier = None if lo >= 0 else self._buffer
        if earlier is None:
            return R[max(lo, 0):k + 1]
        return np.concatenate([earlier[max(len(earlier) + lo, 0):], R[:k + 1]])

    def apply(self, R: np.ndarray, zero_at: Iterable[int] = ()) -> np.ndarray:
        """Segment orientations ``C[N, 18, 3, 3]`` of the next N frames' DCMs
        ``R[N, 18, 3, 3]``; ``zero_at``: extra capture frames, indices into this batch."""
        R = np.asarray(R, dtype=np.float64)
        n = len(R)
        first = self.frames
        events = {int(k) for k in zero_at if 0 <= int(k) < n}
        if self._requested and n:
            events.add(0)
            self._requested = False
        if self.auto and first <= self.auto_frame < first + n:
            events.add(self.auto_frame - first)
        provisional = None
        if self.auto and not self._provisional_done:
            ok = np.isfinite(R[:, :, 0, 0]).all(axis=1)
            if ok.any():
                provisional = int(np.argmax(ok))
                self._provisional_done = True
        captures = events if provisional is None else events | {provisional}
        if not captures:  # most frames: no capture in this batch
            C = segment_orientations(R, self.zero)
            self._remember(R)
            self.frames += n
            return C
        C = np.empty_like(R)
        start = 0
        for k in sorted(captures):
            C[start:k] = segment_orientations(R[start:k], self.zero)
            if k == provisional and k not in events:
                window = R[k:k + 1]
            else:
                window = self._window_ending_at(R, k)
            self.zero = capture_zero(window, self.zero, first + k, self.hip, self.heading)
            self.captures.append(self.zero)
            start = k
        C[start:] = segment_orientations(R[start:], self.zero)
        self._remember(R)
        self.frames += n
        return C
