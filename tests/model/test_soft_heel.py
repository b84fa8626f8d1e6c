"""The compliant heel strike in the step map (the ``soft_heel`` effect, model/effects/soft.py,
docs/soft_feet.md section 5): the rigid path at null, the step map's AD Jacobian, a gait of the
clearing toy on soft feet, and the energy balance of one step."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model import StepFailure, Walker, find_gait, simulate
from toywalk.model.collocation import solve_collocation
from toywalk.model.compliant import SPAN, SoftContact, compliant_strike
from toywalk.model.effects import EFFECTS, LIBRARY
from toywalk.model.effects.soft import FRICTION, ZETA
from toywalk.model.parameters import PARAMETER_NAMES, load_params

from ..conftest import DATA

SOFT = "effects.soft_heel"


def _load(name):
    return load_params(DATA / "params" / f"{name}.toml")


@pytest.fixture(scope="module")
def clearing():
    """The clearing toy (torus feet, 3D) and its rigid gait."""
    params = _load("clearing-toy")
    return params, find_gait(params)


def test_soft_heel_is_registered_last_and_not_screened():
    """Appended to the registry (the other effects' parameter indices stay put) and left out of
    the causes that diagnose tries by default."""
    assert PARAMETER_NAMES[-1] == SOFT and list(EFFECTS)[-1] == "soft_heel"
    effect = EFFECTS["soft_heel"]
    assert not effect.screened and not effect.port_only and "soft_heel" not in LIBRARY
    assert effect.null == 0.0 and effect.unit == "s" and effect.bounds == (0.0, 0.01)
    assert all(EFFECTS[name].screened for name in LIBRARY)


def test_soft_heel_refuses_other_effects(clearing):
    """The phase models the seed's walker."""
    params, _ = clearing
    with pytest.raises(ValueError, match="hip_damping"):
        Walker(params.replace(**{SOFT: 1e-3, "effects.hip_damping": 1e-4}))


def test_collocation_gait_on_soft_feet_is_the_step_maps(clearing):
    """The collocation transcription with the compliant strike (collocation.bvp(soft=True)) and
    the shooting step map find the same gait of the clearing toy at 0.5 and 2 ms: two independent
    ways to the fixed point (Newton on the simulated step against IPOPT on the collocation
    equations, the strike's phase a step's first 10 tau in one and appended after the guard in
    the other) that share only the strike's kernel. Measured: fixed points 8e-12 and 7e-12
    apart, step times 5e-13 s, eigenvalue moduli 3e-11; 1e-9 is the collocation mesh's own
    error on the rigid gait (tests/model/test_collocation.py)."""
    params, gait = clearing
    for tau in (0.5e-3, 2e-3):
        soft = params.replace(**{SOFT: tau})
        shot = find_gait(soft, z_guess=gait.fixed_point)
        coll = solve_collocation(soft, gait.fixed_point)
        assert coll.success, coll.status
        assert_allclose(coll.fixed_point, shot.fixed_point, atol=1e-9)
        assert coll.step_time == pytest.approx(shot.step_time, abs=1e-9)
        assert_allclose(np.abs(coll.eigenvalues), np.abs(shot.eigenvalues), atol=1e-8)
        # the strike's phase is in the step, and the trajectory's flow starts after it
        assert coll.times[0] == pytest.approx(SPAN * tau)


def test_collocation_strike_is_the_rigid_one_at_null_with_the_one_sided_slope(clearing):
    """Below TAU_LINEAR the transcription's strike is the secant from the rigid strike to the
    phase (model/compliant.collocation_strike): at tau = 0 it is the rigid collision, at
    TAU_LINEAR the step map's phase, and its AD derivative in tau at 0 is the phase's one-sided
    derivative at 0+, estimated here by Richardson extrapolation of the step map's strike at 2e-5
    and 4e-5 s (error O(h^2)). Measured: 2e-4 relative apart, the secant's own O(TAU_LINEAR)
    error (docs/soft_feet.md section 5); 1e-3 allows for it, and a slope taken at 1 ms (856.8
    against 870.9 in the largest component) fails."""
    import casadi as ca
    from toywalk.model.collocation import soft_link
    from toywalk.model.compliant import TAU_LINEAR
    from toywalk.model.parameters import INPUT_NAMES

    params, gait = clearing
    rigid = Walker(params)
    x = np.r_[rigid.to_internal(rigid.step(gait.fixed_point).z_minus), 0.0, 0.0]  # no travel yet
    k = INPUT_NAMES.index(SOFT)
    link = soft_link(False)

    def p_at(tau):
        p = params.input_vector(1.0).copy()
        p[k] = tau
        return p

    def strike(tau):  # the step map's strike (its compiled kernel)
        kernel = Walker(params.replace(**{SOFT: tau})).soft_kernels["soft_strike"]
        return np.array(kernel(x, p_at(tau))[0]).ravel()

    hard = np.array(rigid.eng.k["collision"](x, p_at(0.0))[0]).ravel()
    assert_allclose(np.array(link(x, p_at(0.0))).ravel(), hard, rtol=0, atol=1e-15)
    assert_allclose(np.array(link(x, p_at(TAU_LINEAR))).ravel(), strike(TAU_LINEAR), rtol=0, atol=1e-14)
    xs, ps = ca.MX.sym("x", len(x)), ca.MX.sym("p", len(INPUT_NAMES))
    slope = np.array(ca.Function("d", [xs, ps], [ca.jacobian(link(xs, ps), ps)[:, k]])(x, p_at(0.0))).ravel()
    h = 2e-5
    one_sided = 2 * (strike(h) - hard) / h - (strike(2 * h) - hard) / (2 * h)
    assert np.abs(one_sided).max() > 100.0  # the strike moves at O(1) per ms: a real slope
    assert_allclose(slope, one_sided, rtol=0, atol=1e-3 * np.abs(one_sided).max())


@pytest.mark.parametrize("name", ["seed-pointfoot", "compass-3d", "stable-toy", "clearing-toy"])
def test_null_is_the_rigid_model_bit_for_bit(name):
    """Point (seed-pointfoot), sphere (compass-3d), torus (stable-toy, clearing-toy) feet: with
    soft_heel = 0 named in the file the gait, its eigenvalues and a 30-step walk from a
    perturbed start are the rigid model's bit for bit (the same code path; the rigid model
    itself is checked against the seed's equations in tests/model/test_effects.py). A contact
    time of 1e-7 s changes them: the comparison can fail."""
    rigid = _load(name)
    null = rigid.replace(**{SOFT: 0.0})
    assert null.effects["soft_heel"] == 0.0 and "soft_heel" not in rigid.effects
    gait_r, gait_n = find_gait(rigid), find_gait(null)
    assert np.array_equal(gait_r.fixed_point, gait_n.fixed_point)
    assert gait_r.step_time == gait_n.step_time
    assert np.array_equal(gait_r.eigenvalues, gait_n.eigenvalues)
    z0 = gait_r.fixed_point + 1e-6
    walk_r, walk_n = simulate(rigid, z0, 30), simulate(null, z0, 30)
    assert walk_r.status == walk_n.status
    assert np.array_equal(walk_r.times, walk_n.times) and np.array_equal(walk_r.states, walk_n.states)
    assert np.array_equal(walk_r.collision_losses, walk_n.collision_losses)
    soft = Walker(rigid.replace(**{SOFT: 1e-7}), planar=gait_r.planar)
    if name == "seed-pointfoot":
        # The seed's point foot has an effective mass fore-aft 465 times below the normal one, so
        # the isotropic tangential contact is too stiff for 20 RK4 steps per tau: the phase's
        # state goes non-finite, and the step says so (docs/soft_feet.md section 5).
        with pytest.raises(StepFailure, match="non-finite"):
            soft.step(gait_r.fixed_point)
        return
    # 1e-7 s: the strike's state moves by O(tau) (docs/soft_feet.md section 2: about 900 tau rad/s
    # on the clearing toy), far above round-off.
    assert np.abs(soft.step(gait_r.fixed_point).z_plus - gait_r.fixed_point).max() > 1e-8


def _fd_jacobians(params, z0, names, h_state=1e-6, h_rel=1e-4):
    """Central differences of the step map (z_plus and the step time) in the state and in the
    named parameters (steps relative to each parameter's size)."""
    def step(p, z):
        out = Walker(p).step(z)
        return np.append(out.z_plus, out.step_time)

    cols = []
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = h_state
        cols.append((step(params, z0 + dz) - step(params, z0 - dz)) / (2 * h_state))
    pcols = []
    for name in names:
        value = params.get(name)
        # relative to the value; a parameter at 0 (products of inertia) steps by a size of its kind
        h = h_rel * (abs(value) if value != 0.0 else 1e-4)
        pcols.append((step(params.replace(**{name: value + h}), z0)
                      - step(params.replace(**{name: value - h}), z0)) / (2 * h))
    return np.array(cols).T, np.array(pcols).T


def test_step_map_jacobian_against_finite_differences(clearing):
    """tau = 1 ms, at the rigid gait's start: the step map's AD Jacobian in the state and in every
    parameter the soft walker admits (the walker's own and tau itself; the other effects are
    refused with it), z_plus and the step time, against central differences.

    Tolerance 1e-6 of each column's largest entry. Steps: 1e-6 rad (rad/s) in the state, 1e-4
    of each parameter's size (truncation, h^2 times the third derivative, about 1e-8 relative).
    Smaller parameter steps meet the step map's own noise (the guard's Newton tolerance and the
    phase's round-off, about 1e-12): at 1e-6 and 1e-7 relative the difference for the foot's
    lateral radius is off by 1.2e-5 and 1.2e-4 of the column, growing as 1 / h, against 6e-8 at
    1e-4 (measured 2026-11-28)."""
    params, gait = clearing
    soft = params.replace(**{SOFT: 1e-3})
    z0 = gait.fixed_point
    out = Walker(soft).step(z0, params_jacobian=True)
    names = [n for n in PARAMETER_NAMES if not n.startswith("effects.")] + [SOFT]
    cols = [PARAMETER_NAMES.index(n) for n in names]
    fd_x, fd_p = _fd_jacobians(soft, z0, names)
    ad_x = np.vstack([out.jacobian, out.time_gradient])
    ad_p = np.vstack([out.jacobian_params, out.time_gradient_params])[:, cols]
    assert_allclose(ad_x, fd_x, atol=1e-6 * np.abs(fd_x).max())
    for j, name in enumerate(names):
        assert_allclose(ad_p[:, j], fd_p[:, j], atol=1e-6 * np.abs(fd_p[:, j]).max() + 1e-12,
                        err_msg=name)
    # d T / d tau holds the phase's own length, SPAN, besides the flow's change.
    assert abs(out.time_gradient_params[PARAMETER_NAMES.index(SOFT)]) > 0


def test_clearing_toy_walks_on_soft_feet(clearing):
    """A gait of the clearing toy with tau = 0.5 ms, by Newton from the rigid gait: a fixed point
    to 1e-10, stable, whose step holds the phase's 10 tau. The step is not longer than the rigid
    one by the phase, though: the strike hands over a walker already 10 tau further on, and the
    flow after it is shorter by more than that (measured -0.72 ms against the rigid 183.97 ms,
    docs/soft_feet.md section 5): checked as |dT| < 2 SPAN tau."""
    params, gait = clearing
    tau = 5e-4
    soft = find_gait(params.replace(**{SOFT: tau}), gait.fixed_point)
    walker = Walker(soft.params)
    step = walker.step(soft.fixed_point, record=True)
    assert np.abs(step.z_plus - soft.fixed_point).max() < 1e-10
    assert soft.stable and soft.max_abs_eigenvalue < 0.95
    # The step is the flow to the strike (its recorded samples end there) and the phase.
    assert step.step_time - step.times[-1] == pytest.approx(SPAN * tau, rel=1e-12)
    assert abs(soft.step_time - gait.step_time) < 2 * SPAN * tau
    # The gait moved: the phase changes the strike by O(tau), not round-off.
    assert np.abs(soft.fixed_point - gait.fixed_point).max() > 1e-3


def test_energy_balance_of_a_step_with_the_phase(clearing):
    """One step with tau = 1 ms: the rolling model's energy (kinetic and gravitational, with the
    contact travel) falls over the step by what the phase loses, computed independently from the
    phase's own work integrals (toywalk.model.compliant.compliant_strike): the contact forces'
    work, the final projection's loss, and the hand-overs' heights (the walker starts lowered by
    the trailing foot's preload and ends with the landing foot pressed in by delta, which the
    rolling model puts back on the ramp: M g cos(alpha) (delta_end - delta_0)). No continuous
    effect is on, so the flow dissipates nothing.

    Tolerance: the phase's energy balance at 20 RK4 steps per tau, 1.2e-3 of the phase's
    mechanical change at 0.5 ms (model/effects/soft.py, FRICTION), taken as 3e-3 of the loss; the
    flow's RK8 conserves energy to about 1e-12 J."""
    params, gait = clearing
    tau = 1e-3
    soft = params.replace(**{SOFT: tau})
    walker = Walker(soft)
    z0 = gait.fixed_point
    step = walker.step(z0, record=True)
    x0 = walker.full_state(z0)
    x_minus = step.states[-1]  # the internal state at the heel strike, with its contact travel
    e_before = walker.energy(x0)
    # After the step: the mirrored state at the new contact point (mirroring keeps the energy of
    # this mirror-symmetric walker; the ramp has no sideways tilt).
    x_plus = walker.full_state(step.z_plus, step.contact)
    e_after = walker.energy(x_plus, side=-1)
    assert walker.energy(x_minus) == pytest.approx(e_before, abs=1e-11)  # the flow: no dissipation
    strike = compliant_strike(params, x_minus, SoftContact(tau, ZETA, FRICTION))
    penetration = strike.penetrations
    weight = params.total_mass * params.gravity * np.cos(params.slope)
    lost = (-strike.energy["normal_work"] - strike.energy["tangential_work"]
            + strike.energy["projection"] - weight * (penetration[-1, 1] - penetration[0, 0]))
    assert lost > 0
    assert e_after - e_before == pytest.approx(-lost, rel=3e-3)
    assert step.collision_loss == pytest.approx(lost, rel=3e-3)
    # The comparison can fail: without the tangential forces' work (a fifth of the loss) it does.
    tangential = -strike.energy["tangential_work"]
    assert tangential > 0.1 * lost
    assert abs(e_after - e_before + lost - tangential) > 3e-3 * lost



def test_strike_resolution_finds_the_integration_error_where_there_is_one():
    """robust-toy at tau = 4 ms: the default 20 RK4 steps per tau puts the largest eigenvalue
    0.027 below its value at 80 (0.9497 against 0.9767; 0.9776 at 160, docs/soft_feet.md section
    5), which the check flags; solved at 80, the same check (against 320) passes. On rigid feet it
    refuses. A check that always passed, or compared a resolution with itself, fails here."""
    from toywalk.model import solve_fixed_point, strike_resolution

    params = load_params(DATA / "params" / "robust-toy.toml").replace(**{SOFT: 4e-3})
    coarse = find_gait(params)
    check = strike_resolution(coarse)
    assert (check.steps_per_tau, check.fine_steps_per_tau) == (20, 80)
    assert check.max_abs_eigenvalue == coarse.max_abs_eigenvalue
    assert 0.02 < check.eigenvalue_error < 0.04 and not check.resolved
    fine = solve_fixed_point(Walker(params, soft_steps_per_tau=80), coarse.fixed_point)
    assert fine.max_abs_eigenvalue == pytest.approx(check.fine_max_abs_eigenvalue, abs=1e-9)
    again = strike_resolution(fine, steps_per_tau=80)
    assert again.fine_steps_per_tau == 320 and again.resolved and again.eigenvalue_error < 2e-3
    with pytest.raises(ValueError, match="soft feet"):
        strike_resolution(find_gait(params.replace(**{SOFT: 0.0})))
