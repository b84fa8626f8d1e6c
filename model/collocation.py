"""Periodic gaits as boundary value problems, solved by direct collocation with IPOPT.

One step is a two-point boundary value problem on [0, T] with free duration T (docs/model.md section 5):
the equations of motion on the interval, the guard ``h(x(T)) = 0`` at the end (with the swing foot
ahead of the stance foot and moving down), and ``x(0) = mirror(collision(x(T)))``. Time is scaled
to tau = t / T in [0, 1], cut into ``n_intervals`` equal intervals, each with a Lagrange polynomial
of degree ``degree`` through Gauss-Legendre points (Biegler, *Nonlinear Programming*, SIAM 2010,
ch. 10; CasADi's ``collocation_coeff``). Gauss-Legendre collocation is a Runge-Kutta method of order
``2 * degree``: with the defaults (30 intervals, degree 4) the fixed point agrees with shooting to
about 1e-11 on the bundled walkers (tests/model/test_collocation.py).

The NLP has no objective (a square feasibility problem: the fixed point is an isolated solution);
its parameters are the walker's parameter vector, so one NLP, built once, serves every parameter
set. Because the collocation form does not integrate forward, it keeps working for gaits too
unstable to follow by simulation, and it is the form used to fit data.

The step-map Jacobian of a collocation gait is obtained independently of the shooting solver: the
implicit-function theorem on the collocation equations with the start state as a parameter gives
dx(T)/dx(0) (the guard fixing T), and the collision's Jacobian completes dP/dz.
"""

from __future__ import annotations

import dataclasses
from functools import cache

import casadi as ca
import numpy as np

from .compiled import cached_with_derivatives
from .equations import build_functions, layout
from .gait import Stability
from .parameters import N_INPUT, Params, view
from .walker import Walker

__all__ = ["BVP", "CollocationGait", "bvp", "contact_travel", "cycle_jacobian", "initial_guess",
           "interval_equations", "native_interval", "solve_collocation", "step_displacements"]


@dataclasses.dataclass
class CollocationGait(Stability):
    """A gait found by collocation.

    Attributes
    ----------
    fixed_point : ndarray, shape (8,)
        State just after heel strike (public order).
    step_time : float
        (s)
    success : bool
        IPOPT converged and the residuals are small.
    status : str
        IPOPT's return status.
    max_residual : float
        Largest violation of the collocation, boundary and guard equations.
    times : ndarray, shape (n,)
        Mesh and collocation times (s), increasing.
    states : ndarray, shape (n, n_dyn)
        Internal dynamic states at ``times``.
    jacobian : ndarray, shape (8, 8)
        Step-map Jacobian from the collocation equations (public order).
    eigenvalues : ndarray, complex
        Its eigenvalues, sorted by decreasing modulus.
    iterations : int
        IPOPT iterations.
    solution : ndarray
        The NLP's primal solution (pass as ``warm_start`` to a neighbouring solve).
    """

    fixed_point: np.ndarray
    step_time: float
    success: bool
    status: str
    max_residual: float
    times: np.ndarray
    states: np.ndarray
    jacobian: np.ndarray
    eigenvalues: np.ndarray
    iterations: int
    solution: np.ndarray
    multipliers: np.ndarray


