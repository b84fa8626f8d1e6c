"""Can the walker stand still? Static equilibria of every contact configuration and their stability.

The toy's defining property (Coleman & Ruina, Phys. Rev. Lett. 80, 3658, 1998; docs/model.md section 2)
is that it cannot stand: its centre of mass is above the feet's centre of curvature, so no standing
configuration, with parallel or with splayed legs, is stable. :func:`can_stand` checks a parameter
set for this and says how it stands or falls; :func:`static_margin` is the one-number rule of thumb.

Configurations
--------------
A standing walker touches the ramp with

- **one foot**: the left (reference) foot; the other leg hangs from the frictionless hinge, its
  foot clear of the ramp;
- **two feet, parallel legs**: both feet down, side by side, the legs parallel (theta_st =
  theta_sw), still free to hinge;
- **two feet, splayed legs**: both feet down, one ahead of the other.

All are described by the model's own coordinates ``q = (phi, psi, theta_st, theta_sw)``
(docs/model.md section 1, :mod:`toywalk.model.equations`): the left foot is the reference contact C that
rolls without slipping, exactly as in the equations of motion. The right foot, when down, is held by
a contact force ``lambda`` (slope frame, N) at its lowest point c2. Standing on the right foot alone
is the mirror image of standing on the left one (the walker and the ramp are symmetric under
y -> -y), and so is a splay with the right foot ahead; both are covered by the cases above.

Contact model
-------------
Feet roll without slipping (the model's contact; friction is unlimited unless ``friction`` is
given) and spin freely about the ramp normal (no contact couple, as in the seed). For the right foot
this is three velocity constraints, the velocity of its material point at c2 vanishing:
``A(q) u = 0`` with ``A = d v_c2 / d u`` (shape (3, 4)); the z row is the rate of the holonomic
constraint ``c2_z(q) = 0``, the other two are the nonholonomic no-slip conditions.

Equilibria
----------
At rest (u = 0) Kane's equations of the model, ``M(q) du/dt = f(q, u)`` (Kane & Levinson, *Dynamics:
Theory and Applications*, 1985), reduce to the generalised gravity force
``f0(q) = f(q, 0) = sum_i J_i^T m_i g``, whose partial velocities J_i contain the left foot's
rolling. Equilibria solve ``f0(q) = 0`` (one foot; the hanging foot must be clear of the ramp) or
``f0(q) + A(q)^T lambda = 0, c2_z(q) = 0`` (two feet; both normal forces must push), with
theta_sw = theta_st held for parallel legs. They are found by :func:`scipy.optimize.least_squares`
(Levenberg-Marquardt for one foot, trust-region reflective for two) from a grid of starting points,
since equilibria may be tilted: lean 0, +-0.3 rad and the lean that brings the centre of mass over
one foot of a wide walker; stance pitch 0, +-0.3 rad; the free leg hanging; splays 0.15 to 1.1 rad;
on a ramp the headings downhill, across (both ways) and uphill. Equilibria come in families, and
the solver returns one member per start:

- on one foot, a rotation about the true vertical through the contact point does no work, so the
  rest positions form a one-parameter family (the heading on level ground; on a ramp a mix of
  heading, lean and pitch), which shows as a neutral mode;
- on two feet, friction holds any splay and, on a ramp, any heading, so the splay and the heading
  are the grid's family parameters. Splayed solutions within 1e-3 rad of parallel are dropped
  (they duplicate the parallel case and their contact forces are ill-conditioned).

When the contact forces are statically indeterminate (a squeeze along the axle between side-by-side
feet, or the load split between coincident feet when w = 0) the distribution nearest to "each foot
carries half the weight" is taken. Of the equilibria of one kind, the one reported is a stable one
needing the least friction, else the slowest to fall, else the least infeasible.

Stability
---------
Linearising the constrained equations about an equilibrium (Neimark & Fufaev, *Dynamics of
Nonholonomic Systems*, AMS Transl. 33, 1972, ch. III): admissible velocities are ``u = N v`` with N
an orthonormal basis of null(A) (N = identity on one foot), and

    (N^T M N) v'' = (N^T K N) v,    K = d(f0 + A^T lambda)/dq at fixed lambda,

so perturbations grow like exp(s t) with ``s^2 = mu`` the eigenvalues of the pencil
(N^T K N, N^T M N); the coordinate directions that no admissible velocity reaches only add neutral
(zero) exponents. The equilibrium is stable when every mu is real and <= 0, up to neutral modes
(mu = 0: the heading on level ground, families of equilibria), which are not instabilities.

On level ground the contact travel is horizontal, so ``f0 = -dV/dq`` with V the gravitational
potential as a function of q alone (checked in the tests), K is symmetric and ``-N^T K N`` is the
second variation of the potential over the motions that keep the chosen feet on the ramp, including
the contact forces' geometric stiffness (for holonomic contacts the Hessian of the Lagrangian
V - lambda . c2): stability is its positive semi-definiteness (Lagrange-Dirichlet; e.g. Goldstein,
Poole & Safko, *Classical Mechanics*, 3rd ed., section 6.1), independently of the inertia. The
classical special case, a rigid body rocking on a convex foot, is stable iff its centre of mass lies
below the foot's centres of curvature: here, with w = 0 and parallel legs, height < rho sideways and
< r fore-aft (Routh, *Dynamics of a System of Rigid Bodies*, 1905).

On a ramp the rolling foot's contact moves downhill as it rolls, and how far depends on the path
(3D rolling is nonholonomic): there is no potential function of q and K is not symmetric. The
linearisation above still holds exactly (it is the model's own equations, rolling included) and
decides stability, flutter (complex mu) included. What was done: every configuration is evaluated
on the ramp of the parameter set, which gives :attr:`StandingReport.can_stand`, and, when the slope
is not zero, again on level ground (:attr:`StandingReport.can_stand_level`), where the potential
argument applies.

Point-mass legs (zero inertia, e.g. the simplest walker) make N^T M N singular. Massless
directions are quasi-static: restoring ones follow the massive ones (a Schur complement eliminates
them), anti-restoring ones fall at once (mu = +inf), and force-free ones (nothing moves, nothing
changes: a rotation about a massless leg's own axis) are neutral.

Standing requires strictly positive normal forces on every foot down: a two-foot equilibrium whose
second foot is unloaded is decided by the one-foot analysis at the same place. Only upright
configurations count: lean |psi| < 80 degrees, both legs within 90 degrees of the ramp normal, hips
and centre of mass above the ramp. The verdict is linear (spectral) stability; the model's effects
(docs/model.md section 6, e.g. hip friction that could hold a splay) are not part of it.

Limits: the search is a grid, so an equilibrium far from every start (a splay beyond about 1.3 rad,
a heading on a ramp between the four tried) can be missed; a touching free foot that blocks an
unstable one-foot motion is only credited through the two-foot analysis.

The simplest walker (point feet, heavy hip, massless legs; Garcia et al., J. Biomech. Eng. 120:281,
1998) cannot stand in 3D: on one point foot it is an inverted pendulum (falls forward or back), and
on two point feet it pivots about the line joining them with its hip mass above that line (falls
sideways). Its planar reduction, kept from falling sideways, could stand splayed, the two feet
and the hip forming a rigid triangle (not computed here: this module is 3D).
"""

