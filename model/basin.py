"""How large a disturbance a gait survives, and whether a walker released by hand finds its gait.

A gait's eigenvalues (:class:`~toywalk.model.gait.Gait`) describe only an infinitesimal
neighbourhood of its fixed point; Coleman, Garcia, Mombaur & Ruina (Phys. Rev. E 64, 022901, 2001)
leave the basin of attraction of their stable model uninvestigated. Here it is measured on the
full nonlinear step map (:meth:`Walker.step <toywalk.model.walker.Walker.step>`: flow to the heel
strike, collision, mirror), with falls detected and scuffs counted:

- :func:`recovers`: does a walk from a post-strike state return to the gait?
- :func:`basin_radius`: the largest perturbation along a direction of the state from which it
  does, by bracketing and bisection; :func:`eigen_directions` and :func:`random_directions` give
  the directions (each eigenvector's real and imaginary part, both signs; seeded random ones).
- :func:`recovery_curve`: the fraction of random directions that recover, against the size.
- :func:`hand_launch`: released from rest, legs parallel and normal to the ramp, aimed down the
  fall line (or off it by a heading error) and tipped onto one foot: does it walk into its gait?

**Perturbation size.** States are compared in the gait search's units
(:func:`~toywalk.model.gait.state_scale`): angles in rad, rates in units of 1/sqrt(l/g) (for a
15 cm leg, 1 unit = 8.09 rad/s). A perturbation of size s along a unit direction u (Euclidean
norm 1 in those units) is ``z = z* + s * state_scale * u``, then moved onto the post-strike
surface (the trailing foot on the ramp) by adjusting the trailing leg's pitch (:func:`perturbed`):
every start is a state just after a heel strike, as the step map's is. Eigenvectors of the
non-zero eigenvalues already lie in that surface's tangent; random directions are drawn uniformly
on the unit sphere of that tangent space (7 dimensions).

**Cost** (2 cores shared with other jobs, compiled kernels cached): one step of the step map takes
about 0.25 ms for the shipped toy-sized walkers, so a walk of a few hundred steps takes tens of
ms; docs/gaits.md section 5 gives each function's measured time.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from .gait import Gait, find_gait, state_scale
from .parameters import Params
from .walker import StepFailure, Walker

__all__ = ["LAUNCH_MULTIPLES", "BasinRadius", "HandLaunch", "Recovery", "RecoveryCurve", "basin_radius",
           "basin_report", "eigen_directions", "hand_launch", "launch_state", "perturbed",
           "random_directions", "recovers", "recovery_curve"]

#: Default step budget of :func:`recovers`. The slowest shipped stable gait (stable-toy, |lambda|
#: 0.967) shrinks a perturbation by 1e-3 in log(1e-3)/log(0.967) = 206 steps; 600 leaves room for
#: the transient of a large one.
STEPS = 600
#: Default absolute tolerance of :func:`recovers` (state_scale units): the walk has recovered when
#: its state at a heel strike is this close to the fixed point and :data:`SHRINK` times closer than
#: at the start. 1e-4 lies far inside every basin radius measured (docs/gaits.md section 5: the
#: smallest nonzero radius of a stable shipped gait is above 1e-3), where the linear theory holds.
TOL = 1e-4
#: ... and the distance must have shrunk to this fraction of the start's, so that a start already
#: within TOL (a tiny perturbation of an unstable gait) does not count as recovered before it grows.
SHRINK = 1e-2
# The trailing leg's pitch is adjusted until the trailing foot's height is below this (m) at a
# perturbed start (round-off of the guard's height is 1e-17 m for 15 cm legs).
_SURFACE_TOL = 1e-13
# The swing leg starts a hand launch pitched back by this much (rad): the step map needs its foot
# to start behind the stance foot (by 1e-6 leg lengths, walker._START_GAP); 1e-5 rad is 1.5 um of
# a 15 cm leg, against tip angles of 10 mrad and more.
_LAUNCH_GAP = 1e-5


@dataclasses.dataclass(frozen=True)
class Recovery:
    """The outcome of a walk from a perturbed start (:func:`recovers`).

    Attributes
    ----------
    recovered : bool
    steps : int
        Heel strikes walked (to the recovery, the failure, or the budget).
    reason : str
        ``"recovered"``, ``"fell"``, ``"no_heel_strike"``, ``"inadmissible_impact"``,
        ``"scuffed"`` (the swing foot went below the ramp before the legs passed, counted as a
        failure: see :func:`recovers`) or ``"not_converged"`` (walking after ``steps``).
    distance : float
        Distance from the fixed point at the last heel strike (state_scale units; NaN after a fall
        in the first step).
    scuffs : int
        Swing-foot crossings of the ramp before the legs passed, over the walk.
    """

    recovered: bool
    steps: int
    reason: str
    distance: float
    scuffs: int


@dataclasses.dataclass(frozen=True)
class BasinRadius:
    """The basin's extent along one direction (:func:`basin_radius`).

    Attributes
    ----------
    direction : ndarray, shape (8,)
        The unit direction (state_scale units).
    label : str
        What it is (``"eig 1 re +"``, ``"random 3"``, ...).
    radius : float
        The largest size found to recover (state_scale units): the lower end of the final bracket;
        0 when even ``smallest`` fails.
    upper : float
        The smallest size found to fail above it (inf when ``largest`` still recovers).
    evaluations : int
        Walks made.
    """

    direction: np.ndarray
    label: str
    radius: float
    upper: float
    evaluations: int


@dataclasses.dataclass(frozen=True)
class RecoveryCurve:
    """Probability of recovery against perturbation size over random directions.

    Attributes
    ----------
    sizes : ndarray, shape (n,)
        (state_scale units)
    trials : int
        Random directions per size (the same directions at every size).
    recovered : ndarray of int, shape (n,)
    """

    sizes: np.ndarray
    trials: int
    recovered: np.ndarray

    @property
    def probability(self) -> np.ndarray:
        """``recovered / trials``, shape (n,)."""
        return self.recovered / self.trials

    @property
    def se(self) -> np.ndarray:
        """Binomial standard error of :attr:`probability`, sqrt(p (1 - p) / trials)."""
        p = self.probability
        return np.sqrt(p * (1 - p) / self.trials)


@dataclasses.dataclass(frozen=True)
class HandLaunch:
    """Hand launches over tip angles and headings (:func:`hand_launch`).

    Attributes
    ----------
    tip_angles : ndarray, shape (n_tip,)
        (rad)
    headings : ndarray, shape (n_heading,)
        (rad; 0 aims down the fall line)
    results : list of list of Recovery
        ``results[i][j]``: heading i, tip angle j.
    """

    tip_angles: np.ndarray
    headings: np.ndarray
    results: list

    def recovered(self) -> np.ndarray:
        """Shape (n_heading, n_tip), bool."""
        return np.array([[r.recovered for r in row] for row in self.results], dtype=bool)

    def tip_range(self, heading_index: int = 0) -> tuple[float, float] | None:
        """(smallest, largest) tip angle that recovered at that heading (rad), or None. Launches
        between them need not all recover: see :meth:`recovered`."""
        ok = self.tip_angles[self.recovered()[heading_index]]
        return (float(ok.min()), float(ok.max())) if len(ok) else None


def _gait(params: Params, gait: Gait | None) -> Gait:
    if gait is None:
        return find_gait(params, z_guess=None if params.gait_start is None else np.array(params.gait_start))
    if not isinstance(gait, Gait):
        raise TypeError(f"gait must be a Gait or None, got {type(gait).__name__}")
    return gait


def _scuffs_fail(gait: Gait, scuffs_fail: bool | None) -> bool:
    return sum(s.scuffs for s in gait.steps) == 0 if scuffs_fail is None else bool(scuffs_fail)


def recovers(params: Params, z0: np.ndarray, gait: Gait | None = None, steps: int = STEPS,
             tol: float = TOL, shrink: float = SHRINK, scuffs_fail: bool | None = None,
             side: int = 1, walker: Walker | None = None) -> Recovery:
    """Walk from ``z0`` until the state at a heel strike returns to the gait, or it fails.

    Parameters
    ----------
    params : Params
    z0 : ndarray, shape (8,)
        Start (public order), with the left leg in stance for ``side`` = 1, in the mirrored
        description for -1 (as :meth:`Walker.step` takes it). Usually just after a heel strike;
        any state whose swing foot is behind the stance foot will do (a hand launch's is not).
    gait : Gait, optional
        The gait to return to; default ``find_gait(params)`` (from the file's ``[gait]`` start
        when it has one).
    steps : int
        Heel strikes to walk at most.
    tol, shrink : float
        Recovered at the first heel strike (after a whole period, at the gait's phase) whose state
        lies within ``tol`` of the fixed point and within ``shrink`` times the start's distance
        (state_scale units, Euclidean). The step map mirrors each step, so every post-strike state
        is compared with the fixed point directly; a stride-periodic gait is compared every other
        step, when the left leg is again in stance.
    scuffs_fail : bool, optional
        Whether a scuff (the swing foot crossing the ramp before the legs pass; the model lets it
        through) ends the walk as a failure. A real foot that does so catches the ramp: the shipped
        stable walker, whose gait scuffs, falls in MuJoCo (docs/gaits.md section 4). Default: a
        failure exactly when the gait itself does not scuff; for a gait that scuffs every step
        (stable-toy) the basin is the model's, with the foot let through, and the scuffs counted.
    side : {1, -1}
        The physical leg in stance at the start.
    walker : Walker, optional
        Reuse one (built from ``params``).

    Returns
    -------
    Recovery
    """
    gait = _gait(params, gait)
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    if not (tol > 0 and 0 < shrink < 1):
        raise ValueError(f"tol must be > 0 and shrink in (0, 1), got {tol!r}, {shrink!r}")
    if side not in (1, -1):
        raise ValueError(f"side must be +1 (left leg in stance) or -1, got {side!r}")
    walker = Walker(params, planar=gait.planar) if walker is None else walker
    fail_on_scuff = _scuffs_fail(gait, scuffs_fail)
    scale = state_scale(params)
    z = np.asarray(z0, dtype=float)
    if z.shape != (8,) or not np.all(np.isfinite(z)):
        raise ValueError(f"z0 must be 8 finite numbers, got {z0!r}")
    target = min(tol, shrink * float(np.linalg.norm((z - gait.fixed_point) / scale)))
    scuffs, distance = 0, math.nan
    for k in range(steps):
        try:
            step = walker.step(z, side=side)
        except StepFailure as err:
            return Recovery(False, k, err.status, distance, scuffs)
        scuffs += step.scuffs
        z, side = step.z_plus, -side
        distance = float(np.linalg.norm((z - gait.fixed_point) / scale))
        if fail_on_scuff and step.scuffs:
            return Recovery(False, k + 1, "scuffed", distance, scuffs)
        if distance <= target and (gait.period == 1 or side == 1):
            return Recovery(True, k + 1, "recovered", distance, scuffs)
    return Recovery(False, steps, "not_converged", distance, scuffs)


def perturbed(params: Params, gait: Gait, direction: np.ndarray, size: float,
              walker: Walker | None = None) -> np.ndarray:
    """The fixed point moved by ``size`` along ``direction`` (state_scale units) and then onto the
    post-strike surface: the trailing leg's pitch (theta_sw) is adjusted by Newton's method until
    the trailing foot touches the ramp (its height below 1e-13 m), so the start is a state just
    after a heel strike. Shape (8,)."""
    walker = Walker(params, planar=gait.planar) if walker is None else walker
    z = gait.fixed_point + size * state_scale(params) * np.asarray(direction, dtype=float)
    for _ in range(20):
        h = walker.guard(walker.full_state(z))[0]
        if abs(h) <= _SURFACE_TOL:
            break
        dz = np.zeros(8)
        dz[6] = 1e-7
        dh = (walker.guard(walker.full_state(z + dz))[0] - walker.guard(walker.full_state(z - dz))[0]) / 2e-7
        z[6] -= h / dh
    return z


def _tangent_basis(params: Params, gait: Gait, walker: Walker) -> np.ndarray:
    """Orthonormal basis (state_scale units) of the post-strike surface's tangent at the fixed
    point, shape (8, 7) (planar: the pitch block, (8, 3))."""
    scale = state_scale(params)
    grad = np.zeros(8)
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = 1e-7 * scale[i]
        grad[i] = (walker.guard(walker.full_state(gait.fixed_point + dz))[0]
                   - walker.guard(walker.full_state(gait.fixed_point - dz))[0]) / 2e-7
    active = [4, 5, 6, 7] if gait.planar else list(range(8))
    sub = np.zeros((8, len(active)))
    sub[active, range(len(active))] = 1.0
    normal = grad / np.linalg.norm(grad)
    projected = sub - np.outer(normal, normal @ sub)
    u, sv, _ = np.linalg.svd(projected, full_matrices=False)
    return u[:, sv > 1e-8]


def random_directions(params: Params, gait: Gait, n: int, rng=None) -> np.ndarray:
    """``n`` unit directions (state_scale units), uniform on the sphere of the post-strike
    surface's tangent space at the fixed point, drawn from ``rng``; shape (n, 8)."""
    rng = np.random.default_rng(rng)
    basis = _tangent_basis(params, gait, Walker(params, planar=gait.planar))
    draws = rng.standard_normal((n, basis.shape[1]))
    out = draws @ basis.T
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def eigen_directions(gait: Gait) -> list[tuple[str, np.ndarray]]:
    """(label, unit direction in state_scale units) for each non-zero eigenvalue's eigenvector:
    the real part and, for a complex pair (taken once), the imaginary part, each with both signs.
    Labels say ``eig k re +``, k counting the eigenvalues by decreasing modulus from 1."""
    scale = state_scale(gait.params)
    out, seen = [], []
    for k, lam in enumerate(gait.eigenvalues):
        if abs(lam) < 1e-9 or any(abs(lam - np.conj(s)) < 1e-9 and abs(lam.imag) > 0 for s in seen):
            continue
        seen.append(lam)
        vec = gait.eigenvectors[:, k] / scale
        parts = [("re", vec.real)] + ([("im", vec.imag)] if abs(lam.imag) > 1e-12 else [])
        for name, part in parts:
            unit = part / np.linalg.norm(part)
            out += [(f"eig {k + 1} {name} +", unit), (f"eig {k + 1} {name} -", -unit)]
    return out


def basin_radius(params: Params, direction: np.ndarray, gait: Gait | None = None, label: str = "",
                 smallest: float = 1e-5, largest: float = 2.0, first: float = 1e-2, rtol: float = 0.02,
                 walker: Walker | None = None, **kwargs) -> BasinRadius:
    """The largest perturbation along ``direction`` from which the gait recovers (:func:`recovers`).

    From ``first`` the size is doubled while the walk recovers (up to ``largest``), or halved while
    it fails (down to ``smallest``), to bracket the edge; the bracket is then bisected (on a log
    scale) until (upper - radius) <= rtol * radius. The recovering sizes along a ray need not form
    one interval (a larger push can land in the basin again): the radius is the edge of the
    interval that starts at the gait, as far as the bracketing sees it.

    Parameters
    ----------
    params : Params
    direction : ndarray, shape (8,)
        Normalised to unit length (state_scale units).
    gait : Gait, optional
    label : str
    smallest, largest, first : float
        Sizes (state_scale units).
    rtol : float
        Relative width of the final bracket.
    walker : Walker, optional
    **kwargs
        Passed to :func:`recovers` (``steps``, ``tol``, ``shrink``, ``scuffs_fail``).
    """
    gait = _gait(params, gait)
    walker = Walker(params, planar=gait.planar) if walker is None else walker
    direction = np.asarray(direction, dtype=float)
    norm = float(np.linalg.norm(direction))
    if direction.shape != (8,) or not norm > 0:
        raise ValueError(f"direction must be 8 numbers, not all 0, got {direction!r}")
    if not (0 < smallest <= first <= largest and rtol > 0):
        raise ValueError("need 0 < smallest <= first <= largest and rtol > 0")
    unit = direction / norm
    count = 0

    def ok(size: float) -> bool:
        nonlocal count
        count += 1
        return recovers(params, perturbed(params, gait, unit, size, walker), gait, walker=walker,
                        **kwargs).recovered

    size = first
    if ok(size):
        lo, hi = size, math.inf
        while lo < largest:
            size = min(2.0 * lo, largest)
            if not ok(size):
                hi = size
                break
            lo = size
        if math.isinf(hi):
            return BasinRadius(unit, label, lo, math.inf, count)
    else:
        lo, hi = 0.0, size
        while hi > smallest:
            size = max(0.5 * hi, smallest)
            if ok(size):
                lo = size
                break
            hi = size
        if lo == 0.0:
            return BasinRadius(unit, label, 0.0, hi, count)
    while hi - lo > rtol * lo:
        mid = math.sqrt(lo * hi)
        if ok(mid):
            lo = mid
        else:
            hi = mid
    return BasinRadius(unit, label, lo, hi, count)


def recovery_curve(params: Params, sizes: Sequence[float], trials: int, seed=None, gait: Gait | None = None,
                   **kwargs) -> RecoveryCurve:
    """The fraction of ``trials`` random directions (:func:`random_directions`, drawn from
    ``seed``; the same at every size) from which a perturbation of each size recovers.

    ``kwargs`` go to :func:`recovers`.
    """
    gait = _gait(params, gait)
    if trials < 1:
        raise ValueError(f"trials must be >= 1, got {trials!r}")
    sizes = np.asarray(sizes, dtype=float)
    walker = Walker(params, planar=gait.planar)
    directions = random_directions(params, gait, trials, seed)
    counts = np.array([
        sum(recovers(params, perturbed(params, gait, u, s, walker), gait, walker=walker, **kwargs).recovered
            for u in directions)
        for s in sizes
    ])
    return RecoveryCurve(sizes, trials, counts)


def launch_state(tip: float, heading: float = 0.0, split: float = 0.0, rate: float = 0.0) -> np.ndarray:
    """The public state of a hand launch, shape (8,): the left foot on the ramp, the axle tipped by
    ``tip`` (rad, > 0) onto it (psi = -tip: the right end up, the right foot off the ramp), steer
    ``heading`` (rad) from the fall line.

    By default at rest with both legs normal to the ramp (theta = 0), the right leg's pitch 1e-5 rad
    back, because the step map needs its foot to start behind the stance foot. ``split`` (rad, >= 0)
    opens the legs symmetrically about the normal instead, the left (stance) leg forward by
    ``split / 2`` and the right leg back by as much; ``rate`` (rad/s) starts both legs pitching
    forward together at that rate (a push: the walker rolls forward on its stance foot as one body,
    the hinge still)."""
    if not split >= 0.0:
        raise ValueError(f"split must be >= 0 (rad), got {split!r}")
    if not math.isfinite(rate):
        raise ValueError(f"rate must be finite (rad/s), got {rate!r}")
    half = 0.5 * split
    return np.array([heading, 0.0, -tip, 0.0, -half, rate, max(half, _LAUNCH_GAP), rate])


def hand_launch(params: Params, tip_angles: Sequence[float], headings: Sequence[float] = (0.0,),
                gait: Gait | None = None, split: float = 0.0, rate: float = 0.0, **kwargs) -> HandLaunch:
    """Release the walker from rest, tipped onto one foot, and see whether it walks into its gait.

    **The start.** Held by hand with both legs parallel and normal to the ramp, aimed down the fall
    line (steer = ``heading``), the axle tipped by the tip angle onto the left foot so that the
    right foot is off the ramp, every rate 0 (:func:`launch_state`). That is a stance phase on
    the left foot from rest: the model's continuous dynamics start there honestly (the left foot
    rolls on the ramp; the right leg swings freely about the axle). Two departures, both stated:
    the right leg starts pitched back by 1e-5 rad, because the step map needs the swing foot
    behind the stance foot (legs exactly together are a trivial fixed point of the map); and
    the first landing of the lifted foot must come ahead of the stance foot to be a heel strike.
    If it comes down beside or behind it instead (a scuff: the model would let it through the
    ramp, where a real foot lands and rocks the walker onto it, a double support the model does not
    have), the launch is reported as ``"scuffed"`` whatever ``scuffs_fail`` says: the model cannot
    follow it honestly. A walker whose effects break the mirror symmetry would need the launch on
    the right foot too; a symmetric walker's is the mirror image of this one.

    Parameters
    ----------
    params : Params
    tip_angles : sequence of float
        (rad, > 0)
    headings : sequence of float
        Steer at release (rad).
    gait : Gait, optional
    split, rate : float
        A release with the legs open by ``split`` (rad) and pushed forward at ``rate`` (rad/s), as
        :func:`launch_state` makes it; the defaults are the launch above.
    **kwargs
        Passed to :func:`recovers`.
    """
    gait = _gait(params, gait)
    tips = np.asarray(tip_angles, dtype=float)
    if not np.all(tips > 0):
        raise ValueError(f"tip angles must be > 0 (rad), got {tip_angles!r}")
    walker = Walker(params, planar=gait.planar)
    results = []
    for heading in headings:
        row = []
        for tip in tips:
            z0 = launch_state(float(tip), float(heading), split, rate)
            try:
                first = walker.step(z0)
            except StepFailure as err:
                row.append(Recovery(False, 0, err.status, math.nan, 0))
                continue
            if first.scuffs:
                row.append(Recovery(False, 1, "scuffed", math.nan, first.scuffs))
                continue
            rest = recovers(params, first.z_plus, gait, side=-1, walker=walker, **kwargs)
            row.append(dataclasses.replace(rest, steps=rest.steps + 1))
        results.append(row)
    return HandLaunch(tips, np.asarray(headings, dtype=float), results)


#: Tip angles of :func:`basin_report`'s hand launches, as multiples of the gait's lean amplitude
#: (issue 44 asks for 1.5 and 2.5).
LAUNCH_MULTIPLES = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0)


def basin_report(gait: Gait, n_random: int = 20, seed=0, headings: Sequence[float] = (0.0,)) -> dict:
    """A gait's basin in one JSON-ready object (``toywalk gait --basin``): the radius along each
    eigenvector direction and along ``n_random`` random directions drawn from ``seed`` (with
    their minimum, median and maximum), and the hand launch at :data:`LAUNCH_MULTIPLES` times the
    gait's lean amplitude and each heading (rad), with the seconds it all took. Sizes are in
    state_scale units (module docstring); about 0.1-0.3 s a direction for the shipped walkers."""
    import time

    start = time.perf_counter()
    params = gait.params
    walker = Walker(params, planar=gait.planar)
    eig = [basin_radius(params, u, gait, label=label, walker=walker) for label, u in eigen_directions(gait)]
    rnd = [basin_radius(params, u, gait, label=f"random {i}", walker=walker)
           for i, u in enumerate(random_directions(params, gait, n_random, seed))] if n_random else []
    lean = gait.lean_amplitude
    tips = [m * lean for m in LAUNCH_MULTIPLES] if lean > 0 else [math.radians(d) for d in (1.0, 2.0, 3.0)]
    launch = hand_launch(params, tips, headings, gait=gait)

    def spread(radii):
        values = [r.radius for r in radii]
        return ({"min": min(values), "median": float(np.median(values)), "max": max(values)}
                if values else None)

    return {
        "units": "angles rad, rates in 1/sqrt(l/g) (state_scale)",
        "scuffs_fail": _scuffs_fail(gait, None),
        "eigenvectors": [{"direction": r.label, "radius": r.radius, "upper": r.upper} for r in eig],
        "eigenvector_radius": spread(eig),
        "random": {"n": n_random, "seed": seed, "radius": spread(rnd),
                   "radii": [r.radius for r in rnd]},
        "hand_launch": [{"heading": float(h), "tip": float(t),
                         "tip_over_lean": float(t / lean) if lean else None,
                         "recovered": res.recovered, "reason": res.reason, "steps": res.steps}
                        for h, row in zip(launch.headings, launch.results, strict=True)
                        for t, res in zip(launch.tip_angles, row, strict=True)],
        "seconds": time.perf_counter() - start,
    }
