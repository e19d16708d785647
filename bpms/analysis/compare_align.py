"""Aligning a BPMS recording with an optical export in time and in space (``bpms compare``).

Frames (docs/compare.md): the BPMS orientation ``R(t)`` of an IMU maps its filter frame to the
world NED frame; the optical orientation ``Q(t)`` of its marker cluster maps the cluster frame
to the optical system's world frame. Both see the same rigid segment, so

    R(t) ≈ W · Q(t) · S

with two constant rotations: ``S`` IMU frame → cluster frame, ``W`` optical world → NED.

- **Time.** :func:`estimate_offset`: the lag between the two clocks by cross-correlation of the
  angular-rate magnitudes ``|ω|`` (both from consecutive orientations, so both are the same
  quantity), refined to a fraction of a sample by a parabola through the peak. Convention:
  the optical sample at optical time ``t_o`` belongs to BPMS stream time ``t_o + offset``.
- **Resampling.** :func:`resample_optical`: the optical orientation at each BPMS time,
  interpolated on the geodesic between the two optical samples around it — only when both are
  valid; a time next to a missing (occluded) sample stays a gap (NaN) and is counted.
- **Space.** :func:`align_frames`: ``S`` from the angular rates (``ω_IMU = Sᵀ ω_cluster``, the
  Wahba problem solved by SVD, as ``scipy.spatial.transform.Rotation.align_vectors``); ``W``
  either from the IMU's own references (``"sensors"``: gravity from the accelerometer, north
  from the magnetometer's horizontal component, both carried into the optical world through
  ``Q·S``, as BROAD's alignment, Laidig et al. 2021, appendix C) or by least squares on the
  orientations (``"orientation"``: ``W`` and ``S`` alternately, each a Wahba problem). How well
  each is determined: the two halves of the window estimated apart (their angle), the rate
  scatter's conditioning, the residuals.

Only numpy: one implementation of the rotation maths here, vectorised over samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bpms.filter.rotations import rotation_vector

ALIGN_MODES = ("sensors", "orientation", "none")


def exp_map(v: np.ndarray) -> np.ndarray:
    """Rotation matrices ``[..., 3, 3]`` of rotation vectors ``v[..., 3]`` (rad), Rodrigues."""
    v = np.asarray(v, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1)
    safe = np.where(angle > 1e-12, angle, 1.0)
    k = v / safe[..., None]
    K = np.zeros((*v.shape[:-1], 3, 3))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K[..., 1, 0], K[..., 2, 0], K[..., 2, 1] = k[..., 2], -k[..., 1], k[..., 0]
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    small = angle <= 1e-12
    if np.any(small):
        R[small] = np.eye(3)
    return R


def project_so3(M: np.ndarray) -> np.ndarray:
    """The rotation nearest (Frobenius) to ``M[3, 3]``: the Wahba/Kabsch solution of
    ``argmax_R trace(Rᵀ M)``."""
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def angle_deg(R: np.ndarray) -> np.ndarray:
    """Rotation angle(s) of ``R[..., 3, 3]`` in degrees."""
    return np.degrees(np.linalg.norm(rotation_vector(R), axis=-1))


RATE_BASE_S = 0.1  # angular rates are taken over this time: marker noise divided by ~5 at 50 Hz


def rate_step(dt: float) -> int:
    """Samples between the two orientations of an angular rate (:data:`RATE_BASE_S`)."""
    return max(1, round(RATE_BASE_S / dt))


def body_rates(R: np.ndarray, dt: float, step: int = 1) -> np.ndarray:
    """``[N-step, 3]`` rad/s mean angular velocity in body axes from ``R[k]`` to
    ``R[k + step]`` (``R[N, 3, 3]``, NaN where either is missing). For ``R ≈ W Q S`` the
    rates of R and Q relate exactly by ``ω_R = Sᵀ ω_Q``, whatever the step."""
    rel = np.swapaxes(R[:-step], -1, -2) @ R[step:]
    return rotation_vector(rel) / (step * dt)


# -- time --------------------------------------------------------------------------------------
def rate_magnitude_on_grid(t: np.ndarray, R: np.ndarray, grid_dt: float
                           ) -> tuple[float, np.ndarray]:
    """(start time, ``|ω|`` rad/s) of orientations ``R[N, 3, 3]`` at times ``t[N]`` s, put on a
    grid of step ``grid_dt`` from the first midpoint; NaN where a sample is missing."""
    step = rate_step(float(np.median(np.diff(t))))
    w = np.linalg.norm(body_rates(R, 1.0, step), axis=-1) / (t[step:] - t[:-step])
    mid = 0.5 * (t[:-step] + t[step:])
    grid = np.arange(mid[0], mid[-1] + 1e-9, grid_dt)
    k = np.clip(np.searchsorted(mid, grid) - 1, 0, len(mid) - 2)
    f = (grid - mid[k]) / (mid[k + 1] - mid[k])
    out = (1 - f) * w[k] + f * w[k + 1]  # NaN next to a gap stays NaN
    return float(grid[0]), out


def _xcorr(a: np.ndarray, b: np.ndarray, size: int, na: int, nb: int) -> np.ndarray:
    """``c[k] = Σ a[m + k] b[m]`` for lags ``-(nb - 1) .. na - 1`` (FFT)."""
    c = np.fft.irfft(np.fft.rfft(a, size) * np.conj(np.fft.rfft(b, size)), size)
    return np.concatenate([c[size - (nb - 1):], c[:na]]) if nb > 1 else c[:na]


def gyro_magnitude_on_grid(t: np.ndarray, gyr: np.ndarray, dt: float) -> tuple[float, np.ndarray]:
    """(start time, ``|ω|`` rad/s) of gyro samples ``gyr[N, 3]`` at stream times ``t[N]``
    (step ``dt``; sample k the mean rate over ``[t[k-1], t[k]]``), averaged over
    :data:`RATE_BASE_S` as :func:`rate_magnitude_on_grid` does with orientations."""
    step = rate_step(dt)
    cs = np.concatenate([np.zeros((1, 3)), np.cumsum(np.asarray(gyr, np.float64), axis=0)])
    mean = (cs[step + 1:] - cs[1:-step]) / step  # samples k+1 .. k+step: over [t_k, t_k+step]
    return float(t[0] + 0.5 * step * dt), np.linalg.norm(mean, axis=-1)


def estimate_offset(t_b: np.ndarray, mag_b: np.ndarray, t_o: np.ndarray, mag_o: np.ndarray,
                    dt: float, min_overlap: int = 100) -> tuple[float, float]:
    """(offset s, peak correlation coefficient) with ``t_bpms = t_optical + offset``, from the
    rate magnitudes ``mag_b`` (grid starting ``t_b`` s, step ``dt``) and ``mag_o`` (grid
    starting ``t_o``). For every lag the Pearson correlation over the samples both hold
    (gaps left out; lags overlapping by fewer than ``min_overlap`` samples, or a third of the
    shorter signal, are not considered); the best lag is refined by a parabola through the peak
    and its two neighbours. ValueError when no lag overlaps enough."""
    mx, my = np.isfinite(mag_b), np.isfinite(mag_o)
    x, y = np.where(mx, mag_b, 0.0), np.where(my, mag_o, 0.0)
    na, nb = len(x), len(y)
    size = 1 << (na + nb - 2).bit_length()
    fx, fy = mx.astype(float), my.astype(float)
    n = np.rint(_xcorr(fx, fy, size, na, nb))
    sxy, sx, sy = _xcorr(x, y, size, na, nb), _xcorr(x, fy, size, na, nb), _xcorr(fx, y, size,
                                                                                 na, nb)
    sxx, syy = _xcorr(x * x, fy, size, na, nb), _xcorr(fx, y * y, size, na, nb)
    need = max(3, min(min_overlap, int(min(mx.sum(), my.sum()) // 3)))
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = sxy - sx * sy / n
        var = (sxx - sx * sx / n) * (syy - sy * sy / n)
        r = np.where((n >= need) & (var > 0), cov / np.sqrt(np.maximum(var, 1e-300)), -np.inf)
    if not np.isfinite(r).any():
        raise ValueError("the two recordings do not overlap in time at any offset")
    k = int(np.argmax(r))
    frac = 0.0
    if 0 < k < len(r) - 1 and np.isfinite(r[k - 1]) and np.isfinite(r[k + 1]):
        a, b, d = r[k - 1], r[k], r[k + 1]
        denom = a - 2 * b + d
        if denom < 0:
            frac = float(np.clip(0.5 * (a - d) / denom, -0.5, 0.5))
    lag = k - (nb - 1) + frac
    return t_b - t_o + lag * dt, float(r[k])


def resample_optical(t_query: np.ndarray, t_opt: np.ndarray, Q: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(orientations ``[M, 3, 3]`` at optical times ``t_query[M]``, inside ``[M]`` bool,
    gap ``[M]`` bool). ``t_opt[N]`` increasing optical times, ``Q[N, 3, 3]`` (NaN = missing).
    Inside the optical span, a query between two valid samples is interpolated on the geodesic
    between them; one next to a missing sample is a gap (NaN), never bridged."""
    inside = (t_query >= t_opt[0]) & (t_query <= t_opt[-1])
    i = np.clip(np.searchsorted(t_opt, t_query, side="right") - 1, 0, len(t_opt) - 2)
    f = np.clip((t_query - t_opt[i]) / (t_opt[i + 1] - t_opt[i]), 0.0, 1.0)
    Q0, Q1 = Q[i], Q[i + 1]
    ok0 = np.isfinite(Q0).all(axis=(1, 2))
    ok1 = np.isfinite(Q1).all(axis=(1, 2))
    valid = inside & ((ok0 & ok1) | (ok0 & (f < 1e-9)) | (ok1 & (f > 1 - 1e-9)))
    out = np.full((len(t_query), 3, 3), np.nan)
    both = valid & ok0 & ok1
    rel = rotation_vector(np.swapaxes(Q0[both], -1, -2) @ Q1[both])
    out[both] = Q0[both] @ exp_map(rel * f[both, None])
    only0, only1 = valid & ~both & ok0, valid & ~both & ok1
    out[only0], out[only1] = Q0[only0], Q1[only1]
    return out, inside, inside & ~valid


