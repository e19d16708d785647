"""The outputs of ``bpms compare`` (docs/compare.md): the summary CSV (one figure per row),
the per-sample CSV the figures are drawn from, the Markdown report, the JSON document and the
PNG figures (matplotlib, the ``figures`` extra)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from bpms.analysis.compare import CompareResult
from bpms.filter.rotations import dcm_to_quaternion, rotation_vector
from bpms.io.frames import IMU_NAMES

SEGMENT_FIGURES = (  # attribute, label, unit
    ("samples", "compared samples", ""), ("gaps", "occluded samples skipped", ""),
    ("rmse_total", "RMSE total", "deg"), ("rmse_inclination", "RMSE inclination", "deg"),
    ("rmse_heading", "RMSE heading", "deg"), ("max_total", "max error", "deg"),
    ("mean_total", "mean error", "deg"), ("trend_total", "trend of the error", "deg/min"),
    ("trend_heading", "trend of the heading error", "deg/min"),
    ("pause_change", "change first to last pause", "deg"))
JOINT_FIGURES = (
    ("samples", ""), ("rmse", "deg"), ("max_abs", "deg"), ("bias", "deg"), ("sd", "deg"),
    ("loa_low", "deg"), ("loa_high", "deg"), ("proportional", ""), ("trend", "deg/min"))
ALIGN_FIGURES = (
    ("s_angle_deg", "deg"), ("w_angle_deg", "deg"), ("s_sd_deg", "deg"),
    ("s_split_deg", "deg"), ("w_split_deg", "deg"), ("rate_condition", ""),
    ("rate_residual_dps", "deg/s"), ("samples", ""))


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _alignment_dict(res: CompareResult, j: int) -> dict:
    al = res.alignments[j]
    return {
        "mode": al.mode,
        "S_quaternion": [round(float(v), 9) for v in dcm_to_quaternion(al.S)],
        "W_quaternion": [round(float(v), 9) for v in dcm_to_quaternion(al.W)],
        "s_angle_deg": float(np.degrees(np.linalg.norm(rotation_vector(al.S)))),
        "w_angle_deg": float(np.degrees(np.linalg.norm(rotation_vector(al.W)))),
        "s_sd_deg": _num(al.s_sd_deg), "s_split_deg": _num(al.s_split_deg),
        "w_split_deg": _num(al.w_split_deg), "rate_condition": _num(al.rate_condition),
        "rate_residual_dps": _num(al.rate_residual_dps), "samples": al.samples}


def to_dict(res: CompareResult) -> dict:
    """Everything as plain JSON types (NaN → null)."""
    segments = []
    for j, st in enumerate(res.segments):
        entry = {"body": st.body, "segment": IMU_NAMES[st.imu], "imu": st.imu}
        entry.update({k: (_num(getattr(st, k)) if k not in ("samples", "gaps")
                          else getattr(st, k)) for k, _, _ in SEGMENT_FIGURES})
        entry["alignment"] = _alignment_dict(res, j)
        segments.append(entry)
    joints = [{"joint": js.name, **{k: (_num(getattr(js, k)) if k != "samples" else js.samples)
                                    for k, _ in JOINT_FIGURES}} for js in res.joints]
    return {"recording": res.recording, "optical": res.optical,
            "optical_rate_hz": res.optical_rate_hz, "offset_s": res.offset_s,
            "offset_source": res.offset_source, "correlation": _num(res.correlation),
            "overlap_s": list(res.overlap_s), "pauses_s": [list(p) for p in res.pauses],
            "segments": segments, "joints": joints, "warnings": res.warnings}


def read_alignment(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The rotations (S, W) per optical body of a ``bpms compare --json`` document (or a file
    of the same shape: ``segments`` with ``body`` and ``alignment.S_quaternion`` /
    ``W_quaternion``, w x y z). ValueError for anything else."""
    from bpms.filter.rotations import quaternion_to_dcm

    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        out = {}
        for seg in doc["segments"]:
            al = seg["alignment"]
            S = quaternion_to_dcm(np.asarray(al["S_quaternion"], dtype=np.float64))
            W = quaternion_to_dcm(np.asarray(al["W_quaternion"], dtype=np.float64))
            if not (np.isfinite(S).all() and np.isfinite(W).all()):
                raise ValueError("a quaternion is not finite")
            out[str(seg["body"])] = (S, W)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: not an alignment document ({exc})") from None
    if not out:
        raise ValueError(f"{path}: the alignment document names no body")
    return out


