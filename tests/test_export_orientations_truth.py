"""The orientations and angles of the remaining exports against the simulated subject's truth
(issue 46.1): the BVH (offsets and the posed skeleton), the OpenSim ``.sto`` orientations and
``.mot`` joint angles, the quaternion and Euler columns of the Parquet, the ``.mat``, the
MATLAB CSV and the filtered CSV.

Truth comes from bpms.firmware.sim (its own segment orientations ``C``, sensor orientations
``R``, skeleton points and degrees of freedom); every conversion is written here by hand:
quaternion → matrix (scalar first), SPEC §5's Euler angles (roll = atan2(R21, R22),
pitch = −asin(R20), yaw = atan2(R10, R00)), the IMU ids of SPEC's table, OpenSim's sign rules.

Tolerance: the suit is simulated without mounting errors, so after the first Reset Zero
(1.5 s) the exports differ from the truth by the default filter's error alone. Measured on
this script: 10.6° at worst and 4.3° RMS (the right hand while the elbow bends 90° in 1.5 s:
the drift correction, Kp 0.02, is slow), about 1° RMS on the trunk and legs. The bounds
(15° any sample, 6° RMS per column) leave room for that and nothing else: a column in
degrees under a radian name, a quaternion written x-first, a frame turned by 90°, a yaw or an
adduction with its sign flipped is tens of degrees off."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pyarrow.parquet as pq
import pytest
import scipy.io as sio

from bpms.cli import main
from bpms.firmware.sim.motion import Move, Still
from bpms.firmware.sim.sensors import SensorModel
from bpms.firmware.sim.session import simulate

#: The script (degrees of the simulator's own DOFs; its right abduction is negative): arms
#: forward, elbows bent, arms sideways, legs apart, a squat, each held and undone.
SCRIPT = [Still("still", 2.0),
          Move("arms forward", 1.5, {"sh_r_flex": 60, "sh_l_flex": 40}, hold=0.3),
          Move("down", 1.5, hold=0.2),
          Move("elbows", 1.5, {"elbow_r": 90, "elbow_l": 70}, hold=0.3),
          Move("down", 1.5, hold=0.2),
          Move("sideways", 1.5, {"sh_r_abd": -70, "sh_l_abd": 50}, hold=0.3),
          Move("down", 1.5, hold=0.2),
          Move("legs apart", 1.5, {"hip_r_abd": -25, "hip_l_abd": 25}, hold=0.3),
          Move("together", 1.5, hold=0.2),
          Move("squat", 2.0, {"hip_r_flex": 55, "hip_l_flex": 45, "knee_r": 70, "knee_l": 60},
               hold=0.3),
          Move("up", 2.0, hold=0.5)]
START = 1.5  # s, the automatic Reset Zero: the exports follow the truth from here
MAX_DEG, RMS_DEG = 15.0, 6.0
DEG = 180.0 / math.pi
#: OpenSense IMU name → SPEC's IMU id (the table "IMU ids (wire order) and names").
OPENSENSE = {"pelvis_imu": 6, "torso_imu": 8, "humerus_r_imu": 4, "radius_r_imu": 5,
             "hand_r_imu": 3, "femur_r_imu": 0, "tibia_r_imu": 2, "calcn_r_imu": 1,
             "humerus_l_imu": 10, "radius_l_imu": 11, "hand_l_imu": 9, "femur_l_imu": 12,
             "tibia_l_imu": 14, "calcn_l_imu": 13}


@pytest.fixture(scope="module")
def trial(tmp_path_factory):
    rec = simulate(seed=5, script=SCRIPT, model=SensorModel(mounting_error_deg=0.0))
    folder = tmp_path_factory.mktemp("orient")
    raw = rec.save_raw(folder / "Raw_orient_001.bpmsraw")
    return rec, raw, rec.t >= START


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """``[..., 4]`` (w, x, y, z) → ``[..., 3, 3]`` rotation matrices, written out."""
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z),
                               2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z),
                               2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x),
                               1 - 2 * (x * x + y * y)], -1)], -2)


def euler_to_matrix(roll, pitch, yaw) -> np.ndarray:
    """SPEC §5: R = Rz(yaw) Ry(pitch) Rx(roll), angles in rad."""
    c1, s1, c2, s2, c3, s3 = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    return np.stack([np.stack([c2 * c3, s1 * s2 * c3 - c1 * s3, c1 * s2 * c3 + s1 * s3], -1),
                     np.stack([c2 * s3, s1 * s2 * s3 + c1 * c3, c1 * s2 * s3 - s1 * c3], -1),
                     np.stack([-s2, s1 * c2, c1 * c2], -1)], -2)


def angle_deg(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The angle (degrees) of the rotation between ``A`` and ``B`` ``[..., 3, 3]``."""
    c = (np.einsum("...ji,...ji->...", A, B) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _close(err_deg: np.ndarray, what: str) -> None:
    err_deg = np.asarray(err_deg)
    rms = float(np.sqrt(np.mean(err_deg**2)))
    assert np.isfinite(err_deg).all(), what
    assert err_deg.max() < MAX_DEG and rms < RMS_DEG, (what, float(err_deg.max()), rms)


def _column(cols: list[str], imu: int, suffix: str) -> int:
    hits = [k for k, c in enumerate(cols) if c.startswith(f"imu{imu}_") and c.endswith(suffix)]
    assert len(hits) == 1, (imu, suffix, hits)
    return hits[0]


def _text_table(path, comment: str) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith(comment)]
    return lines[0].split(","), np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])


