"""Leg poses from the walker's angles, and angles from leg poses (NumPy; model.md section 1).

These are the geometric conventions shared by the renderer and the tracker, in the physical
(unmirrored) frame: both legs have ``R = Rz(steer) Rx(lean) Ry(pitch)`` in the ramp frame S, with
their own pitch; a leg's body frame has its origin at that leg's hip point, ``b1`` forward, ``b2``
along the hip axis (to the left for both legs), ``b3`` along the leg from foot to hip. The left
leg's hip point is ``hip_width`` to the left (+b2) of the right leg's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .parameters import Params

__all__ = ["LegPoses", "angles_from_rotations", "leg_poses", "rotation"]


def rotation(steer: float, lean: float, pitch: float) -> np.ndarray:
    """``Rz(steer) Rx(lean) Ry(pitch)``, shape (3, 3): body axes as columns, in the ramp frame."""
    cz, sz = np.cos(steer), np.sin(steer)
    cx, sx = np.cos(lean), np.sin(lean)
    cy, sy = np.cos(pitch), np.sin(pitch)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    return rz @ rx @ ry


@dataclasses.dataclass
class LegPoses:
    """Both legs' poses in the ramp frame.

    Attributes
    ----------
    rotation : dict {'L', 'R'} -> ndarray (3, 3)
    hip : dict {'L', 'R'} -> ndarray (3,)
        Hip points (m), the body-frame origins.
    foot_centre : dict {'L', 'R'} -> ndarray (3,)
        Centre O of each foot's torus (m).
    """

    rotation: dict
    hip: dict
    foot_centre: dict


def _foot_offset(params: Params, n: np.ndarray) -> np.ndarray:
    """O - C: the foot centre relative to its lowest point (model.md section 2)."""
    ez = np.array([0.0, 0.0, 1.0])
    t = -ez + n[2] * n
    norm = np.linalg.norm(t)
    t = t / norm if norm > 0 else -ez
    return params.foot_lateral_radius * ez - (params.foot_radius - params.foot_lateral_radius) * t


def leg_poses(params: Params, steer: float, lean: float, pitch_left: float, pitch_right: float,
              stance: str, contact) -> LegPoses:
    """Both legs' poses from the angles, the stance leg and its contact point (ramp frame, m)."""
    if stance not in ("L", "R"):
        raise ValueError(f"stance must be 'L' or 'R', got {stance!r}")
    rot = {"L": rotation(steer, lean, pitch_left), "R": rotation(steer, lean, pitch_right)}
    n = rot["L"][:, 1]
    c = np.array([contact[0], contact[1], 0.0], dtype=float)
    leg_axis = params.leg_length - params.foot_radius
    o_st = c + _foot_offset(params, n)
    hip = {stance: o_st + leg_axis * rot[stance][:, 2]}
    other = "R" if stance == "L" else "L"
    hip[other] = hip[stance] + (-1.0 if stance == "L" else 1.0) * params.hip_width * n
    foot = {k: hip[k] - leg_axis * rot[k][:, 2] for k in ("L", "R")}
    return LegPoses(rotation=rot, hip=hip, foot_centre=foot)


def angles_from_rotations(r_left: np.ndarray, r_right: np.ndarray) -> tuple[float, float, float, float]:
    """(steer, lean, pitch_left, pitch_right) (rad) from the two legs' rotations.

    The hip axis b2 is shared: ``b2 = Rz(steer) Rx(lean) e_y = (-sin(steer) cos(lean),
    cos(steer) cos(lean), sin(lean))``; the pitch is the rotation about it. Measured rotations
    whose b2 axes differ (noise) are combined by averaging b2.
    """
    b2 = r_left[:, 1] + r_right[:, 1]
    b2 = b2 / np.linalg.norm(b2)
    lean = float(np.arcsin(np.clip(b2[2], -1.0, 1.0)))
    steer = float(np.arctan2(-b2[0], b2[1]))
    base = rotation(steer, lean, 0.0)
    pitches = []
    for r in (r_left, r_right):
        local = base.T @ r  # ~ Ry(pitch)
        pitches.append(float(np.arctan2(local[0, 2], local[2, 2])))
    return steer, lean, pitches[0], pitches[1]
