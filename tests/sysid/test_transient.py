"""The transient model (a walk from a free start, every recorded step its own mesh) and the
periodicity test that says when a periodic fit is not appropriate."""

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import bvp, initial_guess
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker
from toywalk.sysid.fit import FitError, fit, periodicity_test
from toywalk.sysid.measurement import MeasurementError, model_steps, observations, operator

from ..conftest import DATA
from .builders import RECOVERED, simulated_walk, start_off

#: Lean rate of the released walk: 1.3 times the gait's (-0.51 rad/s on the cycle, an extra
#: -0.15 rad/s); the stable toy's slowest eigenvalues (|lambda| = 0.97) keep this visible over
#: the whole walk.
_KICK = 1.3


def _released(params, steps, noise, seed, kick=_KICK, steps_per_time_unit=16):
    """A walk released off its cycle (the gait's lean rate times ``kick``), as measured angles."""
    gait = find_gait(params)
    z0 = gait.fixed_point.copy()
    z0[1] *= kick
    table, _ = simulated_walk(params, steps, noise, seed, gait, steps_per_time_unit, z0)
    return table, z0


@pytest.fixture(scope="module")
def toy():
    return load_params(DATA / "params" / "stable-toy.toml")


def test_transient_bvp_reproduces_a_released_walk(toy):
    """The transient BVP with its start held at a released walk's start equals an RK8 simulation
    of that walk (two independent integrators), and its start has n_dyn - 1 free directions."""
    table, z0 = _released(toy, 6, 0.0, 0, steps_per_time_unit=128)
    obs = observations(table)
    prob = bvp(False, 12, 3, obs.n_steps, periodic=False)
    # The closure (8 equations) gives way to the start condition (1): 7 free directions, the
    # dimension of the post-collision surface (the step map's zero eigenvalue is the eighth).
    assert prob.phases * prob.phase_size - prob.n_equalities == prob.n_dyn - 1
    walker = Walker(toy)
    w0 = initial_guess(walker, z0, prob)
    held = np.arange(prob.state_index(0, 0, 0), prob.state_index(0, 0, 0) + prob.n_dyn)
    lbx, ubx = np.full(len(w0), -np.inf), np.full(len(w0), np.inf)
    # Seven held; the start condition fixes the eighth, the swing leg's angle (internal order:
    # lean, steer, stance and swing pitch, then their rates), where h(x_0) is most sensitive.
    hold = np.delete(held, 3)
    lbx[hold] = ubx[hold] = w0[hold]
    sol = prob.solver(x0=w0, p=toy.input_vector(), lbg=prob.lbg, ubg=prob.ubg, lbx=lbx, ubx=ubx)
    assert prob.solver.stats()["success"]
    w = np.array(sol["x"]).ravel()
    # The swing angle solved back from h(x_0) = 0: the simulated start's own, to the BVP's
    # tolerance (1e-12) over dh/dtheta_sw (about the leg length).
    assert_allclose(w[held], w0[held], atol=1e-10)
    a_op, _, model_step = operator(obs, prob, planar=False)
    assert list(model_step) == list(range(obs.n_steps))
    # Gauss-Legendre degree 3 on 12 intervals a step: measured 4e-6 rad against RK8 at 128 steps
    # per sqrt(l/g) (the error of the coarse transient mesh, 0.2 % of a tracker's 0.002 rad).
    assert np.abs(a_op @ w - obs.value).max() < 1e-5
    durations = [w[prob.duration_index(k)] for k in range(obs.n_steps)]
    assert_allclose(durations, obs.durations, atol=1e-8)  # measured 3e-9 s
    # The check can fail: the periodic gait read at the same phases misses the released walk.
    gait_w = np.tile(initial_guess(walker, find_gait(toy).fixed_point, bvp(False, 12, 3, 1)),
                     obs.n_steps)
    assert np.abs(a_op @ gait_w - obs.value).max() > 1e-2
    # A start with its swing foot off the ramp is not a heel-strike state.
    raised = w.copy()
    raised[held[:4]] += 0.01  # the angles (internal order: the four angles, then their rates)
    g = np.array(prob.constraints(raised, toy.input_vector())).ravel()
    assert abs(g[prob.start_guard_index]) > 1e-4
    with pytest.raises(MeasurementError, match="transient model of 5 steps"):
        model_steps(obs, 5, periodic=False)


