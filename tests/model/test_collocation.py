"""Collocation (BVP, IPOPT) against shooting (Newton on the step map): two independent methods."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import solve_collocation
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params

from ..conftest import DATA


@pytest.mark.parametrize("name", ["simplest-walker", "compass-3d"])
def test_collocation_agrees_with_shooting(name):
    params = load_params(DATA / "params" / f"{name}.toml")
    shooting = find_gait(params)
    # Start collocation away from the answer (a perturbed simulation), so that IPOPT does work.
    rng = np.random.default_rng(0)
    start = shooting.fixed_point + rng.normal(0, 0.01, 8) * (np.abs(shooting.fixed_point) + 0.01)
    if shooting.planar:
        start[:4] = 0.0
    coll = solve_collocation(params, start, planar=shooting.planar)
    assert coll.success, coll.status
    assert coll.iterations >= 2
    # Issue 3: fixed point and step time to 1e-8. Both methods are order 8; their own errors are
    # ~1e-12 (shooting: RK8 at 16 steps per time unit; collocation: Gauss-Legendre degree 4).
    assert_allclose(coll.fixed_point, shooting.fixed_point, atol=1e-8)
    assert abs(coll.step_time - shooting.step_time) < 1e-8 * max(1.0, shooting.step_time)
    # Eigenvalues of the step map from the collocation equations (implicit-function theorem)
    # against the shooting Jacobian (AD through the RK8 flow).
    ours = np.sort_complex(coll.eigenvalues)
    theirs = np.sort_complex(shooting.eigenvalues)
    assert_allclose(ours, theirs, atol=1e-7 * max(1.0, np.abs(theirs).max()))


def test_warm_start_and_failure_status():
    params = load_params(DATA / "params" / "simplest-walker.toml")
    gait = find_gait(params)
    first = solve_collocation(params, gait.fixed_point, planar=True)
    nearby = solve_collocation(params.replace(slope=0.0095), planar=True, warm_start=first)
    assert nearby.success
    assert nearby.step_time != first.step_time
    # Uphill no gait exists: the solver reports failure instead of returning garbage quietly.
    uphill = solve_collocation(params.replace(slope=-0.05), planar=True, warm_start=first)
    assert not uphill.success
    assert uphill.status
