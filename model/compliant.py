"""A compliant heel strike: the collision resolved in time on soft feet, as one differentiable map.

The seed's heel strike is instantaneous and plastic (Coleman & Ruina 1998, eqs. 3-4; docs/model.md
section 4): the landing foot D takes the whole impulse, the trailing foot none. Whether the feet's
compliance matters (the brass strips "deform during foot collision in a way that may or may not be
essential") is asked here by resolving the strike in time: the walker leaves the rolling model,
falls on two spring-damper contacts for a short phase, and is handed back to the rolling model with
the landing foot as stance. This module builds that phase as a map with the signature of the
rigid ``collision`` (:func:`toywalk.model.equations.build_functions`), and :func:`step_functions`
the same map as the step map takes it when the ``soft_heel`` effect is on
(:mod:`toywalk.model.effects.soft`; docs/soft_feet.md section 5).

**Free (floating-base) walker.** Generalised coordinates ``Q = (X, q)``: ``X`` the position of the
old stance foot's centre O1 in the slope frame S (3 coordinates; the planar system keeps (x, z))
and ``q = (phi, psi, theta_st, theta_sw)`` (planar: the two pitches) as in the rolling model, so
both legs still share the hinge axis n: 7 degrees of freedom (4 planar). The geometry is the rolling
model's own (:func:`toywalk.model.equations.symbolic`: the points relative to the stance contact,
the torus feet's lowest points with the shared vector t), translated so that O1 sits at ``X``. The
equations follow from Kane's method (Kane & Levinson, *Dynamics: Theory and Applications*, 1985)
with generalised speeds ``U = dQ/dt``, the contact forces entering by virtual work through the
partial velocities of the material points of the feet at their lowest points.

**Normal contact law.** A Kelvin-Voigt spring-damper on the penetration ``delta = -z_C`` of each
foot's lowest point C (the torus's deepest point: the exact interpenetration of a rigid foot and
the plane) and its rate, which is minus the normal velocity of the material point at C (the
surface's tangent plane there is the ramp's)::

    N = max(0, m_eff ((1 / (tau zeta))^2 delta + (2 / tau) d(delta)/dt))   while delta > 0,  else 0.

This is MuJoCo's contact (Todorov, Erez & Tassa, IROS 2012; its ``solref = (tau, zeta)``): a
spring-damper in the contact's acceleration space with natural frequency ``1 / (tau zeta)`` and
damping ``2 / tau``, scaled by the contact's effective mass ``m_eff = 1 / (J M^-1 J')``, J the
partial velocity of the contact point along the normal and M the free walker's mass matrix. So
``tau`` sets the contact's duration whatever the walker's size, and ``zeta = 1`` (critical damping)
makes a landing plastic: an isolated mass landing on it never rebounds. Two departures from MuJoCo,
each for a reason: ``m_eff`` is evaluated once, at the heel-strike configuration, and held through
the phase (MuJoCo updates it every step), so that the spring has a potential ``k delta^2 / 2`` and
the energy balance closes (the configuration changes by O(tau) over the phase); and the force is a
force law, not MuJoCo's regularised constraint solve. ``max(0, .)`` keeps the contact from pulling.
The force jumps at touchdown (from 0 to ``m_eff (2 / tau) d(delta)/dt``): a jump inside an
integration step would make the fixed-step Runge-Kutta method first order, so the phase starts at
the landing foot's touchdown, the rigid model's heel strike, where the jump falls on the grid. A
foot leaves the ramp continuously (the clamp reaches 0 before delta does), with a kink in the force:
the integrator's local error in that one step is O(h^2).

**Tangential contact law.** Rolling without slip, regularised by a stiff tangential spring-damper
at the material contact point: the anchor ``s`` (shape (2,), planar (1,)) integrates the material
contact point's tangential velocity ``v_t`` (``ds/dt = v_t``, so s is constant while the foot
rolls), and the raw force ``F_raw = -(k s + c v_t)`` takes the normal law's stiffness and damping
(an isotropic contact). Friction caps it smoothly at ``mu N``::

    F_t = F_raw mu N / sqrt((mu N)^2 + |F_raw|^2),

which is ``F_raw`` to relative O((|F_raw| / mu N)^2) below the limit and tends to ``mu N`` in
the direction of ``F_raw`` beyond it: at the friction limit the foot slides, the anchor stretching
as it does, and the force vanishes with N (a foot lifting off lets go smoothly). The work of the
tangential forces (their damping, the slip and what the landing foot's tangential spring holds at
the end) is reported.

**Start: the trailing foot's preload.** At the heel strike the trailing foot carries the rolling
model's contact force F (from the rolling equations of motion: ``F = sum_i m_i a_i - m g``), so
its springs start loaded with it: ``delta_0 = F_z / k`` and ``s_0`` such that ``F_t`` is F's
tangential part; the walker is lowered by ``delta_0`` (both feet then touch at that depth, O(tau^2)),
and its velocities are the rolling model's (the trailing foot's material point at rest). Without
the preload the trailing foot would start unloaded and drop under the walker's weight: a spurious
O(1) transient, since its spring force, not the rigid constraint, must hold the weight.

**End and projection.** The phase lasts a fixed ``span`` time constants from touchdown (fixed, so
that the whole map is one CasADi function with an exact AD Jacobian); the result says whether the
trailing foot has left the ramp by then (:attr:`CompliantStrike.trailing_left`). Its end state is
projected onto the rolling model with the landing foot as stance by the seed's plastic law applied
to what is left: an impulse at the landing foot's material contact point that removes its residual
velocity (a plastic constraint: Carnot's theorem, kinetic energy is lost), the configuration
kept. Then relabel and mirror as ``collision`` does.

Reference: Todorov, Erez & Tassa, "MuJoCo: a physics engine for model-based control", IROS 2012,
doi:10.1109/IROS.2012.6386109 (the contact parameterisation, its documentation's "solref").
"""

