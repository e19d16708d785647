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
2. *automatic*: from frame ``settle + window - 1`` of the stream on (defaults: 0.5 s settling
   after the filters initialise, then the 0.5 s ``Options.pose.reset_window_s`` window, i.e.
   1.0 s into the stream), at the first frame whose window is still — no IMU turned more than
   :data:`STILL_DEG` during it (:func:`window_motion`, the check a manual Reset Zero reports) —
   averaged over that window; while the subject moves it waits (:attr:`PoseCalibrator.waiting`).
   An explicit capture before it cancels it;
3. *on request* (Reset Zero pressed, a recorded Reset Zero replayed, ``zero_at`` frames): at
   the next frame, averaged over the window that ends there;
4. *adopted* (a zero received over the network, the zero in force when a recording started):
   the given ``R0`` and ψ0 from the next frame on (:meth:`PoseCalibrator.adopt`).

Each capture is a :class:`Zero`, which also says where it came from, its window and the motion
measured during it (:meth:`Zero.change`: what the recording stores).

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
from bpms.io.event_types import ResetZero
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


#: A window is still when no IMU's filter attitude turned more than this during it, deg.
STILL_DEG = 5.0


def window_motion(R_window: np.ndarray) -> tuple[float, int]:
    """(deg, IMU): the largest rotation of one IMU's DCM away from its first frame over the
    window ``R_window[W, 18, 3, 3]``, and which IMU (-1 when no IMU has data)."""
    deg = _motions(np.moveaxis(np.asarray(R_window, dtype=np.float64), 0, -1)[None])[0]
    if not np.isfinite(deg).any():
        return 0.0, -1
    imu = int(np.nanargmax(deg))
    return float(deg[imu]), imu


def _motions(windows: np.ndarray) -> np.ndarray:
    """``[C, 18]`` deg: per window ``windows[C, 18, 3, 3, W]`` (frames last) and IMU, the
    largest rotation away from the window's first frame (NaN: no data)."""
    first = windows[..., 0]
    trace = np.einsum("ciab,ciabw->ciw", first, windows)
    angle = np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))
    with np.errstate(invalid="ignore"):
        return np.fmax.reduce(angle, axis=-1)


