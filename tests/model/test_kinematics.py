"""Leg poses from angles and back; agreement with the symbolic model's points."""

import numpy as np
from numpy.testing import assert_allclose
from toywalk.model.kinematics import angles_from_rotations, leg_poses, rotation
from toywalk.model.parameters import Params
from toywalk.model.walker import Walker

PARAMS = Params(leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.02,
                leg_mass=0.06, axle_mass=0.01, com_offset=(-0.005, 0.1, -0.11),
                inertia=(2e-4, 3e-4, 2e-4, 1e-5, 2e-5, 1e-5), slope=0.0785, gravity=9.81)


def test_angles_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(50):
        steer, lean = rng.uniform(-1, 1), rng.uniform(-1.2, 1.2)
        pl, pr = rng.uniform(-1.2, 1.2, 2)
        got = angles_from_rotations(rotation(steer, lean, pl), rotation(steer, lean, pr))
        assert_allclose(got, (steer, lean, pl, pr), atol=1e-12)


def test_poses_agree_with_the_symbolic_model():
    """With the left leg in stance, the NumPy poses put hips and feet where the CasADi model does;
    with the right leg in stance they are the mirror image of the model's (mirrored) description."""
    walker = Walker(PARAMS)
    phi, psi, th_st, th_sw = 0.2, -0.1, -0.25, 0.3
    x = np.array([phi, psi, th_st, th_sw, 0, 0, 0, 0, 0, 0])
    pts = walker.points(x)  # rows: C, O1, H1, axle, H2, O2, C2, G1, G2 (relative to C)
    poses = leg_poses(PARAMS, phi, psi, th_st, th_sw, "L", (0.0, 0.0))
    assert_allclose(poses.hip["L"], pts[2], atol=1e-14)
    assert_allclose(poses.hip["R"], pts[4], atol=1e-14)
    assert_allclose(poses.foot_centre["L"], pts[1], atol=1e-14)
    assert_allclose(poses.foot_centre["R"], pts[5], atol=1e-14)
    mirror = np.diag([1.0, -1.0, 1.0])
    poses_r = leg_poses(PARAMS, -phi, -psi, th_sw, th_st, "R", (0.3, -0.1))
    assert_allclose(poses_r.hip["R"], mirror @ pts[2] + [0.3, -0.1, 0], atol=1e-14)
    assert_allclose(poses_r.hip["L"], mirror @ pts[4] + [0.3, -0.1, 0], atol=1e-14)
