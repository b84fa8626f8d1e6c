"""The joint fit of both legs sharing one hip axis (tracking/joint.py): recovery of a known pose
from exact and from noisy corners, the analytic Jacobian against finite differences and the stacked
model against the leg-by-leg one, the hip width, and the mirror ambiguity that a single marker
leaves and the other leg removes."""

import numpy as np
import pytest
from scipy import stats
from toywalk.tracking.camera import undistort_pixels
from toywalk.tracking.joint import _Problem, fit_walker, rot_y
from toywalk.tracking.track import walker_angles

from .scenes import COMPASS, COMPASS_ANGLES, compass_scene, start_near


@pytest.fixture(scope="module")
def setup():
    return compass_scene()


def observations(corners, ids=None, noise=0.0, rng=None):
    rng = np.random.default_rng(rng)
    out = {}
    for foot, markers in corners.items():
        use = [i for i in markers if ids is None or i in ids]
        if use:
            pixels = np.concatenate([markers[i][1] for i in use])
            out[foot] = (np.concatenate([markers[i][0] for i in use]),
                         pixels + rng.normal(0, noise, pixels.shape))
    return out


def test_exact_corners_give_the_true_angles(setup):
    camera, r_ramp, truth, corners = setup
    pose = fit_walker(camera, observations(corners), start_near(truth), hip_width=0.1)
    # exact projections: the fit's residual is round-off (undistortion iterated to 1e-12)
    assert pose.rms < 1e-6
    lean, steer, pl, pr = walker_angles(r_ramp, pose)
    np.testing.assert_allclose([steer, lean, pl, pr], COMPASS_ANGLES, atol=1e-8)
    np.testing.assert_allclose(pose.hip_point("L"), truth["L"][1], atol=1e-8)  # m


def test_hip_width_is_estimated(setup):
    camera, _, truth, corners = setup
    pose = fit_walker(camera, observations(corners), start_near(truth), hip_width=0.05, fit_hip_width=True)
    assert "hip_width" in pose.names
    np.testing.assert_allclose(pose.hip_width, COMPASS.hip_width, atol=1e-8)  # exact data


def test_jacobian_matches_finite_differences(setup):
    camera, _, truth, corners = setup
    problem = _Problem(camera, {f: o[:2] for f, o in observations(corners).items()}, fit_width=True)
    axle, pitch, hip = start_near(truth)
    r0, jac = problem.evaluate(axle, pitch, hip, 0.1)
    h = 1e-7
    for j in range(len(problem.names)):
        delta = np.zeros(len(problem.names))
        delta[j] = h
        r1, _ = problem.evaluate(*problem.step(axle, pitch, hip, 0.1, delta), jacobian=False)
        # central differences would be 1e-9; forward ones err by h |d2r| ~ 1e-7 * 1e4 px
        np.testing.assert_allclose((r1 - r0) / h, jac[:, j], atol=2e-3 * np.abs(jac[:, j]).max() + 1e-3,
                                   err_msg=problem.names[j])


def test_noise_gives_honest_covariance(setup):
    """With 0.3-pixel corner noise, the angle errors over 200 fits match the stated covariance."""
    camera, r_ramp, truth, corners = setup
    sigma = 0.3
    errors, sds, dofs = [], [], set()
    from toywalk.tracking.track import walker_angles_with_sd

    for k in range(200):
        pose = fit_walker(camera, observations(corners, noise=sigma, rng=k), start_near(truth), hip_width=0.1)
        values, sd = walker_angles_with_sd(r_ramp, pose, sigma)
        errors.append([values[n] - a for n, a in zip(("steer", "lean", "pitch_left", "pitch_right"),
                                                       COMPASS_ANGLES, strict=True)])
        sds.append([sd[n] for n in ("steer", "lean", "pitch_left", "pitch_right")])
        dofs.add(pose.dof)
    z = np.array(errors) / np.array(sds)
    # walker_angles_with_sd inflates a fit's covariance by max(1, (rms / expected)^2), which is
    # max(1, X / d) for X ~ chi-square on the fit's d residual degrees of freedom, independent of
    # the pose error: the RMS of z is sqrt(E[1 / max(1, X / d)]) = sqrt(P(X <= d) + d / (d - 2)
    # P(X' > d)), X' ~ chi-square on d - 2 (as x^-1 f_d(x) = f_{d-2}(x) / (d - 2)); 0.958 for d = 25
    # (measured over 6000 fits: 0.93-0.96).
    (d,) = dofs
    centre = np.sqrt(stats.chi2(d).cdf(d) + d / (d - 2) * stats.chi2(d - 2).sf(d))
    # Over 200 draws an RMS scatters with SD centre / sqrt(2 * 200) = 0.048 (measured 0.048-0.059
    # over 30 batches of 200); 4 SDs, 0.2, hold all 30 (these draws give steer 1.105, the largest
    # of them). SDs 20 % too small fail (3 of the 4 angles), 25 % too large fail (lean).
    np.testing.assert_allclose(np.sqrt(np.mean(z**2, axis=0)), centre, rtol=0, atol=0.2)