@dataclasses.dataclass(eq=False)  # one object per (system, mesh, period): hashed by identity
class BVP:
    """The gait boundary value problem of one system, mesh and number of steps, built once.

    Periodic (a gait): the last step's collision leads back to the first step's start. Transient
    (``periodic`` False, a walk of ``phases`` recorded steps from a free start): no closure; the
    first step starts in a heel-strike state (its swing foot on the ramp, ``h(x_0) = 0``, the one
    equation that takes the closure's place), leaving ``n_dyn - 1`` free directions of the start.

    Attributes
    ----------
    solver : casadi.Function
        IPOPT on the square feasibility problem (x = w, p = the parameter input).
    constraints : casadi.Function
        ``(w, p) -> g``: collocation and continuity, guards, periodicity, then the inequalities;
        ``lbg <= g <= ubg``.
    n_dyn, n_int, degree, phases : int
        Dynamic state size, mesh intervals per step, collocation degree, steps per period (or
        steps of the walk).
    periodic : bool
    tau : ndarray, shape (degree,)
        Gauss-Legendre points in (0, 1).
    jac_fun : casadi.Function
        ``(w, p) -> dg/dw``.
    soft : bool
        The heel strike is the compliant one (``effects.soft_heel``, :func:`soft_link`): each
        step's unknown ``T`` is then the whole step, its flow lasting ``T - span tau`` and the
        phase ``span tau`` (:func:`strike_phase`).
    """

    solver: ca.Function
    constraints: ca.Function  # (w, p) -> g
    n_dyn: int
    n_int: int
    degree: int
    phases: int
    lbg: np.ndarray
    ubg: np.ndarray
    tau: np.ndarray
    jac_fun: ca.Function  # (w, p) -> dg/dw
    periodic: bool = True
    soft: bool = False

    @property
    def phase_size(self) -> int:
        """Decision variables of one step: [T, X_0, (Xc_k (degree states), X_{k+1}) per interval]."""
        return 1 + self.n_dyn + self.n_int * self.n_dyn * (self.degree + 1)

    @property
    def phase_equations(self) -> int:
        """Collocation and continuity equations of one step, then its guard h = 0."""
        return self.n_int * self.n_dyn * (self.degree + 1) + 1

    @property
    def n_equalities(self) -> int:
        """The equality constraints (they come first in g): as many as decision variables in a
        periodic problem; ``n_dyn - 1`` fewer in a transient one (the free start)."""
        links = self.phases if self.periodic else self.phases - 1
        return self.phases * self.phase_equations + links * self.n_dyn + (0 if self.periodic else 1)

    @property
    def start_guard_index(self) -> int:
        """Index in g of a transient problem's start condition ``h(x_0) = 0`` (the last equality)."""
        if self.periodic:
            raise ValueError("a periodic problem has no start condition")
        return self.n_equalities - 1

    def duration_index(self, phase: int) -> int:
        """Index in w of the step's duration T."""
        return phase * self.phase_size

    def state_index(self, phase: int, interval: int, point: int) -> int:
        """Index in w of the first component of a state: ``point`` 0 is the interval's start (the
        previous interval's end), 1..degree its collocation points."""
        base = phase * self.phase_size + 1
        if point == 0:
            if interval == 0:
                return base
            return base + self.n_dyn + (interval - 1) * self.n_dyn * (self.degree + 1) \
                + self.n_dyn * self.degree
        return base + self.n_dyn + interval * self.n_dyn * (self.degree + 1) + (point - 1) * self.n_dyn


def _phase_input(p: ca.MX, phase: int) -> ca.MX:
    """The parameter input of a stride's step: the left leg in stance first, then the right."""
    return p if phase % 2 == 0 else ca.vertcat(p[:-1], -p[-1])


def interval_equations(planar: bool, degree: int) -> ca.Function:
    """One mesh interval's collocation and continuity equations, an SX function
    ``interval(x_k[nd], x_c[nd * degree], x_next[nd], h, p[N_INPUT]) -> (nd * (degree + 1),)``:
    the collocation residuals ``Z C - h f(x_c)`` (Legendre points, ``Z = [x_k, x_c]``) and the
    continuity ``Z D - x_next``.

    The gait's BVP maps it over the mesh: its derivatives (IPOPT's constraint Jacobian and
    Lagrangian Hessian) are then mapped functions of one interval, several times faster to
    evaluate than the same equations written interval by interval in the MX graph (measured on
    a 12-step transient fit: 3 s to 0.45 s per Hessian in CasADi's virtual machine), without
    expanding the whole graph to SX (minutes to build).
    """
    lay = layout(planar)
    nd = lay.n_dyn
    base = build_functions(planar)
    ps = ca.SX.sym("p", N_INPUT)
    xk_s, xn_s = ca.SX.sym("xk", nd), ca.SX.sym("xn", nd)
    xc_s, h_s = ca.SX.sym("xc", nd * degree), ca.SX.sym("h")
    xc_m = ca.reshape(xc_s, nd, degree)
    pad = ca.SX.zeros(lay.nx - nd)
    f_c = ca.horzcat(*[base["rhs"](ca.vertcat(xc_m[:, j], pad), ps)[:nd] for j in range(degree)])
    tau = list(ca.collocation_points(degree, "legendre"))
    c_mat, d_vec, _ = (np.array(m) for m in ca.collocation_coeff(tau))
    z_s = ca.horzcat(xk_s, xc_m)
    return ca.Function("interval", [xk_s, xc_s, xn_s, h_s, ps], [ca.vertcat(
        ca.vec(ca.mtimes(z_s, c_mat) - h_s * f_c), ca.mtimes(z_s, d_vec) - xn_s)])


