"""A smoothed copy of the tracked signals: Savitzky-Golay over stretches without gaps or heel strikes.

Savitzky & Golay 1964, Anal. Chem. 36:1627, doi:10.1021/ac60214a047: a least-squares polynomial
of degree ``order`` over a moving window of ``window`` samples. The walker's angular rates jump at
a heel strike, so no window spans one; nor does one span a gap (a missing sample is never
invented). Stretches shorter than the window are left raw. The filter treats the samples as evenly
spaced (the frame times of a fixed-rate video); the SD of a smoothed sample is the raw one times
the filter's noise gain ``sqrt(sum c_i^2)`` (white noise).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["savgol", "savgol_weights", "smooth_signals"]


def smooth_signals(time: np.ndarray, raw: dict, sd: dict, events, window: int,
                   order: int) -> tuple[dict, dict]:
    """Savitzky-Golay smoothing over stretches free of gaps and heel strikes (rates jump there).

    Parameters
    ----------
    time : ndarray, shape (n,)
        Sample times (s), increasing.
    raw, sd : dict of str -> ndarray, shape (n,)
        Signals and their SDs; NaN = gap.
    events : sequence
        Heel strikes, each with a ``time`` (s): no window spans one.
    window : int
        Samples in the filter's window (odd).
    order : int
        The fitted polynomial's degree (< ``window``).

    Returns
    -------
    smooth, smooth_sd : dict of str -> ndarray, shape (n,)
        Copies of ``raw`` and ``sd``, smoothed (and the SDs scaled by the noise gain) on every
        stretch of at least ``window`` samples.
    """
    smooth = {k: v.copy() for k, v in raw.items()}
    smooth_sd = {k: v.copy() for k, v in sd.items()}
    gain = math.sqrt(float(np.sum(savgol_weights(window, order) ** 2)))
    cuts = np.searchsorted(time, [e.time for e in events])
    for k in raw:
        ok = np.isfinite(raw[k])
        seg_id = np.cumsum(np.concatenate([[0], (np.diff(ok.astype(int)) != 0).astype(int)]))
        breaks = np.zeros(len(time), dtype=int)
        breaks[cuts[cuts < len(time)]] = 1
        seg_id = seg_id * 10**6 + np.cumsum(breaks)
        for s in np.unique(seg_id[ok]):
            idx = np.flatnonzero((seg_id == s) & ok)
            if len(idx) >= window:
                smooth[k][idx] = savgol(raw[k][idx], window, order)
                smooth_sd[k][idx] = sd[k][idx] * gain
    return smooth, smooth_sd


def savgol_weights(window: int, order: int) -> np.ndarray:
    """Weights (window,) of the Savitzky-Golay smoother: the value at the window's centre of the
    least-squares polynomial of degree ``order`` through ``window`` equally spaced samples
    (Savitzky & Golay 1964, Anal. Chem. 36:1627). scipy.signal.savgol_coeffs gives the same; this
    module does without scipy.signal, whose import takes about a second (it imports scipy.stats)."""
    return _polynomial_fit(window, order)[1][0]


def savgol(x: np.ndarray, window: int, order: int) -> np.ndarray:
    """``x`` (n,), n >= window, smoothed by :func:`savgol_weights`; the first and last
    ``window // 2`` samples take the polynomial fitted to the first and last ``window`` samples
    (scipy.signal.savgol_filter's ``mode="interp"``)."""
    x = np.asarray(x, dtype=float)
    half = window // 2
    t, fit = _polynomial_fit(window, order)
    out = np.empty_like(x)
    out[half:len(x) - half] = np.convolve(x, fit[0][::-1], mode="valid")
    head = np.vander(t[:half], order + 1, increasing=True)
    tail = np.vander(t[window - half:], order + 1, increasing=True)
    out[:half] = head @ (fit @ x[:window])
    out[len(x) - half:] = tail @ (fit @ x[len(x) - window:])
    return out


def _polynomial_fit(window: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample positions t (window,) about the window's centre, and the least-squares map (order +
    1, window) from ``window`` samples to the coefficients of the polynomial in t (centred: a
    well-conditioned fit); its first row gives the value at the centre."""
    half = window // 2
    t = np.arange(-half, window - half, dtype=float)
    return t, np.linalg.pinv(np.vander(t, order + 1, increasing=True))
