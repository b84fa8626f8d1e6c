"""Compiled numerical kernels of one system (3D or planar): integration steps, scans, Jacobians.

The flow between collisions is integrated with a fixed-step explicit Runge-Kutta method of order 8
(the 12-stage Dormand-Prince coefficients of DOP853; Hairer, Norsett & Wanner, *Solving Ordinary
Differential Equations I*, 2nd ed., 1993, section II.10), so that the integration is a smooth map of
its inputs and AD gives exact derivatives of the numerical flow. A step of length T is ``k`` full
steps of size ``dt`` and one final step of size ``tau`` in (0, dt] that lands on the guard.

All kernels take the parameter vector as a symbolic input and are compiled once (see
:mod:`toywalk.model.compiled`). :class:`Kernel` wraps a function with preallocated buffers for
low-overhead calls from Python.
"""

from __future__ import annotations

from functools import cache

import casadi as ca
import numpy as np

from .compiled import cached_functions
from .equations import build_functions, layout
from .parameters import N_INPUT, view

__all__ = ["CHUNKS", "SCAN", "Engine", "Kernel", "engine", "rk8_step", "soft_heel_kernels"]

#: Samples per call of the scanning kernel (states on the dt grid, guard values).
SCAN = 32
#: Chunk lengths whose Jacobians are compiled; any number of steps is a sum of these.
CHUNKS = (1, 4, 16, 64)


def rk8_step(rhs: ca.Function, x: ca.MX, dt: ca.MX, p: ca.MX) -> ca.MX:
    """One explicit Runge-Kutta step of order 8 (DOP853's 12-stage tableau, no error estimate).

    Parameters
    ----------
    rhs : casadi.Function
        ``rhs(x, p) -> xdot``.
    x : casadi.MX, shape (nx, 1)
    dt : casadi.MX, scalar
    p : casadi.MX, shape (n_p, 1)
    """
    # here, not at import: scipy.integrate takes 0.5 s to import, and a process whose kernels
    # come from the cache (model.compiled.cached_functions) never builds a step
    from scipy.integrate._ivp import dop853_coefficients as _dop853

    a, b = _dop853.A, _dop853.B
    stages = []
    for i in range(_dop853.N_STAGES):
        xi = x
        for j in range(i):
            if a[i, j] != 0.0:
                xi = xi + dt * float(a[i, j]) * stages[j]
        stages.append(rhs(xi, p))
    out = x
    for i in range(_dop853.N_STAGES):
        if b[i] != 0.0:
            out = out + dt * float(b[i]) * stages[i]
    return out


class Kernel:
    """A CasADi function called through preallocated NumPy buffers (microsecond overhead).

    Call with NumPy arrays (any shape, the right number of elements); returns the output arrays
    (views of internal buffers: copy them before the next call if they must be kept).
    """

    def __init__(self, fn: ca.Function):
        for i in range(fn.n_out()):
            if not fn.sparsity_out(i).is_dense():
                raise ValueError(f"Kernel needs dense outputs; {fn.name()} output {i} is sparse")
        self.fn = fn
        self._args = [np.zeros(fn.size_in(i), order="F") for i in range(fn.n_in())]
        self._res = [np.zeros(fn.size_out(i), order="F") for i in range(fn.n_out())]
        self._buf, self._eval = fn.buffer()
        for i, arr in enumerate(self._args):
            self._buf.set_arg(i, memoryview(arr.ravel(order="K")))
        for i, arr in enumerate(self._res):
            self._buf.set_res(i, memoryview(arr.ravel(order="K")))

    def __call__(self, *args) -> tuple[np.ndarray, ...]:
        for dst, src in zip(self._args, args, strict=True):
            dst.ravel(order="K")[:] = np.asarray(src, dtype=float).ravel(order="F")
        self._eval()
        return tuple(self._res)


