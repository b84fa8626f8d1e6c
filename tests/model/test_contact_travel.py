"""The stance contact's advance per step from the collocation BVP, against the shooting step map."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import bvp, initial_guess, step_displacements
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker

from ..conftest import DATA


@pytest.mark.parametrize(("name", "period", "mesh"), [
    ("stable-toy", 1, (30, 4)), ("stable-toy", 2, (12, 3)), ("simplest-walker", 1, (30, 4)),
    ("compass-3d", 1, (12, 3)),
])
def test_step_displacements_agree_with_shooting(name, period, mesh):
    """Each step's contact advance (rolled travel by the collocation's quadrature, plus the
    collision's jump) equals the RK8 step map's ``Step.contact``: two independent integrations.
    A planar walker's has no sideways part."""
    params = load_params(DATA / "params" / f"{name}.toml")
    gait = find_gait(params)
    walker = Walker(params, planar=gait.planar, period=period)
    prob = bvp(gait.planar, *mesh, period)
    sol = prob.solver(x0=initial_guess(walker, gait.fixed_point, prob), p=params.input_vector(),
                      lbg=prob.lbg, ubg=prob.ubg)
    w = np.array(sol["x"]).ravel()
    got = np.array(step_displacements(prob)(w, params.input_vector()))
    steps = [walker.step(gait.fixed_point, side=1)]
    if period == 2:
        steps.append(walker.step(steps[0].z_plus, side=-1))
    want = np.array([s.contact for s in steps]).T
    # Gauss-Legendre of order 2 * degree on the mesh against RK8 at 1e-12: measured 5e-13 to
    # 3e-11 m at (30, 4) and (12, 3) on stable-toy and compass-3d, 2e-9 m on the simplest walker
    # at (12, 3) (its long step); 1e-8 m is 1e-5 of a tracker's error on a toy's step.
    assert_allclose(got, want, atol=1e-8, rtol=0)
    assert got.shape == (2, period)
    if gait.planar:
        assert np.all(got[1] == 0.0)
    else:  # the step width is there, and the check could fail on it
        assert abs(got[1, 0]) > 1e-3
