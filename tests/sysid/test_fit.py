"""The measurement model and the simultaneous BVP fit: recovery of a known truth, the reduced
Jacobian against finite differences, an unstable gait, and the command line."""

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import bvp, initial_guess
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable
from toywalk.model.walker import Walker
from toywalk.sysid.fit import FitError, fit, fit_bounds, score_statistics
from toywalk.sysid.measurement import MeasurementError, observations, operator

from ..conftest import DATA
from .builders import RECOVERED, simulated_walk, start_off
from .command import run


@pytest.fixture(scope="module")
def toy():
    return load_params(DATA / "params" / "stable-toy.toml")


def test_operator_reproduces_the_simulated_walk(toy):
    """The collocation gait, read at each sample's phase by the measurement operator, equals a
    forward simulation (RK8 shooting) of the same gait: two independent integrations."""
    # Samples between the integration grid's nodes are cubic Hermite interpolants, O(dt^4): 1e-5
    # rad at the default 16 steps per sqrt(l/g); at 128 they are below 1e-8.
    table, gait = simulated_walk(toy, 6, 0.0, 0, steps_per_time_unit=128)
    obs = observations(table)
    prob = bvp(False, 30, 4, 1)
    walker = Walker(toy)
    sol = prob.solver(x0=initial_guess(walker, gait.fixed_point, prob), p=toy.input_vector(),
                      lbg=prob.lbg, ubg=prob.ubg)
    w = np.array(sol["x"]).ravel()
    a_op, b_op, model_step = operator(obs, prob, planar=False)
    # Gauss-Legendre degree 4 on 30 intervals vs RK8 at 16 steps per sqrt(l/g), both ~1e-11;
    # the sample phases come from the heel-strike times (exact events): agreement to 1e-8 rad.
    assert_allclose(a_op @ w, obs.value, atol=1e-8)
    assert_allclose([w[prob.duration_index(0)]] * obs.n_steps, obs.durations, atol=1e-10)
    assert b_op.shape == (len(obs.value), 3) and np.all(b_op.sum(axis=1) == 1)
    # The check can fail: the operator without the mirror of right-stance steps is wrong.
    wrong = a_op @ w
    right_steps = np.isin(obs.step, np.flatnonzero(obs.stance == "R")) & (obs.signal <= 1)
    wrong[right_steps] *= -1
    assert np.abs(wrong - obs.value).max() > 1e-3


def test_observations_refuse_unusable_walks(toy):
    table, _ = simulated_walk(toy, 4, 0.0, 0)
    short = TrajectoryTable(table.time, table.signals, table.stance, table.events[:2], {})
    with pytest.raises(MeasurementError, match="at least 3"):
        observations(short)
    skipped = TrajectoryTable(table.time, table.signals, table.stance,
                              [table.events[0], table.events[2], table.events[3]], {})
    with pytest.raises(MeasurementError, match="missing .* no two complete steps in a row"):
        observations(skipped)
    bad = dict(table.signals)
    bad["lean"] = bad["lean"].copy()
    bad["lean"][5] = np.inf
    with pytest.raises(MeasurementError, match="infinite"):
        observations(TrajectoryTable(table.time, bad, table.stance, table.events, {}))


def test_observations_keep_the_longest_run_of_complete_steps(toy):
    """Where a tracker missed heel strikes, the walk's longest run of single steps is fitted and
    the rest set aside, said in a note: one strike missed leaves the same foot twice in a row, two
    missed leave the feet alternating across about three steps, which read as one step would
    compare three steps with one model step (the fit took such a walk without a word)."""
    table, _ = simulated_walk(toy, 12, 0.0, 0)
    events = table.events
    whole = observations(table)
    assert whole.note is None and whole.n_steps == 12
    # one strike missed (the 4th): steps 0-2 and 4-11 (the same foot at events 3 and 5)
    one = observations(TrajectoryTable(table.time, table.signals, table.stance,
                                       events[:4] + events[5:], {}))
    assert one.n_steps == 7 and one.step_start[0] == events[5]["time"]
    assert "again at" in one.note and "the 7 complete steps" in one.note
    # two missed in a row (the 9th and 10th): alternating feet across three steps, 3.0 median steps
    two = observations(TrajectoryTable(table.time, table.signals, table.stance,
                                       events[:9] + events[11:], {}))
    assert two.n_steps == 8 and two.step_end[-1] == events[8]["time"]
    assert "3.0 median steps" in two.note
    # the kept run is read as the whole walk's same steps are: the same observations
    same = whole.step >= 5
    assert_allclose(one.value, whole.value[same])
    assert_allclose(one.phase, whole.phase[same])
    # the fit says what it set aside
    result = fit(TrajectoryTable(table.time, table.signals, table.stance, events[:4] + events[5:], {}),
                 toy, ["foot_radius"], n_intervals=12, check_jacobian=False)
    assert result.warnings[0] == one.note