class Engine:
    """The compiled kernels of one system.

    Attributes
    ----------
    lay : Layout
        State layout (3D: nx = 10, planar: nx = 5).
    fns : dict of str to casadi.Function
        The compiled functions (see :func:`engine` for the list).
    k : dict of str to Kernel
        The same, wrapped for fast calls.
    """

    def __init__(self, planar: bool, effects: bool = True, compiled: bool = True):
        self.lay = layout(planar)
        self.effects = effects
        tag = ("planar" if planar else "walker3d") + ("" if effects else "_seed")
        if compiled:  # the symbolic functions are built only when no cached library serves
            self.fns = cached_functions(tag, f"planar={planar} effects={effects}",
                                        lambda: _kernel_functions(planar, effects))
        else:
            self.fns = _kernel_functions(planar, effects)
        self.k = {name: Kernel(fn) for name, fn in self.fns.items()}

    def chunk_jacobian(self, x0: np.ndarray, n_steps: int, dt: float, p: np.ndarray,
                       params: bool = False):
        """State after ``n_steps`` steps of size dt and its Jacobians wrt x0 (and p).

        Returns ``(x_n, A, B)``: shapes (nx,), (nx, nx), (nx, N_INPUT); B is None unless ``params``.
        """
        nx = self.lay.nx
        x = np.array(x0, dtype=float)
        a_tot = np.eye(nx)
        b_tot = np.zeros((nx, N_INPUT)) if params else None
        remaining = n_steps
        for n in sorted(CHUNKS, reverse=True):
            while remaining >= n:
                if params:
                    xe, a, b = self.k[f"chunkp{n}"](x, dt, p)
                    b_tot = a @ b_tot + b
                else:
                    xe, a = self.k[f"chunk{n}"](x, dt, p)
                a_tot = a @ a_tot
                x = xe.ravel().copy()
                remaining -= n
        return x, a_tot, b_tot


