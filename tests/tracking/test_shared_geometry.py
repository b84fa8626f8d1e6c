"""The geometry written once in model/kinematics.py and imported by the renderer and the tracker:
a foot's lowest point (:func:`lowest_point`, :func:`lowest_point_offset`) and the angles of leg
rotations (:func:`hip_axis_angles`, :func:`pitch_angle`, :func:`angles_from_rotations`; the
tracker's :func:`walker_angles`, the joint fit's starting pitches).

Each is checked against slow, obvious references computed here (the torus searched for its lowest
point; the forward map ``Rz(steer) Rx(lean) Ry(pitch)`` inverted by least squares) and against
the copies it replaced, kept below verbatim as they were before they were merged (tracking/render.py
``_lowest_point``, model/kinematics.py ``_foot_offset`` and ``angles_from_rotations``,
tracking/track.py ``walker_angles`` and the single-leg branch of ``_angles``, tracking/joint.py's
pitch in ``walker_from_legs``).
"""

import math

import numpy as np
import pytest
from scipy.optimize import least_squares, minimize
from toywalk.model.kinematics import (
    angles_from_rotations,
    leg_poses,
    lowest_point,
    lowest_point_offset,
    rotation,
)
from toywalk.model.parameters import Params
from toywalk.tracking.angles import walker_angles
from toywalk.tracking.joint import WalkerPose, rot_y, walker_from_legs

COMPASS = Params(leg_length=0.5, foot_radius=0.1, foot_lateral_radius=0.1, hip_width=0.1, leg_mass=1.0,
                 axle_mass=0.5, com_offset=(0.0, 0.02, -0.3), inertia=(0.02, 0.02, 0.01, 0.0, 0.0, 0.0),
                 slope=0.03, gravity=9.81)  # data/params/compass-3d.toml: a spherical foot
TOY = Params(leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.02, leg_mass=0.05,
             axle_mass=0.02, com_offset=(-0.005, 0.1, -0.11), inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0),
             slope=0.08, gravity=9.81)  # tests/conftest.py toy_params with hips apart: a spool foot