def test_one_marker_leg_is_pinned_by_the_other(setup):
    """A leg seen through one marker alone has two poses that fit alike; with the other leg's
    markers fixing the axle, only its pitch is free and the fit finds the true one even from a
    start 10 degrees off."""
    camera, r_ramp, truth, corners = setup
    obs = observations(corners, ids={0, 2, 3})  # left leg: its upper flag only
    axle, pitch, hip = start_near(truth)
    pitch = {**pitch, "L": pitch["L"] + 0.17}
    pose = fit_walker(camera, obs, (axle, pitch, hip), hip_width=0.1)
    lean, steer, pl, pr = walker_angles(r_ramp, pose)
    np.testing.assert_allclose([steer, lean, pl, pr], COMPASS_ANGLES, atol=1e-7)


def test_rot_y_is_a_pitch():
    # docs/model.md: Ry(theta) turns b3 (foot to hip) towards +x (forward) for theta > 0
    np.testing.assert_allclose(rot_y(0.3) @ [0, 0, 1], [np.sin(0.3), 0, np.cos(0.3)], atol=1e-15)


def _reference_evaluate(camera, observations, names, axle, pitch, hip, width):
    """The joint model's residuals and Jacobian leg by leg, as ``_Problem.evaluate`` computed
    them before it stacked the legs: a slow, obvious reference."""
    rows_r, rows_j = [], []
    k = len(names)
    fx, fy = camera.matrix[0, 0], camera.matrix[1, 1]
    e2 = np.array([0.0, 1.0, 0.0])
    for f in ("L", "R"):
        if f not in observations:
            continue
        obj, pixels = observations[f]
        meas = undistort_pixels(camera, pixels)
        y_pitch = obj @ rot_y(pitch[f]).T
        y = y_pitch + (width * e2 if f == "L" else 0.0)
        x = y @ axle.T + hip
        z = x[:, 2]
        u, v = x[:, 0] / z, x[:, 1] / z
        rows_r.append(np.column_stack([fx * (u - meas[:, 0]), fy * (v - meas[:, 1])]).ravel())
        dp = np.zeros((len(z), 2, 3))
        dp[:, 0, 0], dp[:, 0, 2] = fx / z, -fx * u / z
        dp[:, 1, 1], dp[:, 1, 2] = fy / z, -fy * v / z
        dx = np.zeros((len(z), 3, k))
        zero = np.zeros(len(z))
        dx[:, :, 0] = np.column_stack([zero, -y[:, 2], y[:, 1]]) @ axle.T
        dx[:, :, 1] = np.column_stack([-y[:, 1], y[:, 0], zero]) @ axle.T
        dx[:, :, names.index(f"pitch_{f}")] = np.column_stack([y_pitch[:, 2], zero, -y_pitch[:, 0]]) @ axle.T
        base = names.index("hx")
        dx[:, :, base:base + 3] = np.eye(3)
        if "hip_width" in names and f == "L":
            dx[:, :, names.index("hip_width")] = axle[:, 1]
        rows_j.append(np.einsum("nab,nbk->nak", dp, dx).reshape(-1, k))
    return np.concatenate(rows_r), np.concatenate(rows_j)


@pytest.mark.parametrize("ids, fit_width", [(None, True), (None, False), ({0, 2, 3}, True), ({0, 1}, False),
                                            ({2, 3}, True)])
def test_stacked_model_matches_leg_by_leg(setup, ids, fit_width):
    """Both legs' corners stacked in one array give the leg-by-leg residuals and Jacobian, for
    both legs (hip width fitted or not), one marker on a leg, and one leg alone."""
    camera, _, truth, corners = setup
    obs = {f: o[:2] for f, o in observations(corners, ids=ids).items()}
    problem = _Problem(camera, obs, fit_width)
    assert problem.names[-1:] == (("hip_width",) if fit_width and len(obs) == 2 else ("hz",))
    axle, pitch, hip = start_near(truth)
    r, jac = problem.evaluate(axle, pitch, hip, 0.1)
    r_ref, jac_ref = _reference_evaluate(camera, obs, problem.names, axle, pitch, hip, 0.1)
    # the same sums in another order: agreement to rounding (|J| ~ 1e3 px per unit, r ~ 10 px)
    np.testing.assert_allclose(r, r_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=1e-12 * np.abs(jac_ref).max())
    assert np.abs(r).max() > 1.0  # a start off the truth: residuals of pixels, not zero
