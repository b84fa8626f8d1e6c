"""Rigid-body pose from marker corners (perspective-n-point), with its covariance.

One body's pose is estimated from all its visible marker corners jointly: IPPE for one planar
marker or several coplanar ones (Collins & Bartoli 2014, Int. J. Comput. Vis. 109:252,
doi:10.1007/s11263-014-0725-5), SQPnP otherwise (Terzakis & Lourakis 2020, ECCV,
doi:10.1007/978-3-030-58452-8_28), or OpenCV's iterative solver from a predicted pose, each then
refined by Levenberg-Marquardt on the reprojection error. The covariance of the six pose
parameters is ``sigma^2 (J^T J)^-1`` with ``J`` the Jacobian of the projected corners and ``sigma``
the pixel noise (Hartley & Zisserman 2004, Multiple View Geometry, 2nd ed., section 5.2).
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from .camera import Camera

__all__ = ["PoseEstimate", "estimate_pose", "reprojection_residuals"]

_LM = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 1e-10)


@dataclasses.dataclass(frozen=True)
class PoseEstimate:
    """A body's pose in the camera frame from n point correspondences.

    Attributes
    ----------
    rvec, tvec : ndarray, shape (3,)
        ``X_cam = R(rvec) X_body + tvec`` (rad, m).
    rms : float
        RMS reprojection error per coordinate (pixels).
    n_points : int
    normal : ndarray, shape (6, 6)
        ``(J^T J)^-1`` of the (rvec, tvec) parameters for unit pixel variance: the covariance is
        ``sigma^2 * normal`` for pixel noise ``sigma``.
    """

    rvec: np.ndarray
    tvec: np.ndarray
    rms: float
    n_points: int
    normal: np.ndarray

    def covariance(self, pixel_sd: float) -> np.ndarray:
        """Covariance (6, 6) of (rvec, tvec) for a pixel noise standard deviation (pixels)."""
        return pixel_sd**2 * self.normal


def reprojection_residuals(camera: Camera, object_points, image_points, rvec, tvec):
    """(residuals, shape (2n,), Jacobian, shape (2n, 6)) of projected minus measured pixels."""
    proj, jac = cv2.projectPoints(np.asarray(object_points, float).reshape(-1, 1, 3),
                                  np.asarray(rvec, float).reshape(3, 1),
                                  np.asarray(tvec, float).reshape(3, 1),
                                  camera.matrix, camera.distortion)
    res = (proj.reshape(-1, 2) - np.asarray(image_points, float).reshape(-1, 2)).ravel()
    return res, jac[:, :6]


def _coplanar(points: np.ndarray) -> bool:
    centred = points - points.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    return s[2] <= 1e-9 * max(s[0], 1e-12)


def _candidates(camera, obj, img, guess):
    """Initial solutions: from the guess and from a closed-form solver."""
    out = []
    if guess is not None:
        ok, r, t = cv2.solvePnP(obj, img, camera.matrix, camera.distortion,
                                np.asarray(guess[0], float).reshape(3, 1).copy(),
                                np.asarray(guess[1], float).reshape(3, 1).copy(),
                                useExtrinsicGuess=True, flags=cv2.SOLVEPNP_ITERATIVE)
        if ok:
            out.append((r, t))
    if _coplanar(obj):
        n, rs, ts, _ = cv2.solvePnPGeneric(obj, img, camera.matrix, camera.distortion,
                                           flags=cv2.SOLVEPNP_IPPE)
        out.extend((r, t) for r, t in zip(rs[:n], ts[:n], strict=True)
                   if np.all(np.isfinite(r)) and np.all(np.isfinite(t)))
    if not out or not _coplanar(obj):
        # SQPnP handles planar sets too; IPPE has been seen to return NaN for some large ones
        # SQPnP asserts on point sets of small spatial variance (in m^2): fall back to EPnP.
        for flag in (cv2.SOLVEPNP_SQPNP, cv2.SOLVEPNP_EPNP):
            try:
                ok, r, t = cv2.solvePnP(obj, img, camera.matrix, camera.distortion, flags=flag)
            except cv2.error:
                continue
            if ok:
                out.append((r, t))
                break
    return out


def estimate_pose(camera: Camera, object_points, image_points, *, guess=None,
                  max_rms: float = 4.0, trust_guess: float = 0.0) -> PoseEstimate | None:
    """The pose best explaining the correspondences, or None if none fits to ``max_rms`` pixels.

    Parameters
    ----------
    object_points : array_like, shape (n, 3)
        Points in the body frame (m), n >= 4.
    image_points : array_like, shape (n, 2)
        Their measured pixels (u, v).
    guess : (rvec, tvec), optional
        A predicted pose (e.g. from the previous frames): tried first; among the planar
        solver's two mirror solutions, the one nearer to the guess wins when both fit alike.
    trust_guess : float
        Pixels: when the fit refined from ``guess`` alone has an RMS error at most this, it is
        taken without trying the closed-form solvers (for a body of many markers, which has no
        mirror ambiguity, followed from frame to frame). 0 always tries them.
    """
    obj = np.ascontiguousarray(np.asarray(object_points, float).reshape(-1, 3))
    img = np.ascontiguousarray(np.asarray(image_points, float).reshape(-1, 2))
    if len(obj) != len(img) or len(obj) < 4:
        raise ValueError(f"need n >= 4 matching object and image points, got {len(obj)} and {len(img)}")
    fits = []

    def refine(r, t):
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):
            return
        r, t = cv2.solvePnPRefineLM(obj, img, camera.matrix, camera.distortion, r.copy(), t.copy(), _LM)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))) or t[2, 0] <= 0:
            return
        res, jac = reprojection_residuals(camera, obj, img, r, t)
        rms = float(np.sqrt(np.mean(res**2)))
        if np.isfinite(rms) and np.all(np.isfinite(jac)):
            fits.append((rms, r.ravel(), t.ravel(), jac))

    if guess is not None and trust_guess > 0:
        refine(np.asarray(guess[0], float).reshape(3, 1), np.asarray(guess[1], float).reshape(3, 1))
        if fits and fits[0][0] <= trust_guess:
            return _estimate(fits[0], len(obj), max_rms)
        fits = []
    for r, t in _candidates(camera, obj, img, guess):
        refine(r, t)
    if not fits:
        return None
    best = min(fits, key=lambda f: f[0])
    if guess is not None:
        # A planar target seen small has two poses that fit almost alike (a mirror tilt): among
        # the fits not clearly worse than the best, take the one nearest the prediction.
        g = cv2.Rodrigues(np.asarray(guess[0], float).reshape(3, 1))[0]

        def angle(f):
            rel = cv2.Rodrigues(f[1].reshape(3, 1))[0] @ g.T
            return float(np.arccos(np.clip((np.trace(rel) - 1) / 2, -1.0, 1.0)))

        alike = [f for f in fits if f[0] <= max(2.0 * best[0], best[0] + 0.3)]
        best = min(alike, key=angle)
    return _estimate(best, len(obj), max_rms)


def _estimate(fit, n_points: int, max_rms: float) -> PoseEstimate | None:
    """The PoseEstimate of a fit (rms, rvec, tvec, Jacobian), or None beyond ``max_rms``."""
    rms, r, t, jac = fit
    if not rms <= max_rms:
        return None
    try:
        normal = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return None
    return PoseEstimate(rvec=r, tvec=t, rms=rms, n_points=n_points, normal=normal)
