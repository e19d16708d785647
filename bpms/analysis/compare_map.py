"""Which optical body is which BPMS segment (``bpms compare --map``).

A map file has one pair per line, ``optical body = BPMS segment`` (``,`` or a tab may stand
for ``=``; ``#`` starts a comment). The segment is an IMU name (``Right Forearm``,
``right_forearm``) or its index 0-17 (docs/suit.md). Without a map, :data:`DEFAULT_MAP` pairs
the names that Vicon Nexus's Plug-in Gait and Qualisys QTM's skeleton (Animation / Sports
marker sets) give their segments with the suit's IMUs; the first name of a list found in the
file wins.
"""

from __future__ import annotations

from pathlib import Path

from bpms.analysis.mocap_import import MocapExport, UnknownBodyError
from bpms.io.frames import IMU_NAMES


class CompareError(Exception):
    """Inputs that cannot be compared (one line: no overlap, missing body, bad map...)."""


#: BPMS IMU name → optical body names, preferred first: Plug-in Gait (Nexus), QTM skeleton,
#: then the IMU's own name. (QTM's "RightLeg" is the shank; the suit's "Right Leg" the thigh.)
DEFAULT_MAP: dict[str, tuple[str, ...]] = {
    "Hip": ("Pelvis", "Hips"),
    "Spine": ("Thorax", "Spine1", "Spine2", "Chest", "Spine"),
    "Neck": ("Neck",),
    "Head": ("Head",),
    "Right Shoulder": ("RClavicle", "RightShoulder"),
    "Right Arm": ("RHumerus", "RightArm", "RUpperArm"),
    "Right Forearm": ("RRadius", "RightForeArm", "RForearm"),
    "Right Hand": ("RHand", "RightHand"),
    "Right Leg": ("RFemur", "RightUpLeg", "RThigh"),
    "Right Shank": ("RTibia", "RightLeg", "RShank"),
    "Right Foot": ("RFoot", "RightFoot"),
    "Left Shoulder": ("LClavicle", "LeftShoulder"),
    "Left Arm": ("LHumerus", "LeftArm", "LUpperArm"),
    "Left Forearm": ("LRadius", "LeftForeArm", "LForearm"),
    "Left Hand": ("LHand", "LeftHand"),
    "Left Leg": ("LFemur", "LeftUpLeg", "LThigh"),
    "Left Shank": ("LTibia", "LeftLeg", "LShank"),
    "Left Foot": ("LFoot", "LeftFoot"),
}


def segment_index(text: str) -> int:
    """IMU index of a segment name (any case, spaces or underscores) or number; ValueError."""
    key = text.strip().lower().replace("_", " ")
    if key.isdigit() and int(key) < len(IMU_NAMES):
        return int(key)
    for k, name in enumerate(IMU_NAMES):
        if name.lower() == key:
            return k
    raise ValueError(f"{text.strip()!r} is not a BPMS segment (one of "
                     f"{', '.join(IMU_NAMES)}, or 0-{len(IMU_NAMES) - 1})")


def read_map(path: str | Path) -> list[tuple[str, int]]:
    """(optical body, IMU index) pairs of a map file; CompareError naming the line."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise CompareError(f"{path}: the map cannot be read ({exc})") from None
    pairs: list[tuple[str, int]] = []
    for number, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        for sep in ("=", "\t", ","):
            if sep in text:
                body, segment = (s.strip() for s in text.split(sep, 1))
                break
        else:
            raise CompareError(f"{path}: line {number}: expected 'optical body = BPMS "
                               f"segment', got {text[:40]!r}")
        try:
            imu = segment_index(segment)
        except ValueError as exc:
            raise CompareError(f"{path}: line {number}: {exc}") from None
        if not body:
            raise CompareError(f"{path}: line {number}: no optical body name")
        if any(imu == k for _, k in pairs):
            raise CompareError(f"{path}: line {number}: segment {IMU_NAMES[imu]!r} is mapped "
                               "twice")
        pairs.append((body, imu))
    if not pairs:
        raise CompareError(f"{path}: the map pairs no body with a segment")
    return pairs


def resolve_map(export: MocapExport, mapping: str | Path | None
                ) -> tuple[list[tuple[str, int]], list[str]]:
    """(pairs of the export's body name and IMU index, the export's bodies left out). With a
    map file every body it names must be in the export (CompareError otherwise); without, the
    default names, at least one of which must be found."""
    if mapping is not None:
        pairs = []
        for body, imu in read_map(mapping):
            try:
                pairs.append((export.body(body).name, imu))
            except UnknownBodyError as exc:
                raise CompareError(str(exc)) from None
    else:
        pairs = []
        for imu, name in enumerate(IMU_NAMES):
            for alias in (*DEFAULT_MAP[name], name):
                try:
                    body = export.body(alias).name
                except UnknownBodyError:
                    continue
                if all(body != b for b, _ in pairs):
                    pairs.append((body, imu))
                    break
        if not pairs:
            raise CompareError(f"{export.path}: no body has a name of the default map "
                               f"({', '.join(export.bodies)}); give one with --map")
    used = {b for b, _ in pairs}
    return pairs, [b for b in export.bodies if b not in used]