# -- space -------------------------------------------------------------------------------------
@dataclass
class Alignment:
    """One segment's frame alignment: ``R ≈ W Q S``.

    S: IMU → cluster; W: optical world → NED; mode: how W was found (:data:`ALIGN_MODES`);
    s_split_deg / w_split_deg: angle between the estimates from the window's two halves (how
    well each is determined; NaN when not estimated); rate_condition: smallest / largest
    singular value of the angular-rate scatter (near 0: rotation about one axis only, S is
    poorly determined); rate_residual_dps: RMS of ``ω_cluster − S ω_IMU``, deg/s; samples:
    sample pairs used.
    """

    S: np.ndarray
    W: np.ndarray
    mode: str
    s_split_deg: float = float("nan")
    w_split_deg: float = float("nan")
    rate_condition: float = float("nan")
    rate_residual_dps: float = float("nan")
    samples: int = 0
    s_sd_deg: float = float("nan")


def _s_from_rates(w_b: np.ndarray, w_o: np.ndarray, bias: bool = False
                  ) -> np.ndarray:
    """argmin over S of Σ|ω_o − S (ω_b − b)|² (SVD, Kabsch); with ``bias`` a constant gyro
    bias b is estimated with it (alternately, a few rounds)."""
    S = project_so3(w_o.T @ w_b)
    if bias:
        for _ in range(5):
            b = np.mean(w_b - w_o @ S, axis=0)
            S = project_so3(w_o.T @ (w_b - b))
    return S


