"""What the model gets wrong: residual diagnostics a person can read.

Three questions are asked of a fit's residuals (model minus measurement, per observation of
:class:`toywalk.sysid.measurement.Observations`), component by component in the model's own
description (:data:`COMPONENTS`: lean and steer mirrored for a step with the right leg in stance,
and the pitches as the stance and the swing leg's, whichever leg that is), because a model that
lacks some physics misses the same way in every step *of that description*:

- **Is there a pattern that repeats every step?** Each step's residuals are averaged in ``bins``
  bins of the step phase (a steps-by-bins table); a repeated-measures analysis of variance tests
  the bins' effect against the steps-by-bins interaction, with the Greenhouse-Geisser correction
  of its degrees of freedom for bins that are correlated or unequally noisy (Greenhouse & Geisser
  1959, Psychometrika 24:95). The steps are the units, so the test needs no noise SD, and a step's
  own offset (noise correlated within a step) is not a pattern; it is the verdict's test of
  "systematic". (A constant offset over the whole walk is the fit's nuisance offset, not
  tested.)
- **Are the residuals white?** Ljung-Box on the first ``lags`` autocorrelations of the residual
  series in time (Ljung & Box 1978, Biometrika 65:297) and the Wald-Wolfowitz runs test of their
  signs (too few runs: residuals that stay on one side). Both assume independent measurement
  errors: a tracker's errors correlated over a few frames fail them without any model error, so
  they are reported, with their figure, but do not decide.
- **Which gait features does the model miss?** Features of each measured step (its duration,
  lean and steer ranges, mean steer, pitch ranges), computed alike from the measurement and the
  model at the same samples, then their mean difference over the steps in units of its standard
  error from the step-to-step scatter; plus left-right differences (the same features, right
  steps against left ones), which only a symmetry-breaking cause can produce.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import scipy.sparse as sp
from scipy import special
from toywalk.model.trajectory import SIGNALS

from .measurement import Observations

__all__ = ["COMPONENTS", "FEATURES", "NOISE_INFLATION", "SCATTER_ORDER", "ResidualReport", "feature_misfit",
           "finite_mean", "missed_features", "phase_bins", "residual_report", "scatter_noise",
           "shared_errors", "step_dependence", "step_features"]

#: Per-step gait features (:func:`step_features`), with their unit.
FEATURES = {"duration": "s", "lean_range": "rad", "steer_range": "rad", "steer_mean": "rad",
            "stance_pitch_range": "rad", "swing_pitch_range": "rad"}
#: The residual components tested: lean and steer mirrored back to the model's description
#: (left leg in stance), the stance leg's pitch and the swing leg's.
COMPONENTS = ("lean", "steer", "stance_pitch", "swing_pitch")
#: Ljung-Box lags, in samples.
_LAGS = 10
#: Phase bins of the repeated-pattern test, at most (:func:`phase_bins`).
_BINS = 10
#: :func:`phase_bins` gives up at most this share of the steps that are complete in two bins, for
#: finer bins.
_STEPS_GIVEN_UP = 0.25
#: Degree of the smooth curve whose range is a step's feature (:func:`step_features`).
_SMOOTH_DEGREE = 6
#: The lowest degree that still has a range to measure (a parabola's extreme within the step).
_MIN_DEGREE = 2
#: Order of the differences that measure the noise without a model (:func:`scatter_noise`). A
#: smooth angle f adds ``h**4 d4f / sqrt(70)`` to a 4th difference of samples ``h`` apart: for the
#: stable toy's swing pitch (0.3 rad at 2.5 Hz) filmed at 60 frames/s, 1.7e-4 rad, 0.4 % of a
#: 2 mrad noise in quadrature; a 3rd difference would add 17 %.
SCATTER_ORDER = 4
#: A residual RMS more than this many times a signal's noise SD (its samples' own scatter,
#: :func:`scatter_noise`, or an SD stated) is mostly the model's misfit. The scatter of a 12-step
#: walk at 140 samples/s is the true SD within 0.099 (1 SD; tests/sysid/test_residuals.py), so a
#: model that fits reaches 2 only where the scatter is 5 SDs low; the point-foot base of a
#: round-footed walker gives 11 to 64 (docs/diagnosis.md, "The seed's story").
NOISE_INFLATION = 2.0


@dataclasses.dataclass
class ResidualReport:
    """Residual tests per signal (:func:`residual_report`).

    Attributes
    ----------
    tests : dict of str to dict
        Per component (:data:`COMPONENTS`): ``pattern_f``, ``pattern_p`` (the test of a pattern
        repeated every step), ``epsilon`` (its Greenhouse-Geisser factor), ``ljung_box_q``,
        ``ljung_box_p``, ``runs_z``, ``runs_p`` (too few runs), ``rms``
        (rad), ``n`` (observations).
    phase_mean, phase_se : dict of str to ndarray, shape (bins,)
        Per component: the mean residual in each phase bin over the steps and its standard error
        from the step-to-step scatter (rad).
    bins : int
    systematic : list of str
        Components whose repeated pattern is significant at ``alpha`` over all of them
        (Bonferroni).
    alpha : float
    """

    tests: dict
    phase_mean: dict
    phase_se: dict
    bins: int
    systematic: list
    alpha: float

    def to_json(self) -> dict:
        return {"tests": self.tests, "bins": self.bins, "systematic": self.systematic,
                "alpha": self.alpha,
                "phase_mean": {k: v.tolist() for k, v in self.phase_mean.items()},
                "phase_se": {k: v.tolist() for k, v in self.phase_se.items()}}


def _components(obs: Observations, residuals: np.ndarray) -> dict:
    """Each component's selection of observations and its residuals in the model's description."""
    index = {name: i for i, name in enumerate(SIGNALS)}
    side = np.where(obs.stance[obs.step] == "L", 1.0, -1.0)
    left_stance = obs.stance[obs.step] == "L"
    out = {}
    for name in ("lean", "steer"):
        out[name] = (obs.signal == index[name], residuals * side)
    own_left = obs.signal == index["pitch_left"]
    own_right = obs.signal == index["pitch_right"]
    out["stance_pitch"] = ((own_left & left_stance) | (own_right & ~left_stance), residuals)
    out["swing_pitch"] = ((own_left & ~left_stance) | (own_right & left_stance), residuals)
    return out


def _phase_bin(phase: np.ndarray, bins: int) -> np.ndarray:
    """Each sample's bin of ``bins`` equal bins of the step phase (a phase of 1 in the last)."""
    return np.minimum((phase * bins).astype(int), bins - 1)


