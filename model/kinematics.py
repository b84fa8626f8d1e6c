"""Leg poses from the walker's angles, and angles from leg poses (NumPy; docs/model.md section 1).

These are the geometric conventions shared by the renderer and the tracker, in the physical
(unmirrored) frame: both legs have ``R = Rz(steer) Rx(lean) Ry(pitch)`` in the ramp frame S, with
their own pitch; a leg's body frame has its origin at that leg's hip point, ``b1`` forward, ``b2``
along the hip axis (to the left for both legs), ``b3`` along the leg from foot to hip. The left
leg's hip point is ``hip_width`` to the left (+b2) of the right leg's.

Each piece of this geometry is written once, here, and imported wherever it is needed: a foot's
lowest point (:func:`lowest_point`, :func:`lowest_point_offset`; the renderer's contact points, the
hip placed from a contact) and the angles of measured leg rotations (:func:`angles_from_rotations`,
:func:`hip_axis_angles`, :func:`pitch_angle`; the tracker, the MuJoCo check).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .parameters import Params

__all__ = ["LegPoses", "angles_from_rotations", "hip_axis_angles", "leg_poses", "lowest_point",
           "lowest_point_offset", "pitch_angle", "rotation"]


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


def lowest_point_offset(params: Params, hip_axis: np.ndarray) -> np.ndarray:
    """C - O: a foot's lowest point C relative to the centre O of its torus (ramp frame, m).

    The foot is a torus about the hip axis ``n`` (docs/model.md section 2): its centre circle has radius
    ``foot_radius - foot_lateral_radius`` in the plane normal to ``n``, its tube radius
    ``foot_lateral_radius``. The lowest point lies below the centre circle's lowest point,
    ``C - O = (r - rho) t - rho e_z`` with ``t`` the unit vector of ``-e_z + (n . e_z) n`` (the
    steepest descent within that plane; ``-e_z`` when ``n`` is vertical).

    Parameters
    ----------
    params : Params
        ``foot_radius`` r and ``foot_lateral_radius`` rho (m).
    hip_axis : ndarray, shape (3,)
        The unit hip axis ``n = b2`` in the ramp frame.

    Returns
    -------
    ndarray, shape (3,)
        ``C - O`` (m).
    """
    n = hip_axis
    ez = np.array([0.0, 0.0, 1.0])
    t = -ez + n[2] * n
    norm = np.linalg.norm(t)
    t = t / norm if norm > 0 else -ez
    return (params.foot_radius - params.foot_lateral_radius) * t - params.foot_lateral_radius * ez


def lowest_point(params: Params, rotation: np.ndarray, hip: np.ndarray) -> np.ndarray:
    """A foot's lowest point C (ramp frame, m) for its leg's pose.

    Parameters
    ----------
    params : Params
        ``leg_length``, ``foot_radius``, ``foot_lateral_radius`` (m).
    rotation : ndarray, shape (3, 3)
        The leg's rotation (body axes b1, b2, b3 as columns, ramp frame).
    hip : ndarray, shape (3,)
        The leg's hip point (m, ramp frame).

    Returns
    -------
    ndarray, shape (3,)
        C = O + (C - O) with the foot centre ``O = hip - (leg_length - foot_radius) b3``
        (:func:`lowest_point_offset`).
    """
    centre = hip - (params.leg_length - params.foot_radius) * rotation[:, 2]
    return centre + lowest_point_offset(params, rotation[:, 1])


def leg_poses(params: Params, steer: float, lean: float, pitch_left: float, pitch_right: float,
              stance: str, contact) -> LegPoses:
    """Both legs' poses from the angles, the stance leg and its contact point (ramp frame, m)."""
    if stance not in ("L", "R"):
        raise ValueError(f"stance must be 'L' or 'R', got {stance!r}")
    rot = {"L": rotation(steer, lean, pitch_left), "R": rotation(steer, lean, pitch_right)}
    n = rot["L"][:, 1]
    c = np.array([contact[0], contact[1], 0.0], dtype=float)
    leg_axis = params.leg_length - params.foot_radius
    o_st = c - lowest_point_offset(params, n)  # O = C - (C - O)
    hip = {stance: o_st + leg_axis * rot[stance][:, 2]}
    other = "R" if stance == "L" else "L"
    hip[other] = hip[stance] + (-1.0 if stance == "L" else 1.0) * params.hip_width * n
    foot = {k: hip[k] - leg_axis * rot[k][:, 2] for k in ("L", "R")}
    return LegPoses(rotation=rot, hip=hip, foot_centre=foot)


def hip_axis_angles(b2: np.ndarray) -> tuple[float, float]:
    """(steer, lean) (rad) of a hip axis: the inverse of ``b2 = Rz(steer) Rx(lean) e_y``.

    ``b2 = (-sin(steer) cos(lean), cos(steer) cos(lean), sin(lean))`` (docs/model.md section 1), so
    ``lean = asin(b2_z)`` and ``steer = atan2(-b2_x, b2_y)``.

    Parameters
    ----------
    b2 : ndarray, shape (3,)
        The hip axis in the ramp frame, a unit vector (its z component is clipped to [-1, 1]).
    """
    lean = math.asin(float(np.clip(b2[2], -1.0, 1.0)))
    steer = math.atan2(-b2[0], b2[1])
    return steer, lean


def pitch_angle(local: np.ndarray) -> float:
    """The angle (rad) of a rotation about the y axis: the inverse of ``Ry(pitch)``.

    ``Ry(pitch)`` has ``sin(pitch)`` and ``cos(pitch)`` at [0, 2] and [2, 2]. A leg's pitch is
    this of its rotation relative to ``Rz(steer) Rx(lean)`` (docs/model.md section 1), e.g.
    ``pitch_angle(rotation(steer, lean, 0).T @ r)``; for a measured rotation whose b2 axis differs
    slightly from the frame's, it is the pitch of its b3 axis projected on the frame's (b1, b3)
    plane.

    Parameters
    ----------
    local : ndarray, shape (3, 3)
        The rotation, ~``Ry(pitch)``.
    """
    return math.atan2(local[0, 2], local[2, 2])


def angles_from_rotations(r_left: np.ndarray, r_right: np.ndarray) -> tuple[float, float, float, float]:
    """(steer, lean, pitch_left, pitch_right) (rad) from the two legs' rotations.

    The hip axis b2 is shared: ``b2 = Rz(steer) Rx(lean) e_y`` (:func:`hip_axis_angles`); the pitch
    is the rotation about it (:func:`pitch_angle`). Measured rotations whose b2 axes differ (noise)
    are combined by averaging b2.

    Parameters
    ----------
    r_left, r_right : ndarray, shape (3, 3)
        Each leg's rotation in the ramp frame (body axes as columns).

    Returns
    -------
    tuple of float
        ``(steer, lean, pitch_left, pitch_right)`` (rad).
    """
    b2 = r_left[:, 1] + r_right[:, 1]
    b2 = b2 / np.linalg.norm(b2)
    steer, lean = hip_axis_angles(b2)
    base = rotation(steer, lean, 0.0)
    return steer, lean, pitch_angle(base.T @ r_left), pitch_angle(base.T @ r_right)
