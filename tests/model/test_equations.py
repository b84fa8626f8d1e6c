"""Equations of motion and collision: energy, conservation laws, an independent planar derivation."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp
from toywalk.model.parameters import Params
from toywalk.model.walker import Walker

from . import roundfoot_reference as ref
from .collision_reference import free_system, u_plus_old_labels
from .walkers import FEET, GENERAL

X0 = np.array([0.1, 0.05, -0.1, 0.15, 0.3, -0.2, 0.5, 0.3, 0.0, 0.0])


@pytest.fixture(scope="module", params=sorted(FEET))
def walker(request):
    return Walker(Params(**GENERAL, **FEET[request.param]))


def _integrate(walker, x0, t_end):
    sol = solve_ivp(lambda t, x: walker.rhs(x), (0, t_end), x0, method="DOP853",
                    rtol=1e-12, atol=1e-13, dense_output=True)
    assert sol.success
    return sol


def test_energy_constant_between_collisions(walker):
    """Energy (with the contact's travel in the potential) is conserved to 1e-9 relative."""
    sol = _integrate(walker, X0, 0.25)
    energies = np.array([walker.energy(x) for x in sol.y.T])
    scale = walker.params.total_mass * walker.params.gravity * walker.params.leg_length
    # DOP853 at rtol 1e-12 over ~100 steps: round-off and truncation far below 1e-9 of m g l.
    assert np.ptp(energies) / scale < 1e-9
    # The motion is not trivial: kinetic and potential energy exchange a sizeable fraction.
    assert np.ptp([walker.energy(np.r_[x[:4], 0, 0, 0, 0, x[8:]]) for x in sol.y.T]) / scale > 1e-2


@pytest.mark.parametrize("feet", ["sphere", "torus"])
def test_energy_check_can_fail(feet):
    """A wrong contact-travel rate (10 % off) makes the energy drift: the check above can fail.
    (A point foot's contact does not travel, so there is nothing to get wrong there.)"""
    walker = Walker(Params(**GENERAL, **FEET[feet]))

    def wrong(t, x):
        xdot = walker.rhs(x)
        xdot[8] *= 1.1
        return xdot
    sol = solve_ivp(wrong, (0, 0.25), X0, method="DOP853", rtol=1e-12, atol=1e-13)
    energies = np.array([walker.energy(x) for x in sol.y.T])
    scale = walker.params.total_mass * walker.params.gravity * walker.params.leg_length
    assert np.ptp(energies) / scale > 1e-6


def test_material_contact_point_is_at_rest(walker):
    """Rolling without slip: the foot centre's absolute velocity, obtained by differentiating its
    position (contact travel + O - C) in time, equals omega x (O - C); this checks the contact
    travel rates, including y_C, which the energy does not see."""
    sol = _integrate(walker, X0, 0.1)
    eps = 1e-6
    for t in (0.03, 0.07):
        def o_abs(tt):
            x = sol.sol(tt)
            return np.r_[x[8], x[9], 0.0] + walker.points(x)[1]
        v_fd = (o_abs(t + eps) - o_abs(t - eps)) / (2 * eps)
        # The same velocity from the rigid stance leg: H1 and O1 are both on it, so
        # v_O - v_H = omega x (O - H); omega from the stance leg's rotation about the contact.
        x = sol.sol(t)
        pts = walker.points(x)
        def h_abs(tt):
            xx = sol.sol(tt)
            return np.r_[xx[8], xx[9], 0.0] + walker.points(xx)[2]
        v_h = (h_abs(t + eps) - h_abs(t - eps)) / (2 * eps)
        # Both points move as material points rotating about the (instantaneously fixed) contact
        # material point: v . (P - C) = 0 for any material point P of the stance leg.
        assert abs(np.dot(v_h, pts[2] - pts[0])) < 1e-7 * np.linalg.norm(v_h) * 0.15 + 1e-9
        if walker.params.foot_radius > 0:
            assert abs(np.dot(v_fd, pts[1] - pts[0])) < 1e-7 * (np.linalg.norm(v_fd) + 1e-3)


def test_mass_matrix_symmetric_positive_definite(walker):
    m_mat, _ = walker.eng.k["mass_matrix"](X0, walker.p)
    assert_allclose(m_mat, m_mat.T, atol=1e-15)
    assert np.linalg.eigvalsh(m_mat)[0] > 0


def _pre_impact_states(rng, n):
    for _ in range(n):
        x = X0.copy()
        x[:4] = [0.05, 0.08, 0.25, -0.25] + rng.normal(0, 0.05, 4)
        x[4:8] = rng.normal(0, 1.5, 4)
        yield x


def test_collision_conserves_momenta_and_dissipates(walker):
    """Both jump conditions (seed eqs. 3-4) hold to round-off; kinetic energy never increases."""
    rng = np.random.default_rng(1)
    p = walker.p
    scale = walker.params.total_mass * walker.params.leg_length**2
    for x in _pre_impact_states(rng, 20):
        x_plus = walker.eng.k["collision"](x, p)[0].ravel().copy()
        u_plus = u_plus_old_labels(walker, x_plus)
        residual = walker.eng.k["momenta"](x, u_plus, p)[0].ravel()
        rate = np.max(np.abs(x[4:8]))
        # Round-off of a 4x4 solve with entries ~ m l^2 and rates ~ 1 rad/s.
        assert np.max(np.abs(residual)) < 1e-12 * scale * rate
        # A wrong post-collision rate must violate them (the check can fail).
        bad = walker.eng.k["momenta"](x, u_plus * 1.01, p)[0].ravel()
        assert np.max(np.abs(bad)) > 1e-6 * scale * rate
        ke_before = walker.energy(np.r_[x[:8], 0, 0]) - walker.energy(np.r_[x[:4], 0, 0, 0, 0, 0, 0])
        ke_after = (walker.energy(np.r_[x_plus[:8], 0, 0])
                    - walker.energy(np.r_[x_plus[:4], 0, 0, 0, 0, 0, 0]))
        assert ke_after <= ke_before * (1 + 1e-12)


# ------------------------------------------------------------------ independent planar derivation
PLANAR = dict(l=0.9, r=0.25, m=0.7, M_h=1.3, dx=0.04, dz=-0.35, I=0.03, g=9.81, alpha=0.05)


def _planar_walker():
    p = PLANAR
    params = Params(leg_length=p["l"], foot_radius=p["r"], foot_lateral_radius=p["r"], hip_width=0.0,
                    leg_mass=p["m"], axle_mass=p["M_h"], com_offset=(p["dx"], 0.0, p["dz"]),
                    inertia=(0.02, p["I"], 0.01, 0.0, 0.0, 0.0), slope=p["alpha"], gravity=p["g"])
    return Walker(params, planar=True), Walker(params)


def test_round_foot_dynamics_match_hand_derivation():
    """Planar round-foot accelerations equal the hand-derived Lagrangian reference (tests/model/
    roundfoot_reference.py), from both the planar reduction and the 3D model at phi = psi = 0."""
    planar, full = _planar_walker()
    rng = np.random.default_rng(2)
    for _ in range(10):
        th1, th2 = rng.uniform(-0.4, 0.4, 2)
        w1, w2 = rng.normal(0, 2, 2)
        expected = ref.accelerations(PLANAR, th1, th2, w1, w2)
        got = planar.rhs(np.array([th1, th2, w1, w2, 0.0]))[2:4]
        # Two exact derivations in double precision: agreement to round-off of O(10) terms.
        assert_allclose(got, expected, rtol=1e-10, atol=1e-10)
        got3 = full.rhs(np.array([0, 0, th1, th2, 0, 0, w1, w2, 0, 0]))
        assert_allclose(got3[6:8], expected, rtol=1e-10, atol=1e-10)
        assert_allclose(got3[4:6], 0.0, atol=1e-12)  # the planar motion is invariant


def test_round_foot_collision_matches_hand_derivation():
    planar, _ = _planar_walker()
    rng = np.random.default_rng(3)
    for _ in range(10):
        th = rng.uniform(0.1, 0.3)
        th1, th2 = th, -th + rng.normal(0, 0.02)
        w1, w2 = rng.normal(1, 0.5, 2)
        new_stance, new_swing = ref.collision(PLANAR, th1, th2, w1, w2)
        x_plus = planar.eng.k["collision"](np.array([th1, th2, w1, w2, 0.0]), planar.p)[0].ravel()
        # New labels: stance = old swing (angle th2), swing = old stance.
        assert_allclose(x_plus[:4], [th2, th1, new_stance, new_swing], rtol=1e-11, atol=1e-12)


# ------------------------------------------------------------------ independent 3D collision check
@pytest.mark.parametrize("feet", sorted(FEET))
def test_3d_collision_matches_impulse_projection(feet):
    """The seed's angular-momentum jump conditions equal a plastic impulse at D on the free
    walker (Carnot: M (u+ - u-) = A^T P, A u+ = 0), computed here from NumPy kinematics."""
    params = Params(**GENERAL, **FEET[feet])
    walker = Walker(params)
    rng = np.random.default_rng(4)
    for x in _pre_impact_states(rng, 5):
        q, rates = x[:4], x[4:8]
        m_free, a_d, a_c = free_system(params, q)
        # Pre-impact free speeds: the hip velocity follows from rolling about C (v_C = 0).
        u_minus = np.zeros(7)
        u_minus[3:] = rates
        u_minus[:3] = -(a_c[:, 3:] @ rates)
        kkt = np.block([[m_free, a_d.T], [a_d, np.zeros((3, 3))]])
        sol = np.linalg.solve(kkt, np.r_[m_free @ u_minus, np.zeros(3)])
        expected = sol[3:7]
        x_plus = walker.eng.k["collision"](x, walker.p)[0].ravel()
        got = u_plus_old_labels(walker, x_plus)
        # Two exact formulations in double precision (4x4 vs 10x10 solves): round-off level.
        assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.max(np.abs(rates)))