def test_fit_recovers_foot_radius_mass_offset_and_impact_share(toy):
    """Noisy walk (0.002 rad, about what the tracker measures) of a walker with a trailing-foot
    impulse share: the fit from a start 10 % off recovers the three parameters within three
    reported standard errors, and the residuals are at the noise level."""
    truth = toy.replace(**{"effects.impact_trailing_share": 0.1})
    table, gait = simulated_walk(truth, 12, 0.002, 1)
    start, free = start_off(truth), RECOVERED
    result = fit(table, start, free)
    assert result.success, result.status
    for name in free:
        err = result.estimates[name] - truth.get(name)
        assert abs(err) < 3 * result.std[name], (name, err, result.std[name])
        assert result.std[name] < 0.1 * abs(truth.get(name))  # the data do determine it
    for name in ("lean", "steer", "pitch_left", "pitch_right"):
        # Estimated noise: the residual RMS, within 20 % of the truth for ~500 samples a signal.
        assert abs(result.residual_rms[name] / 0.002 - 1) < 0.2, name
    assert result.noise_source == "estimated from residuals"
    # The reduced Jacobian (implicit-function theorem through the BVP) against re-solved central
    # differences: both exact to the BVP's tolerance (1e-10), differences at 1e-5 relative steps.
    assert max(result.jacobian_check.values()) < 1e-6
    assert abs(result.gait["max_abs_eigenvalue"] - gait.max_abs_eigenvalue) < 0.01
    assert not result.warnings


def test_fit_follows_an_unstable_gait():
    """The Tinkertoy fit's gait is unstable (max |eigenvalue| 4.4): a simulation from a start off
    the gait falls within the walk, yet the BVP fit, which never simulates, recovers the foot
    radius from a start 8 % off."""
    truth = load_params(DATA / "params" / "tinkertoy.toml")
    gait = find_gait(truth)
    assert gait.max_abs_eigenvalue > 4
    table, _ = simulated_walk(truth, 6, 0.002, 2, gait)
    start = truth.replace(foot_radius=1.08 * truth.foot_radius)
    off = simulate(start, find_gait(start).fixed_point + 1e-3, 12)
    assert off.status == "fell"  # shooting cannot follow it for long
    result = fit(table, start, ["foot_radius"])
    assert result.success, result.status
    err = result.estimates["foot_radius"] - truth.foot_radius
    assert abs(err) < 3 * result.std["foot_radius"]
    assert not result.gait["stable"]


@pytest.mark.slow
def test_intervals_are_calibrated_over_20_seeds(toy):
    """20 noise draws (0.003 rad on the angles, 0.5 ms on the heel-strike times, both stated in
    the file as a tracker states them) on one 8-step walk: the 90 % intervals (1.645 reported SEs)
    of foot radius and lateral mass offset contain the truth 80-97 % of the time (issue 9), and
    the standardised errors have an SD near 1. (With the simulation's exact strike times and the
    default SD of a strike known only to its sample, 1.8 ms here, the intervals are conservative:
    40 of 40.)"""
    start = toy.replace(**{"foot_radius": 1.05 * toy.foot_radius,
                           "com_offset[1]": 0.98 * toy.com_offset[1]})
    start_gait = find_gait(start)
    gait = find_gait(toy)
    traj = simulate(toy, gait.fixed_point, 8)
    clean = traj.angles()
    strikes = [(0.0, "L")] + [(e.time, e.foot) for e in traj.events]
    free = ["foot_radius", "com_offset[1]"]
    z = []
    for seed in range(20):
        rng = np.random.default_rng(100 + seed)
        signals = {k: v + rng.normal(0.0, 0.003, v.shape) for k, v in clean.items()}
        events = [{"time": t + rng.normal(0.0, 5e-4), "foot": f, "time_sd": 5e-4} for t, f in strikes]
        table = TrajectoryTable(traj.times, signals, traj.stance, events, {})
        result = fit(table, start, free, z_guess=start_gait.fixed_point, n_intervals=20,
                     check_jacobian=False)
        assert result.success, (seed, result.status)
        z += [(result.estimates[n] - toy.get(n)) / result.std[n] for n in free]
    inside = np.mean(np.abs(z) < 1.6449)
    assert 0.80 <= inside <= 0.97, inside
    # The SD of 40 standard normal draws lies in [0.7, 1.3] with probability > 0.99.
    assert 0.7 < np.std(z) < 1.3