# --- BVH -------------------------------------------------------------------------------------

def read_bvh(path) -> tuple[dict[str, tuple[str | None, np.ndarray, list[str]]], np.ndarray]:
    """A small BVH reader: joint → (parent, OFFSET, channel names) in file order, and the
    MOTION rows ``[frames, channels]``."""
    joints: dict[str, tuple[str | None, np.ndarray, list[str]]] = {}
    stack: list[str | None] = []
    current: str | None = None
    lines = path.read_text().splitlines()
    k = 0
    while lines[k].strip() != "MOTION":
        words = lines[k].split()
        if words and words[0] in ("ROOT", "JOINT", "End"):
            name = words[1] if words[0] != "End" else f"{current}_end"
            joints[name] = (stack[-1] if stack else None, np.zeros(3), [])
            current = name
        elif words and words[0] == "{":
            stack.append(current)
        elif words and words[0] == "}":
            stack.pop()
            current = stack[-1] if stack else None
        elif words and words[0] == "OFFSET":
            joints[current][1][:] = [float(v) for v in words[1:4]]
        elif words and words[0] == "CHANNELS":
            joints[current][2].extend(words[2:])
        k += 1
    rows = np.array([[float(v) for v in ln.split()] for ln in lines[k + 3:] if ln.strip()])
    return joints, rows


def bvh_world_positions(joints, rows) -> dict[str, np.ndarray]:
    """Each joint's position ``[frames, 3]`` (file units, file axes): the BVH rule, a joint's
    rotation channels applied in their listed order (intrinsic), parent after child."""
    axes = {"X": 0, "Y": 1, "Z": 2}

    def rot(axis: int, a: np.ndarray) -> np.ndarray:
        c, s = np.cos(a), np.sin(a)
        m = np.zeros((len(a), 3, 3))
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        m[:, axis, axis] = 1.0
        m[:, i, i], m[:, i, j], m[:, j, i], m[:, j, j] = c, -s, s, c
        return m

    col = 0
    pos: dict[str, np.ndarray] = {}
    frame: dict[str, np.ndarray] = {}
    for name, (parent, offset, channels) in joints.items():
        R = np.broadcast_to(np.eye(3), (len(rows), 3, 3)).copy()
        p = np.broadcast_to(offset, (len(rows), 3)).copy()
        for ch in channels:
            v = rows[:, col]
            col += 1
            if ch.endswith("position"):
                p[:, axes[ch[0]]] += v
            else:
                R = R @ rot(axes[ch[0]], np.radians(v))
        if parent is None:
            pos[name], frame[name] = p, R
        else:
            pos[name] = pos[parent] + np.einsum("nij,nj->ni", frame[parent], p)
            frame[name] = frame[parent] @ R
    return pos


