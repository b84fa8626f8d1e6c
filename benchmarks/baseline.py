"""The step map "the way a Python user would without this toolkit": SciPy's adaptive integrator.

This is the comparison point of ``run_all.py``, not part of the package. It integrates the same
equations of motion as :class:`toywalk.model.walker.Walker` with :func:`scipy.integrate.solve_ivp`
(method ``DOP853``, Hairer, Norsett & Wanner, *Solving Ordinary Differential Equations I*, 2nd ed.,
1993, section II.10; adaptive steps, ``rtol = atol = 1e-12``), locates heel strike with SciPy's
event machinery (root of the dense output), applies :meth:`Walker.collide` and obtains the Jacobian
by central finite differences of the whole step map.

Heel strike is the swing foot's lowest point reaching the ramp, moving down, *after* the swing foot
has passed in front of the stance foot (model.md section 4). Earlier touches while the legs pass
(scuffing; the simplest walker's point foot always dips below the ramp there) must be ignored. A
single event "h if ahead > 0 else 1" is discontinuous where the foot passes the stance foot, and
the root finder would report that jump as a heel strike whenever the foot is below the ramp at that
moment. So, as SciPy users handle guarded events, the step is integrated in two phases: until the
swing foot passes the stance foot (terminal event ``ahead``, rising), then on until heel strike
(terminal event ``h``, falling).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from toywalk.model.walker import Walker

__all__ = ["ScipyStepMap"]

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
    rhs : {"vm", "compiled"}
        ``"vm"``: the uncompiled CasADi ``rhs`` Function (``build_functions(planar)["rhs"]``) called
        with NumPy arrays, i.e. what a user who wrote the equations in Python would have.
        ``"compiled"``: the toolkit's compiled kernel (fair comparison of the methods alone).
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
        else:
            raise ValueError(f"rhs must be 'vm' or 'compiled', got {rhs!r}")
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
