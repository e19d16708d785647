"""Whole-body centre of mass from the body model's joint positions (docs/subject.md).

Segment mass fractions and centre-of-mass locations of Dempster (1955) as tabulated by
D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009,
Table 4.1 (the same book as the subject profile's length proportions,
:mod:`bpms.io.subject`): each segment's centre lies at a fraction of the way from its proximal
to its distal point. Mapped onto the body model's points (docs/body-model.md):

| segment (Winter) | mass fraction | from → to (model points) | centre at |
|---|---|---|---|
| hand | 0.006 | wrist → fingers | 0.506 |
| forearm | 0.016 | elbow → wrist | 0.430 |
| upper arm | 0.028 | shoulder → elbow | 0.436 |
| foot | 0.0145 | ankle → toe | 0.50 |
| leg | 0.0465 | knee → ankle | 0.433 |
| thigh | 0.100 | hip → knee | 0.433 |
| head and neck | 0.081 | neck base (C7–T1) → head base (ear canal) | 1.000 |
| trunk | 0.497 | mid-hips (greater trochanters) → mid-shoulders (glenohumeral joints) | 0.50 |

The fractions add up to 1; the centre is their weighted mean, independent of the mass itself.
"""

from __future__ import annotations

import numpy as np

from bpms.filter.body_model import POINT_INDEX

#: (mass fraction, proximal points, distal points, centre's fraction from proximal); a list of
#: points is their mean.
SEGMENTS: tuple[tuple[float, tuple[str, ...], tuple[str, ...], float], ...] = (
    *((0.006, (f"wrist_{s}",), (f"fingers_{s}",), 0.506) for s in "rl"),
    *((0.016, (f"elbow_{s}",), (f"wrist_{s}",), 0.430) for s in "rl"),
    *((0.028, (f"shoulder_{s}",), (f"elbow_{s}",), 0.436) for s in "rl"),
    *((0.0145, (f"ankle_{s}",), (f"toe_{s}",), 0.50) for s in "rl"),
    *((0.0465, (f"knee_{s}",), (f"ankle_{s}",), 0.433) for s in "rl"),
    *((0.100, (f"hip_{s}",), (f"knee_{s}",), 0.433) for s in "rl"),
    (0.081, ("neck_base",), ("head_base",), 1.0),
    (0.497, ("hip_r", "hip_l"), ("shoulder_r", "shoulder_l"), 0.50),
)
assert abs(sum(s[0] for s in SEGMENTS) - 1.0) < 1e-9, "mass fractions must add up to 1"


def _weights() -> np.ndarray:
    """``[21]``: the centre of mass as a weighted sum of the points (weights add up to 1)."""
    w = np.zeros(len(POINT_INDEX))
    for mass, proximal, distal, at in SEGMENTS:
        for name in proximal:
            w[POINT_INDEX[name]] += mass * (1.0 - at) / len(proximal)
        for name in distal:
            w[POINT_INDEX[name]] += mass * at / len(distal)
    return w


WEIGHTS = _weights()


def centre_of_mass(joint_positions: np.ndarray) -> np.ndarray:
    """``[..., 3]`` m: the whole body's centre of mass from the joint positions
    ``[..., 21, 3]`` (same frame and units); NaN where a point is NaN."""
    return np.einsum("p,...pi->...i", WEIGHTS, np.asarray(joint_positions, dtype=np.float64))
