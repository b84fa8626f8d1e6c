"""Self-checks of the hand-derived round-foot reference model.

These tests only exercise ``roundfoot_reference`` (the test oracle) against
itself and against independent, slower formulations: energy conservation,
a finite-difference Lagrangian, a 4-DOF impulse projection for the heel
strike, and the simplest-walker limit of the heel strike.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

try:  # works whether or not tests/model is a package
    from . import roundfoot_reference as ref
except ImportError:
    import roundfoot_reference as ref


def _params(**overrides):
    """Generic walker: round feet, off-axis COM, inertia, hip mass, slope."""
    p = dict(
        l=1.0,  # m
        r=0.3,  # m
        m=0.5,  # kg
        M_h=1.2,  # kg
        dx=0.05,  # m
        dz=-0.4,  # m
        I=0.03,  # kg m^2
        g=9.81,  # m/s^2
        alpha=0.05,  # rad
    )
    p.update(overrides)
    return p


PARAM_SETS = [
    _params(),
    _params(r=0.6, dx=-0.08, dz=-0.7, I=0.08, M_h=0.3, alpha=0.2),
]

STATES = [
    (-0.2, 0.25, 0.8, -1.5),
    (0.1, -0.3, -0.5, 2.0),
    (0.35, 0.05, 0.0, 0.0),
]


def _rot(d):
    """R(d) = (d_z, -d_x): velocity of a body point per unit pitch rate."""
    return np.array([d[1], -d[0]])


def _total_mass(p):
    return p["M_h"] + 2.0 * p["m"]


# ---------------------------------------------------------------------------
# Kinematics and mass matrix consistency
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("state", STATES)
def test_velocities_match_finite_differences_of_positions(p, state):
    th1, th2, w1, w2 = state
    h = 1e-6  # s; central difference error ~ h^2 * |d3x/dt3| ~ 1e-12 m/s

    def pos(t):
        # Rolling: x_C advances by r * d th_st.
        return np.concatenate(
            ref.positions(p, th1 + w1 * t, th2 + w2 * t, p["r"] * (th1 + w1 * t))
        )

    v_fd = (pos(h) - pos(-h)) / (2.0 * h)
    v = np.concatenate(ref.velocities(p, th1, th2, w1, w2))
    # Roundoff eps * |x| / h ~ 1e-10 m/s dominates; 1e-8 leaves a 100x margin.
    np.testing.assert_allclose(v, v_fd, rtol=0.0, atol=1e-8)


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("state", STATES)
def test_mass_matrix_matches_kinetic_energy(p, state):
    th1, th2, w1, w2 = state
    u = np.array([w1, w2])
    M = ref.mass_matrix(p, th1, th2)
    T = ref.kinetic_energy(p, th1, th2, w1, w2)
    # Two exact expressions of the same quantity: only roundoff (~1e-15) differs.
    assert 0.5 * u @ M @ u == pytest.approx(T, rel=1e-12, abs=1e-14)


# ---------------------------------------------------------------------------
# Energy conservation of the equations of motion
# ---------------------------------------------------------------------------
def _energy_drift(p_eom, p_energy, state, t_end=1.0):
    """Integrate the EOM of ``p_eom``; return max |E - E0| / (Mt g l) of ``p_energy``."""

    def rhs(_t, y):
        th1, th2, w1, w2, _xc = y
        a1, a2 = ref.accelerations(p_eom, th1, th2, w1, w2)
        return [w1, w2, a1, a2, p_eom["r"] * w1]

    y0 = list(state) + [0.0]
    sol = solve_ivp(
        rhs, (0.0, t_end), y0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True
    )
    assert sol.success, sol.message
    ts = np.linspace(0.0, t_end, 201)
    ys = sol.sol(ts)
    E = np.array(
        [ref.energy(p_energy, y[0], y[1], y[2], y[3], y[4]) for y in ys.T]
    )
    return np.max(np.abs(E - E[0])) / (_total_mass(p_energy) * p_energy["g"] * p_energy["l"])


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("state", STATES)
def test_energy_is_conserved_while_rolling(p, state):
    drift = _energy_drift(p, p, state)
    # DOP853 at rtol=atol=1e-12 over ~1 s accumulates ~1e-11 relative error;
    # a wrong EOM term of relative size eps shows up as a drift ~eps (see the
    # negative control below), so 1e-9 separates the two cleanly.
    assert drift < 1e-9


def test_energy_check_detects_a_wrong_model():
    """Negative control: EOM with a 1 % wrong foot radius must fail the check."""
    p = PARAM_SETS[0]
    drift = _energy_drift(_params(r=1.01 * p["r"]), p, STATES[0])
    # A 1 % model error gives a drift many orders above the 1e-9 threshold.
    assert drift > 1e-5


# ---------------------------------------------------------------------------
# Equations of motion against a finite-difference Lagrangian
# ---------------------------------------------------------------------------
def _fd_accelerations(p, q, u, h=1e-5):
    """Accelerations from Lagrange's equations, all derivatives numerical.

    ``L`` is quadratic in ``u``, so ``dL/du`` by a central difference with a
    unit step is exact (up to roundoff); ``dL/dq`` and the convective part of
    ``d/dt (dL/du)`` use central differences with step ``h`` (rad).
    """
    q = np.asarray(q, float)
    u = np.asarray(u, float)
    eye = np.eye(2)

    def L(qq, uu):
        return ref.lagrangian(p, qq[0], qq[1], uu[0], uu[1])

    def mom(qq, uu):
        return np.array([(L(qq, uu + e) - L(qq, uu - e)) / 2.0 for e in eye])

    M = np.column_stack([mom(q, e) for e in eye])  # mom is linear in u
    dLdq = np.array([(L(q + h * e, u) - L(q - h * e, u)) / (2.0 * h) for e in eye])
    # d/dt(dL/du) = (d mom/dq) u + M u'; directional derivative along q' = u.
    conv = (mom(q + h * u, u) - mom(q - h * u, u)) / (2.0 * h)
    return np.linalg.solve(M, dLdq - conv)


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("state", STATES)
def test_accelerations_match_finite_difference_lagrangian(p, state):
    th1, th2, w1, w2 = state
    a = np.array(ref.accelerations(p, th1, th2, w1, w2))
    a_fd = _fd_accelerations(p, (th1, th2), (w1, w2))
    scale = max(np.max(np.abs(a)), p["g"] / p["l"])
    # Step h=1e-5: truncation ~h^2 = 1e-10, roundoff ~eps*|L|/h ~ 1e-9 of the
    # scale, amplified by cond(M) <~ 100; 1e-6 relative keeps a wide margin.
    np.testing.assert_allclose(a, a_fd, rtol=0.0, atol=1e-6 * scale)


# ---------------------------------------------------------------------------
# Heel strike
# ---------------------------------------------------------------------------
def _impulse_projection(p, th1, th2, w1, w2):
    """Heel strike as a plastic impulsive constraint on the free 4-DOF system.

    Generalized velocity ``v = (vH_x, vH_z, w_leg1, w_leg2)``.  The impulse at
    ``D`` makes the material point of leg 2 at ``D`` stop:
    ``v+ = v- - M^-1 J^T (J M^-1 J^T)^-1 J v-``.  Returns
    ``(w_leg2+, w_leg1+, v-, v+, M)``.
    """
    l, r, m, M_h, I = p["l"], p["r"], p["m"], p["M_h"], p["I"]
    H, G1, G2 = ref.positions(p, th1, th2, 0.0)
    C = np.array([0.0, 0.0])  # old stance contact (x_C = 0)
    D = H - (l - r) * ref.b3(th2) - np.array([0.0, r])

    def jac(point_minus_hip, leg):
        Jm = np.zeros((2, 4))
        Jm[:, :2] = np.eye(2)
        if leg is not None:
            Jm[:, 2 + leg] = _rot(point_minus_hip)
        return Jm

    JH = jac(None, None)
    JG1 = jac(G1 - H, 0)
    JG2 = jac(G2 - H, 1)
    M4 = M_h * JH.T @ JH + m * JG1.T @ JG1 + m * JG2.T @ JG2 + I * np.diag([0, 0, 1.0, 1.0])

    # Pre-impact: leg 1 rolls about C, so vH = w1 R(H - C).
    v_minus = np.concatenate([w1 * _rot(H - C), [w1, w2]])
    JD = jac(D - H, 1)
    Minv_JT = np.linalg.solve(M4, JD.T)
    lam = np.linalg.solve(JD @ Minv_JT, JD @ v_minus)
    v_plus = v_minus - Minv_JT @ lam
    return v_plus[3], v_plus[2], v_minus, v_plus, M4


COLLISION_RATES = [(0.9, -1.3), (1.5, 0.4), (-0.3, -2.0), (0.0, 0.0)]


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("rates", COLLISION_RATES)
def test_collision_does_not_gain_kinetic_energy(p, rates):
    th1, th2 = 0.2, -0.2  # heel-strike configuration: swing foot on the ramp
    w1, w2 = rates
    W1, W2 = ref.collision(p, th1, th2, w1, w2)
    T_minus = ref.kinetic_energy(p, th1, th2, w1, w2)
    # After impact the old swing leg (pitch th2) is the rolling stance leg.
    T_plus = ref.kinetic_energy(p, th2, th1, W1, W2)
    # Carnot: a plastic impact can only lose energy; 1e-12 J allows roundoff.
    assert T_plus <= T_minus + 1e-12


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("rates", COLLISION_RATES)
@pytest.mark.parametrize("angles", [(0.2, -0.2), (0.3, -0.1)])
def test_collision_matches_impulse_projection(p, rates, angles):
    th1, th2 = angles
    w1, w2 = rates
    W = np.array(ref.collision(p, th1, th2, w1, w2))
    W1_ip, W2_ip, v_minus, v_plus, M4 = _impulse_projection(p, th1, th2, w1, w2)
    # Two exact linear-algebra formulations of the same impact: roundoff only.
    np.testing.assert_allclose(W, [W1_ip, W2_ip], rtol=1e-10, atol=1e-12)

    # Carnot's theorem: T- - T+ = 1/2 dv^T M dv (energies of the free system).
    dv = v_minus - v_plus
    loss = 0.5 * v_minus @ M4 @ v_minus - 0.5 * v_plus @ M4 @ v_plus
    # Exact identity; relative roundoff ~1e-15 of energies of order 1 J.
    assert loss == pytest.approx(0.5 * dv @ M4 @ dv, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize(
    "th1, th2", [(0.05, -0.05), (0.2, -0.2), (0.35, -0.35), (0.2, -0.3)]
)
@pytest.mark.parametrize("w1, w2", [(0.3, -0.5), (1.2, 0.7)])
def test_collision_simplest_walker_limit(th1, th2, w1, w2):
    """Point feet, leg mass at the foot, m/M_h -> 0 (Garcia et al. 1998).

    Before impact the stance leg's mass sits at the stance foot (velocity 0)
    and the hip moves with ``vH- = l w1 b1(th1)``.  The impulse along the new
    leg ``b3(th2)`` removes that component of the hip velocity and keeps the
    component along ``b1(th2)``: ``l W1 = vH- . b1(th2)``, i.e.
    ``W1 = cos(th1 - th2) w1`` (``= cos(2 theta) w1`` at ``th2 = -th1``).
    The old stance foot keeps zero angular momentum about the hip:
    ``(-l b3(th1)) x m (vH+ - W2 l b1(th1)) = 0`` gives
    ``W2 = cos(th1 - th2) W1`` (``= cos(2 theta)^2 w1``, Garcia's
    ``phi+' = cos 2theta (1 - cos 2theta) theta-'`` in absolute angles).
    The old swing leg's rate ``w2`` carries momentum of order ``m`` only.
    """
    p = dict(l=1.0, r=0.0, m=1e-10, M_h=1.0, dx=0.0, dz=-1.0, I=0.0, g=1.0, alpha=0.01)
    W1, W2 = ref.collision(p, th1, th2, w1, w2)
    c = np.cos(th1 - th2)
    # Corrections are O(m/M_h) = 1e-10 relative (times O(1) rate ratios).
    np.testing.assert_allclose([W1, W2], [c * w1, c * c * w1], rtol=1e-8, atol=1e-12)
    if th2 == -th1:
        c2 = np.cos(2.0 * th1)
        np.testing.assert_allclose([W1, W2], [c2 * w1, c2**2 * w1], rtol=1e-8, atol=1e-12)