from __future__ import annotations

import dataclasses
import math
from functools import cache

import casadi as ca
import numpy as np
import scipy.linalg
from scipy.optimize import least_squares

from .equations import symbolic
from .parameters import Params

__all__ = [
    "KINDS",
    "StandingConfiguration",
    "StandingReport",
    "can_stand",
    "static_margin",
]

#: The static contact configurations, in the order reported.
KINDS: tuple[str, ...] = ("one foot", "two feet, parallel legs", "two feet, splayed legs")

_COORDS = ("phi", "psi", "theta_st", "theta_sw")

# Numerical tolerances, relative to the walker's own scales (M g l for forces x lengths, M l^2 for
# inertia, l for lengths, M g for forces). Equilibria are solved to round-off (residual ~1e-14);
# the thresholds sit well above that and well below any physical effect worth reporting.
_RESIDUAL_TOL = 1e-9  # accepted equilibrium residual, |f| / (M g l)
_STIFF_TOL = 1e-8  # |modal stiffness| / (M g l) below which a mode is neutral
_MASS_TOL = 1e-9  # modal inertia / (M l^2) below which a direction is massless
_RANK_TOL = 1e-9  # singular value of A / l below which a contact constraint is redundant
_CLEAR_TOL = 1e-9  # swing-foot height / l below which the foot touches the ramp
_LOAD_TOL = 1e-6  # normal force / (M g) a foot must exceed to count as loaded
_PARALLEL_TOL = 1e-3  # rad: splayed solutions closer to parallel than this are dropped
_MAX_LEAN = math.radians(80)  # rad: standing means |psi| below this ...
_MAX_PITCH = math.pi / 2  # rad: ... and both legs within this of the ramp normal

# Starting grid. Splays are theta_st - theta_sw > 0 (the mirror image covers < 0); headings on a
# ramp in both senses so that the mirror image is covered there too.
_SPLAYS = (0.15, 0.35, 0.7, 1.1)  # rad
_RAMP_HEADINGS = (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi)  # rad
_TILTS = (0.0, 0.3, -0.3)  # rad, starting lean and stance pitch offsets