@cache
def native_interval(planar: bool, degree: int) -> ca.Function:
    """:func:`interval_equations` compiled with its first and second derivatives
    (:func:`toywalk.model.compiled.cached_with_derivatives`; once per machine, cached on disk):
    one library serves every mesh size, stride length, parameter set and effect. A fit's IPOPT
    iteration then costs several times less than in CasADi's virtual machine (measured on a
    three-walk, 12-step joint fit of stable-toy with hip dry friction: Lagrangian Hessian 430 ->
    51 ms, constraint Jacobian 250 -> 21 ms an evaluation; the same estimates to 10 digits).
    The symbolic function itself without a compiler (``TOYWALK_JIT=0``)."""
    return cached_with_derivatives(f"interval planar={planar} degree={degree}",
                                   lambda: interval_equations(planar, degree))


@cache
def soft_link(planar: bool) -> ca.Function:
    """:func:`toywalk.model.compliant.collocation_strike` compiled with its first derivatives
    (once per machine, cached on disk like :func:`native_interval`; about 40 s), its own
    curvature left out of an NLP's Lagrangian Hessian (``curvature=False`` of
    :func:`toywalk.model.compiled.cached_with_derivatives`): the strike's exact Hessian costs 0.8 s
    an evaluation on the 3D walker, its Jacobian 0.04 s, and IPOPT's limited-memory Hessian in its
    place left a fit of the clearing toy's soft heel short of convergence after 400 s."""
    from .compliant import collocation_strike

    return cached_with_derivatives(f"soft_link planar={planar}", lambda: collocation_strike(planar),
                                   curvature=False)


@cache
def _soft_strike(planar: bool) -> ca.Function:
    """:func:`soft_link` of a dynamic state (the travel padded with zeros), ``(x[nd], p) ->
    x_plus[nx]``: the transcription's link and its contact jump both read it."""
    lay = layout(planar)
    xm, pm = ca.MX.sym("x", lay.n_dyn), ca.MX.sym("p", N_INPUT)
    return ca.Function("soft_strike", [xm, pm],
                       [soft_link(planar)(ca.vertcat(xm, ca.MX.zeros(lay.nx - lay.n_dyn)), pm)])


def strike_phase(p):
    """The compliant heel strike's duration (s) from a parameter input (NumPy or CasADi): the
    phase's ``span`` time constants (toywalk.model.compliant.SPAN; 0 on rigid feet)."""
    from .compliant import SPAN

    return SPAN * view(p).effects["soft_heel"]


