"""Symbolic kinematics, equations of motion, energy, guard and collision of the 3D walker.

Everything is derived once, symbolically, in CasADi SX (docs/model.md sections 1-4), with every physical
quantity a symbolic input (the parameter input of :data:`toywalk.model.parameters.INPUT_NAMES`:
the parameter vector with every effect's strength, and the side in stance), so that one compiled
function serves every parameter set, foot shape and combination of effects. Each effect of
:mod:`toywalk.model.effects` contributes its own terms through its hooks; ``effects=False`` builds
the seed's model alone (for the benchmarks and the null checks), with the same inputs.

Conventions (docs/model.md section 1): slope frame S with x downhill, y left, z along the ramp normal;
stance-leg orientation ``Rz(phi) Rx(psi) Ry(theta_st)``, swing leg ``Rz(phi) Rx(psi) Ry(theta_sw)``.
The stance leg is always described as the left leg (its balance mass on the +b2 side); the swing leg
is its mirror image. Generalised coordinates ``q = (phi, psi, theta_st, theta_sw)`` and speeds
``u = dq/dt``. The internal state is ``x = (q, u, x_C, y_C)`` (shape (10,)), the last two the stance
contact point's travel on the ramp. The planar system (``phi = psi = 0`` held, docs/model.md section 7)
has ``q = (theta_st, theta_sw)`` and ``x = (q, u, x_C)`` with y_C = 0 omitted, shape (5,); see
:class:`Layout`.

Equations of motion by Kane's method (Kane & Levinson, *Dynamics: Theory and Applications*, 1985):
velocities of the centres of mass and angular velocities are linear in u with the rolling constraint
built in (``v_P = omega_1 x (P - C)`` for points of the stance leg, the material contact point being
at rest), and ``sum_i J_i^T m_i (a_i - g) + W_i^T (I_i alpha_i + omega_i x I_i omega_i) = 0`` gives
``M(q) du/dt = f(q, u)``. The collision follows the seed's jump conditions (Coleman & Ruina 1998,
eqs. 3-4): angular momentum of the whole system about the new contact point D, and of the trailing
leg about the hip axis through its hip point, conserved.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import casadi as ca

from .effects import CONTINUOUS, EFFECTS, Context
from .parameters import N_INPUT, view

__all__ = ["Layout", "Symbolic", "build_functions", "layout", "mirror_relabel", "symbolic"]


@dataclasses.dataclass(frozen=True)
class Layout:
    """Where things sit in the internal state vector of one system (3D or planar).

    Attributes
    ----------
    planar : bool
        True for the planar reduction (phi = psi = 0 held).
    nq : int
        Number of generalised coordinates (4 or 2).
    nx : int
        Internal state size: q, u and the contact travel (10 or 5).
    """

    planar: bool
    nq: int
    nx: int

    @property
    def n_dyn(self) -> int:
        """Size of the dynamic state (q, u), without the contact travel."""
        return 2 * self.nq


@cache
def layout(planar: bool) -> Layout:
    """The :class:`Layout` of the 3D (``planar=False``) or planar system."""
    return Layout(planar=planar, nq=2 if planar else 4, nx=5 if planar else 10)


def _rz(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def _rx(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))


def _ry(a: ca.SX) -> ca.SX:
    c, s = ca.cos(a), ca.sin(a)
    return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))


def _inertia_matrix(i: ca.SX, mirror: bool) -> ca.SX:
    """Body-frame inertia tensor from (xx, yy, zz, xy, xz, yz); the mirror leg negates xy and yz."""
    sgn = -1 if mirror else 1
    ixx, iyy, izz, ixy, ixz, iyz = (i[k] for k in range(6))
    return ca.vertcat(
        ca.horzcat(ixx, sgn * ixy, ixz),
        ca.horzcat(sgn * ixy, iyy, sgn * iyz),
        ca.horzcat(ixz, sgn * iyz, izz),
    )


@dataclasses.dataclass
class Symbolic:
    """The walker's symbolic expressions for one system (3D or planar).

    Positions are relative to the stance contact point C, in the slope frame, shape (3, 1).
    """

    lay: Layout
    q: ca.SX
    u: ca.SX
    p: ca.SX
    exprs: dict[str, ca.SX]
    ctx: Context
    effects: bool


def _geometry(ctx: Context, effects: bool) -> dict[str, ca.SX]:
    """Positions of the walker's points relative to the stance contact C, and orientations."""
    phi, psi, th1, th2 = (ctx.q4[k] for k in range(4))
    par = ctx.params
    l, r, rho, w = par.leg_length, par.foot_radius, par.foot_lateral_radius, par.hip_width
    d = par.com_offset
    ez = ca.SX([0, 0, 1])
    ey = ca.SX([0, 1, 0])
    rzx = ca.mtimes(_rz(phi), _rx(psi))
    r1 = ca.mtimes(rzx, _ry(th1))
    r2 = ca.mtimes(rzx, _ry(th2))
    n = ca.mtimes(rzx, ey)
    # Lowest point of the foot's rim circle: t = unit(-e_z + (e_z . n) n) (docs/model.md section 2).
    # Written as -e_z + n_z n over sqrt(1 - n_z^2) = |that vector|, which is smooth while |n_z| < 1.
    nz = n[2]
    t = (-ez + nz * n) / ca.sqrt(1 - nz**2)
    big_r = r - rho
    o_c = rho * ez - big_r * t  # foot centre O relative to contact point C (both feet share C - O)
    h1 = o_c + (l - r) * r1[:, 2]  # stance (left) hip point
    h2 = h1 - w * n  # swing (right) hip point
    axle = h1 - 0.5 * w * n
    d_st, d_sw = d, ca.vertcat(d[0], -d[1], d[2])  # the swing leg is the mirror image
    for effect in _effects(effects):
        d_st, d_sw = effect.com_offsets(par.effects[effect.name], ctx, d_st, d_sw)
    g1 = h1 + ca.mtimes(r1, d_st)
    g2 = h2 + ca.mtimes(r2, d_sw)
    o2 = h2 - (l - r) * r2[:, 2]
    c2 = o2 - o_c  # swing foot's lowest point (its contact point when it lands)
    return dict(r1=r1, r2=r2, n=n, t=t, o1=o_c, h1=h1, h2=h2, axle=axle, g1=g1, g2=g2, o2=o2, c2=c2)


