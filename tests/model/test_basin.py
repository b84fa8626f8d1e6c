"""The basin of attraction and the hand launch (model/basin.py; docs/gaits.md section 5)."""

import math

import numpy as np
import pytest
from toywalk.model import Walker, find_gait, load_params, simulate
from toywalk.model.basin import (
    basin_radius,
    eigen_directions,
    hand_launch,
    launch_state,
    perturbed,
    random_directions,
    recovers,
    recovery_curve,
)
from toywalk.model.gait import state_scale

from ..conftest import DATA
from .documented import shipped_gait


@pytest.fixture(scope="module")
def clearing_gait():
    return shipped_gait("clearing-toy")


@pytest.fixture(scope="module")
def stable_gait():
    return shipped_gait("stable-toy")


def _real_slowest(gait):
    """The real eigenvalue of largest modulus and its unit direction (state_scale units)."""
    k = next(k for k, lam in enumerate(gait.eigenvalues) if abs(lam.imag) < 1e-12 and abs(lam) > 1e-9)
    vec = gait.eigenvectors[:, k].real / state_scale(gait.params)
    return gait.eigenvalues[k].real, vec / np.linalg.norm(vec)


def test_a_small_push_along_the_slowest_real_mode_decays_at_its_eigenvalue(clearing_gait):
    """The clearing toy's real eigenvalue -0.8514 is within 0.001 of its slowest modulus (0.852,
    docs/gaits.md section 4). Pushed 1e-6 along its eigenvector, the walk recovers, and after 20
    steps the deviation is lambda^20 times the push: linear theory, up to the quadratic terms (a
    relative 1e-6 times the map's curvature) and the other modes the surface correction excites
    (O(size^2)); 1e-4 relative allows for both with a margin of 100."""
    params, gait = clearing_gait.params, clearing_gait
    lam, unit = _real_slowest(gait)
    assert abs(abs(lam) - gait.max_abs_eigenvalue) < 1e-3
    walker = Walker(params)
    size = 1e-6
    z0 = perturbed(params, gait, unit, size, walker)
    assert recovers(params, z0, gait, walker=walker).recovered
    z, n = z0, 20
    for _ in range(n):
        z = walker.step(z).z_plus
    deviation = (z - gait.fixed_point) / state_scale(params)
    start = (z0 - gait.fixed_point) / state_scale(params)
    expected = lam ** n * start
    np.testing.assert_allclose(deviation, expected, rtol=0, atol=1e-4 * np.linalg.norm(expected))


def test_a_huge_push_falls(clearing_gait):
    """Two units along the slowest real mode (2 rad of steer and lean, 16 rad/s of rates): far
    outside any radius measured (docs/gaits.md section 5: at most 0.25)."""
    params, gait = clearing_gait.params, clearing_gait
    _, unit = _real_slowest(gait)
    result = recovers(params, perturbed(params, gait, unit, 2.0), gait)
    assert not result.recovered
    assert result.reason in ("fell", "scuffed", "no_heel_strike")


def test_bisection_brackets_the_edge(clearing_gait):
    """Just below the reported radius the walk recovers, at the reported upper end it does not,
    and the two lie within the stated relative tolerance."""
    params, gait = clearing_gait.params, clearing_gait
    label, unit = eigen_directions(gait)[0]
    rtol = 0.02
    r = basin_radius(params, unit, gait, label=label, rtol=rtol)
    assert 0 < r.radius < r.upper <= r.radius * (1 + rtol)
    walker = Walker(params)

    def ok(size):
        return recovers(params, perturbed(params, gait, unit, size, walker), gait, walker=walker).recovered

    assert ok(r.radius) and ok(0.9 * r.radius)
    assert not ok(r.upper)


def test_an_unstable_gait_has_no_basin_along_its_unstable_mode():
    """data/params/toy-sized.toml's gait has max |eigenvalue| about 5.9 (docs/gaits.md): along its
    unstable eigenvector not even a push of 1e-6 (state_scale units) returns, against radii of
    0.01 and more along the stable gaits' eigenvectors (docs/gaits.md section 5)."""
    params = load_params(DATA / "params" / "toy-sized.toml")
    gait = find_gait(params)
    assert gait.max_abs_eigenvalue > 5
    label, unit = eigen_directions(gait)[0]
    r = basin_radius(params, unit, gait, label=label, smallest=1e-6)
    assert r.radius == 0.0 and r.upper <= 2e-6


def test_the_perturbed_start_is_a_post_strike_state(clearing_gait):
    """Every start has its trailing foot on the ramp (to 1e-13 m) and lies along the direction
    to first order; random directions are unit vectors tangent to that surface."""
    params, gait = clearing_gait.params, clearing_gait
    walker = Walker(params)
    directions = random_directions(params, gait, 4, rng=1)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=1e-12)
    for u in directions:
        z = perturbed(params, gait, u, 1e-3, walker)
        assert abs(walker.guard(walker.full_state(z))[0]) <= 1e-13
        moved = (z - gait.fixed_point) / state_scale(params)
        # the correction is second order: 1e-3 squared times a curvature of order 1
        assert np.linalg.norm(moved - 1e-3 * u) < 1e-4


