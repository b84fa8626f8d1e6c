"""The ramp frame in the camera frame, measured from the ramp markers, and a fixed pose checked
against it.

Every walker angle is measured in the ramp frame (docs/model.md section 1), so the rotation of the
ramp into the camera is part of every measurement: an error ``delta`` in it (a small rotation of
the ramp's axes, ``R = R_true exp([delta]x)``, in ramp coordinates: x downhill, y left, z along the
normal) shifts every lean by ``-delta_x``, every pitch by ``-delta_y`` and every steer by
``-delta_z`` (to first order, for a walker heading down the ramp). Its uncertainty is therefore
stated per axis, named by the angle it shifts (:data:`AXES`).

- A fixed camera (the video's ramp markers agree with one pose): one pose is fitted to each
  ramp-marker corner's mean position over the frames. Its covariance is ``s^2 (J^T J)^-1`` with
  ``s`` the residual of that fit (so systematic misfits, a lens or a layout not quite right,
  count as noise), the same error in every frame: a bias, reported, not added to the per-frame
  SDs.
- A moving camera (a following or hand-held shot): each frame's own pose and covariance
  ``sigma^2 (J^T J)^-1`` with the pooled corner noise ``sigma``; frames without ramp markers have
  no ramp frame (their angles are gaps). These errors are independent from frame to frame.
- A fixed pose from a camera file is checked against the measured one and refused when they
  disagree beyond the measurement's accuracy (:func:`check_fixed_pose`).

Pose fits: :func:`toywalk.tracking.pose.estimate_pose`; covariance as in Hartley & Zisserman
2004, Multiple View Geometry, 2nd ed., section 5.2.
"""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np

from .camera import Camera
from .pose import estimate_pose

__all__ = ["AXES", "CHECK_FLOOR", "CHECK_SDS", "RampFrame", "RampPoseError", "axis_covariance",
           "check_fixed_pose", "fixed_ramp", "measure_ramp", "ramp_difference"]

#: The walker angle an error in the ramp's rotation about its x, y, z axis shifts (same order).
AXES = ("lean", "pitch", "steer")
_AXIS_NAMES = ("x (downhill)", "y (across)", "z (normal)")

#: A fixed ramp pose is refused when, about some ramp axis, it differs from the measured pose by
#: more than CHECK_SDS standard deviations of the measurement (for a right pose and Gaussian
#: errors that happens with probability 6e-5 per axis) and by more than CHECK_FLOOR: the pixel
#: residuals do not show every systematic error (a marker printed 0.1 mm off over a 40 cm
#: board turns it by 0.015 deg), and a fixed pose within 0.05 deg shifts the angles by a sixth of
#: the tracker's 0.3 deg target at most.
CHECK_SDS = 4.0
CHECK_FLOOR = math.radians(0.05)

#: The camera counts as fixed when one pose fits the ramp markers of at least 90 % of the frames
#: to a reprojection RMS of max(1 px, 4 pooled corner SDs): a camera moving in more than a tenth of
#: the frames gets each frame's own pose (a few frames with a misdetected marker do not decide).
_STATIC_RMS_PX = 1.0
_STATIC_RMS_SDS = 4.0
_STATIC_SHARE = 90.0  # percentile of the frames' RMS
_MAX_JOINT_FRAMES = 400  # frames averaged into the fixed camera's corners (evenly picked)


class RampPoseError(ValueError):
    """A fixed ramp pose disagrees with the ramp markers in the video; one line naming the angle."""


@dataclasses.dataclass(frozen=True)
class RampFrame:
    """The ramp's rotation into the camera frame in each frame, with its uncertainty.

    Attributes
    ----------
    rotations : list of ndarray, shape (3, 3), or None
        Per frame, ramp frame to camera frame; None where unknown (those frames' angles are gaps).
    covariance : ndarray, shape (n, 3, 3)
        Per frame, the covariance (rad^2) of ``delta``, the rotation error about the ramp's axes
        (module docstring); NaN where unknown or not measured.
    per_frame : bool
        True when each frame has its own pose (a moving camera): errors independent between
        frames; False when one pose serves every frame: one error common to all.
    summary : dict
        JSON-ready: ``source`` (which pose, in words), the pose, ``sd_deg`` per angle
        (:data:`AXES`), and the fixed pose's ``check`` where one was given.
    """

    rotations: list
    covariance: np.ndarray
    per_frame: bool
    summary: dict

    @property
    def sd(self) -> np.ndarray:
        """(n, 3) standard deviations (rad) of the rotation about the ramp's x, y, z axes."""
        return np.sqrt(np.diagonal(self.covariance, axis1=1, axis2=2))