@cache
def bvp(planar: bool, n_intervals: int = 30, degree: int = 4, phases: int = 1,
        periodic: bool = True, soft: bool = False) -> BVP:
    """The (cached) gait BVP of the 3D or planar system over ``phases`` steps: periodic (a gait,
    one step or a stride) or transient (a walk from a free heel-strike start; see :class:`BVP`).

    A step's parameter input alternates its side entry (left leg in stance, then right): pass the
    input of the first step's side as ``p``.

    ``soft``: the heel strike is the compliant one (the ``soft_heel`` effect, :func:`soft_link`),
    its phase part of each step's duration ``T`` (:class:`BVP`); the rigid strike otherwise, the
    effect's strength then unused.
    """
    lay = layout(planar)
    nd = lay.n_dyn
    base = build_functions(planar)
    pad = lay.nx - nd
    xs = ca.SX.sym("x", nd)
    ps = ca.SX.sym("p", N_INPUT)
    full = ca.vertcat(xs, ca.SX.zeros(pad))
    g_end = ca.Function("g_end", [xs, ps], [base["guard"](full, ps)])
    rdot = ca.Function("hdot", [xs, ps], [ca.mtimes(ca.jacobian(base["guard"](full, ps)[0], xs),
                                                     base["rhs"](full, ps)[:nd])])
    if soft:
        xm, pm = ca.MX.sym("x", nd), ca.MX.sym("p", N_INPUT)
        coll = ca.Function("coll", [xm, pm], [_soft_strike(planar)(xm, pm)[:nd]])
    else:
        coll = ca.Function("coll", [xs, ps], [base["collision"](full, ps)[:nd]])

    tau = np.array(ca.collocation_points(degree, "legendre"))
    size = 1 + nd + n_intervals * nd * (degree + 1)
    w = ca.MX.sym("w", size * phases)
    p = ca.MX.sym("p", N_INPUT)
    par = view(p)
    mesh = native_interval(planar, degree).map(n_intervals)
    eqs, lb, ub = [], [], []
    starts, ends, guards = [], [], []
    # Per step: collocation and continuity on its own [0, T_k], then its guard h(x_N) = 0.
    for phase in range(phases):
        pk = _phase_input(p, phase)
        offset = phase * size
        big_t = w[offset] - (strike_phase(p) if soft else 0)  # the flow's duration
        x0 = w[offset + 1:offset + 1 + nd]
        block = ca.reshape(w[offset + 1 + nd:offset + size], nd * (degree + 1), n_intervals)
        x_next = block[nd * degree:, :]
        x_start = ca.horzcat(x0, x_next[:, :n_intervals - 1])
        eqs.append(ca.vec(mesh(x_start, block[:nd * degree, :], x_next,
                               ca.repmat(big_t / n_intervals, 1, n_intervals),
                               ca.repmat(pk, 1, n_intervals))))
        xk = x_next[:, n_intervals - 1]
        guard = g_end(xk, pk)
        eqs.append(guard[0])
        starts.append(x0)
        ends.append(xk)
        guards.append((big_t, x0, xk, guard, pk))
    n_eq = sum(e.shape[0] for e in eqs)
    lb += [0.0] * n_eq
    ub += [0.0] * n_eq
    # Each step starts where the previous one's collision (relabel and mirror) leaves it; the
    # last closes the period, or a transient walk starts with its swing foot on the ramp.
    links = phases if periodic else phases - 1
    for phase in range(links):
        nxt = (phase + 1) % phases
        eqs.append(starts[nxt] - coll(ends[phase], _phase_input(p, phase)))
    if not periodic:
        eqs.append(g_end(starts[0], p)[0])
    n_link = nd * links + (0 if periodic else 1)
    lb += [0.0] * n_link
    ub += [0.0] * n_link
    # The heel strike ahead and moving down; exclude the trivial zero-length "step" with the legs
    # together: the swing foot starts behind the stance foot (as in Walker.step) and the step
    # lasts at least 0.05 sqrt(l/g) (its flow, with soft feet).
    for big_t, x0, xk, guard, pk in guards:
        start_ahead = g_end(x0, pk)[1]
        eqs += [guard[1], rdot(xk, pk), big_t - 0.05 * ca.sqrt(par.leg_length / par.gravity),
                start_ahead + 1e-6 * par.leg_length]
        lb += [0.0, -np.inf, 0.0, -np.inf]
        ub += [np.inf, 0.0, np.inf, 0.0]
    g = ca.vertcat(*eqs)
    nlp = {"x": w, "p": p, "f": 0, "g": g}
    opts = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.tol": 1e-12,
        "ipopt.constr_viol_tol": 1e-12,
        "ipopt.max_iter": 200,
        "ipopt.sb": "yes",
        # A square feasibility problem: the Newton step is set by the constraint Jacobian, so a
        # quasi-Newton Hessian converges in as many iterations as the exact one, at half the cost
        # per iteration (measured on compass-3d: 3 iterations either way, 0.27 s vs 0.49 s warm).
        "ipopt.hessian_approximation": "limited-memory",
    }
    solver = ca.nlpsol("gait_collocation", "ipopt", nlp, opts)
    constraints = ca.Function("g", [w, p], [g])
    jac_fun = ca.Function("dg", [w, p], [ca.jacobian(g, w)])
    return BVP(solver=solver, constraints=constraints, n_dyn=nd, n_int=n_intervals,
                    degree=degree, phases=phases, lbg=np.array(lb), ubg=np.array(ub), tau=tau,
                    jac_fun=jac_fun, periodic=periodic, soft=soft)


