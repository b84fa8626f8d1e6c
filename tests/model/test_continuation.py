"""Continuation of gait families: the simplest walker's stability boundary, and the branch itself."""

import json

import numpy as np
import pytest
from toywalk.model.continuation import continue_branch
from toywalk.model.gait import find_gait
from toywalk.model.parameters import ParameterError, load_params
from toywalk.model.walker import Walker

from ..conftest import DATA
from .documented import assert_documented

# docs/model.md section 7: an eigenvalue through -1 (Garcia et al. 1998, recomputed)
GARCIA_BOUNDARY = 0.0150884
# A branch point is a gait when one step from it returns to it: |P(z) - z| (rates scaled by
# sqrt(l/g)) within continuation's corrector tolerance 1e-10 (model/continuation.py); its points are
# then polished by Newton, measured 2e-15 to 5e-14.
GAIT_TOL = 1e-10


def assert_points_are_gaits(params, branch):
    """Every point of ``branch`` is a gait of ``params`` with the point's parameter value, stepped
    by a fresh walker (step-map residual), with the step time the point reports."""
    for point in branch.points:
        walker_params = params.replace(**{branch.name: point.value})
        step = Walker(walker_params).step(point.fixed_point)
        scale = np.array([1.0, walker_params.time_scale] * 4)
        residual = np.max(np.abs((step.z_plus - point.fixed_point) * scale))
        assert residual < GAIT_TOL, f"{branch.name} = {point.value}: |P(z) - z| = {residual:.3g}"
        # The point reports the step time of this very step (a mismatch: numbers from another state).
        assert abs(step.step_time - point.step_time) < GAIT_TOL * walker_params.time_scale


@pytest.fixture(scope="module")
def simplest():
    return load_params(DATA / "params" / "simplest-walker.toml")


def test_continuation_finds_the_period_doubling(simplest):
    branch = continue_branch(simplest, "slope", 0.009, 0.0175)
    assert branch.status == "reached"
    assert branch.points[-1].value == 0.0175
    losses = [e for e in branch.events if e.kind == "loses stability"]
    assert len(losses) == 1
    # Issue 2/3: 0.01509 +/- 2e-4; the secant refinement is far tighter (1e-6 here).
    assert abs(losses[0].value - GARCIA_BOUNDARY) < 1e-6
    assert "-1" in losses[0].detail
    # Every point on the branch is a gait: compare one with an independent fixed-parameter solve.
    mid = branch.points[len(branch.points) // 2]
    gait = find_gait(simplest.replace(slope=mid.value))
    np.testing.assert_allclose(gait.fixed_point, mid.fixed_point, atol=1e-9)


def test_continuation_in_a_3d_parameter():
    params = load_params(DATA / "params" / "compass-3d.toml")
    branch = continue_branch(params, "com_offset[1]", 0.02, 0.04, max_points=30)
    assert branch.status == "reached"
    assert not branch.planar
    values = [p.value for p in branch.points]
    assert values[0] == 0.02 and values[-1] == 0.04
    assert all(np.diff(values) > 0)  # no fold in this range: monotone parameter
    assert_points_are_gaits(params, branch)


def test_continuation_bad_input(simplest):
    with pytest.raises(ParameterError, match="cannot continue"):
        continue_branch(simplest, "bogus", 0.0, 1.0)
    with pytest.raises(ValueError, match="two different"):
        continue_branch(simplest, "slope", 0.01, 0.01)


def test_cli_continue_writes_table_plot_and_events(tmp_path):
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", "gait", "--params",
                          str(DATA / "params" / "simplest-walker.toml"), "--continue", "slope",
                          "0.012", "0.016", "--out", str(tmp_path / "branch.csv")],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "period doubling" in out.stdout
    header = (tmp_path / "branch.csv").read_text().splitlines()[0]
    assert header.startswith("slope,step_time,stride_length,max_abs_eigenvalue,stable")
    assert (tmp_path / "branch.png").read_bytes()[:4] == b"\x89PNG"
    events = json.loads((tmp_path / "branch.json").read_text())["events"]
    assert abs(events[0]["value"] - GARCIA_BOUNDARY) < 1e-6
    bad = subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", "gait", "--params",
                          str(DATA / "params" / "simplest-walker.toml"), "--continue", "slope",
                          "0.012", "x", "--out", str(tmp_path / "bad.csv")],
                         capture_output=True, text=True, timeout=600)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad.csv").exists()