def _effects(effects: bool):
    """The effect units the builder includes (all, or none for the seed's model)."""
    return tuple(EFFECTS.values()) if effects else ()


def _omegas(q4: ca.SX, u4: ca.SX) -> tuple[ca.SX, ca.SX]:
    phi, psi = q4[0], q4[1]
    ez = ca.SX([0, 0, 1])
    ex = ca.SX([1, 0, 0])
    ey = ca.SX([0, 1, 0])
    rz = _rz(phi)
    n = ca.mtimes(ca.mtimes(rz, _rx(psi)), ey)
    base = u4[0] * ez + u4[1] * ca.mtimes(rz, ex)
    return base + u4[2] * n, base + u4[3] * n


def _embed(lay: Layout, q: ca.SX) -> ca.SX:
    """Full (phi, psi, theta_st, theta_sw) from the system's own coordinates (zeros if planar)."""
    if lay.planar:
        return ca.vertcat(0, 0, q[0], q[1])
    return q


@cache
def symbolic(planar: bool, effects: bool = True) -> Symbolic:
    """Build (once) the symbolic expressions of the 3D or planar system.

    Parameters
    ----------
    planar : bool
        The planar reduction.
    effects : bool
        Include the effect library's terms (False: the seed's model, same inputs).
    """
    lay = layout(planar)
    q = ca.SX.sym("q", lay.nq)
    u = ca.SX.sym("u", lay.nq)
    p = ca.SX.sym("p", N_INPUT)
    par = view(p)
    q4, u4 = _embed(lay, q), _embed(lay, u)
    ctx = Context(planar=planar, params=par, side=par.side, q4=q4, u4=u4)
    geo = _geometry(ctx, effects)
    ctx.n = geo["n"]
    r, rho, m, mh = par.foot_radius, par.foot_lateral_radius, par.leg_mass, par.axle_mass
    alpha, grav = par.slope, par.gravity
    gvec = grav * ca.vertcat(ca.sin(alpha), 0, -ca.cos(alpha))
    for effect in _effects(effects):
        gvec = effect.gravity(par.effects[effect.name], ctx, gvec)
    w1, w2 = _omegas(q4, u4)
    ctx.w1, ctx.w2 = w1, w2

    # Velocities: stance-leg material points rotate about the contact point (rolling, no slip);
    # swing-leg points move with the hip plus the swing leg's rotation about it.
    v_h2 = ca.cross(w1, geo["h2"])
    v_g1 = ca.cross(w1, geo["g1"])
    v_axle = ca.cross(w1, geo["axle"])
    v_g2 = v_h2 + ca.cross(w2, geo["g2"] - geo["h2"])
    i1 = ca.mtimes(ca.mtimes(geo["r1"], _inertia_matrix(par.inertia, False)), geo["r1"].T)
    i2 = ca.mtimes(ca.mtimes(geo["r2"], _inertia_matrix(par.inertia, True)), geo["r2"].T)

    # Kane's equations: sum_i J_i^T m_i (a_i - g) + W_i^T (I_i alpha_i + w_i x I_i w_i) = Q,
    # with a_i = J_i du/dt + (d(J_i u)/dq) u, since dq/dt = u.
    mass_matrix = ca.SX.zeros(lay.nq, lay.nq)
    forcing = ca.SX.zeros(lay.nq, 1)
    for v, mass in ((v_g1, m), (v_g2, m), (v_axle, mh)):
        jac = ca.jacobian(v, u)
        mass_matrix += mass * ca.mtimes(jac.T, jac)
        forcing -= mass * ca.mtimes(jac.T, ca.mtimes(ca.jacobian(v, q), u) - gvec)
    for omega, iw in ((w1, i1), (w2, i2)):
        jac = ca.jacobian(omega, u)
        mass_matrix += ca.mtimes(ca.mtimes(jac.T, iw), jac)
        forcing -= ca.mtimes(
            jac.T, ca.mtimes(iw, ca.mtimes(ca.jacobian(omega, q), u)) + ca.cross(omega, ca.mtimes(iw, omega))
        )
    # The world-frame inertia I_i(q) changes with q; Kane's inertia torque uses d(I w)/dt =
    # I alpha + w x I w, which already accounts for that (body-fixed principal axes rotate with w).

    # Effects' couples: generalised forces by virtual work, Q = sum_legs W_leg^T M_leg, and each
    # continuous effect's dissipated power -sum_legs M_leg . omega_leg (one entry per CONTINUOUS).
    omegas = {1: w1, 2: w2}
    partials = {leg: ca.jacobian(omega, u) for leg, omega in omegas.items()}
    generalised = ca.SX.zeros(lay.nq, 1)
    dissipation = []
    for name in CONTINUOUS:
        power = ca.SX(0)
        if effects:
            for leg, couple in EFFECTS[name].couples(par.effects[name], ctx):
                generalised += ca.mtimes(partials[leg].T, couple)
                power -= ca.dot(couple, omegas[leg])
        dissipation.append(power)
    forcing += generalised

    # Contact-point travel on the ramp: dC/dt = v_O + (C - O)' with v_O = w1 x (O - C).
    big_r = r - rho
    c_minus_o = big_r * geo["t"] - rho * ca.SX([0, 0, 1])
    c_dot = ca.cross(w1, geo["o1"]) + ca.mtimes(ca.jacobian(c_minus_o, q), u)

    kinetic = 0.5 * (m * ca.dot(v_g1, v_g1) + m * ca.dot(v_g2, v_g2) + mh * ca.dot(v_axle, v_axle))
    kinetic += 0.5 * (ca.dot(w1, ca.mtimes(i1, w1)) + ca.dot(w2, ca.mtimes(i2, w2)))
    # Potential relative to C; the contact travel term is added where the state has it.
    potential_rel = -ca.dot(gvec, m * geo["g1"] + m * geo["g2"] + mh * geo["axle"])

    exprs = dict(
        mass_matrix=mass_matrix,
        forcing=forcing,
        generalised=generalised,
        dissipation=ca.vertcat(*dissipation) if dissipation else ca.SX.zeros(0, 1),
        c_dot=c_dot,
        kinetic=kinetic,
        potential_rel=potential_rel,
        gvec=gvec,
        v_g1=v_g1,
        v_g2=v_g2,
        v_axle=v_axle,
        w1=w1,
        w2=w2,
        i1=i1,
        i2=i2,
        **geo,
    )
    return Symbolic(lay=lay, q=q, u=u, p=p, exprs=exprs, ctx=ctx, effects=effects)