@cache
def contact_travel(prob: BVP) -> ca.Function:
    """``(w, p) -> (rolled, jump)``: the stance contact's travel on each mesh interval,
    ``rolled`` shape (2, phases * n_int) (interval ``k`` of step ``j`` in column ``j * n_int +
    k``), and the collision's jump from the old contact to the new one at each step's end,
    ``jump`` shape (2, phases) (m, each step's own mirrored ramp frame; docs/model.md section 4).

    An interval's travel is the integral of the travel rates of the equations of motion (docs/model.md
    section 3) by the collocation's own Gauss-Legendre quadrature (exact to the collocation's
    order). Each output depends on one interval's (or one end state's) unknowns only, so the
    derivatives stay as sparse as the BVP's. A planar system has no sideways component (0).
    """
    planar = prob.n_dyn == layout(True).n_dyn
    lay = layout(planar)
    nd, d = prob.n_dyn, prob.degree
    base = build_functions(planar)
    pad = lay.nx - nd
    xs, ps = ca.SX.sym("x", nd), ca.SX.sym("p", N_INPUT)
    full = ca.vertcat(xs, ca.SX.zeros(pad))
    rate = base["rhs"](full, ps)[nd:]
    jump = base["collision"](full, ps)[nd:]
    if pad == 1:
        rate, jump = ca.vertcat(rate, 0), ca.vertcat(jump, 0)
    f_rate = ca.Function("travel_rate", [xs, ps], [rate])
    if prob.soft:
        xm, pm = ca.MX.sym("x", nd), ca.MX.sym("p", N_INPUT)
        jump = _soft_strike(planar)(xm, pm)[nd:]
        f_jump = ca.Function("contact_jump", [xm, pm], [ca.vertcat(jump, 0) if pad == 1 else jump])
    else:
        f_jump = ca.Function("contact_jump", [xs, ps], [jump])
    b_vec = np.array(ca.collocation_coeff(list(prob.tau))[2]).ravel()
    xc_s, h_s = ca.SX.sym("xc", nd * d), ca.SX.sym("h")
    xc_m = ca.reshape(xc_s, nd, d)
    travel = h_s * sum(float(b_vec[j]) * f_rate(xc_m[:, j], ps) for j in range(d))
    interval = ca.Function("interval_travel", [xc_s, h_s, ps], [travel]).map(prob.n_int)
    w = ca.MX.sym("w", prob.phases * prob.phase_size)
    p = ca.MX.sym("p", N_INPUT)
    rolled, jumps = [], []
    for phase in range(prob.phases):
        pk = _phase_input(p, phase)
        offset = phase * prob.phase_size
        block = ca.reshape(w[offset + 1 + nd:offset + prob.phase_size], nd * (d + 1), prob.n_int)
        flow = w[offset] - (strike_phase(p) if prob.soft else 0)
        rolled.append(interval(block[:nd * d, :], ca.repmat(flow / prob.n_int, 1, prob.n_int),
                               ca.repmat(pk, 1, prob.n_int)))
        jumps.append(f_jump(block[nd * d:, prob.n_int - 1], pk))
    return ca.Function("contact_travel", [w, p], [ca.horzcat(*rolled), ca.horzcat(*jumps)],
                       ["w", "p"], ["rolled", "jump"])


