"""Heel strikes from measured leg pitches, to sub-frame precision, and the stance foot per sample.

A heel strike is a collision: the angles are continuous through it but their rates jump (docs/model.md
section 4). It is found where the leg pitches have a kink, without the walker's geometry (which
``track`` does not know):

1. candidates: for each frame interval, quadratic fits to the ``half_window`` samples before and
   after it give the pitch rates on either side; a rate jump far beyond what the pitch noise
   explains (a z-score over both legs) and a local maximum of it marks a candidate;
2. refinement: a continuous, piecewise quadratic with one breakpoint ``tau`` is fitted to both
   pitches around the candidate (least squares for each ``tau`` on a fine grid, then a parabola
   through the best three): ``tau`` is the heel-strike time, between frames;
3. the striking foot is the leading one, the leg with the smaller pitch at ``tau``
   (``theta > 0``: hip ahead of the foot); it becomes the stance foot;
4. consistency: a kink whose shape (the two legs' rate jumps) points away from the typical
   strike's is dropped; of two strikes that cannot both be real (closer than half the median
   step, or the same foot twice in a row within 1.5 steps with no long gap between, where the
   other foot's strike may be hidden), the weaker kink is dropped.

Before all this, isolated wrong samples (a pose that neither the samples before nor those after
explain, :func:`isolated_outliers`) are treated as gaps, and kinks are also sought across short
gaps (``max_gap`` frames), timed from the samples either side.

Scuffing while the legs pass each other has no collision and so no kink. This is change-point
estimation by segmented regression (Muggeo 2003, Stat. Med. 22:3055, doi:10.1002/sim.1545).
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["HeelStrike", "fit_samples_per_side", "heel_strikes", "isolated_outliers", "legs_passing",
           "noise_sd", "stance_from_events", "step_samples"]

#: Half-width of the band (rad) the legs' relative pitch must cross to count as the legs passing
#: (:func:`legs_passing`): about five times a tracked pitch's noise (0.1 degree RMS), a few percent
#: of a toy's swing (its legs 15-40 degrees apart at a heel strike).
PASSING_BAND = np.radians(0.5)


def legs_passing(pitch_left, pitch_right, band: float = PASSING_BAND) -> int:
    """How many times the legs pass each other: the swing leg overtakes the stance leg once a
    step, so a walk's heel strikes number about as many (one fewer or more at its ends). A count
    independent of the kinks the strikes are found from: far more passings than strikes found
    means strikes were missed (a swing too fast for the frame rate).

    Parameters
    ----------
    pitch_left, pitch_right : array_like, shape (n,)
        The legs' pitches (rad); NaN where not tracked (those samples are skipped).
    band : float
        The relative pitch ``left - right`` must go from below ``-band`` to above ``band``, or
        back, to count (rad): noise about zero is not a passing.
    """
    rel = np.asarray(pitch_left, float) - np.asarray(pitch_right, float)
    side = np.sign(rel[np.isfinite(rel) & (np.abs(rel) > band)])
    return int(np.count_nonzero(side[1:] != side[:-1]))


@dataclasses.dataclass(frozen=True)
class HeelStrike:
    """One heel strike.

    Attributes
    ----------
    time : float
        Sub-frame time (s).
    foot : str
        'L' or 'R', the foot that strikes (the new stance foot).
    index : int
        The last sample before ``time``.
    rate_jump : float
        Jump of the striking leg's pitch rate (rad/s).
    z : float
        Kink strength in standard errors of the rate difference.
    time_sd : float
        Standard deviation of ``time`` (s) for white pitch noise of the measured level, from the
        curvature of the fit's residual sum of squares in the strike time (a profile
        likelihood); larger across a gap. NaN if unknown.
    """

    time: float
    foot: str
    index: int
    rate_jump: float
    z: float
    time_sd: float = float("nan")


def _side_rate(t, y, t0, min_quadratic=4):
    """Slope at t0 and its variance factor of a quadratic (or, with fewer than ``min_quadratic``
    samples, a line) fitted to (t, y)."""
    x = t - t0
    deg = 2 if len(x) >= min_quadratic else 1
    a = np.vander(x, deg + 1, increasing=True)
    try:
        inv = np.linalg.inv(a.T @ a)
    except np.linalg.LinAlgError:
        return np.nan, np.inf
    coef = inv @ (a.T @ y)
    return coef[1], inv[1, 1]


def noise_sd(y) -> float:
    """Robust SD of a signal's white noise from its fourth differences (MAD), NaN-aware.

    Fourth differences of a smooth signal sampled densely are small; of white noise of SD sigma
    they have SD sigma * sqrt(70). Near-uniform sampling is assumed (video frames).
    """
    d4 = np.convolve(y, [1.0, -4.0, 6.0, -4.0, 1.0], mode="valid")
    d4 = d4[np.isfinite(d4)]
    if len(d4) < 5:
        return np.nan
    return float(1.4826 * np.median(np.abs(d4 - np.median(d4))) / np.sqrt(70.0))


def step_samples(pitch_left, pitch_right) -> float:
    """Step period in samples (frames), from the oscillation of the pitch difference; NaN if unknown.

    The legs pass each other once per step, so ``pitch_left - pitch_right`` changes sign once per
    step. Sign changes are counted with hysteresis (the difference must go beyond a quarter of its
    typical amplitude, the 90th percentile of its magnitude) so that noise near a crossing is not
    a step; the period is the median spacing of successive changes. NaN if fewer than three are
    seen (too short a series, or legs that do not swap).
    """
    d = np.asarray(pitch_left, float) - np.asarray(pitch_right, float)
    idx = np.flatnonzero(np.isfinite(d))
    if len(idx) < 5:
        return np.nan
    level = 0.25 * float(np.percentile(np.abs(d[idx]), 90))
    if not level > 0:
        return np.nan
    crossings, state = [], 0
    for i in idx:
        side = 1 if d[i] > level else -1 if d[i] < -level else 0
        if side and side != state:
            if state:
                crossings.append(i)
            state = side
    if len(crossings) < 3:
        return np.nan
    return float(np.median(np.diff(crossings)))


def fit_samples_per_side(step: float, longest: int) -> int:
    """Samples a one-sided fit may use so that it rarely spans a heel strike: under half a step
    (``step`` samples, NaN = unknown), at least 3 (a quadratic) and at most ``longest``."""
    if not np.isfinite(step):
        return longest
    return int(min(longest, max(3, np.floor(step / 2))))


def _extrapolation_factor(count: int) -> float:
    """SD of a quadratic fitted to ``count`` unit-spaced, unit-noise samples, extrapolated one step."""
    x = np.arange(-count, 0, dtype=float)
    a = np.vander(x, 3, increasing=True)
    inv = np.linalg.inv(a.T @ a)
    return float(np.sqrt(inv[0, 0]))


def isolated_outliers(y, sd: float, *, count: int = 5, threshold: float = 6.0,
                      floor: float = np.radians(1.0)) -> np.ndarray:
    """Samples (bool mask, shape (n,)) that neither side's neighbours explain.

    Each sample is compared with quadratics fitted to the ``count`` valid samples before it and to
    the ``count`` after it, each extrapolated to it. A kink (heel strike) bends the signal, but it
    stays continuous, so at least one side predicts every sample near it; a wrong pose (a mirrored
    single-marker fit, a blurred marker) is an isolated jump that both sides miss. Flagged if both
    misses exceed ``threshold`` times the extrapolation's SD for white noise ``sd`` (and
    ``floor``, rad: the curvature of the signal over a frame or two); at the ends of the series
    or of a gap, one side's miss decides. A sample so flagged, with no gap within 3 samples, is
    kept when a cubic through the 3 nearest samples on each side not found wrong (interpolation,
    which follows a smooth turn that no extrapolation does) passes within ``threshold`` times its
    own SD (and ``floor``): a fast leg reversing within a few frames (a walker filmed at 60
    frames/s, 10 frames a step) is not a jump. Uniform sampling assumed.
    """
    y = np.asarray(y, float)
    ok = np.isfinite(y)
    n = len(y)
    limit = max(threshold * sd * _extrapolation_factor(count), floor)
    out = np.zeros(n, dtype=bool)
    if n < 2 * count + 1:
        return out
    # where the count samples on a side are all valid, the extrapolation is a fixed linear filter
    x = np.arange(-count, 0, dtype=float)
    a = np.vander(x, 3, increasing=True)
    weights = (np.linalg.inv(a.T @ a) @ a.T)[0]  # value at 0 from samples at -count..-1
    filled = np.where(ok, y, 0.0)
    valid = np.concatenate([[0], np.cumsum(ok)])
    from_left = np.full(n, np.inf)
    from_right = np.full(n, np.inf)
    idx = np.arange(count, n)
    full = valid[idx] - valid[idx - count] == count
    pred = np.lib.stride_tricks.sliding_window_view(filled, count)[: n - count] @ weights
    from_left[idx[full]] = np.abs(pred[full] - y[idx[full]])
    idx = np.arange(0, n - count)
    full = valid[idx + count + 1] - valid[idx + 1] == count
    pred = np.lib.stride_tricks.sliding_window_view(filled, count)[1:] @ weights[::-1]
    from_right[idx[full]] = np.abs(pred[full] - y[idx[full]])
    # near a gap: fit the nearest valid samples on that side (up to 2 count away)
    for i in np.flatnonzero(ok & ~(np.isfinite(from_left) & np.isfinite(from_right))):
        for step, miss in ((-1, from_left), (1, from_right)):
            if np.isfinite(miss[i]):
                continue
            sel = _window(ok, i + step, -1 if step < 0 else n, step, count)
            if len(sel) < count:
                continue  # an end or a long gap: no evidence from this side
            coef = np.polyfit(np.array(sel, float) - i, y[sel], 2)
            miss[i] = abs(coef[-1] - y[i])
    nearest = np.minimum(from_left, from_right)  # inf: no side had enough samples
    out = ok & np.isfinite(nearest) & (nearest > limit)
    # the largest misses first, each interpolated without the samples already found wrong (a
    # jump also spoils its neighbours' interpolations)
    trusted = ok.copy()
    for i in sorted(np.flatnonzero(out), key=lambda i: -nearest[i]):
        if not ok[max(i - 3, 0):i + 4].all():
            continue  # a gap within 3 samples (where blur hides a leg, the samples at a gap's
            # edge are the least sure): the one-sided verdict stands
        before = _window(trusted, i - 1, -1, -1, 3)
        after = _window(trusted, i + 1, n, 1, 3)
        if not before or not after or len(before) + len(after) < 4:
            continue  # not enclosed (an end, neighbours found wrong): the one-sided verdict stands
        x = np.array(before + after, float) - i
        a = np.vander(x, 4 if len(x) >= 5 else 3, increasing=True)
        coef = np.linalg.lstsq(a, y[before + after], rcond=None)[0]
        spread = float(np.sqrt(np.linalg.inv(a.T @ a)[0, 0]))  # its value at 0, for unit noise
        if abs(coef[0] - y[i]) <= max(threshold * sd * spread, floor):
            out[i] = False
        else:
            trusted[i] = False
    return out


def _window(ok, start, stop, step, count):
    idx = []
    i = start
    while 0 <= i < len(ok) and len(idx) < count and abs(i - start) < 2 * count:
        if ok[i]:
            idx.append(i)
        i += step
    return idx if step > 0 else idx[::-1]


def _parabola_min(grid, vals, sigma: float) -> tuple[float, float]:
    """Minimum of a residual sum of squares sampled on a uniform ``grid``: the parabola through the
    lowest sample and its neighbours gives the place and, for white noise of SD ``sigma`` in the
    residuals, its SD ``sqrt(2 sigma^2 / curvature)`` (the chi-square rising by one). At an end
    of the grid or without curvature: the lowest sample and the grid's span over sqrt(12)."""
    k = int(np.argmin(vals))
    h = grid[1] - grid[0]
    if 0 < k < len(grid) - 1:
        denom = vals[k - 1] - 2 * vals[k] + vals[k + 1]
        if denom > 0:
            return (float(grid[k] + 0.5 * (vals[k - 1] - vals[k + 1]) / denom * h),
                    float(np.sqrt(2 * sigma**2 / (denom / h**2))))
    return float(grid[k]), float((grid[-1] - grid[0]) / np.sqrt(12.0))


