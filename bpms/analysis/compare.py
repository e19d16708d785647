"""``bpms compare``: a BPMS recording against an optical motion-capture export (docs/compare.md).

:func:`compare` reads both (the recording through the one door, the export through
:mod:`bpms.analysis.mocap_import`), pairs optical bodies with BPMS segments (:mod:`.compare_map`),
aligns the clocks and the frames (:mod:`.compare_align`) and measures the errors
(:mod:`.compare_stats`). Inputs that cannot be compared raise :class:`CompareError` with a
one-line message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bpms.analysis.compare_align import (
    Alignment,
    align_frames,
    estimate_offset,
    gyro_magnitude_on_grid,
    rate_magnitude_on_grid,
    resample_optical,
)
from bpms.analysis.compare_map import CompareError, resolve_map
from bpms.analysis.compare_stats import JointStats, SegmentStats, joint_stats, segment_stats
from bpms.analysis.mocap_import import MocapExport, MocapFormatError, read_qualisys, read_vicon
from bpms.filter.joints import joint_angles
from bpms.filter.rotations import dcm_to_euler, quaternion_to_dcm
from bpms.io.frames import IMU_NAMES

__all__ = [
    "CompareError",
    "CompareResult",
    "Recording",
    "compare",
    "load_recording",
    "read_optical",
]

MIN_OVERLAP_S = 2.0
NO_MATCH_CORRELATION = 0.3  # below: the two files do not overlap in time (at any offset)
STILL_DPS = 10.0  # a pause: every mapped segment slower than this (optical) ...
STILL_S = 1.0     # ... for at least this long
PAUSE_RATE_S = 0.25  # the rates of the pause detection are taken over this time


@dataclass
class Recording:
    """What compare needs of a processed BPMS recording: stream times ``t[N]`` s (step
    ``dt``), ``R[N, 18, 3, 3]`` filter frame → NED, ``C`` segment orientations (NaN before
    Reset Zero), joint angles ``[N, 28]`` rad, and (raw recordings) calibrated accelerometer,
    magnetometer and gyro (rad/s) ``[N, 18, 3]`` in the filter frame."""

    t: np.ndarray
    dt: float
    R: np.ndarray
    C: np.ndarray
    joints: np.ndarray
    convention: str
    acc: np.ndarray | None = None
    mag: np.ndarray | None = None
    gyr: np.ndarray | None = None
    sources: str = ""


def load_recording(path: str | Path, opened=None) -> Recording:
    """Process a recording through the one door (``opened``: an already opened
    :class:`bpms.filter.door.OpenedRecording`, e.g. with the CLI's options)."""
    from bpms.filter.door import open_for_processing

    opened = opened or open_for_processing(path)
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("t", "R", "C", "J", "acc", "mag", "gyr")}
    convention = "isb"
    for chunk in opened.chunks():
        res = chunk.result
        convention = res.convention
        parts["t"].append(res.t)
        parts["R"].append(res.R)
        parts["C"].append(res.C)
        parts["J"].append(res.joint_angles)
        if chunk.raw is not None:
            acc, mag, gyr = opened.processor.calibrate(chunk.raw)
            parts["acc"].append(acc)
            parts["mag"].append(mag)
            parts["gyr"].append(gyr)
    if not parts["t"]:
        raise CompareError(f"{path}: the recording holds no frames")
    cat = {k: np.concatenate(v) if v else None for k, v in parts.items()}
    return Recording(cat["t"], float(opened.processor.options.filter.dt), cat["R"], cat["C"],
                     cat["J"], convention, cat["acc"], cat["mag"], cat["gyr"],
                     opened.sources_line())


def read_optical(path: str | Path) -> MocapExport:
    """A Vicon Nexus CSV (``.csv``) or Qualisys TSV (``.tsv``, ``.txt``) export; CompareError
    with the reader's one-line message otherwise."""
    path = Path(path)
    reader = read_vicon if path.suffix.lower() == ".csv" else read_qualisys
    try:
        export = reader(path)
    except MocapFormatError as exc:
        raise CompareError(str(exc)) from None
    rigid = {n: b for n, b in export.bodies.items() if b.quaternion is not None}
    if not rigid:
        raise CompareError(f"{path}: no rigid body with orientations (only markers)")
    return MocapExport(export.path, export.rate_hz, rigid)