@dataclass
class Zero:
    """One capture: ``R0[18, 3, 3]``, heading ``yaw0`` rad, and ``offset = R0^T Rz(ψ0)``;
    ``frame`` its stream frame index, ``source`` (:data:`bpms.io.session_events.ZERO_SOURCES`),
    ``window`` frames averaged, ``motion_deg`` / ``motion_imu`` the largest rotation of one IMU
    during the window (:func:`window_motion`), ``waited`` frames the automatic capture waited
    for a still pose, ``heading`` where ψ0 came from."""

    R0: np.ndarray
    yaw0: float
    frame: int
    source: str = "automatic"
    window: int = 1
    motion_deg: float = 0.0
    motion_imu: int = -1
    waited: int = 0
    heading: str = "hip"

    @cached_property
    def offset(self) -> np.ndarray:
        # once per capture, not once per frame (a capture is never changed after it is made)
        return np.swapaxes(self.R0, -1, -2) @ rot_z(self.yaw0)

    @property
    def moved(self) -> bool:
        """The subject moved during the window (more than :data:`STILL_DEG`)."""
        return self.motion_deg > STILL_DEG

    def change(self, source: str | None = None) -> ResetZero:
        """What a recording stores of this capture: the ``reset_zero`` event
        (:class:`bpms.io.event_types.ResetZero`), as made here or under another ``source``
        (``in force``: the zero in force when logging started)."""
        return ResetZero(source or self.source, int(self.window), self.R0, float(self.yaw0),
                         self.heading, round(float(self.motion_deg), 3), int(self.motion_imu),
                         bool(self.moved), int(self.waited))


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
                 hip: int = HIP_IMU, heading: str = "hip", source: str = "automatic") -> Zero:
    """A capture from the DCMs ``R_window[W, 18, 3, 3]`` (see the module docstring);
    ``heading``: where ψ0 comes from (:func:`body_heading`)."""
    R0 = average_dcm(R_window)
    missing = ~np.isfinite(R0).all(axis=(-1, -2))
    if previous is not None:
        R0[missing] = previous.R0[missing]
    yaw0 = body_heading(R0, heading, hip)
    if yaw0 is None:
        yaw0 = previous.yaw0 if previous is not None else 0.0
    moved, imu = window_motion(R_window)
    return Zero(R0, yaw0, frame, source, len(R_window), moved, imu, 0, heading)


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
    capture window starts; ``auto`` enables the automatic capture, ``provisional`` (default:
    as ``auto``) the provisional one. Changes to both take effect at :meth:`restart`.
    """

    def __init__(self, window: int = 25, settle: int = 25, auto: bool = True,
                 hip: int = HIP_IMU, heading: str = "hip",
                 provisional: bool | None = None) -> None:
        self.window = max(1, int(window))
        self.settle = max(0, int(settle))
        self.auto = auto
        self.provisional = auto if provisional is None else provisional
        self.hip = hip
        self.heading = heading
        self.restart()

    def restart(self, origin: int = 0) -> None:
        """A new stream: forget the zero and the frame count (auto captures run again);
        ``origin``: the processor's frame number of the stream's first frame (captures'
        :attr:`Zero.frame` count from the processor's first frame)."""
        self.zero: Zero | None = None
        self.origin = int(origin)
        self.frames = 0  # frames seen in this stream
        # the last window-1 frames of R, a ring: frame by frame costs one copy of a frame
        self._ring: np.ndarray | None = None
        self._held = 0  # frames in the ring
        self._next = 0  # where the next frame goes (the oldest, once the ring is full)
        self._provisional_done = False
        self._fallback_provisional = False
        self._auto_pending = self.auto
        #: While the automatic capture waits for a still pose: (deg, IMU) of the last window.
        self.waiting: tuple[float, int] | None = None
        self._pending: list[tuple] = []  # captures asked for at the next frame, in order
        self.captures: list[Zero] = []
        #: Index into the last :meth:`apply`'s batch of its first frame with a zero in force
        #: (its length when none had one).
        self.zeroed_from = 0

    def request(self, source: str = "manual", window: int | None = None) -> None:
        """Reset Zero pressed: capture at the next frame over the window ending there
        (``window`` frames, default :attr:`window`)."""
        self._pending.append(("capture", source, self.window if window is None else
                              max(1, int(window))))

    def adopt(self, R0: np.ndarray, yaw0: float, source: str = "network",
              window: int = 1, motion: tuple[float, int] = (0.0, -1)) -> None:
        """Use a zero made elsewhere (``R0[18, 3, 3]``, ψ0 rad) from the next frame on; an IMU
        with no data in ``R0`` keeps its present zero."""
        self._pending.append(("adopt", source, int(window), np.array(R0, dtype=np.float64),
                              float(yaw0), motion))

    def fall_back(self) -> None:
        """A recorded capture is lost (its record damaged): the automatic capture runs again
        from the next frame, at the first still window (after the settling time when the
        stream has just started), preceded by the provisional one-frame capture when no zero
        is in force yet."""
        self._auto_pending = True
        self.waiting = None
        if self.zero is None and not self._pending:
            self._provisional_done = False
            self._fallback_provisional = True

    @property
    def auto_frame(self) -> int:
        """Stream frame index from which the automatic capture may happen."""
        return self.settle + self.window - 1

    def state_text(self, dt: float = 0.02) -> str:
        """The Reset Zero in force, for labels: ``waiting for a still pose (moved 12.0° on
        IMU 6)``, ``manual at 10.32 s`` (the processor's stream time), or ``none yet``."""
        waiting = self.waiting
        if waiting is not None:
            return f"waiting for a still pose (moved {waiting[0]:.1f}° on IMU {waiting[1]})"
        zero = self.zero
        if zero is None:
            return "none yet"
        return f"{zero.source} at {zero.frame * dt:.2f} s"

    @property
    def auto_pending(self) -> bool:
        """The automatic capture has not happened yet (and was not cancelled)."""
        return self._auto_pending

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
        self._next = (self._next + n) % keep
        self._held = min(self._held + n, keep)

    def _window_ending_at(self, R: np.ndarray, k: int, window: int | None = None
                          ) -> np.ndarray:
        """The last ``window`` frames up to batch frame ``k``, reaching into earlier batches
        (at most ``self.window`` frames back)."""
        lo = k - (self.window if window is None else min(window, self.window)) + 1
        earlier = None if lo >= 0 else self._buffer
        if earlier is None:
            return R[max(lo, 0):k + 1]
        return np.concatenate([earlier[max(len(earlier) + lo, 0):], R[:k + 1]])

    def _still_frame(self, R: np.ndarray, lo: int, hi: int) -> int | None:
        """The first batch frame in ``lo .. hi-1`` whose window is still (None: none;
        :attr:`waiting` then holds the motion of the last window looked at)."""
        if hi <= lo:
            return None
        earlier = self._buffer
        full = R if earlier is None else np.concatenate([earlier, R])
        shift = len(full) - len(R)
        w = self.window
        views = np.lib.stride_tricks.sliding_window_view(full, w, axis=0)  # [.., 18, 3, 3, w]
        for a in range(lo, hi, 256):
            b = min(hi, a + 256)
            starts = np.arange(a, b) + shift - w + 1
            motion = _motions(views[np.maximum(starts, 0)])
            worst = np.where(np.isfinite(motion), motion, 0.0)
            still = worst.max(axis=1) <= STILL_DEG
            if still.any():
                self.waiting = None
                return a + int(np.argmax(still))
            last = worst[-1]
            self.waiting = (float(last.max()), int(np.argmax(last)))
        return None

    def apply(self, R: np.ndarray, zero_at: Iterable[int] = ()) -> np.ndarray:
        """Segment orientations ``C[N, 18, 3, 3]`` of the next N frames' DCMs
        ``R[N, 18, 3, 3]``; ``zero_at``: extra capture frames, indices into this batch."""
        R = np.asarray(R, dtype=np.float64)
        n = len(R)
        first = self.frames + self.origin  # the processor's frame number of R[0]
        zeroed = self.zero is not None
        ops: dict[int, list[tuple]] = {}
        for k in zero_at:
            if 0 <= int(k) < n:
                ops.setdefault(int(k), []).append(("capture", "re-analysis", self.window))
        if self._pending and n:
            ops[0] = [*self._pending, *ops.get(0, [])]
            self._pending = []
        if (self.provisional or self._fallback_provisional) and not self._provisional_done:
            ok = np.isfinite(R[:, :, 0, 0]).all(axis=1)
            if ok.any():
                k = int(np.argmax(ok))
                self._provisional_done = True
                if k not in ops:  # an explicit capture at the same frame stands for it
                    ops[k] = [("provisional",)]
        if self._auto_pending and n:
            explicit = [k for k, todo in ops.items() if todo[0][0] != "provisional"]
            stop = min(explicit) if explicit else n
            found = self._still_frame(R, max(self.auto_frame - self.frames, 0), stop)
            if found is not None:
                ops.setdefault(found, []).append(("automatic",))
            if found is not None or explicit:
                self._auto_pending = False
                self.waiting = None
        self.zeroed_from = 0 if zeroed else min(ops, default=n)
        if not ops:  # most frames: no capture in this batch
            C = segment_orientations(R, self.zero)
        else:
            C = np.empty_like(R)
            start = 0
            for k in sorted(ops):
                C[start:k] = segment_orientations(R[start:k], self.zero)
                for op in ops[k]:
                    self.zero = self._capture(op, R, k, first)
                    self.captures.append(self.zero)
                start = k
            C[start:] = segment_orientations(R[start:], self.zero)
        self._remember(R)
        self.frames += n
        return C

    def _capture(self, op: tuple, R: np.ndarray, k: int, first: int) -> Zero:
        kind = op[0]
        if kind == "adopt":
            _, source, window, R0, yaw0, motion = op
            if self.zero is not None:
                missing = ~np.isfinite(R0).all(axis=(-1, -2))
                R0[missing] = self.zero.R0[missing]
            return Zero(R0, yaw0, first + k, source, window, motion[0], motion[1], 0,
                        self.heading)
        if kind == "provisional":
            window, source = R[k:k + 1], "provisional"
        elif kind == "automatic":
            window, source = self._window_ending_at(R, k), "automatic"
        else:  # ("capture", source, window)
            window, source = self._window_ending_at(R, k, op[2]), op[1]
        zero = capture_zero(window, self.zero, first + k, self.hip, self.heading, source)
        if kind == "automatic":
            zero.waited = first + k - self.origin - self.auto_frame
        return zero