from __future__ import annotations

import dataclasses
import math
from functools import cache

import casadi as ca
import numpy as np

from .effects.soft import FRICTION, ZETA
from .equations import build_functions, layout, mirror_relabel, symbolic
from .parameters import INPUT_NAMES, N_INPUT, Params, view

__all__ = ["TAU_LINEAR", "CompliantStrike", "SoftContact", "collocation_strike", "compliant_strike",
           "phase_functions", "phase_path", "step_functions"]

#: The phase's default length in contact time constants after touchdown. A critically damped
#: landing settles as (1 + t / tau) exp(-t / tau): 5e-4 of its touchdown rate is left after 10 tau.
SPAN = 10
#: Default integration steps per contact time constant: the contact's natural period is
#: 2 pi tau zeta, about 125 RK4 steps at zeta = 1 (docs/soft_feet.md gives the measured error).
STEPS_PER_TAU = 20
#: Below this contact time constant (s) the collocation transcription's heel strike
#: (:func:`collocation_strike`) is the secant from the rigid strike (tau = 0) to the phase at
#: TAU_LINEAR, so that it is defined, and differentiable, down to tau = 0, where the phase's
#: stiffness 1 / tau^2 is not. Its slope there is the one-sided derivative at 0+ to a few parts in
#: 1e4 (measured on the clearing toy's strike: the secant's largest component 870.93 per s at
#: 1e-5 s, 870.75 at 2e-5 s, 856.8 at 1e-3 s).
TAU_LINEAR = 1e-5


@dataclasses.dataclass(frozen=True)
class SoftContact:
    """The feet's contact with the ramp (module docstring), MuJoCo's ``solref`` and a friction.

    Attributes
    ----------
    tau : float
        Contact time constant (s), > 0.
    zeta : float
        Damping ratio, > 0 (1: critically damped, a plastic landing).
    friction : float
        Coulomb friction coefficient mu, > 0; large values approach rolling without slip.
    """

    tau: float
    zeta: float = 1.0
    friction: float = 1.0

    def __post_init__(self):
        for name in ("tau", "zeta", "friction"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"SoftContact.{name} must be a finite number > 0, got {value!r}")

    def vector(self) -> np.ndarray:
        """``(tau, zeta, friction)``, the phase functions' contact input, shape (3,)."""
        return np.array([self.tau, self.zeta, self.friction], dtype=float)


@dataclasses.dataclass
class _Free:
    """The free walker's symbolic quantities (one system, 3D or planar).

    ``y`` is the phase state ``(X, q, V, u, s1, s2, W_n, W_t, I_1, I_2)``: foot centre O1 (m), the
    rolling model's coordinates, their rates, the two feet's tangential anchors (m), the work of the
    normal and tangential contact forces (J) and the two feet's normal impulses (N s); foot 1 is the
    trailing (old stance) foot, foot 2 the landing one.
    """

    planar: bool
    y: ca.SX
    q: ca.SX
    u: ca.SX
    p: ca.SX
    kc: ca.SX
    big_q: ca.SX
    big_u: ca.SX
    mass: ca.SX
    forcing: ca.SX
    energy: ca.SX
    delta: ca.SX
    v_mat: tuple[ca.SX, ca.SX]
    anchors: tuple[ca.SX, ca.SX]
    foot2: ca.SX
    rigid_force: ca.SX
    rigid_u: ca.SX
    o1: ca.SX


def _tangential(planar: bool) -> list[int]:
    """The ramp-plane components of a vector in S that the system moves in."""
    return [0] if planar else [0, 1]