def _poses(count, seed):
    """Random leg poses within a walker's range: (steer, lean, pitch) (rad) and a hip point (m)."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        steer, lean, pitch = rng.uniform(-0.4, 0.4), rng.uniform(-0.25, 0.25), rng.uniform(-0.5, 0.5)
        yield (steer, lean, pitch), rng.uniform(-0.2, 0.2, 3) + [0.0, 0.0, 0.3]


# --- the copies this replaced, verbatim ----------------------------------------------------------

def _old_render_lowest_point(params, rot, hip):
    """tracking/render.py ``_lowest_point`` (its ``state.rotation[leg]``, ``state.hip[leg]``)."""
    ell, r, rho = float(params.leg_length), float(params.foot_radius), float(params.foot_lateral_radius)
    centre = hip - (ell - r) * rot[:, 2]
    n = rot[:, 1]
    ez = np.array([0.0, 0.0, 1.0])
    t = -ez + n[2] * n
    norm = np.linalg.norm(t)
    t = t / norm if norm > 0 else -ez
    return centre + (r - rho) * t - rho * ez


def _old_foot_offset(params, n):
    """model/kinematics.py ``_foot_offset``: O - C."""
    ez = np.array([0.0, 0.0, 1.0])
    t = -ez + n[2] * n
    norm = np.linalg.norm(t)
    t = t / norm if norm > 0 else -ez
    return params.foot_lateral_radius * ez - (params.foot_radius - params.foot_lateral_radius) * t


def _old_angles_from_rotations(r_left, r_right):
    """model/kinematics.py ``angles_from_rotations``."""
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


def _old_walker_angles(r_ramp, pose):
    """tracking/track.py ``walker_angles``."""
    axle = r_ramp.T @ pose.axle
    b2 = axle[:, 1]
    lean = math.asin(float(np.clip(b2[2], -1.0, 1.0)))
    steer = math.atan2(-b2[0], b2[1])
    base = rotation(steer, lean, 0.0).T @ axle
    pitches = []
    for f in ("L", "R"):
        if f in pose.seen:
            local = base @ rot_y(pose.pitch[f])
            pitches.append(math.atan2(local[0, 2], local[2, 2]))
        else:
            pitches.append(math.nan)
    return np.array([lean, steer, *pitches])


def _old_one_leg_angles(r_ramp, foot, r_camera):
    """tracking/track.py ``_angles``, its branch for one leg seen (``r_camera`` its rotation)."""
    r = r_ramp.T @ r_camera
    b2 = r[:, 1]
    lean = float(np.arcsin(np.clip(b2[2], -1.0, 1.0)))
    steer = float(np.arctan2(-b2[0], b2[1]))
    local = rotation(steer, lean, 0.0).T @ r
    pitch = float(np.arctan2(local[0, 2], local[2, 2]))
    return np.array([lean, steer, pitch if foot == "L" else np.nan, pitch if foot == "R" else np.nan])


# --- slow, obvious references ---------------------------------------------------------------------

def _torus_lowest_point(params, rot, hip):
    """The lowest point of the foot's torus, found by search: the surface
    ``O + (a + rho cos v) (cos u b1 + sin u b3) + rho sin v b2`` (centre circle of radius
    ``a = r - rho`` in the leg's (b1, b3) plane, tube radius rho; docs/model.md section 2) sampled on a
    grid, its lowest sample refined by BFGS."""
    b1, b2, b3 = rot[:, 0], rot[:, 1], rot[:, 2]
    r, rho = params.foot_radius, params.foot_lateral_radius
    centre = hip - (params.leg_length - r) * b3

    def point(uv):
        u, v = uv
        return centre + (r - rho + rho * math.cos(v)) * (math.cos(u) * b1 + math.sin(u) * b3) + \
            rho * math.sin(v) * b2

    grid = [(u, v) for u in np.linspace(-math.pi, math.pi, 181) for v in np.linspace(-math.pi, math.pi, 91)]
    start = min(grid, key=lambda uv: point(uv)[2])
    best = minimize(lambda uv: point(uv)[2], start, method="BFGS", options={"gtol": 1e-14})
    return point(best.x)


def _angles_by_least_squares(r):
    """(steer, lean, pitch) whose ``rotation`` is nearest ``r`` (Frobenius norm), from zero."""
    fit = least_squares(lambda a: (rotation(*a) - r).ravel(), np.zeros(3), xtol=1e-15, ftol=1e-15,
                        gtol=1e-15)
    return fit.x


# --- the foot's lowest point ----------------------------------------------------------------------

@pytest.mark.parametrize("params", [COMPASS, TOY], ids=["sphere", "spool"])
def test_lowest_point_is_the_torus_lowest_point(params):
    for (steer, lean, pitch), hip in _poses(8, 1):
        rot = rotation(steer, lean, pitch)
        got = lowest_point(params, rot, hip)
        want = _torus_lowest_point(params, rot, hip)
        # Its height is a minimum, found to the rounding of z (1e-16 m); where the surface is
        # flat (radius of curvature r <= 0.1 m) the point moves sqrt(2 r dz) = 5e-9 m for that.
        assert abs(got[2] - want[2]) < 1e-13
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)


@pytest.mark.parametrize("params", [COMPASS, TOY], ids=["sphere", "spool"])
def test_lowest_point_agrees_with_the_copies_it_replaced(params):
    for (steer, lean, pitch), hip in _poses(50, 2):
        rot = rotation(steer, lean, pitch)
        # the renderer's contact point; a few roundings of lengths below 1 m apart
        np.testing.assert_allclose(lowest_point(params, rot, hip), _old_render_lowest_point(params, rot, hip),
                                   rtol=0, atol=1e-15)
        np.testing.assert_allclose(lowest_point_offset(params, rot[:, 1]),
                                   -_old_foot_offset(params, rot[:, 1]), rtol=0, atol=1e-16)
        # leg_poses places the stance foot's centre from its contact with it, O = C - (C - O),
        # exactly the old C + (O - C) (a negated difference is exact), and the hip above it
        contact = hip[:2]
        poses = leg_poses(params, steer, lean, pitch, -pitch, "L", contact)
        old_centre = np.array([*contact, 0.0]) + _old_foot_offset(params, rot[:, 1])
        old_hip = old_centre + (params.leg_length - params.foot_radius) * rot[:, 2]
        np.testing.assert_array_equal(poses.hip["L"], old_hip)
        # and the contact is the lowest point of the placed foot
        np.testing.assert_allclose(lowest_point(params, poses.rotation["L"], poses.hip["L"]),
                                   [*contact, 0.0], rtol=0, atol=1e-15)


# --- angles from rotations ------------------------------------------------------------------------

def test_angles_from_rotations_invert_the_forward_map():
    for (steer, lean, pitch), _ in _poses(20, 3):
        other = pitch - 0.6
        got = angles_from_rotations(rotation(steer, lean, pitch), rotation(steer, lean, other))
        left = _angles_by_least_squares(rotation(steer, lean, pitch))
        right = _angles_by_least_squares(rotation(steer, lean, other))
        # the least-squares inversion converges to the rounding of the rotation's entries
        np.testing.assert_allclose(got, [*left[:2], left[2], right[2]], rtol=0, atol=1e-10)
        np.testing.assert_allclose(right[:2], left[:2], rtol=0, atol=1e-10)


def test_angles_from_rotations_agree_with_the_copy_they_replaced():
    rng = np.random.default_rng(4)
    for (steer, lean, pitch), _ in _poses(50, 4):
        # measured rotations: each leg turned by a little noise, so that their b2 axes differ
        noisy = [rotation(steer, lean, p) @ rotation(*rng.normal(0, 0.01, 3)) for p in (pitch, -pitch)]
        # math.asin/atan2 against np.arcsin/arctan2: the same to a rounding of the angle (< 1 rad)
        np.testing.assert_allclose(angles_from_rotations(*noisy), _old_angles_from_rotations(*noisy),
                                   rtol=0, atol=1e-15)


def _walker_pose(axle, pitch, seen=("L", "R")):
    return WalkerPose(axle=axle, pitch=pitch, hip=np.zeros(3), hip_width=0.0, rms=0.1,
                      n_points={f: 4 for f in seen}, names=(), normal=np.zeros((0, 0)))


def test_walker_angles_are_the_models_inverse():
    rng = np.random.default_rng(5)
    r_ramp = rotation(0.3, -1.2, 0.1)  # the ramp seen obliquely
    for (steer, lean, pitch), _ in _poses(20, 5):
        tilt = rng.uniform(-0.3, 0.3)  # the axle frame's own pitch: arbitrary in a fit
        axle = r_ramp @ rotation(steer, lean, tilt)
        pose = _walker_pose(axle, {"L": pitch - tilt, "R": -pitch - tilt})
        got = walker_angles(r_ramp, pose)
        legs = [_angles_by_least_squares(rotation(steer, lean, p)) for p in (pitch, -pitch)]
        np.testing.assert_allclose(got, [legs[0][1], legs[0][0], legs[0][2], legs[1][2]], rtol=0, atol=1e-10)
        # and the same as the general function of both legs' rotations (ramp frame)
        steer2, lean2, pl, pr = angles_from_rotations(*(r_ramp.T @ pose.rotation(f) for f in ("L", "R")))
        np.testing.assert_allclose(got, [lean2, steer2, pl, pr], rtol=0, atol=1e-14)


def test_walker_angles_agree_with_the_copies_they_replaced():
    """Bit for bit where both legs are seen: the angles' SDs are finite differences with a step of
    1e-7 (tracking/angles.py), which magnify any change of rounding ten million times."""
    rng = np.random.default_rng(6)
    r_ramp = rotation(-0.2, -1.1, 0.3)
    for (steer, lean, pitch), _ in _poses(50, 6):
        axle = r_ramp @ rotation(steer, lean, 0.0) @ rotation(*rng.normal(0, 0.01, 3))
        pitches = {"L": pitch, "R": -pitch}
        np.testing.assert_array_equal(walker_angles(r_ramp, _walker_pose(axle, pitches)),
                                      _old_walker_angles(r_ramp, _walker_pose(axle, pitches)))
        for foot in ("L", "R"):
            one = _walker_pose(axle, {**{"L": math.nan, "R": math.nan}, foot: pitches[foot]}, seen=(foot,))
            np.testing.assert_array_equal(walker_angles(r_ramp, one), _old_walker_angles(r_ramp, one))
            # the removed per-leg angles: the leg's own rotation; rounding of angles below 1 rad
            np.testing.assert_allclose(walker_angles(r_ramp, one),
                                       _old_one_leg_angles(r_ramp, foot, one.rotation(foot)),
                                       rtol=0, atol=1e-15, equal_nan=True)


def test_joint_start_pitch_agrees_with_the_copy_it_replaced():
    for (steer, lean, pitch), hip in _poses(20, 7):
        legs = {"L": (rotation(steer, lean, pitch), hip), "R": (rotation(steer, lean, -pitch), hip)}
        axle, got, _ = walker_from_legs(legs, 0.0, prefer="L")
        local = axle.T @ legs["R"][0]
        assert got["R"] == math.atan2(local[0, 2], local[2, 2])  # verbatim
        assert got["R"] == pytest.approx(-2 * pitch, abs=1e-12)
