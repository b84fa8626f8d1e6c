"""The log-posterior of free parameters given a measured walk, fast enough for emcee.

For a parameter vector theta the gait is found by Newton's method on the period map (shooting:
the compiled step map and its exact AD Jacobian, :func:`toywalk.model.gait.solve_fixed_point`),
warm-started from the nearest gait this process has already solved (the fit's gait at first).
Newton converges to unstable gaits as well; nothing is simulated beyond one period. The model's
angles at the measured phases come from that period's recorded integration grid, by cubic Hermite
interpolation with the exact derivatives at the nodes (error below 1e-5 rad at the default 16
steps per sqrt(l/g), under 1 % of a tracker's noise; tests/sysid/test_fit.py compares it with
the collocation operator). The measurement model is that of :mod:`toywalk.sysid.measurement`.

The nuisance offsets (and, where the walk has contact positions, their origin) enter linearly
with fixed weights, so with a flat prior they integrate out exactly: the marginal likelihood is
the profile likelihood (nuisances at their weighted least-squares values) times a constant. (The
contacts' design holds the model's path in the yaw column that the steer offset shares, so the
"constant" is the log-determinant of a 5-by-5 normal matrix that moves with the stride length,
by its relative spread over the posterior, a fraction of a percent: neglected.) The time offset
(the model's first heel strike against the measured one, :mod:`toywalk.sysid.measurement`) is
profiled too, by Gauss-Newton from the fit's value: the profile of a nuisance this well
determined (a few hundredths of a millisecond) is its marginal to within a constant (Laplace).
The noise SDs are fixed (the file's, or the fit's estimates).

Priors: uniform within each free parameter's physical bounds (effect declarations, lengths and
masses non-negative, foot radii below the leg length), flat elsewhere; a parameter set that is
not a valid walker has zero prior density. ``log_prob(theta)`` returns ``-inf`` outside the
prior or where no gait exists, with a status recorded in the blob; a NaN in theta is an error.
"""

from __future__ import annotations

import math
import uuid

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from toywalk.model.gait import GaitNotFound, solve_fixed_point
from toywalk.model.parameters import ParameterError, Params
from toywalk.model.walker import Walker

from .measurement import Observations, components, offsets_design, path, shutter_reads, step_counts
from .problem import with_values

__all__ = ["NO_GAIT", "OK", "OUTSIDE_PRIOR", "GaitCurves", "LogPosterior", "Reading", "model_angles"]

#: Status codes stored with every sample (the blob's ``status``).
OK, OUTSIDE_PRIOR, NO_GAIT = 0, 1, 2
# Warm starts kept per process and posterior: (theta, fixed point), the newest last. They live in
# the process, not in the (pickled, per task) posterior object, so a pool worker keeps them.
_CACHE = 64
_WARM: dict[str, list] = {}
#: Gauss-Newton iterations of the time offset's profile (it converges in two or three: the
#: residuals are nearly linear in it over the few hundredths of a millisecond it moves).
_PROFILE_ITERATIONS = 5


class Reading:
    """Where each observation reads a gait of ``period`` steps (model step, state component,
    mirror sign) and how the model's clock counts steps: everything that does not depend on the
    gait, built once per posterior rather than per evaluation."""

    def __init__(self, obs: Observations, period: int, planar: bool):
        reads, self.average = shutter_reads(obs)  # three reads a sample with the shutter open
        model_step, self.component, self.sign = components(reads, period, planar)
        self.before, _, self.strikes_before = step_counts(reads, period)
        self.rows = [np.flatnonzero((model_step == j) & (self.component >= 0)) for j in range(period)]
        self.t_rel = reads.time - obs.step_start[0]
        self.strike_rel = obs.strikes - obs.step_start[0]
        self.n_reads = len(reads.value)  # the samples' own count where the shutter is not stated