def _breakpoint(t, ys, idx, lo, hi, sigma, n_grid=41):
    """Best breakpoint tau in [lo, hi] of continuous piecewise quadratics through all ys[idx]:
    (tau, the rate jumps of each y, tau's SD for noise of SD ``sigma`` or the fit's residuals',
    correlated between the ys as the residuals are, :func:`_kink_noise`)."""
    tt = t[idx]
    y = np.column_stack([v[idx] for v in ys])  # (samples, signals)

    def design(tau):
        """The piecewise quadratics' columns for breakpoints ``tau`` (any shape): shape
        tau.shape + (samples, 5)."""
        x = tt - np.asarray(tau, float)[..., None]
        left = x < 0
        return np.stack([np.ones_like(x), np.where(left, x, 0), np.where(left, x * x, 0),
                         np.where(left, 0, x), np.where(left, 0, x * x)], axis=-1)

    def sse(tau):
        a = design(tau)
        coef = np.linalg.lstsq(a, y, rcond=None)[0]
        return float(np.sum((a @ coef - y) ** 2)), list(coef[3] - coef[1])

    grid = np.linspace(lo, hi, n_grid)
    # every breakpoint of the grid at once: least squares through the pseudo-inverse (an SVD per
    # breakpoint, as lstsq's)
    a = design(grid)
    resid = a @ (np.linalg.pinv(a) @ y) - y  # (grid, samples, signals)
    vals = np.sum(resid**2, axis=(1, 2))
    best = int(np.argmin(vals))
    # the noise: the measured level, or the fit's own residuals where they say it is worse, and
    # the signals' correlation theirs (a pitch's freedom: its samples less five coefficients and
    # half the breakpoint)
    cov = _noise_covariance(resid[best], len(idx) - 5.5, sigma)
    noise = _kink_noise(cov, np.asarray(sse(grid[best])[1], float))
    tau, tau_sd = _parabola_min(grid, vals, noise)
    return tau, sse(tau)[1], tau_sd