@pytest.mark.slow
def test_periodicity_test_rejects_a_released_walk_and_the_transient_fit_recovers_it(toy):
    """A stable toy released with 1.3 times its lean rate, 12 steps, 0.002 rad noise. The
    periodic fit cannot follow it (residuals far above the noise, estimates pulled away); the
    periodicity test rejects the periodic model; the transient fit recovers the foot radius,
    lateral mass offset and trailing share within 3 reported SEs, and the released lean rate.
    Measured: delta chi-square in the thousands (p ~ 0); the transient's standardised errors
    -0.7, 0.1 and 1.7 when fitted aligned on the measured strikes (its first stage)."""
    truth = toy.replace(**{"effects.impact_trailing_share": 0.1})
    table, z0 = _released(truth, 12, 0.002, 1)
    start, free = start_off(truth), RECOVERED
    test = periodicity_test(table, start, free)
    assert test.appropriate is False and test.p_value < 1e-6, test.message
    assert test.dof == 7 and test.chosen is test.transient
    # and its periodic fit's residuals change from step to step (measured F = 1300)
    assert test.step_dependence["p"] < 1e-6 and "from step to step" in test.message
    tr = test.transient
    assert tr.success and tr.model == "transient"
    for name in free:
        assert abs(tr.estimates[name] - truth.get(name)) < 3 * tr.std[name], name
        assert tr.std[name] < 0.05 * abs(truth.get(name))
    # The residuals are the noise (estimated per signal: within 20 % for ~200 samples a signal).
    for name in ("lean", "steer", "pitch_left", "pitch_right"):
        assert abs(tr.residual_rms[name] / 0.002 - 1) < 0.2, name
    # The free start's lean rate: 2 % of the kick's 0.15 rad/s (about 3 SE; the rates at a heel
    # strike come from the angles after it, 0.002 rad of noise at 20 samples a step).
    assert abs(tr.initial_state["phi_dot"] - z0[1]) < 0.02 * abs(z0[1])
    # Reduced Jacobian through the transient BVP (start held) against re-solved central
    # differences: measured 1e-8 to 4e-8 relative.
    assert max(tr.jacobian_check.values()) < 1e-6
    # The check can fail: the periodic fit's residuals are far above the noise (measured 0.5 to
    # 3 deg against 0.11 deg), so with the transient's noise model its reduced chi-square is
    # far above one.
    assert test.periodic.residual_rms["steer"] > 10 * 0.002
    assert test.periodic.chi2 > 10 * test.periodic.n_residuals
    # The periodic gait of the transient fit's walker is the truth's (stable, the same slowest
    # eigenvalue to 0.01).
    assert abs(tr.gait["max_abs_eigenvalue"] - find_gait(truth).max_abs_eigenvalue) < 0.01


@pytest.mark.slow
def test_a_walk_on_its_cycle_that_the_model_misfits_stays_periodic(toy):
    """The stable toy with rolling resistance hidden (2e-4 N m s/rad, the library's typical
    value), on its cycle, 12 steps, 0.002 rad noise, fitted by the base model (nothing free). A
    free start bends the transient towards what the model cannot follow, so the likelihood ratio
    alone rejects the periodic model (measured: 28.6 on 7 degrees of freedom, p = 1.7e-4; 185 on
    two `toywalk simulate` walks of the same, both until now called off their cycle); but the
    periodic fit's residuals repeat every step (step-to-step F measured 0.88, p = 0.81), so the
    walk is kept periodic and the message says why. The released walk above is still rejected
    (there F = 1300)."""
    truth = toy.replace(**{"effects.rolling_resistance": 2e-4})
    table, _ = simulated_walk(truth, 12, 0.002, 5711)
    said = []
    test = periodicity_test(table, toy, [], progress=said.append)
    # a line before each fit (toywalk fit prints them in a terminal: a long walk's take minutes)
    assert [m.split(":")[0] if m.startswith("periodicity") else m for m in said] == [
        "periodicity test", "periodicity test", "periodicity test", "periodicity test",
        "the periodic model, on its own heel strikes"], said
    assert test.p_value < test.alpha, test.message  # the likelihood ratio alone would reject
    assert test.step_dependence["p"] >= test.alpha and test.appropriate is True, test.message
    assert test.chosen is test.periodic and test.chosen.model == "periodic"
    assert "the model's misfit, not a walk off its cycle" in test.message
    assert json.loads(json.dumps(test.to_json()))["step_dependence"]["F"] == test.step_dependence["F"]


