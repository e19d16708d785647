"""The simulated subject: calibration posture and the functional-calibration movements.

- **Calibration posture** (:data:`POSTURES`, :func:`parse_posture`): the joint degrees of
  freedom (:data:`.motion.DOFS`, degrees) the subject holds whenever the script says "still"
  or "arms down". ``neutral`` is the model's standard pose (every DOF 0: upright, arms down,
  feet forward); ``suit`` is a pressure-suit posture: shoulders abducted 20°, elbows 15°,
  hips 10° and knees 15° flexed, ankles 5° dorsiflexed so that the feet stay flat. A custom
  posture names DOFs: ``"sh_r_abd=-20,elbow_r=15"``.
- **Functional movements** (:func:`functional_moves`): what the functional pose calibration
  needs, done from the posture after its still window: each knee flexed twice while the thigh
  swings and turns, each elbow flexed twice while the upper arm turns, an arm swing and four
  steps. :func:`functional_script` puts them in front of a script.

Signs are the script's (:mod:`.motion`): right shoulder abduction is negative, left positive.
"""

from __future__ import annotations

from bpms.firmware.sim.motion import DOFS, Move, Step, Still, Walk, default_script

#: Named calibration postures, DOF → degrees.
POSTURES: dict[str, dict[str, float]] = {
    "neutral": {},
    "suit": {"sh_r_abd": -20.0, "sh_l_abd": 20.0, "elbow_r": 15.0, "elbow_l": 15.0,
             "hip_r_flex": 10.0, "hip_l_flex": 10.0, "knee_r": 15.0, "knee_l": 15.0,
             "ankle_r": 5.0, "ankle_l": 5.0},
}


def parse_posture(text: str | dict | None) -> dict[str, float]:
    """A posture from its name (:data:`POSTURES`), ``"dof=deg,dof=deg"`` or a dict (None:
    neutral). Raises ValueError naming the choices."""
    if text is None:
        return {}
    if isinstance(text, dict):
        items = dict(text)
    elif str(text).strip().lower() in POSTURES:
        return dict(POSTURES[str(text).strip().lower()])
    else:
        items = {}
        for part in str(text).replace(";", ",").split(","):
            name, sep, value = part.partition("=")
            try:
                items[name.strip()] = float(value)
            except ValueError:
                sep = ""
            if not sep:
                raise ValueError(f"posture '{text}': not one of {', '.join(POSTURES)} nor "
                                 "'dof=deg,...' (e.g. 'elbow_r=15,knee_r=10')") from None
    unknown = sorted(set(items) - set(DOFS))
    if unknown:
        raise ValueError(f"posture: unknown degree(s) of freedom {', '.join(unknown)}; "
                         f"known: {', '.join(DOFS)}")
    return {k: float(v) for k, v in items.items()}


def functional_moves() -> list[Step]:
    """The functional-calibration movements, each from and back to the posture (≈ 27 s)."""
    moves: list[Step] = []
    for side in ("r", "l"):
        moves += [
            Move(f"knee {side} flexion 1", 1.2, {f"hip_{side}_flex": 35, f"knee_{side}": 70,
                                                 f"hip_{side}_abd": 8 if side == "l" else -8}),
            Move(f"knee {side} extension 1", 1.2),
            Move(f"knee {side} flexion 2", 1.2, {f"hip_{side}_flex": 20, f"knee_{side}": 60,
                                                 f"hip_{side}_abd": -8 if side == "l" else 8}),
            Move(f"knee {side} extension 2", 1.2, hold=0.3),
        ]
    for side in ("r", "l"):
        turn = 30 if side == "r" else -30
        moves += [
            Move(f"elbow {side} flexion 1", 1.0, {f"elbow_{side}": 90, f"sh_{side}_rot": turn,
                                                  f"sh_{side}_flex": 20}),
            Move(f"elbow {side} extension 1", 1.0),
            Move(f"elbow {side} flexion 2", 1.0, {f"elbow_{side}": 80, f"sh_{side}_rot": -turn,
                                                  f"sh_{side}_flex": 35}),
            Move(f"elbow {side} extension 2", 1.0, hold=0.3),
        ]
    moves += [
        Move("arm swing forward", 1.0, {"sh_r_flex": 40, "sh_l_flex": -25}),
        Move("arm swing back", 1.0, {"sh_r_flex": -25, "sh_l_flex": 40}),
        Move("arms to the posture", 1.0, hold=0.5),
        Walk("functional steps", steps=4, step_period=0.9, hip_amp_deg=15.0, knee_deg=30.0,
             arm_deg=10.0),
        Still("still (after the functional movements)", 2.0),
    ]
    return moves


def functional_script(script: list[Step] | None = None) -> list[Step]:
    """A still window in the posture, :func:`functional_moves`, then ``script`` (default: the
    standard trial)."""
    rest = default_script() if script is None else script
    return [Still("still (calibration posture)", 3.0), *functional_moves(), *rest]
