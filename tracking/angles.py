"""The walker's angles and their standard deviations from the joint leg fits (docs/model.md section 1).

A joint fit (:class:`toywalk.tracking.joint.WalkerPose`) gives the axle frame and each seen leg's
pitch about it, in the camera frame; turned into the ramp frame, the legs' rotations give
``lean, steer, pitch_left, pitch_right`` through the inverse of the model's leg rotation
``Rz(steer) Rx(lean) Ry(pitch)`` (:func:`toywalk.model.kinematics.hip_axis_angles`,
:func:`toywalk.model.kinematics.pitch_angle`, as
:func:`toywalk.model.kinematics.angles_from_rotations`; the joint fit's legs share b2 exactly, so
no averaging; one leg seen: the other pitch a gap). Their standard deviations propagate the fit's
covariance through the angle function by finite differences. The covariance is
``sigma^2 (J^T J)^-1`` (Hartley & Zisserman 2004, Multiple View Geometry, 2nd ed., section 5.2)
when every corner has one pixel noise ``sigma`` pooled over the video from the reprojection
residuals (:func:`pooled_pixel_sd`, :func:`pooled_walker_sd`); the tracker gives each marker its
own (:func:`pooled_marker_sd`), takes the unweighted fit's sandwich covariance, and scales each
frame by its own residual moderated by all frames' (:func:`residual_ratio`,
:func:`moderated_noise_scales`).

Angles are returned in the order ``(lean, steer, pitch_left, pitch_right)`` (rad), the trajectory
file's :data:`toywalk.model.trajectory.SIGNALS` names.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..model.kinematics import hip_axis_angles, pitch_angle, rotation
from .joint import FEET, WalkerPose, rot_y

__all__ = ["ANGLE_NAMES", "angle_jacobian", "moderated_noise_scales", "motion_smoothed", "pooled_marker_sd",
           "pooled_pixel_sd", "pooled_walker_sd", "residual_ratio", "walker_angles", "walker_angles_with_sd"]

#: The order of :func:`walker_angles`' values.
ANGLE_NAMES = ("lean", "steer", "pitch_left", "pitch_right")


def walker_angles(r_ramp: np.ndarray, pose: WalkerPose) -> np.ndarray:
    """The angles of a joint leg pose; NaN for an unseen leg's pitch.

    The hip axis b2 gives steer and lean (``b2 = Rz(steer) Rx(lean) e_y``, docs/model.md section 1,
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


#: The joint fit's parameters that turn the legs (:class:`toywalk.tracking.joint.WalkerPose`): the
#: axle frame about its b1 and b3 axes and each leg's pitch; the hip point and width move none.
_ANGULAR = ("d1", "d3", "pitch_L", "pitch_R")
#: Forward-difference step (rad) of the angles' derivatives in the pose's and the ramp's rotations.
_ANGLE_STEP = 1e-7


def angle_jacobian(r_ramp: np.ndarray, pose: WalkerPose) -> tuple[np.ndarray, np.ndarray]:
    """The angles of a joint leg pose and their derivatives in its parameters, by forward
    differences (:data:`_ANGLE_STEP`) in the parameters that turn the legs.

    Parameters
    ----------
    r_ramp : ndarray, shape (3, 3)
        Rotation of the ramp frame into the camera frame.
    pose : WalkerPose

    Returns
    -------
    angles : ndarray, shape (4,)
        :func:`walker_angles`.
    jacobian : ndarray, shape (4, k)
        d angles / d parameters, in the order of ``pose.names``; zero for the hip point and width
        (which move no angle) and for a leg not seen.
    """
    base = walker_angles(r_ramp, pose)
    h = _ANGLE_STEP
    jac = np.zeros((4, len(pose.names)))
    for j, name in enumerate(pose.names):
        if name in _ANGULAR:
            step = np.zeros(len(pose.names))
            step[j] = h
            jac[:, j] = (walker_angles(r_ramp, pose.perturbed(step)) - base) / h
    return base, np.nan_to_num(jac)


def walker_angles_with_sd(r_ramp: np.ndarray, pose: WalkerPose, pixel_sd: float, ramp_covariance=None,
                          marker_sd=None, scale: float | None = None) -> tuple[dict, dict]:
    """Angles of a joint leg pose and their standard deviations.

    The covariance of the fit is propagated through :func:`walker_angles` by finite
    differences. With one pixel SD for every corner it is ``pixel_sd^2 (J^T J)^-1``; with each
    marker's own (``marker_sd``, :func:`pooled_marker_sd`) it is the least-squares estimate's
    ``(J^T J)^-1 J^T S J (J^T J)^-1``, ``S`` the corners' variances (the fit is unweighted). It is
    then multiplied by this frame's noise ``scale`` (:func:`moderated_noise_scales`: blur and a
    bent edge make some frames noisier than others); without one, by the ratio of the frame's
    residual sum of squares to its expectation where that exceeds 1.

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
    marker_sd : dict int -> float, optional
        Pixel noise SD of each marker's corners (pixels), used where ``pose`` names its corners'
        markers (``labels``); a marker not in it takes ``pixel_sd``.
    scale : float, optional
        The frame's noise variance relative to the pooled one.

    Returns
    -------
    values, sds : dict of str -> float
        :data:`ANGLE_NAMES` -> angle and SD (rad); NaN for the pitch of a leg not seen.
    """
    base, jac = angle_jacobian(r_ramp, pose)
    angular = [j for j, name in enumerate(pose.names) if name in _ANGULAR]
    jac = jac[:, angular]
    if scale is None:
        ratio, _ = residual_ratio(pose, pixel_sd, marker_sd)
        scale = max(1.0, ratio) if math.isfinite(ratio) else 1.0
    cov = scale * _parameter_covariance(pose, pixel_sd, marker_sd)[np.ix_(angular, angular)]
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    if ramp_covariance is not None and np.all(np.isfinite(ramp_covariance)):
        turned = np.zeros((4, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = _ANGLE_STEP
            turned[:, j] = (walker_angles(r_ramp @ cv2.Rodrigues(step)[0], pose) - base) / _ANGLE_STEP
        turned = np.nan_to_num(turned)
        var = var + np.einsum("ij,jk,ik->i", turned, np.asarray(ramp_covariance, float), turned)
    sd = np.sqrt(np.maximum(var, 0.0))
    sd[~np.isfinite(base)] = np.nan
    return dict(zip(ANGLE_NAMES, base, strict=True)), dict(zip(ANGLE_NAMES, sd, strict=True))


def _corner_variances(pose: WalkerPose, pixel_sd: float, marker_sd) -> np.ndarray | None:
    """Each residual's variance (2 n,; pixels^2) from its marker's SD, or None where the pose does
    not name its corners' markers."""
    if marker_sd is None or pose.labels is None or pose.jacobian is None:
        return None
    sd = np.array([marker_sd.get(int(i), pixel_sd) for i in pose.labels])
    return np.repeat(sd**2, 2)


def _parameter_covariance(pose: WalkerPose, pixel_sd: float, marker_sd=None) -> np.ndarray:
    """The covariance (k, k) of a joint fit's parameters for the pooled noise
    (:func:`walker_angles_with_sd`)."""
    variances = _corner_variances(pose, pixel_sd, marker_sd)
    if variances is None:
        return pose.normal * pixel_sd**2
    gain = pose.normal @ pose.jacobian.T  # (k, 2n): the parameters' change per residual
    return (gain * variances) @ gain.T


def residual_ratio(pose: WalkerPose, pixel_sd: float, marker_sd=None) -> tuple[float, int]:
    """The frame's residual sum of squares over its expectation under the pooled noise, and the
    residual degrees of freedom ``2 n - k``; (NaN, dof) when there are none.

    With the corners' variances ``S`` the residuals' covariance is ``M S M``, ``M = I - J (J^T
    J)^-1 J^T`` (the residual maker of the unweighted fit); with one SD ``sigma`` the expectation is
    ``sigma^2 (2 n - k)``.
    """
    if pose.dof <= 0:
        return math.nan, pose.dof
    variances = _corner_variances(pose, pixel_sd, marker_sd)
    rss = 2 * sum(pose.n_points.values()) * pose.rms**2
    if variances is None:
        return rss / (pixel_sd**2 * pose.dof), pose.dof
    maker = pose.residual_maker
    return float(pose.residuals @ pose.residuals) / float(np.sum(maker**2 * variances)), pose.dof


#: :func:`moderated_noise_scales` pools over at least this many frames with residual freedom; with
#: fewer, the prior's spread is not estimable and a frame's scale is its ratio where that exceeds 1.
_MIN_FRAMES_MODERATED = 10


def moderated_noise_scales(ratios, dofs) -> tuple[np.ndarray, dict]:
    """Each frame's noise variance relative to the pooled one, its own residual moderated by
    all frames' (empirical Bayes).

    Frames differ in noise (motion blur near a heel strike, a marker turning edge-on), so one pooled
    SD overstates the uncertainty of quiet frames and understates that of blurred ones; a frame's
    own residual, with 10-20 degrees of freedom, is too noisy to stand alone. Each frame's variance
    scale ``c`` is given a scaled inverse chi-square prior with ``d0`` degrees of freedom about
    ``s0^2``, both estimated from the spread of all frames' log ratios; its posterior estimate is
    ``(d0 s0^2 + d rho) / (d0 + d)`` for a frame with ratio ``rho`` on ``d`` degrees of freedom
    (Smyth 2004, Stat. Appl. Genet. Mol. Biol. 3:3, doi:10.2202/1544-6115.1027, sections 3 and
    6.2). Measured on toy-sized clips with a flag hidden: ``d0`` about 2, and the pitch's error
    over SD where a leg shows one flag moved from 0.51-1.09 to 0.61-1.22 (benchmarks/TRACKING.md,
    "One marker on a leg").

    Parameters
    ----------
    ratios : array_like, shape (n,)
        :func:`residual_ratio` of each frame; NaN where a frame has none.
    dofs : array_like, shape (n,)
        Their degrees of freedom.

    Returns
    -------
    scales : ndarray, shape (n,)
        Variance scales; ``s0^2`` for a frame without residual freedom.
    prior : dict
        ``prior_dof`` (``d0``; inf where the frames are as alike as chi-square noise allows),
        ``prior_scale`` (``s0^2``) and ``frames``; ``method`` names the rule used.
    """
    from scipy.optimize import brentq
    from scipy.special import digamma, polygamma

    ratios = np.asarray(ratios, float)
    dofs = np.asarray(dofs, float)
    good = np.isfinite(ratios) & (ratios > 0) & (dofs > 0)
    if good.sum() < _MIN_FRAMES_MODERATED:
        scales = np.where(np.isfinite(ratios), np.maximum(ratios, 1.0), 1.0)
        return scales, {"method": f"fewer than {_MIN_FRAMES_MODERATED} frames with residual freedom: "
                                  "each frame's ratio where above 1", "frames": int(good.sum())}
    d = dofs[good]
    # log ratio of a chi-square on d degrees of freedom over d: mean digamma(d/2) - log(d/2),
    # variance trigamma(d/2); what is left of the spread is the prior's, trigamma(d0/2)
    z = np.log(ratios[good]) - digamma(d / 2) + np.log(d / 2)
    centre = float(np.mean(z))
    excess = float(np.mean((z - centre) ** 2 * len(z) / (len(z) - 1) - polygamma(1, d / 2)))
    if excess > float(polygamma(1, 1e7)):  # else d0 > 2e7: the frames as alike as noise allows
        d0 = 2.0 * brentq(lambda x: float(polygamma(1, x)) - excess, 1e-6, 1e7)
        s0 = math.exp(centre + float(digamma(d0 / 2)) - math.log(d0 / 2))
    else:
        d0, s0 = math.inf, math.exp(centre)
    scales = np.full(len(ratios), s0)
    own = np.isfinite(ratios) & (dofs > 0)
    if math.isfinite(d0):
        scales[own] = (d0 * s0 + dofs[own] * ratios[own]) / (d0 + dofs[own])
    return scales, {"method": "empirical Bayes moderated residual variance (Smyth 2004)",
                    "prior_dof": d0, "prior_scale": s0, "frames": int(good.sum())}


def pooled_marker_sd(poses, min_frames: int = 5, iterations: int = 20) -> dict:
    """Pixel noise SD of each marker's corners, pooled over the joint leg fits, robustly.

    Corners of different markers are not equally precise (a marker's size in the image, its
    obliquity and its print). A fit's residuals are ``r = M e`` (``M = I - J (J^T J)^-1 J^T``, the
    residual maker; ``e`` the corner errors of variances ``S``), so a marker's residuals have the
    covariance ``C`` = its rows of ``M S M``: its own corners' noise less what the fit absorbed,
    plus what the other markers' noise spilt into it (Belsley, Kuh & Welsch 1980, Regression
    Diagnostics, section 2.1). Their sum of squares is about ``tr C`` times a chi-square over its
    ``(tr C)^2 / tr C^2`` degrees of freedom, over those degrees of freedom (Satterthwaite 1946,
    Biometrics Bull. 2:110). Each marker's variance is scaled until the median over frames of its
    sum over ``tr C`` is that chi-square's median (robust to blurred frames, as
    :func:`pooled_pixel_sd`), all markers together, to a fixed point.

    Parameters
    ----------
    poses : sequence of WalkerPose or None
        One per frame; fits whose ``labels`` are None, or whose markers have unequal numbers of
        corners, are skipped.
    min_frames : int
        A marker seen with residual freedom in fewer frames is left out (the caller's common SD
        serves it).
    iterations : int
        Fixed-point steps at most (each moves a variance by the ratio of medians; they stop when
        none moves by 1e-6).

    Returns
    -------
    dict int -> float
        Marker id -> pixels, never below 0.02 (sub-pixel corners are never better).
    """
    from scipy.special import chdtri

    # One row per (frame, marker seen in it): the marker's sum of squared residuals, its share of
    # the residual freedom (tr of its block of M), and, for the variances v of all markers,
    # tr C = spill @ v and tr C^2 = v^T cross v with C = sum_n v_n R_n R_n^T, R_n the marker's
    # rows of M in marker n's columns.
    usable = [p for p in poses if p is not None and p.labels is not None and p.jacobian is not None
              and p.dof > 0]
    names = sorted({int(m) for p in usable for m in np.unique(p.labels)})
    if not names:
        return {}
    index = {m: i for i, m in enumerate(names)}
    owner, squares, shares, spill, cross = [], [], [], [], []
    for p in usable:
        maker = p.residual_maker
        # the coordinates grouped by marker, each marker's in a block of its own (q markers)
        order = np.argsort(np.repeat(p.labels, 2), kind="stable")
        present, sizes = np.unique(p.labels, return_counts=True)
        if np.any(sizes != sizes[0]):  # markers of unequal corner counts: not pooled here
            continue
        q, d = len(present), 2 * int(sizes[0])
        blocks = maker[np.ix_(order, order)].reshape(q, d, q, d)  # [m, a, n, b] = M_(m a),(n b)
        gram = np.einsum("manb,mcnb->mnac", blocks, blocks)  # R_mn R_mn^T
        slots = np.array([index[int(m)] for m in present])
        a = np.zeros((q, len(names)))
        a[:, slots] = np.einsum("mnaa->mn", gram)
        t = np.zeros((q, len(names), len(names)))
        t[:, slots[:, None], slots[None, :]] = np.einsum("mnac,mkac->mnk", gram, gram)
        r = p.residuals[order].reshape(q, d)
        owner.extend(slots.tolist())
        squares.extend(np.einsum("ma,ma->m", r, r).tolist())
        shares.extend(np.einsum("mama->m", blocks).tolist())
        spill.extend(a)
        cross.extend(t)
    if not owner:
        return {}
    owner, squares, shares = np.array(owner, int), np.array(squares), np.array(shares)
    spill, cross = np.array(spill), np.array(cross)
    # at least half a degree of freedom in a frame: else the residual says little
    counted = np.bincount(owner[shares > 0.5], minlength=len(names))
    known = [i for i in range(len(names)) if counted[i] >= min_frames]
    if not known:
        return {}
    variance = np.ones(len(names))
    for _ in range(iterations):
        v = variance.copy()
        rare = np.setdiff1d(np.arange(len(names)), known)
        v[rare] = np.median(variance[known])  # a marker too rarely seen: the others' median
        trace = spill @ v
        dof = trace**2 / np.einsum("pij,i,j->p", cross, v, v)  # Satterthwaite's (1946)
        ratio = squares / trace
        step = np.ones(len(names))
        for i in known:
            take = (owner == i) & (dof > 0.5)
            if not take.any():
                continue
            freedom = float(np.median(dof[take]))
            # the median of a chi-square over its mean, for that many degrees of freedom
            step[i] = float(np.median(ratio[take])) / (chdtri(freedom, 0.5) / freedom)
        variance *= step
        if np.max(np.abs(step - 1.0)) < 1e-6:  # settled: SDs to 5e-7
            break
    return {names[i]: max(math.sqrt(variance[i]), 0.02) for i in known}


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
    ratio = _chi_median(dof) / math.sqrt(dof)  # median of rms/sigma for dof degrees of freedom
    return max(float(np.median(values)) / ratio, 0.02)  # floor: sub-pixel corners are never better


def _chi_median(dof: float) -> float:
    """Median of the chi distribution on ``dof`` degrees of freedom: the root of the chi-square's
    (scipy.special, not scipy.stats, which takes a second to import)."""
    from scipy.special import chdtri

    return math.sqrt(float(chdtri(dof, 0.5)))


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
    ratio = _chi_median(dof) / math.sqrt(dof)
    return max(float(np.median(values)) / ratio, 0.02)


#: The white-jerk motion model of :func:`motion_smoothed`: how diffuse the state is where nothing
#: ties it (the first sample, and each leg's rate and acceleration just after a heel strike). A
#: walker's leg turns at most a few rad/s and its pitch accelerates by at most a few hundred rad/s^2
#: (stable-toy, the fastest shipped gait: 0.3 rad swings in 0.1 s); these are ten times more.
_FREE_RATE = 30.0  # rad/s
_FREE_ACCELERATION = 3e3  # rad/s^2
#: log10 of the jerk densities (rad^2/s^5) tried: coarse, then refined around the best. Measured
#: maximum-likelihood values: compass-3d 3e2, the toy 2e4, stable-toy 2e6 (benchmarks/TRACKING.md).
_LOG_DENSITIES = np.arange(-2.0, 14.01, 1.0)
_REFINE = np.arange(-0.75, 0.76, 0.25)


def _white_jerk(dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition (3, 3) of (angle, rate, acceleration) over ``dt`` s and its process noise (3, 3)
    for a unit jerk density (Bar-Shalom, Li & Kirubarajan 2001, Estimation with Applications to
    Tracking and Navigation, section 6.2.3)."""
    f = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    q = np.array([[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                  [dt**3 / 6, dt**2 / 2, dt]])
    return f, q


class _MotionModel:
    """The steps of :func:`motion_smoothed`'s model between samples: ``x_i = F_i x_{i-1} + w_i``,
    ``cov w_i = q Q_i + S_i`` with ``S_i`` freeing rate and acceleration at a strike inside the step."""

    def __init__(self, time: np.ndarray, strikes):
        strikes = np.sort(np.asarray(list(strikes), float))
        free = np.diag([0.0, _FREE_RATE**2, _FREE_ACCELERATION**2])
        n = len(time)
        self.f = np.zeros((n, 3, 3))
        self.q = np.zeros((n, 3, 3))
        self.s = np.zeros((n, 3, 3))
        for i in range(1, n):
            a, b = float(time[i - 1]), float(time[i])
            inside = strikes[(strikes > a) & (strikes <= b)]
            if len(inside):  # to the strike, free the rate and acceleration, on to the sample
                f1, q1 = _white_jerk(float(inside[0]) - a)
                f2, q2 = _white_jerk(b - float(inside[0]))
                self.f[i] = f2 @ f1
                self.q[i] = f2 @ q1 @ f2.T + q2
                self.s[i] = f2 @ free @ f2.T
            else:
                self.f[i], self.q[i] = _white_jerk(b - a)
        self.prior = np.diag([1.0, _FREE_RATE**2, _FREE_ACCELERATION**2])  # rad, rad/s, rad/s^2

    def filter(self, values, sds, density: float):
        """Kalman filter: predicted and filtered (means (n, 3), covariances (n, 3, 3)) and the log
        likelihood of the samples after the first three (whose innovations the diffuse start sets)."""
        n = len(values)
        xp, pp = np.zeros((n, 3)), np.zeros((n, 3, 3))
        xf, pf = np.zeros((n, 3)), np.zeros((n, 3, 3))
        seen = np.isfinite(values)
        x = np.array([values[np.argmax(seen)], 0.0, 0.0])
        p = self.prior.copy()
        loglik, used = 0.0, 0
        for i in range(n):
            if i > 0:
                x = self.f[i] @ x
                p = self.f[i] @ p @ self.f[i].T + density * self.q[i] + self.s[i]
            xp[i], pp[i] = x, p
            if seen[i]:
                var = p[0, 0] + sds[i] ** 2
                gain = p[:, 0] / var
                innovation = values[i] - x[0]
                if used >= 3:
                    loglik -= 0.5 * (innovation**2 / var + math.log(2 * math.pi * var))
                used += 1
                x = x + gain * innovation
                p = p - np.outer(gain, p[0])
                p = 0.5 * (p + p.T)
            xf[i], pf[i] = x, p
        return xp, pp, xf, pf, loglik

    def smooth(self, values, sds, density: float):
        """Rauch-Tung-Striebel smoother (Rauch, Tung & Striebel 1965, AIAA J. 3:1445,
        doi:10.2514/3.3166): the angle's posterior means and SDs (n,) given every sample."""
        xp, pp, xs, ps, _ = self.filter(values, sds, density)
        for i in range(len(values) - 2, -1, -1):
            c = ps[i] @ self.f[i + 1].T @ np.linalg.inv(pp[i + 1])
            xs[i] = xs[i] + c @ (xs[i + 1] - xp[i + 1])
            ps[i] = ps[i] + c @ (ps[i + 1] - pp[i + 1]) @ c.T
        return xs[:, 0], np.sqrt(np.maximum(ps[:, 0, 0], 0.0))


def motion_smoothed(time, values, sds, strikes=(), *, density: float | None = None):
    """An angle's samples combined with its continuity over time: each sample's posterior given
    all of them under a smooth-motion model, with its SD.

    The angle, its rate and its acceleration follow a white-jerk model (the jerk's spectral
    density ``density``; Bar-Shalom et al. 2001, section 6.2.3) whose rate and acceleration are
    free to jump at each heel strike (an impact: the angle is continuous, its rates are not,
    docs/model.md section 4). The samples are the per-frame estimates with their stated SDs; the
    posterior is the Rauch-Tung-Striebel smoother's. Unless given, ``density`` is the one of
    largest likelihood of the samples (a grid of powers of ten, then quarter decades), so the
    model is as loose as the signal needs: the posterior SD then covers the model's misfit too.

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times (s), increasing.
    values, sds : array_like, shape (n,)
        The angle (rad; NaN = no sample) and its SD (rad).
    strikes : iterable of float
        Heel-strike times (s), of either foot.
    density : float, optional
        Jerk spectral density (rad^2/s^5).

    Returns
    -------
    values, sds : ndarray, shape (n,)
        Posterior mean and SD (rad) at every time (in gaps too: callers keep gaps as gaps).
    density : float
        The density used (rad^2/s^5).
    """
    t = np.asarray(time, float)
    y = np.asarray(values, float)
    s = np.asarray(sds, float)
    if not (t.shape == y.shape == s.shape and t.ndim == 1):
        raise ValueError(f"time, values and sds must be 1-D of one length, got shapes {t.shape}, "
                         f"{y.shape}, {s.shape}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time must increase strictly")
    y = np.where(np.isfinite(s) & (s > 0), y, np.nan)
    if np.sum(np.isfinite(y)) < 4:
        raise ValueError("need at least 4 samples with a finite value and SD")
    model = _MotionModel(t, strikes)
    if density is None:
        def loglik(log_q):
            return model.filter(y, s, 10.0**log_q)[4]

        coarse = max(_LOG_DENSITIES, key=loglik)
        density = 10.0 ** max(coarse + _REFINE, key=loglik)
    mean, sd = model.smooth(y, s, float(density))
    return mean, sd, float(density)
