"""Both legs' poses fitted jointly, sharing one hip axis (docs/model.md section 1).

The legs are two rigid bodies hinged on one axle: they share its direction ``b2`` (so steer and
lean) and their hip points lie ``hip_width`` apart along it; only the pitches differ. Fitting the
two legs separately spends 12 parameters where the walker has 8 (or 9 with an unknown hip width),
and a leg seen through one small marker then has an ill-determined, sometimes mirrored pose with a
deceptively small residual. Here one model is fitted to every visible leg-marker corner at once:

    X_cam = R_A (Ry(theta_f) P + w e2 [f = L]) + h,       f in {L, R}

with ``R_A`` the axle frame's rotation into the camera frame, ``theta_f`` the leg's pitch about the
axle, ``h`` the right hip point (camera frame, m), ``w`` the hip width and ``P`` a corner in the
leg's body frame (the marker layout). ``R_A`` is perturbed only about its own b1 and b3 axes
(a rotation about b2 would duplicate the pitches), so the parameters are
``(d1, d3, theta_L, theta_R, h_x, h_y, h_z[, w])``; an unseen leg drops its pitch.

The reprojection error is minimised by Levenberg-Marquardt (Levenberg 1944, Q. Appl. Math. 2:164;
Marquardt 1963, J. SIAM 11:431, doi:10.1137/0111030) in undistorted image coordinates scaled by
the focal lengths (pixels), with an analytic Jacobian. The covariance of the parameters is
``sigma^2 (J^T J)^-1`` (Hartley & Zisserman 2004, Multiple View Geometry, 2nd ed., section 5.2).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import numpy as np

from ..model.kinematics import pitch_angle
from .camera import Camera, undistort_pixels

__all__ = ["WalkerPose", "fit_walker", "rot_y", "walker_from_legs"]

FEET = ("L", "R")


def rot_y(angle: float) -> np.ndarray:
    """Rotation (3, 3) by ``angle`` (rad) about the y axis."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _exp(omega: np.ndarray) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(omega, float).reshape(3, 1))[0]