def test_bvh_offsets_and_pose_match_the_simulated_skeleton(trial, tmp_path):
    rec, raw, late = trial
    out = tmp_path / "s.bvh"
    assert main(["export", "bvh", str(raw), "-o", str(out)]) == 0
    joints, rows = read_bvh(out)
    truth = rec.truth.joint_positions  # [N, 21, 3] m, NED
    names = list(rec.truth.point_names)
    # BVH axes by hand: x north, y up, z east (NED turned +90° about north), centimetres
    to_bvh = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) * 100.0
    # each segment's joint and the next point down the chain, by the skeleton's names
    segments = {"thigh_r": ("hip_r", "knee_r"), "shank_r": ("knee_r", "ankle_r"),
                "arm_l": ("shoulder_l", "elbow_l"), "forearm_r": ("elbow_r", "wrist_r"),
                "mid_spine": ("spine_mid", "neck_base"), "foot_l": ("ankle_l", "toe_l")}
    for seg, (a, b) in segments.items():
        child = next(n for n, (parent, _, _) in joints.items() if parent == seg)
        length_cm = np.linalg.norm(joints[child][1])
        want = 100.0 * np.linalg.norm(truth[0, names.index(b)] - truth[0, names.index(a)])
        assert length_cm == pytest.approx(want, abs=0.05), (seg, length_cm, want)
    pos = bvh_world_positions(joints, rows)
    assert len(pos) >= 21
    # every joint's place relative to the pelvis, in the posed skeleton: the filter's error
    # along a chain of up to 90 cm (8° → 12 cm at worst; 3 cm allowed on a typical sample)
    errs = []
    for name, (parent, _, _) in joints.items():
        if parent is None or name.endswith("_end"):
            continue
        start = _segment_start(name)
        got = pos[name] - pos["pelvis"]
        want = (truth[:, names.index(start)] - truth[:, 0]) @ to_bvh.T
        errs.append(np.linalg.norm(got - want, axis=-1)[late])
    errs = np.array(errs)
    assert np.median(errs) < 1.0 and np.percentile(errs, 99) < 4.0, (
        float(np.median(errs)), float(np.percentile(errs, 99)))


def _segment_start(name: str) -> str:
    """The skeleton point where BVH joint ``name`` sits (its segment's start point)."""
    side = name[-2:] if name[-2:] in ("_r", "_l") else ""
    base = name.removesuffix(side)
    start = {"low_spine": "pelvis", "mid_spine": "spine_mid", "neck": "neck_base",
             "head": "head_base", "shoulder": "neck_base", "arm": "shoulder",
             "forearm": "elbow", "hand": "wrist",
             "hip": "pelvis", "thigh": "hip", "shank": "knee", "foot": "ankle"}[base]
    return start + side if start in ("shoulder", "elbow", "wrist", "hip", "knee",
                                     "ankle") else start


# --- OpenSim -------------------------------------------------------------------------------

def test_opensim_sto_orientations_are_the_segments_true_orientations(trial, tmp_path):
    rec, raw, late = trial
    assert main(["export", "opensim", str(raw), "-o", str(tmp_path / "t")]) == 0
    lines = (tmp_path / "t_orientations.sto").read_text().splitlines()
    end = lines.index("endheader")
    labels = lines[end + 1].split("\t")
    rows = [ln.split("\t") for ln in lines[end + 2:]]
    assert len(rows) == len(rec.t)
    for label, imu in OPENSENSE.items():
        k = labels.index(label)
        q = np.array([[float(v) for v in r[k].split(",")] for r in rows])  # w, x, y, z
        _close(angle_deg(quat_to_matrix(q), rec.truth.C[:, imu])[late], label)


