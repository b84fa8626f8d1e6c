"""Continuation of gait families in any parameter, reporting folds and locating stability changes.

Pseudo-arclength continuation (Keller 1977; Allgower & Georg, *Introduction to Numerical
Continuation Methods*, SIAM 2003, ch. 2) of the fixed points of the step map: the unknowns are the
state just after heel strike and the parameter mu, the equations ``P(z; mu) - z = 0`` plus the
arclength condition. Both derivatives come exact from :meth:`Walker.step` (AD through the flow,
guard time and collision, ``params_jacobian``). The step length adapts to the corrector's
convergence. Along the branch the code reports:

- **folds** (limit points), where dmu/ds changes sign: the branch turns back (two gaits merge).
  A fold is reported at the first branch point past it, not refined;
- **stability changes**, where max |lambda| crosses 1, classified by the eigenvalue that leaves
  the unit circle: through +1 (fold or symmetry breaking), through -1 (period doubling), or as a
  complex pair (Neimark-Sacker). Each is refined by the secant method on max |lambda| - 1 with
  fixed-parameter Newton solves, so its parameter value is accurate to the solver's tolerance.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from tqdm.auto import tqdm

from .gait import Gait, GaitNotFound, Stability, find_gait, solve_fixed_point
from .parameters import PARAMETER_NAMES, ParameterError, Params
from .walker import StepFailure, Walker

__all__ = ["Branch", "BranchEvent", "BranchPoint", "continue_branch"]

_TOL = 1e-10  # corrector tolerance on |P(z) - z| (rad, and rad per sqrt(l/g))
_MAXIT = 8


@dataclasses.dataclass
class BranchPoint(Stability):
    """One gait on the branch: ``clearance`` is the swing foot's over its whole swing and
    ``clearance_ahead`` where it occurs, ahead of the stance contact (m; :class:`SwingClearance`)."""

    value: float
    fixed_point: np.ndarray
    step_time: float
    stride_length: float
    eigenvalues: np.ndarray
    lean_amplitude: float
    period: int = 1
    steer_amplitude: float = 0.0
    heading: float = 0.0
    clearance: float = math.nan
    clearance_ahead: float = math.nan


@dataclasses.dataclass
class BranchEvent:
    """A fold or a stability change between two branch points."""

    kind: str  # "fold", "loses stability", "gains stability"
    value: float
    detail: str


@dataclasses.dataclass
class Branch:
    """A followed gait family.

    Attributes
    ----------
    name : str
        The continued parameter (a parameter-file name such as ``slope`` or ``com_offset[1]``).
    points : list of BranchPoint
    events : list of BranchEvent
    status : str
        ``"reached"`` (the end value), ``"stalled"`` (the step length fell below its minimum; the
        message says where and why), ``"turned back"`` (past a fold, the branch came back past
        the start value) or ``"max_points"``.
    message : str
    planar : bool
    period : int
        Steps of the map followed: 1 (step map) or 2 (stride map, for symmetry-breaking effects);
        the eigenvalues are that map's.
    """

    name: str
    points: list[BranchPoint]
    events: list[BranchEvent]
    status: str
    message: str
    planar: bool
    period: int = 1

    def table(self) -> tuple[list[str], np.ndarray]:
        """(column names, rows): value, step time, stride length, max|lambda|, stable, lean and
        steer amplitudes, heading, the swing foot's clearance over the whole swing and where it
        occurs (ahead of the stance contact), the fixed point's eight components."""
        from .walker import STATE_NAMES

        cols = [self.name, "step_time", "stride_length", "max_abs_eigenvalue", "stable",
                "lean_amplitude", "steer_amplitude", "heading", "clearance", "clearance_ahead",
                *STATE_NAMES]
        rows = np.array([[p.value, p.step_time, p.stride_length, p.max_abs_eigenvalue,
                          float(p.stable), p.lean_amplitude, p.steer_amplitude, p.heading,
                          p.clearance, p.clearance_ahead, *p.fixed_point] for p in self.points])
        return cols, rows