@dataclasses.dataclass(frozen=True)
class WalkerPose:
    """Both legs' poses in the camera frame, sharing the hip axis.

    Attributes
    ----------
    axle : ndarray, shape (3, 3)
        Rotation of the axle frame into the camera frame; its second column is the hip axis b2.
    pitch : dict {'L', 'R'} -> float
        Each leg's pitch about b2 relative to the axle frame (rad); NaN for a leg not seen.
    hip : ndarray, shape (3,)
        The right leg's hip point (camera frame, m); the left one is ``hip + hip_width * b2``.
    hip_width : float
        m.
    rms : float
        RMS reprojection error per coordinate (pixels).
    n_points : dict {'L', 'R'} -> int
        Corners used on each leg.
    names : tuple of str
        The fitted parameters, in the order of ``normal``'s rows: ``d1, d3`` (rad, rotations of the
        axle frame about its own b1, b3), ``pitch_L``, ``pitch_R`` (rad, the seen legs only),
        ``hx, hy, hz`` (m) and, if it was fitted, ``hip_width`` (m).
    normal : ndarray, shape (k, k)
        ``(J^T J)^-1`` for unit pixel variance; the covariance is ``sigma^2 * normal`` when every
        corner is equally precise.
    residuals : ndarray, shape (2 n,), or None
        The reprojection residuals at the fit (pixels; u and v of each corner in turn, the left
        leg's corners first), for a covariance with corners of unequal precision
        (:func:`toywalk.tracking.angles.walker_angles_with_sd`).
    jacobian : ndarray, shape (2 n, k), or None
        Their Jacobian in the parameters of ``names``.
    labels : ndarray of int, shape (n,), or None
        Each corner's marker id, where the observations named them.
    """

    axle: np.ndarray
    pitch: dict
    hip: np.ndarray
    hip_width: float
    rms: float
    n_points: dict
    names: tuple
    normal: np.ndarray
    residuals: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    labels: np.ndarray | None = None

    @functools.cached_property
    def residual_maker(self) -> np.ndarray | None:
        """``M = I - J (J^T J)^-1 J^T`` (2 n, 2 n): the residuals are ``M`` times the corner errors
        (linearised); None without the Jacobian. Computed once per fit."""
        if self.jacobian is None:
            return None
        return np.eye(len(self.jacobian)) - self.jacobian @ self.normal @ self.jacobian.T

    @property
    def seen(self) -> tuple:
        return tuple(f for f in FEET if self.n_points.get(f, 0) > 0)

    @property
    def dof(self) -> int:
        """Residual degrees of freedom: 2 n - k."""
        return 2 * sum(self.n_points.values()) - len(self.names)

    def rotation(self, foot: str) -> np.ndarray:
        """The leg's rotation (3, 3) into the camera frame."""
        return self.axle @ rot_y(self.pitch[foot])

    def hip_point(self, foot: str) -> np.ndarray:
        return self.hip + (self.hip_width * self.axle[:, 1] if foot == "L" else 0.0)

    def leg_pose(self, foot: str) -> tuple[np.ndarray, np.ndarray]:
        """(rvec, tvec) of the leg body in the camera frame (``X_cam = R X_body + t``)."""
        return cv2.Rodrigues(self.rotation(foot))[0].ravel(), self.hip_point(foot).copy()

    def perturbed(self, delta: np.ndarray) -> WalkerPose:
        """A copy moved by ``delta`` in the parameters of ``names`` (for finite differences)."""
        d = dict(zip(self.names, np.asarray(delta, float).tolist(), strict=True))
        axle = self.axle @ _exp([d.get("d1", 0.0), 0.0, d.get("d3", 0.0)])
        pitch = {f: self.pitch[f] + d.get(f"pitch_{f}", 0.0) for f in FEET}
        hip = self.hip + np.array([d.get("hx", 0.0), d.get("hy", 0.0), d.get("hz", 0.0)])
        return WalkerPose(axle=axle, pitch=pitch, hip=hip, hip_width=self.hip_width + d.get("hip_width", 0.0),
                          rms=self.rms, n_points=self.n_points, names=self.names, normal=self.normal,
                          residuals=self.residuals, jacobian=self.jacobian, labels=self.labels)


def walker_from_legs(legs: dict, hip_width: float, prefer: str | None = None):
    """An initial (axle, pitch, hip) from separate leg poses ``{foot: (R (3, 3), t (3,))}``.

    The axle frame is the ``prefer``red leg's frame (default: the first seen); the other leg's
    pitch is its rotation about that leg's b2, its hip point is ignored.
    """
    feet = [f for f in FEET if f in legs]
    if not feet:
        raise ValueError("legs must hold at least one of 'L', 'R'")
    ref = prefer if prefer in legs else feet[0]
    axle, t = legs[ref]
    pitch = {f: math.nan for f in FEET}
    pitch[ref] = 0.0
    for f in feet:
        if f != ref:
            pitch[f] = pitch_angle(axle.T @ legs[f][0])
    hip = np.asarray(t, float) - (hip_width * axle[:, 1] if ref == "L" else 0.0)
    return np.asarray(axle, float), pitch, hip