def test_periodicity_test_refuses_bad_requests(toy):
    table, _ = _released(toy, 3, 0.001, 0)
    with pytest.raises(FitError, match="alpha"):
        periodicity_test(table, toy, ["foot_radius"], alpha=1.5)
    with pytest.raises(FitError, match="model must be"):
        fit(table, toy, ["foot_radius"], model="chaotic")


class _IpoptStops:
    """A BVP whose solver stops at once, as IPOPT did (a restoration failure in one iteration) on
    the README's walk for a transient's start held; everything else is the BVP's."""

    def __init__(self, prob):
        self._prob = prob

    def __getattr__(self, name):
        return getattr(self._prob, name)

    @property
    def solver(self):
        def solve(**kwargs):
            return {"x": kwargs["x0"]}

        solve.stats = lambda: {"success": False, "return_status": "Restoration_Failed"}
        return solve


def test_the_jacobian_check_re_solves_by_newton_where_ipopt_stops(toy, monkeypatch):
    """The AD Jacobian of a transient fit against central differences re-solved with the start
    held: where IPOPT's re-solve stops (the README's walk: `toywalk fit` of clearing-toy filmed
    at 120 frames/s, by default, warned that the check could not be made), Newton on the BVP's
    equalities re-solves it, and the check agrees with the one IPOPT's re-solves give (both
    measured 2e-9 to 3e-8 relative, against 1e-6)."""
    import toywalk.sysid.problem as fit_problem

    truth = toy.replace(**{"effects.impact_trailing_share": 0.1})
    table, _ = _released(truth, 6, 0.002, 1)  # 6 steps: the check is as good, the fits quicker
    by_ipopt = fit(table, truth, RECOVERED, model="transient")
    result = fit_problem.FitProblem.result

    def without_ipopt(self, *args, **kwargs):
        self.prob = _IpoptStops(self.prob)
        return result(self, *args, **kwargs)

    monkeypatch.setattr(fit_problem.FitProblem, "result", without_ipopt)
    by_newton = fit(table, truth, RECOVERED, model="transient")
    assert set(by_newton.jacobian_check) == set(RECOVERED) and not by_newton.warnings
    assert max(by_newton.jacobian_check.values()) < 1e-6, by_newton.jacobian_check
    for name in RECOVERED:  # the same residuals re-solved two ways: the same differences
        assert abs(by_newton.jacobian_check[name] - by_ipopt.jacobian_check[name]) < 1e-7, (
            name, by_newton.jacobian_check, by_ipopt.jacobian_check)


def _transient_problem(params, steps):
    """The transient fit's NLP of a released walk of ``steps`` steps, on the model's strikes, at
    its start (a time offset of 2 ms, so that the clock's path through the offset is seen)."""
    from toywalk.sysid.problem import setup

    table, _ = _released(params, steps, 0.002, 1)
    problem, w0 = setup(table, params, ["foot_radius"], model="transient", offsets=True,
                         n_intervals=None, degree=None, z_guess=None, max_iter=500,
                         check_jacobian=False, priors={}, strikes="model")
    x = problem.start(w0)
    x[-1] = 0.002 / problem.t_scale
    return problem, problem.clocked(x)