def _index(name: str) -> int:
    if name not in PARAMETER_NAMES:
        raise ParameterError(f"cannot continue in {name!r}; parameters: {', '.join(PARAMETER_NAMES)}")
    return PARAMETER_NAMES.index(name)


def _point(gait: Gait, value: float) -> BranchPoint:
    swing = gait.swing_clearance
    return BranchPoint(value=value, fixed_point=gait.fixed_point.copy(), step_time=gait.step_time,
                       stride_length=gait.stride_length, eigenvalues=gait.eigenvalues.copy(),
                       lean_amplitude=gait.lean_amplitude, period=gait.period,
                       steer_amplitude=gait.steer_amplitude, heading=gait.heading,
                       clearance=swing.minimum, clearance_ahead=swing.ahead)


def _first_gait(params: Params, first: Params, name: str, start: float, planar, max_points: int,
                ds_max: float) -> Gait:
    """The gait of ``first`` (``params`` with ``name = start``). A walker that stores a start near
    its own gait (``[gait] start``, found past a fold of the search's homotopy) has its gait
    followed from its own value to ``start``, where the search alone may not reach it; otherwise,
    or if that stops short, :func:`find_gait`, and where that finds none, the walker's own gait
    followed there (:func:`_approach`)."""
    own = params.get(name)
    if own == start:
        return find_gait(first, planar=planar)
    if params.gait_start is not None:
        gait, why = _follow_own(params, first, name, own, start, planar, max_points, ds_max)
        if gait is not None:
            return gait
        try:
            return find_gait(first, planar=planar)
        except GaitNotFound as err:
            raise GaitNotFound(f"{why}; and the search at {start:.10g} found none ({err})") from err
    try:
        return find_gait(first, planar=planar)
    except GaitNotFound as err:
        return _approach(params, first, name, own, start, planar, max_points, ds_max, err)


def _follow_own(params: Params, first: Params, name: str, own: float, start: float, planar,
                max_points: int, ds_max: float) -> tuple[Gait | None, str]:
    """The walker's own gait (at its own value ``own``) followed to ``name = start``: (the gait of
    ``first`` there, "") or (None, why it does not get there)."""
    try:
        approach = continue_branch(params, name, own, start, max_points=max_points, ds_max=ds_max,
                                   planar=planar)
    except GaitNotFound as err:
        return None, f"the walker's own gait at {name} = {own:.10g} is not found ({err})"
    if approach.status == "reached":
        return solve_fixed_point(Walker(first, planar=approach.planar, period=approach.period),
                                 approach.points[-1].fixed_point), ""
    folds = [e.value for e in approach.events if e.kind == "fold"]
    where = (f"folds back at {name} = {folds[0]:.10g} (a fold: no gait of this branch beyond it)"
             if folds else f"stops short ({approach.status}: {approach.message})")
    return None, f"the walker's own gait at {name} = {own:.10g}, followed towards {start:.10g}, {where}"


def _approach(params: Params, first: Params, name: str, own: float, start: float, planar,
              max_points: int, ds_max: float, search_err: GaitNotFound) -> Gait:
    """Where the search found no gait at ``name = start``: the walker's own gait followed there
    (:func:`_follow_own`), or why it does not get there (a fold between: the Tinkertoy fit's gait
    ends 1e-9 rad below its own slope, and a slope typed to seven digits lies past it)."""
    gait, why = _follow_own(params, first, name, own, start, planar, max_points, ds_max)
    if gait is not None:
        return gait
    raise GaitNotFound(f"{why}; the search at {start:.10g} found none either ({search_err})") from search_err