def ramp_difference(r_a: np.ndarray, r_b: np.ndarray) -> np.ndarray:
    """The small rotation ``delta`` (rad, shape (3,), about the ramp's x, y, z axes) with
    ``r_a = r_b exp([delta]x)``: how far the ramp axes of pose ``a`` are turned from those of ``b``.
    Measured with ``a`` the ramp rotation used and ``b`` the true one, the angles are shifted by
    ``-delta`` (module docstring)."""
    rel = np.asarray(r_b, float).T @ np.asarray(r_a, float)
    # the logarithm of a rotation, accurate for small ones too (OpenCV's Rodrigues rounds
    # rotations below 1e-5 rad to zero)
    w = 0.5 * np.array([rel[2, 1] - rel[1, 2], rel[0, 2] - rel[2, 0], rel[1, 0] - rel[0, 1]])
    s = float(np.linalg.norm(w))
    if s == 0.0:
        return np.zeros(3)
    return w * (math.atan2(s, 0.5 * (np.trace(rel) - 1.0)) / s)


def axis_covariance(rvec, rvec_covariance) -> np.ndarray:
    """Covariance (3, 3) of the rotation about the ramp's axes from that of a Rodrigues vector
    ``rvec`` (3, 3): ``J C J^T``, ``J`` = d delta / d rvec (central differences)."""
    rvec = np.asarray(rvec, float).reshape(3)
    base = cv2.Rodrigues(rvec)[0]
    h = 1e-6
    jac = np.empty((3, 3))
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        jac[:, j] = (ramp_difference(cv2.Rodrigues(rvec + step)[0], base)
                     - ramp_difference(cv2.Rodrigues(rvec - step)[0], base)) / (2 * h)
    return jac @ np.asarray(rvec_covariance, float) @ jac.T


def _sd_deg(covariance: np.ndarray) -> dict:
    sd = np.degrees(np.sqrt(np.clip(np.diagonal(covariance), 0.0, None)))
    return {name: float(v) for name, v in zip(AXES, sd, strict=True)}


def measure_ramp(camera: Camera, points: dict, detections: list, poses: list,
                 pixel_sd: float) -> RampFrame | None:
    """The ramp frame from the ramp markers found in a video, or None if none was found.

    Parameters
    ----------
    camera : Camera
    points : dict of int to ndarray, shape (4, 3)
        Each ramp marker's corners in the ramp frame (m), by id.
    detections : list of dict of int to ndarray, shape (4, 2)
        Per frame, the markers found (corners in pixels, by id; other bodies' ids are ignored).
    poses : list of PoseEstimate or None
        Per frame, the ramp's own pose fitted to that frame's ramp markers.
    pixel_sd : float
        The ramp markers' corner noise, pooled over the video (pixels).

    One pose fits every frame (a fixed camera) when the reprojection RMS against it is at most
    max(1 px, 4 ``pixel_sd``) in 90 % of the frames; otherwise each frame keeps its own.
    """
    n = len(poses)
    frames = [i for i, p in enumerate(poses) if p is not None]
    if not frames:
        return None
    ids = sorted(points)
    pick = frames if len(frames) <= _MAX_JOINT_FRAMES else [
        frames[k] for k in np.linspace(0, len(frames) - 1, _MAX_JOINT_FRAMES).astype(int)]
    # A static ramp: one pose fitted to each corner's mean position over the frames (the same
    # least-squares optimum as stacking every frame, without repeated object points, which the
    # closed-form PnP solvers reject).
    obj, img = [], []
    for m in ids:
        seen = [detections[i][m] for i in pick if m in detections[i]]
        if seen:
            obj.append(points[m])
            img.append(np.mean(seen, axis=0))
    first = poses[pick[0]]
    joint = estimate_pose(camera, np.concatenate(obj), np.concatenate(img),
                          guess=(first.rvec, first.tvec), max_rms=np.inf)
    rms = []
    if joint is not None:
        for i in pick:
            seen = [m for m in ids if m in detections[i]]
            uv, _ = cv2.projectPoints(np.concatenate([points[m] for m in seen]).reshape(-1, 1, 3),
                                      joint.rvec.reshape(3, 1), joint.tvec.reshape(3, 1),
                                      camera.matrix, camera.distortion)
            found = np.concatenate([detections[i][m] for m in seen])
            rms.append(float(np.sqrt(np.mean((uv.reshape(-1, 2) - found) ** 2))))
    limit = max(_STATIC_RMS_PX, _STATIC_RMS_SDS * pixel_sd)
    if joint is not None and float(np.percentile(rms, _STATIC_SHARE)) <= limit:
        dof = 2 * joint.n_points - 6
        s = joint.rms * math.sqrt(2 * joint.n_points / dof) if dof > 0 else pixel_sd
        cov = axis_covariance(joint.rvec, joint.covariance(max(s, 1e-3))[:3, :3])
        rot = cv2.Rodrigues(joint.rvec.reshape(3, 1))[0]
        summary = {"source": f"ramp markers, one fixed pose fitted to {len(pick)} frames (a fixed camera)",
                   "rvec": joint.rvec.tolist(), "tvec": joint.tvec.tolist(), "rms_px": joint.rms,
                   "sd_deg": _sd_deg(cov),
                   "sd_note": "one error common to every frame (a bias), not in the per-frame SDs"}
        return RampFrame(rotations=[rot] * n, covariance=np.broadcast_to(cov, (n, 3, 3)).copy(),
                         per_frame=False, summary=summary)
    rotations, covariance = [None] * n, np.full((n, 3, 3), np.nan)
    for i in frames:
        p = poses[i]
        rotations[i] = cv2.Rodrigues(p.rvec.reshape(3, 1))[0]
        covariance[i] = axis_covariance(p.rvec, p.covariance(pixel_sd)[:3, :3])
    moved = (f"by {np.percentile(rms, _STATIC_SHARE):.2g} px or more in a tenth of the frames" if rms
             else "by more than any one pose explains")
    summary = {"source": f"ramp markers, each frame's own pose in {len(frames)} of {n} frames (the "
                         f"camera moves: one fixed pose misses the markers {moved})",
               "frames": len(frames),
               "sd_deg": _sd_deg(np.nanmedian(covariance[frames], axis=0)),
               "sd_note": "median per frame; independent between frames, included in the per-frame SDs"}
    return RampFrame(rotations=rotations, covariance=covariance, per_frame=True, summary=summary)


