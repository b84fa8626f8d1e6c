"""The walker's angles and their standard deviations from the joint leg fits (model.md section 1).

A joint fit (:class:`toywalk.tracking.joint.WalkerPose`) gives the axle frame and each seen leg's
pitch about it, in the camera frame; turned into the ramp frame, the legs' rotations give
``lean, steer, pitch_left, pitch_right`` through the inverse of the model's leg rotation
``Rz(steer) Rx(lean) Ry(pitch)`` (:func:`toywalk.model.kinematics.hip_axis_angles`,
:func:`toywalk.model.kinematics.pitch_angle`, as
:func:`toywalk.model.kinematics.angles_from_rotations`; the joint fit's legs share b2 exactly, so
no averaging; one leg seen: the other pitch a gap). Their standard deviations propagate the fit's covariance
``sigma^2 (J^T J)^-1`` (Hartley & Zisserman 2004, Multiple View Geometry, 2nd ed., section 5.2),
with the pixel noise ``sigma`` pooled over the video from the reprojection residuals
(:func:`pooled_pixel_sd`, :func:`pooled_walker_sd`), through the angle function by finite
differences.

Angles are returned in the order ``(lean, steer, pitch_left, pitch_right)`` (rad), the trajectory
file's :data:`toywalk.model.trajectory.SIGNALS` names.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..model.kinematics import hip_axis_angles, pitch_angle, rotation
from .joint import FEET, WalkerPose, rot_y

__all__ = ["ANGLE_NAMES", "pooled_pixel_sd", "pooled_walker_sd", "walker_angles", "walker_angles_with_sd"]

#: The order of :func:`walker_angles`' values.
ANGLE_NAMES = ("lean", "steer", "pitch_left", "pitch_right")


def walker_angles(r_ramp: np.ndarray, pose: WalkerPose) -> np.ndarray:
    """The angles of a joint leg pose; NaN for an unseen leg's pitch.

    The hip axis b2 gives steer and lean (``b2 = Rz(steer) Rx(lean) e_y``, model.md section 1,
    :func:`toywalk.model.kinematics.hip_axis_angles`), each leg its pitch about it
    (:func:`toywalk.model.kinematics.pitch_angle`): the axle frame relative to
    ``Rz(steer) Rx(lean)`` times the leg's ``Ry(pitch)`` about the axle.

    Parameters
    ----------
    r_ramp : ndarray, shape (3, 3)
        Rotation of the ramp frame into the camera frame.
    pose : WalkerPose
        The joint fit of the legs (camera frame).

    Returns
    -------
    ndarray, shape (4,)
        ``(lean, steer, pitch_left, pitch_right)`` (rad).
    """
    axle = r_ramp.T @ pose.axle
    steer, lean = hip_axis_angles(axle[:, 1])
    in_base = rotation(steer, lean, 0.0).T @ axle  # ~ Ry(the axle frame's pitch)
    pitches = [pitch_angle(in_base @ rot_y(pose.pitch[f])) if f in pose.seen else math.nan for f in FEET]
    return np.array([lean, steer, *pitches])


def walker_angles_with_sd(r_ramp: np.ndarray, pose: WalkerPose, pixel_sd: float,
                          ramp_covariance=None) -> tuple[dict, dict]:
    """Angles of a joint leg pose and their standard deviations.

    The covariance ``pixel_sd^2 (J^T J)^-1`` of the fit is propagated through
    :func:`walker_angles` by finite differences. It is inflated by ``(rms / rms_expected)^2`` when
    the frame's residual exceeds what the pooled pixel noise explains (blur, a bent edge): such
    a pose is less certain than its Jacobian says.

    Parameters
    ----------
    r_ramp : ndarray, shape (3, 3)
        Rotation of the ramp frame into the camera frame.
    pose : WalkerPose
        The joint fit of the legs (camera frame), with ``normal`` = ``(J^T J)^-1``.
    pixel_sd : float
        Pixel noise SD (pixels), e.g. :func:`pooled_walker_sd`.
    ramp_covariance : ndarray, shape (3, 3), optional
        Covariance (rad^2) of the ramp rotation's error about its own axes
        (:mod:`toywalk.tracking.ramp`), where it is this frame's own: propagated alike and added.

    Returns
    -------
    values, sds : dict of str -> float
        :data:`ANGLE_NAMES` -> angle and SD (rad); NaN for the pitch of a leg not seen.
    """
    base = walker_angles(r_ramp, pose)
    angular = [j for j, name in enumerate(pose.names) if name in ("d1", "d3", "pitch_L", "pitch_R")]
    h = 1e-7
    jac = np.zeros((4, len(angular)))
    for c, j in enumerate(angular):
        step = np.zeros(len(pose.names))
        step[j] = h
        jac[:, c] = (walker_angles(r_ramp, pose.perturbed(step)) - base) / h
    jac = np.nan_to_num(jac)
    cov = pose.normal[np.ix_(angular, angular)] * pixel_sd**2
    if pose.dof > 0:
        expected = pixel_sd * math.sqrt(pose.dof / (pose.dof + len(pose.names)))
        cov = cov * max(1.0, (pose.rms / expected) ** 2)
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    if ramp_covariance is not None and np.all(np.isfinite(ramp_covariance)):
        turned = np.zeros((4, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = h
            turned[:, j] = (walker_angles(r_ramp @ cv2.Rodrigues(step)[0], pose) - base) / h
        turned = np.nan_to_num(turned)
        var = var + np.einsum("ij,jk,ik->i", turned, np.asarray(ramp_covariance, float), turned)
    sd = np.sqrt(np.maximum(var, 0.0))
    sd[~np.isfinite(base)] = np.nan
    return dict(zip(ANGLE_NAMES, base, strict=True)), dict(zip(ANGLE_NAMES, sd, strict=True))


def pooled_pixel_sd(poses) -> float:
    """Pixel noise SD pooled over the frames of one body's own pose fits, robustly.

    The median over frames of each frame's residual RMS corrected for the six fitted parameters
    (``rms * sqrt(2n / (2n - 6))``), scaled so that it estimates the SD for Gaussian noise (the
    median of a chi distribution lies below its RMS).

    Parameters
    ----------
    poses : sequence of PoseEstimate or None
        One per frame (:class:`toywalk.tracking.pose.PoseEstimate`); None where not found.

    Returns
    -------
    float
        Pixels; 0.5 (a conservative guess) when no frame has redundant points, never below 0.02
        (sub-pixel corners are never better).
    """
    values = [p.rms * math.sqrt(2 * p.n_points / (2 * p.n_points - 6))
              for p in poses if p is not None and 2 * p.n_points > 6]
    if not values:
        return 0.5  # pixels: a conservative guess when no frame has redundant points
    dof = np.median([2 * p.n_points - 6 for p in poses if p is not None and 2 * p.n_points > 6])
    from scipy.stats import chi

    ratio = chi.median(dof) / math.sqrt(dof)  # median of rms/sigma for dof degrees of freedom
    return max(float(np.median(values)) / ratio, 0.02)  # floor: sub-pixel corners are never better


def pooled_walker_sd(poses) -> float:
    """Pixel noise SD pooled over the joint leg fits, as :func:`pooled_pixel_sd`.

    Parameters
    ----------
    poses : sequence of WalkerPose or None
        One per frame; None where no leg was found.

    Returns
    -------
    float
        Pixels, with the same guess and floor as :func:`pooled_pixel_sd`.
    """
    good = [p for p in poses if p is not None and p.dof > 0]
    if not good:
        return 0.5  # pixels: a conservative guess when no frame has redundant points
    values = [p.rms * math.sqrt((p.dof + len(p.names)) / p.dof) for p in good]
    dof = float(np.median([p.dof for p in good]))
    from scipy.stats import chi

    ratio = chi.median(dof) / math.sqrt(dof)
    return max(float(np.median(values)) / ratio, 0.02)
