"""The body's per-frame numbers in one compiled pass: segment Euler angles, joint angles and
joint positions from segment orientations ``C[N, 18, 3, 3]``.

Whole recordings and live frames run these same kernels (a live frame is N = 1), so a frame
gives the same numbers bit for bit whichever way it was filtered; short recordings without
numba run their numpy twins (:mod:`bpms.filter.twins`), which give the same numbers as well.
The joint and body tables come from :mod:`bpms.filter.joints` and
:mod:`bpms.filter.body_model`, which define what is computed; this module only holds the loops.

Formulas (docs/joint-angles.md, docs/body-model.md):

- Euler angles of a DCM: roll = atan2(C21, C22), pitch = −asin(C20 clipped to [−1, 1]),
  yaw = atan2(C10, C00), radians;
- hinge flexion = acos of the cosine between the two segments' axes (clipped to [−1, 1]);
- ball joints: the Euler angles of ``C_staticᵀ C_dynamic``;
- joint positions: each point = its parent + ``C[imu] @ (direction × length)``, pelvis at the
  origin; with ``on_ground`` the whole figure is shifted along z (down) so that the lowest foot
  point is at z = 0.

Non-finite orientations give NaN where they enter; nothing raises.
"""

from __future__ import annotations

import math
from contextlib import AbstractContextManager, nullcontext

from bpms.filter.kernels import TWIN_FRAME_BUDGET, kernel, numba_loaded, twins, twins_active


def body_context(frames: int) -> AbstractContextManager[None]:
    """How ``frames`` frames of body numbers run: the numpy twins inside a caller's twins block,
    or while numba is not loaded and the work is small (so drawing a figure or filtering a
    short recording never imports numba); otherwise compiled. The numbers are the same."""
    if twins_active():
        return nullcontext()
    if not numba_loaded() and frames <= TWIN_FRAME_BUDGET:
        return twins(True)
    return nullcontext()


@kernel
def row_times(M, a, v):
    """Row ``a`` of the 3 × 3 matrix ``M`` times the vector ``v``, summed left to right (the
    twins repeat this order)."""
    return (M[a, 0] * v[0] + M[a, 1] * v[1]) + M[a, 2] * v[2]


@kernel(twin="bpms.filter.twins:segment_euler")
def segment_euler(C, out):
    """``out[k, i]`` = (roll, pitch, yaw) rad of ``C[k, i]`` (``[N, n, 3, 3]`` → ``[N, n, 3]``)."""
    for k in range(C.shape[0]):
        for i in range(C.shape[1]):
            s = C[k, i, 2, 0]
            if s > 1.0:
                s = 1.0
            elif s < -1.0:
                s = -1.0
            out[k, i, 0] = math.atan2(C[k, i, 2, 1], C[k, i, 2, 2])
            out[k, i, 1] = -math.asin(s)
            out[k, i, 2] = math.atan2(C[k, i, 1, 0], C[k, i, 0, 0])


@kernel(twin="bpms.filter.twins:joint_angle_frames")
def joint_angle_frames(C, hinge, hinge_axes, ball, signs, out):
    """Joint angles ``out[N, H + 3B]`` rad from ``C[N, 18, 3, 3]``.

    hinge ``[H, 2]`` (proximal, distal IMU) with ``hinge_axes[H, 2, 3]`` their segment axes;
    ball ``[B, 2]`` (static, dynamic IMU); ``signs[H + 3B]`` multiplies each column (the
    convention). Columns: H flexions, then roll, pitch, yaw of each ball joint."""
    n_hinge = hinge.shape[0]
    for k in range(C.shape[0]):
        for j in range(n_hinge):
            p = hinge[j, 0]
            d = hinge[j, 1]
            u0 = row_times(C[k, p], 0, hinge_axes[j, 0])
            u1 = row_times(C[k, p], 1, hinge_axes[j, 0])
            u2 = row_times(C[k, p], 2, hinge_axes[j, 0])
            v0 = row_times(C[k, d], 0, hinge_axes[j, 1])
            v1 = row_times(C[k, d], 1, hinge_axes[j, 1])
            v2 = row_times(C[k, d], 2, hinge_axes[j, 1])
            c = ((u0 * v0 + u1 * v1) + u2 * v2) / math.sqrt(
                ((u0 * u0 + u1 * u1) + u2 * u2) * ((v0 * v0 + v1 * v1) + v2 * v2))
            if c > 1.0:
                c = 1.0
            elif c < -1.0:
                c = -1.0
            out[k, j] = math.acos(c) * signs[j]
        for b in range(ball.shape[0]):
            s = ball[b, 0]
            d = ball[b, 1]
            # rel = C_sᵀ C_d: rel[a, c] = Σ_m C_s[m, a] C_d[m, c]; only five entries are needed
            r00 = (C[k, s, 0, 0] * C[k, d, 0, 0] + C[k, s, 1, 0] * C[k, d, 1, 0]) \
                + C[k, s, 2, 0] * C[k, d, 2, 0]
            r10 = (C[k, s, 0, 1] * C[k, d, 0, 0] + C[k, s, 1, 1] * C[k, d, 1, 0]) \
                + C[k, s, 2, 1] * C[k, d, 2, 0]
            r20 = (C[k, s, 0, 2] * C[k, d, 0, 0] + C[k, s, 1, 2] * C[k, d, 1, 0]) \
                + C[k, s, 2, 2] * C[k, d, 2, 0]
            r21 = (C[k, s, 0, 2] * C[k, d, 0, 1] + C[k, s, 1, 2] * C[k, d, 1, 1]) \
                + C[k, s, 2, 2] * C[k, d, 2, 1]
            r22 = (C[k, s, 0, 2] * C[k, d, 0, 2] + C[k, s, 1, 2] * C[k, d, 1, 2]) \
                + C[k, s, 2, 2] * C[k, d, 2, 2]
            if r20 > 1.0:
                r20 = 1.0
            elif r20 < -1.0:
                r20 = -1.0
            col = n_hinge + 3 * b
            out[k, col] = math.atan2(r21, r22) * signs[col]
            out[k, col + 1] = -math.asin(r20) * signs[col + 1]
            out[k, col + 2] = math.atan2(r10, r00) * signs[col + 2]


@kernel(twin="bpms.filter.twins:joint_position_frames")
def joint_position_frames(C, imus, parents, vectors, feet, on_ground, out):
    """Joint positions ``out[N, P + 1, 3]`` m (NED) from ``C[N, 18, 3, 3]``.

    Point 0 is the pelvis at the origin; point ``p + 1`` = point ``parents[p]`` +
    ``C[imus[p]] @ vectors[p]`` (``vectors[P, 3]`` m, segment axes; parents come first).
    ``on_ground``: subtract the largest z (z down: the lowest) of the points ``feet`` from every
    z (NaN when one of them is NaN)."""
    for k in range(C.shape[0]):
        out[k, 0, 0] = 0.0
        out[k, 0, 1] = 0.0
        out[k, 0, 2] = 0.0
        for p in range(imus.shape[0]):
            i = imus[p]
            q = parents[p]
            for a in range(3):
                out[k, p + 1, a] = out[k, q, a] + row_times(C[k, i], a, vectors[p])
        if on_ground:
            lowest = out[k, feet[0], 2]
            for f in range(1, feet.shape[0]):
                z = out[k, feet[f], 2]
                if z > lowest or z != z:
                    lowest = z
            for p in range(out.shape[1]):
                out[k, p, 2] = out[k, p, 2] - lowest
