"""Gaits by shooting: the simplest walking model's published numbers and stability boundary."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.gait import find_gait, solve_fixed_point
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker

from ..conftest import DATA

# Garcia, Chatterjee, Ruina & Coleman 1998, J. Biomech. Eng. 120:281, recomputed with sensitivity
# equations at tolerance 1e-13 (docs/model.md section 7). Time in sqrt(l/g) units (g = l = 1).
GARCIA_THETA = 0.20031090054428
GARCIA_THETA_DOT = 0.19983247300499
# The swing leg's rate: the same recomputation gives, in Garcia's signs, theta_dot =
# -0.19983247300499 and the inter-leg angle's rate phi_dot = -0.01582299994832; the swing leg's
# absolute angle is theta - phi, and ours has the opposite sign: theta_sw_dot = -(theta_dot -
# phi_dot).
GARCIA_THETA_SW_DOT = 0.19983247300499 - 0.01582299994832
GARCIA_STEP_TIME = 3.8824637528506
GARCIA_EIG = -0.190099841064371 + 0.557598776683120j
GARCIA_BOUNDARY = 0.0150884  # slope at which an eigenvalue leaves through -1
# Garcia's own code comments (docs/model.md section 7): finite-difference-era values, off in the
# 11th digit.
GARCIA_CODE_THETA = 0.20031090049483
GARCIA_CODE_THETA_DOT = 0.19983247291764


@pytest.fixture(scope="module")
def simplest():
    # The light-leg limit: m/M = 1e-13 (data/params/simplest-walker.toml); the model's fixed point
    # differs from the m/M -> 0 limit by O(m/M), far below the tolerances below.
    return load_params(DATA / "params" / "simplest-walker.toml")


def test_simplest_walker_gait(simplest):
    gait = find_gait(simplest)
    assert gait.planar  # point masses: the 3D mass matrix has no yaw inertia (docs/model.md section 5)
    z = gait.fixed_point
    # Tolerances: the differences from the reference barely move when our grid is refined 4x (16 ->
    # 64 steps per time unit: by 1e-15 in the states, 2e-14 in the step time, 7e-14 in the
    # eigenvalues), so they are the reference's own error, from its integration at tolerance 1e-13,
    # plus O(m/M) = 1e-13. Measured: states 5e-14, step time 7.2e-13, eigenvalues 3.2e-12 (the event
    # time and the variational equations carry more of the reference's error than the states).
    # Each tolerance is about 10x its measured difference.
    # Our angles: theta_st < 0 just after heel strike, rate > 0 (Garcia's theta = -theta_st).
    state_tol = 5e-13
    assert abs(z[4] + GARCIA_THETA) < state_tol
    assert abs(z[5] - GARCIA_THETA_DOT) < state_tol
    assert abs(z[6] - GARCIA_THETA) < state_tol  # point feet, symmetric legs: theta_sw = -theta_st
    assert abs(z[7] - GARCIA_THETA_SW_DOT) < state_tol
    assert abs(gait.step_time - GARCIA_STEP_TIME) < 1e-11
    lead = gait.eigenvalues[:2]
    assert_allclose(sorted(lead, key=lambda e: e.imag), [np.conj(GARCIA_EIG), GARCIA_EIG],
                    rtol=0, atol=5e-11)
    assert gait.stable
    # The tolerances tell the reference from values nearly as good: Garcia's code comments differ
    # by 5e-11 (theta) and 9e-11 (rate), his finite-difference eigenvalues by ~1e-3.
    assert abs(z[4] + GARCIA_CODE_THETA) > 10 * state_tol
    assert abs(z[5] - GARCIA_CODE_THETA_DOT) > 10 * state_tol
    assert abs(lead[0].real - (-0.19120868949940)) > 1e-4


def test_collision_law_of_simplest_walker(simplest):
    """Heel strike of the simplest walker: new stance rate = cos(2 theta) times the old one, the
    new swing rate = cos^2(2 theta) times it (Garcia et al. 1998, eq. 4 in absolute angles)."""
    w = Walker(simplest, planar=True)
    th, rate = 0.2, 0.3
    z_minus = np.array([0, 0, 0, 0, th, rate, -th, -0.1])
    z_plus = w.collide(z_minus)
    assert_allclose(z_plus[[4, 6]], [-th, th], atol=1e-15)
    # O(m/M) = 1e-13 corrections from the light legs; rtol 1e-8 leaves room for round-off.
    assert_allclose(z_plus[5], np.cos(2 * th) * rate, rtol=1e-8)
    assert_allclose(z_plus[7], np.cos(2 * th) ** 2 * rate, rtol=1e-8)


def test_stability_lost_at_published_slope(simplest):
    """Bisect on slope for max |eigenvalue| = 1, warm-starting each gait: 0.0150884 +/- 2e-4."""
    lo, hi = 0.0140, 0.0160
    z = find_gait(simplest.replace(slope=lo)).fixed_point
    walkers = {}

    def max_eig(slope, z_start):
        w = walkers.setdefault(slope, Walker(simplest.replace(slope=slope), planar=True))
        gait = solve_fixed_point(w, z_start)
        return gait.max_abs_eigenvalue, gait.fixed_point

    e_lo, z = max_eig(lo, z)
    e_hi, _ = max_eig(hi, z)
    assert e_lo < 1 < e_hi
    while hi - lo > 2e-5:
        mid = 0.5 * (lo + hi)
        e_mid, z_mid = max_eig(mid, z)
        if e_mid < 1:
            lo, z = mid, z_mid
        else:
            hi = mid
    assert abs(0.5 * (lo + hi) - GARCIA_BOUNDARY) < 2e-4
    # Period doubling: the critical eigenvalue is real and near -1 there.
    gait = solve_fixed_point(Walker(simplest.replace(slope=hi), planar=True), z)
    assert abs(gait.eigenvalues[0] + 1) < 0.02


def test_planar_and_3d_models_agree_on_a_planar_gait():
    """A planar-symmetric walker with real inertia: the 3D model's gait has phi = psi = 0 and the
    same fixed point, step time and in-plane eigenvalues as the planar reduction."""
    params = load_params(DATA / "params" / "compass-3d.toml").replace(
        **{"com_offset[1]": 0.0, "hip_width": 0.0})
    planar = find_gait(params, planar=True)
    full = solve_fixed_point(Walker(params), planar.fixed_point)
    assert_allclose(full.fixed_point, planar.fixed_point, atol=1e-10)
    assert abs(full.step_time - planar.step_time) < 1e-10
    in_plane = [e for e in planar.eigenvalues if abs(e) > 1e-9]
    for e in in_plane:
        assert np.min(np.abs(full.eigenvalues - e)) < 1e-8


def test_compass_3d_gait():
    params = load_params(DATA / "params" / "compass-3d.toml")
    gait = find_gait(params)
    assert not gait.planar
    assert gait.residual < 1e-10
    assert gait.lean_amplitude > 1e-3  # genuinely 3D: the lateral offset makes it lean
    # One eigenvalue is zero: the post-collision state lies on the guard surface.
    assert np.min(np.abs(gait.eigenvalues)) < 1e-8
    summary = gait.summary()
    for key in ("step_time", "stride_length", "fixed_point", "eigenvalues", "max_abs_eigenvalue"):
        assert key in summary
    assert summary["stride_length"] > 0


@pytest.mark.parametrize("name, max_abs", [("stable-toy", 0.967116), ("seed-pointfoot", 1.081824)])
def test_find_gait_from_scratch_reaches_the_shipped_gaits(name, max_abs):
    """Heavy-legged walkers: the simplest walker's starts do not continue to their 3D gait; the
    wider grid of planar starts does, and lands on the gait documented in docs/gaits.md."""
    gait = find_gait(load_params(DATA / "params" / f"{name}.toml"))
    assert abs(gait.max_abs_eigenvalue - max_abs) < 1e-5  # six digits as documented
    if name == "stable-toy":
        assert gait.stable


def test_a_search_from_nothing_is_kept_and_each_caller_owns_its_copy(monkeypatch):
    """find_gait without a guess is deterministic, so a second call for the same walker is served
    from the first (a diagnosis starts every candidate's and fold's fit from the same walker):
    no step is integrated, the gait is equal to the digit, and changing the one returned does not
    change the next. Another walker, or a guess, is searched again."""
    import toywalk.model.gait as gait_module

    params = load_params(DATA / "params" / "compass-3d.toml")
    gait_module._found.cache_clear()
    first = find_gait(params)
    solved = []
    real = gait_module.solve_fixed_point
    monkeypatch.setattr(gait_module, "solve_fixed_point", lambda *a, **k: solved.append(1) or real(*a, **k))
    found = first.fixed_point.copy()
    first.fixed_point[:] = 0.0  # the caller's own copy
    again = find_gait(params)
    assert solved == []
    assert np.array_equal(again.fixed_point, found) and again.step_time == first.step_time
    find_gait(params.replace(slope=1.01 * params.slope))
    assert solved, "another walker is searched"
    solved.clear()
    find_gait(params, z_guess=again.fixed_point)
    assert solved, "a guess is followed, not looked up"


def test_chord_steps_from_a_neighbours_jacobian_reach_newtons_gait(monkeypatch):
    """A posterior's next draw is a walker near one already solved: chord steps holding the
    neighbour's map Jacobian (each one map evaluation without derivatives) reach the gait Newton
    reaches, to round-off, and derivatives are evaluated once, for the gait's eigenvalues. A
    held Jacobian that does not contract (zero: plain fixed-point iteration, which this gait's
    eigenvalues near 1 make crawl) hands over to Newton, which still gets there."""
    params = load_params(DATA / "params" / "compass-3d.toml")
    near = find_gait(params)
    walker = Walker(params.replace(slope=1.01 * params.slope))
    newton = solve_fixed_point(walker, near.fixed_point)
    derivatives = []
    real = Walker.cycle
    monkeypatch.setattr(Walker, "cycle", lambda self, z, jacobian=False, **k:
                        derivatives.append(jacobian) or real(self, z, jacobian, **k))
    chord = solve_fixed_point(walker, near.fixed_point, jacobian=near.map_jacobian)
    # both converged to the 1e-11 tolerance and polished: they agree far below it
    assert_allclose(chord.fixed_point, newton.fixed_point, rtol=0, atol=1e-12)
    assert_allclose(chord.eigenvalues, newton.eigenvalues, rtol=0, atol=1e-9)
    assert sum(derivatives) == 1 and len(derivatives) <= 14  # measured: 1 of 10 (8 chord steps)
    assert chord.iterations == len(derivatives) - 2  # the start's evaluation and the gait's
    derivatives.clear()
    stalled = solve_fixed_point(walker, near.fixed_point, jacobian=np.zeros((8, 8)))
    assert_allclose(stalled.fixed_point, newton.fixed_point, rtol=0, atol=1e-12)
    assert sum(derivatives) >= 2  # Newton took over
    for bad in (np.eye(4), np.full((8, 8), np.nan)):
        with pytest.raises(ValueError, match="finite .8, 8. map Jacobian"):
            solve_fixed_point(walker, near.fixed_point, jacobian=bad)