class _Problem:
    """Residuals and Jacobian of the joint model for one frame's observations.

    The seen legs' corners are stacked (left leg's first): ``obj`` (n, 3), ``meas`` (n, 2),
    each point's leg in ``foot`` (n,; index into ``feet``), whether it is on the left leg and,
    where the observations name them, each point's marker id in ``labels`` (n,; else None).
    """

    def __init__(self, camera: Camera, observations: dict, fit_width: bool):
        self.feet = [f for f in FEET if f in observations and len(observations[f][0])]
        objs = {f: np.asarray(observations[f][0], float).reshape(-1, 3) for f in self.feet}
        self.fx, self.fy = float(camera.matrix[0, 0]), float(camera.matrix[1, 1])
        self.fit_width = fit_width
        self.names = ("d1", "d3", *[f"pitch_{f}" for f in self.feet], "hx", "hy", "hz") + \
            (("hip_width",) if fit_width and len(self.feet) == 2 else ())
        self.n_points = {f: len(objs[f]) for f in self.feet}
        self._index = {name: i for i, name in enumerate(self.names)}
        if not self.feet:
            return
        self.obj = np.concatenate([objs[f] for f in self.feet])
        px = np.concatenate([np.asarray(observations[f][1], float).reshape(-1, 2) for f in self.feet])
        self.meas = undistort_pixels(camera, px) if np.any(camera.distortion) else \
            (px - camera.matrix[:2, 2]) / [self.fx, self.fy]
        named = [len(observations[f]) > 2 for f in self.feet]
        if any(named) and not all(named):
            raise ValueError("observations must name the markers of every seen leg or of none")
        self.labels = np.concatenate([np.asarray(observations[f][2], int).reshape(-1) for f in self.feet]) \
            if all(named) else None
        if self.labels is not None and len(self.labels) != len(self.obj):
            raise ValueError(f"observations' marker labels: {len(self.labels)} for {len(self.obj)} corners")
        self.foot = np.repeat(np.arange(len(self.feet)), [len(objs[f]) for f in self.feet])
        self.left = np.array([f == "L" for f in self.feet])[self.foot]
        self._pitch_column = np.array([self.names.index(f"pitch_{f}") for f in self.feet])[self.foot]

    def evaluate(self, axle, pitch, hip, width, jacobian=True):
        """Residuals (2n,; pixels, u and v of each point in turn) and, if asked, their Jacobian
        (2n, k) in the parameters of ``names``; (None, None) if a point is not in front."""
        theta = np.array([pitch[f] for f in self.feet])[self.foot]
        cos, sin = np.cos(theta), np.sin(theta)
        p = self.obj
        y_pitch = np.empty_like(p)  # Ry(theta) P, axle frame
        y_pitch[:, 0] = cos * p[:, 0] + sin * p[:, 2]
        y_pitch[:, 1] = p[:, 1]
        y_pitch[:, 2] = cos * p[:, 2] - sin * p[:, 0]
        y = y_pitch.copy()
        y[self.left, 1] += width
        x = y @ axle.T + hip
        z = x[:, 2]
        if np.any(z <= 1e-6):
            return None, None
        u, v = x[:, 0] / z, x[:, 1] / z
        r = np.empty((len(z), 2))
        r[:, 0] = self.fx * (u - self.meas[:, 0])
        r[:, 1] = self.fy * (v - self.meas[:, 1])
        if not jacobian:
            return r.ravel(), None
        # dX/dparams, (n, 3, k): the axle perturbed as axle @ exp(d) moves X by axle (d x y), with
        # e1 x y = (0, -y3, y2), e3 x y = (-y2, y1, 0); a pitch by axle (e2 x y_pitch) =
        # axle (y_pitch3, 0, -y_pitch1); the hip point by the unit vectors; the hip width (left
        # leg) by b2
        n, k = len(z), len(self.names)
        dx = np.zeros((n, 3, k))
        dx[:, :, 0] = y[:, 2, None] * -axle[:, 1] + y[:, 1, None] * axle[:, 2]
        dx[:, :, 1] = y[:, 1, None] * -axle[:, 0] + y[:, 0, None] * axle[:, 1]
        dx[np.arange(n), :, self._pitch_column] = y_pitch[:, 2, None] * axle[:, 0] - \
            y_pitch[:, 0, None] * axle[:, 2]
        base = self._index["hx"]
        dx[:, 0, base] = dx[:, 1, base + 1] = dx[:, 2, base + 2] = 1.0
        if "hip_width" in self._index:
            dx[self.left, :, self._index["hip_width"]] = axle[:, 1]
        # through d(u, v)/dX = (1 / z) (fx (1, 0, -u), fy (0, 1, -v))
        jac = np.empty((n, 2, k))
        jac[:, 0] = (self.fx / z)[:, None] * (dx[:, 0] - u[:, None] * dx[:, 2])
        jac[:, 1] = (self.fy / z)[:, None] * (dx[:, 1] - v[:, None] * dx[:, 2])
        return r.ravel(), jac.reshape(2 * n, k)

    def step(self, axle, pitch, hip, width, delta):
        """The parameters (axle, pitch, hip, width) moved by ``delta`` (k,), ``names``' order."""
        delta = np.asarray(delta, float)
        axle = axle @ _exp([delta[0], 0.0, delta[1]])
        pitch = {f: pitch[f] + (delta[self._index[f"pitch_{f}"]] if f in self.feet else 0.0) for f in FEET}
        base = self._index["hx"]
        hip = hip + delta[base:base + 3]
        if "hip_width" in self._index:
            width = width + delta[self._index["hip_width"]]
        return axle, pitch, hip, width


