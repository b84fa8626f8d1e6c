"""Every gait of a walker: a global search over many starts, catalogued by distinct fixed points.

:func:`find_gait` follows one branch from the planar reduction (docs/model.md section 5) and stops
at the first gait; :func:`all_gaits` looks for all of them. Its starts, each Newton's method on
the period map (:func:`~toywalk.model.gait.solve_fixed_point`):

- ``find_gait``: the gait :func:`find_gait` returns (the parameter file's ``[gait] start``, or the
  planar reduction's first gait followed to the walker);
- ``planar branch T``: every distinct gait of the planar reduction (:func:`planar_gaits`, a wide
  grid), each followed to the walker by continuation (:func:`continue_gait`);
- ``pitch a= k=``: a pitch-paced grid, stance angle ``a`` (rad) and stance rate ``k a sqrt(g/l)``,
  the swing leg's rate ``cos(2a)`` times it (the simplest walker's heel strike, Garcia et al. 1998,
  J. Biomech. Eng. 120:281), lean and steer zero;
- ``rocking psi= T= a=`` (3D walkers only): rocking-paced starts, a small pitch amplitude ``a``,
  a large lean ``psi`` at heel strike turning back through zero over the step (lean rate
  ``-2 psi / T``), with step time ``T`` a fraction of the leg's half pendulum period
  ``pi sqrt(l/g)``: the toy of Coleman & Ruina (1998) steps about every third of its legs' swing
  period, paced by its side-to-side rocking (issue 42).

:func:`follow_in_slope` follows each gait found in the ramp's slope, both ways from the walker's
own (:func:`~toywalk.model.continuation.continue_branch`, which passes folds): where each family
exists, where it is stable, and whether two gaits of the catalogue are one family through a fold.

Two gaits are the same when their fixed points, scaled by :func:`state_scale` (rad and rad per
sqrt(l/g)), differ by at most :data:`SAME_GAIT` in every component and their step times by at most
:data:`SAME_GAIT` relative. Each gait kept is a fixed point to :data:`FIXED_POINT_TOL` in that
scaled max norm, checked by one more step of a fresh walker.

A module of its own (not :mod:`toywalk.model.gait`): it only composes that module's public
solvers, and the catalogue, its starts and its bookkeeping would double a file already at the
size where one reads it whole.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterator, Sequence

import numpy as np

from .continuation import Branch, BranchPoint, continue_branch
from .gait import (
    Gait,
    GaitNotFound,
    continue_gait,
    find_gait,
    lateral_singular,
    planar_gaits,
    planar_reduction,
    solve_fixed_point,
    state_scale,
)
from .parameters import Params
from .walker import StepFailure, Walker, is_planar_symmetric

__all__ = ["FIXED_POINT_TOL", "SAME_GAIT", "FoundGait", "GaitSearch", "SlopeFamily", "all_gaits",
           "follow_in_slope"]

#: A gait returned is a fixed point to this: max |P(z) - z| over the state, angles in rad and rates
#: in rad per sqrt(l/g) (the issue's 1e-10; Newton stops at 1e-11 and polishes, measured 1e-16 to
#: 1e-13 on the shipped walkers).
FIXED_POINT_TOL = 1e-10
#: Two fixed points within this (scaled max norm) and step times within this relative are one gait:
#: far above Newton's residual (1e-11), far below the distance between the branches found (the
#: simplest walker's two planar gaits differ by 0.1 rad).
SAME_GAIT = 1e-6

#: Pitch-paced grid: stance angles (rad) and rate ratios (dimensionless).
_PITCH_ANGLES = (0.05, 0.1, 0.2, 0.3)
_PITCH_RATES = (0.5, 1.0, 1.5)
#: Rocking-paced grid: lean at heel strike (rad), step time as a fraction of pi sqrt(l/g), and the
#: small stance angle (rad).
_ROCK_LEANS = (0.03, 0.07, 0.12)
_ROCK_TIMES = (0.25, 0.4, 0.6)
_ROCK_PITCH = (0.03, 0.08)


@dataclasses.dataclass
class FoundGait:
    """One distinct gait of :func:`all_gaits`.

    Attributes
    ----------
    gait : Gait
    how : str
        The start it was first found from (see the module's docstring for the kinds).
    start : ndarray, shape (8,)
        That start (public state order, docs/model.md section 1).
    residual : float
        max |P(z) - z| at the fixed point, angles in rad and rates in rad per sqrt(l/g).
    found_from : int
        How many starts converged to it.
    """

    gait: Gait
    how: str
    start: np.ndarray
    residual: float
    found_from: int = 1

    def summary(self) -> dict:
        """JSON-ready row (``toywalk gait --all --json``)."""
        g = self.gait
        return {"step_time": g.step_time, "stride_length": g.stride_length,
                "lean_amplitude": g.lean_amplitude, "steer_amplitude": g.steer_amplitude,
                "max_abs_eigenvalue": g.max_abs_eigenvalue, "stable": g.stable,
                "clearance": g.clearance, "planar": g.planar, "residual": self.residual,
                "how": self.how, "found_from": self.found_from,
                "fixed_point": [float(v) for v in g.fixed_point]}


@dataclasses.dataclass
class GaitSearch:
    """What :func:`all_gaits` found and what it cost.

    Attributes
    ----------
    gaits : list of FoundGait
        Distinct gaits sorted by step time.
    starts : int
        Starts tried.
    converged : int
        Starts that converged to a gait (distinct or not).
    seconds : float
        Wall time.
    """

    gaits: list
    starts: int
    converged: int
    seconds: float


def all_gaits(params: Params, starts: Sequence[tuple[str, np.ndarray]] | None = None,
              seed: int | None = None, n_random: int = 0, planar: bool | None = None) -> GaitSearch:
    """Every distinct symmetric gait found from many starts.

    Parameters
    ----------
    params : Params
    starts : sequence of (str, ndarray shape (8,)), optional
        Extra starts (label, state just after heel strike), tried after the built-in ones.
    seed : int, optional
        Seed of ``n_random`` random starts (uniform over the built-in grids' ranges).
    n_random : int
        Random starts (0: none).
    planar : bool, optional
        Solve in the planar reduction; default as :func:`find_gait` (planar exactly for a
        planar-symmetric walker with point-mass lateral inertia).

    Returns
    -------
    GaitSearch
        Its ``gaits`` sorted by step time; empty when no start converged.
    """
    if n_random < 0:
        raise ValueError(f"n_random must be >= 0, got {n_random}")
    if n_random and seed is None:
        raise ValueError("n_random starts need a seed (seed=...)")
    if planar is None:
        planar = is_planar_symmetric(params) and lateral_singular(params)
    clock = time.perf_counter()
    walker = Walker(params, planar=planar)
    scale = state_scale(params)
    found: list[FoundGait] = []
    tried = converged = 0
    for how, z0, gait in _candidates(params, walker, planar, starts, seed, n_random):
        tried += 1
        if gait is None:
            try:
                gait = solve_fixed_point(walker, z0)
            except GaitNotFound:
                continue
        residual = _residual(walker, gait.fixed_point, scale)
        if not residual <= FIXED_POINT_TOL:
            continue
        converged += 1
        same = next((f for f in found if _same(f.gait, gait, scale)), None)
        if same is not None:
            same.found_from += 1
            continue
        found.append(FoundGait(gait=gait, how=how, start=np.asarray(z0, float).copy(),
                               residual=residual))
    found.sort(key=lambda f: f.gait.step_time)
    return GaitSearch(gaits=found, starts=tried, converged=converged,
                      seconds=time.perf_counter() - clock)


@dataclasses.dataclass
class SlopeFamily:
    """One gait of a catalogue followed in slope, down and up from the walker's own.

    Attributes
    ----------
    gait : int
        Its index in the catalogue (:attr:`GaitSearch.gaits`, sorted by step time).
    down, up : Branch or None
        The family followed from the walker's slope to the lower and to the upper end (None where
        the range does not reach that side, or the first step failed: ``why``).
    why : str
        Why a side was not followed ("" when both were).
    joins : int or None
        The catalogue's gait that this family comes back to at the walker's slope after a fold
        (a side that turned back, solved at the walker's slope from its last gait), if any: the
        two are one family.
    """

    gait: int
    down: Branch | None
    up: Branch | None
    why: str = ""
    joins: int | None = None

    @property
    def points(self) -> list[BranchPoint]:
        """The family's gaits in order along it: the lower side from its far end, the walker's own
        gait once, then the upper side."""
        down = self.down.points[::-1] if self.down is not None else []
        up = self.up.points if self.up is not None else []
        return down + (up[1:] if down and up else up)

    @property
    def branches(self) -> list[Branch]:
        return [b for b in (self.down, self.up) if b is not None]

    def table(self) -> tuple[list[str], np.ndarray]:
        """(column names, rows) of :attr:`points`, in :meth:`Branch.table`'s columns."""
        planar = bool(self.branches and self.branches[0].planar)
        return Branch("slope", self.points, [], "", "", planar).table()


def follow_in_slope(params: Params, search: GaitSearch, low: float, high: float,
                    max_points: int = 60) -> list[SlopeFamily]:
    """Each gait of ``search`` (found for ``params``) followed in ``slope`` from the walker's own to
    ``low`` and to ``high`` (rad; ``low <= params.slope <= high``), at most ``max_points`` gaits a
    side. A side whose first gait does not step is left out, with the reason."""
    own = float(params.slope)
    if not (math.isfinite(low) and math.isfinite(high) and low <= own <= high and low < high):
        raise ValueError(f"the slope range must hold the walker's slope {own:.6g} rad, "
                         f"got {low:.6g} to {high:.6g}")
    families = []
    for i, found in enumerate(search.gaits):
        sides, why = [], []
        for end in (low, high):
            if end == own:
                sides.append(None)
                continue
            try:
                sides.append(continue_branch(params, "slope", own, end, max_points=max_points,
                                             z_start=found.gait.fixed_point, planar=found.gait.planar))
            except GaitNotFound as err:
                sides.append(None)
                why.append(f"towards {end:.6g} rad: {str(err).splitlines()[0]}")
        families.append(SlopeFamily(gait=i, down=sides[0], up=sides[1], why="; ".join(why),
                                    joins=_rejoined(params, search, i, sides)))
    return families


def _rejoined(params: Params, search: GaitSearch, i: int, sides) -> int | None:
    """The catalogue's gait (other than ``i``) a side that turned back past a fold reaches at the
    walker's slope: Newton there from the side's last gait, matched as :func:`all_gaits` matches."""
    scale = state_scale(params)
    for branch in sides:
        if branch is None or branch.status != "turned back":
            continue
        try:
            back = solve_fixed_point(Walker(params, planar=branch.planar), branch.points[-1].fixed_point)
        except GaitNotFound:
            continue
        for j, other in enumerate(search.gaits):
            if j != i and _same(other.gait, back, scale):
                return j
    return None


def _candidates(params: Params, walker: Walker, planar: bool, extra, seed: int | None,
                n_random: int) -> Iterator[tuple[str, np.ndarray, Gait | None]]:
    """(label, start, gait already solved or None), the built-in starts then ``extra``."""
    try:
        known = find_gait(params, planar=planar)
        yield "find_gait", known.fixed_point, known
    except GaitNotFound:
        pass
    if not planar:
        reduced = planar_reduction(params)
        for base in planar_gaits(params):
            try:
                gait = continue_gait(reduced, params, base.fixed_point)
            except GaitNotFound:
                continue
            yield f"planar branch {base.step_time:.4g} s", base.fixed_point, gait
    rate = 1.0 / params.time_scale
    for a in _PITCH_ANGLES:
        for k in _PITCH_RATES:
            yield f"pitch a={a:g} k={k:g}", _pitch_start(a, k * a * rate), None
    if not planar:
        half_swing = math.pi * params.time_scale
        for psi in _ROCK_LEANS:
            for frac in _ROCK_TIMES:
                for a in _ROCK_PITCH:
                    step = frac * half_swing
                    yield (f"rocking psi={psi:g} T={frac:g}pi a={a:g}",
                           _rocking_start(a, psi, step), None)
    if n_random:
        rng = np.random.default_rng(seed)
        for i in range(n_random):
            a = rng.uniform(0.02, 0.35)
            z = _pitch_start(a, rng.uniform(0.3, 2.0) * a * rate)
            if not planar:
                z[2] = rng.uniform(-0.15, 0.15)
                z[3] = rng.uniform(-3.0, 3.0) * z[2] / params.time_scale
            yield f"random {i} (seed {seed})", z, None
    for label, z in extra or ():
        z = np.asarray(z, float)
        if z.shape != (8,) or not np.all(np.isfinite(z)):
            raise ValueError(f"start {label!r} must be a finite state of shape (8,), got {z!r}")
        yield str(label), z, None


def _pitch_start(a: float, rate: float) -> np.ndarray:
    z = np.zeros(8)
    z[4], z[5], z[6], z[7] = -a, rate, a, rate * math.cos(2.0 * a)
    return z


def _rocking_start(a: float, psi: float, step_time: float) -> np.ndarray:
    """Small pitch ``a`` covered in ``step_time``, lean ``psi`` turning back through zero."""
    z = _pitch_start(a, 2.0 * a / step_time)
    z[2], z[3] = psi, -2.0 * psi / step_time
    return z


def _residual(walker: Walker, z: np.ndarray, scale: np.ndarray) -> float:
    """max |P(z) - z| / scale, by a fresh cycle (inf when the step fails)."""
    try:
        z_plus = walker.cycle(z).z_plus
    except StepFailure:
        return math.inf
    active = slice(4, 8) if walker.planar else slice(0, 8)
    return float(np.max(np.abs((z_plus - z)[active] / scale[active])))


def _same(a: Gait, b: Gait, scale: np.ndarray) -> bool:
    close = np.max(np.abs((a.fixed_point - b.fixed_point) / scale)) <= SAME_GAIT
    return bool(close and abs(a.step_time - b.step_time) <= SAME_GAIT * a.step_time)