def step_displacements(prob: BVP) -> ca.Function:
    """``(w, p) -> D``, shape (2, phases): each step's advance of the stance contact, from the
    contact at its first heel strike to the new one at its end (m, the step's own mirrored ramp
    frame: a step with the right leg in stance has its sideways component negated; docs/model.md
    section 4, as :attr:`toywalk.model.walker.Step.contact`): the rolled travel of its mesh
    intervals plus the collision's jump (:func:`contact_travel`)."""
    w = ca.MX.sym("w", prob.phases * prob.phase_size)
    p = ca.MX.sym("p", N_INPUT)
    rolled, jump = contact_travel(prob)(w, p)
    per_step = ca.horzcat(*[ca.sum2(rolled[:, j * prob.n_int:(j + 1) * prob.n_int])
                            for j in range(prob.phases)])
    return ca.Function("step_displacements", [w, p], [per_step + jump], ["w", "p"], ["D"])


def initial_guess(walker: Walker, z0: np.ndarray, prob: BVP, side: int = 1) -> np.ndarray:
    """Collocation variables from a forward simulation of the problem's steps from z0, the first
    with ``side`` in stance (states at the collocation times by cubic Hermite interpolation of the
    recorded integration grid)."""
    from scipy.interpolate import CubicHermiteSpline

    nd = prob.n_dyn
    w, steps, z = [], [], np.asarray(z0, dtype=float)
    for k in range(prob.phases):
        steps.append(walker.step(z, record=True, side=side if k % 2 == 0 else -side))
        z = steps[-1].z_plus
    for step in steps:
        states = step.states[:, :nd]
        derivs = np.array([walker.rhs(x, step.side)[:nd] for x in step.states])
        spline = CubicHermiteSpline(step.times, states, derivs, axis=0)
        big_t = step.step_time
        w += [np.array([big_t]), states[0]]
        h = 1.0 / prob.n_int
        for k in range(prob.n_int):
            tc = (k + prob.tau) * h * big_t
            w.append(spline(tc).T.ravel(order="F"))
            w.append(spline(min((k + 1) * h * big_t, step.times[-1])))
    return np.concatenate(w)


def solve_collocation(params: Params, z_guess: np.ndarray | None = None, planar: bool = False,
                      n_intervals: int = 30, degree: int = 4,
                      warm_start: CollocationGait | None = None) -> CollocationGait:
    """Solve the periodic-gait BVP by collocation.

    Parameters
    ----------
    params : Params
    z_guess : ndarray, shape (8,), optional
        A state near the gait's fixed point; one step is simulated from it for the initial guess.
    planar : bool
        Solve the planar reduction.
    n_intervals, degree : int
        Mesh intervals and the collocation polynomials' degree.
    warm_start : CollocationGait, optional
        A neighbouring solution (same mesh) to start from instead of a simulation.

    A walker whose effects break the mirror symmetry is solved over a stride (two steps, the left
    leg in stance first, each with its own duration and mesh); the fixed point, Jacobian and
    eigenvalues are then the stride map's, and ``step_time`` is half the stride's duration.

    Returns
    -------
    CollocationGait
        ``success`` False (with IPOPT's status) if it did not converge; never raises for that.

    With ``effects.soft_heel`` on, the heel strike is the compliant one (:func:`soft_link`; the
    step map's above :data:`toywalk.model.compliant.TAU_LINEAR`) and ``step_time`` holds its
    phase, as the step map's does.
    """
    walker = Walker(params, planar=planar)
    prob = bvp(planar, n_intervals, degree, walker.period, soft=walker.soft_kernels is not None)
    p = params.input_vector()
    if warm_start is not None:
        w0, lam0 = warm_start.solution, warm_start.multipliers
    elif z_guess is not None:
        w0, lam0 = initial_guess(walker, np.asarray(z_guess, float), prob), None
    else:
        raise ValueError("solve_collocation needs z_guess or warm_start")
    kwargs = dict(x0=w0, p=p, lbg=prob.lbg, ubg=prob.ubg)
    if lam0 is not None:
        kwargs["lam_g0"] = lam0
    sol = prob.solver(**kwargs)
    stats = prob.solver.stats()
    w = np.array(sol["x"]).ravel()
    g = np.array(prob.constraints(w, p)).ravel()
    viol = np.maximum(prob.lbg - g, 0) + np.maximum(g - prob.ubg, 0)
    max_res = float(np.max(viol))
    nd = prob.n_dyn
    times, states = _trajectory(w, prob, float(strike_phase(p)) if prob.soft else 0.0)
    x0 = w[1:1 + nd]
    jac = cycle_jacobian(w, p, prob, walker)
    vals = np.linalg.eigvals(jac[np.ix_(_active(planar), _active(planar))]) if planar else \
        np.linalg.eigvals(jac)
    if planar:
        vals = np.concatenate([vals, np.zeros(4)])
    order = np.argsort(-np.abs(vals), kind="stable")
    success = bool(stats["success"]) and max_res < 1e-8
    durations = w[::prob.phase_size][:prob.phases]
    return CollocationGait(
        fixed_point=walker.to_public(np.concatenate([x0, np.zeros(walker.lay.nx - nd)])),
        step_time=float(np.mean(durations)), success=success, status=str(stats["return_status"]),
        max_residual=max_res, times=times, states=states, jacobian=jac, eigenvalues=vals[order],
        iterations=int(stats["iter_count"]), solution=w,
        multipliers=np.array(sol["lam_g"]).ravel())


