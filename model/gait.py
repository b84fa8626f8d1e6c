"""Symmetric period-one gaits by shooting (Newton on the step map), and their stability.

A fixed point of the step map P (docs/model.md section 4) is a symmetric gait. It is found by Newton's
method on ``P(z) - z = 0`` with the exact AD Jacobian of :meth:`Walker.step`, damped by a
backtracking line search. From no guess, :func:`find_gait` first solves the walker's planar
reduction (d_y, I_xy, I_yz and w set to zero, phi = psi = 0; docs/model.md section 5's advice) from a
grid of starts, then follows the gait by natural-parameter continuation in a homotopy parameter
s in [0, 1] from the planar-symmetric walker (s = 0) to the requested one (s = 1).

Stability: eigenvalues of dP/dz at the fixed point (the stride map P o P has their squares). One
eigenvalue is 0 because the state after a collision lies on the guard surface.

A walker whose effects break the mirror symmetry (:attr:`Params.breaks_symmetry`) has no
step-periodic gait: its gaits are fixed points of the stride map P_R o P_L (left leg in stance
first), and their eigenvalues are the stride map's (:meth:`Walker.cycle`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np

from .effects import EFFECTS
from .parameters import Params
from .walker import (
    CLEARANCE_RESOLUTION,
    STATE_NAMES,
    Step,
    StepFailure,
    SwingClearance,
    Walker,
    is_planar_symmetric,
)

__all__ = ["Gait", "GaitNotFound", "Stability", "StrikeResolution", "continue_gait", "find_gait",
           "lateral_singular", "planar_gaits", "planar_reduction", "solve_fixed_point", "state_scale",
           "strike_resolution"]

# Newton on the fixed point: residual tolerance (max abs over the state, rad and rad/s scaled by
# sqrt(l/g)) and iteration cap.
_NEWTON_TOL = 1e-11
_NEWTON_MAXIT = 40
#: A real step-map eigenvalue this close to +1 marks a gait at a fold of its branch (a saddle-node,
#: where it merges with a partner gait): its fixed point moves by 1 / (1 - lambda), over 1000
#: times a parameter's change, and a small change can remove it. The shipped walkers' nearest
#: eigenvalues to +1 lie 2.2e-4 (the Tinkertoy fit, which sits on its fold: docs/effects_study.md)
#: and 9.9e-3 to 0.86 away.
NEAR_FOLD = 1e-3
#: Relative slope change used to tell on which side of a fold the gait exists.
_FOLD_PROBE = 1e-3
#: :func:`strike_resolution`'s verdict: the compliant strike's integration is resolved when the
#: largest eigenvalue moves by less than this when the RK4 steps per tau are quadrupled. The
#: integrator's share measured on the shipped walkers at the default 20 steps per tau runs from
#: 0.003 to 0.03 (docs/soft_feet.md section 5); 0.005 keeps the stability verdict of every gait
#: farther than that from 1.
STRIKE_EIGENVALUE_RESOLUTION = 5e-3


class GaitNotFound(RuntimeError):
    """No gait was found; the message says what was tried and why it failed (not "no gait found"
    itself: whoever reports it says that, as ``toywalk gait`` does)."""


class Stability:
    """Stability verdict from a step map's ``eigenvalues`` (an attribute of the class using it)."""

    eigenvalues: np.ndarray

    @property
    def max_abs_eigenvalue(self) -> float:
        """Largest step-map eigenvalue modulus; < 1 is asymptotically stable."""
        return float(np.max(np.abs(self.eigenvalues)))

    @property
    def stable(self) -> bool:
        return self.max_abs_eigenvalue < 1.0