def _step_bin_means(obs: Observations, residuals: np.ndarray, sel: np.ndarray, bins: int) -> np.ndarray:
    """Mean residual of each (step, phase bin), shape (n_steps, bins), NaN where empty."""
    b = _phase_bin(obs.phase[sel], bins)
    k = obs.step[sel]
    total = np.zeros((obs.n_steps, bins))
    count = np.zeros((obs.n_steps, bins))
    np.add.at(total, (k, b), residuals[sel])
    np.add.at(count, (k, b), 1.0)
    with np.errstate(invalid="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def phase_bins(obs: Observations) -> int:
    """The phase bins of the repeated-pattern test for these observations: the most, up to
    :data:`_BINS`, that leave every component at least three steps with a sample in every bin,
    and at least three quarters (1 - :data:`_STEPS_GIVEN_UP`) of the steps complete in two bins.

    A step with fewer samples than bins has an empty bin and drops out of the test (a
    repeated-measures analysis needs every bin of a step): the stable toy filmed at 60 frames/s
    has 6-7 samples a step, and with 10 bins none of its steps was complete, so the test was
    never made (NaN). A short gap costs its step at fine bins too; so that a few gaps do not
    coarsen the test, up to a quarter of the steps may be given up.
    """
    zero = np.zeros(obs.value.shape)
    components = [sel for sel, _ in _components(obs, zero).values() if np.any(sel)]

    def complete(bins: int) -> int:
        return min((int(np.all(np.isfinite(_step_bin_means(obs, zero, sel, bins)), axis=1).sum())
                    for sel in components), default=0)

    floor = max(3, math.ceil((1.0 - _STEPS_GIVEN_UP) * complete(2)))
    return next((b for b in range(_BINS, 1, -1) if complete(b) >= floor), _BINS)


def shared_errors(obs: Observations, bins: int | None = None) -> sp.csr_matrix:
    """Loadings of the errors each sample shares with the same phase of every step of its foot,
    shape (n_obs, cells): row ``i`` holds ``obs.phase_sd[i]`` (rad) in the column of its cell
    (signal, stance foot, phase bin of :func:`phase_bins`), so that these errors' covariance is
    ``L @ L.T`` with one standard normal per cell. A tracker's bias by phase (what its
    calibration leaves uncertain, tracking/accuracy_phase.py) repeats in every step of a foot,
    so averaging more steps does not shrink it; an estimate that leans on that phase carries it
    whole (:meth:`toywalk.sysid.fitresult.FitResult` standard errors). Empty columns where the file
    gives no ``*_phase_sd``."""
    bins = phase_bins(obs) if bins is None else int(bins)
    b = _phase_bin(obs.phase, bins)
    foot = (obs.stance[obs.step] == "R").astype(int)
    cell = (obs.signal * 2 + foot) * bins + b
    loads = sp.csr_matrix((obs.phase_sd, (np.arange(len(cell)), cell)),
                          shape=(len(cell), len(SIGNALS) * 2 * bins))
    loads.eliminate_zeros()
    return loads


def _pattern(x: np.ndarray, shared: np.ndarray | None = None, feet=None) -> tuple[float, float, float]:
    """Repeated-measures ANOVA of a steps-by-bins table ``x`` (n, p): the bins' F against the
    interaction, its Greenhouse-Geisser epsilon, and the corrected p-value; NaNs with fewer than
    three complete steps.

    ``shared`` (n, p), with the steps' stance ``feet``, is the variance of an error each sample
    shares with the same phase of every step of its foot (a tracker's calibrated bias, its
    uncertainty: ``Observations.phase_sd`` squared). It adds to a bin's mean over the steps
    ``v = sum over feet of (n_f / n)^2 mean(shared)`` whatever the number of steps, and, differing
    between the feet, it is no part of the noise: the interaction and the bins' covariance (for
    epsilon) are then taken within each foot's steps, and the bins' mean square is compared with
    the interaction's plus ``n v`` (its expectation with no pattern). Without it (zero), the test
    above. Measured on 200 draws of a shared error of 1 mrad under 2 mrad noise (16 steps, 800
    components): false-alarm rate 0.064 at 0.05 and 0.015 at 0.01; the plain test's 0.90 at 0.05
    (tests/sysid/test_residuals.py)."""
    complete = np.all(np.isfinite(x), axis=1)
    extra, groups = 0.0, [x[complete]]
    if shared is not None and np.any(shared[complete] > 0):
        c, f = shared[complete], np.asarray(feet)[complete]
        extra = sum((np.sum(f == foot) / len(f)) ** 2 * np.mean(c[f == foot], axis=0)
                    for foot in np.unique(f)).mean()
        groups = [x[complete][f == foot] for foot in np.unique(f)]
    x = x[complete]
    n, p = x.shape
    if n < 3 or p < 2 or min(len(g) for g in groups) < 2:
        return math.nan, math.nan, math.nan
    bin_mean, grand = x.mean(axis=0), x.mean()
    ss_bins = n * float(np.sum((bin_mean - grand) ** 2))
    within = [g - g.mean(axis=1)[:, None] - g.mean(axis=0)[None, :] + g.mean() for g in groups]
    ss_err = float(sum(np.sum(w**2) for w in within))
    df_bins, df_err = p - 1, sum(len(g) - 1 for g in groups) * (p - 1)
    if ss_err <= 0 and extra <= 0:
        return math.inf, 1.0, 0.0
    noise, known = ss_err / df_err, n * extra
    f = (ss_bins / df_bins) / (noise + known)
    centre = np.eye(p) - 1.0 / p
    spread = [g - g.mean(axis=0) for g in groups]
    pooled = sum(d.T @ d for d in spread) / sum(len(g) - 1 for g in groups)
    cov = centre @ pooled @ centre
    eps = float(np.trace(cov) ** 2 / (df_bins * np.trace(cov @ cov)))
    eps = min(max(eps, 1.0 / df_bins), 1.0)
    # Satterthwaite's degrees of freedom: the noise's corrected by epsilon, the shared error's
    # spherical (independent bins of equal variance) and, in the denominator, known
    total = noise + known
    df_num = total**2 / (noise**2 / (eps * df_bins) + known**2 / df_bins) if total > 0 else eps * df_bins
    df_den = total**2 / (noise**2 / (eps * df_err)) if noise > 0 else math.inf
    return float(f), eps, float(special.fdtrc(df_num, min(df_den, 1e12), f))


def _ljung_box(series: np.ndarray, lags: int) -> tuple[float, float]:
    """Ljung-Box Q of the first ``lags`` autocorrelations and its chi-square p-value."""
    x = series - series.mean()
    n = len(x)
    lags = min(lags, n - 2)
    if lags < 1:
        return math.nan, math.nan
    denom = float(x @ x)
    if denom <= 0.0:  # a constant series: no correlation to measure
        return math.nan, math.nan
    acf = np.array([float(x[k:] @ x[:-k]) / denom for k in range(1, lags + 1)])
    q = float(n * (n + 2) * np.sum(acf**2 / (n - np.arange(1, lags + 1))))
    return q, float(special.chdtrc(lags, q))


def _runs(series: np.ndarray) -> tuple[float, float]:
    """Wald-Wolfowitz runs test of the signs: z and the one-sided p-value of too few runs."""
    signs = series[series != 0] > 0
    n1, n2 = int(signs.sum()), int((~signs).sum())
    n = n1 + n2
    if n1 == 0 or n2 == 0:
        return -math.inf, 0.0
    runs = 1 + int(np.count_nonzero(signs[1:] != signs[:-1]))
    mean = 2.0 * n1 * n2 / n + 1.0
    var = 2.0 * n1 * n2 * (2.0 * n1 * n2 - n) / (n**2 * (n - 1.0))
    z = (runs - mean) / math.sqrt(max(var, 1e-300))
    return float(z), float(special.ndtr(z))


def residual_report(obs: Observations, residuals: np.ndarray, bins: int | None = None,
                    alpha: float = 0.01) -> ResidualReport:
    """Test each signal's residuals (module docstring).

    Parameters
    ----------
    obs : Observations
    residuals : ndarray, shape (n_obs,)
        Model minus measurement (rad).
    bins : int, optional
        Phase bins (default :func:`phase_bins`: as many as the samples a step allow, at most
        :data:`_BINS`).
    alpha : float
        Level of the "systematic" verdict over all signals together.
    """
    residuals = np.asarray(residuals, float)
    if residuals.shape != obs.value.shape:
        raise ValueError(f"residuals must have shape {obs.value.shape}, got {residuals.shape}")
    bins = phase_bins(obs) if bins is None else int(bins)
    tests, means, ses, pattern_p = {}, {}, {}, {}
    for name, (sel, values) in _components(obs, residuals).items():
        if not np.any(sel):
            continue
        per_step = _step_bin_means(obs, values, sel, bins)
        shared = _step_bin_means(obs, obs.phase_sd**2, sel, bins)
        f, eps, p_pattern = _pattern(per_step, shared, obs.stance)
        with warnings.catch_warnings():  # a phase bin no step reached is NaN, on purpose
            warnings.simplefilter("ignore", RuntimeWarning)
            count = np.sum(np.isfinite(per_step), axis=0)
            means[name] = np.nanmean(per_step, axis=0)
            ses[name] = np.nanstd(per_step, axis=0, ddof=1) / np.sqrt(np.maximum(count, 1))
        order = np.argsort(obs.time[sel], kind="stable")
        series = values[sel][order]
        q, p_lb = _ljung_box(series, _LAGS)
        z, p_runs = _runs(series)
        tests[name] = {"pattern_f": f, "epsilon": eps, "pattern_p": p_pattern, "ljung_box_q": q,
                       "ljung_box_p": p_lb, "runs_z": z, "runs_p": p_runs,
                       "rms": float(np.sqrt(np.mean(series**2))), "n": int(sel.sum())}
        pattern_p[name] = p_pattern
    level = alpha / max(len(pattern_p), 1)
    systematic = [n for n, p in pattern_p.items() if math.isfinite(p) and p < level]
    return ResidualReport(tests=tests, phase_mean=means, phase_se=ses, bins=bins,
                          systematic=systematic, alpha=alpha)


def _differences(times: np.ndarray, values: np.ndarray, order: int) -> np.ndarray:
    """Divided differences of ``order`` over every run of ``order + 1`` consecutive samples, each
    scaled to the noise's SD: ``sum(c_i v_i) / sqrt(sum(c_i**2))`` with ``c_i = 1 / prod_j (t_i -
    t_j)``, zero for a polynomial of degree below ``order`` and of variance ``sigma**2`` for white
    noise of SD ``sigma``, whatever the spacing."""
    if len(times) <= order:
        return np.empty(0)
    t = np.lib.stride_tricks.sliding_window_view(times, order + 1)
    v = np.lib.stride_tricks.sliding_window_view(values, order + 1)
    gaps = t[:, :, None] - t[:, None, :]
    gaps[:, np.arange(order + 1), np.arange(order + 1)] = 1.0
    c = 1.0 / np.prod(gaps, axis=2)
    return np.sum(c * v, axis=1) / np.sqrt(np.sum(c * c, axis=1))


def scatter_noise(obs: Observations, order: int = SCATTER_ORDER) -> dict:
    """Each signal's noise SD from its samples' own scatter, without a model: the RMS of its
    ``order``-th differences within each step (a heel strike's jump in the rates is left out),
    scaled to the noise (:func:`_differences`). A fit's residual RMS measures the noise plus the
    model's misfit; this measures the noise alone, if it is independent from sample to sample.
    Whether it is: the same taken over every other sample (``sd_alternate``) is as large for
    white noise and larger for noise correlated over a few samples (a tracker's smoothing).

    Returns
    -------
    dict
        Per signal of :data:`toywalk.model.trajectory.SIGNALS` measured: ``sd``, ``sd_alternate``
        (rad; NaN with too few samples), ``windows``, the differences behind ``sd``, and
        ``rel_se``, the relative standard error of ``sd`` from the step-to-step spread of the
        steps' mean squares (the windows within a step overlap and are not independent).
    """
    out = {}
    for s_i, name in enumerate(SIGNALS):
        here = obs.signal == s_i
        if not np.any(here):
            continue
        every, alternate = [], []
        for k in np.unique(obs.step[here]):
            sel = here & (obs.step == k)
            order_t = np.argsort(obs.time[sel], kind="stable")
            t, v = obs.time[sel][order_t], obs.value[sel][order_t]
            every.append(_differences(t, v, order))
            alternate += [_differences(t[first::2], v[first::2], order) for first in (0, 1)]
        # the overlapping windows of a step are correlated, the steps are not: the mean square's
        # standard error from the steps' own mean squares (a ratio estimator over the steps)
        counts = np.array([len(e) for e in every], float)
        squares = np.array([float(np.sum(e**2)) for e in every])
        every, alternate = np.concatenate(every), np.concatenate(alternate)
        rel_se = math.nan
        if len(every) and np.count_nonzero(counts) > 1 and squares.sum() > 0:
            ms = squares.sum() / counts.sum()
            se_ms = math.sqrt(float(np.sum((squares - ms * counts) ** 2))
                              * len(counts) / (len(counts) - 1)) / counts.sum()
            rel_se = 0.5 * se_ms / ms  # of the SD, the square root of the mean square
        out[name] = {"sd": float(np.sqrt(np.mean(every**2))) if len(every) else math.nan,
                     "sd_alternate": float(np.sqrt(np.mean(alternate**2))) if len(alternate) else math.nan,
                     "windows": len(every), "rel_se": rel_se}
    return out


def step_features(obs: Observations, values: np.ndarray) -> dict:
    """Per-step gait features of angle ``values`` at the observations (measured, or a model's at
    the same samples), each shape (n_steps,), NaN where a step lacks the signal: the step's
    duration (measured strikes), the range and mean of the lean and steer, the stance and swing
    pitch ranges. Lean and steer are in the physical description (not mirrored).

    Ranges are those of a smooth curve through each step's samples (Legendre polynomial of degree
    :data:`_SMOOTH_DEGREE` in the phase, by least squares): the raw samples' range grows with the
    noise (by about 4 SDs for 100 samples), so a noisy measurement would always seem to swing
    more than a noiseless model. A step with few samples of a signal (fewer than 13: a walker
    taking 0.18 s a step filmed at 60 frames/s gives 11) gets the highest degree with at least
    twice as many samples as coefficients, down to :data:`_MIN_DEGREE`; below that the feature
    is NaN. The degree depends only on the samples, so a model's features at the same samples
    are smoothed alike."""
    values = np.asarray(values, float)
    out = {k: np.full(obs.n_steps, np.nan) for k in FEATURES}
    out["duration"] = obs.durations.copy()
    index = {name: i for i, name in enumerate(SIGNALS)}
    grid = np.linspace(-1.0, 1.0, 101)
    for k in range(obs.n_steps):
        in_step = obs.step == k
        stance = "pitch_left" if obs.stance[k] == "L" else "pitch_right"
        swing = "pitch_right" if stance == "pitch_left" else "pitch_left"
        for name, key in (("lean", "lean_range"), ("steer", "steer_range"),
                          (stance, "stance_pitch_range"), (swing, "swing_pitch_range")):
            sel = in_step & (obs.signal == index[name])
            degree = min(_SMOOTH_DEGREE, (np.count_nonzero(sel) - 1) // 2)
            if degree < _MIN_DEGREE:
                continue
            x = 2.0 * obs.phase[sel] - 1.0
            coef = np.polynomial.legendre.legfit(x, values[sel], degree)
            curve = np.polynomial.legendre.legval(grid[(grid >= x.min()) & (grid <= x.max())], coef)
            out[key][k] = np.ptp(curve)
            if name == "steer":
                out["steer_mean"][k] = values[sel].mean()
    return out


def feature_misfit(obs: Observations, measured: np.ndarray, model: np.ndarray,
                   model_durations: np.ndarray | None = None, sigma: np.ndarray | None = None,
                   replicates: int = 20, rng=None) -> dict:
    """Each feature's misfit: measured minus model, mean over the steps, its standard error from
    the step-to-step scatter of the differences, and ``z`` their ratio; then the left-right
    difference of the same (right steps minus left steps) as ``<feature>_right_minus_left``.

    ``model_durations`` (n_steps,), the model's step durations, replaces the measured ones for
    the model's ``duration`` feature (otherwise the two are the same measured strikes). With
    ``sigma`` (n_obs,), the noise SD of each observation, the model's features are those of the
    model plus simulated noise (the mean over ``replicates`` draws): a range measured through
    noise is larger than the noiseless curve's, and the model is compared as it would be measured.
    """
    want = step_features(obs, model)
    if sigma is not None:
        rng = np.random.default_rng(rng)
        draws = [step_features(obs, model + rng.normal(0.0, 1.0, len(model)) * sigma)
                 for _ in range(replicates)]
        with warnings.catch_warnings():  # a step without a signal stays NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            want = {k: np.nanmean([d[k] for d in draws], axis=0) for k in want}
    got = step_features(obs, measured)
    if model_durations is not None:
        want["duration"] = np.asarray(model_durations, float)
    right = obs.stance == "R"
    shared = _shared_feature_sd(obs, measured, got, right, replicates, rng)
    out = {}
    for key, unit in FEATURES.items():
        diff = got[key] - want[key]
        out[key] = _summary(diff, unit, got[key], want[key])
        if key in shared:
            se = math.hypot(out[key]["se"], shared[key])
            out[key].update(se=se, z=out[key]["difference"] / se if se > 0 else math.nan)
        if key == "duration":
            # The strikes' own error bounds the standard error from below: a model with one step
            # time against exact strikes would otherwise have a zero scatter.
            floor = math.sqrt(float(np.mean(obs.duration_sd**2)) / obs.n_steps)
            se = math.hypot(out[key]["se"], floor)
            out[key].update(se=se, z=out[key]["difference"] / se)
        if np.any(right) and np.any(~right):
            lr_meas = _lr(got[key], right)
            lr_model = _lr(want[key], right)
            d = _lr(diff, right)
            se = math.hypot(_se(diff[right]), _se(diff[~right]))
            if key == "duration":  # the strikes' error bounds it from below, as above
                floor = math.sqrt(float(np.mean(obs.duration_sd**2))
                                  * (1.0 / np.sum(right) + 1.0 / np.sum(~right)))
                se = math.hypot(se, floor)
            if f"{key}_right_minus_left" in shared:
                se = math.hypot(se, shared[f"{key}_right_minus_left"])
            # the fewer steps of a foot less one: a conservative count for two means' difference
            dof = min(int(np.count_nonzero(np.isfinite(diff[side]))) for side in (right, ~right)) - 1
            out[f"{key}_right_minus_left"] = {
                "measured": lr_meas, "model": lr_model, "difference": float(d), "se": se,
                "z": float(d / se) if se > 0 else math.nan, "unit": unit, "dof": dof}
    return out


#: Phase bins of the shared error's draws (:func:`_shared_feature_sd`), as a tracker's
#: calibration has them (tracking/accuracy_phase.py, MAX_BINS).
_SHARED_BINS = 20


def _shared_feature_sd(obs: Observations, measured: np.ndarray, got: dict, right: np.ndarray,
                       replicates: int, rng) -> dict:
    """Each feature's SD (and its left-right difference's) from the error the samples share with
    the same phase of every step of their foot (``Observations.phase_sd``: a tracker's bias by
    phase). Unlike the noise it does not average out over the steps, so the steps' scatter does
    not hold it: it is drawn, one value per signal, foot and phase bin scaled by each sample's
    ``phase_sd``, ``replicates`` times, and the features' mean over the steps measured through
    each draw. Empty where no sample has one. Measured: a walk of the toy-sized walker tracked with
    its errors carried left its left-right steer-mean difference 6.3 SE from the model with the
    hidden hip damping, 0.09 degrees, within the tracker's own steer bias by foot."""
    if not np.any(obs.phase_sd > 0):
        return {}
    rng = np.random.default_rng(rng)
    cell = np.minimum((obs.phase * _SHARED_BINS).astype(int), _SHARED_BINS - 1)
    foot = (obs.stance[obs.step] == "R").astype(int)
    draws = {k: [] for k in FEATURES}
    draws.update({f"{k}_right_minus_left": [] for k in FEATURES})
    for _ in range(replicates):
        pattern = rng.normal(0.0, 1.0, (len(SIGNALS), 2, _SHARED_BINS))
        f = step_features(obs, measured + obs.phase_sd * pattern[obs.signal, foot, cell])
        for key in FEATURES:
            draws[key].append(finite_mean(f[key] - got[key]))
            if np.any(right) and np.any(~right):
                draws[f"{key}_right_minus_left"].append(_lr(f[key], right) - _lr(got[key], right))
    return {k: float(np.std(v, ddof=1)) for k, v in draws.items() if len(v) > 1 and np.all(np.isfinite(v))}


def missed_features(features: dict, limit: float = 3.0) -> list[str]:
    """The features of :func:`feature_misfit` missed by more than ``limit`` standard errors,
    largest misfit first."""
    strong = sorted(((abs(v["z"]), k) for k, v in features.items()
                     if math.isfinite(v.get("z", math.nan)) and abs(v["z"]) > limit), reverse=True)
    return [k for _, k in strong]


#: Degrees of :func:`step_dependence`'s curves in the phase of the step: the pattern common to
#: every step of a foot (a misfit's, however shaped), and each step's own departure from it (a
#: walk converging to its cycle changes slowly from step to step, smoothly within a step).
STEP_PATTERN_DEGREE, STEP_OWN_DEGREE = 8, 2


def step_dependence(obs: Observations, residuals: np.ndarray, degree: int = STEP_PATTERN_DEGREE,
                    own: int = STEP_OWN_DEGREE) -> dict:
    """Do the residuals of a periodic fit change from step to step beyond the noise?

    A walk on a limit cycle repeats itself: the residuals of a periodic model, read at each
    measured step's phase, are one pattern (the model's misfit, zero if it is right) plus noise,
    the same every step of a foot. A walk off its cycle differs from step to step. For each
    signal, model A fits each stance foot's residuals by one Legendre curve of the phase of
    ``degree``; model B adds each step's own curve of degree ``own``. F test of B against A
    (each signal's reduction in the sum of squares over its own residual variance under B,
    pooled over the signals; white noise assumed): the misfit's pattern, however large, is in
    both models and does not count.

    Parameters
    ----------
    obs : Observations
    residuals : ndarray, shape (n_obs,)
        Measured minus model, read at each measured step's phase (a fit aligned on the measured
        strikes).

    Returns
    -------
    dict
        ``F``, ``dfn``, ``dfd``, ``p`` (NaN when no signal has samples enough), and
        ``by_signal`` (each signal's F).
    """
    stat, dfn, dfd, by_signal = 0.0, 0, 0, {}
    ok = np.isfinite(residuals)
    for s_i, name in enumerate(SIGNALS):
        rss_a = rss_b = 0.0
        k_a = k_b = n = 0
        for foot in ("L", "R"):
            sel = ok & (obs.signal == s_i) & (obs.stance[obs.step] == foot)
            u = 2.0 * obs.phase[sel] - 1.0
            a = np.polynomial.legendre.legvander(u, degree)
            steps = obs.step[sel]
            b = np.hstack([a] + [np.polynomial.legendre.legvander(u, own) * (steps == k)[:, None]
                                 for k in np.unique(steps)])
            if len(u) <= b.shape[1]:
                continue
            (rss, rank), (rss_own, rank_own) = (_least_squares(d, residuals[sel]) for d in (a, b))
            rss_a, k_a, rss_b, k_b = rss_a + rss, k_a + rank, rss_b + rss_own, k_b + rank_own
            n += len(u)
        if n - k_b <= 0 or k_b <= k_a or rss_b <= 0:
            continue
        variance = rss_b / (n - k_b)
        by_signal[name] = float((rss_a - rss_b) / (k_b - k_a) / variance)
        stat += (rss_a - rss_b) / variance
        dfn, dfd = dfn + int(k_b - k_a), dfd + int(n - k_b)
    if not dfn:
        return {"F": math.nan, "dfn": 0, "dfd": 0, "p": math.nan, "by_signal": {}}
    f_value = float(stat / dfn)
    return {"F": f_value, "dfn": dfn, "dfd": dfd, "p": float(special.fdtrc(dfn, dfd, f_value)),
            "by_signal": by_signal}


def _least_squares(design: np.ndarray, y: np.ndarray) -> tuple[float, int]:
    """The residual sum of squares of ``y`` (n,) on the columns of ``design`` (n, k), and the
    design's rank."""
    coef, _, rank, _ = np.linalg.lstsq(design, y, rcond=None)
    return float(np.sum((design @ coef - y) ** 2)), int(rank)


def _se(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.std(x, ddof=1) / math.sqrt(len(x))) if len(x) > 1 else math.nan


def _lr(x: np.ndarray, right: np.ndarray) -> float:
    return finite_mean(x[right]) - finite_mean(x[~right])


def finite_mean(x: np.ndarray) -> float:
    """The mean of the finite values of ``x``; NaN, quietly, when there are none."""
    x = x[np.isfinite(x)]
    return float(np.mean(x)) if len(x) else math.nan


def _summary(diff: np.ndarray, unit: str, got: np.ndarray, want: np.ndarray) -> dict:
    finite = np.isfinite(diff)
    if not np.any(finite):
        return {"measured": math.nan, "model": math.nan, "difference": math.nan, "se": math.nan,
                "z": math.nan, "unit": unit}
    d, se = float(np.mean(diff[finite])), _se(diff)
    return {"measured": float(np.nanmean(got)), "model": float(np.nanmean(want)), "difference": d,
            "se": se, "z": float(d / se) if se > 0 else math.nan, "unit": unit,
            "dof": int(np.count_nonzero(finite)) - 1}