@cache
def _free(planar: bool) -> _Free:
    """Build (once) the free walker's mass matrix, forcing, energy and contact kinematics."""
    sym = symbolic(planar, effects=False)
    q, u, p, e = sym.q, sym.u, sym.p, sym.exprs
    n_x = 2 if planar else 3
    n_t = n_x - 1
    big_x, big_v = ca.SX.sym("X", n_x), ca.SX.sym("V", n_x)
    anchors = (ca.SX.sym("s1", n_t), ca.SX.sym("s2", n_t))
    quad = ca.SX.sym("quad", 4)
    y = ca.vertcat(big_x, q, big_v, u, *anchors, quad)
    kc = ca.SX.sym("kc", 5)  # (k1, c1, k2, c2, mu): stiffness (N/m), damping (N s/m), friction
    big_q, big_u = ca.vertcat(big_x, q), ca.vertcat(big_v, u)
    x3 = ca.vertcat(big_x[0], 0, big_x[1]) if planar else big_x

    def at(point):  # absolute position in S of a point given relative to the stance contact
        return x3 + point - e["o1"]

    def velocity(point):
        return ca.mtimes(ca.jacobian(at(point), big_q), big_u)

    par = sym.ctx.params
    m, mh, gvec = par.leg_mass, par.axle_mass, e["gvec"]
    # Kane's equations with speeds U = dQ/dt (docs/model.md section 3, the rolling model's form).
    mass = ca.SX.zeros(n_x + sym.lay.nq, n_x + sym.lay.nq)
    forcing = ca.SX.zeros(n_x + sym.lay.nq, 1)
    potential = ca.SX(0)
    for point, mass_i in ((e["g1"], m), (e["g2"], m), (e["axle"], mh)):
        v = velocity(point)
        jac = ca.jacobian(v, big_u)
        mass += mass_i * ca.mtimes(jac.T, jac)
        forcing -= mass_i * ca.mtimes(jac.T, ca.mtimes(ca.jacobian(v, big_q), big_u) - gvec)
        potential -= mass_i * ca.dot(gvec, at(point))
    for omega, iw in ((e["w1"], e["i1"]), (e["w2"], e["i2"])):
        jac = ca.jacobian(omega, big_u)
        mass += ca.mtimes(ca.mtimes(jac.T, iw), jac)
        forcing -= ca.mtimes(jac.T, ca.mtimes(iw, ca.mtimes(ca.jacobian(omega, big_q), big_u))
                             + ca.cross(omega, ca.mtimes(iw, omega)))
    kinetic = 0.5 * ca.dot(big_u, ca.mtimes(mass, big_u))
    # The feet's material points at their lowest points: v = v_O + omega x (C - O).
    v_o2 = velocity(e["o2"])
    v_mat1 = (ca.vertcat(big_v[0], 0, big_v[1]) if planar else big_v) + ca.cross(e["w1"], -e["o1"])
    v_mat2 = v_o2 + ca.cross(e["w2"], e["c2"] - e["o2"])
    delta = -ca.vertcat(at(ca.SX.zeros(3))[2], at(e["c2"])[2])
    # The rolling model's contact force on the stance foot: F = sum_i m_i a_i - m g (Newton),
    # a_i = J_i du/dt + (d(J_i u)/dq) u along its own equations of motion.
    udot = ca.solve(e["mass_matrix"], e["forcing"])
    force = -(2 * m + mh) * gvec
    for v, mass_i in ((e["v_g1"], m), (e["v_g2"], m), (e["v_axle"], mh)):
        force += mass_i * (ca.mtimes(ca.jacobian(v, u), udot) + ca.mtimes(ca.jacobian(v, q), u))
    return _Free(planar=planar, y=y, q=q, u=u, p=p, kc=kc, big_q=big_q, big_u=big_u, mass=mass,
                 forcing=forcing, energy=kinetic + potential, delta=delta, v_mat=(v_mat1, v_mat2),
                 anchors=anchors, foot2=at(e["c2"]), rigid_force=force,
                 rigid_u=ca.vertcat(ca.cross(e["w1"], e["o1"])[[0, 2] if planar else [0, 1, 2]], u),
                 o1=e["o1"])


