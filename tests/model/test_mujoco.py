"""The shipped walkers in an independent rigid-body engine with soft contacts (MuJoCo;
toywalk.model.mujoco_check): built from their parameter files and started from the model's fixed
point, with every contact of both feet on (docs/gaits.md section 4)."""

import math

import mujoco
import numpy as np
import pytest
from toywalk.model import Walker, load_params, solve_fixed_point
from toywalk.model.mujoco_check import build_mjcf, initial_state, walk_in_mujoco

from ..conftest import DATA
from .test_clearance import Z_CLEARING
from .test_research_gaits import Z_STABLE


@pytest.fixture(scope="module")
def clearing_gait():
    params = load_params(DATA / "params" / "clearing-toy.toml")
    return solve_fixed_point(Walker(params), np.array(Z_CLEARING))


def test_the_build_matches_the_model(clearing_gait):
    """At the start the MuJoCo walker has the model's pose, masses and kinetic energy. The feet
    differ in shape only away from their rims (spheroid against torus): the lowest point's height
    differs by O(r lean^4), 1e-10 m at the gait's 0.6 degree lean at heel strike. Measured: 3.8e-10 m
    in position, 6.4e-10 relative in kinetic energy (velocities rotate about that point);
    tolerances 1e-9 m and 1e-8."""
    gait = clearing_gait
    params = gait.params
    model = mujoco.MjModel.from_xml_string(build_mjcf(params).replace(
        'integrator="RK4"', 'integrator="RK4"><flag energy="enable"/></option><option'))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(params, gait.fixed_point)
    mujoco.mj_forward(model, data)
    walker = Walker(params)
    x = walker.full_state(gait.fixed_point)
    points = walker.points(x)  # rows: C, O1, H1, axle, H2, O2, C2, G1, G2 (relative to C)
    np.testing.assert_allclose(data.xpos[model.body("left").id], points[2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(data.xpos[model.body("right").id], points[4], rtol=0, atol=1e-9)
    np.testing.assert_allclose(data.geom_xpos[model.geom("left_foot").id], points[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(data.geom_xpos[model.geom("right_foot").id], points[5], rtol=0, atol=1e-9)
    # Whole mass and centre of mass (the axle's point mass rides on the left leg's body).
    assert abs(sum(model.body_mass) - params.total_mass) < 1e-15
    com = (params.leg_mass * (points[7] + points[8]) + params.axle_mass * points[3]) / params.total_mass
    np.testing.assert_allclose(data.subtree_com[model.body("left").id], com, rtol=0, atol=1e-9)
    # Kinetic energy: the model's total energy less its potential (contact at the origin).
    gvec = params.gravity * np.array([math.sin(params.slope), 0.0, -math.cos(params.slope)])
    potential = -gvec @ (params.leg_mass * (points[7] + points[8]) + params.axle_mass * points[3])
    kinetic = walker.energy(x) - potential
    assert abs(data.energy[1] - kinetic) < 1e-8 * kinetic


def test_the_clearing_walker_walks_in_mujoco(clearing_gait):
    """Issue 13, item 3: data/params/clearing-toy.toml, started from the model's fixed point with
    both feet's contacts on, walks 20 steps without falling or scuffing, at the model's step time
    and length. Measured (1e-4 s steps, 1 ms contacts, friction 2): mean step time 0.1835 s against
    the model's 0.1840 s (-0.3 %), each within 0.1730..0.1928 s (-6.0..+4.8 %); mean step length
    40.2 mm against 40.6 mm (-1.1 %); strides 79.3..81.1 mm against 81.2 mm (-2.4..-0.2 %). Single
    steps alternate in length (37.0..43.4 mm) because the heading drifts, to 1.8 degrees after 20
    steps, and the feet are 107 mm apart (107 mm * sin(1.8 deg) = 3.4 mm either way); a stride is
    blind to that. Tolerances: mean step time and step length 2 %, each step time 8 %, each
    stride 3 %."""
    gait = clearing_gait
    walk = walk_in_mujoco(gait.params, gait.fixed_point, steps=20)
    assert walk.status == "completed", walk.message
    assert walk.steps == 20 and walk.scuffs == 0
    step_time, step_length = gait.step_time, 0.5 * gait.stride_length
    assert abs(walk.step_times.mean() / step_time - 1) < 0.02
    assert abs(walk.step_lengths.mean() / step_length - 1) < 0.02
    assert np.all(np.abs(walk.step_times / step_time - 1) < 0.08)
    strides = walk.step_lengths.reshape(-1, 2).sum(axis=1)
    assert np.all(np.abs(strides / gait.stride_length - 1) < 0.03)


def test_the_stable_walker_scuffs_and_falls_in_mujoco():
    """Issue 13: data/params/stable-toy.toml, whose swing foot dips 0.017 mm into the ramp before
    the legs pass (the model ignores it), catches the ramp in MuJoCo and falls within 0.6 s.
    Measured: four scuffs and no heel strike ahead of the stance foot before a hip came down, at
    0.27 s."""
    params = load_params(DATA / "params" / "stable-toy.toml")
    gait = solve_fixed_point(Walker(params), np.array(Z_STABLE))
    walk = walk_in_mujoco(params, gait.fixed_point, steps=20)
    assert walk.status == "fell" and walk.scuffs >= 1
    assert walk.duration < 0.6