def continue_branch(params: Params, name: str, start: float, end: float, max_points: int = 200,
                    ds: float | None = None, ds_max: float = 0.05, z_start: np.ndarray | None = None,
                    planar: bool | None = None, progress: bool = False) -> Branch:
    """Follow the gait from ``name = start`` towards ``name = end``.

    Parameters
    ----------
    params : Params
        The walker; ``name`` is set to ``start`` for the first gait.
    name : str
        Parameter-file name of the continued parameter.
    start, end : float
        Parameter range (SI units of that parameter).
    max_points : int
        Cap on the number of branch points.
    ds : float, optional
        Initial arclength step (in units where the parameter range is 1); default 1/20.
    ds_max : float
        Largest arclength step (same units).
    z_start : ndarray, shape (8,), optional
        A start near the first gait (default: :func:`find_gait`).
    planar : bool, optional
        Continue in the planar reduction (default: as the first gait is found).

    The branch follows fixed points of the stride map (two steps) when the walker or the
    continued parameter breaks the mirror symmetry (an effect such as ``effects.asymmetry``), so
    that every point's eigenvalues belong to the same map; otherwise of the step map.
    """
    from .effects import EFFECTS

    k = _index(name)
    if not (math.isfinite(start) and math.isfinite(end)) or start == end:
        raise ValueError(f"continuation needs two different finite values, got {start} and {end}")
    first_params = params.replace(**{name: start})
    breaking = name.startswith("effects.") and EFFECTS[name.split(".", 1)[1]].breaks_symmetry
    period = 2 if breaking or params.breaks_symmetry or first_params.breaks_symmetry else 1
    if z_start is None:
        gait = _first_gait(params, first_params, name, start, planar, max_points, ds_max)
        if gait.period != period:
            gait = solve_fixed_point(Walker(first_params, planar=gait.planar, period=period),
                                     gait.fixed_point)
    else:
        gait = solve_fixed_point(Walker(first_params, planar=bool(planar), period=period), z_start)
    planar = gait.planar
    active = [4, 5, 6, 7] if planar else list(range(8))
    na = len(active)
    scale = abs(end - start)  # the parameter is measured in units of the range
    direction = math.copysign(1.0, end - start)
    ds = ds if ds is not None else 0.05
    ds_min = 1e-6
    ds = min(ds, ds_max)
    points = [_point(gait, start)]
    events: list[BranchEvent] = []
    y = np.concatenate([gait.fixed_point[active], [start / scale]])
    tangent = None
    status, message = "max_points", ""  # the message says where, once stopped

    def residual(yv):
        value = yv[-1] * scale
        walker = Walker(params.replace(**{name: value}), planar=planar, period=period)
        z = np.zeros(8)
        z[active] = yv[:na]
        step = walker.cycle(z, params_jacobian=True)
        f = (step.z_plus - z)[active]
        jac = np.zeros((na, na + 1))
        jac[:, :na] = step.jacobian[np.ix_(active, active)] - np.eye(na)
        jac[:, na] = step.jacobian_params[active, k] * scale
        return f, jac

    def gait_at(value, active_state):
        """The gait at ``name = value`` by Newton from a state given by its active components."""
        z = np.zeros(8)
        z[active] = active_state
        return solve_fixed_point(Walker(params.replace(**{name: value}), planar=planar,
                                        period=period), z)

    def add_point(point):
        if points[-1].stable != point.stable:
            events.append(_stability_event(params, name, points[-1], point, planar, period))
        points.append(point)

    def null_vector(jac, previous):
        _, _, vt = np.linalg.svd(jac)
        t = vt[-1]
        if previous is None:
            t = t * math.copysign(1.0, t[-1] * direction if t[-1] != 0 else 1.0)
        elif t @ previous < 0:
            t = -t
        return t / np.linalg.norm(t)

    try:
        _, jac0 = residual(y)
    except StepFailure as err:
        raise GaitNotFound(f"the first gait does not step: {err}") from err
    tangent = null_vector(jac0, None)
    bar = tqdm(total=max_points, disable=not progress, desc=f"continuing {name}", unit="pt")
    while len(points) < max_points:
        predicted = y + ds * tangent
        if (predicted[-1] * scale - end) * direction >= 0:
            # The predictor passes the end: land on it with a fixed-parameter solve (this also
            # keeps the parameter inside its valid range when the end is a bound, e.g. w = 0).
            try:
                final = gait_at(end, y[:na])
            except GaitNotFound:
                ds *= 0.5
                if ds < ds_min:
                    status, message = "stalled", f"no gait found at the end value {name} = {end:.6g}"
                    break
                continue
            add_point(_point(final, end))
            status, message = "reached", f"reached {name} = {end:.6g}"
            break
        yc, ok, its, refused = predicted.copy(), False, 0, None
        for _ in range(_MAXIT):
            its += 1
            try:
                f, jac = residual(yc)
            except StepFailure:  # a fall
                break
            except ParameterError as err:  # the parameter left its valid range
                refused = str(err)
                break
            g = np.concatenate([f, [tangent @ (yc - predicted)]])
            if np.max(np.abs(f)) < _TOL:
                ok = True
                break
            big = np.vstack([jac, tangent])
            try:
                yc = yc - np.linalg.solve(big, g)
            except np.linalg.LinAlgError:
                break
        if not ok:
            ds *= 0.5
            if ds < ds_min:
                status = "stalled"
                why = (f"the branch leaves the parameter's valid range ({refused})" if refused else
                       "the gait may end there: a fall or a grazing heel strike")
                message = (f"the corrector failed below the minimum step near {name} = "
                           f"{y[-1] * scale:.6g} ({why})")
                break
            continue
        new_tangent = null_vector(jac, tangent)
        value = float(yc[-1] * scale)
        try:
            gait_new = gait_at(value, yc[:na])
        except GaitNotFound:
            ds *= 0.5
            continue
        if tangent[-1] * new_tangent[-1] < 0:
            events.append(BranchEvent("fold", value, f"the branch turns back at {name} = {value:.6g}"))
        add_point(_point(gait_new, value))
        bar.update(1)
        y, tangent = yc, new_tangent
        ds = min(ds_max, ds * (1.5 if its <= 3 else 1.0))
        if (value - start) * direction < -1e-12 * scale:
            status, message = "turned back", f"the branch came back past {name} = {start:.6g}"
            break
    bar.close()
    if status == "max_points":
        last = points[-1].value
        message = (f"stopped after {max_points} points at {name} = {last:.6g}, "
                   f"{abs(last - start) / scale:.0%} of the way from {start:.6g} to {end:.6g}")
    return Branch(name=name, points=points, events=events, status=status, message=message,
                  planar=planar, period=period)