class GaitCurves:
    """A shot gait read at the observations: its period's integration grid by cubic Hermite
    interpolation, built once per gait, read at any time offset."""

    def __init__(self, gait, obs: Observations, planar: bool, walker: Walker,
                 reading: Reading | None = None):
        self.reading = reading or Reading(obs, gait.period, planar)
        self.strike_rel = self.reading.strike_rel
        self.durations = np.array([s.step_time for s in gait.steps])
        self.splines = []
        for step in gait.steps:
            derivs = np.array([walker.rhs(x, step.side) for x in step.states])
            self.splines.append(CubicHermiteSpline(step.times, step.states, derivs, axis=0))

    def angles(self, time_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The gait's angle at every observation (rad), read between the model's heel strikes,
        and the model's strike times from the first measured one (s)."""
        r = self.reading
        local = r.t_rel - (time_offset + r.before @ self.durations)
        out = np.zeros(r.n_reads)
        for rows, spline in zip(r.rows, self.splines, strict=True):
            if len(rows):
                states = spline(local[rows])
                out[rows] = r.sign[rows] * states[np.arange(len(rows)), r.component[rows]]
        if r.average is not None:
            out = r.average @ out
        return out, time_offset + r.strikes_before @ self.durations


def model_angles(gait, obs: Observations, planar: bool, walker: Walker,
                 time_offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The gait's angle at every observation (rad) and the model's heel-strike times from the
    first measured one (s) (:class:`GaitCurves`)."""
    return GaitCurves(gait, obs, planar, walker).angles(time_offset)


class LogPosterior:
    """Picklable log-posterior of ``free`` parameters (the blob: max |eigenvalue|, status).

    Parameters
    ----------
    params : Params
        The walker; its values of the free parameters are not used.
    free : list of str
        Parameter-file names of the sampled parameters.
    bounds : list of (float, float)
        The uniform prior's support for each.
    obs : Observations
        The measured walk.
    sigma : ndarray, shape (n_obs,)
        Noise SD of each observation (rad).
    offsets : bool
        Integrate out the ramp-frame offsets.
    z_start : ndarray, shape (8,)
        A gait near the posterior (the fit's), for the first warm start.
    planar : bool
    period : int
    priors : dict of str to (float, float), optional
        Gaussian priors ``name -> (mean, sd)`` on some free parameters (on top of the bounds).
    time_offset : float
        The fit's time offset (s), where the profile's Gauss-Newton starts.
    contact_sd : ndarray, shape (2 n_pos,), optional
        SDs (m) of the measured contact positions at heel strikes (``x`` of each, then ``y``),
        required when the walk has them (:class:`toywalk.sysid.measurement.Path`).
    """

    def __init__(self, params: Params, free, bounds, obs: Observations, sigma: np.ndarray,
                 offsets: bool, z_start: np.ndarray, planar: bool, period: int,
                 priors: dict | None = None, time_offset: float = 0.0,
                 contact_sd: np.ndarray | None = None):
        self.params, self.free, self.bounds = params, list(free), [tuple(b) for b in bounds]
        priors = priors or {}
        self._prior = [(self.free.index(n), float(m), float(s)) for n, (m, s) in priors.items()]
        self.obs, self.sigma = obs, np.asarray(sigma, float)
        self.offsets, self.planar, self.period = offsets, planar, period
        self.z_start = np.asarray(z_start, float)
        self._design = offsets_design(obs) if offsets else np.zeros((len(obs.value), 0))
        self._reading = Reading(obs, period, planar)
        self._path = path(obs, period)
        self.contact_sd = np.zeros(0) if contact_sd is None else np.asarray(contact_sd, float)
        if self.contact_sd.shape != (2 * self._path.n,) or not np.all(self.contact_sd > 0):
            raise ValueError(f"contact_sd must hold {2 * self._path.n} positive SDs (m), one per "
                             f"measured contact coordinate, got shape {self.contact_sd.shape}")
        self.time_offset = float(time_offset)
        self._token = uuid.uuid4().hex  # names this posterior's warm starts in each process

    @property
    def _cache(self) -> list:
        return _WARM.setdefault(self._token, [])

    def _start(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """The nearest solved gait's fixed point and its map's Jacobian, else the start's (no
        Jacobian)."""
        cache = self._cache
        if not cache:
            return self.z_start, None
        dist = [np.sum(((t - theta) / np.maximum(np.abs(t), 1e-12)) ** 2) for t, _, _ in cache]
        _, z, jac = cache[int(np.argmin(dist))]
        return z, jac

    def gait(self, theta: np.ndarray, warm: bool = True):
        """The gait at ``theta`` (from the nearest solved gait by chord steps with its Jacobian,
        Newton where they stall, else Newton from the start), or None."""
        try:
            walker_params = with_values(self.params, self.free,
                                        dict(zip(self.free, map(float, theta), strict=True)))
        except ParameterError:
            return None, None
        walker = Walker(walker_params, planar=self.planar, period=self.period)
        starts = [self._start(theta)] if warm else []
        if not any(z is self.z_start for z, _ in starts):
            starts.append((self.z_start, None))
        for z0, jac in starts:
            try:
                gait = solve_fixed_point(walker, z0, jacobian=jac)
            except GaitNotFound:
                continue
            self._cache.append((np.array(theta, float), gait.fixed_point.copy(), gait.map_jacobian))
            del self._cache[:-_CACHE]
            return gait, walker
        return None, walker

    def _nuisance_design(self, gait) -> tuple[np.ndarray, np.ndarray]:
        """The linear nuisances' design over the angle rows then the contact rows (offsets, then
        the contacts' origin; the steer offset also yaws the contacts) and the contacts' model
        values without them, ``(design, contacts)``."""
        n_pos, b = self._path.n, self._design
        if not n_pos:
            return b, np.zeros(0)
        disp = np.array([step.contact for step in gait.steps]).T
        x, y = self._path.relative(disp)
        design = np.zeros((len(b) + 2 * n_pos, b.shape[1] + 2))
        design[:len(b), :b.shape[1]] = b
        design[len(b):len(b) + n_pos, b.shape[1]] = 1.0  # origin_x on the X rows
        design[len(b) + n_pos:, b.shape[1] + 1] = 1.0  # origin_y on the Y rows
        if self.offsets:  # the steer offset yaws the path: X - o Y, Y + o X (measurement.Path)
            design[len(b):, 1] = np.r_[-y, x]
        return design, np.r_[x, y]

    def _residuals(self, curves: GaitCurves, time_offset: float,
                   nuisance: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Whitened residuals (angles with the linear nuisances at their best values, strike
        times, then contact positions) and the model's angles with those nuisances."""
        angles, strikes = curves.angles(time_offset)
        design, contacts = nuisance
        n_obs = len(angles)
        sd = np.r_[self.sigma, self.contact_sd]
        resid = np.r_[angles - self.obs.value, contacts - self._path.value.T.ravel()] / sd
        if design.shape[1]:
            whitened = design / sd[:, None]
            best = np.linalg.lstsq(whitened, -resid, rcond=None)[0]
            resid = resid + whitened @ best
            angles = angles + design[:n_obs] @ best
        r_strike = (strikes - curves.strike_rel) / self.obs.strike_sd
        return np.r_[resid[:n_obs], r_strike, resid[n_obs:]], angles

    def profile(self, gait, walker) -> tuple[float, float, np.ndarray]:
        """``(chi2, time_offset, angles)`` with the offsets and the time offset at their best
        values (Gauss-Newton on the time offset, central differences of 1 microsecond: the
        angles are cubic in it, so the difference is exact to round-off times the rates)."""
        curves = GaitCurves(gait, self.obs, self.planar, walker, self._reading)
        nuisance = self._nuisance_design(gait)
        dt, h = self.time_offset, 1e-6
        for _ in range(_PROFILE_ITERATIONS):
            r0, _ = self._residuals(curves, dt, nuisance)
            slope = (self._residuals(curves, dt + h, nuisance)[0]
                     - self._residuals(curves, dt - h, nuisance)[0]) / (2 * h)
            step = -float(slope @ r0) / max(float(slope @ slope), 1e-300)
            dt += step
            if abs(step) < 1e-9:
                break
        r, angles = self._residuals(curves, dt, nuisance)
        return float(r @ r), dt, angles

    def chi2(self, gait, walker) -> float:
        """Sum of squared whitened residuals, the offsets and the time offset at their best
        values."""
        return self.profile(gait, walker)[0]

    def __call__(self, theta) -> tuple[float, float, int]:
        theta = np.asarray(theta, dtype=float)
        if not np.all(np.isfinite(theta)):
            raise ValueError(f"log_prob got a non-finite parameter vector {theta.tolist()}")
        for value, (low, high) in zip(theta, self.bounds, strict=True):
            if not low <= value <= high:
                return -math.inf, math.nan, OUTSIDE_PRIOR
        gait, walker = self.gait(theta)
        if walker is None:
            return -math.inf, math.nan, OUTSIDE_PRIOR
        if gait is None:
            return -math.inf, math.nan, NO_GAIT
        value = -0.5 * (self.chi2(gait, walker)
                        + sum(((theta[j] - m) / s) ** 2 for j, m, s in self._prior))
        if math.isnan(value):
            at = dict(zip(self.free, theta.tolist(), strict=True))
            raise ValueError(f"the log-likelihood is NaN at {at}")
        return value, gait.max_abs_eigenvalue, OK

