"""Searching parameter space for gaits: branches, warm-started evaluation, eigenvalue minimisation
and fits to measured gait features.

The step map's eigenvalues have no analytic parameter derivative here (that would need the second
derivative of the step map), so the optimisers are derivative-free (Nelder-Mead; Nelder & Mead,
Comput. J. 7:308, 1965) or use finite differences of gait features (``scipy.optimize.least_squares``).
Each evaluation solves a fixed point by Newton's method warm-started from the last gait found
(:func:`toywalk.model.gait.solve_fixed_point`), falling back to natural-parameter continuation
from it (:func:`toywalk.model.gait.continue_gait`), so that consecutive evaluations stay on one gait
branch (docs/model.md section 5). Branches are told apart by step time: the evaluator counts accepted
gaits whose step time differs from the previous one's by more than a set fraction (``jumps``, a
suspected branch jump), and every result reports that count; compare ``result.gait.step_time``
with the starting gait's to see where a search ended.

Free parameters are named by their file names (``"com_offset[1]"``, ``"foot_radius"``, ...; see
:meth:`Params.replace`). Internally they are scaled to [0, 1] between their bounds.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import scipy.optimize

from .gait import Gait, GaitNotFound, continue_gait, planar_gaits, solve_fixed_point
from .parameters import ParameterError, Params
from .walker import STATE_NAMES, Walker

__all__ = [
    "GAIT_FEATURES",
    "GaitEvaluator",
    "GaitTargetFit",
    "OptimisationResult",
    "clearance_constraint",
    "fit_gait_targets",
    "gait_features",
    "heading_eigenvalue",
    "minimise_max_eigenvalue",
    "planar_gaits",
]

#: Gait features that :func:`fit_gait_targets` can match (units in :func:`gait_features`).
GAIT_FEATURES = ("stride_time", "stride_length", "lean_amplitude", "steer_amplitude",
                 "max_abs_eigenvalue", "step_time", "clearance")

# A failed evaluation (no gait, a bound or constraint violated) is worth this much more than any
# gait in :func:`minimise_max_eigenvalue`, plus a term that grows with the violation so that the
# simplex is pushed back towards the feasible region.
_PENALTY = 1e3


def heading_eigenvalue(gait: Gait) -> tuple[complex, float]:
    """The step-map eigenvalue of the heading mode and the share of phi in its eigenvector.

    On level ground heading is an exact symmetry of the 3D walker; the step map mirrors phi
    (docs/model.md section 4), so a heading change shows as a step-map eigenvalue of exactly -1 (stride
    map +1). On a slope gravity breaks the symmetry and the eigenvalue moves off -1. This returns
    the eigenvalue with the largest phi share in its eigenvector (angles and rates scaled as in
    :meth:`Gait.dominant_components`).

    Returns
    -------
    eigenvalue : complex
        Step-map eigenvalue (its square is the stride-map one).
    phi_share : float
        Share of phi in the eigenvector, in [0, 1].
    """
    shares = []
    for k in range(len(gait.eigenvalues)):
        comps = dict(gait.dominant_components(k, n=len(STATE_NAMES)))
        shares.append(comps["phi"])
    k = int(np.argmax(shares))
    return complex(gait.eigenvalues[k]), float(shares[k])


def gait_features(gait: Gait) -> dict[str, float]:
    """Scalar features of a gait, keyed by :data:`GAIT_FEATURES`.

    Returns
    -------
    dict
        ``stride_time`` (s, two steps), ``step_time`` (s), ``stride_length`` (m, advance along the
        fall line per stride), ``lean_amplitude`` and ``steer_amplitude`` (rad, max |psi| and
        |phi| over a step), ``max_abs_eigenvalue`` (step map), ``clearance`` (m, the swing foot's
        over its whole swing, :attr:`Gait.clearance`).
    """
    return {
        "stride_time": gait.stride_time,
        "step_time": gait.step_time,
        "stride_length": gait.stride_length,
        "lean_amplitude": gait.lean_amplitude,
        "steer_amplitude": gait.steer_amplitude,
        "max_abs_eigenvalue": gait.max_abs_eigenvalue,
        "clearance": gait.clearance,
    }


class GaitEvaluator:
    """Gaits of a family of walkers that differ in a few named parameters, warm-started.

    Each call solves the fixed point of ``base.replace(name_i = x_i)`` by Newton from the last gait
    found; if that fails, it continues the last gait to the new parameters along the straight line
    (:func:`continue_gait`). Keeping the last gait makes a sequence of nearby evaluations (an
    optimiser's, a row of a map) follow one branch.

    Parameters
    ----------
    base : Params
        The walker whose other parameters are kept.
    names : sequence of str
        Free parameters by file name (see :meth:`Params.replace`).
    gait : Gait
        A gait of ``base`` with its free parameters at ``gait.params`` (the starting branch).
    max_jump : float
        An accepted gait whose step time differs from the previous one's by more than this
        fraction is flagged as a possible branch jump (counted in ``jumps``).
    continuation : bool
        Fall back to continuation when warm-started Newton fails.
    """

    def __init__(self, base: Params, names: Sequence[str], gait: Gait, max_jump: float = 0.2,
                 continuation: bool = True):
        if not isinstance(base, Params):
            raise TypeError(f"base must be a Params, got {type(base).__name__}")
        if not isinstance(gait, Gait):
            raise TypeError(f"gait must be a Gait, got {type(gait).__name__}")
        self.base = base
        self.names = tuple(names)
        for name in self.names:
            base.get(name)  # raises ParameterError for an unknown name
        self.last = gait
        self.start_step_time = gait.step_time
        self.max_jump = float(max_jump)
        self.continuation = bool(continuation)
        self.jumps = 0
        self.evaluations = 0
        self.failures = 0

    def params_at(self, x: Sequence[float]) -> Params:
        """The walker with the free parameters set to ``x`` (raises ParameterError if invalid)."""
        x = np.asarray(x, dtype=float)
        if x.shape != (len(self.names),):
            raise ValueError(f"x must have {len(self.names)} values ({self.names}), got shape {x.shape}")
        return self.base.replace(**dict(zip(self.names, map(float, x), strict=True)))

    def values(self, params: Params | None = None) -> np.ndarray:
        """The free parameters' values of ``params`` (default: of the last gait), shape (n,)."""
        params = self.last.params if params is None else params
        return np.array([params.get(n) for n in self.names])

    def __call__(self, x: Sequence[float]) -> Gait | None:
        """The gait at free parameters ``x``, or None when none is found (or ``x`` is invalid)."""
        self.evaluations += 1
        try:
            params = self.params_at(x)
        except ParameterError:
            self.failures += 1
            return None
        gait = None
        try:
            gait = solve_fixed_point(Walker(params), self.last.fixed_point)
        except GaitNotFound:
            if self.continuation:
                try:
                    gait = continue_gait(self.last.params, params, self.last.fixed_point)
                except GaitNotFound:
                    gait = None
        if gait is None or not np.all(np.isfinite(gait.eigenvalues)):
            self.failures += 1
            return None
        if abs(gait.step_time - self.last.step_time) > self.max_jump * self.last.step_time:
            self.jumps += 1
        self.last = gait
        return gait


@dataclasses.dataclass
class OptimisationResult:
    """What :func:`minimise_max_eigenvalue` found.

    Attributes
    ----------
    params : Params
        Best feasible walker found.
    gait : Gait
        Its gait.
    value : float
        Objective there (default: step-map max |eigenvalue|).
    start_value : float
        Objective at the start.
    history : ndarray, shape (n_evaluations, n_free + 1)
        Every evaluated point (free parameters, then the objective; ``inf`` where no gait or
        infeasible).
    evaluations, failures, jumps : int
        Counts from the :class:`GaitEvaluator`.
    status : str
        ``"improved"``, ``"no_improvement"``.
    message : str
        The optimiser's message.
    """

    params: Params
    gait: Gait
    value: float
    start_value: float
    history: np.ndarray
    evaluations: int
    failures: int
    jumps: int
    status: str
    message: str


def minimise_max_eigenvalue(gait: Gait, free_names: Sequence[str],
                            bounds: Mapping[str, tuple[float, float]],
                            constraint: Callable[[Params, Gait], float] | None = None,
                            objective: Callable[[Gait], float] | None = None,
                            maxiter: int = 300, initial_step: float = 0.1,
                            continuation: bool = True, progress: bool = False,
                            min_clearance: float | None = None) -> OptimisationResult:
    """Minimise a gait's step-map max |eigenvalue| over a few parameters (Nelder-Mead).

    Parameters
    ----------
    gait : Gait
        Starting gait (its ``params`` are the starting walker and fix the branch).
    free_names : sequence of str
        Free parameters by file name, e.g. ``["com_offset[1]", "foot_radius"]``.
    bounds : mapping of str to (float, float)
        Lower and upper bound of every free parameter (the parameter's units). The starting value
        must lie within them.
    constraint : callable, optional
        ``constraint(params, gait) -> float``, feasible when >= 0 (e.g. the static margin minus a
        required value, ``lambda p, g: static_margin(p) - 0.005``). Infeasible points are penalised.
    objective : callable, optional
        ``objective(gait) -> float`` to minimise instead of ``gait.max_abs_eigenvalue``.
    maxiter : int
        Nelder-Mead iterations.
    initial_step : float
        Size of the initial simplex as a fraction of each bound interval.
    continuation : bool
        Fall back to continuation from the last gait when warm-started Newton fails (slower, but
        fewer lost points; see :class:`GaitEvaluator`).
    progress : bool
        Show a tqdm progress bar of the evaluations.
    min_clearance : float, optional
        A constraint: the swing foot must clear the ramp by at least this much over its whole
        swing (m, :attr:`Gait.clearance`); checked with ``constraint``, penalised alike.

    Returns
    -------
    OptimisationResult
        The best feasible point evaluated (not necessarily the optimiser's last).

    Raises
    ------
    ValueError
        A free parameter without bounds, bounds in the wrong order or a start outside them.
    """
    names = tuple(free_names)
    lo, hi = _check_bounds(names, bounds, gait.params)
    objective = objective or (lambda g: g.max_abs_eigenvalue)
    constraint = clearance_constraint(min_clearance, constraint)
    evaluator = GaitEvaluator(gait.params, names, gait, continuation=continuation)
    x0 = evaluator.values()
    start_value = float(objective(gait))
    best = {"value": start_value, "gait": gait}
    if constraint is not None and constraint(gait.params, gait) < 0:
        best["value"] = math.inf
    history: list[list[float]] = []
    bar = _progress(progress, maxiter)

    def cost(u: np.ndarray) -> float:
        x = lo + np.asarray(u) * (hi - lo)
        outside = float(np.sum(np.maximum(0.0, -u) + np.maximum(0.0, u - 1.0)))
        if outside > 0:
            history.append([*x, math.inf])
            return _PENALTY * (1.0 + outside)
        g = evaluator(x)
        if bar is not None:
            bar.update(1)
        if g is None:
            history.append([*x, math.inf])
            return _PENALTY
        value = float(objective(g))
        if constraint is not None:
            c = float(constraint(g.params, g))
            if c < 0:
                history.append([*x, math.inf])
                return _PENALTY * 0.1 + value - c / _constraint_scale(g.params)
        history.append([*x, value])
        if value < best["value"]:
            best.update(value=value, gait=g)
        return value

    u0 = (x0 - lo) / (hi - lo)
    simplex = [u0]
    for i in range(len(names)):
        u = u0.copy()
        u[i] = u[i] + initial_step if u[i] + initial_step <= 1.0 else u[i] - initial_step
        simplex.append(u)
    res = scipy.optimize.minimize(cost, u0, method="Nelder-Mead",
                                  options={"initial_simplex": np.array(simplex), "maxiter": maxiter,
                                           "xatol": 1e-4, "fatol": 1e-5})
    if bar is not None:
        bar.close()
    final = best["gait"]
    improved = best["value"] < start_value
    return OptimisationResult(
        params=final.params, gait=final, value=float(best["value"]), start_value=start_value,
        history=np.array(history), evaluations=evaluator.evaluations, failures=evaluator.failures,
        jumps=evaluator.jumps, status="improved" if improved else "no_improvement",
        message=str(res.message),
    )


@dataclasses.dataclass
class GaitTargetFit:
    """What :func:`fit_gait_targets` found.

    Attributes
    ----------
    params : Params
    gait : Gait
    features : dict
        :func:`gait_features` of the fitted gait.
    residuals : dict
        (feature - target) / scale for every target.
    cost : float
        Half the sum of squared scaled residuals.
    evaluations, failures : int
    status : str
        ``"converged"`` or ``"stopped"`` (iteration limit or no progress).
    message : str
    names : tuple of str
        The free parameters.
    jacobian : ndarray, shape (n_res, n_free)
        Derivative of the scaled residuals (the targets', then the priors', then the
        regularisation's) with respect to the free parameters in their own units, at the
        solver's last point (forward differences); ``inv(J^T J)`` is the parameters' covariance
        when the scales are the measurements' standard deviations.
    """

    params: Params
    gait: Gait
    features: dict[str, float]
    residuals: dict[str, float]
    cost: float
    evaluations: int
    failures: int
    status: str
    message: str
    names: tuple = ()
    jacobian: np.ndarray | None = None


def fit_gait_targets(gait: Gait, free_names: Sequence[str], bounds: Mapping[str, tuple[float, float]],
                     targets: Mapping[str, tuple[float, float]], max_nfev: int = 200,
                     regularisation: float = 0.0, continuation: bool = True,
                     priors: Mapping[str, tuple[float, float]] | None = None) -> GaitTargetFit:
    """Fit free parameters so that the gait's features match target values (least squares).

    Minimises ``sum_k ((f_k(p) - target_k) / scale_k)^2`` (+ ``regularisation * |u - u0|^2`` in the
    bound-scaled parameters u) with :func:`scipy.optimize.least_squares` (trust-region reflective,
    bounds enforced, Jacobian by forward finite differences of warm-started gait solves).

    Parameters
    ----------
    gait : Gait
        Starting gait (branch and starting walker).
    free_names : sequence of str
        Free parameters by file name.
    bounds : mapping of str to (float, float)
        Bounds of every free parameter; the start must lie within them.
    targets : mapping of str to (float, float)
        Feature name (one of :data:`GAIT_FEATURES`) to ``(target, scale)``, in the feature's units
        (:func:`gait_features`); ``scale`` > 0 is the tolerated misfit.
    max_nfev : int
        Function evaluations allowed to the least-squares solver.
    regularisation : float
        Weight of the pull towards the starting parameters (0: none).
    continuation : bool
        As in :func:`minimise_max_eigenvalue`.
    priors : mapping of str to (float, float), optional
        Free parameter to ``(mean, sd)``: a Gaussian prior, one more residual
        ``(value - mean) / sd`` each (a parameter measured with that uncertainty).

    Returns
    -------
    GaitTargetFit

    Raises
    ------
    ValueError
        Unknown feature, non-positive scale, missing or bad bounds, a prior on a parameter that is
        not free or with a non-positive SD.
    """
    names = tuple(free_names)
    for key, (_, scale) in targets.items():
        if key not in GAIT_FEATURES:
            raise ValueError(f"unknown gait feature {key!r}; known: {', '.join(GAIT_FEATURES)}")
        if not scale > 0:
            raise ValueError(f"the scale of target {key!r} must be > 0, got {scale!r}")
    priors = dict(priors or {})
    for key, (_, sd) in priors.items():
        if key not in names:
            raise ValueError(f"a prior on {key!r}, which is not free ({', '.join(names)})")
        if not sd > 0:
            raise ValueError(f"the prior SD of {key!r} must be > 0, got {sd!r}")
    prior_at = [(names.index(k), mean, sd) for k, (mean, sd) in priors.items()]
    lo, hi = _check_bounds(names, bounds, gait.params)
    evaluator = GaitEvaluator(gait.params, names, gait, continuation=continuation)
    u0 = (evaluator.values() - lo) / (hi - lo)
    keys = list(targets)
    n_res = len(keys) + len(prior_at) + (len(names) if regularisation > 0 else 0)
    best = {"cost": math.inf, "gait": gait}

    def residuals(u: np.ndarray) -> np.ndarray:
        x = lo + u * (hi - lo)
        g = evaluator(x)
        if g is None:
            return np.full(n_res, 1e3)
        feats = gait_features(g)
        r = [(feats[k] - targets[k][0]) / targets[k][1] for k in keys]
        r.extend((x[i] - mean) / sd for i, mean, sd in prior_at)
        if regularisation > 0:
            r.extend(math.sqrt(regularisation) * (u - u0))
        r = np.array(r)
        c = 0.5 * float(r @ r)
        if c < best["cost"]:
            best.update(cost=c, gait=g)
        return r

    res = scipy.optimize.least_squares(residuals, u0, bounds=(0.0, 1.0), diff_step=1e-4,
                                       max_nfev=max_nfev, x_scale=1.0)
    final = best["gait"]
    feats = gait_features(final)
    return GaitTargetFit(
        params=final.params, gait=final, features=feats,
        residuals={k: (feats[k] - targets[k][0]) / targets[k][1] for k in keys},
        cost=float(best["cost"]), evaluations=evaluator.evaluations, failures=evaluator.failures,
        status="converged" if res.status > 0 else "stopped", message=str(res.message),
        names=names, jacobian=np.asarray(res.jac) / (hi - lo),
    )


def clearance_constraint(min_clearance: float | None,
                         constraint: Callable[[Params, Gait], float] | None = None
                         ) -> Callable[[Params, Gait], float] | None:
    """``constraint`` joined with a minimum clearance: a ``constraint(params, gait) -> float``,
    feasible when >= 0, that is the smaller of ``constraint``'s value and ``gait.clearance -
    min_clearance`` (m). Either may be None (no such constraint)."""
    if min_clearance is None:
        return constraint
    if not math.isfinite(min_clearance):
        raise ValueError(f"min_clearance must be a finite height (m) or None, got {min_clearance!r}")

    def joined(params: Params, gait: Gait) -> float:
        margin = gait.clearance - min_clearance
        return margin if constraint is None else min(margin, float(constraint(params, gait)))

    return joined


# ------------------------------------------------------------------------------------------------
def _check_bounds(names: Sequence[str], bounds: Mapping[str, tuple[float, float]],
                  params: Params) -> tuple[np.ndarray, np.ndarray]:
    if not names:
        raise ValueError("free_names is empty: name at least one parameter to vary")
    extra = sorted(set(bounds) - set(names))
    if extra:
        raise ValueError(f"bounds given for {extra[0]!r}, which is not among free_names {tuple(names)}")
    lo, hi = [], []
    for name in names:
        if name not in bounds:
            raise ValueError(f"free parameter {name!r} has no bounds")
        a, b = map(float, bounds[name])
        if not a < b:
            raise ValueError(f"bounds of {name!r} must satisfy lower < upper, got ({a}, {b})")
        v = params.get(name)
        if not a <= v <= b:
            raise ValueError(f"the starting value of {name!r} ({v}) lies outside its bounds ({a}, {b})")
        lo.append(a)
        hi.append(b)
    return np.array(lo), np.array(hi)


def _constraint_scale(params: Params) -> float:
    return params.leg_length


def _progress(show: bool, total: int):
    if not show:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc="gaits", leave=False)