def _active(planar: bool) -> list[int]:
    return [4, 5, 6, 7] if planar else list(range(8))


def _trajectory(w: np.ndarray, prob: BVP, lead: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Mesh and collocation times (s, from the start of the period) and the states there; each
    step's flow starts ``lead`` (s) after its start, the compliant strike's phase."""
    nd, d = prob.n_dyn, prob.degree
    times, states = [], []
    t0 = 0.0
    for phase in range(prob.phases):
        offset = phase * prob.phase_size
        big_t = w[offset]
        h = (big_t - lead) / prob.n_int
        t0 += lead
        times.append(t0)
        states.append(w[offset + 1:offset + 1 + nd])
        offset += 1 + nd
        for k in range(prob.n_int):
            xc = w[offset:offset + nd * d].reshape(d, nd)
            offset += nd * d
            times.extend(t0 + (k + prob.tau) * h)
            states.extend(xc)
            times.append(t0 + (k + 1) * h)
            states.append(w[offset:offset + nd])
            offset += nd
        t0 += big_t - lead
    return np.array(times), np.array(states)


def cycle_jacobian(w: np.ndarray, p: np.ndarray, prob: BVP, walker: Walker) -> np.ndarray:
    """dP/dz by the implicit-function theorem on each step's collocation and guard equations.

    Per step: unknowns y = (T, interior states, end state), parameters x0; equations collocation
    and continuity (all intervals) and the guard h(x_N) = 0; then the step's map is
    C_x(x_N) dx_N/dx0, and a stride's is the product of its two steps'.
    """
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    nd, size, n_eq = prob.n_dyn, prob.phase_size, prob.phase_equations
    dg = prob.jac_fun(w, p)
    col_ptr, row_idx = (np.array(v) for v in dg.sparsity().get_ccs())
    jac = csc_matrix((np.array(dg.nonzeros()), row_idx, col_ptr), shape=dg.shape).tocsr()
    total = np.eye(nd)
    for phase in range(prob.phases):
        rows = np.arange(phase * n_eq, (phase + 1) * n_eq)
        first = phase * size
        cols_x0 = np.arange(first + 1, first + 1 + nd)
        cols_y = np.r_[first, np.arange(first + 1 + nd, first + size)]
        a = jac[rows][:, cols_y].tocsc()
        b = jac[rows][:, cols_x0].toarray()
        dxn = -splu(a).solve(b)[-nd:]  # the end state is the last block of the step's variables
        x_end = np.concatenate([w[first + size - nd:first + size], np.zeros(walker.lay.nx - nd)])
        side = 1 if phase % 2 == 0 else -1
        soft = walker.soft_kernels
        strike = walker.eng.k["collision_jac"] if soft is None else soft["soft_strike_jac"]
        _, c_x, _ = strike(x_end, walker.params.input_vector(side))
        total = c_x[:nd, :nd] @ dxn @ total
    return walker._jac_to_public(total)
