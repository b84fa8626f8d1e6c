"""data/params/robust-toy.toml, the design of docs/make_robust_design.py and
docs/make_soft_robust_design.py (docs/gaits.md sections 7 and 8): a walker that cannot stand,
walks stably on rigid and soft feet with its swing foot clear by 2 mm, and survives larger pushes
than clearing-toy. Its MuJoCo checks are in tests/model/test_robust_toy_mujoco.py."""

import numpy as np
import pytest
from toywalk.model import Walker, basin, can_stand, find_gait, load_params, solve_fixed_point

from ..conftest import DATA
from .documented import assert_documented, shipped_gait

PARAMS = DATA / "params" / "robust-toy.toml"
# What docs/gaits.md quotes for this walker's gait (to the digits quoted there).
DOCUMENTED = {"max_abs_eigenvalue": (0.935, 0.001), "step_time": (0.1432, 0.0001),
              "lean_amplitude": (np.radians(1.220), np.radians(0.001))}
#: Its largest eigenvalue modulus on soft feet of 1, 2 and 4 ms, as docs/gaits.md section 7 quotes
#: it, with the strike integrated at 80 RK4 steps per tau (160 moves it by at most 0.0009).
SOFT_DOCUMENTED = {1e-3: 0.935, 2e-3: 0.938, 4e-3: 0.977}


@pytest.fixture(scope="module")
def gait():
    # find_gait starts from the file's [gait] start, as `toywalk gait --params` does.
    return find_gait(load_params(PARAMS))


def test_the_issues_constraints(gait):
    """Issue 44's design constraints: stable, the swing foot clear by 1 mm over the whole swing,
    unable to stand in any configuration."""
    assert gait.stable
    assert gait.clearance >= 1e-3
    report = can_stand(gait.params)
    assert not report.can_stand, report.reason


def test_gait_as_documented(gait):
    for name, (documented, unit) in DOCUMENTED.items():
        assert_documented(getattr(gait, name), documented, unit, name)


def test_basin_wider_than_clearing_toys(gait):
    """The design search's aim: a larger basin in general directions. The median radius over five
    random directions (seed 0, bisected to 2 %): measured 0.041 against clearing-toy's 0.0061,
    6.7 times (docs/gaits.md section 7 quotes 20 directions: 0.032 against 0.0066). Three times
    is asked: a walker no more robust than clearing-toy fails, and so would docs/robust_best.toml
    (0.020 over these five: 3.3 times, a bare pass), while the sampling spread of a median of five
    (the radii range over a factor of eight) stays inside it. About 2 s."""
    clearing = shipped_gait("clearing-toy")
    medians = {}
    for name, g in (("robust", gait), ("clearing", clearing)):
        directions = basin.random_directions(g.params, g, 5, 0)
        medians[name] = np.median([basin.basin_radius(g.params, u, g).radius for u in directions])
    assert medians["robust"] >= 3.0 * medians["clearing"], medians


def test_stable_on_soft_feet(gait):
    """The issue asks for the design with soft contacts: the gait followed onto soft feet (the
    ``soft_heel`` effect) of 1, 2 and 4 ms, each by Newton from the last, stays stable, with the
    largest eigenvalue modulus docs/gaits.md quotes. At the Walker's default 20 RK4 steps per tau
    these read 0.938, 0.941 and 0.950: not converged on this walker, hence 80. About 5 s (a
    first run compiles the 80-step strike, a few seconds)."""
    z = gait.fixed_point
    for tau, documented in SOFT_DOCUMENTED.items():
        walker = Walker(gait.params.replace(**{"effects.soft_heel": tau}), soft_steps_per_tau=80)
        soft = solve_fixed_point(walker, z)
        assert soft.stable
        assert_documented(soft.max_abs_eigenvalue, documented, 0.001, f"max |eigenvalue| at {tau} s")
        z = soft.fixed_point


def test_hand_launch_fails_as_documented(gait):
    """docs/gaits.md sections 7-8: released from rest at 1.5 and 2.5 times its lean amplitude it
    falls in its third step (two heel strikes walked), as every walker of the search does."""
    launch = basin.hand_launch(gait.params, [1.5 * gait.lean_amplitude, 2.5 * gait.lean_amplitude], gait=gait)
    assert [(r.steps, r.reason) for r in launch.results[0]] == [(2, "fell"), (2, "fell")]