def _contact_forces(fr: _Free) -> tuple[list[ca.SX], list[ca.SX]]:
    """Each foot's normal force N (N) and tangential force (N, shape (n_t,)), the laws of the
    module docstring, from the phase state and the contact constants."""
    comps = _tangential(fr.planar)
    mu = fr.kc[4]
    normals, tangentials = [], []
    for i in range(2):
        k, c = fr.kc[2 * i], fr.kc[2 * i + 1]
        delta = fr.delta[i]
        rate = -fr.v_mat[i][2]
        normal = ca.if_else(delta > 0, ca.fmax(0, k * delta + c * rate), 0)
        raw = -(k * fr.anchors[i] + c * fr.v_mat[i][comps])
        limit = mu * normal
        # 1e-300 N^2 keeps 0/0 away when a foot is off the ramp with its anchor relaxed; it is
        # below any force squared this model meets by more than 200 orders of magnitude.
        tangentials.append(raw * limit / ca.sqrt(limit**2 + ca.sumsqr(raw) + 1e-300))
        normals.append(normal)
    return normals, tangentials


def _rate(fr: _Free) -> ca.SX:
    """d y / dt of the phase state (:class:`_Free`)."""
    comps = _tangential(fr.planar)
    normals, tangentials = _contact_forces(fr)
    generalised = fr.forcing
    power_n, power_t = ca.SX(0), ca.SX(0)
    for i in range(2):
        force = ca.SX.zeros(3)
        force[comps] = tangentials[i]
        force[2] = normals[i]
        generalised += ca.mtimes(ca.jacobian(fr.v_mat[i], fr.big_u).T, force)
        power_n += normals[i] * fr.v_mat[i][2]
        power_t += ca.dot(tangentials[i], fr.v_mat[i][comps])
    udot = ca.solve(fr.mass, generalised)
    return ca.vertcat(fr.big_u, udot, fr.v_mat[0][comps], fr.v_mat[1][comps], power_n, power_t,
                      normals[0], normals[1])


def _effective_masses(fr: _Free) -> ca.SX:
    """The feet's effective masses along the normal, ``1 / (J M^-1 J')`` (kg, shape (2,))."""
    out = []
    for v in fr.v_mat:
        jac = ca.jacobian(v[2], fr.big_u)
        out.append(1 / ca.mtimes(jac, ca.solve(fr.mass, jac.T)))
    return ca.vertcat(*out)


def _start(fr: _Free, lay) -> tuple[ca.SX, ca.SX, ca.SX, ca.SX]:
    """The symbols ``x`` (rigid state at touchdown) and ``c`` (contact), and as expressions of them
    the phase's start state ``y0`` and contact constants ``kc`` (module docstring, "Start")."""
    comps = _tangential(fr.planar)
    x = ca.SX.sym("x", lay.nx)
    c = ca.SX.sym("c", 3)
    tau, zeta, mu = c[0], c[1], c[2]
    q, u, travel = x[:lay.nq], x[lay.nq:lay.n_dyn], x[lay.n_dyn:]

    def rolling(expr):
        return ca.substitute([expr], [fr.q, fr.u], [q, u])[0]

    m_eff = rolling(_effective_masses(fr))
    stiff, damp = m_eff / (tau * zeta) ** 2, 2 * m_eff / tau
    force = rolling(fr.rigid_force)
    delta0 = force[2] / stiff[0]
    limit = mu * force[2]
    f_t = force[comps]
    anchor1 = -f_t * limit / ca.sqrt(limit**2 - ca.sumsqr(f_t)) / stiff[0]
    o1 = rolling(fr.o1)
    big_x = ca.vertcat(travel + o1[comps], o1[2] - delta0)  # O1 = C + (O1 - C), lowered
    y0 = ca.vertcat(big_x, q, rolling(fr.rigid_u), anchor1, ca.SX.zeros(len(comps) + 4))
    kc = ca.vertcat(stiff[0], damp[0], stiff[1], damp[1], mu)
    return x, c, y0, kc


def _projection(fr: _Free, lay) -> tuple[ca.SX, ca.SX, ca.SX]:
    """The rolling model's state (relabelled, mirrored) from the phase's end state, the kinetic
    energy change of the plastic projection (J, <= 0) and its impulse's normal component at the
    landing foot (N s)."""
    comps = _tangential(fr.planar)
    n_x = len(comps) + 1
    rows = [0, 2] if fr.planar else [0, 1, 2]
    jac = ca.jacobian(fr.v_mat[1][rows], fr.big_u)
    m_inv_jt = ca.solve(fr.mass, jac.T)
    impulse = -ca.solve(ca.mtimes(jac, m_inv_jt), ca.mtimes(jac, fr.big_u))
    u_after = fr.big_u + ca.mtimes(m_inv_jt, impulse)
    # Carnot: the kinetic energy change is -(J U)' (J M^-1 J')^-1 (J U) / 2 = impulse . (J U) / 2.
    d_kinetic = 0.5 * ca.dot(impulse, ca.mtimes(jac, fr.big_u))
    q = fr.big_q[n_x:]
    x_plus = ca.vertcat(mirror_relabel(lay, q, u_after[n_x:]), fr.foot2[comps])
    return x_plus, d_kinetic, impulse[-1]