@dataclass
class CompareResult:
    """Everything ``bpms compare`` reports (angles in degrees unless named otherwise).

    offset_s: ``t_bpms = t_optical + offset_s``; offset_source: ``"cross-correlation"`` or
    ``"given"``; correlation: the cross-correlation's peak coefficient (1 = identical shapes);
    pairs: (optical body, BPMS IMU index); alignments / segments per pair, in order; joints:
    every joint angle whose segments are all mapped; pauses: (start, end) s of the first and
    last still pause; t / errors: the per-sample series for the figures and the CSV.
    """

    recording: str
    optical: str
    optical_rate_hz: float
    dt: float
    offset_s: float
    offset_source: str
    correlation: float
    pairs: list[tuple[str, int]]
    alignments: list[Alignment]
    segments: list[SegmentStats]
    joints: list[JointStats]
    overlap_s: tuple[float, float]
    pauses: list[tuple[float, float]]
    t: np.ndarray
    segment_error_deg: np.ndarray  # [N, pairs] total error, NaN = gap / outside
    joint_bpms_deg: np.ndarray  # [N, joints]
    joint_optical_deg: np.ndarray
    #: ``[N, pairs, 3]`` roll, pitch, yaw (deg) of each segment after Reset Zero, by BPMS and
    #: by the aligned optical body (NaN = gap, outside, or no Reset Zero)
    segment_angles_bpms_deg: np.ndarray | None = None
    segment_angles_optical_deg: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)


def _dcm(track) -> np.ndarray:
    return quaternion_to_dcm(track.quaternion)


def _pauses(t: np.ndarray, Q: np.ndarray, dt: float) -> list[tuple[float, float]]:
    """The first and last still pause: every segment seen slower than STILL_DPS (optical)."""
    from bpms.analysis.compare_align import body_rates

    step = max(1, round(PAUSE_RATE_S / dt))
    rates = np.stack([np.degrees(np.linalg.norm(body_rates(Q[:, j], dt, step), axis=-1))
                      for j in range(Q.shape[1])], axis=1)
    with np.errstate(invalid="ignore"):  # a gap neither moves nor breaks a pause
        still = ~np.any(rates >= STILL_DPS, axis=1) & np.any(np.isfinite(rates), axis=1)
    runs, start = [], None
    for k, s in enumerate(np.append(still, False)):
        if s and start is None:
            start = k
        elif not s and start is not None:
            if (k - start) * dt >= STILL_S:
                runs.append((float(t[start]), float(t[k])))
            start = None
    if len(runs) < 2:
        return runs
    return [runs[0], runs[-1]]