def test_a_transient_fits_clock_keeps_its_hessian_sparse_and_its_derivatives_exact(toy):
    """A transient fit reads every sample between the model's heel strikes, which are the time
    offset plus every step duration before them. Held as unknowns of their own (the clock, tied
    to the durations by equalities), they keep the misfit's Hessian growing with the walk's
    length, not with its square (without them the 60-step walk of benchmarks/diagnose_speed.py
    built its solver for more than nine minutes). Checked: the Hessian's size against the
    steps; the clock where its equalities put it; the model's angles read through the clock
    against the same reading through the durations in NumPy; the time offset's column of the
    fit's Jacobian (the clock's path) against central differences."""
    import casadi as ca
    from toywalk.sysid.measurement import Timing

    sizes = {}
    for steps in (4, 12):
        problem, x = _transient_problem(toy, steps)
        nlp = problem._nlp[0]
        sizes[steps] = ca.hessian(nlp["f"], nlp["x"])[0].nnz()
    # Linear: three times the steps, three times the non-zeros (measured 3.00); through the
    # durations the duration-by-state blocks grow with the square (measured 4.41 without the
    # clock).
    assert sizes[12] / sizes[4] < 3.3, sizes
    problem, x = _transient_problem(toy, 8)
    tm: Timing = problem.tm
    g = np.array(problem.nlp_fn(x, np.r_[np.ones(problem.n_obs + 2 * problem.path.n), 1.0])[1]).ravel()
    n_k = len(problem.clock_cols)
    assert n_k == 9
    assert_allclose(g[-n_k:], 0.0, atol=1e-14)  # the clock's equalities hold at the clocked start
    # The angles through the clock (CasADi) against the durations' own reading (NumPy).
    w, durations, offset = x[:problem.n_w], problem.durations(x), x[-1] * problem.t_scale
    by_numpy = tm.values(w, durations, offset) + problem.b_op @ problem.offsets_of(x)
    assert_allclose(np.array(problem.angles_fn(x, 1.0)).ravel(), by_numpy, rtol=0, atol=1e-13)
    # The check can fail: a clock a millisecond off moves the angles.
    moved = x.copy()
    moved[problem.clock_cols[3]] += 1e-3
    assert np.abs(np.array(problem.angles_fn(moved, 1.0)).ravel() - by_numpy).max() > 1e-4
    # d(residuals)/d(time offset) through the clock: central differences, the clock re-set.
    sigma = np.full(problem.n_obs, 0.002)
    jac = problem.jacobian(x, sigma)
    h = 1e-6
    cols = []
    for sign in (1.0, -1.0):
        xs = x.copy()
        xs[-1] += sign * h / problem.t_scale
        cols.append(problem.whitened(problem.clocked(xs), sigma))
    fd = (cols[0] - cols[1]) / (2 * h)
    # central differences of a smooth function at h = 1 us: truncation and round-off 1e-6 relative
    assert np.linalg.norm(jac[:, -1] - fd) < 1e-6 * np.linalg.norm(fd)


def test_the_checks_re_solve_lands_on_the_root_and_keeps_ipopts_where_newton_fails(toy, monkeypatch):
    """The Jacobian check re-solves the BVP at a perturbed parameter: IPOPT, then Newton steps on
    the equalities past its tolerance (IPOPT's unknowns stand off the root along ill-conditioned
    directions; a central difference divides that by its step). Where those Newton steps go
    wrong, IPOPT's solution, within the tolerance, stands rather than none."""
    import toywalk.sysid.problem as fitting

    problem, x = _transient_problem(toy, 6)
    problem.jacobian(x, np.full(problem.n_obs, 0.002))  # sets the free start the re-solve holds
    theta = problem.theta(x) * (1 + 1e-5)
    polished = problem._resolve(x, theta)
    p = problem.p_full(theta)
    g = np.array(problem.prob.constraints(polished, p)).ravel()[:problem.prob.n_equalities]
    assert np.abs(g).max() <= fitting._NEWTON_TOL
    # Newton steps a million times too long: non-finite or far off, never within the tolerance
    real = fitting._equality_jacobians(problem.prob)
    monkeypatch.setattr(fitting, "_equality_jacobians",
                        lambda prob: lambda w, p: [m * 1e-6 for m in real(w, p)])
    kept = problem._resolve(x, theta)
    assert kept is not None  # before: None, the check not made
    g = np.array(problem.prob.constraints(kept, p)).ravel()[:problem.prob.n_equalities]
    assert np.abs(g).max() <= fitting._NEWTON_TOL
    # IPOPT's solution and the polished one: the same root to the BVP's conditioning
    assert np.abs(kept - polished).max() < 1e-6