@cache
@cache
def phase_functions(planar: bool, steps_per_tau: int = STEPS_PER_TAU,
                    span: int = SPAN) -> dict[str, ca.Function]:
    """CasADi functions of the compliant heel strike of one system (3D or planar).

    Parameters
    ----------
    planar : bool
        The planar reduction (docs/model.md section 7).
    steps_per_tau : int
        Fixed RK4 steps per contact time constant.
    span : int
        The phase's length in contact time constants.

    Returns
    -------
    dict of ca.Function
        ``strike(x, p, c) -> (x_plus, ys, kc, dK)``: the map; ``x`` the rigid model's internal state
        at the heel strike (as ``collision`` takes it, shape (nx,)), ``p`` the parameter input
        (N_INPUT), ``c`` the contact ``(tau, zeta, mu)`` (:meth:`SoftContact.vector`); ``x_plus``
        as ``collision`` gives it (relabelled, mirrored, travel at the new contact point, old
        frame), ``ys`` the phase states on the grid (ny, n + 1), ``kc`` the contact constants
        ``(k1, c1, k2, c2, mu)`` (N/m, N s/m) and ``dK`` the projection's kinetic energy change (J).
        ``start(x, p, c) -> (y0, kc)`` and ``project(y, p) -> (x_plus, dK)``: the map's first and
        last parts (so ``project(start(x))`` is the strike with no phase at all).
        ``forces(y, p, kc) -> (N, F_t, delta)``: normal forces (2,), tangential forces
        (n_t, 2) and penetrations (2,) at one phase state. ``energy(y, p) -> E``: kinetic plus
        gravitational energy of the free walker (J).
    """
    if steps_per_tau < 1 or span < 1:
        raise ValueError(f"steps_per_tau and span must be >= 1, got {steps_per_tau!r}, {span!r}")
    lay = layout(planar)
    fr = _free(planar)
    n_steps = steps_per_tau * span
    flow = _rk4(fr).mapaccum("flow", n_steps)
    x, c, y0, kc = _start(fr, lay)
    start = ca.Function("start", [x, fr.p, c], [y0, kc])
    x_plus, d_kinetic, _ = _projection(fr, lay)
    project = ca.Function("project", [fr.y, fr.p], [x_plus, d_kinetic])
    xm, pm, cm = ca.MX.sym("x", lay.nx), ca.MX.sym("p", fr.p.numel()), ca.MX.sym("c", 3)
    y0m, kcm = start(xm, pm, cm)
    ys = flow(y0m, pm, kcm, cm[0] * span / n_steps)
    xp, dk = project(ys[:, -1], pm)
    normals, tangentials = _contact_forces(fr)
    return {
        "strike": ca.Function("strike", [xm, pm, cm], [xp, ca.horzcat(y0m, ys), kcm, dk],
                              ["x", "p", "c"], ["x_plus", "ys", "kc", "dK"]),
        "start": start,
        "project": project,
        "forces": ca.Function("forces", [fr.y, fr.p, fr.kc],
                              [ca.vertcat(*normals), ca.horzcat(*tangentials), fr.delta],
                              ["y", "p", "kc"], ["N", "F_t", "delta"]),
        "energy": ca.Function("energy", [fr.y, fr.p], [fr.energy], ["y", "p"], ["E"]),
    }


def _rk4(fr: _Free, sym=ca.SX, opts: dict | None = None) -> ca.Function:
    """One classical Runge-Kutta step of the phase state, ``rk4(y, p, kc, h) -> y_next``: with
    ``sym`` SX the rate is expanded in it four times, with MX it is called (and ``opts`` given to
    it, to the step's too)."""
    opts = opts or {}
    rate = ca.Function("rate", [fr.y, fr.p, fr.kc], [_rate(fr)], opts)
    y, p, kc = (fr.y, fr.p, fr.kc) if sym is ca.SX else (
        ca.MX.sym("y", fr.y.sparsity()), ca.MX.sym("p", fr.p.sparsity()), ca.MX.sym("kc", 5))
    h = sym.sym("h")
    k1 = rate(y, p, kc)
    k2 = rate(y + 0.5 * h * k1, p, kc)
    k3 = rate(y + 0.5 * h * k2, p, kc)
    k4 = rate(y + h * k3, p, kc)
    return ca.Function("rk4", [y, p, kc, h], [y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)], opts)


#: Derivative directions per generated derivative function of the step map's phase: 1 keeps
#: the generated code to one adjoint of each piece (the 3D walker's x_plus has 10 rows).
_DIRS = {"max_num_dir": 1}