def test_fit_refuses_bad_requests(toy):
    table, _ = simulated_walk(toy, 3, 0.001, 0)
    with pytest.raises(FitError, match="not a parameter"):
        fit(table, toy, ["foot_radiuss"])
    with pytest.raises(FitError, match="named twice"):
        fit(table, toy, ["foot_radius", "foot_radius"])


def test_fit_command(tmp_path):
    params = DATA / "params" / "stable-toy.toml"
    walk = tmp_path / "walk.csv"
    assert run("simulate", "--params", params, "--steps", "8", "--noise", "0.002", "--seed", "5",
               "--out", walk).returncode == 0
    out = run("fit", walk, "--params", params, "--free", "foot_radius,com_offset[1]",
              "--out", tmp_path / "fit.json")
    assert out.returncode == 0, out.stderr
    report = json.loads((tmp_path / "fit.json").read_text())
    for key in ("estimates", "std", "covariance", "residual_rms", "status"):
        assert key in report
    assert set(report["estimates"]) >= {"foot_radius", "com_offset[1]"}
    assert math.isfinite(report["std"]["foot_radius"])
    bad = run("fit", walk, "--params", params, "--free", "warp", "--out", tmp_path / "bad.json")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "not a parameter" in bad.stderr and not (tmp_path / "bad.json").exists()
    missing = run("fit", tmp_path / "nope.csv", "--params", params, "--free", "foot_radius",
                  "--out", tmp_path / "m.json")
    assert missing.returncode == 2 and "not found" in missing.stderr


def test_fit_says_when_a_parameter_is_weakly_determined(toy):
    """The stable toy leans 0.3 deg: its lateral foot radius barely shows in the angles. The fit
    says so (standard error larger than the parameter's magnitude), and an estimate that ends on
    its bound is clipped into it, so that the fitted walker is valid."""
    table, _ = simulated_walk(toy, 8, 0.002, 3)
    result = fit(table, toy, ["foot_lateral_radius", "foot_radius"], check_jacobian=False)
    assert any("foot_lateral_radius is weakly determined" in note for note in result.warnings)
    assert result.std["foot_lateral_radius"] > toy.foot_lateral_radius
    assert 0.0 <= result.params.foot_lateral_radius <= result.params.foot_radius
    assert result.std["foot_radius"] < 0.05 * toy.foot_radius  # the other one is determined


def test_a_prior_on_the_slope_combines_with_the_data(toy):
    """The slope as measured with its error: a Gaussian prior adds (theta - mean) / sd to the
    residuals. With a prior twice as tight as the data, 2 data-SEs away, the estimate moves
    towards the prior's mean and its SE falls below both the prior's SD and the data's SE."""
    table, _ = simulated_walk(toy, 8, 0.002, 4)
    free = ["slope", "foot_radius"]
    data_only = fit(table, toy, free, check_jacobian=False)
    sd = 0.5 * data_only.std["slope"]
    mean = toy.slope + 2 * data_only.std["slope"]
    both = fit(table, toy, free, priors={"slope": (mean, sd)}, check_jacobian=False)
    assert both.success
    assert both.std["slope"] < min(sd, data_only.std["slope"])
    assert abs(both.estimates["slope"] - mean) < abs(data_only.estimates["slope"] - mean)
    with pytest.raises(FitError, match="not free"):
        fit(table, toy, ["foot_radius"], priors={"slope": (0.05, 0.01)})