@dataclasses.dataclass
class Gait(Stability):
    """A gait (a fixed point of :meth:`Walker.cycle`) and its stability.

    Attributes
    ----------
    params : Params
    planar : bool
        Solved in the planar reduction.
    fixed_point : ndarray, shape (8,)
        State just after heel strike (public order, docs/model.md section 1).
    step_time : float
        (s)
    step : Step
        The step from the fixed point, with its Jacobian and recorded trajectory.
    steps : list of Step
        The steps of one period (one, or two for a stride-periodic gait), recorded.
    eigenvalues : ndarray, shape (8,), complex
        Eigenvalues of the period map (the step map, or the stride map of a stride-periodic gait),
        sorted by decreasing modulus (planar: the four lateral ones are 0).
    eigenvectors : ndarray, shape (8, 8), complex
        Columns matching ``eigenvalues``.
    residual : float
        max |P(z) - z| at the returned fixed point.
    iterations : int
    status : str
        ``"converged"``.
    """

    params: Params
    planar: bool
    fixed_point: np.ndarray
    step_time: float
    step: Step
    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    residual: float
    iterations: int
    status: str = "converged"
    steps: list = dataclasses.field(default_factory=list)

    @property
    def period(self) -> int:
        """Steps per period: 1 (step-periodic) or 2 (stride-periodic)."""
        return len(self.steps)

    @property
    def map_jacobian(self) -> np.ndarray:
        """The period map's Jacobian at the fixed point, shape (8, 8): the steps' Jacobians
        multiplied in order (what :attr:`eigenvalues` are of)."""
        jac = np.eye(8)
        for s in self.steps:
            jac = s.jacobian @ jac
        return jac

    @property
    def fold_eigenvalue(self) -> float | None:
        """The real step-map eigenvalue within :data:`NEAR_FOLD` of +1 (the gait is at a fold of its
        branch), or None."""
        real = [float(e.real) for e in self.eigenvalues if abs(e.imag) <= 1e-12]
        near = min(real, key=lambda v: abs(v - 1.0), default=None)
        return near if near is not None and abs(near - 1.0) < NEAR_FOLD else None

    def growth_factor(self, n_steps: int) -> float:
        """How much the worst perturbation grows over n steps: |lambda_max|^(n / period)."""
        return self.max_abs_eigenvalue ** (n_steps / self.period)

    @property
    def stride_displacement(self) -> np.ndarray:
        """Advance of the contact per stride (two steps), shape (2,) (m, ramp frame): along the
        fall line and sideways (to the left); the sideways part is the drift of a turning gait."""
        if self.period == 2:
            return self.steps[0].contact + self.steps[1].contact * [1.0, -1.0]
        return np.array([2.0 * self.step.contact[0], 0.0])

    @property
    def stride_length(self) -> float:
        """Advance per stride (two steps) along the ramp's fall line (m)."""
        return float(self.stride_displacement[0])

    @property
    def stride_time(self) -> float:
        return 2.0 * self.step_time

    @property
    def heading(self) -> float:
        """The direction of travel over a stride, from the fall line towards the left (rad)."""
        dx, dy = self.stride_displacement
        return float(np.arctan2(dy, dx))

    @property
    def swing_clearance(self) -> SwingClearance:
        """How the swing foot clears the ramp over its whole swing (:class:`SwingClearance`), for
        the step of the period where it comes closest."""
        return min((s.swing for s in self.steps), key=lambda c: c.minimum)

    @property
    def clearance(self) -> float:
        """The swing foot's clearance over its whole swing (m; :class:`SwingClearance`), the
        lowest over the period's steps: negative when it goes below the ramp between heel strikes."""
        return self.swing_clearance.minimum

    @property
    def swing_foot(self) -> str:
        """``"clears"`` the ramp over its whole swing, ``"touches"`` it (a clearance within
        :data:`~toywalk.model.walker.CLEARANCE_RESOLUTION` leg lengths of 0: the feet of a walker
        with w = 0 pass through each other at the ramp) or goes ``"below"`` it."""
        tol = CLEARANCE_RESOLUTION * self.params.leg_length
        return "clears" if self.clearance > tol else ("touches" if self.clearance >= -tol else "below")

    @property
    def lean_amplitude(self) -> float:
        """Half the peak-to-peak lean psi over a stride, in the physical frame (rad): max |psi|
        for a step-periodic gait, about the mean lean for a stride-periodic one."""
        return self._amplitude("psi")

    @property
    def steer_amplitude(self) -> float:
        """Half the peak-to-peak steer phi over a stride, in the physical frame (rad): max |phi|
        for a step-periodic gait, about the heading for a stride-periodic one."""
        return self._amplitude("phi")

    def _amplitude(self, name: str) -> float:
        if self.planar:
            return 0.0
        index = {"phi": 0, "psi": 1}[name]
        if self.period == 1:  # the stride is the step and its mirror image
            return float(np.max(np.abs(self.step.states[:, index])))
        # The second step of a stride is described mirrored: its physical angles change sign.
        series = np.concatenate([s.states[:, index] * s.side for s in self.steps])
        return float(0.5 * (series.max() - series.min()))

    def dominant_components(self, k: int, n: int = 2) -> list[tuple[str, float]]:
        """The ``n`` state components with the largest share of eigenvector ``k`` (name, share).

        Rates are measured in rad per sqrt(l/g), angles in rad, so that the shares compare like
        with like (a rate in rad/s of a small, fast walker would otherwise always dominate).
        """
        vec = np.abs(self.eigenvectors[:, k]) / state_scale(self.params)
        share = vec / max(vec.sum(), 1e-300)
        order = np.argsort(share)[::-1][:n]
        return [(STATE_NAMES[i], float(share[i])) for i in order]

    def summary(self) -> dict:
        """JSON-ready summary (the keys of ``toywalk gait --json``, docs/cli.md)."""
        return {
            "status": self.status,
            "planar": self.planar,
            "map": "step" if self.period == 1 else "stride",
            "period_steps": self.period,
            "step_time": self.step_time,
            "step_times": [s.step_time for s in self.steps],
            "stride_time": self.stride_time,
            "stride_length": self.stride_length,
            "stride_drift": float(self.stride_displacement[1]),
            "heading": self.heading,
            "fixed_point": dict(zip(STATE_NAMES, map(float, self.fixed_point), strict=True)),
            "eigenvalues": [
                {"re": float(e.real), "im": float(e.imag), "abs": float(abs(e)),
                 "dominant": [c for c, _ in self.dominant_components(i)]}
                for i, e in enumerate(self.eigenvalues)
            ],
            "stride_eigenvalues": [{"re": float((e**(2 // self.period)).real),
                                    "im": float((e**(2 // self.period)).imag)}
                                   for e in self.eigenvalues],
            "max_abs_eigenvalue": self.max_abs_eigenvalue,
            "stable": self.stable,
            "growth_factor_20_steps": self.growth_factor(20),
            "lean_amplitude": self.lean_amplitude,
            "steer_amplitude": self.steer_amplitude,
            "scuffs": sum(s.scuffs for s in self.steps),
            "clearance": self.clearance,
            "swing_clearance": self.swing_clearance.as_dict(),
            "swing_foot": self.swing_foot,
            "clearance_after_passing": min(s.clearance for s in self.steps),
            "collision_loss": [s.collision_loss for s in self.steps],
            "residual": self.residual,
            "iterations": self.iterations,
            "fold_eigenvalue": self.fold_eigenvalue,
        }


def planar_reduction(params: Params) -> Params:
    """The planar-symmetric walker nearest to ``params``: d_y = I_xy = I_yz = 0, w = 0, and the
    symmetry-breaking effects at null."""
    return _symmetric_part(params).replace(**{"com_offset[1]": 0.0, "inertia[3]": 0.0,
                                              "inertia[5]": 0.0, "hip_width": 0.0})


def solve_fixed_point(walker: Walker, z0: np.ndarray, tol: float = _NEWTON_TOL,
                      maxit: int = _NEWTON_MAXIT, jacobian: np.ndarray | None = None) -> Gait:
    """Newton's method on P(z) - z = 0 from ``z0``, damped by backtracking.

    Parameters
    ----------
    walker : Walker
    z0 : ndarray, shape (8,)
        The start.
    tol : float
        Residual tolerance, max |P(z) - z| with rates scaled by sqrt(l/g).
    maxit : int
        Newton iterations at most.
    jacobian : ndarray, shape (8, 8), optional
        The map's Jacobian at a fixed point near ``z0`` (a neighbouring walker's gait, as a
        posterior's next draw has): chord steps first (Kelley 2003, Solving Nonlinear Equations
        with Newton's Method, SIAM, section 1.10), each one map evaluation without derivatives,
        the Jacobian held; while they shrink the residual at least :data:`_CHORD_RATE`-fold a
        step they go on to round-off, else Newton takes over from where they stopped. A map
        evaluation with derivatives costs about six without (the 3D walker).

    Raises
    ------
    GaitNotFound
        The iteration failed (a step fell, or no convergence); the message says how.
    """
    active = [4, 5, 6, 7] if walker.planar else list(range(8))
    scale = state_scale(walker.params)
    z = np.array(z0, dtype=float)
    if walker.planar:
        z[:4] = 0.0
    if jacobian is not None:
        jacobian = np.asarray(jacobian, float)
        if jacobian.shape != (8, 8) or not np.all(np.isfinite(jacobian)):
            raise ValueError(f"jacobian must be a finite (8, 8) map Jacobian, got shape {jacobian.shape}")
        z, chords, converged = _chord(walker, z, jacobian, active, scale, tol)
        if converged:
            return _make_gait(walker, z, chords)
    try:
        step = walker.cycle(z, jacobian=True)
    except StepFailure as err:
        raise GaitNotFound(f"the starting state does not complete a step ({err.status}: {err})") from err
    res = (step.z_plus - z)[active]
    norm = np.max(np.abs(res / scale[active]))
    for it in range(1, maxit + 1):
        jac = step.jacobian[np.ix_(active, active)] - np.eye(len(active))
        try:
            dz = np.linalg.solve(jac, -res)
        except np.linalg.LinAlgError:
            dz = np.linalg.lstsq(jac, -res, rcond=None)[0]
        if norm < tol:
            # Converged: one more Newton step polishes the fixed point to round-off (quadratic
            # convergence), kept only if it lowers the residual.
            polished = z.copy()
            polished[active] += dz
            try:
                s_pol = walker.cycle(polished)
                if np.max(np.abs((s_pol.z_plus - polished)[active] / scale[active])) < norm:
                    z = polished
            except StepFailure:
                pass
            return _make_gait(walker, z, it)
        lam = 1.0
        while lam > 1e-4:
            trial = z.copy()
            trial[active] += lam * dz
            try:
                s_trial = walker.cycle(trial, jacobian=True)
            except StepFailure:
                lam *= 0.5
                continue
            r_trial = (s_trial.z_plus - trial)[active]
            n_trial = np.max(np.abs(r_trial / scale[active]))
            if n_trial < norm or lam < 2e-4:
                break
            lam *= 0.5
        else:
            raise GaitNotFound(f"Newton's line search failed at residual {norm:.3g}")
        z, step, res, norm = trial, s_trial, r_trial, n_trial
    if norm < tol:
        return _make_gait(walker, z, maxit)
    raise GaitNotFound(f"Newton did not converge in {maxit} iterations (residual {norm:.3g})")


def _chord(walker: Walker, z: np.ndarray, jacobian: np.ndarray, active: list, scale: np.ndarray,
           tol: float) -> tuple[np.ndarray, int, bool]:
    """Chord steps on P(z) - z = 0 with a held Jacobian (:func:`solve_fixed_point`), while each
    shrinks the residual :data:`_CHORD_RATE`-fold: (the state with the lower residual of the last
    two, the steps taken, whether that residual is below ``tol``)."""
    try:
        res = (walker.cycle(z).z_plus - z)[active]
    except StepFailure:
        return z, 0, False
    norm = np.max(np.abs(res / scale[active]))
    held = jacobian[np.ix_(active, active)] - np.eye(len(active))
    for k in range(1, _CHORD_MAXIT + 1):
        try:
            dz = np.linalg.solve(held, -res)
        except np.linalg.LinAlgError:
            return z, k - 1, False
        trial = z.copy()
        trial[active] += dz
        try:
            r_trial = (walker.cycle(trial).z_plus - trial)[active]
        except StepFailure:
            return z, k - 1, False
        n_trial = np.max(np.abs(r_trial / scale[active]))
        if n_trial <= _CHORD_RATE * norm:
            z, res, norm = trial, r_trial, n_trial
            continue
        if min(norm, n_trial) < tol:  # at round-off: the better of the last two
            return (trial, k, True) if n_trial < norm else (z, k - 1, True)
        return z, k - 1, False
    return z, _CHORD_MAXIT, norm < tol


#: Chord steps (:func:`solve_fixed_point` given a neighbour's Jacobian) go on while each shrinks
#: the residual at least this much (to round-off, where they stop shrinking it), at most
#: :data:`_CHORD_MAXIT` of them. Measured from a walker 1-5 % away in slope (compass-3d,
#: stable-toy, toy-sized): 4-12 steps to the residual Newton reaches (1e-15 to 5e-13).
_CHORD_RATE = 0.25
_CHORD_MAXIT = 16


def state_scale(params: Params) -> np.ndarray:
    """The unit of each public state component, shape (8,): 1 rad for the angles and 1 /
    sqrt(l/g) (rad/s) for the rates, so that ``z / state_scale(params)`` is dimensionless (the
    scale of Newton's residual here and of a perturbation in :mod:`toywalk.model.basin`)."""
    rate = 1.0 / params.time_scale
    return np.array([1.0, rate] * 4)


def _make_gait(walker: Walker, z: np.ndarray, iterations: int) -> Gait:
    cycle = walker.cycle(z, jacobian=True, record=True)
    active = [4, 5, 6, 7] if walker.planar else list(range(8))
    jac = cycle.jacobian
    vals, vecs = np.linalg.eig(jac)
    if walker.planar:  # the lateral block is absent: report zeros there, eigenvectors of the block
        sub_vals, sub_vecs = np.linalg.eig(jac[np.ix_(active, active)])
        vals = np.concatenate([sub_vals, np.zeros(4)])
        vecs = np.zeros((8, 8), dtype=complex)
        vecs[np.ix_(active, range(4))] = sub_vecs
        vecs[np.arange(4), np.arange(4, 8)] = 1.0
    order = np.argsort(-np.abs(vals), kind="stable")
    residual = float(np.max(np.abs(cycle.z_plus - z)))
    return Gait(params=walker.params, planar=walker.planar, fixed_point=z.copy(),
                step_time=cycle.time / walker.period, step=cycle.steps[0], eigenvalues=vals[order],
                eigenvectors=vecs[:, order], residual=residual,
                iterations=iterations, steps=cycle.steps)


def _planar_starts(params: Params):
    """Initial guesses for the planar gait, from the simplest walker's asymptotics (Garcia et al.
    1998: stance angle ~ 0.970956 slope^(1/3), angular rate ~ stance angle in sqrt(g/l) units)."""
    base = 0.970956 * abs(params.slope) ** (1.0 / 3.0)
    rate_unit = 1.0 / params.time_scale
    for factor in (1.0, 0.7, 1.4, 0.5, 2.0):
        th = min(base * factor, 0.6)
        for rate_ratio in (1.0, 0.6, 1.6):
            thd = th * rate_ratio * rate_unit
            z = np.zeros(8)
            z[4], z[5], z[6], z[7] = -th, thd, th, thd * math.cos(2 * th)
            yield z


def planar_gaits(params: Params, stance_angles: Sequence[float] = (0.05, 0.1, 0.2, 0.3, 0.4),
                 rate_ratios: Sequence[float] = (0.5, 1.0, 1.5, 2.0),
                 swing_ratios: Sequence[float] = (-1.0, 0.0, 1.0)) -> list[Gait]:
    """All distinct gaits of the planar reduction found from a grid of starts (one per branch).

    The start is ``theta_st = -a``, ``theta_sw = a``, ``theta_st_dot = k a sqrt(g/l)``,
    ``theta_sw_dot = s theta_st_dot`` for every ``a`` in ``stance_angles``, ``k`` in
    ``rate_ratios`` and ``s`` in ``swing_ratios``. Wider than the simplest walker's asymptotics
    that :func:`find_gait` tries first (those miss the gaits of walkers with heavy legs).

    Parameters
    ----------
    params : Params
        The walker; its planar reduction (:func:`planar_reduction`) is solved.
    stance_angles : sequence of float
        (rad)
    rate_ratios, swing_ratios : sequence of float
        Dimensionless.

    Returns
    -------
    list of Gait
        Planar gaits, distinct by step time (relative difference > 1e-6), sorted by step time
        (short-period branch first). Empty when none is found.
    """
    reduced = planar_reduction(params)
    walker = Walker(reduced, planar=True)
    rate_unit = 1.0 / reduced.time_scale
    found: list[Gait] = []
    for a in stance_angles:
        for k in rate_ratios:
            for s in swing_ratios:
                z = np.zeros(8)
                z[4], z[5], z[6], z[7] = -a, k * a * rate_unit, a, s * k * a * rate_unit
                try:
                    gait = solve_fixed_point(walker, z)
                except GaitNotFound:
                    continue
                if not any(abs(gait.step_time - f.step_time) <= 1e-6 * f.step_time for f in found):
                    found.append(gait)
    return sorted(found, key=lambda g: g.step_time)


def find_gait(params: Params, z_guess: np.ndarray | None = None, planar: bool | None = None,
              steps_per_time_unit: int = 16, min_clearance: float | None = None) -> Gait:
    """Find the walker's symmetric gait.

    Parameters
    ----------
    params : Params
    z_guess : ndarray, shape (8,), optional
        A start near the gait; without it the planar reduction is solved first and followed to
        ``params`` by continuation.
    planar : bool, optional
        Solve in the planar reduction. Default: planar exactly when ``params`` is planar-symmetric
        and its 3D mass matrix is singular in the lateral directions (point-mass limits).
    steps_per_time_unit : int
        Integration resolution (see :class:`Walker`).
    min_clearance : float, optional
        Accept only a gait whose swing foot clears the ramp by at least this much over its whole
        swing (m, :attr:`Gait.clearance`): the search goes on to the next gait branch when one does
        not. Default: any gait.

    Raises
    ------
    GaitNotFound
        With what was tried (and, with ``min_clearance``, the clearances of the gaits refused).
    """
    if min_clearance is not None and not math.isfinite(min_clearance):
        raise ValueError(f"min_clearance must be a finite height (m) or None, got {min_clearance!r}")
    if planar is None:
        planar = is_planar_symmetric(params) and lateral_singular(params)
    if z_guess is not None:
        return _find_gait(params, z_guess, planar, steps_per_time_unit, min_clearance)
    # A search from nothing is deterministic: kept, so that the fits of one analysis that start
    # from the same walker (a diagnosis: every candidate and held-out fold of each walk) search
    # once. A copy each time: callers own what they are given.
    return copy.deepcopy(_found(params, planar, steps_per_time_unit, min_clearance))


@functools.lru_cache(maxsize=16)
def _found(params: Params, planar: bool, steps_per_time_unit: int, min_clearance: float | None) -> Gait:
    """:func:`find_gait` from nothing, its 16 latest searches kept (a failed one is not)."""
    return _find_gait(params, None, planar, steps_per_time_unit, min_clearance)


def _find_gait(params: Params, z_guess: np.ndarray | None, planar: bool, steps_per_time_unit: int,
               min_clearance: float | None) -> Gait:
    refused: list[Gait] = []
    reasons: list[str] = []
    for gait in _gaits(params, z_guess, planar, steps_per_time_unit, reasons):
        if min_clearance is None or gait.clearance >= min_clearance:
            return gait
        refused.append(gait)
    if refused:
        which = ", ".join(f"{1e3 * g.clearance:.3g} mm (step time {g.step_time:.4g} s)" for g in refused)
        raise GaitNotFound(
            f"no gait clears the ramp by {1e3 * min_clearance:.3g} mm over the whole swing; the gaits "
            f"found clear it by {which}"
        )
    raise GaitNotFound(reasons[-1] if reasons else "no start gave a gait")


def _gaits(params: Params, z_guess: np.ndarray | None, planar: bool, steps_per_time_unit: int,
           reasons: list[str]):
    """The gaits :func:`find_gait` tries, one branch after another (a generator); why each
    attempt failed is appended to ``reasons``, the last entry saying what was tried."""
    walker = Walker(params, planar=planar, steps_per_time_unit=steps_per_time_unit)
    if z_guess is not None:
        try:
            yield solve_fixed_point(walker, z_guess)
        except GaitNotFound as err:
            reasons.append(str(err))
        return
    if params.gait_start is not None and not (planar or params.active_effects):
        # The parameter file's stored start (Params.gait_start): a designed gait the search from
        # the planar reduction does not reach (it may lie past a fold of that homotopy).
        try:
            yield solve_fixed_point(walker, np.array(params.gait_start))
        except GaitNotFound as err:
            reasons.append(f"from the parameter file's gait start: {err}")
    if params.active_effects:
        # Effects on: the seed model's gait first, then the effects raised from null along the
        # gaits (the stride map's fixed points where an effect breaks the mirror symmetry).
        seed = _without_effects(params)
        base = find_gait(seed, planar=planar, steps_per_time_unit=steps_per_time_unit)
        try:
            yield continue_gait(seed, params, base.fixed_point, steps_per_time_unit, planar=base.planar)
        except GaitNotFound as err:
            reasons.append(
                f"the walker without effects walks (step time {base.step_time:.4g} s) but its gait "
                f"does not follow to these effects: {err}{_fold_note(base, steps_per_time_unit)}"
            )
        return
    reduced = planar_reduction(params)
    planar_walker = Walker(reduced, planar=True, steps_per_time_unit=steps_per_time_unit)
    tried: list[Gait] = []
    # First the simplest walker's asymptotics (fast, enough for light legs); then, if no gait
    # follows from there, every distinct planar gait of a wider grid of starts (heavy legs).
    for z0 in _planar_starts(params):
        try:
            tried.append(solve_fixed_point(planar_walker, z0))
            break
        except GaitNotFound as err:
            reasons.append(str(err))
    for attempt in (tried, None):
        bases = attempt if attempt is not None else [
            g for g in planar_gaits(reduced) if not any(
                abs(g.step_time - t.step_time) <= 1e-6 * t.step_time for t in tried)]
        for base in bases:
            if planar:
                yield base
                continue
            try:
                yield continue_gait(reduced, params, base.fixed_point, steps_per_time_unit)
            except GaitNotFound as err:
                reasons.append(f"from the planar gait with step time {base.step_time:.4g} s: {err}")
    # What was tried, without "no gait found": the callers' messages start with that.
    reasons.append(
        f"tried planar starts near the simplest walker's and a wider grid; last: "
        f"{reasons[-1] if reasons else 'no planar gait from any start'}"
    )


@dataclasses.dataclass(frozen=True)
class StrikeResolution:
    """A soft-footed gait re-solved with its compliant heel strike integrated finer
    (:func:`strike_resolution`).

    Attributes
    ----------
    steps_per_tau, fine_steps_per_tau : int
        RK4 steps per contact time constant of the gait given and of the re-solved one.
    max_abs_eigenvalue, fine_max_abs_eigenvalue : float
    step_time, fine_step_time : float
        (s)
    shift : float
        The fixed point's move (state_scale units, Euclidean).
    """

    steps_per_tau: int
    fine_steps_per_tau: int
    max_abs_eigenvalue: float
    fine_max_abs_eigenvalue: float
    step_time: float
    fine_step_time: float
    shift: float

    @property
    def eigenvalue_error(self) -> float:
        """``|fine - given|`` max |eigenvalue|: the given gait's integration error, estimated."""
        return abs(self.fine_max_abs_eigenvalue - self.max_abs_eigenvalue)

    @property
    def resolved(self) -> bool:
        """The error is below :data:`STRIKE_EIGENVALUE_RESOLUTION`."""
        return self.eigenvalue_error < STRIKE_EIGENVALUE_RESOLUTION


def strike_resolution(gait: Gait, steps_per_tau: int | None = None, factor: int = 4) -> StrikeResolution:
    """Check a soft-footed gait's integration: re-solve it (Newton from its fixed point) with the
    compliant heel strike at ``factor`` times the RK4 steps per contact time constant.

    The compliant phase is integrated at fixed steps (:data:`toywalk.model.compliant.STEPS_PER_TAU`
    per tau by default), and its convergence is first order, not fourth: the landing foot rebounds
    and lands again inside the phase and a foot lets go with a kink. The error depends on the
    walker (docs/soft_feet.md section 5: 0.003 on the clearing toy, 0.03 on the robust toy at
    4 ms), so it is measured here, not assumed.

    Parameters
    ----------
    gait : Gait
        A gait of a walker with ``effects.soft_heel`` > 0.
    steps_per_tau : int, optional
        The steps per tau ``gait`` was solved with (default the walker's default).
    factor : int
        The finer integration's multiple of them (>= 2).

    Raises
    ------
    ValueError
        The walker has rigid feet, or ``factor`` < 2.
    GaitNotFound
        Newton lost the gait at the finer resolution.
    """
    from .compliant import STEPS_PER_TAU

    if not gait.params.effects.get("soft_heel", 0.0) > 0.0:
        raise ValueError("strike_resolution checks a gait of soft feet (effects.soft_heel > 0)")
    if int(factor) != factor or factor < 2:
        raise ValueError(f"factor must be an integer >= 2, got {factor!r}")
    coarse = STEPS_PER_TAU if steps_per_tau is None else int(steps_per_tau)
    fine_steps = int(factor) * coarse
    walker = Walker(gait.params, planar=gait.planar, soft_steps_per_tau=fine_steps)
    fine = solve_fixed_point(walker, gait.fixed_point)
    shift = float(np.linalg.norm((fine.fixed_point - gait.fixed_point) / state_scale(gait.params)))
    return StrikeResolution(coarse, fine_steps, gait.max_abs_eigenvalue, fine.max_abs_eigenvalue,
                            gait.step_time, fine.step_time, shift)


def continue_gait(start: Params, end: Params, z_start: np.ndarray, steps_per_time_unit: int = 16,
                  min_ds: float = 1e-3, planar: bool = False) -> Gait:
    """Follow a gait from parameter set ``start`` (gait ``z_start``) to ``end`` along the straight
    line in parameter space, halving the step on failure (natural-parameter continuation). The
    map is the stride map all the way when ``end`` breaks the mirror symmetry."""
    period = 2 if end.breaks_symmetry else 1
    pa, pb = start.vector(), end.vector()
    s, ds = 0.0, 0.25
    z = np.array(z_start, dtype=float)
    gait = None
    while s < 1.0:
        s_new = min(1.0, s + ds)
        trial = _params_at(end, pa + s_new * (pb - pa))
        try:
            gait = solve_fixed_point(Walker(trial, planar=planar, period=period,
                                            steps_per_time_unit=steps_per_time_unit), z)
        except GaitNotFound as err:
            ds *= 0.5
            if ds < min_ds:
                raise GaitNotFound(
                    f"continuation stalled at s = {s:.4f} of the way ({err})"
                ) from err
            continue
        z, s = gait.fixed_point, s_new
        ds = min(0.5, ds * 1.5)
    return gait


def _fold_note(gait: Gait, steps_per_time_unit: int) -> str:
    """Why a gait at a fold (:attr:`Gait.fold_eigenvalue`) may not follow to a change, and on which
    side of its slope it exists (each side solved from it); '' for a gait not at a fold."""
    lam = gait.fold_eigenvalue
    if lam is None:
        return ""
    exists = {}
    for side, factor in (("steeper", 1.0 + _FOLD_PROBE), ("shallower", 1.0 - _FOLD_PROBE)):
        walker = Walker(gait.params.replace(slope=gait.params.slope * factor), planar=gait.planar,
                        period=gait.period, steps_per_time_unit=steps_per_time_unit)
        try:
            solve_fixed_point(walker, gait.fixed_point)
            exists[side] = True
        except GaitNotFound:
            exists[side] = False
    pct = f"{100 * _FOLD_PROBE:g} %"
    if exists["steeper"] and not exists["shallower"]:
        where = (f"; it exists on a ramp {pct} steeper but not on one {pct} shallower, so an effect that "
                 f"costs it energy, as a shallower ramp would, removes it: try a steeper slope")
    elif exists["shallower"] and not exists["steeper"]:
        where = (f"; it exists on a ramp {pct} shallower but not on one {pct} steeper, so an effect that "
                 f"gives it energy, as a steeper ramp would, removes it: try a shallower slope")
    else:
        where = ""
    return (f". That gait is at a fold of its branch (a step-map eigenvalue {lam:.6g}, {abs(1 - lam):.2g} "
            f"from 1: a small change moves it by {1 / abs(1 - lam):.3g} times as much, or removes it)"
            f"{where} (docs/effects_study.md)")


def _without_effects(params: Params) -> Params:
    """``params`` with every effect at its null value (the seed's model)."""
    return params.replace(**{f"effects.{k}": EFFECTS[k].null for k in params.effects})


def _symmetric_part(params: Params) -> Params:
    """``params`` with every symmetry-breaking effect at its null value."""
    return params.replace(**{f"effects.{k}": EFFECTS[k].null for k in params.effects
                             if EFFECTS[k].breaks_symmetry})


def _params_at(template: Params, vector: np.ndarray) -> Params:
    from .parameters import PARAMETER_NAMES

    return template.replace(**dict(zip(PARAMETER_NAMES, map(float, vector), strict=True)))


def lateral_singular(params: Params) -> bool:
    """True when the 3D mass matrix is (numerically) singular at the upright configuration: a
    point-mass limit (no lateral inertia) whose gaits are solved in the planar reduction, where
    the walker is also planar-symmetric (:func:`find_gait` by default; the fit asks it of the
    walker it starts from)."""
    from .engine import engine

    x = np.zeros(10)
    m_mat = np.array(engine(False).k["mass_matrix"](x, params.input_vector())[0])
    scale = params.total_mass * params.leg_length**2
    return bool(np.linalg.eigvalsh(0.5 * (m_mat + m_mat.T))[0] < 1e-8 * scale)
