"""Searching parameter space for gaits (toywalk.model.optimize): Nelder-Mead on the largest
eigenvalue against a brute-force scan and docs/gaits.md's optimum, and the least-squares fit of
gait features recovering a known walker."""

import numpy as np
import pytest
from toywalk.model import Walker, load_params, solve_fixed_point
from toywalk.model.optimize import fit_gait_targets, gait_features, minimise_max_eigenvalue

from ..conftest import DATA
from .documented import Z_STABLE, assert_documented


@pytest.fixture(scope="module")
def stable_gait():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return solve_fixed_point(Walker(params), np.array(Z_STABLE))


def test_minimise_max_eigenvalue_finds_the_coalescence(stable_gait):
    """docs/gaits.md section 2: the optimum had two coalescing eigenvalue pairs at max |lambda|
    0.956, and the shipped walker has its slope lowered by 10 % from there. Minimising over the
    slope alone from the shipped walker goes back to it; a scan of the slope agrees."""
    params = stable_gait.params
    bounds = {"slope": (0.05, 0.066)}  # the stable gait's branch exists over this range
    result = minimise_max_eigenvalue(stable_gait, ["slope"], bounds, maxiter=20)
    assert result.status == "improved" and result.jumps == 0 and result.failures == 0
    assert result.start_value == stable_gait.max_abs_eigenvalue
    assert result.value == result.gait.max_abs_eigenvalue  # its own gait's value
    assert result.history.shape == (result.evaluations, 2)
    assert result.value == np.min(result.history[:, 1])  # the best point evaluated
    assert_documented(result.value, 0.956, 1e-3, "optimum max |eigenvalue|")
    assert_documented(params.slope / result.params.slope, 0.90, 0.01, "shipped slope / optimum's")
    # Two pairs coalesce there: their moduli agree to 1e-3 (measured 1.2e-5), against 0.028 apart
    # at the shipped slope.
    moduli, shipped = np.abs(result.gait.eigenvalues), np.abs(stable_gait.eigenvalues)
    assert moduli[0] - moduli[2] < 1e-3 < shipped[0] - shipped[2]
    # Brute force: fixed-parameter Newton solves on a grid of slopes around the optimum, each
    # from the optimum's fixed point. None is lower than the optimiser's value by more than the
    # optimiser's stopping tolerance on the objective (fatol 1e-5, model/optimize.py).
    scan = []
    for slope in np.linspace(0.0590, 0.0600, 21):  # steps of 5e-5 rad, 0.08 % of the slope
        walker = Walker(params.replace(slope=float(slope)))
        scan.append(solve_fixed_point(walker, result.gait.fixed_point).max_abs_eigenvalue)
    assert min(scan) > result.value - 1e-5
    assert np.argmin(scan) not in (0, len(scan) - 1)  # an interior minimum, inside the scan


def test_fit_gait_targets_recovers_a_known_walker(stable_gait):
    """A synthetic truth: the stable walker with 10 mm more lateral offset and a 0.9 mm larger
    foot radius. Fitting those two parameters to its stride time and stride length, from the
    shipped walker, recovers them."""
    truth = stable_gait.params.replace(**{"com_offset[1]": 0.2, "foot_radius": 0.0125})
    features = gait_features(solve_fixed_point(Walker(truth), stable_gait.fixed_point))
    # Scales: 0.1 ms and 0.1 mm, tolerated misfits far below the features' change (the truth's
    # stride time and length differ from the start's by 2.5 ms and 0.6 mm).
    targets = {"stride_time": (features["stride_time"], 1e-4),
               "stride_length": (features["stride_length"], 1e-4)}
    bounds = {"com_offset[1]": (0.15, 0.25), "foot_radius": (0.009, 0.02)}
    result = fit_gait_targets(stable_gait, list(bounds), bounds, targets, max_nfev=20)
    assert result.status == "converged" and result.failures == 0
    # The fit ends with scaled residuals ~1e-11 (features matched to ~1e-15 s and m); with
    # sensitivities of order 0.1 to 1 (s/m, m/m) the parameters are then off by ~1e-13 m (measured
    # 1e-13 and 2e-16). 1e-10 m leaves 1000x for other platforms while any fit that merely comes
    # near the truth (the start is 10 mm and 0.9 mm away) fails.
    assert abs(result.params.com_offset[1] - 0.2) < 1e-10
    assert abs(result.params.foot_radius - 0.0125) < 1e-10
    assert max(abs(r) for r in result.residuals.values()) < 1e-6  # 1e-6 of a scale: 1e-10 s and m
    assert result.features == gait_features(result.gait)