@dataclasses.dataclass(frozen=True)
class StandingConfiguration:
    """One contact configuration of a standing walker: its best equilibrium and its stability.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    slope : float
        Slope (rad) of the ground it was evaluated on: the parameter set's ramp, or 0 (level).
    equilibrium : dict of str to float or None
        ``phi, psi, theta_st, theta_sw`` (rad) of the equilibrium reported (the most stable one
        found, else the least unstable, else the least infeasible), None if there is none.
    status : str
        ``"stable"``, ``"unstable"``, ``"infeasible"`` (an equilibrium that needs the free foot
        below the ramp, a pulling foot, or more friction than allowed) or ``"no equilibrium"``.
    stable : bool
        True when the walker can stand this way.
    growth_rate : float
        Largest growth rate Re(s) (1/s) of a perturbation, exp(s t); 0 when stable, inf for a
        massless direction that falls at once, nan without an equilibrium.
    mode : str
        Plain words for the fastest falling mode (e.g. "sideways (lean)"); empty when stable.
    exponents_squared : tuple of complex
        The mu = s^2 (1/s^2) of the linearised modes; real and <= 0 when stable.
    stiffness : tuple of float
        Eigenvalues (N m / rad^2) of the symmetric part of the reduced stiffness -N^T K N over the
        admissible motions (orthonormal basis); positive restores. On level ground this is the
        second variation of the potential energy.
    com_height : float
        Whole walker's centre of mass above the ramp (m), along the ramp normal.
    margin : float
        ``com_height - foot_lateral_radius`` (m): positive when the centre of mass is above the
        feet's sideways centre of curvature.
    normal_forces : tuple of 2 floats
        Ramp-normal force (N) on the left foot and on the right foot (0 when it is up).
    friction_needed : float
        Largest ratio of tangential to normal contact force over the feet down.
    swing_clearance : float
        Height (m) of the free foot's lowest point over the ramp (one foot); 0 with two feet down.
    splay : float
        theta_st - theta_sw (rad).
    n_equilibria : int
        Number of distinct equilibria of this kind found (members of a family count separately).
    note : str
        What else a reader should know (touching foot, indeterminate forces).
    why_infeasible : str
        Why an equilibrium found cannot be a standing position (empty unless infeasible).
    """

    kind: str
    slope: float
    equilibrium: dict[str, float] | None
    status: str
    stable: bool
    growth_rate: float = math.nan
    mode: str = ""
    exponents_squared: tuple[complex, ...] = ()
    stiffness: tuple[float, ...] = ()
    com_height: float = math.nan
    margin: float = math.nan
    normal_forces: tuple[float, float] = (math.nan, math.nan)
    friction_needed: float = math.nan
    swing_clearance: float = math.nan
    splay: float = math.nan
    n_equilibria: int = 0
    note: str = ""
    why_infeasible: str = ""

    @property
    def level(self) -> bool:
        """True when evaluated on level ground."""
        return self.slope == 0.0


@dataclasses.dataclass(frozen=True)
class StandingReport:
    """Whether and how a walker can stand (see :func:`can_stand`).

    Attributes
    ----------
    can_stand : bool
        A stable standing configuration exists on the parameter set's ramp.
    reason : str
        One or two plain sentences naming the deciding configuration and its numbers.
    configurations : list of StandingConfiguration
        One per kind in :data:`KINDS` on the ramp, then (if the slope is not zero) on level ground.
    slope : float
        The ramp's slope (rad).
    can_stand_level : bool
        A stable standing configuration exists on level ground.
    static_margin : float
        :func:`static_margin` of the parameter set (m).
    """

    can_stand: bool
    reason: str
    configurations: list[StandingConfiguration]
    slope: float
    can_stand_level: bool
    static_margin: float

    def configuration(self, kind: str, level: bool = False) -> StandingConfiguration:
        """The result for one kind of :data:`KINDS` on the ramp, or on level ground (``level``)."""
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
        want_level = level or self.slope == 0.0
        for conf in self.configurations:
            if conf.kind == kind and conf.level == want_level:
                return conf
        raise LookupError(f"no {kind!r} result on {'level ground' if level else 'the ramp'}")


def static_margin(params: Params) -> float:
    """Centre-of-mass height above the feet's sideways centre of curvature, legs upright (m).

    The whole walker's centre of mass height over level ground with both legs upright and parallel
    and no lean, ``l + 2 m d_z / (2 m + M_h)``, minus the foot's lateral radius rho. Positive means
    the centre of mass is above the feet's lateral centre of curvature: with w = 0 such a walker
    cannot stand (it falls sideways; docs/model.md section 2). Cheap: no equilibrium is solved; see
    :func:`can_stand` for the full check (which also covers hip width, tilted equilibria and
    splayed legs).

    Parameters
    ----------
    params : Params

    Returns
    -------
    float
        Margin (m).
    """
    _check_params(params)
    height = params.leg_length + 2.0 * params.leg_mass * params.com_offset[2] / params.total_mass
    return float(height - params.foot_lateral_radius)