def step_functions(planar: bool, steps_per_tau: int = STEPS_PER_TAU,
                   span: int = SPAN) -> dict[str, ca.Function]:
    """The compliant heel strike as the step map uses it (the ``soft_heel`` effect,
    :mod:`toywalk.model.effects.soft`): functions of the rolling model's state at the heel strike
    and the parameter input alone, the contact's time constant read from the input
    (``effects.soft_heel``, > 0) and its damping ratio and friction the effect's constants.

    The phase's ``steps_per_tau * span`` RK4 steps are one step function folded (``fold``), so the
    generated code holds one step and its derivatives, not ``steps_per_tau * span`` copies.

    Parameters
    ----------
    planar : bool
        The planar reduction.
    steps_per_tau, span : int
        As for :func:`phase_functions`.

    Returns
    -------
    dict of ca.Function
        ``soft_strike(x, p) -> (x_plus, T, dE, lambda, K)``: ``x`` the rolling model's internal
        state at the heel strike (as ``collision`` takes it), ``p`` the parameter input (N_INPUT);
        ``x_plus`` as ``collision`` gives it; ``T`` the phase's duration (s); ``dE`` the rolling
        model's energy (kinetic and gravitational with the contact travel) after the strike less
        that before it (J; the phase's work against gravity included); ``lambda`` the normal
        impulses at the landing foot (the phase's and the projection's) and at the trailing foot
        (N s); ``K`` the kinetic energy before the strike (J).
        ``soft_strike_jac(x, p) -> (x_plus, C_x, C_p)``: with ``x_plus``'s Jacobians by AD.
    """
    lay = layout(planar)
    fr = _free(planar)
    n_steps = steps_per_tau * span
    flow = _rk4(fr, ca.MX, _DIRS).fold(n_steps)
    x, c, y0, kc = _start(fr, lay)
    start = ca.Function("start", [x, fr.p, c], [y0, kc], _DIRS)
    x_plus, d_kinetic, normal = _projection(fr, lay)
    project = ca.Function("project", [fr.y, fr.p], [x_plus, d_kinetic, normal], _DIRS)
    rolling = build_functions(planar, effects=False)
    # One symbol for the state and the parameters, so that x_plus's Jacobian with respect to
    # both is one reverse sweep (nx adjoint directions) rather than forward sweeps over nx +
    # N_INPUT directions: the generated code holds one adjoint of the RK4 step.
    xp_in = ca.MX.sym("xp", lay.nx + N_INPUT)
    xm, pm = xp_in[:lay.nx], xp_in[lay.nx:]
    tau = view(pm).effects["soft_heel"]
    y0m, kcm = start(xm, pm, ca.vertcat(tau, ZETA, FRICTION))
    y_end = flow(y0m, pm, kcm, tau * span / n_steps)
    xp, _, normal_end = project(y_end, pm)
    d_energy = rolling["energy"](xp, pm) - rolling["energy"](xm, pm)
    impulses = ca.vertcat(y_end[-1] + normal_end, y_end[-2])
    kinetic = rolling["impact"](xm, pm)[2]
    jac = ca.jacobian(xp, xp_in)
    x_in, p_in = ca.MX.sym("x", lay.nx), ca.MX.sym("p", N_INPUT)
    strike = ca.Function("strike", [xp_in], [xp, span * tau, d_energy, impulses, kinetic])
    strike_jac = ca.Function("strike_jac", [xp_in], [xp, jac[:, :lay.nx], jac[:, lay.nx:]])
    both = ca.vertcat(x_in, p_in)
    return {
        "soft_strike": ca.Function("soft_strike", [x_in, p_in], strike(both),
                                   ["x", "p"], ["x_plus", "T", "dE", "lambda", "K"]),
        "soft_strike_jac": ca.Function("soft_strike_jac", [x_in, p_in], strike_jac(both),
                                       ["x", "p"], ["x_plus", "C_x", "C_p"]),
    }


