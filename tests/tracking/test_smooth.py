"""The tracker's Savitzky-Golay smoother against scipy.signal's, the reference."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.tracking.smooth import savgol, savgol_weights

from ..conftest import loaded_by


@pytest.mark.parametrize("window, order", [(5, 2), (7, 3), (9, 2), (11, 4), (15, 3)])
def test_savgol_is_scipys(window, order):
    """Weights and smoothed series equal scipy.signal's savgol_coeffs and savgol_filter (mode
    "interp", the ends from the polynomial through the first and last windows), series as short
    as one window; to 1e-12 of a random walk's unit steps (round-off of two least-squares fits)."""
    from scipy.signal import savgol_coeffs, savgol_filter

    assert_allclose(savgol_weights(window, order), savgol_coeffs(window, order), rtol=0, atol=1e-13)
    rng = np.random.default_rng(window * 10 + order)
    for n in (window, window + 1, 60):
        x = np.cumsum(rng.normal(size=n))
        assert_allclose(savgol(x, window, order), savgol_filter(x, window, order, mode="interp"),
                        rtol=0, atol=1e-12)


def test_savgol_keeps_a_polynomial_of_its_order():
    """A polynomial of the filter's degree passes unchanged, ends included (an analytic check)."""
    t = np.linspace(-1.0, 2.0, 31)
    x = 0.3 - 1.2 * t + 0.7 * t**2 - 0.25 * t**3
    assert_allclose(savgol(x, 9, 3), x, rtol=0, atol=1e-12)


def test_smoothing_does_not_load_scipy_stats():
    """The tracker smooths without scipy.signal, whose import brings scipy.stats (about a second
    in every tracking run)."""
    code = ("import numpy as np; from toywalk.tracking.smooth import smooth_signals; "
            "t = np.arange(30) / 60; s = smooth_signals(t, {'a': np.sin(t)}, {'a': np.ones(30)}, [], 7, 3)")
    assert loaded_by(code, "scipy.stats", "scipy.signal") == {"scipy.stats": False, "scipy.signal": False}