def _dense(fn: ca.Function) -> ca.Function:
    """The same function with dense outputs (the buffers of :class:`Kernel` are dense)."""
    if all(fn.sparsity_out(i).is_dense() for i in range(fn.n_out())):
        return fn
    args = [ca.MX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    outs = [ca.densify(o) for o in fn.call(args)]
    return ca.Function(fn.name(), args, outs, fn.name_in(), fn.name_out())


def _kernel_functions(planar: bool, effects: bool) -> dict[str, ca.Function]:
    """The kernels of :class:`Engine`, symbolic (dense outputs), built from the equations."""
    lay = layout(planar)
    base = build_functions(planar, effects)
    nx = lay.nx
    x = ca.MX.sym("x", nx)
    p = ca.MX.sym("p", N_INPUT)
    par = view(p)
    dt = ca.MX.sym("dt")
    rhs = base["rhs"]
    guard = base["guard"]
    x_next = rk8_step(rhs, x, dt, p)
    step = ca.Function("step", [x, dt, p], [x_next], ["x", "dt", "p"], ["x_next"])
    sym = base["points"](x, p)
    # Fallen when a hip, the whole walker's centre of mass, or a leg's centre of mass (the
    # balance mass) reaches the ramp. A leg whose mass sits inside its foot (|G - O| <= r, as
    # for the simplest walker's point-mass feet) is exempt: that is the foot, not a fall.
    m, mh = par.leg_mass, par.axle_mass
    com_z = (m * (sym[2, 7] + sym[2, 8]) + mh * sym[2, 3]) / (2 * m + mh)
    foot_centre = ca.vertcat(0, 0, -(par.leg_length - par.foot_radius))
    in_foot = (ca.norm_2(par.com_offset - foot_centre)
               <= par.foot_radius + 1e-9 * par.leg_length)
    legs_z = ca.if_else(in_foot, ca.inf, ca.fmin(sym[2, 7], sym[2, 8]))
    low = ca.fmin(ca.fmin(ca.fmin(sym[2, 2], sym[2, 4]), com_z), legs_z)
    probe = ca.Function("probe", [x, p], [ca.vertcat(guard(x, p), low)], ["x", "p"], ["g"])
    scan_step = ca.Function(
        "scan_step", [x, dt, p], [x_next, probe(x_next, p)], ["x", "dt", "p"], ["x_next", "g"]
    )
    acc = scan_step.mapaccum("scan_acc", SCAN, [0], [0])
    xs, gs = acc(x, dt, p)
    scan = ca.Function("scan", [x, dt, p], [xs, gs], ["x", "dt", "p"], ["X", "G"])
    # Final step onto the guard: value, d/dtau of the guard, and all Jacobians.
    xt = step(x, dt, p)
    g_final = guard(xt, p)
    final = ca.Function(
        "final", [x, dt, p], [g_final, ca.jacobian(g_final[0], dt), xt],
        ["x", "tau", "p"], ["g", "dh_dtau", "x_T"],
    )
    final_jac = ca.Function(
        "final_jac", [x, dt, p],
        [xt, ca.jacobian(xt, x), ca.jacobian(xt, dt), ca.jacobian(xt, p)],
        ["x", "tau", "p"], ["x_T", "S_x", "S_tau", "S_p"],
    )
    h = guard(x, p)[0]
    guard_jac = ca.Function(
        "guard_jac", [x, p], [h, ca.jacobian(h, x), ca.jacobian(h, p)], ["x", "p"], ["h", "h_x", "h_p"]
    )
    xp = base["collision"](x, p)
    collision_jac = ca.Function(
        "collision_jac", [x, p], [xp, ca.jacobian(xp, x), ca.jacobian(xp, p)],
        ["x", "p"], ["x_plus", "C_x", "C_p"],
    )
    # The energy each continuous effect dissipates over one integration step: the same
    # Runge-Kutta step of the system augmented with W' = D(x), so that E(t) - E(0) + W(t)
    # vanishes to the integrator's accuracy (docs/model.md section 6's energy accounting).
    n_diss = base["dissipation"].size1_out(0)
    xw = ca.MX.sym("xw", nx + n_diss)
    rhs_aug = ca.Function("rhs_aug", [xw, p], [ca.vertcat(rhs(xw[:nx], p),
                                                          base["dissipation"](xw[:nx], p))])
    dissipated = rk8_step(rhs_aug, ca.vertcat(x, ca.MX.zeros(n_diss)), dt, p)[nx:]
    dissipation_step = ca.Function("dissipation_step", [x, dt, p], [dissipated],
                                   ["x", "dt", "p"], ["W"])
    fns = {
        "rhs": rhs, "energy": base["energy"], "guard": guard, "collision": base["collision"],
        "impact": base["impact"], "dissipation": base["dissipation"],
        "dissipation_step": dissipation_step,
        "points": base["points"], "momenta": base["momenta"], "mass_matrix": base["mass_matrix"],
        "step": step, "probe": probe, "scan": scan, "final": final, "final_jac": final_jac,
        "guard_jac": guard_jac, "collision_jac": collision_jac,
    }
    # Chunk Jacobians: wrt the state only (cheap), and wrt state and parameters.
    for n in CHUNKS:
        xe = step.fold(n)(x, dt, p)
        fns[f"chunk{n}"] = ca.Function(
            f"chunk{n}", [x, dt, p], [xe, ca.jacobian(xe, x)], ["x", "dt", "p"], ["x_end", "A"]
        )
        fns[f"chunkp{n}"] = ca.Function(
            f"chunkp{n}", [x, dt, p], [xe, ca.jacobian(xe, x), ca.jacobian(xe, p)],
            ["x", "dt", "p"], ["x_end", "A", "B"],
        )
    return {name: _dense(fn) for name, fn in fns.items()}


@cache
def engine(planar: bool, effects: bool = True, compiled: bool = True) -> Engine:
    """The (cached) :class:`Engine` of the 3D or planar system.

    ``effects=False`` gives the seed's model alone (same inputs; benchmarks and null checks);
    ``compiled=False`` runs in CasADi's virtual machine (no compile).
    """
    return Engine(planar, effects, compiled)


@cache
def soft_heel_kernels(planar: bool, compiled: bool = True,
                      steps_per_tau: int | None = None) -> dict[str, Kernel]:
    """The (cached) kernels of the compliant heel strike that replaces the collision in the step
    map when the ``soft_heel`` effect is on (:func:`toywalk.model.compliant.step_functions`):
    ``soft_strike(x, p)`` and ``soft_strike_jac(x, p)``, the contact's time constant an input as
    every parameter is. A library of their own, compiled the first time a walker with soft feet
    steps (about 5 s for the 3D walker at -O1), so that the walker's engine does not carry them.
    ``steps_per_tau``: the phase's RK4 steps per time constant (default
    :data:`toywalk.model.compliant.STEPS_PER_TAU`).
    """
    from .compliant import STEPS_PER_TAU, step_functions

    steps = STEPS_PER_TAU if steps_per_tau is None else steps_per_tau

    def build() -> dict[str, ca.Function]:
        return {name: _dense(fn) for name, fn in step_functions(planar, steps).items()}

    tag = "soft_heel_" + ("planar" if planar else "walker3d")
    variant = f"planar={planar}" + ("" if steps == STEPS_PER_TAU else f" steps_per_tau={steps}")
    fns = cached_functions(tag, variant, build) if compiled else build()
    return {name: Kernel(fn) for name, fn in fns.items()}
