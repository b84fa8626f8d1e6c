"""Tests of the standing check (toywalk.model.statics).

Independent checks used here: the classical rocking-body criterion and its exponents (a rigid body
on a convex foot, Routh 1905), the inverted pendulum, the two-wheeled cart, sideways rocking on two
torus feet, the gravitational potential of :mod:`toywalk.model.equations` differentiated on its own
(second variation along the constraint manifold, by finite differences), and the model's own
equations of motion (at rest, and the nonlinear flow away from an unstable equilibrium).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from toywalk.model.equations import build_functions, symbolic
from toywalk.model.parameters import Params, load_params
from toywalk.model.statics import KINDS, can_stand, static_margin

from ..conftest import DATA

# Equilibria are solved to round-off and the linearisation is exact (algorithmic derivatives), so
# analytic comparisons are at 1e-9 relative: far above round-off (1e-14), far below any modelling
# difference that would matter.
RTOL = 1e-9


def _rocker(rho: float, **changes) -> Params:
    """w = 0, no fore-aft offset, level ground, no axle mass: legs whose mass sits 20 mm above the
    ramp, below the foot's fore-aft centre (r = 50 mm), so splaying the legs only raises it.
    Upright centre-of-mass height h = l + d_z = 0.02 m."""
    params = Params(
        leg_length=0.15,
        foot_radius=0.05,
        foot_lateral_radius=rho,
        hip_width=0.0,
        leg_mass=0.05,
        axle_mass=0.0,
        com_offset=(0.0, 0.1, -0.13),
        inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0),
        slope=0.0,
        gravity=9.81,
    )
    return params.replace(**changes) if changes else params


def _com_height(p: Params) -> float:
    return p.leg_length + 2 * p.leg_mass * p.com_offset[2] / p.total_mass


def _rigid_exponents(p: Params) -> tuple[float, float]:
    """s^2 of lean and pitch of the whole walker as one rigid body rocking on its torus foot (legs
    parallel, d_x = 0, no products of inertia): M g (h - radius) / (inertia about the contact)."""
    m, mh, l = p.leg_mass, p.axle_mass, p.leg_length
    _, d_y, d_z = p.com_offset
    weight = p.total_mass * p.gravity
    h = _com_height(p)
    i_lean = 2 * (p.inertia[0] + m * (d_y**2 + (l + d_z) ** 2)) + mh * l**2
    i_pitch = 2 * (p.inertia[1] + m * (l + d_z) ** 2) + mh * l**2
    return weight * (h - p.foot_lateral_radius) / i_lean, weight * (h - p.foot_radius) / i_pitch


@pytest.fixture(scope="module")
def toy_report():
    # The same walker as the conftest fixture (module scope: one evaluation for several tests).
    params = Params(
        leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.0,
        leg_mass=0.05, axle_mass=0.02, com_offset=(-0.005, 0.1, -0.11),
        inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0), slope=math.radians(4.5), gravity=9.81,
    )
    return params, can_stand(params)


# --------------------------------------------------------------------------------------------------
def test_low_heavy_walker_stands():
    params = _rocker(rho=0.04)  # centre of mass 20 mm below the lateral centre of curvature
    assert static_margin(params) == pytest.approx(0.02 - 0.04, abs=1e-15)
    report = can_stand(params)
    assert report.can_stand and report.can_stand_level
    assert report.reason.startswith("It can stand on level ground")
    parallel = report.configuration("two feet, parallel legs")
    assert parallel.stable and parallel.status == "stable"
    assert parallel.margin == pytest.approx(-0.02, abs=1e-12)
    assert len(report.configurations) == 3  # level ground only: nothing to repeat


def test_toy_cannot_stand_and_says_why(toy_params, toy_report):
    params, report = toy_report
    assert params == toy_params
    assert static_margin(params) > 0.05  # 53 mm above rho: statically unstable sideways
    assert not report.can_stand and not report.can_stand_level
    for conf in report.configurations:
        assert not conf.stable
        assert conf.status in ("unstable", "infeasible", "no equilibrium")
    # At least one configuration of each kind is a real (feasible) equilibrium that falls.
    assert {c.kind for c in report.configurations if c.status == "unstable"} == set(KINDS)
    assert report.reason.startswith("It cannot stand on the 4.5 degree ramp")
    assert "above the feet's lateral centre of curvature (rho = 5 mm)" in report.reason
    assert "falls" in report.reason and "e-folding time" in report.reason
    # Ramp first, then level ground, one result per kind each.
    assert [(c.kind, c.level) for c in report.configurations] == [
        *((k, False) for k in KINDS), *((k, True) for k in KINDS)
    ]
    assert report.configuration("one foot", level=True).slope == 0.0
    assert report.configuration("one foot").slope == params.slope


@pytest.mark.parametrize("rho", [0.01, 0.04])
def test_rigid_rocker_exponents_match_the_classical_result(rho):
    # w = 0 and parallel legs: both feet at one point, the hinge locked by the contact: one rigid
    # body rocking on a torus foot. Lean s^2 = M g (h - rho) / I_x, pitch M g (h - r) / I_y, and
    # the heading is neutral (0).
    params = _rocker(rho)
    conf = can_stand(params).configuration("two feet, parallel legs")
    lean, pitch = _rigid_exponents(params)
    got = sorted(conf.exponents_squared, key=lambda z: z.real)
    assert all(abs(z.imag) == 0 for z in got)
    want = sorted([lean, pitch, 0.0])
    np.testing.assert_allclose([z.real for z in got], want, rtol=RTOL, atol=RTOL * abs(pitch))
    assert conf.stable == (rho > _com_height(params))
    if not conf.stable:
        assert conf.mode == "sideways (lean)"
        assert conf.growth_rate == pytest.approx(math.sqrt(lean), rel=RTOL)


@pytest.mark.parametrize("delta", [1e-4, -1e-4])
def test_verdict_flips_where_the_centre_of_mass_crosses_rho(delta):
    # Boundary: centre of mass exactly at the lateral centre of curvature (h = rho = 20 mm). A
    # margin of 0.1 mm (0.5 % of rho) changes the lean stiffness by M g delta = 1.2e-4 N m, 1e5
    # times the solver's neutral threshold (1e-8 M g l). Splaying raises this walker's centre of
    # mass (its mass is below the foot centres), so no configuration does better than parallel legs.
    params = _rocker(rho=0.02 - delta)
    assert static_margin(params) == pytest.approx(delta, abs=1e-15)
    report = can_stand(params)
    assert report.can_stand == (delta < 0)
    if delta > 0:
        assert "above the feet's lateral centre of curvature" in report.reason
        assert "sideways (lean)" in report.reason
    else:
        assert "below the feet's lateral centre of curvature" in report.reason


def test_hip_width_gives_a_two_foot_base(toy_params):
    # Centre of mass 45 mm above rho but between feet 200 mm apart and below the fore-aft centre
    # of curvature (r = 60 mm): standing on both feet with parallel legs is stable, like a
    # two-wheeled cart; on one foot it falls sideways.
    params = toy_params.replace(
        hip_width=0.2, foot_radius=0.06, com_offset=(0.0, 0.05, -0.12)
    )
    assert static_margin(params) == pytest.approx(0.045, abs=1e-12)
    report = can_stand(params)
    assert report.can_stand and report.can_stand_level
    assert report.reason.startswith("It can stand on the 4.5 degree ramp on two feet, parallel")
    assert "200 mm wide two-foot base" in report.reason
    for level in (False, True):
        assert report.configuration("two feet, parallel legs", level=level).stable
        assert not report.configuration("one foot", level=level).stable
    # On level ground the legs' common pitch is the cart's: s^2 = -M g (r - h) / I_pitch, h = 50 mm.
    conf = report.configuration("two feet, parallel legs", level=True)
    _, pitch = _rigid_exponents(params)
    assert pitch < 0
    assert min(abs(z - pitch) for z in conf.exponents_squared) <= RTOL * abs(pitch)


def test_splayed_round_feet_rock_sideways_like_a_cylinder():
    # w = 0, legs splayed symmetrically, d_x = 0: the only motion that keeps both feet rolling
    # without slip is leaning about the line through the two contacts, on two torus tubes of
    # radius rho: the centre-of-mass height is rho + (h - rho) cos(psi) exactly, so
    # s^2 = M g (h - rho) / I_x, with I_x about that line at the splayed configuration.
    for rho in (0.01, 0.045):  # centre of mass (32 mm at this splay) above, then below, rho
        params = _rocker(rho, axle_mass=0.01, **{"inertia[2]": 2.5e-4})
        conf = can_stand(params).configuration("two feet, splayed legs")
        eq = conf.equilibrium
        theta = eq["theta_st"]
        assert eq["theta_sw"] == pytest.approx(-theta, abs=1e-9) and abs(eq["psi"]) < 1e-9
        l, r, m, mh = params.leg_length, params.foot_radius, params.leg_mass, params.axle_mass
        _, d_y, d_z = params.com_offset
        z_leg = r + (l - r + d_z) * math.cos(theta)  # each leg's centre of mass over the ramp
        z_axle = r + (l - r) * math.cos(theta)
        i_xx = params.inertia[0] * math.cos(theta) ** 2 + params.inertia[2] * math.sin(theta) ** 2
        i_x = 2 * (i_xx + m * (d_y**2 + z_leg**2)) + mh * z_axle**2
        h = (2 * m * z_leg + mh * z_axle) / params.total_mass
        assert conf.com_height == pytest.approx(h, rel=RTOL)
        lean = params.total_mass * params.gravity * (h - rho) / i_x
        assert len(conf.exponents_squared) == 1
        assert conf.exponents_squared[0] == pytest.approx(lean, rel=RTOL)
        assert conf.stable == (h < rho)


def test_ramp_growth_rate_matches_the_model_flow(toy_report):
    # On the ramp the rolling contact is nonholonomic and the stiffness is not symmetric: check the
    # one-foot growth rate against the model's own nonlinear flow. A 1e-10 rad perturbation grows
    # by e^10 in 1.2 s (still linear); the fit over 0.8-1.2 s sees the fastest mode, the next one
    # (s^2 = 28, growth 5.3/s) being 20 times smaller there: 1 % tolerance.
    params, report = toy_report
    conf = report.configuration("one foot")
    assert conf.status == "unstable" and 8.0 < conf.growth_rate < 8.7  # fixes the time window
    q0 = np.array([conf.equilibrium[k] for k in ("phi", "psi", "theta_st", "theta_sw")])
    rhs = build_functions(False)["rhs"]
    p = params.input_vector()
    x0 = np.concatenate([q0 + 1e-10 * np.random.default_rng(1).standard_normal(4), np.zeros(6)])
    sol = solve_ivp(lambda t, x: np.array(rhs(x, p)).ravel(), (0.0, 1.2), x0, method="DOP853",
                    rtol=1e-12, atol=1e-16, dense_output=True)
    assert sol.success
    times = np.linspace(0.8, 1.2, 50)
    dev = np.linalg.norm(sol.sol(times)[:4].T - q0, axis=1)
    fitted = np.polyfit(times, np.log(dev), 1)[0]
    assert fitted == pytest.approx(conf.growth_rate, rel=1e-2)


W0_WALKERS = [
    # (d_z, rho) on the rocker: leg mass below the foot centres, h = 0.15 + d_z.
    (-0.14, 0.005), (-0.14, 0.03), (-0.125, 0.005), (-0.125, 0.03), (-0.125, 0.045),
    (-0.11, 0.03), (-0.11, 0.045),
]


@pytest.mark.parametrize(("d_z", "rho"), W0_WALKERS)
def test_static_margin_sign_agrees_with_the_verdict_for_w0(d_z, rho):
    params = _rocker(rho, **{"com_offset[2]": d_z})
    margin = static_margin(params)
    assert abs(margin) >= 0.004  # well away from the boundary (tested on its own above)
    assert can_stand(params).can_stand == (margin < 0)


def test_static_margin_sign_agrees_for_the_toy(toy_report):
    params, report = toy_report
    assert params.hip_width == 0.0
    assert static_margin(params) == pytest.approx(0.15 - 0.11 * 0.1 / 0.12 - 0.005, rel=1e-14)
    assert (static_margin(params) > 0) == (not report.can_stand)


def test_simplest_walker_cannot_stand_and_does_not_crash():
    # Point feet, point masses, legs of mass 1e-10 M: massless directions in the mass matrix.
    params = load_params(DATA / "params" / "simplest-walker.toml")
    report = can_stand(params)
    assert not report.can_stand and not report.can_stand_level
    g_over_l = params.gravity / params.leg_length
    for level in (False, True):
        one = report.configuration("one foot", level=level)
        assert one.status == "unstable"
        # A point hip mass on a massless rod over a point contact: an inverted pendulum,
        # s^2 = g / l in both directions (to O(m / M) = 1e-10).
        unstable = sorted(z.real for z in one.exponents_squared if z.real > 0)
        np.testing.assert_allclose(unstable, [g_over_l, g_over_l], rtol=1e-8)
        # Splayed on two point feet it pivots about the line through them: falls sideways.
        splayed = report.configuration("two feet, splayed legs", level=level)
        assert splayed.status == "unstable" and splayed.mode == "sideways (lean)"


def test_one_foot_equilibrium_is_at_rest_in_the_model(toy_report):
    # The model's own state derivative (equations.build_functions) at the reported equilibrium
    # with zero rates: no acceleration, to 1e-9 g / l (the solver's residual tolerance).
    params, report = toy_report
    rhs = build_functions(False)["rhs"]
    for level in (False, True):
        p = params.replace(slope=0.0) if level else params
        eq = report.configuration("one foot", level=level).equilibrium
        x = np.concatenate([[eq["phi"], eq["psi"], eq["theta_st"], eq["theta_sw"]], np.zeros(6)])
        accel = np.array(rhs(x, p.input_vector())).ravel()[4:8]
        assert np.max(np.abs(accel)) < 1e-9 * p.gravity / p.leg_length


def _potential_functions():
    sym = symbolic(False)
    e = sym.exprs
    hess, grad = ca.hessian(e["potential_rel"], sym.q)
    forcing0 = ca.substitute(e["forcing"], sym.u, ca.SX.zeros(4))
    return (
        ca.Function("pot", [sym.q, sym.p], [e["potential_rel"], grad, hess, forcing0]),
        ca.Function("c2", [sym.q, sym.p], [e["c2"], ca.jacobian(e["c2"], sym.q)]),
    )


def test_level_ground_one_foot_stiffness_is_the_potential_hessian(toy_params):
    # On level ground the contact travels horizontally, so Kane's generalised gravity force must be
    # minus the gradient of the potential and the one-foot stiffness its Hessian (an independent
    # differentiation of equations' potential). Hip width and products of inertia make it general.
    params = toy_params.replace(
        slope=0.0, hip_width=0.03, **{"inertia[3]": 2e-5, "inertia[4]": -1e-5}
    )
    conf = can_stand(params).configuration("one foot")
    q = [conf.equilibrium[k] for k in ("phi", "psi", "theta_st", "theta_sw")]
    pot, _ = _potential_functions()
    _, grad, hess, forcing0 = (np.array(v) for v in pot(q, params.input_vector()))
    scale = params.total_mass * params.gravity * params.leg_length
    np.testing.assert_allclose(forcing0.ravel(), -grad.ravel(), atol=1e-12 * scale)
    np.testing.assert_allclose(np.linalg.norm(grad), 0.0, atol=1e-9 * scale)  # an equilibrium
    np.testing.assert_allclose(
        sorted(conf.stiffness), np.linalg.eigvalsh(hess), rtol=0, atol=1e-9 * scale
    )


@pytest.mark.parametrize("slope", [0.0, 0.1])
def test_point_feet_two_feet_stiffness_is_the_constrained_second_variation(slope):
    # Point feet do not roll: with both down, the configurations that keep them in place are the
    # curve c2(q) = c2(q0) (3 equations, 4 angles), holonomic even on a ramp, and the potential is
    # a function of q. The splayed stiffness must be V'' along that curve (finite differences,
    # step 1e-3 rad: truncation ~1e-7 relative, round-off ~1e-10).
    params = Params(
        leg_length=0.5, foot_radius=0.0, foot_lateral_radius=0.0, hip_width=0.05, leg_mass=1.0,
        axle_mass=0.5, com_offset=(0.02, 0.03, -0.3), inertia=(0.02, 0.02, 0.002, 0.001, 0.0, 0.0),
        slope=slope, gravity=9.81,
    )
    report = can_stand(params)
    assert not report.can_stand  # two point contacts: it pivots about the line through them
    conf = report.configuration("two feet, splayed legs")
    assert conf.status == "unstable" and len(conf.stiffness) == 1
    q0 = np.array([conf.equilibrium[k] for k in ("phi", "psi", "theta_st", "theta_sw")])
    pot, c2fun = _potential_functions()
    p = params.input_vector()
    target, jac0 = (np.array(v) for v in c2fun(q0, p))
    tangent = np.linalg.svd(jac0)[2][-1]

    def potential_on_curve(eps):
        q = q0 + eps * tangent
        for _ in range(50):  # chord Newton in the row space of the constraint Jacobian
            res = (np.array(c2fun(q, p)[0]) - target).ravel()
            q = q - np.linalg.lstsq(jac0, res, rcond=None)[0]
        assert np.max(np.abs(np.array(c2fun(q, p)[0]) - target)) < 1e-14
        return float(pot(q, p)[0])

    h = 1e-3
    second = (potential_on_curve(h) - 2 * potential_on_curve(0.0) + potential_on_curve(-h)) / h**2
    assert second < 0
    assert conf.stiffness[0] == pytest.approx(second, rel=1e-5)


def test_friction_limit(toy_params):
    # On a ramp the feet together carry the weight's downhill component M g sin(alpha) against the
    # normal M g cos(alpha): some foot needs a friction coefficient of at least tan(alpha) = 0.079.
    params = _rocker(0.04).replace(slope=toy_params.slope)
    assert can_stand(params).can_stand
    report = can_stand(params, friction=0.05)
    assert not report.can_stand and report.can_stand_level
    for conf in report.configurations:
        if not conf.level:
            assert conf.status in ("infeasible", "no equilibrium")
            assert conf.friction_needed >= math.tan(params.slope) * (1 - 1e-12)
    assert "needs a friction coefficient of 0.0787 (limit 0.05)" in report.reason
    assert "On level ground it could stand" in report.reason


def test_bad_arguments(toy_params):
    with pytest.raises(TypeError, match="Params"):
        can_stand({"leg_length": 0.15})
    with pytest.raises(TypeError, match="Params"):
        static_margin(None)
    for bad in (-1.0, math.nan, "1"):
        with pytest.raises(ValueError, match="friction"):
            can_stand(toy_params, friction=bad)
    with pytest.raises(TypeError):
        can_stand(toy_params, frictoin=1.0)  # misspelled keyword
    report = can_stand(toy_params.replace(slope=0.0))
    with pytest.raises(ValueError, match="kind"):
        report.configuration("three feet")