def write_csv(path: str | Path, res: CompareResult) -> Path:
    """One figure per row: ``section, name, figure, value, unit``."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["section", "name", "figure", "value", "unit"])
        w.writerow(["time", "optical", "offset", f"{res.offset_s:.6f}", "s"])
        w.writerow(["time", "optical", "correlation", _fmt(res.correlation), ""])
        for j, st in enumerate(res.segments):
            name = f"{st.body} / {IMU_NAMES[st.imu]}"
            for key, _, unit in SEGMENT_FIGURES:
                w.writerow(["segment", name, key, _fmt(getattr(st, key)), unit])
            al = _alignment_dict(res, j)
            for key, unit in ALIGN_FIGURES:
                w.writerow(["alignment", name, key, _fmt(al[key]), unit])
        for js in res.joints:
            for key, unit in JOINT_FIGURES:
                w.writerow(["joint", js.name, key, _fmt(getattr(js, key)), unit])
    return path


def _fmt(x) -> str:
    if x is None:
        return ""
    if isinstance(x, int | np.integer):
        return str(int(x))
    return "" if not math.isfinite(x) else f"{x:.4f}"


def write_series_csv(path: str | Path, res: CompareResult) -> Path:
    """Per BPMS sample in the overlap: time, every segment's total error (deg, empty = gap),
    every compared joint angle by BPMS and by the optical system (deg)."""
    path = Path(path)
    lo, hi = res.overlap_s
    k = (res.t >= lo) & (res.t <= hi)
    names = [js.name for js in res.joints]
    header = (["time_s"] + [f"error_{st.body.split(':')[-1]}_deg" for st in res.segments]
              + [f"{n}_bpms_deg" for n in names] + [f"{n}_optical_deg" for n in names])
    data = np.concatenate([res.t[k, None], res.segment_error_deg[k], res.joint_bpms_deg[k],
                           res.joint_optical_deg[k]], axis=1)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in data:
            w.writerow(["" if not np.isfinite(v) else f"{v:.4f}" for v in row])
    return path


def markdown(res: CompareResult) -> str:
    """The report: the clocks, per segment the errors and the alignment, per joint angle the
    errors and the Bland-Altman summary."""
    def f(x: float, d: int = 2) -> str:
        return "–" if x is None or not math.isfinite(x) else f"{x:.{d}f}"

    lines = [f"# {Path(res.recording).name or 'recording'} against "
             f"{Path(res.optical).name}", "",
             f"- clock offset: {res.offset_s:+.3f} s ({res.offset_source}"
             + (f", peak correlation {res.correlation:.3f}" if math.isfinite(res.correlation)
                else "") + f"); optical rate {res.optical_rate_hz:g} Hz",
             f"- compared from {res.overlap_s[0]:.2f} s to {res.overlap_s[1]:.2f} s of the "
             "recording; pauses: " + (", ".join(f"{a:.2f}-{b:.2f} s" for a, b in res.pauses)
                                      or "none found"), ""]
    lines += ["## Segments (degrees; trends in deg/min)", "",
              "| body | segment | samples | gaps | RMSE | incl. | heading | max | trend | "
              "heading trend | pause change |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for st in res.segments:
        lines.append(f"| {st.body} | {IMU_NAMES[st.imu]} | {st.samples} | {st.gaps} | "
                     f"{f(st.rmse_total)} | {f(st.rmse_inclination)} | {f(st.rmse_heading)} | "
                     f"{f(st.max_total)} | {f(st.trend_total)} | {f(st.trend_heading)} | "
                     f"{f(st.pause_change)} |")
    lines += ["", "## Frame alignment (IMU → cluster S, optical world → NED W)", "",
              "| body | mode | S angle | S std. error | S halves apart | W angle | "
              "W halves apart | rate condition | rate residual deg/s |",
              "|---|---|---|---|---|---|---|---|---|"]
    for j, st in enumerate(res.segments):
        al = _alignment_dict(res, j)
        lines.append(f"| {st.body} | {al['mode']} | {f(al['s_angle_deg'])} | "
                     f"{f(al['s_sd_deg'] or math.nan, 3)} | {f(al['s_split_deg'] or math.nan)} |"
                     f" {f(al['w_angle_deg'])} | {f(al['w_split_deg'] or math.nan)} | "
                     f"{f(al['rate_condition'] or math.nan, 3)} | "
                     f"{f(al['rate_residual_dps'] or math.nan)} |")
    if res.joints:
        lines += ["", "## Joint angles, BPMS − optical (degrees; Bland-Altman)", "",
                  "| joint angle | samples | RMSE | max | bias | SD | limits of agreement | "
                  "proportional | trend deg/min |", "|---|---|---|---|---|---|---|---|---|"]
        for js in res.joints:
            lines.append(f"| {js.name} | {js.samples} | {f(js.rmse)} | {f(js.max_abs)} | "
                         f"{f(js.bias)} | {f(js.sd)} | {f(js.loa_low)} to {f(js.loa_high)} | "
                         f"{f(js.proportional, 3)} | {f(js.trend)} |")
    if res.warnings:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in res.warnings]
    return "\n".join(lines) + "\n"


def figures(res: CompareResult, directory: str | Path, stem: str) -> list[Path]:
    """``<stem>_errors.png`` (every segment's error over time) and, with joint angles,
    ``<stem>_bland_altman.png`` (one panel per joint angle). Needs matplotlib."""
    from bpms.analysis.plots import _pyplot

    plt = _pyplot()
    out = Path(directory)
    paths = []
    fig, ax = plt.subplots(figsize=(9, 4))
    for j, st in enumerate(res.segments):
        ax.plot(res.t, res.segment_error_deg[:, j], linewidth=0.8,
                label=f"{st.body.split(':')[-1]} ({IMU_NAMES[st.imu]})")
    for a, b in res.pauses:
        ax.axvspan(a, b, color="0.9")
    ax.set_xlabel("time, s (recording)")
    ax.set_ylabel("orientation error, deg")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    paths.append(out / f"{stem}_errors.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    if res.joints:
        n = len(res.joints)
        cols = min(4, n)
        rows = math.ceil(n / cols)
        fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
        for k, js in enumerate(res.joints):
            ax = axes[k // cols][k % cols]
            a, b = res.joint_bpms_deg[:, k], res.joint_optical_deg[:, k]
            diff = np.degrees(np.angle(np.exp(1j * np.radians(a - b))))  # as the statistics
            ax.plot(0.5 * (a + b), diff, ".", markersize=2)
            for y, style in ((js.bias, "-"), (js.loa_low, "--"), (js.loa_high, "--")):
                ax.axhline(y, color="C3", linestyle=style, linewidth=0.8)
            ax.set_title(js.name, fontsize=8)
            ax.tick_params(labelsize=7)
        for k in range(n, rows * cols):
            axes[k // cols][k % cols].axis("off")
        fig.supxlabel("mean of the two, deg")
        fig.supylabel("BPMS − optical, deg")
        fig.tight_layout()
        paths.append(out / f"{stem}_bland_altman.png")
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths
