"""The shipped walkers in an independent rigid-body engine with soft contacts (MuJoCo;
toywalk.model.mujoco_check): built from their parameter files and started from the model's fixed
point, with every contact of both feet on (docs/gaits.md section 4).

One 30-step walk of data/params/clearing-toy.toml (module fixture ``clearing_walk``: 3 s of CPU,
3.5 to 5.6 s on a loaded 2-core machine, of the module's 8 to 12 s) serves the walk, angle and
trajectory tests."""

import math

import mujoco
import numpy as np
import pytest
from toywalk.model import Walker, find_gait, load_params, solve_fixed_point
from toywalk.model.kinematics import angles_from_rotations
from toywalk.model.mujoco_check import build_mjcf, initial_state, mujoco_trajectory, walk_in_mujoco
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import SIGNALS, read_trajectory, write_trajectory
from toywalk.sysid.measurement import observations

from ..conftest import DATA, ROOT
from .documented import Z_CLEARING, Z_STABLE

CLEARING = DATA / "params" / "clearing-toy.toml"
STEPS = 30  # issue 13's done criterion: at least 30 steps


@pytest.fixture(scope="module")
def clearing_gait():
    params = load_params(CLEARING)
    return solve_fixed_point(Walker(params), np.array(Z_CLEARING))


@pytest.fixture(scope="module")
def clearing_walk(clearing_gait):
    """The clearing walker's 30 steps in MuJoCo at the default settings (1e-4 s steps, 1 ms
    contacts, friction 2), its angles sampled every 1 ms."""
    return walk_in_mujoco(clearing_gait.params, clearing_gait.fixed_point, steps=STEPS, sample_rate=1000.0)


def _model_angles(traj) -> np.ndarray:
    """The model's simulated angles, shape (n, 4), columns SIGNALS."""
    left, right = traj.pitches()
    return np.column_stack([traj.lean, traj.steer, left, right])


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


def test_the_build_follows_the_model_over_a_step(clearing_gait):
    """Over the first step, before either heel strike, the MuJoCo walker's angles (read from its
    two legs' frames by kinematics.angles_from_rotations) follow the model's simulation, sampled
    every 1 ms, when the trailing foot's contact is off for the first integration step (0.1 ms).
    That foot starts on the ramp, leaving it at 0.150 m/s with no impulse in the model; MuJoCo
    finds it at zero distance and, for that one step, grips it with friction at its limit (2.8 N
    normal, 5.6 N tangential against the walker's 0.98 N weight), which is what
    test_the_walk_records_the_models_angles sees. Measured, 0..0.183 s: lean 4.0e-6 rad, steer
    1.2e-5 rad, pitches 6.5e-5 and 9.5e-5 rad, the same at 5e-5 and 2.5e-5 s steps. They come
    from the stance foot's creep: MuJoCo's friction is soft, and the material point at the contact
    moves 15 um sideways and 3 um along over the step (the lowest point ends 15 um beside the
    model's rolled contact), 1e-4 rad over the 0.15 m legs. Tolerances: 2e-4 rad on the pitches,
    twice that; 5e-5 rad on lean and steer, which it moves less. The stance foot's contact is
    the only one (it drops out for single integration steps, 60 of 1830, at under 0.26 um
    penetration)."""
    params, z0 = clearing_gait.params, clearing_gait.fixed_point
    model = mujoco.MjModel.from_xml_string(build_mjcf(params))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(params, z0)
    right = model.geom("right_foot").id
    model.geom_contype[right] = 0
    mujoco.mj_step(model, data)
    model.geom_contype[right] = 1
    per_sample = round(1e-3 / model.opt.timestep)
    end = clearing_gait.step_time - 1e-3  # before the model's heel strike, and MuJoCo's
    angles, times = [], []
    while data.time < end:
        mujoco.mj_step(model, data)
        if round(data.time / model.opt.timestep) % per_sample == 0:
            rot = [data.xmat[model.body(k).id].reshape(3, 3) for k in ("left", "right")]
            steer, lean, pitch_left, pitch_right = angles_from_rotations(*rot)
            angles.append((lean, steer, pitch_left, pitch_right))
            times.append(data.time)
        assert right not in data.contact.geom  # no heel strike or scuff yet
    sim = simulate(params, z0, 1, sample_rate=1000.0)
    n = len(times)
    np.testing.assert_allclose(times, sim.times[1:n + 1], rtol=0, atol=1e-9)
    error = np.abs(np.array(angles) - _model_angles(sim)[1:n + 1]).max(axis=0)
    assert np.all(error < [5e-5, 5e-5, 2e-4, 2e-4]), error