def _noise_covariance(resid: np.ndarray, dof: float, sigma: float) -> np.ndarray:
    """Covariance (m, m) of m signals' noise from a fit's residuals (samples, m) with ``dof``
    residual degrees of freedom a signal: each signal's variance the measured ``sigma``^2 or the
    residuals', whichever is larger; the correlations the residuals'."""
    if dof <= 0:
        return np.eye(resid.shape[1]) * sigma**2
    cov = resid.T @ resid / dof
    sd = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = np.nan_to_num(cov / np.outer(sd, sd))
    np.fill_diagonal(corr, 1.0)
    sd = np.maximum(sd, sigma)
    return corr * np.outer(sd, sd)


def _kink_noise(cov: np.ndarray, jumps: np.ndarray) -> float:
    """The noise SD that scales a breakpoint's SD for unit white noise, for noise of covariance
    ``cov`` between the signals whose rates jump by ``jumps``.

    To first order the breakpoint moves by the sum over the signals of each one's rate jump
    times the projection of its noise on one shape (the step the kink's slope makes, less its
    part the design fits): its variance is that of unit noise times ``J^T C J / J^T J``, with C
    the noise covariance between the signals. Independent signals of SD sigma give sigma;
    without rate jumps, the largest SD.

    The two legs' pitch errors are correlated within a frame (the hip axis and point are
    fitted to both legs' markers), differently at either foot's strikes: on the toy-sized
    walker's renders (120 fps, noise 1), within 8 frames of a strike, by +0.64 to +0.77 at the
    left foot's and -0.06 to -0.36 at the right's. Taken as independent, the left strikes' SDs
    were too small and the right's too large there (errors over SD, RMS over 15 strikes on six
    clips of two walks: left 1.01-2.26, right 0.68-1.65; with the correlation 0.82-1.75 and
    0.84-1.69, what is left being alike on all noise seeds of a walk, not noise). The
    correlation of one strike's residuals (about nine degrees of freedom a pitch) enters
    linearly: it scatters the SD but does not bias its square, unlike whitening the fit with it,
    which was tried and made the SDs too small on independent noise (test_events.py's gait: RMS
    1.25 -> 1.44).
    """
    norm = float(jumps @ jumps)
    if not norm > 0:
        return float(np.sqrt(np.max(np.diag(cov))))
    return float(np.sqrt(max(float(jumps @ cov @ jumps), 0.0) / norm))


