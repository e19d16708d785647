"""OpenSense end to end on a ``bpms export opensim`` pair: the IMU placer, then IMU inverse
kinematics (OpenSim's Python API, ``pip install opensim``; docs/analysis.md, "OpenSim").

    bpms export opensim Raw_trial_001.bpmsraw -o trial
    python tools/opensim_ik.py trial_orientations.sto trial_calibration.sto -o ik/
    python tools/opensim_ik.py ... --model Rajagopal2015.osim -o ik/      # your own model

Without ``--model`` the script builds a small model of its own (``bpms_simple.osim``, written
into the output folder): the 14 bodies the export names (``pelvis``, ``torso``, ``humerus_r``,
``radius_r``, ``hand_r``, ``femur_r``, ``tibia_r``, ``calcn_r`` and the left side), the pelvis
free, ball joints at the lumbar spine, shoulders, wrists, hips and ankles, hinges at the
elbows and knees, with these coordinates (degrees, positive as named): ``arm_flex_r``
(shoulder flexion), ``elbow_flex_r``, ``hip_flexion_r``, ``knee_angle_r`` (knee flexion),
``ankle_angle_r`` (dorsiflexion), ``lumbar_extension`` and the left ones. A ball joint's
three coordinates are body-fixed X, Y, Z rotations of its child (``_x``: about forward, ``_y``:
about up, the named one: about right). Any model whose bodies carry the export's names works
with ``--model`` (Rajagopal 2015, gait2392 for the legs).

Steps, with the settings of docs/analysis.md: the placer puts one IMU frame on each body from
the calibration-pose file (``sensor_to_opensim_rotations = (π/2, 0, 0)``: NED → OpenSim's
y-up ground; base IMU ``pelvis_imu``, heading axis x), writes the calibrated model, then the
IK tool tracks the whole trial and writes ``ik_<orientations>.mot`` (coordinates over time,
degrees). The script prints each coordinate's range.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

#: NED (x north, y east, z down) → OpenSim ground (x forward, y up, z right): +90° about X.
SENSOR_TO_OPENSIM = (math.pi / 2, 0.0, 0.0)


def _need_opensim():
    try:
        import opensim
    except ImportError:
        raise SystemExit("opensim_ik: OpenSim's Python package is not installed "
                         "(pip install opensim; on macOS: conda install -c opensim-org "
                         "opensim)") from None
    opensim.Logger.setLevelString("warn")  # not one line per frame solved
    return opensim


def build_model(path: Path) -> Path:
    """Write the small model (see the module docstring) to ``path``; returns it."""
    osim = _need_opensim()
    model = osim.Model()
    model.setName("bpms_simple")
    v = osim.Vec3

    def body(name: str, mass: float, length: float):
        b = osim.Body(name, mass, v(0, -length / 2, 0), osim.Inertia(0.01 * mass, 0.002 * mass,
                                                                      0.01 * mass))
        model.addBody(b)
        return b

    def name_coordinates(joint, names):
        for k, name in enumerate(names):
            joint.upd_coordinates(k).setName(name)
        model.addJoint(joint)

    pelvis = body("pelvis", 11.0, 0.1)
    name_coordinates(osim.FreeJoint("ground_pelvis", model.getGround(), v(0, 0.95, 0), v(0),
                                    pelvis, v(0), v(0)),
                     ["pelvis_list", "pelvis_rotation", "pelvis_tilt",
                      "pelvis_tx", "pelvis_ty", "pelvis_tz"])
    torso = body("torso", 26.0, -0.5)  # grows upwards from the lumbar joint
    name_coordinates(osim.BallJoint("lumbar", pelvis, v(0, 0.1, 0), v(0), torso, v(0), v(0)),
                     ["lumbar_bending", "lumbar_rotation", "lumbar_extension"])
    # a hinge whose positive rotation is flexion of the named joint (about the body's right
    # axis z, or left when the segment folds backwards: the knee)
    backwards = v(0, math.pi, 0)
    for side, s in (("r", 1.0), ("l", -1.0)):
        humerus = body(f"humerus_{side}", 2.0, 0.3)
        name_coordinates(osim.BallJoint(f"shoulder_{side}", torso, v(0, 0.4, 0.18 * s), v(0),
                                        humerus, v(0), v(0)),
                         [f"arm_add_{side}_x", f"arm_rot_{side}_y", f"arm_flex_{side}"])
        radius = body(f"radius_{side}", 1.2, 0.27)
        name_coordinates(osim.PinJoint(f"elbow_{side}", humerus, v(0, -0.3, 0), v(0), radius,
                                       v(0), v(0)), [f"elbow_flex_{side}"])
        hand = body(f"hand_{side}", 0.5, 0.18)
        name_coordinates(osim.BallJoint(f"radius_hand_{side}", radius, v(0, -0.27, 0), v(0),
                                        hand, v(0), v(0)),
                         [f"wrist_dev_{side}_x", f"wrist_rot_{side}_y", f"wrist_flex_{side}"])
        femur = body(f"femur_{side}", 8.0, 0.43)
        name_coordinates(osim.BallJoint(f"hip_{side}", pelvis, v(0, -0.07, 0.09 * s), v(0),
                                        femur, v(0), v(0)),
                         [f"hip_adduction_{side}_x", f"hip_rotation_{side}_y",
                          f"hip_flexion_{side}"])
        tibia = body(f"tibia_{side}", 3.5, 0.43)
        name_coordinates(osim.PinJoint(f"knee_{side}", femur, v(0, -0.43, 0), backwards,
                                       tibia, v(0), backwards), [f"knee_angle_{side}"])
        calcn = body(f"calcn_{side}", 1.0, 0.05)
        name_coordinates(osim.BallJoint(f"ankle_{side}", tibia, v(0, -0.43, 0), v(0), calcn,
                                        v(0), v(0)),
                         [f"subtalar_{side}_x", f"ankle_rot_{side}_y", f"ankle_angle_{side}"])
    model.finalizeConnections()
    model.initSystem()
    model.printToXML(str(path))
    return path


def run(orientations: Path, calibration: Path, out: Path, model: Path | None = None,
        ) -> Path:
    """Placer + IK; returns the ``.mot`` of the coordinates (degrees)."""
    osim = _need_opensim()
    out.mkdir(parents=True, exist_ok=True)
    model = model or build_model(out / "bpms_simple.osim")
    rotations = osim.Vec3(*SENSOR_TO_OPENSIM)
    placer = osim.IMUPlacer()
    placer.set_model_file(str(model))
    placer.set_orientation_file_for_calibration(str(calibration))
    placer.set_sensor_to_opensim_rotations(rotations)
    placer.set_base_imu_label("pelvis_imu")
    placer.set_base_heading_axis("x")
    calibrated = out / f"{model.stem}_calibrated.osim"
    placer.set_output_model_file(str(calibrated))
    if not placer.run(False):
        raise SystemExit("opensim_ik: the IMU placer failed")
    ik = osim.IMUInverseKinematicsTool()
    ik.set_model_file(str(calibrated))
    ik.set_orientations_file(str(orientations))
    ik.set_sensor_to_opensim_rotations(rotations)
    ik.set_results_directory(str(out))
    table = osim.TimeSeriesTableQuaternion(str(orientations))
    times = table.getIndependentColumn()
    ik.set_time_range(0, times[0])
    ik.set_time_range(1, times[-1])
    motion = out / f"ik_{orientations.stem}.mot"
    ik.set_output_motion_file(str(motion))
    if not ik.run(False):
        raise SystemExit("opensim_ik: IMU inverse kinematics failed")
    return motion


def read_motion(path: Path) -> dict[str, list[float]]:
    """The columns of an OpenSim ``.mot``/``.sto`` text file (header up to ``endheader``)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    start = next(k for k, line in enumerate(lines) if line.strip() == "endheader") + 1
    names = lines[start].split("\t")
    rows = [[float(x) for x in line.split("\t")] for line in lines[start + 1:] if line.strip()]
    return {name: [row[k] for row in rows] for k, name in enumerate(names)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("orientations", type=Path, help="STEM_orientations.sto")
    parser.add_argument("calibration", type=Path, help="STEM_calibration.sto")
    parser.add_argument("-o", "--output", type=Path, default=Path("opensim_ik"),
                        help="output folder (default opensim_ik)")
    parser.add_argument("--model", type=Path, help="an .osim model (default: the small model)")
    args = parser.parse_args(argv)
    for path in (args.orientations, args.calibration, args.model):
        if path is not None and not path.is_file():
            print(f"opensim_ik: {path}: no such file", file=sys.stderr)
            return 2
    motion = run(args.orientations, args.calibration, args.output, args.model)
    columns = read_motion(motion)
    print(f"{motion} ({len(columns['time'])} frames)")
    for name, values in columns.items():
        if name != "time" and not name.endswith(("_tx", "_ty", "_tz")):
            print(f"{name:20s} {min(values):8.1f} .. {max(values):6.1f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