def can_stand(params: Params, friction: float = math.inf) -> StandingReport:
    """Check every static contact configuration of a walker for a stable equilibrium.

    Parameters
    ----------
    params : Params
        The walker and its ramp.
    friction : float
        Largest tangential-to-normal force ratio a foot can hold (coefficient of static friction);
        the model's no-slip contact is ``inf``. Equilibria that need more are infeasible.

    Returns
    -------
    StandingReport
        ``can_stand`` on the parameter set's ramp, the same on level ground, the reason in words and
        one :class:`StandingConfiguration` per kind and ground.

    Notes
    -----
    Method, tolerances and references in the module docstring.
    """
    _check_params(params)
    if isinstance(friction, bool) or not isinstance(friction, (int, float)) or not friction >= 0:
        raise ValueError(f"friction must be a number >= 0 (inf for no slip), got {friction!r}")
    grounds = [params] if params.slope == 0.0 else [params, params.replace(slope=0.0)]
    configurations: list[StandingConfiguration] = []
    for ground in grounds:
        configurations.extend(_Statics(ground, float(friction)).run())
    ramp = [c for c in configurations if c.slope == params.slope]
    level = [c for c in configurations if c.level]
    stands = any(c.stable for c in ramp)
    stands_level = any(c.stable for c in level)
    return StandingReport(
        can_stand=stands,
        reason=_reason(params, ramp, level, stands, stands_level),
        configurations=configurations,
        slope=params.slope,
        can_stand_level=stands_level,
        static_margin=static_margin(params),
    )


# ------------------------------------------------------------------------------------------------
def _check_params(params: object) -> None:
    if not isinstance(params, Params):
        raise TypeError(f"params must be a toywalk Params, got {type(params).__name__}")


@cache
def _kernels() -> tuple[ca.Function, ca.Function]:
    """CasADi functions of the statics, built once from the model's symbolic expressions.

    ``statics(q, lam, p) -> (F, K, A, c2, dc2z)``: generalised force at rest with a force ``lam``
    on the right foot's contact point, its q-Jacobian at fixed ``lam``, the right foot's contact
    velocity Jacobian, its lowest point (relative to C) and the gradient of its height.
    ``inertial(q, p) -> (M, com, hips)``: mass matrix, whole centre of mass and the two hip points
    (columns), relative to C.
    """
    sym = symbolic(False)
    q, u, p, e = sym.q, sym.u, sym.p, sym.exprs
    lam = ca.SX.sym("lam", 3)
    f0 = ca.substitute(e["forcing"], u, ca.SX.zeros(u.shape))
    v_c2 = ca.cross(e["w1"], e["h2"]) + ca.cross(e["w2"], e["c2"] - e["h2"])
    a_mat = ca.jacobian(v_c2, u)
    force = f0 + ca.mtimes(a_mat.T, lam)
    stiff = ca.jacobian(force, q)
    c2z = e["c2"][2]
    m, mh = sym.ctx.params.leg_mass, sym.ctx.params.axle_mass
    com = (m * (e["g1"] + e["g2"]) + mh * e["axle"]) / (2 * m + mh)
    opts = {"allow_free": False}
    statics = ca.Function(
        "statics", [q, lam, p], [force, stiff, a_mat, e["c2"], ca.jacobian(c2z, q)],
        ["q", "lam", "p"], ["F", "K", "A", "c2", "dc2z"], opts,
    )
    hips = ca.horzcat(e["h1"], e["h2"])
    inertial = ca.Function(
        "inertial", [q, p], [e["mass_matrix"], com, hips], ["q", "p"], ["M", "com", "hips"], opts
    )
    return statics, inertial


@dataclasses.dataclass
class _Equilibrium:
    q: np.ndarray
    lam: np.ndarray  # force on the right foot (N, slope frame); zeros on one foot
    two_feet: bool