def collocation_strike(planar: bool, steps_per_tau: int = STEPS_PER_TAU,
                       span: int = SPAN) -> ca.Function:
    """The heel strike of the gait's collocation transcription with ``effects.soft_heel`` free or
    on (:func:`toywalk.model.collocation.bvp`): ``soft_link(x, p) -> x_plus``, as ``collision``
    takes and gives them (internal state at the heel strike, shape (nx,); parameter input).

    For ``tau >= TAU_LINEAR`` it is the compliant strike of :func:`step_functions`, the one the
    step map takes. Below, the secant ``C(x) + (tau / TAU_LINEAR) (S(x, TAU_LINEAR) - C(x))`` from
    the rigid strike ``C`` (tau = 0, the seed's law, which the phase converges to at first order:
    docs/soft_feet.md section 2): it equals the rigid strike at 0, where the phase has no
    finite stiffness, and its derivative in tau there is the phase's one-sided derivative at 0+ to
    within the secant's error (:data:`TAU_LINEAR`), which a score test of the effect at its null
    needs. Between 0 and TAU_LINEAR it differs from the step map's strike by O(tau TAU_LINEAR).
    """
    phase = step_functions(planar, steps_per_tau, span)["soft_strike"]
    rigid = build_functions(planar, effects=False)["collision"]
    lay = layout(planar)
    x, p = ca.MX.sym("x", lay.nx), ca.MX.sym("p", N_INPUT)
    tau = view(p).effects["soft_heel"]
    unit = np.zeros(N_INPUT)
    unit[INPUT_NAMES.index("effects.soft_heel")] = 1.0
    at_least = ca.fmax(tau, TAU_LINEAR)
    soft = phase(x, p + (at_least - tau) * ca.DM(unit))[0]
    hard = rigid(x, p)
    return ca.Function("soft_link", [x, p], [hard + ca.fmin(tau / TAU_LINEAR, 1.0) * (soft - hard)],
                       ["x", "p"], ["x_plus"])


