"""Slow, explicit reference model of a round-footed planar two-leg walker.

This module is a *test oracle*: it is written independently of ``toywalk.model``
and favours obvious, hand-derived formulas over speed.  It uses only numpy.

Conventions (all fixed; SI units)
---------------------------------
* Slope frame: ``x`` points downhill along the ramp, ``z`` along the ramp
  normal (up).  Gravity is ``g * (sin(alpha), -cos(alpha))`` in ``(x, z)``.
* A leg with pitch ``theta`` (rad, measured from the ramp normal) has body axes
  ``b3 = (sin theta, cos theta)`` (foot -> hip) and
  ``b1 = (cos theta, -sin theta)`` (forward).  ``theta > 0`` means the hip is
  downhill of that leg's foot.  Angles are *absolute* (not relative).
* State ``(th_st, th_sw, dth_st, dth_sw)``: stance/swing pitch (rad) and
  pitch rates (rad/s).  Just after heel strike ``th_st < 0 < th_sw``.
* Foot: circular arc of radius ``r`` centred at ``O = H - (l - r) b3``.  The
  stance foot rolls without slipping on ``z = 0``; its contact point is
  ``C = (x_C, 0)`` with ``x_C = x_C0 + r * th_st`` and ``O = C + r e_z``.
* Leg centre of mass ``G = H + dx b1 + dz b3`` (``dz < 0``: below the hip).
* Planar scalar cross product (the ``y`` component of the 3-D cross product
  in the right-handed frame ``(x, y, z)``)::

      a x b = a_z b_x - a_x b_z

  With it, a body of pitch rate ``w`` rotating about a fixed point ``P`` has
  angular momentum ``(m |G - P|**2 + I) * w`` about ``P`` (positive sign), and
  the velocity of a body point is ``v_P = v_Q + w * R(P - Q)`` with
  ``R(a_x, a_z) = (a_z, -a_x)`` (note ``R b3 = b1`` and ``R b1 = -b3``).

Parameters dictionary ``p`` (keys and units)
--------------------------------------------
``l`` leg length, hip to foot bottom (m); ``r`` foot radius (m), ``0 <= r < l``;
``m`` mass of one leg (kg); ``M_h`` hip point mass (kg); ``dx``, ``dz`` leg
centre-of-mass offsets from the hip along ``b1``, ``b3`` (m); ``I`` leg moment
of inertia about its centre of mass (kg m^2); ``g`` gravity (m/s^2);
``alpha`` ramp slope (rad).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "b1",
    "b3",
    "cross",
    "positions",
    "velocities",
    "mass_matrix",
    "accelerations",
    "kinetic_energy",
    "potential_energy",
    "energy",
    "lagrangian",
    "collision",
]


# ---------------------------------------------------------------------------
# Small geometric helpers
# ---------------------------------------------------------------------------
def b1(theta):
    """Forward body axis ``(cos theta, -sin theta)`` in ``(x, z)``.

    Parameters
    ----------
    theta : float
        Leg pitch from the ramp normal (rad).

    Returns
    -------
    numpy.ndarray, shape (2,)
        Unit vector (dimensionless).
    """
    return np.array([np.cos(theta), -np.sin(theta)])


def b3(theta):
    """Leg axis (foot to hip) ``(sin theta, cos theta)`` in ``(x, z)``.

    Parameters
    ----------
    theta : float
        Leg pitch from the ramp normal (rad).

    Returns
    -------
    numpy.ndarray, shape (2,)
        Unit vector (dimensionless).
    """
    return np.array([np.sin(theta), np.cos(theta)])


def cross(a, b):
    """Planar scalar cross product ``a_z b_x - a_x b_z``.

    This is the ``y`` component of ``a x b`` in the right-handed frame
    ``(x, y, z)``; positive pitch rates are rotations about ``+y``.

    Parameters
    ----------
    a, b : array_like, shape (2,)
        Vectors in ``(x, z)`` components.

    Returns
    -------
    float
        Scalar cross product (units of ``a`` times units of ``b``).
    """
    return a[1] * b[0] - a[0] * b[1]


# ---------------------------------------------------------------------------
# Kinematics
# ---------------------------------------------------------------------------
def positions(p, th_st, th_sw, x_C):
    """Positions of the hip and of both leg centres of mass.

    Derivation::

        C  = (x_C, 0)                      stance contact point
        O1 = C + r e_z                     stance arc centre
        H  = O1 + (l - r) b3(th_st)
        G1 = H + dx b1(th_st) + dz b3(th_st)   stance leg COM
        G2 = H + dx b1(th_sw) + dz b3(th_sw)   swing leg COM

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    x_C : float
        Downhill position of the stance contact point (m).

    Returns
    -------
    H, G1, G2 : numpy.ndarray, shape (2,)
        Positions in the slope frame ``(x, z)`` (m).
    """
    l, r, dx, dz = p["l"], p["r"], p["dx"], p["dz"]
    H = np.array([x_C, r]) + (l - r) * b3(th_st)
    G1 = H + dx * b1(th_st) + dz * b3(th_st)
    G2 = H + dx * b1(th_sw) + dz * b3(th_sw)
    return H, G1, G2


def velocities(p, th_st, th_sw, dth_st, dth_sw):
    """Velocities of the hip and both leg centres of mass while rolling.

    Derivation (``d b3/dtheta = b1``, ``d b1/dtheta = -b3``,
    ``d x_C/dt = r dth_st``)::

        vH  = r dth_st e_x + (l - r) dth_st b1(th_st)
        vG1 = vH + dth_st (dz b1(th_st) - dx b3(th_st))
        vG2 = vH + dth_sw (dz b1(th_sw) - dx b3(th_sw))

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    dth_st, dth_sw : float
        Stance and swing pitch rates (rad/s).

    Returns
    -------
    vH, vG1, vG2 : numpy.ndarray, shape (2,)
        Velocities in the slope frame ``(x, z)`` (m/s).
    """
    l, r, dx, dz = p["l"], p["r"], p["dx"], p["dz"]
    ex = np.array([1.0, 0.0])
    vH = dth_st * (r * ex + (l - r) * b1(th_st))
    vG1 = vH + dth_st * (dz * b1(th_st) - dx * b3(th_st))
    vG2 = vH + dth_sw * (dz * b1(th_sw) - dx * b3(th_sw))
    return vH, vG1, vG2


# ---------------------------------------------------------------------------
# Energies and Lagrangian
# ---------------------------------------------------------------------------
def kinetic_energy(p, th_st, th_sw, dth_st, dth_sw):
    """Kinetic energy while the stance foot rolls.

    ``T = 1/2 M_h |vH|^2 + 1/2 m |vG1|^2 + 1/2 m |vG2|^2
    + 1/2 I (dth_st^2 + dth_sw^2)``, evaluated from :func:`velocities`
    (not from :func:`mass_matrix`, so the two can be checked against each
    other).

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    dth_st, dth_sw : float
        Stance and swing pitch rates (rad/s).

    Returns
    -------
    float
        Kinetic energy (J).
    """
    m, M_h, I = p["m"], p["M_h"], p["I"]
    vH, vG1, vG2 = velocities(p, th_st, th_sw, dth_st, dth_sw)
    return 0.5 * (
        M_h * (vH @ vH)
        + m * (vG1 @ vG1)
        + m * (vG2 @ vG2)
        + I * (dth_st**2 + dth_sw**2)
    )


def potential_energy(p, th_st, th_sw, x_C):
    """Gravitational potential energy measured from the ramp origin.

    ``V = -sum_k m_k g . r_k = g sum_k m_k (z_k cos(alpha) - x_k sin(alpha))``
    over the hip mass and both leg masses (positions from :func:`positions`).

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    x_C : float
        Downhill position of the stance contact point (m).

    Returns
    -------
    float
        Potential energy (J).
    """
    m, M_h, g, alpha = p["m"], p["M_h"], p["g"], p["alpha"]
    H, G1, G2 = positions(p, th_st, th_sw, x_C)

    def height(q):
        # Height against gravity: -(gravity direction) . q  (m).
        return q[1] * np.cos(alpha) - q[0] * np.sin(alpha)

    return g * (M_h * height(H) + m * height(G1) + m * height(G2))


def energy(p, th_st, th_sw, dth_st, dth_sw, x_C):
    """Total mechanical energy (kinetic + gravitational potential).

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    dth_st, dth_sw : float
        Stance and swing pitch rates (rad/s).
    x_C : float
        Downhill position of the stance contact point (m); while rolling it
        changes as ``d x_C = r d th_st``.

    Returns
    -------
    float
        Energy (J).
    """
    return kinetic_energy(p, th_st, th_sw, dth_st, dth_sw) + potential_energy(
        p, th_st, th_sw, x_C
    )


def lagrangian(p, th_st, th_sw, dth_st, dth_sw):
    """Lagrangian ``L = T - V`` with the rolling constraint substituted.

    The (holonomic) rolling constraint is ``x_C = r * th_st`` (the additive
    constant ``x_C0`` is taken as 0; it only shifts ``L`` by a constant).

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    dth_st, dth_sw : float
        Stance and swing pitch rates (rad/s).

    Returns
    -------
    float
        Lagrangian (J).
    """
    return kinetic_energy(p, th_st, th_sw, dth_st, dth_sw) - potential_energy(
        p, th_st, th_sw, p["r"] * th_st
    )


# ---------------------------------------------------------------------------
# Equations of motion (hand-derived)
# ---------------------------------------------------------------------------
def mass_matrix(p, th_st, th_sw):
    """Hand-derived 2x2 mass matrix ``M(q)`` with ``T = 1/2 u^T M u``.

    With ``u = (dth_st, dth_sw)``, write ``vH = J_H dth_st``,
    ``vG1 = J_G1 dth_st``, ``vG2 = J_H dth_st + K2 dth_sw`` where::

        J_H  = r e_x + (l - r) b1(th_st)
        J_G1 = r e_x + (l - r + dz) b1(th_st) - dx b3(th_st)
        K2   = dz b1(th_sw) - dx b3(th_sw)

    and use ``e_x . b1(t) = cos t``, ``e_x . b3(t) = sin t``,
    ``b1(a) . b1(b) = cos(a - b)``, ``b1(a) . b3(b) = -sin(a - b)``::

        |J_H|^2  = r^2 + (l-r)^2 + 2 r (l-r) cos th_st
        |J_G1|^2 = r^2 + a^2 + dx^2 + 2 r a cos th_st - 2 r dx sin th_st,
                   a = l - r + dz
        J_H.K2   = r (dz cos th_sw - dx sin th_sw)
                   + (l-r) (dz cos(th_st - th_sw) + dx sin(th_st - th_sw))

        M11 = (M_h + m) |J_H|^2 + m |J_G1|^2 + I
        M12 = M21 = m J_H.K2
        M22 = m (dx^2 + dz^2) + I

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).

    Returns
    -------
    numpy.ndarray, shape (2, 2)
        Mass matrix (kg m^2).
    """
    l, r, m, M_h = p["l"], p["r"], p["m"], p["M_h"]
    dx, dz, I = p["dx"], p["dz"], p["I"]
    s = l - r
    a = l - r + dz
    JH2 = r**2 + s**2 + 2.0 * r * s * np.cos(th_st)
    JG12 = r**2 + a**2 + dx**2 + 2.0 * r * a * np.cos(th_st) - 2.0 * r * dx * np.sin(th_st)
    JHK2 = r * (dz * np.cos(th_sw) - dx * np.sin(th_sw)) + s * (
        dz * np.cos(th_st - th_sw) + dx * np.sin(th_st - th_sw)
    )
    M11 = (M_h + m) * JH2 + m * JG12 + I
    M12 = m * JHK2
    M22 = m * (dx**2 + dz**2) + I
    return np.array([[M11, M12], [M12, M22]])


def accelerations(p, th_st, th_sw, dth_st, dth_sw):
    """Angular accelerations from hand-derived Lagrange equations.

    Lagrange's equations ``d/dt(dL/du) - dL/dq = 0`` with ``L = 1/2 u^T M u - V``
    give ``M u' + c(q, u) + dV/dq = 0`` with the Christoffel form
    ``c_i = sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) u_j u_k``.

    ``M11`` depends on ``th_st`` only, ``M22`` is constant, and with::

        M11' = dM11/dth_st = -2 r [ (M_h + m) (l-r) sin th_st
                                    + m (a sin th_st + dx cos th_st) ]
        P1   = dM12/dth_st = m (l-r) (dx cos(th_st-th_sw) - dz sin(th_st-th_sw))
        P2   = dM12/dth_sw = m [ -r (dz sin th_sw + dx cos th_sw)
                                 + (l-r) (dz sin(th_st-th_sw) - dx cos(th_st-th_sw)) ]

    the cross terms cancel and::

        c1 = 1/2 M11' dth_st^2 + P2 dth_sw^2
        c2 = P1 dth_st^2

    Potential (``Mt = M_h + 2 m``, ``x_C = x_C0 + r th_st``,
    ``z_H = r + (l-r) cos th_st``, ``x_H = x_C + (l-r) sin th_st``)::

        V = g cos(alpha) [Mt z_H + m (dz cos th_st - dx sin th_st)
                                 + m (dz cos th_sw - dx sin th_sw)]
          - g sin(alpha) [Mt x_H + m (dx cos th_st + dz sin th_st)
                                 + m (dx cos th_sw + dz sin th_sw)]

        dV/dth_st = g cos(alpha) [-Mt (l-r) sin th_st - m (dx cos th_st + dz sin th_st)]
                  - g sin(alpha) [ Mt (r + (l-r) cos th_st)
                                   + m (dz cos th_st - dx sin th_st)]
        dV/dth_sw = -g cos(alpha) m (dx cos th_sw + dz sin th_sw)
                  - g sin(alpha) m (dz cos th_sw - dx sin th_sw)

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Stance and swing leg pitch (rad).
    dth_st, dth_sw : float
        Stance and swing pitch rates (rad/s).

    Returns
    -------
    ddth_st, ddth_sw : float
        Angular accelerations (rad/s^2).
    """
    l, r, m, M_h = p["l"], p["r"], p["m"], p["M_h"]
    dx, dz, g, alpha = p["dx"], p["dz"], p["g"], p["alpha"]
    s = l - r
    a = l - r + dz
    Mt = M_h + 2.0 * m
    ca, sa = np.cos(alpha), np.sin(alpha)
    c1t, s1t = np.cos(th_st), np.sin(th_st)
    c2t, s2t = np.cos(th_sw), np.sin(th_sw)
    c12, s12 = np.cos(th_st - th_sw), np.sin(th_st - th_sw)

    M = mass_matrix(p, th_st, th_sw)

    dM11 = -2.0 * r * ((M_h + m) * s * s1t + m * (a * s1t + dx * c1t))
    P1 = m * s * (dx * c12 - dz * s12)
    P2 = m * (-r * (dz * s2t + dx * c2t) + s * (dz * s12 - dx * c12))
    c1 = 0.5 * dM11 * dth_st**2 + P2 * dth_sw**2
    c2 = P1 * dth_st**2

    dV1 = g * ca * (-Mt * s * s1t - m * (dx * c1t + dz * s1t)) - g * sa * (
        Mt * (r + s * c1t) + m * (dz * c1t - dx * s1t)
    )
    dV2 = -g * ca * m * (dx * c2t + dz * s2t) - g * sa * m * (dz * c2t - dx * s2t)

    rhs = -np.array([c1 + dV1, c2 + dV2])
    dd = np.linalg.solve(M, rhs)
    return float(dd[0]), float(dd[1])


# ---------------------------------------------------------------------------
# Heel strike
# ---------------------------------------------------------------------------
def collision(p, th_st, th_sw, dth_st, dth_sw):
    """Plastic, no-slip heel strike of the swing foot.

    The swing foot touches at ``D = O2 - r e_z`` with
    ``O2 = H - (l - r) b3(th_sw)``.  Angles are unchanged; the old stance
    leg (leg 1) leaves the ground with no impulse; the old swing leg (leg 2)
    rolls about ``D`` afterwards.  Unknowns are the post-impact rates in the
    new labelling: ``W1`` (new stance = leg 2, pitch ``th_sw``) and ``W2``
    (new swing = leg 1, pitch ``th_st``).

    Post-impact velocities (rolling about ``D``)::

        vH+  = W1 J_H(th_sw),  J_H(t) = r e_x + (l - r) b1(t)
        vG2+ = W1 J_G(th_sw),  J_G(t) = r e_x + (l - r + dz) b1(t) - dx b3(t)
        vG1+ = vH+ + W2 K(th_st),  K(t) = dz b1(t) - dx b3(t)

    Pre-impact velocities are those of :func:`velocities` (leg 1 rolling).
    Angular momentum of a rigid body about point ``P``:
    ``(G - P) x m vG + I w``.  Conserved quantities:

    (a) whole system about ``D``::

            A11 W1 + A12 W2 = L_D-
            A11 = M_h (H-D) x J_H(th_sw) + m (G2-D) x J_G(th_sw) + I
                  + m (G1-D) x J_H(th_sw)
            A12 = m (G1-D) x K(th_st) + I
            L_D- = M_h (H-D) x vH- + m (G1-D) x vG1- + I dth_st
                   + m (G2-D) x vG2- + I dth_sw

    (b) leg 1 (old stance, new swing) about the hip ``H``::

            B1 W1 + B2 W2 = L_H-
            B1 = m (G1-H) x J_H(th_sw)
            B2 = m (G1-H) x K(th_st) + I   (= m (dx^2 + dz^2) + I)
            L_H- = m (G1-H) x vG1- + I dth_st

    Parameters
    ----------
    p : dict
        Parameters (see module docstring).
    th_st, th_sw : float
        Pre-impact stance and swing pitch (rad); unchanged by the impact.
    dth_st, dth_sw : float
        Pre-impact stance and swing pitch rates (rad/s).

    Returns
    -------
    dth_st_plus, dth_sw_plus : float
        Post-impact pitch rates (rad/s) of the NEW stance leg (old swing leg,
        pitch ``th_sw``) and of the NEW swing leg (old stance leg, pitch
        ``th_st``).
    """
    l, r, m, M_h = p["l"], p["r"], p["m"], p["M_h"]
    dx, dz, I = p["dx"], p["dz"], p["I"]
    ex = np.array([1.0, 0.0])
    ez = np.array([0.0, 1.0])

    # Geometry at impact; x_C only translates everything, take x_C = 0.
    H, G1, G2 = positions(p, th_st, th_sw, 0.0)
    O2 = H - (l - r) * b3(th_sw)
    D = O2 - r * ez

    # Pre-impact velocities (old stance leg rolling).
    vH, vG1, vG2 = velocities(p, th_st, th_sw, dth_st, dth_sw)

    # Post-impact velocity directions (per unit W1, W2).
    JH_new = r * ex + (l - r) * b1(th_sw)
    JG_new = r * ex + (l - r + dz) * b1(th_sw) - dx * b3(th_sw)
    K_sw_new = dz * b1(th_st) - dx * b3(th_st)

    # (a) Angular momentum of the whole system about D.
    A11 = (
        M_h * cross(H - D, JH_new)
        + m * cross(G2 - D, JG_new)
        + I
        + m * cross(G1 - D, JH_new)
    )
    A12 = m * cross(G1 - D, K_sw_new) + I
    LD_minus = (
        M_h * cross(H - D, vH)
        + m * cross(G1 - D, vG1)
        + I * dth_st
        + m * cross(G2 - D, vG2)
        + I * dth_sw
    )

    # (b) Angular momentum of the old stance leg about the hip H.
    B1 = m * cross(G1 - H, JH_new)
    B2 = m * cross(G1 - H, K_sw_new) + I
    LH_minus = m * cross(G1 - H, vG1) + I * dth_st

    A = np.array([[A11, A12], [B1, B2]])
    rhs = np.array([LD_minus, LH_minus])
    W = np.linalg.solve(A, rhs)
    return float(W[0]), float(W[1])