class _Statics:
    """All configurations of one walker on one ground."""

    def __init__(self, params: Params, friction: float):
        self.params = params
        self.friction = friction
        self.p = params.input_vector()
        self.statics, self.inertial = _kernels()
        mass = params.total_mass
        self.l = params.leg_length
        self.weight = mass * params.gravity
        self.k_scale = self.weight * self.l  # N m
        self.m_scale = mass * self.l**2  # kg m^2
        alpha = params.slope
        beta = params.effects.get("cross_slope", 0.0)  # the ramp tilted sideways (an effect)
        self.gvec = params.gravity * np.array([math.sin(alpha), -math.cos(alpha) * math.sin(beta),
                                               -math.cos(alpha) * math.cos(beta)])
        d_x, _, d_z = params.com_offset
        # Angle at which a free leg hangs with its centre of mass below the hip on level ground.
        self.hang = math.atan2(d_x, -d_z) if (d_x or d_z) else 0.0

    # -------------------------------------------------------------------------------------------
    def _eval(self, q: np.ndarray, lam: np.ndarray):
        out = self.statics(q, lam, self.p)
        return tuple(np.array(o.full()) for o in out)

    def run(self) -> list[StandingConfiguration]:
        one = self._one_foot_equilibria()
        parallel, splayed = self._two_feet_equilibria()
        found = (one, parallel, splayed)
        return [self._summarise(kind, eqs) for kind, eqs in zip(KINDS, found, strict=True)]

    # -------------------------------------------------------------------------------------------
    def _one_foot_equilibria(self) -> list[_Equilibrium]:
        level = self.params.slope == 0.0
        free = [1, 2, 3] if level else [0, 1, 2, 3]  # heading is neutral on level ground
        headings = (0.0,) if level else _RAMP_HEADINGS
        zero = np.zeros(3)
        found: list[_Equilibrium] = []
        # Leaning onto the left foot brings the centre of mass over it when the hips are apart.
        height = max(self.params.leg_length + self.params.com_offset[2], 0.1 * self.l)
        lean_w = math.atan2(0.5 * self.params.hip_width, height)
        leans = sorted({*_TILTS, lean_w, -lean_w})
        for phi in headings:
            for psi in leans:
                for tilt in _TILTS:
                    q0 = np.array([phi, psi, tilt, self.hang])

                    def fun(x, q0=q0):
                        q = q0.copy()
                        q[free] = x
                        return self._eval(q, zero)[0].ravel() / self.k_scale

                    def jac(x, q0=q0):
                        q = q0.copy()
                        q[free] = x
                        return self._eval(q, zero)[1][:, free] / self.k_scale

                    sol = _solve(fun, jac, q0[free], "lm")
                    if sol is None:
                        continue
                    q = q0.copy()
                    q[free] = sol
                    _add_unique(found, _Equilibrium(_wrap(q), zero.copy(), False))
        return found

    def _two_feet_equilibria(self) -> tuple[list[_Equilibrium], list[_Equilibrium]]:
        """Equilibria on both feet: (exactly parallel legs, splayed legs)."""
        level = self.params.slope == 0.0
        headings = (0.0,) if level else _RAMP_HEADINGS
        parallel: list[_Equilibrium] = []
        splayed: list[_Equilibrium] = []
        for phi in headings:
            back = -self.params.slope * math.cos(phi)  # legs along the true vertical
            for splay in (0.0, *_SPLAYS):
                for tilt in sorted({0.0, back}):
                    theta = np.array([tilt + 0.5 * splay, tilt - 0.5 * splay])
                    if splay == 0.0:  # legs held parallel: unknowns psi, theta, lambda
                        x0 = np.array([0.0, tilt, 0.0, 0.0, 0.0])
                        sol = _solve(lambda x, phi=phi: self._two_feet_residual(phi, x, True),
                                     lambda x, phi=phi: self._two_feet_jacobian(phi, x, True),
                                     x0, "trf")
                        q = None if sol is None else np.array([phi, sol[0], sol[1], sol[1]])
                    else:  # legs free: unknowns psi, theta_st, theta_sw, lambda
                        x0 = np.concatenate([[0.0], theta, np.zeros(3)])
                        sol = _solve(lambda x, phi=phi: self._two_feet_residual(phi, x, False),
                                     lambda x, phi=phi: self._two_feet_jacobian(phi, x, False),
                                     x0, "trf")
                        q = None if sol is None else np.concatenate([[phi], sol[:3]])
                    if q is None:
                        continue
                    q = _wrap(q)
                    lam = self._contact_force(q)
                    if lam is None:
                        continue
                    if splay == 0.0:
                        _add_unique(parallel, _Equilibrium(q, lam, True))
                    elif abs(q[2] - q[3]) >= _PARALLEL_TOL:  # near-parallel: ill-conditioned
                        _add_unique(splayed, _Equilibrium(q, lam, True))
        return parallel, splayed

    def _unpack(self, phi: float, x: np.ndarray, parallel: bool) -> tuple[np.ndarray, np.ndarray]:
        n_q = 2 if parallel else 3
        q = np.concatenate([[phi], x[:n_q]])
        if parallel:
            q = np.append(q, q[2])
        return q, x[n_q:] * self.weight

    def _two_feet_residual(self, phi: float, x: np.ndarray, parallel: bool) -> np.ndarray:
        q, lam = self._unpack(phi, x, parallel)
        force, _, _, c2, _ = self._eval(q, lam)
        return np.concatenate([force.ravel() / self.k_scale, [c2[2, 0] / self.l]])

    def _two_feet_jacobian(self, phi: float, x: np.ndarray, parallel: bool) -> np.ndarray:
        q, lam = self._unpack(phi, x, parallel)
        _, stiff, a_mat, _, dc2z = self._eval(q, lam)
        # d q / d x: identity on (psi, theta_st, theta_sw), or theta driving both legs.
        dq = np.eye(4)[:, 1:]
        if parallel:
            dq = np.array([[0, 0], [1, 0], [0, 1], [0, 1]], dtype=float)
        top = np.hstack([stiff @ dq / self.k_scale, a_mat.T * self.weight / self.k_scale])
        bottom = np.hstack([dc2z @ dq / self.l, np.zeros((1, 3))])
        return np.vstack([top, bottom])

    def _contact_force(self, q: np.ndarray) -> np.ndarray | None:
        """The force on the right foot that balances the walker, None if there is none.

        Of all balancing forces (an affine set when statically indeterminate), the one nearest
        to half the weight on each foot.
        """
        force0, _, a_mat, _, _ = self._eval(q, np.zeros(3))
        f0 = force0.ravel()
        lam_p, *_ = np.linalg.lstsq(a_mat.T, -f0, rcond=None)
        if np.linalg.norm(f0 + a_mat.T @ lam_p) > _RESIDUAL_TOL * self.k_scale:
            return None
        u_, s_, _ = np.linalg.svd(a_mat)
        rank = int(np.sum(s_ > _RANK_TOL * self.l))
        null = u_[:, rank:]  # forces on the right foot that do no generalised work
        half = -0.5 * self.params.total_mass * self.gvec
        return lam_p + null @ (null.T @ (half - lam_p))

    # -------------------------------------------------------------------------------------------
    def _analyse(self, eq: _Equilibrium) -> dict:
        """Feasibility, forces, margins and linear stability of one equilibrium."""
        params = self.params
        _, stiff, a_mat, c2, _ = self._eval(eq.q, eq.lam)
        mass_matrix, com, hips = (np.array(o.full()) for o in self.inertial(eq.q, self.p))
        info: dict = {
            "q": eq.q,
            "com_height": float(com[2, 0]),
            "splay": float(eq.q[2] - eq.q[3]),
            "notes": [],
        }
        total = -params.total_mass * self.gvec  # force the ground must supply, N
        if eq.two_feet:
            right = eq.lam
            _, s_, vt = np.linalg.svd(a_mat)
            rank = int(np.sum(s_ > _RANK_TOL * self.l))
            basis = vt[rank:].T  # admissible velocities, shape (4, k)
            info["swing_clearance"] = 0.0
            if rank < 3:
                info["notes"].append("the contact forces are statically indeterminate "
                                     "(taken nearest to half the weight on each foot)")
        else:
            right = np.zeros(3)
            basis = np.eye(4)
            info["swing_clearance"] = float(c2[2, 0])
        left = total - right
        info["normal_forces"] = (float(left[2]), float(right[2]))
        loads = [left] + ([right] if eq.two_feet else [])
        info["friction_needed"] = max(
            (math.hypot(f[0], f[1]) / f[2] if f[2] > 0 else math.inf) for f in loads
        )
        # Feasibility: upright, feet above or on the ramp, pushing, within the friction limit.
        infeasible = []
        if abs(eq.q[1]) >= _MAX_LEAN or max(abs(eq.q[2]), abs(eq.q[3])) >= _MAX_PITCH:
            infeasible.append("it is not upright (lean or leg angle too large)")
        elif min(hips[2].min(), com[2, 0]) <= 0:
            infeasible.append("a hip or the centre of mass would be below the ramp")
        if not eq.two_feet and c2[2, 0] < -_CLEAR_TOL * self.l:
            infeasible.append(f"the free foot would be {-c2[2, 0] * 1e3:.3g} mm below the ramp")
        if not eq.two_feet and abs(c2[2, 0]) <= _CLEAR_TOL * self.l:
            info["notes"].append("the free foot just touches the ramp")
        if min(f[2] for f in loads) < _LOAD_TOL * self.weight:
            if eq.two_feet and min(f[2] for f in loads) > -_LOAD_TOL * self.weight:
                infeasible.append("a foot is unloaded (decided by the one-foot analysis)")
            else:
                infeasible.append("a foot would have to pull on the ramp")
        if info["friction_needed"] > self.friction:
            infeasible.append(
                f"it needs a friction coefficient of {info['friction_needed']:.3g} "
                f"(limit {self.friction:.3g})"
            )
        info["infeasible"] = infeasible
        # Linear stability over the admissible motions.
        k_red = basis.T @ stiff @ basis
        m_red = basis.T @ mass_matrix @ basis
        info["stiffness"] = tuple(np.sort(np.linalg.eigvalsh(-0.5 * (k_red + k_red.T))).tolist())
        modes = _modes(m_red, k_red, self.m_scale, self.k_scale)
        info["mu"] = tuple(complex(mu) for mu, _, _ in modes)
        worst_growth, worst_vec = -1.0, None
        for mu, vec, unstable in modes:
            growth = math.inf if math.isinf(mu.real) else float(np.sqrt(complex(mu)).real)
            if unstable and growth > worst_growth:
                worst_growth, worst_vec = growth, vec
        info["unstable"] = any(unstable for _, _, unstable in modes)
        info["growth_rate"] = worst_growth if info["unstable"] else 0.0
        info["mode"] = _describe_mode(basis @ worst_vec) if worst_vec is not None else ""
        # Most restoring weakest mode (to rank stable equilibria): smallest positive stiffness.
        stiff_pos = [s for s in info["stiffness"] if s > _STIFF_TOL * self.k_scale]
        info["softest"] = min(stiff_pos) if stiff_pos else 0.0
        return info

    def _summarise(self, kind: str, eqs: list[_Equilibrium]) -> StandingConfiguration:
        slope = self.params.slope
        if not eqs:
            return StandingConfiguration(kind=kind, slope=slope, equilibrium=None,
                                         status="no equilibrium", stable=False)
        infos = [self._analyse(e) for e in eqs]

        def rank(info):  # lower is better: stable (least friction), unstable (slowest), infeasible
            if not info["infeasible"] and not info["unstable"]:
                return (0, info["friction_needed"], -info["softest"])
            if not info["infeasible"]:
                return (1, info["growth_rate"], 0.0)
            return (2, len(info["infeasible"]), info["growth_rate"])

        best = min(infos, key=rank)
        feasible = not best["infeasible"]
        stable = feasible and not best["unstable"]
        status = "stable" if stable else ("unstable" if feasible else "infeasible")
        return StandingConfiguration(
            kind=kind,
            slope=slope,
            equilibrium=dict(zip(_COORDS, (float(v) for v in best["q"]), strict=True)),
            status=status,
            stable=stable,
            growth_rate=best["growth_rate"],
            mode=best["mode"],
            exponents_squared=best["mu"],
            stiffness=best["stiffness"],
            com_height=best["com_height"],
            margin=best["com_height"] - self.params.foot_lateral_radius,
            normal_forces=best["normal_forces"],
            friction_needed=best["friction_needed"],
            swing_clearance=best["swing_clearance"],
            splay=best["splay"],
            n_equilibria=len(eqs),
            note="; ".join(best["notes"]),
            why_infeasible="; ".join(best["infeasible"]),
        )