def check_fixed_pose(rvec, measured: RampFrame) -> dict:
    """Compare a fixed ramp pose (a camera file's ``ramp_pose`` rotation) with the measured one.

    Per ramp axis, the disagreement is ``|delta|`` (:func:`ramp_difference`; for a moving camera,
    its median over the frames measured) and the limit ``max(CHECK_SDS * sd, CHECK_FLOOR)`` with
    ``sd`` the measurement's standard deviation about that axis (median over frames).

    Returns
    -------
    dict
        ``disagreement_deg`` and ``limit_deg`` per angle (:data:`AXES`), when within the limits.

    Raises
    ------
    RampPoseError
        One line naming the angle the fixed pose would shift most (relative to its limit), by how
        much, and the limit.
    """
    fixed = cv2.Rodrigues(np.asarray(rvec, float).reshape(3, 1))[0]
    known = [i for i, r in enumerate(measured.rotations) if r is not None]
    if not known:
        raise ValueError("the measured ramp frame has no frame with a pose")
    if not measured.per_frame:
        known = known[:1]  # one pose serves every frame
    delta = np.array([ramp_difference(fixed, measured.rotations[i]) for i in known])
    size = np.median(np.abs(delta), axis=0)
    sd = np.nanmedian(measured.sd[known], axis=0)
    limit = np.maximum(CHECK_SDS * np.nan_to_num(sd, nan=0.0), CHECK_FLOOR)
    k = int(np.argmax(size / limit))
    if size[k] > limit[k]:
        if measured.per_frame:
            by = f"by {math.degrees(size[k]):.2f} deg (median over {len(known)} frames of a moving camera)"
        else:
            by = f"by {-math.degrees(delta[0, k]):+.2f} deg"
        raise RampPoseError(
            f"the camera file's ramp_pose disagrees with the ramp markers in the video: it would shift "
            f"every {AXES[k]} {by} (a turn about the ramp's {_AXIS_NAMES[k]} axis; the markers "
            f"measure it to {math.degrees(sd[k]):.3f} deg, limit {math.degrees(limit[k]):.2f} deg); "
            "this is not where the camera stood: remove ramp_pose from the camera file to use the "
            "measured pose")
    return {"disagreement_deg": {a: float(math.degrees(v)) for a, v in zip(AXES, size, strict=True)},
            "limit_deg": {a: float(math.degrees(v)) for a, v in zip(AXES, limit, strict=True)}}


def fixed_ramp(n: int, pose, measured: RampFrame | None) -> RampFrame:
    """The ramp frame of a camera file's fixed ``ramp_pose`` (rvec, tvec) for ``n`` frames, after
    :func:`check_fixed_pose` against the measured one where the video shows ramp markers (raises
    :class:`RampPoseError` on a disagreement). Where the two agree, the fixed pose is used: the
    user's own calibration, confirmed."""
    rvec, tvec = (np.asarray(v, float).reshape(3) for v in pose)
    rot = cv2.Rodrigues(rvec.reshape(3, 1))[0]
    summary = {"rvec": rvec.tolist(), "tvec": tvec.tolist()}
    if measured is None:
        summary["source"] = "camera file (fixed ramp_pose); not checked: no ramp marker seen"
    else:
        check = check_fixed_pose(rvec, measured)
        worst = max(check["disagreement_deg"].values())
        summary.update(source=f"camera file (fixed ramp_pose), confirmed by the ramp markers "
                              f"(within {worst:.3f} deg)", check=check, measured=measured.summary)
    return RampFrame(rotations=[rot] * n, covariance=np.full((n, 3, 3), np.nan), per_frame=False,
                     summary=summary)