def _w_from_sensors(Q: np.ndarray, S: np.ndarray, acc: np.ndarray, mag: np.ndarray
                    ) -> np.ndarray:
    """W from the mean gravity direction and the field's mean horizontal direction, both
    carried into the optical world (``Q S a``). Accelerometer samples whose norm strays more
    than 5 % from its median (linear acceleration) and field samples whose norm or dip stray
    more than 5 % / 5° from their medians (a local disturbance) are left out, unless that
    would leave too few."""
    QS = Q @ S
    norm_a = np.linalg.norm(acc, axis=-1)
    calm = np.abs(norm_a / np.median(norm_a) - 1) < 0.05  # little linear acceleration
    if calm.mean() < 0.2:
        calm = np.ones(len(acc), dtype=bool)
    g = np.einsum("nij,nj->ni", QS[calm], acc[calm] / norm_a[calm, None])
    g = g.mean(axis=0)
    g /= np.linalg.norm(g)
    down = np.array([0.0, 0.0, 1.0])
    axis = np.cross(g, down)
    W1 = exp_map(axis / max(np.linalg.norm(axis), 1e-300)
                 * np.arctan2(np.linalg.norm(axis), g @ down))
    m = np.einsum("ij,njk,nk->ni", W1, QS, mag)
    norm = np.linalg.norm(m, axis=-1)
    dip = np.arcsin(np.clip(m[:, 2] / norm, -1, 1))
    ok = ((np.abs(norm / np.median(norm) - 1) < 0.05)
          & (np.abs(dip - np.median(dip)) < np.radians(5.0)))
    if ok.mean() < 0.5:
        ok = np.ones(len(m), dtype=bool)
    delta = np.angle(np.exp(1j * np.arctan2(m[ok, 1], m[ok, 0])).mean())
    return exp_map(np.array([0.0, 0.0, -delta])) @ W1


def _w_from_orientations(R: np.ndarray, Q: np.ndarray, S: np.ndarray) -> np.ndarray:
    return project_so3(np.sum(R @ np.swapaxes(Q @ S, -1, -2), axis=0))