def test_foot_radii_stay_ordered():
    """A spherical foot (compass-3d: rho = r) stays a sphere when its radius alone is free: both
    radii move together (sysid.problem.tied), the estimate recovers the truth, and the reduced
    Jacobian through the tie agrees with re-solved differences. A torus foot's fore-aft radius
    freed alone is bounded below by the fixed sideways one; freeing both keeps rho <= r (a
    constraint). Either way the fitted walker is valid, and a failed fit is refused by the
    sampler with the reason."""
    params = load_params(DATA / "params" / "compass-3d.toml")
    table, _ = simulated_walk(params, 6, 0.003, 21)
    start = params.replace(foot_radius=0.97 * params.foot_radius,
                           foot_lateral_radius=0.97 * params.foot_radius)
    one = fit(table, start, ["com_offset[2]", "foot_radius"])
    assert one.success, one.status
    assert one.params.foot_lateral_radius == one.params.foot_radius  # still a sphere
    err = one.estimates["foot_radius"] - params.foot_radius
    assert abs(err) < 3 * one.std["foot_radius"], (err, one.std["foot_radius"])
    # Central differences re-solve the BVP with the tie applied (p_full): both exact to the
    # BVP's tolerance (1e-10), differences at 1e-5 relative steps, as in the recovery test.
    assert max(one.jacobian_check.values()) < 1e-6
    # Bounds: a torus's fore-aft radius freed alone stays above its sideways one; a sphere's
    # has only its physical bound (its sideways radius follows it).
    torus = params.replace(foot_lateral_radius=0.9 * params.foot_radius)
    assert fit_bounds(torus, ["foot_radius"], "foot_radius")[0] == torus.foot_lateral_radius
    assert fit_bounds(params, ["foot_radius"], "foot_radius")[0] == 0.0
    assert fit_bounds(params, ["foot_radius", "foot_lateral_radius"], "foot_radius")[0] == 0.0
    both = fit(table, params, ["foot_radius", "foot_lateral_radius"], check_jacobian=False)
    assert both.success and both.params.foot_lateral_radius <= both.params.foot_radius
    from toywalk.sysid.sample import SampleError, posterior_from_fit

    failed = dict(one.to_json(), success=False, gait={}, warnings=["made up for the test"])
    with pytest.raises(SampleError, match="did not succeed"):
        posterior_from_fit(failed, table)


def test_score_statistics_are_the_joint_regressions_coefficients():
    """Rao's score step of a held column, projected off the fitted ones, against the slow obvious
    way (Frisch-Waugh-Lovell): regress -r on the fitted columns and that one together and read its
    coefficient and standard error (unit noise). Random, correlated columns; one held column a
    combination of the fitted ones (nothing left but round-off: a standard error 1e10 times the
    others')."""
    rng = np.random.default_rng(5)
    jac = rng.normal(size=(200, 6))
    jac[:, 4] += 0.9 * jac[:, 0]  # correlated with a fitted column
    jac[:, 5] = jac[:, 1] - 2.0 * jac[:, 2]  # nothing beyond the fitted columns
    r = rng.normal(size=200) + 0.3 * jac[:, 4] + 0.5 * jac[:, 0]  # and along a fitted column
    got = score_statistics(jac, r, [3, 4, 5])
    for k, col in enumerate((3, 4)):
        design = np.column_stack([jac[:, :3], jac[:, col]])
        coef, *_ = np.linalg.lstsq(design, -r, rcond=None)
        cov = np.linalg.inv(design.T @ design)
        # two exact computations of the same numbers: agreement to rounding (1e-10 relative)
        assert_allclose(got[k]["step"], coef[-1], rtol=1e-10)
        assert_allclose(got[k]["se"], math.sqrt(cov[-1, -1]), rtol=1e-10)
    assert got[2]["se"] > 1e10 * got[1]["se"]
    # The check can fail: without the projection (the raw column) the step is a different number.
    raw = -float(jac[:, 4] @ r) / float(jac[:, 4] @ jac[:, 4])
    assert abs(raw - got[1]["step"]) > 0.1 * abs(got[1]["step"])
