"""The step map "the way a Python user would without this toolkit": SciPy's adaptive integrator.

This is the comparison point of ``run_all.py``, not part of the package. It integrates the same
equations of motion as :class:`toywalk.model.walker.Walker` with :func:`scipy.integrate.solve_ivp`
(method ``DOP853``, Hairer, Norsett & Wanner, *Solving Ordinary Differential Equations I*, 2nd ed.,
1993, section II.10; adaptive steps, ``rtol = atol = 1e-12``), locates heel strike with SciPy's
event machinery (root of the dense output), applies :meth:`Walker.collide` and obtains the Jacobian
by central finite differences of the whole step map.

Heel strike is the swing foot's lowest point reaching the ramp, moving down, *after* the swing foot
has passed in front of the stance foot (docs/model.md section 4). Earlier touches while the legs pass
(scuffing; the simplest walker's point foot always dips below the ramp there) must be ignored. A
single event "h if ahead > 0 else 1" is discontinuous where the foot passes the stance foot, and
the root finder would report that jump as a heel strike whenever the foot is below the ramp at that
moment. So, as SciPy users handle guarded events, the step is integrated in two phases: until the
swing foot passes the stance foot (terminal event ``ahead``, rising), then on until heel strike
(terminal event ``h``, falling).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from toywalk.model.parameters import Params
from toywalk.model.walker import Walker

__all__ = ["ScipyStepMap", "planar_constants", "planar_rhs"]

#: Integration tolerances of the baseline (relative and absolute).
RTOL = 1e-12
ATOL = 1e-12
#: Central-difference step of the baseline's Jacobian (absolute, in public state units).
FD_STEP = 1e-6


class ScipyStepMap:
    """Step map by ``solve_ivp`` + event + :meth:`Walker.collide`; Jacobian by central differences.

    Parameters
    ----------
    walker : Walker
        Supplies the state layout, the guard and the collision (and the compiled kernels).
    rhs : {"vm", "compiled", "numpy"}
        ``"vm"``: the uncompiled CasADi ``rhs`` Function (``build_functions(planar)["rhs"]``) called
        with NumPy arrays, i.e. what a user who wrote the equations in Python would have.
        ``"compiled"``: the toolkit's compiled kernel (fair comparison of the methods alone).
        ``"numpy"`` (planar walkers only): :func:`planar_rhs`, equations written by hand in plain
        Python floats, as cheap a right-hand side as a Python user could write; the guard is
        the toolkit's compiled one.
    """

    def __init__(self, walker: Walker, rhs: str = "vm"):
        from toywalk.model.equations import build_functions

        self.w = walker
        self.p = walker.p
        base = build_functions(walker.planar)
        if rhs == "vm":
            fn_rhs, fn_guard = base["rhs"], base["guard"]
            p_dm = self.p

            def f(t, x):
                return fn_rhs(x, p_dm).full().ravel()

            def guard(x):
                g = fn_guard(x, p_dm).full().ravel()
                return g[0], g[1]
        elif rhs == "compiled":
            k_rhs, k_guard = walker.eng.k["rhs"], walker.eng.k["guard"]
            p_np = self.p

            def f(t, x):
                return k_rhs(x, p_np)[0].ravel().copy()

            def guard(x):
                g = k_guard(x, p_np)[0].ravel()
                return float(g[0]), float(g[1])
        elif rhs == "numpy":
            if not walker.planar:
                raise ValueError("rhs='numpy' is written for the planar walker only")
            k_guard = walker.eng.k["guard"]
            p_np, consts = self.p, planar_constants(walker.params)

            def f(t, x):
                return planar_rhs(x, consts)

            def guard(x):
                g = k_guard(x, p_np)[0].ravel()
                return float(g[0]), float(g[1])
        else:
            raise ValueError(f"rhs must be 'vm', 'compiled' or 'numpy', got {rhs!r}")
        self._f = f

        def passed(t, x):
            return guard(x)[1]

        passed.terminal = True
        passed.direction = 1.0

        def strike(t, x):
            return guard(x)[0]

        strike.terminal = True
        strike.direction = -1.0
        self._passed, self._strike = passed, strike
        self.t_max = walker.max_step_time
        self.nfev = 0

    def _phase(self, t0: float, x0: np.ndarray, event) -> tuple[float, np.ndarray]:
        sol = solve_ivp(self._f, (t0, self.t_max), x0, method="DOP853", rtol=RTOL, atol=ATOL,
                        events=event)
        self.nfev += sol.nfev
        if sol.status != 1 or len(sol.t_events[0]) == 0:
            raise RuntimeError(f"baseline: event {event.__name__!r} not reached ({sol.message})")
        return float(sol.t_events[0][0]), sol.y_events[0][0]

    def step(self, z0: np.ndarray) -> tuple[np.ndarray, float]:
        """(z_plus, step_time) from a public state just after heel strike, shape (8,)."""
        x0 = self.w.full_state(z0)
        t1, x1 = self._phase(0.0, x0, self._passed)
        t2, x2 = self._phase(t1, x1, self._strike)
        z_minus = self.w.to_public(x2)
        return self.w.collide(z_minus), t2

    def jacobian(self, z0: np.ndarray, h: float = FD_STEP) -> tuple[np.ndarray, np.ndarray, float]:
        """(z_plus, dz_plus/dz0, step_time) with central differences of step h, shape (8, 8).

        Only the walker's active coordinates are perturbed (planar: indices 4..7).
        """
        z0 = np.asarray(z0, dtype=float)
        z_plus, t = self.step(z0)
        jac = np.zeros((8, 8))
        for i in (range(4, 8) if self.w.planar else range(8)):
            e = np.zeros(8)
            e[i] = h
            jac[:, i] = (self.step(z0 + e)[0] - self.step(z0 - e)[0]) / (2.0 * h)
        return z_plus, jac, t


def planar_constants(params: Params) -> tuple:
    """The constants of :func:`planar_rhs`: (l, r, m, M_h, d_x, d_z, I_yy, g, slope)."""
    return (params.leg_length, params.foot_radius, params.leg_mass, params.axle_mass,
            params.com_offset[0], params.com_offset[2], params.inertia[1], params.gravity,
            params.slope)


def planar_rhs(x: np.ndarray, c: tuple) -> np.ndarray:
    """The planar walker's state derivative, written by hand: Lagrange's equations of two legs
    on a round (or point) foot rolling on the ramp, a point mass at the hip, the 2x2 mass matrix
    inverted by Cramer's rule.

    The formulas are those of the project's independent test oracle
    (``tests/model/roundfoot_reference.py``: ``mass_matrix`` and ``accelerations``, derived
    there), in plain floats: what a Python user writing the walker's equations for SciPy would
    have. ``run_all.py`` checks it against the toolkit's compiled right-hand side.

    Parameters
    ----------
    x : ndarray, shape (5,)
        Stance and swing pitch (rad), their rates (rad/s), the contact's travel along the ramp (m).
    c : tuple
        :func:`planar_constants`.
    """
    l, r, m, m_h, dx, dz, inertia, g, alpha = c
    th1, th2, w1, w2 = float(x[0]), float(x[1]), float(x[2]), float(x[3])
    s, a, mt = l - r, l - r + dz, m_h + 2.0 * m
    c1, s1, c2, s2 = math.cos(th1), math.sin(th1), math.cos(th2), math.sin(th2)
    c12, s12 = math.cos(th1 - th2), math.sin(th1 - th2)
    ca, sa = math.cos(alpha), math.sin(alpha)
    m11 = ((m_h + m) * (r * r + s * s + 2.0 * r * s * c1)
           + m * (r * r + a * a + dx * dx + 2.0 * r * a * c1 - 2.0 * r * dx * s1) + inertia)
    m12 = m * (r * (dz * c2 - dx * s2) + s * (dz * c12 + dx * s12))
    m22 = m * (dx * dx + dz * dz) + inertia
    dm11 = -2.0 * r * ((m_h + m) * s * s1 + m * (a * s1 + dx * c1))
    p1 = m * s * (dx * c12 - dz * s12)
    p2 = m * (-r * (dz * s2 + dx * c2) + s * (dz * s12 - dx * c12))
    dv1 = (g * ca * (-mt * s * s1 - m * (dx * c1 + dz * s1))
           - g * sa * (mt * (r + s * c1) + m * (dz * c1 - dx * s1)))
    dv2 = -g * ca * m * (dx * c2 + dz * s2) - g * sa * m * (dz * c2 - dx * s2)
    f1 = -(0.5 * dm11 * w1 * w1 + p2 * w2 * w2 + dv1)
    f2 = -(p1 * w1 * w1 + dv2)
    det = m11 * m22 - m12 * m12
    return np.array([w1, w2, (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det, r * w1])