def _estimate(R: np.ndarray, Q: np.ndarray, w_b: np.ndarray, w_o: np.ndarray, mode: str,
              acc: np.ndarray | None, mag: np.ndarray | None, gyro: bool
              ) -> tuple[np.ndarray, np.ndarray]:
    S = _s_from_rates(w_b, w_o, bias=gyro)
    if mode == "sensors":
        return S, _w_from_sensors(Q, S, acc, mag)
    W = _w_from_orientations(R, Q, S)
    for _ in range(20):  # alternating least squares on the orientations
        S_new = project_so3(np.sum(np.swapaxes(W @ Q, -1, -2) @ R, axis=0))
        W = _w_from_orientations(R, Q, S_new)
        done = angle_deg(S_new @ S.T) < 1e-6
        S = S_new
        if done:
            break
    return S, W


def align_frames(R: np.ndarray, Q: np.ndarray, dt: float, mode: str = "sensors",
                 acc: np.ndarray | None = None, mag: np.ndarray | None = None,
                 use: np.ndarray | None = None, gyr: np.ndarray | None = None) -> Alignment:
    """Estimate ``S`` and ``W`` of one segment from ``R[N, 3, 3]`` (BPMS, on its stream
    times) and ``Q[N, 3, 3]`` (optical resampled onto the same times, NaN = gap), over the
    samples ``use[N]`` (default all valid). ``acc`` / ``mag`` ``[N, 3]``: the IMU's calibrated
    accelerometer (gravity direction) and magnetometer in its filter frame, for ``"sensors"``;
    ``gyr[N, 3]`` rad/s its gyro (sample k the mean rate over ``[t[k-1], t[k]]``): S then comes
    from the measured rates with a gyro bias (as BROAD's alignment), else from the rates of R.
    Raises ValueError when too few valid samples remain."""
    if mode not in ALIGN_MODES:
        raise ValueError(f"alignment {mode!r}: one of {', '.join(ALIGN_MODES)}")
    if mode == "none":
        return Alignment(np.eye(3), np.eye(3), mode)
    if mode == "sensors" and (acc is None or mag is None):
        raise ValueError("the 'sensors' alignment needs the recording's raw sensor values "
                         "(a raw recording, not a filtered file); use --align orientation")
    ok = np.isfinite(R).all(axis=(1, 2)) & np.isfinite(Q).all(axis=(1, 2))
    if use is not None:
        ok &= use
    if mode == "sensors":
        ok &= np.isfinite(acc).all(axis=1) & np.isfinite(mag).all(axis=1)
    step = rate_step(dt)
    pair = ok[:-step] & ok[step:]
    idx = np.flatnonzero(pair)
    if len(idx) < 20:
        raise ValueError(f"only {len(idx)} valid sample pairs to align the frames with")
    if gyr is not None:  # mean of samples k+1 .. k+step: the mean rate over [t_k, t_k+step]
        cs = np.concatenate([np.zeros((1, 3)), np.cumsum(np.nan_to_num(gyr), axis=0)])
        w_b = ((cs[step + 1:] - cs[1:-step]) / step)[idx]
    else:
        w_b = body_rates(R, dt, step)[idx]
    w_o = body_rates(Q, dt, step)[idx]
    k = np.flatnonzero(ok)

    def fit(sel_pairs: np.ndarray, sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _estimate(R[sel], Q[sel], w_b[sel_pairs], w_o[sel_pairs], mode,
                         None if acc is None else acc[sel], None if mag is None else mag[sel],
                         gyr is not None)

    S, W = fit(np.arange(len(idx)), k)
    if not (np.isfinite(S).all() and np.isfinite(W).all()):
        raise ValueError("the sensors give no usable gravity or north (magnetometer or "
                         "accelerometer missing?); use --align orientation")
    half_p, half_k = len(idx) // 2, len(k) // 2
    S1, W1 = fit(np.arange(half_p), k[:half_k])
    S2, W2 = fit(np.arange(half_p, len(idx)), k[half_k:])
    sv = np.linalg.svd(w_o.T @ w_o, compute_uv=False)
    resid = w_o - (w_b - np.mean(w_b - w_o @ S, axis=0) * (gyr is not None)) @ S.T
    sigma2 = float(np.mean(np.sum(resid**2, axis=1))) / 3.0
    info = np.sum(np.sum(w_o**2, axis=1)) * np.eye(3) - w_o.T @ w_o
    with np.errstate(divide="ignore"):
        ev = np.linalg.eigvalsh(info)
        sd = float(np.degrees(np.sqrt(sigma2 / ev[0]))) if ev[0] > 0 else float("inf")
    return Alignment(S, W, mode, float(angle_deg(S1 @ S2.T)), float(angle_deg(W1 @ W2.T)),
                     float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0,
                     float(np.degrees(np.sqrt(3 * sigma2))), len(idx), sd)