def _refine(t, pl, pr, ok, k, half_window, span, sigma):
    """Breakpoint near the interval (t[k], t[k+1]), searched over ``span`` valid samples either
    side (so across a gap the bracket reaches the samples beyond it)."""
    n = len(t)
    idx = _window(ok, k, -1, -1, half_window)[::-1] + _window(ok, k + 1, n, 1, half_window)
    if len(idx) < 2 * half_window:  # too near a gap or an end for a reliable fit
        return None
    valid = np.flatnonzero(ok)
    pos = int(np.searchsorted(valid, k, side="right")) - 1  # the last valid sample <= k
    lo = int(valid[max(0, pos - span + 1)]) if pos >= 0 else max(0, k - span + 1)
    hi = int(valid[min(len(valid) - 1, pos + span)]) if pos >= 0 else min(n - 1, k + span)
    return _breakpoint(t, (pl, pr), np.array(sorted(idx)), t[lo], t[hi], sigma)


def heel_strikes(time, pitch_left, pitch_right, *, half_window: int = 5, min_z: float = 5.0,
                 min_jump_fraction: float = 0.3,
                 min_spread: float = np.radians(3.0),
                 reject_outliers: bool = True, max_gap: int = 3) -> list[HeelStrike]:
    """Heel strikes in pitch series (rad) sampled at ``time`` (s), shape (n,) each; NaN = gap.

    Parameters
    ----------
    half_window : int
        Samples on each side used for the rate estimates and the breakpoint fit, at most: fewer
        when the steps are short (:func:`step_samples`, :func:`fit_samples_per_side`: under half
        a step, at least 3), as is the outlier filter's ``count``.
    min_z : float
        Minimum kink strength (rate jump over its standard error from the measured noise).
    min_jump_fraction : float
        Minimum size of a kink's rate jump (both legs) relative to the typical size of the
        largest half of the kinks found: a collision changes the rates by about as much at every
        step, noise much less.
    min_spread : float
        Minimum |pitch_left - pitch_right| (rad) at a heel strike: the legs are apart (rules out
        the legs passing each other).
    reject_outliers : bool
        Treat isolated wrong samples (:func:`isolated_outliers`) as gaps first.
    max_gap : int
        Longest run of missing samples (frames) across which a strike is still looked for and timed
        from the samples either side.
    """
    t = np.asarray(time, float)
    pl, pr = np.asarray(pitch_left, float), np.asarray(pitch_right, float)
    if not (t.shape == pl.shape == pr.shape) or t.ndim != 1:
        raise ValueError(f"time and pitches must share shape (n,), got {t.shape}, {pl.shape}, {pr.shape}")
    ok = np.isfinite(pl) & np.isfinite(pr) & np.isfinite(t)
    sds = [v for v in (noise_sd(pl), noise_sd(pr)) if np.isfinite(v)] if ok.sum() > 10 else []
    if not sds:  # too few (runs of) samples to measure the noise: no kink can be judged
        return []
    sd = max(max(sds), 1e-5)  # rad: a floor for noise-free (synthetic) signals
    # Fast steps (a few frames each): every fit window must fit inside a step, or it straddles a
    # strike and neither side's rate is a rate.
    longest = half_window
    step = step_samples(pl, pr)
    half_window = fit_samples_per_side(step, half_window)
    min_quadratic = 3 if half_window <= 3 else 4  # a line over a fast step is biased by curvature
    if reject_outliers:
        count = fit_samples_per_side(step, 5)
        bad = isolated_outliers(pl, sd, count=count) | isolated_outliers(pr, sd, count=count)
        if bad.any():
            pl, pr = pl.copy(), pr.copy()
            pl[bad] = np.nan
            pr[bad] = np.nan
            ok &= ~bad
    n = len(t)
    z = np.zeros(n)
    leg_z = np.zeros((n, 2))  # each leg's rate jump in standard errors, signed
    valid = np.flatnonzero(ok)
    for k, k_next in zip(valid[:-1], valid[1:], strict=True):
        if k_next - k > max_gap + 1:  # a strike inside a longer gap is not timed
            continue
        before = _window(ok, k, -1, -1, half_window)
        after = _window(ok, k_next, n, 1, half_window)
        if len(before) < 3 or len(after) < 3:
            continue
        t0 = 0.5 * (t[k] + t[k_next])
        zz = 0.0
        for j, y in enumerate((pl, pr)):
            rb, vb = _side_rate(t[before], y[before], t0, min_quadratic)
            ra, va = _side_rate(t[after], y[after], t0, min_quadratic)
            leg_z[k, j] = (ra - rb) / (sd * np.sqrt(vb + va))
            zz += (ra - rb) ** 2 / (sd**2 * (vb + va))
        z[k] = np.sqrt(zz)
    candidates = []
    k = 0
    while k < n - 1:
        lo, hi = max(0, k - half_window), min(n - 1, k + half_window + 1)
        if z[k] < min_z or z[k] < z[lo:hi].max():
            k += 1
            continue
        # The rate-jump score is smeared over the fit windows: search a wide bracket first, then
        # refit with the window centred on the breakpoint found.
        found = _refine(t, pl, pr, ok, k, half_window, min(3, half_window), sd)
        if found is None:
            k += 1
            continue
        i0 = int(np.clip(np.searchsorted(t, found[0]) - 1, 0, n - 2))
        found = _refine(t, pl, pr, ok, i0, half_window, 1, sd) or found
        tau, rate_jumps, tau_sd = found
        # the kink's strength and shape where it was placed: the strongest score within a frame
        # or two of tau (the peak that led here may lie on the far side of a gap)
        i0 = int(np.clip(np.searchsorted(t, tau) - 1, 0, n - 2))
        near = np.arange(max(0, i0 - 2), min(n - 1, i0 + 3))
        at = int(near[np.argmax(z[near])]) if z[near].max() > 0 else k
        if candidates and abs(candidates[-1][1] - tau) < 0.5 * (t[1] - t[0]):
            # two score peaks refined to one kink: keep the stronger
            if z[at] > z[candidates[-1][0]]:
                candidates[-1] = (at, tau, rate_jumps, tau_sd)
        else:
            candidates.append((at, tau, rate_jumps, tau_sd))
        k = hi
    if not candidates:
        return []
    # A collision changes the rates by about as much at every step; noise kinks are far smaller.
    size = np.array([np.hypot(*c[2]) for c in candidates])
    reference = np.median(np.sort(size)[len(size) // 2:])
    # gaps a strike inside is not timed: (start, end) times of the samples either side
    long_gaps = [(t[a], t[b]) for a, b in zip(valid[:-1], valid[1:], strict=True) if b - a > max_gap + 1]
    near = 1.5 * float(np.median(np.diff(t)))  # s: a kink this near a long gap may be its edge
    events: list[HeelStrike] = []
    kinks = []  # per event: (striking leg, other leg) rate jumps in standard errors
    for (k, tau, rate_jumps, tau_sd), jump_size in zip(candidates, size, strict=True):
        if jump_size < min_jump_fraction * reference:
            continue
        i0 = int(np.clip(np.searchsorted(t, tau) - 1, 0, n - 2))
        spread = float(np.interp(tau, t[ok], (pl - pr)[ok]))  # across a short gap too
        # inside a gap the kink itself is unseen, its time extrapolated from either side: add
        # the uncertainty of a time anywhere in the gap
        j = int(np.searchsorted(valid, np.searchsorted(t, tau)))
        if 0 < j < len(valid) and valid[j] - valid[j - 1] > 1:
            tau_sd = float(np.hypot(tau_sd, (t[valid[j]] - t[valid[j - 1]]) / np.sqrt(12.0)))
        else:
            tau_sd = float(np.hypot(tau_sd, _beside_a_long_gap(tau, long_gaps, near)))
        if not abs(spread) >= min_spread:
            continue
        foot = "R" if spread > 0 else "L"  # the leading leg has the smaller pitch
        jump = rate_jumps[1] if foot == "R" else rate_jumps[0]
        events.append(HeelStrike(time=tau, foot=foot, index=i0, rate_jump=float(jump), z=float(z[k]),
                                 time_sd=tau_sd))
        kinks.append(leg_z[k, ::-1] if foot == "R" else leg_z[k])
    events = _like_the_others(events, kinks)
    events = _alternating(events, long_gaps)
    if half_window < longest:  # fast steps: too few samples a side for a local fit
        events = _periodic_refine(t, pl, pr, ok, events, sd, long_gaps=long_gaps)
    return events


def _beside_a_long_gap(tau: float, long_gaps, near: float) -> float:
    """The time uncertainty (s) a kink at ``tau`` (s) gains from a gap longer than ``max_gap``
    (``long_gaps``: (start, end) times of the samples either side) within ``near`` seconds of
    it: the span from the kink to the gap's far end over sqrt(12), or 0.

    Blur hides the fast legs around a heel strike, and the frames at a blurred gap's edge are the
    most blurred of those seen: their bias bends the signals there. A kink at such an edge may be
    that bend while the strike lies inside the gap, where no kink is timed (the toy's level-3 and
    blur-only benchmark videos gave kinks 1.9-4.7 frames from the truth with SDs of 0.05-0.11
    frame), so its time is known only to lie somewhere from the kink to the gap's far end.
    """
    extra = 0.0
    for start, end in long_gaps:
        if start > tau + near or end < tau - near:
            continue
        if tau <= start:  # the gap follows the kink
            extra = max(extra, (end - tau) / np.sqrt(12.0))
        elif tau >= end:
            extra = max(extra, (tau - start) / np.sqrt(12.0))
    return extra


def _periodic_refine(t, pl, pr, ok, events, sigma, degree=4, iterations=20, min_per_foot=4, max_move=1.5,
                     long_gaps=None):
    """Strike times of a fast, periodic gait from one template per striking foot.

    With a few frames a step, a local fit around one strike cannot follow the pitches (they swing
    through most of their range within a step). The gait repeats, though, and the frames fall at
    a different phase of each step, so all steps together sample the pitches densely. Around a
    strike by one foot, each sample with u = t - tau in the half-steps either side (the
    boundaries halfway to the neighbouring strikes) is explained by a template per pitch
    (striking leg, other leg): a polynomial of ``degree`` in u on each side of u = 0, continuous
    there, with a jump in all derivatives (the collision). Alternately the templates are fitted
    (linear least squares over all strikes of that foot) and each tau is moved to the best shift
    of its samples against them (a grid within a frame, refined by a parabola); the kink at
    u = 0 fixes the absolute timing. Strikes of a foot with fewer than ``min_per_foot`` strikes
    are left as they are; a strike whose move from its local estimate differs by more than
    ``max_move`` frames from the median move of its foot's strikes takes its local estimate
    plus that median move. (Template, or ensemble, alignment of repeated cycles: cf. Ramsay &
    Silverman 2005, Functional Data Analysis, ch. 7, "registration".)

    Given ``long_gaps`` ((start, end) times of the gaps a strike inside is not timed), a strike
    missed where every frame was seen is put back: two strikes of one foot 1.5-2.5 steps apart
    with no long gap between have a strike of the other foot between them (the feet alternate),
    found by that foot's templates (:func:`_missed_strikes`), its time relative to them as the
    others'. A strike's samples reach at most half a step from it, so that a neighbour beyond a
    missed strike does not lend the templates that strike's kink.
    """
    if len(events) < 3:
        return events
    taus = np.array([e.time for e in events])
    first = taus.copy()
    feet = np.array([e.foot for e in events])
    dt = float(np.median(np.diff(t)))
    step = float(np.median(np.diff(taus)))
    pitch = {"L": pl, "R": pr}
    # each strike's samples: to halfway to its neighbours, but at most half a step where they lie
    # beyond 1.5 steps (a strike missed between, or a long gap)
    apart = np.diff(taus) > 1.5 * step
    middle = 0.5 * (taus[:-1] + taus[1:])
    starts = np.concatenate([[taus[0] - 0.5 * step], np.where(apart, taus[1:] - 0.5 * step, middle)])
    ends = np.concatenate([np.where(apart, taus[:-1] + 0.5 * step, middle), [taus[-1] + 0.5 * step]])
    windows = [np.flatnonzero(ok & (t >= starts[i]) & (t < ends[i])) for i in range(len(taus))]
    scale = 0.5 * step  # u in units of half a step, for a well-conditioned basis

    powers = np.arange(1, degree + 1)

    def basis(u):
        """The templates' columns at offsets ``u`` (any shape): shape u.shape + (2 degree + 1,)."""
        x = (u / scale)[..., None]
        xp = x ** powers
        left = x < 0
        return np.concatenate([np.ones_like(x), np.where(left, xp, 0.0), np.where(left, 0.0, xp)],
                              axis=-1)

    def template(mine, idx, ys, at):
        """Template coefficients (one column per pitch) and total squared residual for strike
        times ``at``."""
        a = basis(np.concatenate([t[w] - at[i] for i, w in zip(mine, idx, strict=True)]))
        y = np.column_stack([np.concatenate([v[w] for w in idx]) for v in ys])
        coefs = np.linalg.lstsq(a, y, rcond=None)[0]
        return coefs, float(np.sum((a @ coefs - y) ** 2))

    grid = np.linspace(-dt, dt, 41)

    def shifted(mine, idx, ys, at):
        """The templates' total squared residual with the strike times ``at`` all shifted by each
        of the grid's shifts (template's, for every shift at once)."""
        a = basis(np.concatenate([t[w] - at[i] for i, w in zip(mine, idx, strict=True)])[None, :]
                  - grid[:, None])  # (grid, samples, columns)
        y = np.column_stack([np.concatenate([v[w] for w in idx]) for v in ys])
        return np.sum((a @ (np.linalg.pinv(a) @ y) - y) ** 2, axis=(1, 2))

    sds = np.array([e.time_sd for e in events])
    templates = {}  # foot -> (coefficients, residual SD of its strikes' samples, common shift's SD)
    for foot in ("L", "R"):
        mine = np.flatnonzero(feet == foot)
        if len(mine) < min_per_foot:
            continue
        other = "R" if foot == "L" else "L"
        ys = (pitch[foot], pitch[other])
        idx = [windows[i] for i in mine]
        # two values (the pitches) per sample; at least twice as many values as unknowns (the
        # two templates' coefficients and the strikes' shifts)
        if sum(len(w) for w in idx) < 2 * (2 * degree + 1) + len(mine):
            continue
        for _ in range(iterations):
            coefs, _ = template(mine, idx, ys, taus)
            shifts = np.zeros(len(mine))
            own_sd = np.full(len(mine), np.nan)
            for j, (i, w) in enumerate(zip(mine, idx, strict=True)):
                if len(w) < 4:
                    continue
                # the strike's samples against the templates at every shift of the grid at once
                fitted = basis(t[w][None, :] - taus[i] - grid[:, None]) @ coefs  # (grid, samples, 2)
                measured = np.column_stack([y[w] for y in ys])
                costs = np.sum((fitted - measured) ** 2, axis=(1, 2))
                shifts[j], own_sd[j] = _parabola_min(grid, costs, sigma)
            shifts -= np.mean(shifts)  # each strike against the others; the common shift is above
            taus[mine] += shifts
            # the common shift of this foot's strikes: the only thing the kink at u = 0 fixes
            common, common_sd = _parabola_min(grid, shifted(mine, idx, ys, taus), sigma)
            taus[mine] += common
            if max(abs(common), np.max(np.abs(shifts))) < 1e-3 * dt:
                break
        # each strike against the templates, and the foot's common shift; the noise level is
        # the measured one, or the templates' own residuals where they say it is worse
        coefs, total = template(mine, idx, ys, taus)
        dof = 2 * sum(len(w) for w in idx) - 2 * (2 * degree + 1) - len(mine)
        inflate = max(1.0, float(np.sqrt(total / dof)) / sigma) if dof > 0 else 1.0
        templates[foot] = (coefs, inflate * sigma, inflate * common_sd)
        sds[mine] = np.where(np.isfinite(own_sd), inflate * np.hypot(own_sd, common_sd), sds[mine])
    # The local estimates of fast steps are biased (late by 0.5-1 frame), about alike for every
    # strike of a foot: a strike whose move differs from its foot's median move by more than
    # ``max_move`` frames fitted the templates badly (a step unlike the others, a long gap) and
    # keeps its local estimate, corrected by that median move.
    move = taus - first
    typical = np.zeros_like(move)
    for foot in ("L", "R"):
        mine = feet == foot
        if mine.any():
            typical[mine] = np.median(move[mine])
    kept = np.abs(move - typical) <= max_move * dt
    taus = np.where(kept, taus, first + typical)
    sds = np.where(kept, sds, np.hypot([e.time_sd for e in events], max_move * dt))
    refined = [dataclasses.replace(e, time=float(tau), time_sd=float(sd),
                                   index=int(np.clip(np.searchsorted(t, tau) - 1, 0, len(t) - 2)))
               for e, tau, sd in zip(events, taus, sds, strict=True)]
    if long_gaps is None:
        return refined
    missed = _missed_strikes(t, pitch, ok, refined, templates, basis, step, long_gaps)
    return sorted(refined + missed, key=lambda e: e.time)


def _missed_strikes(t, pitch, ok, events, templates, basis, step, long_gaps,
                    max_rms: float = 3.0) -> list:
    """Strikes missed between two strikes of one foot (:func:`_periodic_refine`).

    For each pair of strikes of one foot 1.5-2.5 median ``step`` apart with no long gap between
    them, the other foot's strike is sought at every time between them at least half a step from
    both (a grid of a twentieth of a frame), its templates (``templates[foot]``: coefficients
    for (its pitch, the other pitch), residual SD) against the samples within half a step of the
    pair's midpoint, and placed at the least squared residual (the parabola through the grid's
    best three). It is kept where those samples' residual RMS is at most ``max_rms`` times the
    templates' own (the strikes the templates were fitted to): a walk that changes its gait there
    is left with the hole. Its time SD is the parabola's (:func:`_parabola_min`) for the
    templates' residual SD, with the foot's common shift's SD (all its strikes share that
    error). It is not refined with the others: at level 2 (stable-toy, 20 steps) refitting the
    templates with it moved its foot's common shift by 0.3-0.6 frame, the wrong way on both walks
    measured.
    """
    dt = float(np.median(np.diff(t)))
    found = []
    for a, b in zip(events[:-1], events[1:], strict=True):
        foot = "R" if a.foot == "L" else "L"
        if (a.foot != b.foot or foot not in templates or not 1.5 * step < b.time - a.time < 2.5 * step
                or not _seen_between(a, b, long_gaps)):
            continue
        coefs, resid_sd, common_sd = templates[foot]
        mid = 0.5 * (a.time + b.time)
        w = np.flatnonzero(ok & (np.abs(t - mid) < 0.5 * step))
        grid = np.arange(a.time + 0.5 * step, b.time - 0.5 * step, dt / 20.0)
        if len(w) < 4 or len(grid) < 3:
            continue
        measured = np.column_stack([pitch[foot][w], pitch[a.foot][w]])
        costs = np.sum((basis(t[w][None, :] - grid[:, None]) @ coefs - measured) ** 2, axis=(1, 2))
        tau, tau_sd = _parabola_min(grid, costs, resid_sd)
        if np.sqrt(costs.min() / measured.size) > max_rms * resid_sd:
            continue
        found.append(HeelStrike(time=tau, foot=foot, index=int(np.clip(np.searchsorted(t, tau) - 1, 0,
                                                                            len(t) - 2)),
                                rate_jump=float("nan"), z=float("nan"),
                                time_sd=float(np.hypot(tau_sd, common_sd))))
    return found


def _like_the_others(events: list, kinks, min_cosine: float = 0.5) -> list:
    """Drop kinks whose shape is unlike the heel strikes'.

    A collision changes both legs' pitch rates the same way at every step, so each strike's kink,
    the pair (striking leg, other leg) of rate jumps in standard errors, points about the same
    way: for compass-3d mostly along the striking leg, for the synthetic gait of the tests mostly
    along the other leg, and with either sign. The componentwise median of the kinks stands for
    the strikes; a kink more than 60 degrees (``min_cosine``) away from it is a noise kink, such
    as one leg's blurred frames bending it alone. Kinks with no common shape (their median
    shorter than half their median length: as many point one way as the opposite) are not
    strikes one can tell from noise, and none is kept; this happens when every strike is hidden
    in a gap and only the gaps' edges bend the signals (heavy motion blur).
    """
    if len(events) < 3:
        return events
    kinks = np.asarray(kinks, float)
    typical = np.median(kinks, axis=0)
    length = np.linalg.norm(kinks, axis=1)
    if np.linalg.norm(typical) < 0.5 * np.median(length):
        return []
    cosine = kinks @ typical / (length * np.linalg.norm(typical) + 1e-300)
    return [e for e, c in zip(events, cosine, strict=True) if c >= min_cosine]


def _seen_between(a: HeelStrike, b: HeelStrike, long_gaps) -> bool:
    """Whether the frames between strikes ``a`` and ``b`` were seen: no long gap ((start, end)
    times) overlaps them, where a strike of the other foot could have gone unseen."""
    return not any(a.time < end and start < b.time for start, end in long_gaps)


def _alternating(events: list, long_gaps=()) -> list:
    """Drop the weaker of two strikes that cannot both be real.

    Steps of one gait last about alike and the feet alternate: two strikes less than half the
    median step apart, or by the same foot less than 1.5 median steps apart with the stretch
    between them seen (no gap in ``long_gaps``, (start, end) times, where a strike of the other
    foot may have gone unseen), are one strike and a noise kink; the one with the smaller kink
    strength ``z`` goes.
    """
    events = sorted(events, key=lambda e: e.time)
    while len(events) >= 3:
        step = float(np.median(np.diff([e.time for e in events])))
        worst = None
        for a, b in zip(events[:-1], events[1:], strict=True):
            gap = b.time - a.time
            if gap < 0.5 * step or (a.foot == b.foot and gap < 1.5 * step and _seen_between(a, b, long_gaps)):
                weaker = a if a.z < b.z else b
                if worst is None or weaker.z < worst.z:
                    worst = weaker
        if worst is None:
            break
        events.remove(worst)
    return events


def stance_from_events(time, events, pitch_left=None, pitch_right=None) -> np.ndarray:
    """Stance foot ('L', 'R') per sample: the last foot to strike; before the first strike, the other.

    Samples with no event on record (no heel strike at all) are '' (unknown) unless pitches are
    given, in which case the trailing leg (larger pitch) is taken as the stance leg.
    """
    t = np.asarray(time, float)
    stance = np.full(t.shape, "", dtype="<U1")
    if events:
        first = events[0]
        stance[t < first.time] = "R" if first.foot == "L" else "L"
        for ev in events:
            stance[t >= ev.time] = ev.foot
    elif pitch_left is not None and pitch_right is not None:
        pl, pr = np.asarray(pitch_left, float), np.asarray(pitch_right, float)
        ok = np.isfinite(pl) & np.isfinite(pr)
        stance[ok & (pl > pr)] = "L"
        stance[ok & (pl <= pr)] = "R"
    return stance
