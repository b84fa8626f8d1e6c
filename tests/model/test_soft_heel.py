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


def test_soft_heel_refuses_other_effects_and_collocation(clearing):
    """The phase models the seed's walker; the collocation transcription the rigid strike."""
    params, gait = clearing
    with pytest.raises(ValueError, match="hip_damping"):
        Walker(params.replace(**{SOFT: 1e-3, "effects.hip_damping": 1e-4}))
    with pytest.raises(ValueError, match="soft_heel"):
        solve_collocation(params.replace(**{SOFT: 1e-3}), gait.fixed_point)


@pytest.mark.parametrize("name", ["seed-pointfoot", "stable-toy", "clearing-toy"])
def test_null_is_the_rigid_model_bit_for_bit(name):
    """Point (seed-pointfoot), torus (stable-toy, clearing-toy) feet: with soft_heel = 0 named in
    the file the gait, its eigenvalues and a 30-step walk from a perturbed start are the rigid
    model's bit for bit (the same code path; the rigid model itself is checked against the
    seed's equations in tests/model/test_effects.py). A contact time of 1e-7 s changes them: the
    comparison can fail."""
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