def phase_path(params: Params, x_minus: np.ndarray, planar: bool = False,
               side: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The walker's angles and rates through the step map's compliant heel strike
    (``effects.soft_heel`` > 0, its damping ratio and friction the effect's constants), as
    :func:`toywalk.model.simulate.simulate` samples them inside the phase.

    Returns
    -------
    times : ndarray, shape (n + 1,)
        From touchdown (s), over the phase's ``SPAN`` time constants.
    states : ndarray, shape (n + 1, nx)
        The rolling model's internal state with the free walker's angles and rates (the old
        stance's description, as ``x_minus``), the contact travel zero.
    """
    tau = params.effects.get("soft_heel", 0.0)
    if not tau > 0:
        raise ValueError(f"phase_path needs effects.soft_heel > 0, got {tau!r}")
    lay = layout(planar)
    fns = phase_functions(planar)
    _, ys, _, _ = fns["strike"](np.asarray(x_minus, float), params.input_vector(float(side)),
                                [tau, ZETA, FRICTION])
    ys = ys.full().T
    n_x, n_q = (2 if planar else 3), lay.n_dyn // 2
    q, u = ys[:, n_x:n_x + n_q], ys[:, 2 * n_x + n_q:2 * n_x + 2 * n_q]
    states = np.hstack([q, u, np.zeros((len(ys), lay.nx - lay.n_dyn))])
    return np.linspace(0.0, SPAN * tau, len(ys)), states


@dataclasses.dataclass
class CompliantStrike:
    """One compliant heel strike (:func:`compliant_strike`). Foot 1 is the trailing (old stance)
    foot, foot 2 the landing one; time series are (n_times, n_signals), n = steps_per_tau * span.

    Attributes
    ----------
    x_plus : ndarray, shape (nx,)
        The rolling model's internal state after the strike, as ``collision`` gives it.
    duration : float
        The phase's length (s): ``span`` contact time constants.
    times : ndarray, shape (n + 1,)
        Sample times from touchdown (s).
    states : ndarray, shape (n + 1, ny)
        Phase states (``X, q, V, u, s1, s2, W_n, W_t, I_1, I_2``; module docstring).
    normal_forces, tangential_forces, penetrations : ndarray, shape (n + 1, 2)
        Each foot's normal force (N), the magnitude of its tangential force (N) and its
        penetration (m, negative when off the ramp).
    impulses : ndarray, shape (2,)
        Each foot's normal impulse over the phase (N s).
    peak_normal, peak_tangential : ndarray, shape (2,)
        The largest sampled forces (N).
    friction_used : float
        The landing foot's |F_t| / N at its peak normal force: the friction the strike needs there
        (the friction coefficient caps it; module docstring). A foot being unloaded always reaches
        the cap as N goes to 0, so the ratio over the whole phase says nothing.
    trailing_left : bool
        The trailing foot is off the ramp (no force, no penetration) at the phase's end: the
        projection, which ignores it, is then consistent.
    trailing_lift_off : float
        The first sample time at which the trailing foot carries no load (s).
    landing_rebounds : bool
        The landing foot lost its load at some sample of the phase (a rebound; module docstring).
    energy : dict of str to float
        Energies (J): ``mechanical``, the free walker's kinetic plus gravitational energy change
        over the phase; ``normal_work`` and ``tangential_work``, the contact forces' work (their
        integrated power); ``elastic``, the normal springs' stored energy, end minus start;
        ``damping``, the normal contact's dissipation ``-normal_work - elastic``; ``tangential``,
        ``-tangential_work`` (tangential damping, slip, the landing foot's tangential spring at
        the end); ``projection``, the kinetic energy the final plastic projection removes (>= 0);
        ``balance``, ``mechanical - normal_work - tangential_work``, zero up to the integrator's
        error.
    """

    x_plus: np.ndarray
    duration: float
    times: np.ndarray
    states: np.ndarray
    normal_forces: np.ndarray
    tangential_forces: np.ndarray
    penetrations: np.ndarray
    impulses: np.ndarray
    peak_normal: np.ndarray
    peak_tangential: np.ndarray
    friction_used: float
    trailing_left: bool
    trailing_lift_off: float
    landing_rebounds: bool
    energy: dict[str, float]


def compliant_strike(params: Params, x_minus: np.ndarray, contact: SoftContact, planar: bool = False,
                     side: int = 1, steps_per_tau: int = STEPS_PER_TAU, span: int = SPAN) -> CompliantStrike:
    """Resolve the heel strike at ``x_minus`` on soft feet (module docstring).

    Parameters
    ----------
    params : Params
        The walker; its effects must be at their null values (the phase models the seed's walker;
        the effects enter with the phase's wiring into the step map).
    x_minus : ndarray, shape (nx,)
        The rolling model's internal state at the heel strike (:class:`toywalk.model.Walker`'s
        ``full_state`` of ``Step.z_minus``), as ``collision`` takes it.
    contact : SoftContact
    planar : bool
        The planar reduction.
    side : {1, -1}
        The physical leg in stance (see :meth:`toywalk.model.Walker.step`).
    steps_per_tau, span : int
        RK4 steps per time constant and the phase's length in time constants.

    Raises
    ------
    ValueError
        For an effect not at its null value, a state of the wrong shape or not finite, or a
        trailing foot whose rolling contact force lies outside the friction cone (or pulls).
    """
    if params.active_effects:
        raise ValueError(f"compliant_strike models the seed's walker: set the effects "
                         f"{', '.join(params.active_effects)} to their null values")
    lay = layout(planar)
    x = np.asarray(x_minus, dtype=float)
    if x.shape != (lay.nx,) or not np.all(np.isfinite(x)):
        raise ValueError(f"x_minus must be a finite internal state of shape ({lay.nx},), got shape {x.shape}")
    if not isinstance(contact, SoftContact):
        raise TypeError(f"contact must be a SoftContact, got {type(contact).__name__}")
    fns = phase_functions(planar, steps_per_tau, span)
    p = params.input_vector(float(side))
    x_plus, ys, kc, d_kinetic = (a.full() for a in fns["strike"](x, p, contact.vector()))
    ys = ys.T
    if not np.all(np.isfinite(ys)):
        raise ValueError("the trailing foot's rolling contact force at x_minus pulls or needs more friction "
                         f"than contact.friction = {contact.friction!r}")
    kc = kc.ravel()
    normal, tangential, delta = (np.zeros((len(ys), 2)) for _ in range(3))
    for i, y in enumerate(ys):
        n_i, t_i, d_i = fns["forces"](y, p, kc)
        normal[i], delta[i] = n_i.full().ravel(), d_i.full().ravel()
        tangential[i] = np.linalg.norm(t_i.full(), axis=0)
    duration = span * contact.tau
    times = np.linspace(0.0, duration, len(ys))
    peak = int(np.argmax(normal[:, 1]))
    off = np.flatnonzero(normal[:, 0] == 0.0)
    energy_fn = fns["energy"]
    mechanical = float(energy_fn(ys[-1], p).full()[0, 0] - energy_fn(ys[0], p).full()[0, 0])
    stiff = kc[[0, 2]]
    elastic = float(0.5 * stiff @ (np.maximum(delta[-1], 0) ** 2 - np.maximum(delta[0], 0) ** 2))
    w_n, w_t = float(ys[-1, -4]), float(ys[-1, -3])
    energy = dict(mechanical=mechanical, normal_work=w_n, tangential_work=w_t, elastic=elastic,
                  damping=-w_n - elastic, tangential=-w_t, projection=-float(d_kinetic[0, 0]),
                  balance=mechanical - w_n - w_t)
    return CompliantStrike(
        x_plus=x_plus.ravel(), duration=duration, times=times, states=ys,
        normal_forces=normal, tangential_forces=tangential, penetrations=delta,
        impulses=ys[-1, -2:].copy(), peak_normal=normal.max(axis=0), peak_tangential=tangential.max(axis=0),
        friction_used=float(tangential[peak, 1] / normal[peak, 1]),
        trailing_left=bool(normal[-1, 0] == 0.0 and delta[-1, 0] <= 0.0),
        trailing_lift_off=float(times[off[0]]) if len(off) else math.nan,
        landing_rebounds=bool(np.any(normal[1:, 1] == 0.0)), energy=energy)