def _collision_exprs(sym: Symbolic) -> dict[str, ca.SX]:
    """Post-collision speeds (old labels) and the impact's energy change and normal impulses.

    Unknowns u+ with the old swing leg (leg 2) rolling about D = c2. Conserved (seed eqs. 3-4):
    (a) the whole system's angular momentum about D, (b) the old stance leg's angular momentum about
    the hip axis through its hip point H1, both with absolute velocities. The planar system keeps
    the n-component of (a). Effects of the collision law add, to the same linear equations, a
    normal impulse ``lambda_C e_z`` at the trailing foot C (a share of the total normal impulse,
    itself linear in u+), and blend with the laws that also arrest rates of the landing leg
    (:class:`toywalk.model.effects.Arrest`; with several, every subset of them).

    Returns a dict: ``u_plus``; ``residual`` (the jump conditions as a function of ``up``, the
    symbol of trial post-collision speeds, with the effects' trailing impulse); ``up``;
    ``kinetic_before`` and ``energy_change`` (J, kinetic energy before, and after minus before);
    ``normal_impulses`` (N s, shape (2,): at the landing foot D and at the trailing foot C, along
    the ramp normal).
    """
    lay, q, e, ctx = sym.lay, sym.q, sym.exprs, sym.ctx
    par = ctx.params
    m, mh = par.leg_mass, par.axle_mass
    q4 = _embed(lay, q)
    ez = ca.SX([0, 0, 1])
    up = ca.SX.sym("u_plus", lay.nq)
    d = e["c2"]

    def velocities(u_trial):
        """After: leg 2 rolls about D; its hip H2 and the axle move with it; leg 1 swings about H1."""
        w1p, w2p = _omegas(q4, _embed(lay, u_trial))
        v_h1p = ca.cross(w2p, e["h1"] - d)
        return dict(v_g1=v_h1p + ca.cross(w1p, e["g1"] - e["h1"]), v_g2=ca.cross(w2p, e["g2"] - d),
                    v_axle=ca.cross(w2p, e["axle"] - d), w1=w1p, w2=w2p)

    def total_momentum(v):
        return (
            ca.cross(e["g1"] - d, m * v["v_g1"])
            + ca.cross(e["g2"] - d, m * v["v_g2"])
            + ca.cross(e["axle"] - d, mh * v["v_axle"])
            + ca.mtimes(e["i1"], v["w1"])
            + ca.mtimes(e["i2"], v["w2"])
        )

    def leg1_hip_momentum(v):
        return ca.dot(e["n"], ca.cross(e["g1"] - e["h1"], m * v["v_g1"]) + ca.mtimes(e["i1"], v["w1"]))

    def linear_momentum(v):
        return m * v["v_g1"] + m * v["v_g2"] + mh * v["v_axle"]

    def kinetic(v):
        return 0.5 * (m * ca.dot(v["v_g1"], v["v_g1"]) + m * ca.dot(v["v_g2"], v["v_g2"])
                      + mh * ca.dot(v["v_axle"], v["v_axle"]) + ca.dot(v["w1"], ca.mtimes(e["i1"], v["w1"]))
                      + ca.dot(v["w2"], ca.mtimes(e["i2"], v["w2"])))

    before = dict(v_g1=e["v_g1"], v_g2=e["v_g2"], v_axle=e["v_axle"], w1=e["w1"], w2=e["w2"])
    after = velocities(up)
    # The total normal impulse is the jump of the normal linear momentum (gravity is finite).
    normal_total = ca.dot(ez, linear_momentum(after) - linear_momentum(before))
    share = ca.SX(0)
    arrests = []
    for effect in _effects(sym.effects):
        k = par.effects[effect.name]
        extra = effect.trailing_impulse(k, ctx)
        if extra is not None:
            share += extra
        arrest = effect.arrest(k, ctx)
        if arrest is not None:
            arrests.append(arrest)

    def jump_conditions(trailing_share):
        """The jump conditions, linear in u+: residual = A(q) u+ - b(q, u)."""
        lam_c = trailing_share * normal_total  # the trailing foot's normal impulse at C (origin)
        # Angular impulses of lambda_C e_z at C = 0: about D, and about the hip axis through H1.
        jump_total = total_momentum(after) - total_momentum(before) - ca.cross(-d, ez) * lam_c
        jump_hip = (leg1_hip_momentum(after) - leg1_hip_momentum(before)
                    - ca.dot(e["n"], ca.cross(-e["h1"], ez)) * lam_c)
        if lay.planar:
            jump_total = ca.dot(e["n"], jump_total)
        residual = ca.vertcat(jump_total, jump_hip)
        return residual, ca.jacobian(residual, up), -ca.substitute(residual, up, ca.SX.zeros(lay.nq))

    residual, a_mat, b_vec = jump_conditions(share)
    u_plus = ca.solve(a_mat, b_vec)
    normal = ca.substitute(normal_total, up, u_plus)

    def arrested(chosen):
        """The law that also arrests the rates of ``chosen`` (arrests), the landing foot's patch
        taking the whole impulse (no trailing share): an impulsive couple mu_i * axis_i on the
        landing leg for each (in the whole walker's angular momentum about D, not the trailing
        leg's) and axis_i . omega_2+ = 0. Plastic constraints all: a plastic projection (Carnot),
        so its blends with an admissible law never gain energy (kinetic energy is convex in the
        rates); impulses blend alike. Returns (u+, landing normal impulse, trailing one)."""
        _, a_plain, b_plain = jump_conditions(0)
        if lay.planar:  # omega . e_z and omega . h vanish identically there: already enforced
            law = ca.solve(a_plain, b_plain)
        else:
            rows = ca.vertcat(*(ca.jacobian(ca.dot(a.axis, after["w2"]), up) for a in chosen))
            columns = ca.horzcat(*(ca.vertcat(-a.axis, 0) for a in chosen))
            n = len(chosen)
            kkt = ca.vertcat(ca.horzcat(a_plain, columns), ca.horzcat(rows, ca.SX.zeros(n, n)))
            law = ca.solve(kkt, ca.vertcat(b_plain, ca.SX.zeros(n)))[:lay.nq]
        return law, ca.substitute(normal_total, up, law), ca.SX(0)

    def blend(i, chosen):
        """The arrests from the i-th on blended into the law of ``chosen``: multilinear in the
        strengths (:class:`toywalk.model.effects.Arrest`), nested so that a strength of exactly 0
        leaves the other laws' numbers bit for bit."""
        if i == len(arrests):
            return arrested(chosen) if chosen else (u_plus, (1 - share) * normal, share * normal)
        u_a, lead_a, trail_a = blend(i + 1, chosen)
        u_b, lead_b, trail_b = blend(i + 1, (*chosen, arrests[i]))
        k = arrests[i].strength
        return u_a + k * (u_b - u_a), (1 - k) * lead_a + k * lead_b, (1 - k) * trail_a + k * trail_b

    u_plus, lead, trail = blend(0, ())
    final = velocities(u_plus)
    return dict(u_plus=u_plus, residual=residual, up=up, kinetic_before=kinetic(before),
                energy_change=kinetic(final) - kinetic(before),
                normal_impulses=ca.vertcat(lead, trail))


