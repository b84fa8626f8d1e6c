"""The stride-to-stride return map estimated directly from measured strides (Floquet multipliers
from data).

A measured walk is cut into steps at its heel strikes (:func:`toywalk.sysid.measurement.observations`).
Once per step, at a chosen **phase** of the step (default mid-step, 0.5), the walker's state is
estimated from the samples around it: a local quartic least-squares fit of each angle in time over
a window of the step, weighted by a tricube kernel (Savitzky & Golay, Anal. Chem. 36:1627, 1964;
Cleveland, J. Am. Stat. Assoc. 74:829, 1979), gives the angle and its rate, and the fit's
covariance gives their measurement error. The section state is docs/model.md's public state in the
step's own description, shape (8,)::

    x = (phi, phi_dot, psi, psi_dot, theta_st, theta_st_dot, theta_sw, theta_sw_dot)

with phi the steer and psi the lean (rad, rad/s), theta_st / theta_sw the pitches of the leg in
stance / in swing during that step.

The return map is fitted to the section states ``x_k`` (Hurmuzlu & Basdogan, J. Biomech. Eng.
116:30, 1994; Dingwell & Kang, J. Biomech. Eng. 129:586, 2007)::

    x_{k+1} - xbar_1 = J (x_k - xbar_0) + e_k

- **stride map** (default): the sections of the steps with one stance leg (every other step), so
  ``x_k`` and ``x_{k+1}`` are a stride apart and need no mirroring; its eigenvalues are the stride
  map's Floquet multipliers (for a symmetric walker, the step map's squared);
- **step map**: every step, the right-stance steps mirrored (y -> -y: lean, steer and their rates
  change sign; the pitches are already stance / swing), for walkers whose gait repeats every step;
  its eigenvalues are the step map's. The left- and right-stance sections are each centred on
  their own mean: a constant offset of the measured lean or steer (a camera's roll or yaw about
  the ramp) changes sign with the mirror and would otherwise show as an eigenvalue -1.

The eigenvalues do not depend on the phase of the section, nor on a smooth change of the section
coordinates (the map in other coordinates is conjugate to it), so a bias of the local fit that is
a smooth function of the state does not bias them. A quadratic fit is not enough for that: the
cubic term it leaves out leaks into the rate and varies from stride to stride by more than the
rates themselves do (for the walker of ``data/params/stable-toy.toml`` at mid-step, noise-free,
the steer rate's error scatters by 0.044 rad/s, twice the rate's own 0.022 rad/s; with a cubic,
by 0.001). On a window centred in the step the rate comes from the odd terms (u, u^3) and the
angle from the even ones (1, u^2, u^4), so a quartic costs the rate nothing over a cubic and
frees the angle of the quartic term's bias (0.3 to 0.4 of an SD in the pitches at 0.003 rad of
noise; below 0.1 with it), for 20 % more noise in the angle.

Measurement *noise* does bias them: noise in the regressor ``x_k`` biases least squares toward
zero (errors in variables, regression dilution; Fuller, *Measurement Error Models*, Wiley 1987,
ch. 1 and 2). Three estimators, with the sample covariances ``S_ab`` of ``x_{k+a}`` and
``x_{k+b}``:

- ``naive``: ordinary least squares, ``J = S_10 S_00^-1``;
- ``corrected``: the errors-in-variables correction with the known noise covariance of the section
  states (from the local fits), ``J = S_10 (S_00 - Sigma_noise)^-1`` (Fuller 1987, ch. 2);
- ``instrumental``: instrumental variables with ``x_{k-1}`` as instrument, ``J = S_1,-1
  S_0,-1^-1``, consistent because the noise of different strides is independent (Durbin, Rev.
  Int. Stat. Inst. 22:23, 1954). It needs no noise model, but three consecutive sections, and a
  state whose every direction remembers the last stride (no fast or constrained directions).

Directions in which the section states vary between strides by less than ``min_snr`` times their
noise (generalized eigenvectors of ``S_00`` and ``Sigma_noise`` with signal-to-noise variance
ratio ``mu - 1 < min_snr``) hold no usable information about ``J``: ``S_00 - Sigma_noise`` is
near singular there. All three estimators are fitted in the other directions and map those to
zero, with a warning. A walk exactly on its cycle has no such direction at all, and no estimate.
A fit in fewer directions than coordinates is a partial observation of the state: its eigenvalues
are those of the map seen through the retained combinations, close to the dominant multipliers
when those dominate the spread, not equal to them.

**Section coordinates.** The default is the full state, :data:`ALL_COORDINATES`: its map is the
only one whose eigenvalues are the walker's multipliers at any phase of the section. A subset
(:data:`LATERAL_COORDINATES`, lean and steer with their rates) is a partial observation: its
eigenvalues are those of the map seen through the subset, and they move with the phase. For the
stable walker of ``data/params/stable-toy.toml`` (two noise-free walks of 5000 strides kicked by
0.001 rad/s), the full state's largest stride multiplier is 0.930 to 0.948 at phases 0.25, 0.5
and 0.75, the model's 0.935; lean and steer alone give 0.919 to 0.931 at 0.25 and 0.5, and 0.977
to 0.979 at 0.75. The 8 x 8 map's 72 unknowns are too many for the 20 to 40 strides of a video, and the
full section state lies on a 7-dimensional surface (the state after a heel strike is on the guard
surface, docs/model.md section 4). So the fit keeps only the directions the data determine: those
above the noise, at most 7 of the full state's 8, and at most ``n_pairs // 5 - 1`` of them (5 pairs
per unknown of each row of J), largest signal-to-noise ratio first, and it says so. (Without the
guard's cap, the eighth direction of a noise-free walk sometimes reaches a signal-to-noise ratio
of 1 against the fourth-difference noise floor, and the correction, dividing by it, moved the
largest multiplier from 0.94 to 1.01.) A short or noisy walk's map is therefore a partial
observation too, through the combinations that vary most.

Uncertainty: a bootstrap over strides (pairs, or triplets for the instrumental estimate, drawn with
replacement; Efron & Tibshirani, *An Introduction to the Bootstrap*, Chapman & Hall 1993, ch. 9)
of each estimator's largest eigenvalue modulus, with the retained directions held fixed. It
ignores the serial dependence of the strides; for the stable walker at 600 strides it gave 0.011
to 0.019 in four walks, where least squares on repeated walks of the linearised map scatter by
0.016.

Heel-strike times are taken as exact unless the events carry ``time_sd``; then a strike's timing
error shifts the section time and adds ``(rate, acceleration)`` times it to the section state's
error covariance. For the step map, consecutive sections share a strike, so timing errors make
their noise correlated, which the instrumental estimate assumes away.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.linalg
from toywalk.model.trajectory import SIGNALS, TrajectoryTable
from toywalk.model.walker import STATE_NAMES

from .measurement import MeasurementError, observations

__all__ = ["ALL_COORDINATES", "ESTIMATORS", "LATERAL_COORDINATES", "MapEstimate", "ReturnMap",
           "ReturnMapError", "Sections", "return_map", "return_maps", "section_states"]

#: Every section coordinate, in docs/model.md's public state order.
ALL_COORDINATES = STATE_NAMES
#: Steer and lean with their rates (a partial observation: see the module docstring).
LATERAL_COORDINATES = ("phi", "phi_dot", "psi", "psi_dot")
#: The estimators of J, in the order they are reported.
ESTIMATORS = ("naive", "corrected", "instrumental")

# The measured signal each section coordinate is read from (pitches: by the step's stance leg).
_SIGNAL_OF = {"phi": "steer", "psi": "lean", "theta_st": "pitch", "theta_sw": "pitch"}
# Public indices of the angles whose rate follows them (phi, psi, theta_st, theta_sw).
_ANGLE_INDEX = {"phi": 0, "psi": 2, "theta_st": 4, "theta_sw": 6}
# Indices that change sign in the mirror y -> -y (docs/model.md section 4): phi, phi_dot, psi, psi_dot.
_MIRRORED = np.array([0, 1, 2, 3])
# Pairs per unknown of each row of J (the kept directions and the intercept): fewer directions
# are fitted when the walk is short (a rule of thumb for regressions: below 5 observations per
# unknown the estimates scatter by a large fraction of their spread).
_PAIRS_PER_UNKNOWN = 5
# Weak instrument: the first-stage F statistic of the weakest direction below 10 (Staiger & Stock,
# Econometrica 65:557, 1997).
_WEAK_INSTRUMENT = 10.0
# Given standard deviations are called inconsistent with the samples when the fourth-difference
# variance over their mean variance leaves [1/2, 2]: from thousands of differences its sampling
# error is a few per cent, so such a ratio means the SDs are wrong by a factor sqrt(2) or more.
_VARIANCE_RATIO = (0.5, 2.0)
# Samples count as evenly spaced (for the fourth differences) within this fraction of the median
# sample interval.
_EVEN_SPACING = 0.05
# Regularisation of the noise covariance in the generalized eigenproblem, relative to the
# standardized (unit-variance) coordinates: a noise-free walk's estimated noise is round-off.
_NOISE_FLOOR = 1e-14
# The bootstrap interval: central 95 %. The bootstrap SD is half the central 68.3 % interval,
# robust to the heavy tails a weak instrument gives the bootstrap distribution.
_INTERVAL = (2.5, 97.5)
_ONE_SIGMA = (15.87, 84.13)


class ReturnMapError(MeasurementError):
    """The walk cannot give a return map as asked (too few strides, missing signals, bad options)."""


# --------------------------------------------------------------------------------- sections
@dataclasses.dataclass
class Sections:
    """The state at one phase of every complete measured step, from local polynomial fits.

    Shapes use ``n`` for the number of complete steps.

    Attributes
    ----------
    phase : float
        Phase of the section within each step, in [0, 1].
    width : float
        Window of the local fits, as a fraction of the step (centred on ``phase``, clipped to the
        step).
    degree : int
        Degree of the local polynomials.
    step : ndarray of int, shape (n,)
        Index of the measured step (0 = the step after the first heel strike).
    stance : ndarray of str, shape (n,)
        'L' or 'R', the physical leg in stance.
    time : ndarray, shape (n,)
        Section times (s).
    duration : ndarray, shape (n,)
        Step durations (s).
    states : ndarray, shape (n, 8)
        Section states in the public order (rad, rad/s), physical description (unmirrored); NaN
        where a signal needed has too few samples in the window.
    covariance : ndarray, shape (n, 8, 8)
        Measurement-error covariance of each section state (rad^2, rad^2/s, rad^2/s^2).
    valid : ndarray of bool, shape (n,)
        Every requested coordinate was estimated.
    signals : tuple of str
        The measured signals used (of :data:`toywalk.model.trajectory.SIGNALS`).
    noise_sd : dict of str to float
        Noise SD per signal (rad) the covariances use: the RMS of the ``*_sd`` column (where every
        sample has one), or the estimate from the samples' fourth differences, or failing those
        (no five evenly spaced samples in a row) from the residuals of the local fits;
        ``noise_source`` says which.
    noise_source : dict of str to str
        ``"*_sd columns"``, ``"fourth differences"`` or ``"local-fit residuals"``.
    difference_sd : dict of str to float
        The fourth-difference estimate of the noise SD (rad; NaN where there are no such runs), also
        where the file gives SDs: a check of them.
    residual_rms : dict of str to float
        Kernel-weighted RMS residual about the local fits (rad): noise plus the polynomial's misfit.
    timing : bool
        The heel strikes' ``time_sd`` entered the covariance (else strike times are taken as exact).
    """

    phase: float
    width: float
    degree: int
    step: np.ndarray
    stance: np.ndarray
    time: np.ndarray
    duration: np.ndarray
    states: np.ndarray
    covariance: np.ndarray
    valid: np.ndarray
    signals: tuple
    noise_sd: dict
    noise_source: dict
    difference_sd: dict
    residual_rms: dict
    timing: bool

    def mirrored(self) -> tuple[np.ndarray, np.ndarray]:
        """(states, covariance) with the right-stance steps mirrored to the left-stance description
        (steer, lean and their rates change sign); shapes (n, 8), (n, 8, 8)."""
        sign = np.ones((len(self.step), 8))
        sign[np.ix_(self.stance == "R", _MIRRORED)] = -1.0
        return self.states * sign, self.covariance * sign[:, :, None] * sign[:, None, :]


def _check_window(phase, width, degree) -> tuple[float, float, int]:
    try:
        phase, width = float(phase), float(width)
    except (TypeError, ValueError) as err:
        raise ReturnMapError(f"phase and width must be numbers, got {phase!r}, {width!r}") from err
    if not 0.0 <= phase <= 1.0:
        raise ReturnMapError(f"phase must lie in [0, 1] (a fraction of the step), got {phase!r}")
    if not 0.0 < width <= 1.0:
        raise ReturnMapError(f"width must lie in (0, 1] (a fraction of the step), got {width!r}")
    if isinstance(degree, bool) or not isinstance(degree, int | np.integer) or not 1 <= degree <= 5:
        raise ReturnMapError(f"degree must be an integer from 1 to 5 (the rate needs 1), got {degree!r}")
    return phase, width, int(degree)


def section_states(table: TrajectoryTable, phase: float = 0.5, width: float = 0.5, degree: int = 4,
                   signals=SIGNALS) -> Sections:
    """Estimate the state at ``phase`` of every complete step by local polynomial fits.

    Parameters
    ----------
    table : TrajectoryTable
        A measured walk (the trajectory format of docs/formats.md) with its heel strikes.
    phase : float
        Section phase within the step, in [0, 1] (0 = heel strike).
    width : float
        The fit window as a fraction of the step, in (0, 1]: samples with ``|phase_i - phase| <
        width / 2``, clipped to the step. Wider windows average more samples (the rate's SD falls
        as width^-1.5) but let more of the motion's higher terms into the estimates (for the
        stable walker at 240 samples per second and 0.003 rad of noise, width 0.5 gives 0.0017 rad
        and 0.18 rad/s SDs, with biases below 0.1 of those).
    degree : int
        Degree of the local polynomials (1 to 5); the rate needs 1, the timing term 2. Default 4
        (see the module docstring).
    signals : sequence of str
        The signals to use (of :data:`toywalk.model.trajectory.SIGNALS`); the states' other
        components are NaN.

    Returns
    -------
    Sections

    Raises
    ------
    ReturnMapError
        A signal is missing from the table, fewer than two complete steps, or bad options.
    """
    phase, width, degree = _check_window(phase, width, degree)
    if not isinstance(table, TrajectoryTable):
        raise ReturnMapError(f"table must be a TrajectoryTable, got {type(table).__name__}")
    signals = tuple(signals)
    unknown = [s for s in signals if s not in SIGNALS]
    if unknown or not signals:
        raise ReturnMapError(f"signals must be among {', '.join(SIGNALS)}, got {list(signals)}")
    missing = [s for s in signals if s not in table.signals]
    if missing:
        raise ReturnMapError(f"the walk has no {', '.join(missing)} column: the section states need it")
    try:
        obs = observations(table, signals=signals)
    except MeasurementError as err:
        raise ReturnMapError(str(err)) from err
    n = obs.n_steps
    duration = obs.durations
    t_c = obs.step_start + phase * duration
    tau = 0.5 * width * duration  # half-window (s): the polynomials' time unit
    est, cov2 = {}, {}
    noise_sd, noise_source, residual_rms, difference_sd = {}, {}, {}, {}
    for name in signals:
        rows = np.flatnonzero(obs.signal == SIGNALS.index(name))
        difference_sd[name] = _difference_sd(obs, rows)
        known = bool(np.all(np.isfinite(obs.sd[rows])))
        rows = rows[np.abs(obs.phase[rows] - phase) < 0.5 * width]
        est[name], cov2[name], residual_rms[name] = _local_fits(obs, rows, n, t_c, tau, degree, known)
        if not np.any(np.isfinite(est[name][:, 0])):
            raise ReturnMapError(f"no step has {degree + 2} or more {name} samples within the window "
                                 f"(phase {phase:g} +/- {0.5 * width:g}): widen it or lower the degree")
        if known:
            noise_sd[name] = float(np.sqrt(np.mean(obs.sd[rows] ** 2)))
            noise_source[name] = "*_sd columns"
        elif math.isfinite(difference_sd[name]):
            noise_sd[name] = difference_sd[name]
            noise_source[name] = "fourth differences"
            cov2[name] *= noise_sd[name] ** 2
        else:
            noise_sd[name] = residual_rms[name]
            noise_source[name] = "local-fit residuals"
            cov2[name] *= noise_sd[name] ** 2
    states = np.full((n, 8), np.nan)
    cov = np.zeros((n, 8, 8))
    grad = np.zeros((n, 8))  # d(section state)/d(section time): (rate, acceleration) per angle
    left = obs.stance == "L"
    for coord, i in _ANGLE_INDEX.items():
        source = _SIGNAL_OF[coord]
        if source == "pitch":
            own_left = coord == "theta_st"  # stance pitch: the left leg's in left-stance steps
            names = ("pitch_left", "pitch_right") if own_left else ("pitch_right", "pitch_left")
            if names[0] not in signals or names[1] not in signals:
                continue
            e = np.where(left[:, None], est[names[0]], est[names[1]])
            c = np.where(left[:, None, None], cov2[names[0]], cov2[names[1]])
        else:
            if source not in signals:
                continue
            e, c = est[source], cov2[source]
        states[:, i:i + 2] = e[:, :2]
        cov[:, i:i + 2, i:i + 2] = c
        grad[:, i:i + 2] = e[:, 1:3]
    # the strikes of the steps used (a run of complete steps where strikes are missing), where
    # the events file gives their SDs
    timing = obs.strike_sd_measured
    if timing:
        strike_sd = obs.strike_sd
        var_t = ((1.0 - phase) * strike_sd[:-1]) ** 2 + (phase * strike_sd[1:]) ** 2
        cov += var_t[:, None, None] * grad[:, :, None] * grad[:, None, :]
    cols = [j for j in range(8) if set(_signals_for((STATE_NAMES[j],))) <= set(signals)]
    valid = np.all(np.isfinite(states[:, cols]), axis=1)
    return Sections(phase=phase, width=width, degree=degree, step=np.arange(n), stance=obs.stance,
                    time=t_c, duration=duration, states=states, covariance=cov, valid=valid,
                    signals=signals, noise_sd=noise_sd, noise_source=noise_source,
                    difference_sd=difference_sd, residual_rms=residual_rms, timing=timing)


def _local_fits(obs, rows, n, t_c, tau, degree, known):
    """Kernel-weighted polynomial fits of one signal's samples ``rows`` around every section.

    The weights are the tricube kernel of the time from the section over the half-window
    (Cleveland, J. Am. Stat. Assoc. 74:829, 1979), times the inverse variance where the SDs are
    ``known``: samples entering and leaving the window as the sample grid slides along the steps
    then change the fit smoothly, not by a jump.

    Returns ``(est, cov, residual_rms)``: (value, rate, acceleration) per step, shape (n, 3), NaN
    where the window holds fewer than ``degree + 2`` samples; the covariance of (value, rate),
    shape (n, 2, 2), for the given SDs or for unit noise; and the kernel-weighted RMS residual
    (rad).
    """
    n_coef = degree + 1
    rows = rows[np.argsort(obs.step[rows], kind="stable")]
    k_of = obs.step[rows]
    bounds = np.searchsorted(k_of, np.arange(n + 1))
    # The windows side by side, padded to the longest with zero weight: shape (n, m).
    slot = np.arange(len(rows)) - bounds[k_of]
    m = int(np.diff(bounds).max()) if len(rows) else 0
    u, y, kernel, var = np.zeros((n, m)), np.zeros((n, m)), np.zeros((n, m)), np.ones((n, m))
    u[k_of, slot] = (obs.time[rows] - t_c[k_of]) / tau[k_of]
    y[k_of, slot] = obs.value[rows]
    kernel[k_of, slot] = (1.0 - np.minimum(np.abs(u[k_of, slot]), 1.0) ** 3) ** 3
    if known:
        var[k_of, slot] = obs.sd[rows] ** 2
    powers = u[:, :, None] ** np.arange(n_coef)  # (n, m, n_coef)
    gram = np.einsum("kmi,km,kmj->kij", powers, kernel / var, powers)
    usable = np.sum(kernel > 0, axis=1) >= n_coef + 1  # a residual degree of freedom
    if np.any(usable):
        eig = np.linalg.eigvalsh(gram[usable])
        usable[usable] = eig[:, 0] > 1e-10 * eig[:, -1]  # samples that determine the polynomial
    est = np.full((n, 3), np.nan)
    cov = np.full((n, 2, 2), np.nan)
    if not np.any(usable):
        return est, cov, math.nan
    p, kw, v = powers[usable], kernel[usable], var[usable]
    g_inv = np.linalg.inv(gram[usable])
    coef = np.einsum("kij,kmj,km->ki", g_inv, p, kw / v * y[usable])
    # Sandwich: Cov(coef) = G^-1 (P^T diag(K^2 / var) P) G^-1 for samples of variance var.
    c = g_inv @ np.einsum("kmi,km,kmj->kij", p, kw**2 / v, p) @ g_inv
    resid = y[usable] - np.einsum("kmi,ki->km", p, coef)
    t_u = tau[usable]
    est[usable, 0] = coef[:, 0]
    est[usable, 1] = coef[:, 1] / t_u
    est[usable, 2] = 2.0 * coef[:, 2] / t_u**2 if degree >= 2 else 0.0
    to_rate = np.stack([np.ones_like(t_u), 1.0 / t_u], axis=1)
    cov[usable] = c[:, :2, :2] * to_rate[:, :, None] * to_rate[:, None, :]
    return est, cov, float(np.sqrt(np.sum(kw * resid**2) / np.sum(kw)))


def _difference_sd(obs, rows) -> float:
    """Noise SD of one signal from the fourth differences of runs of five consecutive, evenly
    spaced samples within one step; NaN where there are none.

    For white noise of SD sigma, ``y[i] - 4 y[i+1] + 6 y[i+2] - 4 y[i+3] + y[i+4]`` has variance
    70 sigma^2, while a smooth motion contributes ``dt^4`` times its fourth derivative, far below
    the noise at the tens of samples per step of a video (difference-based variance estimation:
    Gasser, Sroka & Jennen-Steinmetz, Biometrika 73:625, 1986; Hall, Kay & Titterington,
    Biometrika 77:521, 1990). Noise correlated between samples (a smoothing tracker) makes it an
    underestimate.
    """
    if len(rows) < 5:
        return math.nan
    t, y, k = obs.time[rows], obs.value[rows], obs.step[rows]
    dt = np.diff(t)
    typical = np.median(dt)
    idx = np.arange(len(rows) - 4)
    keep = k[idx] == k[idx + 4]
    for j in range(4):
        keep &= np.abs(dt[idx + j] - typical) <= _EVEN_SPACING * typical
    idx = idx[keep]
    if len(idx) == 0:
        return math.nan
    d4 = y[idx] - 4 * y[idx + 1] + 6 * y[idx + 2] - 4 * y[idx + 3] + y[idx + 4]
    return float(np.sqrt(np.mean(d4**2) / 70.0))

# --------------------------------------------------------------------------------- the map
@dataclasses.dataclass
class MapEstimate:
    """One estimate of the return map's Jacobian J.

    Shapes use ``d`` for the number of section coordinates.

    Attributes
    ----------
    method : str
        ``"naive"``, ``"corrected"`` or ``"instrumental"`` (:data:`ESTIMATORS`).
    jacobian : ndarray, shape (d, d)
        J in the section coordinates (units: those of the row over those of the column); NaN when
        the estimate failed.
    eigenvalues : ndarray, shape (d,), complex
        Eigenvalues of J sorted by decreasing modulus (dimensionless).
    max_abs_eigenvalue : float
    max_abs_sd : float
        Bootstrap standard deviation of ``max_abs_eigenvalue``: half its central 68.3 % interval
        (NaN without a bootstrap).
    max_abs_interval : tuple of float
        Central 95 % bootstrap interval of ``max_abs_eigenvalue``.
    n_used : int
        Stride pairs (naive, corrected) or triplets (instrumental) the estimate used.
    status : str
        ``"ok"``, ``"unreliable"`` (an instrumental estimate with a weak instrument) or
        ``"failed"`` (no estimate: NaN); ``message`` says why.
    message : str
    """

    method: str
    jacobian: np.ndarray
    eigenvalues: np.ndarray
    max_abs_eigenvalue: float
    max_abs_sd: float
    max_abs_interval: tuple
    n_used: int
    status: str = "ok"
    message: str = ""

    def to_json(self) -> dict:
        """JSON-ready dictionary (NaN written as null)."""
        return {
            "method": self.method, "status": self.status, "message": self.message,
            "n_used": self.n_used,
            "jacobian": [[_num(v) for v in row] for row in self.jacobian],
            "eigenvalues": [{"re": _num(e.real), "im": _num(e.imag), "abs": _num(abs(e))}
                            for e in self.eigenvalues],
            "max_abs_eigenvalue": _num(self.max_abs_eigenvalue), "max_abs_sd": _num(self.max_abs_sd),
            "max_abs_interval": [_num(v) for v in self.max_abs_interval],
        }


@dataclasses.dataclass
class ReturnMap:
    """The return map estimated from measured strides, at one section phase.

    Shapes use ``d`` for the number of section coordinates.

    Attributes
    ----------
    kind : str
        ``"stride"`` or ``"step"``.
    phase : float
        Section phase within the step.
    stance : str or None
        The stance leg of the stride map's sections ('L' or 'R'); None for the step map.
    coordinates : tuple of str
        Section coordinates (names of docs/model.md's public state).
    n_sections : int
        Section states (strides for the stride map, steps for the step map) in the pairs.
    n_pairs, n_triplets : int
        Consecutive pairs (naive, corrected) and triplets (instrumental) of valid sections.
    mean : ndarray, shape (d,)
        Mean section state over the pairs' first members (rad, rad/s). The step map centres the
        left- and right-stance sections each on their own mean (a stance-specific intercept).
    spread : ndarray, shape (d, d)
        ``S_00``: sample covariance of the pairs' first members.
    noise_covariance : ndarray, shape (d, d)
        ``Sigma_noise``: mean measurement-error covariance of the pairs' first members.
    snr : ndarray, shape (d,)
        Signal-to-noise variance ratios ``mu - 1`` of the generalized eigenproblem ``S_00 v = mu
        Sigma_noise v``, decreasing.
    rank : int
        Directions kept: those with ``snr >= min_snr``, at most ``n_pairs // 5 - 1`` of them, and
        at most 7 of the full state's 8 (the state after a heel strike lies on the guard surface).
    directions : ndarray, shape (d, rank)
        The kept directions as weights: column j gives the combination ``z_j = directions[:, j] @
        (x - mean)`` of the section coordinates, scaled to unit noise variance.
    min_snr : float
    naive, corrected, instrumental : MapEstimate
    warnings : list of str
        What the data cannot determine, with numbers.
    sections : Sections
    """

    kind: str
    phase: float
    stance: str | None
    coordinates: tuple
    n_sections: int
    n_pairs: int
    n_triplets: int
    mean: np.ndarray
    spread: np.ndarray
    noise_covariance: np.ndarray
    snr: np.ndarray
    rank: int
    directions: np.ndarray
    min_snr: float
    naive: MapEstimate
    corrected: MapEstimate
    instrumental: MapEstimate
    warnings: list
    sections: Sections = dataclasses.field(repr=False)

    @property
    def estimates(self) -> dict:
        """The three estimates by name (:data:`ESTIMATORS`)."""
        return {"naive": self.naive, "corrected": self.corrected, "instrumental": self.instrumental}

    def to_json(self) -> dict:
        """JSON-ready dictionary (NaN written as null)."""
        sec = self.sections
        return {
            "kind": self.kind, "phase": self.phase, "stance": self.stance,
            "coordinates": list(self.coordinates), "n_sections": self.n_sections,
            "n_pairs": self.n_pairs, "n_triplets": self.n_triplets,
            "mean": {c: _num(v) for c, v in zip(self.coordinates, self.mean, strict=True)},
            "spread": [[_num(v) for v in row] for row in self.spread],
            "noise_covariance": [[_num(v) for v in row] for row in self.noise_covariance],
            "snr": [_num(v) for v in self.snr], "rank": self.rank, "min_snr": self.min_snr,
            "directions": [[_num(v) for v in row] for row in self.directions],
            "estimates": {name: e.to_json() for name, e in self.estimates.items()},
            "warnings": list(self.warnings),
            "sections": {
                "width": sec.width, "degree": sec.degree, "timing": sec.timing,
                "noise_sd": dict(sec.noise_sd), "noise_source": dict(sec.noise_source),
                "difference_sd": {k: _num(v) for k, v in sec.difference_sd.items()},
                "residual_rms": {k: _num(v) for k, v in sec.residual_rms.items()},
            },
            "units": {"angles": "rad", "rates": "rad/s", "time": "s", "eigenvalues": "dimensionless"},
        }


def _num(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _check_coordinates(coordinates) -> tuple[str, ...]:
    if isinstance(coordinates, str):
        raise ReturnMapError(f"coordinates must be a sequence of state names, got the string {coordinates!r}")
    coords = tuple(coordinates)
    bad = [c for c in coords if c not in STATE_NAMES]
    if bad or not coords:
        raise ReturnMapError(f"coordinates must be names of {', '.join(STATE_NAMES)}; got {list(coords)}")
    if len(set(coords)) != len(coords):
        raise ReturnMapError(f"a coordinate is named twice in {list(coords)}")
    return coords


def _signals_for(coords) -> tuple[str, ...]:
    need = set()
    for c in coords:
        source = _SIGNAL_OF[c.removesuffix("_dot")]
        need |= {"pitch_left", "pitch_right"} if source == "pitch" else {source}
    return tuple(s for s in SIGNALS if s in need)


def _sorted_eigenvalues(jac: np.ndarray) -> np.ndarray:
    ev = np.linalg.eigvals(jac)
    return ev[np.lexsort((-ev.imag, -np.abs(ev)))]


def _fit(x0, x1, basis, method, xm=None):
    """J (d, d) from pairs ``x0 -> x1`` (n, d) in the retained directions ``basis`` (d, r), whose
    noise covariance is the identity; ``xm`` (n, d) the instruments. Raises LinAlgError."""
    n = len(x0)
    z = (x0 - x0.mean(axis=0)) @ basis
    y = x1 - x1.mean(axis=0)
    if method == "instrumental":
        w = (xm - xm.mean(axis=0)) @ basis
        a = np.linalg.solve((z.T @ w).T, (y.T @ w).T).T
    else:
        s_zz = z.T @ z / (n - 1)
        if method == "corrected":
            s_zz = s_zz - np.eye(basis.shape[1])
        a = np.linalg.solve(s_zz, (y.T @ z / (n - 1)).T).T
    return a @ basis.T


def _estimate(method, x0, x1, xm, basis, scale, n_boot, rng) -> MapEstimate:
    d = x0.shape[1]
    n = len(x0)
    nan_map = MapEstimate(method, np.full((d, d), np.nan), np.full(d, np.nan + 0j), math.nan, math.nan,
                          (math.nan, math.nan), n, status="failed")
    if basis.shape[1] == 0:
        nan_map.message = "no direction of the section state varies between strides beyond its noise"
        return nan_map
    if n < basis.shape[1] + 2:
        nan_map.message = (f"{n} {'triplets' if method == 'instrumental' else 'pairs'} for "
                           f"{basis.shape[1]} directions: at least {basis.shape[1] + 2} needed")
        return nan_map
    try:
        jac = _fit(x0, x1, basis, method, xm)
    except np.linalg.LinAlgError as err:
        nan_map.message = f"singular moment matrix: {err}"
        return nan_map
    if not np.all(np.isfinite(jac)):
        nan_map.message = "the moment matrices gave a non-finite J"
        return nan_map
    ev = _sorted_eigenvalues(jac)
    boot = []
    for _ in range(n_boot):
        idx = rng.integers(0, n, n)
        try:
            jb = _fit(x0[idx], x1[idx], basis, method, None if xm is None else xm[idx])
        except np.linalg.LinAlgError:
            continue
        if np.all(np.isfinite(jb)):
            boot.append(float(np.max(np.abs(np.linalg.eigvals(jb)))))
    if len(boot) > 1:
        low, high, sd_low, sd_high = np.percentile(boot, _INTERVAL + _ONE_SIGMA)
        sd, interval = float(sd_high - sd_low) / 2.0, (float(low), float(high))
    else:
        sd, interval = math.nan, (math.nan, math.nan)
    # Back to physical units: the fit ran in standardized coordinates x / scale.
    jac = jac * scale[:, None] / scale[None, :]
    return MapEstimate(method, jac, ev, float(np.abs(ev[0])), sd, interval, n)


def return_map(table: TrajectoryTable, phase: float = 0.5, *, kind: str = "stride", stance: str = "L",
               coordinates=ALL_COORDINATES, width: float = 0.5, degree: int = 4,
               min_snr: float = 1.0, bootstrap: int = 200, rng=None) -> ReturnMap:
    """Estimate the return map and its eigenvalues (Floquet multipliers) from a measured walk.

    Parameters
    ----------
    table : TrajectoryTable
        A measured walk with its heel strikes (the trajectory format of docs/formats.md).
    phase : float
        Section phase within the step, in [0, 1] (default mid-step).
    kind : {'stride', 'step'}
        The stride map (sections a stride apart, one stance leg) or the step map (every step,
        right-stance steps mirrored; for walkers whose gait repeats every step).
    stance : {'L', 'R'}
        The stride map's stance leg at the section (ignored for the step map).
    coordinates : sequence of str
        Section coordinates, names of docs/model.md's public state (default :data:`ALL_COORDINATES`,
        the full state; :data:`LATERAL_COORDINATES` for lean and steer with their rates).
    width, degree : float, int
        The local fits' window (fraction of the step) and degree (:func:`section_states`).
    min_snr : float
        Directions whose signal-to-noise variance ratio is below this are left out of the fit
        (default 1: a spread between strides no larger than the noise). Of the others, at most
        ``n_pairs // 5 - 1`` are fitted, those of largest ratio.
    bootstrap : int
        Bootstrap replicates for the uncertainty of the largest eigenvalue modulus (0: none).
    rng : int, numpy.random.Generator or None
        Seed or generator of the bootstrap (``np.random.default_rng(rng)``).

    Returns
    -------
    ReturnMap

    Raises
    ------
    ReturnMapError
        Missing signals, fewer section pairs than the coordinates need (``d + 2``), or bad options.
    """
    if kind not in ("stride", "step"):
        raise ReturnMapError(f"kind must be 'stride' or 'step', got {kind!r}")
    if kind == "stride" and stance not in ("L", "R"):
        raise ReturnMapError(f"stance must be 'L' or 'R', got {stance!r}")
    coords = _check_coordinates(coordinates)
    try:
        min_snr = float(min_snr)
    except (TypeError, ValueError) as err:
        raise ReturnMapError(f"min_snr must be a positive number, got {min_snr!r}") from err
    if not (math.isfinite(min_snr) and min_snr > 0):
        raise ReturnMapError(f"min_snr must be a positive number, got {min_snr!r}")
    if isinstance(bootstrap, bool) or not isinstance(bootstrap, int | np.integer) or bootstrap < 0:
        raise ReturnMapError(f"bootstrap must be a non-negative integer, got {bootstrap!r}")
    rng = np.random.default_rng(rng)
    sections = section_states(table, phase, width, degree, signals=_signals_for(coords))
    cols = [STATE_NAMES.index(c) for c in coords]
    d = len(cols)
    if kind == "stride":
        states, covariance, lag = sections.states, sections.covariance, 2
        first = sections.stance == stance
        unit = "stride"
    else:
        (states, covariance), lag = sections.mirrored(), 1
        first = np.ones(len(sections.step), dtype=bool)
        unit = "step"
    x = states[:, cols]
    cov = covariance[np.ix_(np.arange(len(x)), cols, cols)]
    ok = sections.valid
    n = len(x)
    pair = np.array([i for i in range(n - lag) if first[i] and ok[i] and ok[i + lag]], dtype=int)
    triple = np.array([i for i in pair if i - lag >= 0 and ok[i - lag]], dtype=int)
    if len(pair) < d + 2:
        raise ReturnMapError(
            f"the walk gives {len(pair)} usable {unit} pair(s): a {d}-coordinate map needs at least "
            f"{d + 2}; record more {unit}s or choose fewer coordinates")
    mean = x[pair].mean(axis=0)
    if kind == "step":
        # Each stance leg's sections about their own mean: a constant offset of the measured lean
        # or steer (a tilted camera) changes sign with the mirror, and would otherwise enter J as
        # a perfectly predictable alternation, an eigenvalue -1.
        x = x.copy()
        for leg in ("L", "R"):
            rows = (sections.stance == leg) & ok
            x[rows] += mean - x[rows].mean(axis=0)
    x0 = x[pair]
    spread = np.atleast_2d(np.cov(x0, rowvar=False))
    noise = cov[pair].mean(axis=0)
    # Standardize (unit spread per coordinate) for conditioning; the eigenvalues do not change.
    scale = np.sqrt(np.diag(spread))
    if not np.all(scale > 0):
        flat = [c for c, s in zip(coords, scale, strict=True) if not s > 0]
        raise ReturnMapError(f"{', '.join(flat)} take(s) the same value at every section: no information")
    s00 = spread / np.outer(scale, scale)
    sig = noise / np.outer(scale, scale) + _NOISE_FLOOR * np.eye(d)
    mu, vec = scipy.linalg.eigh(s00, sig)  # vec.T @ sig @ vec = I
    order = np.argsort(mu)[::-1]
    mu, vec = mu[order], vec[:, order]
    snr = mu - 1.0
    informative = snr >= min_snr
    if d == len(STATE_NAMES):
        # The full state after a heel strike lies on the guard surface, so at any later phase on
        # a 7-dimensional surface: its eighth direction holds only noise and curvature.
        informative[7:] = False
    cap = max(1, len(pair) // _PAIRS_PER_UNKNOWN - 1)  # rank + intercept unknowns per row of J
    keep = informative & (np.arange(d) < cap)
    basis = vec[:, keep]
    warnings: list[str] = []
    rank = int(keep.sum())
    if rank == 0:
        warnings.append(
            f"the walk stays on its cycle within the measurement noise: the largest signal-to-noise "
            f"variance ratio of the section states is {snr[0]:.3g} (< {min_snr:g}), so the {unit}s "
            "hold no information about J")
    elif np.count_nonzero(snr < min_snr):
        warnings.append(
            f"{np.count_nonzero(snr < min_snr)} of {d} directions of the section state vary between "
            f"{unit}s by less than {min_snr:g} times their noise variance (signal-to-noise ratios "
            f"{', '.join(f'{v:.2g}' for v in snr[snr < min_snr])}): S_00 - Sigma_noise is near "
            f"singular there; J is estimated in the other {informative.sum()} and maps those to zero")
    if informative.sum() > rank:
        warnings.append(
            f"{len(pair)} {unit} pairs for a {d}-coordinate map: to keep {_PAIRS_PER_UNKNOWN} pairs "
            f"per unknown of each row of J, only the {rank} directions of largest signal-to-noise "
            f"ratio are fitted (of {informative.sum()} above the noise); record more {unit}s or "
            "choose fewer coordinates")
    xs = x / scale
    t0, t1, tm = xs[triple], xs[triple + lag], xs[triple - lag]
    weak = ""
    if rank and len(triple) > rank + 1:
        canon = _canonical_correlations((t0 - t0.mean(axis=0)) @ basis, (tm - tm.mean(axis=0)) @ basis)
        concentration = len(triple) * canon[-1] ** 2 / (1.0 - min(canon[-1], 1 - 1e-12) ** 2)
        if concentration < _WEAK_INSTRUMENT:
            weak = (f"weak instrument: the smallest canonical correlation between x_k and x_k-1 in "
                    f"the kept directions is {canon[-1]:.2g} (first-stage F = n rho^2 / (1 - rho^2) "
                    f"= {concentration:.3g} < {_WEAK_INSTRUMENT:g} for n = {len(triple)}), so the "
                    "instrumental estimate is unreliable: a direction that forgets within a "
                    f"{unit} (a fast mode, or the guard surface's)")
            warnings.append(weak)
    for name, source in sections.noise_source.items():
        ratio = (sections.difference_sd[name] / sections.noise_sd[name]) ** 2
        if source == "*_sd columns" and math.isfinite(ratio) and not (
                _VARIANCE_RATIO[0] <= ratio <= _VARIANCE_RATIO[1]):
            warnings.append(
                f"the {name}_sd column (RMS {sections.noise_sd[name]:.3g} rad) disagrees with the "
                f"samples' scatter (fourth differences: {sections.difference_sd[name]:.3g} rad): the "
                f"noise correction is {'too small' if ratio > 1 else 'too large'}")
    estimates = {}
    for method in ESTIMATORS:
        if method == "instrumental":
            estimates[method] = _estimate(method, t0, t1, tm, basis, scale, bootstrap, rng)
            if weak and estimates[method].status == "ok":
                estimates[method].status, estimates[method].message = "unreliable", weak
        else:
            estimates[method] = _estimate(method, xs[pair], xs[pair + lag], None, basis, scale,
                                          bootstrap, rng)
    corrected, iv = estimates["corrected"], estimates["instrumental"]
    gap = abs(corrected.max_abs_eigenvalue - iv.max_abs_eigenvalue)
    if corrected.status == iv.status == "ok" and gap > 3.0 * math.hypot(corrected.max_abs_sd,
                                                                         iv.max_abs_sd):
        warnings.append(
            f"the corrected and instrumental estimates of max |eigenvalue| disagree "
            f"({corrected.max_abs_eigenvalue:.3g} +/- {corrected.max_abs_sd:.2g} against "
            f"{iv.max_abs_eigenvalue:.3g} +/- {iv.max_abs_sd:.2g}): the kept coordinates do not "
            "carry the whole state (partial observation), the map is not linear over the spread, or "
            "the noise model is wrong")
    used = np.union1d(pair, pair + lag)
    return ReturnMap(kind=kind, phase=sections.phase, stance=stance if kind == "stride" else None,
                     coordinates=coords, n_sections=len(used), n_pairs=len(pair),
                     n_triplets=len(triple), mean=mean, spread=spread, noise_covariance=noise,
                     snr=snr, rank=rank, directions=basis / scale[:, None], min_snr=min_snr,
                     warnings=warnings, sections=sections,
                     **estimates)


def _canonical_correlations(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Canonical correlations between the columns of ``a`` and ``b`` (n, r), decreasing."""
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return np.linalg.svd(qa.T @ qb, compute_uv=False)


def return_maps(table: TrajectoryTable, phases=(0.25, 0.5, 0.75), **options) -> list[ReturnMap]:
    """:func:`return_map` at several section phases (the eigenvalues should not depend on it:
    a consistency check); ``options`` are :func:`return_map`'s keyword arguments."""
    phases = np.atleast_1d(np.asarray(phases, dtype=float))
    if phases.ndim != 1 or len(phases) == 0:
        raise ReturnMapError(f"phases must be a non-empty sequence of numbers, got {phases!r}")
    return [return_map(table, float(p), **options) for p in phases]