def test_the_walk_records_the_models_angles(clearing_gait, clearing_walk):
    """walk_in_mujoco's angle record, in the model's conventions (docs/model.md section 1: lean psi,
    steer phi, each leg's pitch, physical frame). At t = 0 the angles read back from MuJoCo's leg
    frames are z0's, exactly up to round-off (measured 2.8e-17 rad; tolerance 1e-9 rad), with the
    left foot in stance at the origin. Over the first step, until the earlier of the two heel
    strikes (0.1840 s in the model, 0.1843 s in MuJoCo), they follow the model's simulation;
    measured largest differences: lean 2.1e-4 rad, steer 6.5e-4 rad, pitch_left 2.2e-3 rad,
    pitch_right 3.8e-3 rad (0.22 degrees). These are the start's grip on the trailing foot
    (test_the_build_follows_the_model_over_a_step: without it they are 35 to 55 times smaller), which
    changes the trailing leg's rate by 0.06 rad/s in 0.1 ms. Tolerance 5e-3 rad for all four: the
    gait's lean reaches 0.034 rad and its steer 0.07 rad, so a sign or a swapped leg would show."""
    walk, z0 = clearing_walk, clearing_gait.fixed_point
    assert walk.times[0] == 0.0 and walk.stance[0] == "L"
    np.testing.assert_allclose(walk.angles[0], z0[[2, 0, 4, 6]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(walk.contact[0], [0.0, 0.0], rtol=0, atol=1e-9)
    assert np.allclose(np.diff(walk.times), 1e-3, rtol=0, atol=1e-9)
    sim = simulate(clearing_gait.params, z0, 1, sample_rate=1000.0)
    end = min(sim.events[0].time, walk.step_times[0])
    n = int(np.sum(sim.times < end))
    np.testing.assert_allclose(walk.times[:n], sim.times[:n], rtol=0, atol=1e-9)
    assert np.all(walk.stance[:n] == "L")
    error = np.abs(walk.angles[:n] - _model_angles(sim)[:n]).max(axis=0)
    assert np.all(error < 5e-3), error
    # The stance foot's contact point, which rolls 3.4 mm down the ramp and 0.5 mm across it:
    # measured 2.1e-5 m from the model's (the start's grip and the creep); tolerance 0.1 mm, 3 %
    # of the roll, so that a contact read from the wrong foot (107 mm away) shows.
    offset = np.abs(walk.contact[:n] - sim.contact[:n]).max()
    assert offset < 1e-4, offset


def test_the_clearing_walker_walks_30_steps_in_mujoco(clearing_gait, clearing_walk):
    """Issue 13, item 3: data/params/clearing-toy.toml, started from the model's fixed point with
    both feet's contacts on, walks 30 steps without falling or scuffing; over them its mean step
    time is the model's to 2 % and its lean amplitude to 20 % (the done criterion).

    Measured (1e-4 s steps, 1 ms contacts, friction 2), against the model's gait:

    - step time: mean 0.18396 s against 0.18397 s (-0.002 %); single steps -6.0..+4.8 %, strides
      -5.8..+3.9 %. The walk does not settle onto a periodic gait: over 150 steps the step time
      keeps fluctuating (rms 2.1 %, periods of 6 to 13 steps), where the model's walk from a
      start perturbed by 1e-3 rad/s is back within 6e-5 of its step time by the 30th step (its
      eigenvalues all lie inside 0.86);
    - step length: mean 40.07 mm against 40.62 mm (-1.4 %); single steps 37.0..43.4 mm, strides
      -2.4..-0.2 %. Single steps alternate because the heading wanders (below) and the feet are
      107 mm apart (107 mm * sin(1.7 deg) = 3.2 mm either way); a stride is blind to that;
    - lean amplitude (half the peak-to-peak of psi over a stride, Gait.lean_amplitude's
      definition): mean 1.924 degrees against 1.923 (+0.03 %), single strides -13.6..+8.8 %;
    - steer amplitude: mean 4.017 degrees against 4.040 (-0.6 %), single strides -2.2..+1.4 %;
    - heading (each stride's direction from left contact to left contact): 0 in the model, here
      -0.05 degrees in the first stride, -1.70 in the ninth, -0.88 in the fifteenth.

    Tolerances: mean step time and step length 2 % (the criterion); lean amplitude 20 % on the
    mean (the criterion) and on each stride (measured 13.6 %); each step time 8 % (measured
    6.0 %) and each stride 3 % (2.4 %), the spread of a walk that does not settle with a quarter
    to a third more; each stride's steer amplitude 5 % (2.2 %); heading 3 degrees, near twice the
    measured wander. The walk itself is fragile
    (docs/gaits.md section 4): with the start's rates changed by 1e-3 rad/s, four of eight starts
    fell within 38 steps, and from the fixed point the walks at friction 4 and with 2 ms contacts
    fell after 22 and 10 steps. That is what MuJoCo says about this gait's stability, not a
    tolerance: the test pins the default walk."""
    gait, walk = clearing_gait, clearing_walk
    assert walk.status == "completed", walk.message
    assert walk.steps == STEPS and walk.scuffs == 0
    step_time, step_length = gait.step_time, 0.5 * gait.stride_length
    assert abs(walk.step_times.mean() / step_time - 1) < 0.02
    assert abs(walk.step_lengths.mean() / step_length - 1) < 0.02
    assert np.all(np.abs(walk.step_times / step_time - 1) < 0.08)
    strides = walk.step_lengths.reshape(-1, 2).sum(axis=1)
    assert np.all(np.abs(strides / gait.stride_length - 1) < 0.03)
    assert abs(walk.lean_amplitude / gait.lean_amplitude - 1) < 0.2
    assert np.all(np.abs(walk.stride_amplitudes("lean") / gait.lean_amplitude - 1) < 0.2)
    assert np.all(np.abs(walk.stride_amplitudes("steer") / gait.steer_amplitude - 1) < 0.05)
    assert len(walk.stride_headings) == STEPS // 2
    assert np.all(np.abs(walk.stride_headings) < math.radians(3.0))


def test_the_walk_is_a_trajectory_the_fit_reads(tmp_path, clearing_gait, clearing_walk):
    """mujoco_trajectory writes the walk as `toywalk simulate` writes one (docs/formats.md, "Trajectory"):
    the columns of the model's simulation, the heel strikes after the start as events with their
    contact positions, metadata naming MuJoCo and its settings. It survives write_trajectory and
    read_trajectory exactly (repr'd floats), and sysid.measurement.observations cuts it into the
    walk's steps: 29 complete steps between its 30 heel strikes, each sample in the step its
    stance column says, at a phase in [0, 1]."""
    walk, params = clearing_walk, clearing_gait.params
    table = mujoco_trajectory(walk, params, parameters=str(CLEARING))
    path = tmp_path / "mujoco.csv"
    write_trajectory(table, path)
    back = read_trajectory(path)
    assert sorted(back.signals) == sorted([*SIGNALS, "contact_x", "contact_y"])
    np.testing.assert_array_equal(back.time, walk.times)
    for i, name in enumerate(SIGNALS):
        np.testing.assert_array_equal(back.signals[name], walk.angles[:, i])
    np.testing.assert_array_equal(back.signals["contact_x"], walk.contact[:, 0])
    np.testing.assert_array_equal(back.stance, walk.stance)
    assert [e["foot"] for e in back.events] == ["R", "L"] * (STEPS // 2)
    np.testing.assert_array_equal([[e["time"], e["x"], e["y"]] for e in back.events], walk.strikes)
    source = back.metadata["source"]
    assert source["kind"] == "mujoco" and source["parameters"] == str(CLEARING)
    assert source["timestep"] == 1e-4 and source["friction"] == 2.0
    assert source["contact_time_constant"] == 1e-3 and source["sample_rate"] == 1000.0
    assert source["parameter_values"]["hip_width"] == params.hip_width
    assert source["start"]["theta_st"] == clearing_gait.fixed_point[4]
    assert back.metadata["units"] == {"time": "s", "angles": "rad", "contact": "m"}
    assert back.metadata["status"] == "completed" and back.metadata["scuffs"] == 0

    obs = observations(back)
    strikes = walk.strikes[:, 0]
    assert obs.n_steps == STEPS - 1
    np.testing.assert_array_equal(obs.strikes, strikes)
    assert list(obs.stance) == walk.feet[:-1]
    np.testing.assert_array_equal(obs.contact, walk.strikes[:, 1:])
    stance_at = dict(zip(walk.times.tolist(), walk.stance, strict=True))
    assert all(stance_at[t] == obs.stance[k] for t, k in zip(obs.time, obs.step, strict=True))
    assert np.all((obs.phase >= 0) & (obs.phase <= 1))
    # Every sample between the first and the last heel strike is observed, once per signal.
    inside = np.sum((walk.times >= strikes[0]) & (walk.times < strikes[-1]))
    assert len(obs.value) == len(SIGNALS) * inside


def test_bad_requests_say_what_is_wrong(clearing_gait):
    """1 / sample_rate must be a whole number of integration steps (300 Hz is 33.3 steps of
    1e-4 s); amplitudes need a complete stride and a signal that has one."""
    params, z0 = clearing_gait.params, clearing_gait.fixed_point
    with pytest.raises(ValueError, match="sample_rate"):
        walk_in_mujoco(params, z0, sample_rate=300.0)
    with pytest.raises(ValueError, match="sample_rate"):
        walk_in_mujoco(params, z0, sample_rate=0.0)
    walk = walk_in_mujoco(params, z0, steps=1, sample_rate=100.0)
    assert walk.status == "completed" and len(walk.times) == 19  # 0..0.18 s
    with pytest.raises(ValueError, match="no complete stride"):
        _ = walk.lean_amplitude
    with pytest.raises(ValueError, match="signal must be"):
        walk.stride_amplitudes("pitch_left")


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


def test_a_landing_foot_that_bounces_is_not_a_second_heel_strike():
    """docs/robust_best.toml (the design of docs/make_robust_design.py, docs/gaits.md section 7)
    from its fixed point with the four rates kicked by 0.02 rad/s,
    the signs of seed 5 as docs/make_basin_mujoco.py draws them, at 1 ms contacts and friction 1:
    its right foot lands at 0.668 s, leaves the ramp for over 2 ms and lands again 7 ms later
    (measured: 0.6681 and 0.6751 s), and the walker walks on. The second touch is a bounce, counted
    as one, and the sixth heel strike is the left foot's a step later (0.803 s; the gait's step is
    134.5 ms, checked to within the kick's spread of 10 ms). Before bounces were told apart the walk
    ended there as the same foot striking twice. About 0.2 s."""
    gait = find_gait(load_params(ROOT / "docs" / "robust_best.toml"))
    z0 = gait.fixed_point.copy()
    z0[[1, 3, 5, 7]] += 0.02 * np.random.default_rng(5).choice([-1.0, 1.0], 4)
    walk = walk_in_mujoco(gait.params, z0, steps=6, friction=1.0, contact_time=1e-3)
    assert walk.status == "completed" and walk.steps == 6
    assert walk.bounces == 1 and walk.scuffs == 0
    assert walk.feet == ["R", "L", "R", "L", "R", "L"]
    assert walk.strikes[4, 0] == pytest.approx(0.668, abs=1e-3)
    assert walk.step_times[5] == pytest.approx(gait.step_time, abs=0.01)