def compare(rec: Recording, export: MocapExport, mapping: str | Path | None = None, *,
            offset_s: float | None = None, align: str = "sensors",
            window: tuple[float, float] | None = None,
            given: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
            recording_name: str = "") -> CompareResult:
    """Compare a processed recording with an optical export.

    mapping: a map file, or None for the default names (:mod:`.compare_map`); offset_s: the
    clock offset (s, ``t_bpms = t_optical + offset``) instead of the cross-correlation;
    align: :data:`~.compare_align.ALIGN_MODES`; window: (start, end) s of BPMS stream time the
    frame alignment uses (default: the whole overlap); given: per optical body the rotations
    ``(S, W)`` to use instead of estimating them."""
    pairs, unmapped = resolve_map(export, mapping)
    warnings = [f"optical bodies not compared (not in the map): {', '.join(unmapped)}"
                ] if unmapped else []
    dt = rec.dt
    Qs = [_dcm(export.bodies[name]) for name, _ in pairs]
    t_opt = export.bodies[pairs[0][0]].t
    if len(t_opt) < 3 or len(rec.t) < 3:
        raise CompareError("too few samples to compare (fewer than 3)")
    correlation = math.nan
    if offset_s is None:
        # the BPMS side from its gyros (the measurement, free of the filter's dynamics), or
        # from its orientations for a filtered file
        rb = [rate_magnitude_on_grid(rec.t, rec.R[:, imu], dt) if rec.gyr is None
              else gyro_magnitude_on_grid(rec.t, rec.gyr[:, imu], dt) for _, imu in pairs]
        ro = [rate_magnitude_on_grid(t_opt, Q, dt) for Q in Qs]
        with np.errstate(invalid="ignore"):
            mag_b = np.nanmean(np.stack([r[1] for r in rb]), axis=0)
            mag_o = np.nanmean(np.stack([r[1] for r in ro]), axis=0)
        try:
            offset_s, correlation = estimate_offset(rb[0][0], mag_b, ro[0][0], mag_o, dt)
        except ValueError as exc:
            raise CompareError(f"{export.path}: {exc}") from None
        source = "cross-correlation"
        if correlation < NO_MATCH_CORRELATION:
            raise CompareError(
                f"{export.path}: its angular rates match the recording's at no offset (best "
                f"correlation {correlation:.2f}): not the same session? Give the offset with "
                "--offset")
        if correlation < 0.5:
            warnings.append(f"the angular rates correlate poorly (peak {correlation:.2f}): "
                            "check the offset, or give it with --offset")
    else:
        source = "given"
    t_query = rec.t - offset_s
    resampled = [resample_optical(t_query, t_opt, Q) for Q in Qs]
    inside = resampled[0][1]
    if inside.sum() * dt < MIN_OVERLAP_S:
        raise CompareError(
            f"the recording ({rec.t[0]:.1f}-{rec.t[-1]:.1f} s) and the optical file "
            f"({t_opt[0] + offset_s:.1f}-{t_opt[-1] + offset_s:.1f} s on the recording's "
            f"clock, offset {offset_s:+.3f} s) overlap by less than {MIN_OVERLAP_S:g} s")
    use = inside.copy()
    if window is not None:
        use &= (rec.t >= window[0]) & (rec.t <= window[1])
    alignments, segments, aligned = [], [], np.full((len(rec.t), 18, 3, 3), np.nan)
    Q_all = np.stack([r[0] for r in resampled], axis=1)
    pauses = _pauses(rec.t, Q_all, dt)
    if len(pauses) < 2:
        warnings.append("fewer than two still pauses found: no start-to-end change reported")
    errors = np.full((len(rec.t), len(pairs)), np.nan)
    for j, ((name, imu), (Q, ins, gap)) in enumerate(zip(pairs, resampled, strict=True)):
        R = rec.R[:, imu]
        try:
            if given is not None:
                if name not in given:
                    raise CompareError(f"the alignment file has no rotations for {name!r}")
                S, W = given[name]
                al = Alignment(S, W, "given")
            else:
                al = align_frames(R, Q, dt, align,
                                  None if rec.acc is None else rec.acc[:, imu],
                                  None if rec.mag is None else rec.mag[:, imu], use,
                                  None if rec.gyr is None else rec.gyr[:, imu])
        except ValueError as exc:
            raise CompareError(f"{name} ({IMU_NAMES[imu]}): {exc}") from None
        alignments.append(al)
        R_opt = al.W @ Q @ al.S
        aligned[:, imu] = R_opt
        st = segment_stats(name, imu, rec.t, R, R_opt, ins, gap, pauses)
        segments.append(st)
        errors[:, j] = st.series
        if al.mode != "given" and al.rate_condition < 0.01:
            warnings.append(f"{name}: rotation about one axis only (rate condition "
                            f"{al.rate_condition:.3f}): its IMU-to-cluster rotation is "
                            "poorly determined")
    # joint angles: the optical segments through the recording's own Reset Zero offsets
    with np.errstate(invalid="ignore"):
        offset = np.swapaxes(rec.R, -1, -2) @ rec.C
        C_opt = aligned @ offset
        J_opt = joint_angles(C_opt, rec.convention)
    joints, jb, jo = joint_stats(rec.t, rec.joints, J_opt, inside)
    imus = [imu for _, imu in pairs]
    angles_b = np.degrees(dcm_to_euler(rec.C[:, imus]))
    angles_o = np.degrees(dcm_to_euler(C_opt[:, imus]))
    angles_b[~inside] = np.nan
    lo, hi = rec.t[inside][[0, -1]]
    return CompareResult(
        recording_name, export.path, float(export.rate_hz), dt, float(offset_s), source,
        float(correlation), pairs, alignments, segments, joints, (float(lo), float(hi)),
        pauses, rec.t, errors, jb, jo, angles_b, angles_o, warnings)