def mirror_relabel(lay: Layout, q: ca.SX, u_plus: ca.SX) -> ca.SX:
    """New dynamic state after relabel (swap legs) and mirror (y -> -y: phi, psi negated), from the
    configuration ``q`` and the post-collision speeds ``u_plus`` in the old labels (docs/model.md
    section 4)."""
    if lay.planar:
        return ca.vertcat(q[1], q[0], u_plus[1], u_plus[0])
    return ca.vertcat(-q[0], -q[1], q[3], q[2], -u_plus[0], -u_plus[1], u_plus[3], u_plus[2])


@cache
def build_functions(planar: bool, effects: bool = True) -> dict[str, ca.Function]:
    """Uncompiled CasADi functions of one system (3D or planar), all with inputs ``(x, p)``.

    ``p`` is the parameter input (:meth:`toywalk.model.parameters.Params.input_vector`).
    Returns a dict of ``ca.Function`` by name:

    - ``rhs(x, p) -> xdot`` : shape (nx,), the state derivative (q', u', contact travel rates).
    - ``energy(x, p) -> E`` : kinetic + gravitational (J), potential including the contact travel.
    - ``dissipation(x, p) -> D`` : shape (n_continuous,), the power (W) each continuous effect
      dissipates (:data:`toywalk.model.effects.CONTINUOUS` order); dE/dt = -sum(D).
    - ``guard(x, p) -> (h, ahead)`` : swing foot's lowest-point height over the ramp (m) and its
      distance ahead of the stance contact along the heading (m).
    - ``collision(x, p) -> x_plus`` : impact, relabel and mirror; the contact travel is set to the
      new contact point (in the old frame; the caller handles frames).
    - ``impact(x, p) -> (dK, lambda, K)`` : the collision's kinetic-energy change (J), the normal
      impulses at the landing and trailing feet (N s) and the kinetic energy before it (J).
    - ``momenta(x, u_plus, p) -> residual`` : the conservation residuals of the collision law.
    - ``points(x, p) -> P`` : shape (3, 9), the walker's points relative to C (drawing, checks).
    """
    sym = symbolic(planar, effects)
    lay, q, u, p, e = sym.lay, sym.q, sym.u, sym.p, sym.exprs
    travel = ca.SX.sym("travel", lay.nx - lay.n_dyn)
    x = ca.vertcat(q, u, travel)
    udot = ca.solve(e["mass_matrix"], e["forcing"])
    c_dot = e["c_dot"][0] if planar else e["c_dot"][:2]
    xdot = ca.vertcat(u, udot, c_dot)
    gvec = e["gvec"]
    c_abs = ca.vertcat(travel[0], 0 if planar else travel[1], 0)
    total_mass = 2 * sym.ctx.params.leg_mass + sym.ctx.params.axle_mass
    energy = e["kinetic"] + e["potential_rel"] - total_mass * ca.dot(gvec, c_abs)
    phi = 0 if planar else q[0]
    heading = ca.vertcat(ca.cos(phi), ca.sin(phi), 0)
    guard = ca.vertcat(e["c2"][2], ca.dot(heading, e["c2"]))
    coll = _collision_exprs(sym)
    new_dyn = mirror_relabel(lay, q, coll["u_plus"])
    c2xy = e["c2"][0] if planar else e["c2"][:2]
    x_plus = ca.vertcat(new_dyn, travel + c2xy)
    points = ca.horzcat(
        ca.SX.zeros(3), e["o1"], e["h1"], e["axle"], e["h2"], e["o2"], e["c2"], e["g1"], e["g2"]
    )
    opts = {"allow_free": False}
    fns = {
        "rhs": ca.Function("rhs", [x, p], [xdot], ["x", "p"], ["xdot"], opts),
        "energy": ca.Function("energy", [x, p], [energy], ["x", "p"], ["energy"], opts),
        "dissipation": ca.Function("dissipation", [x, p], [e["dissipation"]], ["x", "p"], ["D"], opts),
        "guard": ca.Function("guard", [x, p], [guard], ["x", "p"], ["guard"], opts),
        "collision": ca.Function("collision", [x, p], [x_plus], ["x", "p"], ["x_plus"], opts),
        "impact": ca.Function("impact", [x, p], [coll["energy_change"], coll["normal_impulses"],
                                                 coll["kinetic_before"]],
                              ["x", "p"], ["dK", "lambda", "K"], opts),
        "momenta": ca.Function(
            "momenta", [x, coll["up"], p], [coll["residual"]], ["x", "u_plus", "p"], ["residual"], opts
        ),
        "points": ca.Function("points", [x, p], [points], ["x", "p"], ["points"], opts),
        "mass_matrix": ca.Function(
            "mass_matrix", [x, p], [e["mass_matrix"], e["forcing"]], ["x", "p"], ["M", "f"], opts
        ),
        "generalised": ca.Function("generalised", [x, p], [e["generalised"]], ["x", "p"], ["Q"], opts),
    }
    return fns
