"""The compliant heel strike (model/compliant.py, docs/soft_feet.md): its limit as the contact
stiffens, its energy balance, its AD Jacobian, and its projection against the rigid collision."""

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.compliant import SoftContact, compliant_strike, phase_functions
from toywalk.model.equations import build_functions
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker

from ..conftest import DATA

# The contact time constants of the convergence check (s): MuJoCo's defaults of this project are
# 1 ms (model/mujoco_check.py); each halving should halve the distance to the limit.
TAUS = (4e-3, 2e-3, 1e-3, 5e-4)


def _planar_compass():
    """compass-3d.toml made a planar point-foot walker: no lateral offset, no hip width, point feet
    (distributed leg mass, unlike the simplest walker's massless legs)."""
    params = dataclasses.replace(load_params(DATA / "params" / "compass-3d.toml"),
                                 com_offset=(0.0, 0.0, -0.3), hip_width=0.0, foot_radius=0.0,
                                 foot_lateral_radius=0.0)
    return params, True


def _clearing_toy():
    """The 3D toy-sized walker with torus feet and a stable gait that clears the ramp."""
    return load_params(DATA / "params" / "clearing-toy.toml"), False


@pytest.fixture(scope="module", params=["planar-compass", "clearing-toy"])
def strike_case(request):
    """(params, planar, x_minus): a walker at its gait's heel strike (internal state)."""
    params, planar = _planar_compass() if request.param == "planar-compass" else _clearing_toy()
    gait = find_gait(params, planar=planar)
    walker = Walker(params, planar=planar)
    return params, planar, walker.full_state(walker.step(gait.fixed_point).z_minus)


def _rigid(params, planar, x):
    return build_functions(planar)["collision"](x, params.input_vector(1.0)).full().ravel()


def test_converges_to_the_seed_law_at_first_order(strike_case):
    params, planar, x = strike_case
    n_dyn = 4 if planar else 8
    rigid = _rigid(params, planar, x)
    errors, shares = [], []
    for tau in TAUS:
        out = compliant_strike(params, x, SoftContact(tau), planar=planar)
        errors.append(np.abs(out.x_plus - rigid)[:n_dyn].max())
        shares.append(out.impulses[0] / out.impulses.sum())
        assert out.trailing_left
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # Measured orders 0.98-1.00 on both walkers (docs/soft_feet.md): the distance is O(tau), the
    # phase's length; a limit other than the seed's law (a trailing-foot impulse that does not
    # vanish) would make the distance level off and the order fall towards 0.
    assert np.all(orders > 0.9) and np.all(orders < 1.1), (errors, orders)
    # The trailing foot's share of the normal impulse vanishes with tau (measured 2e-4 at 0.5 ms on
    # both, falling as tau): its preload's impulse is O(tau); 1e-3 leaves room, and any finite
    # limiting share (impact_trailing_share's typical 0.1) is far above it.
    assert shares[-1] < 1e-3 and shares[-1] < shares[0]


def test_energy_balance_through_the_phase(strike_case):
    params, planar, x = strike_case
    coarse = compliant_strike(params, x, SoftContact(1e-3), planar=planar)
    fine = compliant_strike(params, x, SoftContact(1e-3), planar=planar, steps_per_tau=40)
    e = coarse.energy
    # The free walker's energy change equals the contact forces' integrated work up to RK4's error:
    # measured 1e-4 of the change at 20 steps per tau, 16 times less at 40 (fourth order; the
    # lift-off kinks do not show). 1e-3 of the change, and at least a factor 8 on refinement.
    assert abs(e["balance"]) < 1e-3 * abs(e["mechanical"])
    assert abs(fine.energy["balance"]) < abs(e["balance"]) / 8
    # Dissipative parts: the normal damping, the tangential work and the projection take energy.
    assert e["damping"] > 0 and e["tangential"] > 0 and e["projection"] >= 0
    assert e["mechanical"] < 0


def test_ad_jacobian_matches_central_differences(strike_case):
    params, planar, x = strike_case
    fns = phase_functions(planar)
    p, c = params.input_vector(1.0), SoftContact(1e-3).vector()
    jac = fns["strike"].factory("strike_jacobian", ["x", "p", "c"], ["jac:x_plus:x"])(x, p, c).full()
    h = 1e-6
    fd = np.zeros_like(jac)
    for i in range(len(x)):
        dx = np.zeros(len(x))
        dx[i] = h
        ahead, behind = (fns["strike"](x + s * dx, p, c)[0].full().ravel() for s in (1, -1))
        fd[:, i] = (ahead - behind) / (2 * h)
    # Central differences with h = 1e-6: truncation O(h^2) times third derivatives, large here (the
    # stiff contact), and round-off 1e-16 / h times the entries; measured agreement 1.4e-6 (planar
    # compass) and 9e-7 (clearing toy) of the largest entry, so 1e-5. The map is piecewise smooth
    # (contact switches on the fixed grid): a difference straddling a switch would show as an O(1)
    # mismatch, far above the tolerance.
    assert_allclose(jac, fd, rtol=0, atol=1e-5 * np.abs(jac).max())


def test_projection_alone_is_the_rigid_collision(strike_case):
    params, planar, x = strike_case
    fns = phase_functions(planar)
    p = params.input_vector(1.0)
    y0, _ = fns["start"](x, p, SoftContact(1e-3).vector())
    x_plus, d_kinetic = (a.full().ravel() for a in fns["project"](y0, p))
    # No phase: the free walker at touchdown (rolling velocities, lowered by the preload, which
    # moves no velocity) hit by the one impulse at D that stops D. That is the seed's law written
    # another way (an impulse projection of the free walker, not the momentum balances of
    # model/equations.py): equal to round-off, 1e-12 of the rates (about 1-10 rad/s).
    assert_allclose(x_plus, _rigid(params, planar, x), rtol=0, atol=1e-12 * np.abs(x).max())
    d_rigid = build_functions(planar)["impact"](x, p)[0].full()[0, 0]
    assert_allclose(d_kinetic[0], d_rigid, rtol=1e-10)


def test_refuses_effects_and_bad_states():
    params, planar = _planar_compass()
    x = np.zeros(5)
    with pytest.raises(ValueError, match="hip_damping"):
        compliant_strike(dataclasses.replace(params, effects={"hip_damping": 0.01}), x, SoftContact(1e-3),
                         planar=planar)
    with pytest.raises(ValueError, match="shape"):
        compliant_strike(params, np.zeros(4), SoftContact(1e-3), planar=planar)
    with pytest.raises(ValueError, match="tau"):
        SoftContact(0.0)