def _read_mot(path) -> dict[str, np.ndarray]:
    """OpenSim's own reader where installed, else a plain one (header to endheader, a
    tab-separated label row, rows)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import opensim as osim
    except ImportError:
        lines = path.read_text().splitlines()
        end = next(k for k, ln in enumerate(lines) if ln.strip() == "endheader")
        labels = lines[end + 1].split("\t")
        data = np.array([[float(v) for v in ln.split("\t")] for ln in lines[end + 2:]])
        return {name: data[:, k] for k, name in enumerate(labels)}
    table = osim.TimeSeriesTable(str(path))
    return {name: table.getDependentColumn(name).to_numpy()
            for name in table.getColumnLabels()}


def test_opensim_mot_joint_angles_follow_the_simulated_degrees_of_freedom(trial, tmp_path):
    """OpenSim's signs (Rajagopal 2016), applied here by hand to the simulator's degrees of
    freedom: flexion positive (as the simulator's); adduction positive, so every abduction of
    the script (the simulator's truth reads a sideways raise positive on both sides: checked
    below against the script's own amplitudes) is negative in the .mot."""
    rec, raw, late = trial
    assert main(["export", "opensim", str(raw), "-o", str(tmp_path / "t")]) == 0
    mot = _read_mot(tmp_path / "t_joint_angles.mot")
    truth = dict(zip(rec.truth.joint_names, np.asarray(rec.truth.joint_angles).T * DEG,
                     strict=True))
    pairs = {"knee_angle_r": ("knee_r.flexion", 1), "knee_angle_l": ("knee_l.flexion", 1),
             "elbow_flex_r": ("elbow_r.flexion", 1), "elbow_flex_l": ("elbow_l.flexion", 1),
             "hip_flexion_r": ("hip_r.flexion", 1), "hip_flexion_l": ("hip_l.flexion", 1),
             "arm_flex_r": ("shoulder_r.flexion", 1), "arm_flex_l": ("shoulder_l.flexion", 1),
             "arm_add_r": ("shoulder_r.abduction", -1), "arm_add_l": ("shoulder_l.abduction", -1),
             "hip_adduction_r": ("hip_r.abduction", -1),
             "hip_adduction_l": ("hip_l.abduction", -1)}
    # the truth's signs, from the script: 70° and 50° sideways raises, legs 25° apart,
    # hips flexed 55° and 45°, knees 70° and 60°
    for dof, peak in (("shoulder_r.abduction", 70), ("shoulder_l.abduction", 50),
                      ("hip_r.abduction", 25), ("hip_l.abduction", 25), ("hip_r.flexion", 55),
                      ("hip_l.flexion", 45), ("knee_r.flexion", 70), ("knee_l.flexion", 60)):
        assert truth[dof].max() == pytest.approx(peak, abs=0.5), dof
    moved = 0
    for name, (dof, sign) in pairs.items():
        want = sign * truth[dof][late]
        got = mot[name][late]
        assert len(mot[name]) == len(rec.t), name
        err = np.abs(got - want)
        moved += np.ptp(want) > 20.0
        _close(err, name)
    assert moved == len(pairs)  # the script moves each through more than 20°


# --- Parquet, .mat, MATLAB CSV, filtered CSV ------------------------------------------------

def test_mat_and_parquet_quaternions_are_the_true_orientations(trial, tmp_path):
    rec, raw, late = trial
    assert main(["convert", str(raw), "-o", str(tmp_path / "t")]) == 0
    mat = sio.loadmat(tmp_path / "t.mat")
    table = pq.read_table(tmp_path / "t.parquet")
    cols = table.column_names
    for imu in range(18):
        truth = rec.truth.R[:, imu]
        _close(angle_deg(quat_to_matrix(mat["quaternions"][:, imu]), truth)[late], f"mat {imu}")
        q = np.stack([table.column(_column(cols, imu, f"_q{c}")).to_numpy() for c in "wxyz"],
                     -1)
        _close(angle_deg(quat_to_matrix(q), truth)[late], f"parquet {imu}")


def test_matlab_csv_sensor_quaternions_and_euler_degrees(trial, tmp_path):
    rec, raw, late = trial
    out = tmp_path / "m.csv"
    assert main(["export", "matlab", str(raw), "-o", str(out)]) == 0
    cols, data = _text_table(out, "%")
    for imu in range(18):
        truth = rec.truth.R[:, imu]
        q = data[:, [_column(cols, imu, f"_sensor_q{c}") for c in "wxyz"]]
        _close(angle_deg(quat_to_matrix(q), truth)[late], f"q {imu}")
        rpy = data[:, [_column(cols, imu, f"_sensor_{e}_deg") for e in ("roll", "pitch", "yaw")]]
        R = euler_to_matrix(*np.radians(rpy).T)
        _close(angle_deg(R, truth)[late], f"euler {imu}")


def test_filtered_csv_euler_radians_segment_and_sensor(trial, tmp_path):
    rec, raw, late = trial
    out = tmp_path / "f.csv"
    assert main(["filter", str(raw), "-o", str(out)]) == 0
    cols, data = _text_table(out, "#")
    for imu in range(18):
        for group, truth in (("", rec.truth.C[:, imu]), ("_sensor", rec.truth.R[:, imu])):
            idx = [k for e in ("roll", "pitch", "yaw") for k, c in enumerate(cols)
                   if c.startswith(f"imu{imu}_") and c.endswith(f"_{e}_rad")
                   and (("_sensor_" in c) == bool(group))]
            assert len(idx) == 3, (imu, group, idx)
            R = euler_to_matrix(*data[:, idx].T)
            _close(angle_deg(R, truth)[late], f"filtered {group or 'segment'} {imu}")