def test_fold_is_found_and_is_a_fold():
    """compass-3d's gait family in hip width turns back near w = 0.118 m. Check it is a real fold:
    below the turning value the branch holds two different gaits at the same parameter (one on
    each side), each confirmed by an independent fixed-parameter Newton solve."""
    from toywalk.model.gait import solve_fixed_point

    params = load_params(DATA / "params" / "compass-3d.toml")
    branch = continue_branch(params, "hip_width", 0.1, 0.3, max_points=60)
    assert_points_are_gaits(params, branch)  # both sides of the fold
    folds = [e for e in branch.events if e.kind == "fold"]
    assert len(folds) == 1
    w_fold = folds[0].value
    assert 0.11 < w_fold < 0.125  # measured 0.1177 (docs: toywalk gait --continue)
    values = np.array([p.value for p in branch.points])
    turn = int(np.argmax(values))
    assert 0 < turn < len(values) - 1  # the parameter rises, then falls: the branch turned back
    w = 0.5 * (values[turn - 1] + w_fold) if values[turn - 1] < w_fold else values[turn - 1]
    walker = Walker(params.replace(hip_width=w))
    before = solve_fixed_point(walker, branch.points[turn - 1].fixed_point)
    after_index = turn + int(np.argmin(np.abs(values[turn:] - w)))
    after = solve_fixed_point(walker, branch.points[after_index].fixed_point)
    assert np.max(np.abs(before.fixed_point - after.fixed_point)) > 1e-4


def test_continuation_to_a_bound_lands_on_it():
    """Continuing hip width down to exactly 0 (its lower bound) ends on w = 0, not past it; every
    point is a gait, and the walker without hip width is unstable there."""
    params = load_params(DATA / "params" / "stable-toy.toml")
    branch = continue_branch(params, "hip_width", params.hip_width, 0.0, max_points=60)
    assert branch.status == "reached"
    assert branch.points[-1].value == 0.0
    assert_points_are_gaits(params, branch)
    # docs/gaits.md section 2: hip width helps; without it this walker's gait is unstable.
    assert_documented(branch.points[0].max_abs_eigenvalue, 0.967, 1e-3, "max |eigenvalue|, w = 34.7 mm")
    assert_documented(branch.points[-1].max_abs_eigenvalue, 1.25, 0.01, "max |eigenvalue|, w = 0")


def test_a_stored_gait_is_followed_to_the_first_value():
    """A walker whose file stores a start near its gait (clearing-toy: the search from the planar
    reduction does not reach it) is continued from another value of the parameter by following its
    own gait there first. At slope 0.065, where the stored start also converges directly, the two
    ways give one gait (Newton's tolerance, 1e-10, times the map's conditioning)."""
    params = load_params(DATA / "params" / "clearing-toy.toml")
    branch = continue_branch(params, "slope", 0.065, 0.066, max_points=3)
    assert branch.points[0].value == 0.065
    # three points do not reach 0.066: the message says where the branch stopped, and how far
    last = branch.points[-1].value
    assert branch.status == "max_points" and 0.065 < last < 0.066
    assert branch.message == (f"stopped after 3 points at slope = {last:.6g}, "
                              f"{(last - 0.065) / 0.001:.0%} of the way from 0.065 to 0.066")
    direct = find_gait(params.replace(slope=0.065))
    np.testing.assert_allclose(branch.points[0].fixed_point, direct.fixed_point, rtol=0, atol=1e-8)


def test_a_first_value_past_the_walkers_fold_is_explained():
    """The Tinkertoy fit's gait exists only down to about 1e-9 rad below its own slope
    (docs/effects_study.md): a continuation asked to start at 0.0785398 (its slope to seven
    digits) finds no gait there, and following the walker's own gait down says why: a fold, where
    the search alone gave only "Newton did not converge". The search itself is stood in for here
    (it takes a minute to fail); `_approach` is what runs after it."""
    from toywalk.model.continuation import _approach
    from toywalk.model.gait import GaitNotFound

    params = load_params(DATA / "params" / "tinkertoy.toml")
    own, start = params.slope, 0.0785398
    assert start < own
    with pytest.raises(GaitNotFound, match=r"folds back at slope = 0\.07853981\d* \(a fold") as err:
        _approach(params, params.replace(slope=start), "slope", own, start, None, 20, 0.05,
                  GaitNotFound("the search failed"))
    assert "the search at 0.0785398 found none either (the search failed)" in str(err.value)
    # and a value on the branch's side is reached from the walker's own gait
    steeper = own * 1.001
    gait = _approach(params, params.replace(slope=steeper), "slope", own, steeper, None, 20, 0.05,
                     GaitNotFound("the search failed"))
    assert gait.params.slope == steeper and gait.fold_eigenvalue is None