# ------------------------------------------------------------------------------------------------
def _solve(fun, jac, x0: np.ndarray, method: str) -> np.ndarray | None:
    """Least-squares root of ``fun`` from ``x0``; None unless the residual vanishes."""
    try:
        sol = least_squares(fun, x0, jac=jac, method=method, xtol=1e-14, ftol=1e-14, gtol=1e-14,
                            max_nfev=200)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(sol.x)) or np.max(np.abs(sol.fun)) > _RESIDUAL_TOL:
        return None
    return sol.x


def _wrap(q: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi]."""
    return np.mod(q + math.pi, 2 * math.pi) - math.pi


def _add_unique(found: list[_Equilibrium], eq: _Equilibrium) -> None:
    for other in found:
        diff = _wrap(other.q - eq.q)
        if np.max(np.abs(diff)) < 1e-6:
            return
    found.append(eq)


def _modes(m_red: np.ndarray, k_red: np.ndarray, m_scale: float, k_scale: float):
    """Linear modes of ``m_red v'' = k_red v``: list of (mu = s^2, vector, unstable).

    Massless directions of ``m_red`` are quasi-static: restoring ones are eliminated (Schur
    complement), falling ones are returned with mu = +inf, force-free ones are neutral (mu = 0).
    A mode is neutral when its modal stiffness |mu| * modal inertia is below the tolerance.
    """
    size = m_red.shape[0]
    if size == 0:
        return []
    m_sym = 0.5 * (m_red + m_red.T)
    w, v = np.linalg.eigh(m_sym)
    massive = w > _MASS_TOL * m_scale
    out = []
    r_basis = v[:, massive]
    z_basis = v[:, ~massive]
    slaved = np.zeros((size, 0))
    if z_basis.shape[1]:
        kzz = z_basis.T @ k_red @ z_basis
        kappa, rot = np.linalg.eigh(0.5 * (kzz + kzz.T))
        z_rot = z_basis @ rot
        for i, kap in enumerate(kappa):
            if kap > _STIFF_TOL * k_scale:
                out.append((complex(math.inf), z_rot[:, i], True))
            elif kap >= -_STIFF_TOL * k_scale:
                out.append((0j, z_rot[:, i], False))
        slaved = z_rot[:, kappa < -_STIFF_TOL * k_scale]
    if r_basis.shape[1] == 0:
        return out
    k_rr = r_basis.T @ k_red @ r_basis
    if slaved.shape[1]:
        k_ss = slaved.T @ k_red @ slaved
        coupling = np.linalg.solve(k_ss, slaved.T @ k_red @ r_basis)
        k_rr = k_rr - (r_basis.T @ k_red @ slaved) @ coupling
    else:
        coupling = np.zeros((0, r_basis.shape[1]))
    m_rr = r_basis.T @ m_sym @ r_basis
    asym = np.max(np.abs(k_rr - k_rr.T))
    if asym <= 1e-12 * max(np.max(np.abs(k_rr)), k_scale * 1e-300):
        mus, vecs = scipy.linalg.eigh(0.5 * (k_rr + k_rr.T), m_rr)
        mus = mus.astype(complex)
    else:
        mus, vecs = scipy.linalg.eig(k_rr, m_rr)
    for i, mu in enumerate(mus):
        y = vecs[:, i]
        vec = r_basis @ y - slaved @ (coupling @ y)
        modal_mass = float(np.real(np.conj(y) @ m_rr @ y) / np.real(np.conj(y) @ y))
        modal = abs(mu) * modal_mass
        if modal <= _STIFF_TOL * k_scale:
            out.append((0j, vec, False))
        else:
            unstable = mu.real * modal_mass > _STIFF_TOL * k_scale or \
                abs(mu.imag) * modal_mass > _STIFF_TOL * k_scale
            out.append((complex(mu), vec, bool(unstable)))
    return out


def _describe_mode(vec: np.ndarray) -> str:
    """Plain words for a mode shape in q = (phi, psi, theta_st, theta_sw)."""
    mag = np.abs(vec)
    if not np.any(mag > 0):
        return ""
    mag = mag / mag.max()
    steer, lean, st, sw = mag
    if lean >= max(st, sw, steer) * 0.999:
        return "sideways (lean)"
    if steer >= max(st, sw):
        return "by turning (steer)"
    re = np.real(vec * np.exp(-1j * np.angle(vec[np.argmax(np.abs(vec))])))
    if st > 0.2 and sw > 0.2:
        if re[2] * re[3] > 0:
            return "forward or backward (pitch)"
        return "by splaying its legs"
    if st >= sw:
        return "forward or backward (stance-leg pitch)"
    return "by swinging its free leg"


def _ground(slope: float) -> str:
    if slope == 0.0:
        return "on level ground"
    return f"on the {math.degrees(slope):.3g} degree ramp"


def _reason(params: Params, ramp, level, stands: bool, stands_level: bool) -> str:
    rho = _length(params.foot_lateral_radius)
    slope = params.slope
    if stands:
        stable = [c for c in ramp if c.stable]  # in the order of KINDS: one foot first
        conf = stable[0]
        eq = conf.equilibrium
        text = (
            f"It can stand {_ground(slope)} on {conf.kind}: a stable equilibrium at "
            + (f"heading {_angle(eq['phi'])} rad from downhill, " if slope != 0.0 else "")
            + "lean "
            f"{_angle(eq['psi'])} rad, leg pitches {_angle(eq['theta_st'])} and "
            f"{_angle(eq['theta_sw'])} rad, "
            f"with the centre of mass {_length(conf.com_height)} above the ramp, "
            f"{_above(conf.margin)} the feet's lateral centre of curvature (rho = {rho})"
        )
        if conf.kind != "one foot" and params.hip_width > 0 and conf.margin > 0:
            text += f", held up sideways by the {_length(params.hip_width)} wide two-foot base"
        text += "."
        if len(stable) > 1:
            text += " Also stable: " + "; ".join(c.kind for c in stable[1:]) + "."
    else:
        feasible = [c for c in ramp if c.status == "unstable"]
        if feasible:
            conf = min(feasible, key=lambda c: c.growth_rate)
            grow = (f"with an e-folding time of {1.0 / conf.growth_rate:.3g} s"
                    if 0 < conf.growth_rate < math.inf else "at once (a massless direction)")
            text = (
                f"It cannot stand {_ground(slope)}: no contact configuration (one foot, two feet "
                f"with parallel or splayed legs) is stable. The closest, {conf.kind}, falls "
                f"{conf.mode} {grow}; its centre of mass is {_length(conf.com_height)} above "
                f"the ramp, {_above(conf.margin)} the feet's lateral centre of curvature "
                f"(rho = {rho})."
            )
        else:
            found = [c for c in ramp if c.status == "infeasible"]
            text = (f"It cannot stand {_ground(slope)}: no contact configuration has a feasible "
                    "equilibrium")
            if found:
                conf = min(found, key=lambda c: c.friction_needed)
                text += f"; the closest, {conf.kind}, fails because {conf.why_infeasible}"
            text += "."
    if slope != 0.0 and stands_level != stands:
        if stands_level:
            conf = next(c for c in level if c.stable)
            text += f" On level ground it could stand on {conf.kind}."
        else:
            text += " On level ground it could not."
    active = sorted(params.active_effects)
    if active:
        text += f" The effects {', '.join(active)} are not part of this static check."
    return text


def _angle(x: float) -> str:
    """An angle (rad) for people: round-off shown as 0."""
    return "0" if abs(x) < 1e-9 else f"{x:.3g}"


def _length(x: float) -> str:
    """A length for people: millimetres below a metre, else metres."""
    if abs(x) < 0.9995:
        return f"{x * 1e3:.3g} mm"
    return f"{x:.3g} m"


def _above(margin: float) -> str:
    return f"{_length(abs(margin))} {'above' if margin > 0 else 'below'}"