def fit_walker(camera: Camera, observations: dict, init, *, hip_width: float, fit_hip_width: bool = False,
               max_iterations: int = 20, tolerance: float = 1e-7) -> WalkerPose | None:
    """Least-squares joint pose of both legs from their visible marker corners.

    Parameters
    ----------
    camera : Camera
    observations : dict {'L', 'R'} -> (object_points, image_points[, labels])
        Per seen leg: corners in its body frame, shape (n, 3) (m), their pixels, shape (n, 2),
        and optionally each corner's marker id, shape (n,) (for every seen leg or for none).
    init : (axle, pitch, hip)
        Starting point: rotation (3, 3), dict of pitches (rad; a seen leg's must be finite), the
        right hip point (3,) (m); see :func:`walker_from_legs`.
    hip_width : float
        m; the starting value if ``fit_hip_width``.
    fit_hip_width : bool
        Fit the hip width too (only when both legs are seen).

    Returns
    -------
    WalkerPose, or None if the problem is degenerate (fewer residuals than parameters, points
    behind the camera, a singular normal matrix).
    """
    problem = _Problem(camera, observations, fit_hip_width)
    if not problem.feet:
        raise ValueError("observations must hold corners of at least one leg")
    k = len(problem.names)
    if 2 * sum(problem.n_points.values()) < k:
        return None
    axle, pitch, hip = init
    axle = np.asarray(axle, float)
    pitch = {f: float(pitch.get(f, math.nan)) for f in FEET}
    if not all(math.isfinite(pitch[f]) for f in problem.feet):
        raise ValueError("init must give a finite pitch for every seen leg")
    hip = np.asarray(hip, float).reshape(3)
    width = float(hip_width)
    r, jac = problem.evaluate(axle, pitch, hip, width)
    if r is None:
        return None
    cost = float(r @ r)
    lam = 1e-3
    diagonal = np.diag_indices(k)
    for _ in range(max_iterations):
        jtj = jac.T @ jac
        g = jac.T @ r
        improved = False
        for _ in range(8):
            a = jtj.copy()
            a[diagonal] += lam * (a[diagonal] + 1e-12)
            try:
                delta = -np.linalg.solve(a, g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            cand = problem.step(axle, pitch, hip, width, delta)
            r_new, jac_new = problem.evaluate(*cand)
            if r_new is not None and float(r_new @ r_new) < cost:
                old = cost
                axle, pitch, hip, width = cand
                r, jac, cost = r_new, jac_new, float(r_new @ r_new)
                lam = max(lam / 10, 1e-9)
                improved = True
                break
            lam *= 10
        if not improved or old - cost <= tolerance * max(old, 1e-12) or \
                float(np.max(np.abs(delta))) < 1e-10:
            break
    try:
        normal = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(normal)):
        return None
    for f in FEET:
        if f not in problem.feet:
            pitch[f] = math.nan
    return WalkerPose(axle=axle, pitch=pitch, hip=hip, hip_width=width,
                      rms=math.sqrt(cost / len(r)), n_points=dict(problem.n_points),
                      names=problem.names, normal=normal, residuals=r, jacobian=jac, labels=problem.labels)