def _stability_event(params: Params, name: str, a: BranchPoint, b: BranchPoint,
                     planar: bool, period: int) -> BranchEvent:
    """Locate where max|lambda| = 1 between two points (secant on max|lambda| - 1)."""
    lo, hi = a, b
    for _ in range(30):
        fa, fb = lo.max_abs_eigenvalue - 1.0, hi.max_abs_eigenvalue - 1.0
        if fb == fa:
            break
        value = hi.value - fb * (hi.value - lo.value) / (fb - fa)
        if abs(hi.value - lo.value) < 1e-12 * max(1.0, abs(value)):
            break
        w = Walker(params.replace(**{name: value}), planar=planar, period=period)
        frac = (value - lo.value) / (hi.value - lo.value) if hi.value != lo.value else 0.5
        guess = lo.fixed_point + frac * (hi.fixed_point - lo.fixed_point)
        try:
            mid = _point(solve_fixed_point(w, guess), value)
        except GaitNotFound:
            break
        if abs(mid.max_abs_eigenvalue - 1.0) < 1e-10:
            lo = hi = mid
            break
        if (mid.max_abs_eigenvalue < 1.0) == (lo.max_abs_eigenvalue < 1.0):
            lo = mid
        else:
            hi = mid
    crossing = hi if abs(hi.max_abs_eigenvalue - 1) <= abs(lo.max_abs_eigenvalue - 1) else lo
    lam = crossing.eigenvalues[0]
    if abs(lam.imag) > 1e-6:
        arg = math.degrees(np.angle(lam))
        how = f"a complex pair crosses the unit circle (|lambda| = 1, arg {arg:.1f} deg)"
    elif lam.real < 0:
        how = "an eigenvalue passes through -1 (period doubling)"
    else:
        how = "an eigenvalue passes through +1 (fold or symmetry-breaking bifurcation)"
    kind = "loses stability" if a.stable else "gains stability"
    value = float(0.5 * (lo.value + hi.value))
    return BranchEvent(kind, value, f"the gait {kind} at {name} = {value:.8g}: {how}")