def test_scuffs_fail_where_the_gait_clears(clearing_gait, stable_gait):
    """The clearing toy's gait never scuffs, so a scuff ends its walk; the stable toy's scuffs
    every step, so its walk goes on with the scuffs counted (docs/gaits.md section 4) unless
    asked to fail on them."""
    params, gait = stable_gait.params, stable_gait
    result = recovers(params, perturbed(params, gait, eigen_directions(gait)[0][1], 1e-3), gait)
    # the perturbed first step may miss the scuff (95 of 96 steps scuff here)
    assert result.recovered and result.scuffs >= result.steps - 2
    assert recovers(params, gait.fixed_point, gait, scuffs_fail=True, steps=3).reason == "scuffed"


def test_the_recovery_curve_counts_its_trials(clearing_gait):
    """Tiny pushes all recover, 2 units none; the standard error is binomial."""
    params, gait = clearing_gait.params, clearing_gait
    curve = recovery_curve(params, [1e-5, 2.0], trials=4, seed=0, gait=gait)
    assert curve.recovered.tolist() == [4, 0]
    assert curve.se.tolist() == [0.0, 0.0]


def test_the_hand_launch_starts_on_one_foot_and_the_clearing_toy_falls(clearing_gait):
    """The launch state has the right foot off the ramp by about w sin(tip) and just behind the
    stance foot; released from it at 2.9 degrees (1.5 times the gait's lean amplitude, the tip the
    issue tried in MuJoCo) the clearing toy falls within two steps, as it did there."""
    params, gait = clearing_gait.params, clearing_gait
    tip = math.radians(2.9)
    height, ahead = Walker(params).guard(Walker(params).full_state(launch_state(tip)))
    assert height == pytest.approx(params.hip_width * math.sin(tip), rel=0.05)
    assert -1e-5 * params.leg_length < ahead < 0
    launch = hand_launch(params, [tip], gait=gait)
    assert launch.results[0][0].reason == "fell" and launch.results[0][0].steps <= 3
    assert launch.tip_range() is None


def test_a_release_with_the_legs_open_and_a_push(clearing_gait):
    """launch_state's split and rate: the legs open symmetrically about the normal, the rear foot
    (the right, lifted by the tip) behind the stance foot by about the chord l_eff * split, both
    legs pitching at the push's rate, the hinge still; the defaults are the launch at rest (the
    same state to the bit); a negative split is refused."""
    params = clearing_gait.params
    tip, split, rate = 0.03, 0.2, 1.5
    assert np.array_equal(launch_state(tip), launch_state(tip, 0.0, 0.0, 0.0))
    z = launch_state(tip, split=split, rate=rate)
    assert z[4] == -0.1 and z[6] == 0.1 and z[5] == z[7] == rate and z[1] == z[3] == 0.0
    height, ahead = Walker(params).guard(Walker(params).full_state(z))
    chord = 2 * (params.leg_length - params.foot_radius) * math.sin(split / 2)
    assert -ahead == pytest.approx(chord, rel=0.1)
    assert height > 0
    with pytest.raises(ValueError, match="split"):
        launch_state(tip, split=-0.1)


def test_recovers_agrees_with_the_dense_simulation(clearing_gait):
    """A second route to the same verdict: simulate (dense samples, physical frame) from the
    starts just inside and just outside the basin along a random direction. Inside, it walks the
    steps recovers took and ends on the gait's step time; outside, it stops as recovers did, at the same
    step."""
    params, gait = clearing_gait.params, clearing_gait
    walker = Walker(params)
    unit = random_directions(params, gait, 1, rng=3)[0]
    r = basin_radius(params, unit, gait, walker=walker)
    inside = perturbed(params, gait, unit, r.radius, walker)
    outside = perturbed(params, gait, unit, r.upper, walker)
    good, bad = recovers(params, inside, gait, walker=walker), recovers(params, outside, gait, walker=walker)
    assert good.recovered and not bad.recovered and bad.reason != "not_converged"
    walk = simulate(params, inside, good.steps)
    assert walk.status == "completed" and walk.scuffs == 0
    # back on the gait: its last step lasts the gait's step time (recovers' tolerance, 1e-4 of a
    # state unit, moves the step time by about that fraction; 1e-3 leaves a margin of 10)
    last = walk.events[-1].time - walk.events[-2].time
    assert last == pytest.approx(gait.step_time, rel=1e-3)
    fall = simulate(params, outside, bad.steps + 5)
    if bad.reason == "scuffed":
        assert fall.scuffs > 0
    else:
        assert fall.status == bad.reason and len(fall.events) == bad.steps
