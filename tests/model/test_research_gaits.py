"""The project's research gaits (docs/gaits.md, docs/tinkertoy.md): the seed's point-foot case and
its heading eigenvalue against slope, a stable gait of a walker that cannot stand, the Tinkertoy
fit's gait; checked by their eigenvalues, by forward simulation, by a finer integration grid and by
the numbers the documents quote.

A documented number is quoted to some digits; ``assert_documented`` (tests/model/documented.py)
checks that the model, run as the documents say (default integration grid), rounds to it: the
tolerance is half a unit of the last quoted digit.
"""

import math

import numpy as np
import pytest
from toywalk.model import Walker, can_stand, find_gait, load_params, solve_fixed_point, static_margin
from toywalk.model.optimize import heading_eigenvalue

from ..conftest import DATA
from .documented import Z_STABLE, assert_documented

# The seed's fixed point (public state order) found when its file was made (docs/gaits.md); Newton
# polishes it, so it only needs to be near the gait. The stable toy's is in tests/model/documented.py.
Z_SEED = [0.0068691677560342185, -0.05803631223443323, 4.2840513469809e-09, 0.008068837555385303,
          -0.008168480883295554, 1.2064281809023907, 0.008168480883311213, 1.0683654791509936]
# The Tinkertoy fit's gait, reached by docs/make_tinkertoy.py's route (continuation from the
# toy-like start walker). It lies 1e-9 rad of slope from a fold (docs/effects_study.md), next to a
# partner gait, which test_tinkertoy_fit_gait tells apart.
Z_TINKERTOY = [0.06588800838779761, 0.2818328806369188, 0.0048322317613100395, 0.02147970186186541,
               -0.08849678845360837, 2.8939041328234243, 0.08982578011390356, 3.8088698420881335]
# The fixed point as docs/tinkertoy.md quotes it (six significant digits).
TINKERTOY_FIXED_POINT_DOC = [0.065888, 0.281833, 0.00483223, 0.0214797, -0.0884968, 2.8939, 0.0898258,
                             3.80887]
# The toy's measurements and the misfit the fit tolerated (Coleman & Ruina 1998, PRL 80:3658;
# docs/model.md section 7; docs/make_tinkertoy.py): value, scale.
TOY_MEASURED = {"stride_time": (0.47, 0.01), "stride_length": (0.013, 0.001),
                "lean_amplitude": (math.radians(4.0), math.radians(0.5))}


def _phi_eigenvalues(gait):
    """Step-map eigenvalues whose eigenvectors are mostly steer (docs/make_seed_case.py), nearest
    to -1 first."""
    out = [e for k, e in enumerate(gait.eigenvalues) if dict(gait.dominant_components(k, n=8))["phi"] > 0.5]
    return sorted(out, key=lambda e: abs(e + 1))


def _swing_heights(walker, step):
    """Swing-foot height over the ramp and its distance ahead of the stance contact (m) at every
    recorded sample of ``step``, one sample at a time."""
    return np.array([walker.guard(x, step.side) for x in step.states]).T


@pytest.fixture(scope="module")
def stable_gait():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return solve_fixed_point(Walker(params), np.array(Z_STABLE))


@pytest.fixture(scope="module")
def seed_gait():
    params = load_params(DATA / "params" / "seed-pointfoot.toml")
    return solve_fixed_point(Walker(params), np.array(Z_SEED))


# ----------------------------------------------------------------------------- 1. the seed's case
def test_seed_pointfoot_case(seed_gait):
    """Coleman & Ruina 1998: stride-map max |eigenvalue| about 1.15, lean-dominated unstable mode;
    and the figures docs/gaits.md section 1 quotes."""
    gait = seed_gait
    params = gait.params
    assert params.foot_radius == params.foot_lateral_radius == params.hip_width == 0.0
    stride_max = gait.max_abs_eigenvalue**2
    assert 1.1 < stride_max < 1.25  # "about 1.15" (seed); ours is 1.17
    shares = dict(gait.dominant_components(0, n=8))
    assert shares["psi"] + shares["psi_dot"] > 0.6  # lean dominates the unstable mode
    # Heading: on this shallow slope (0.002 rad) a pair of step-map eigenvalues sits within 1e-3 of
    # -1 (stride map: within 2e-3 of +1), not exactly at it (docs/model.md section 4).
    heading, phi_share = heading_eigenvalue(gait)
    assert phi_share > 0.9
    assert 1e-6 < abs(heading + 1) < 1e-3
    # The other eigenvalues are inside the unit circle (up to the heading pair at 0.9999).
    assert np.sum(np.abs(gait.eigenvalues) > 1.0) == 1
    # docs/gaits.md section 1, to the digits quoted there.
    assert_documented(gait.step_time, 0.048, 1e-3, "step time (s)")
    assert_documented(gait.step_time / params.time_scale, 0.15, 0.01, "step time (sqrt(l/g))")
    assert_documented(100 * gait.stride_length, 3.3, 0.1, "stride (cm)")
    # Amplitudes are maxima over the integration grid's samples, here four a step: the digits
    # quoted are those a 64x finer grid confirms (0.0038 and 0.397 degrees there).
    assert_documented(math.degrees(gait.lean_amplitude), 0.004, 0.001, "lean (deg)")
    assert_documented(math.degrees(gait.steer_amplitude), 0.4, 0.1, "steer (deg)")
    assert_documented(stride_max, 1.170, 1e-3, "stride-map max |eigenvalue|")
    assert_documented(gait.eigenvalues[0].real, -1.0818, 1e-4, "step-map eigenvalue")
    assert_documented(shares["psi"] + shares["psi_dot"], 0.76, 0.01, "lean share")
    assert_documented(shares["psi"], 0.50, 0.01, "psi share")
    assert_documented(shares["psi_dot"], 0.26, 0.01, "psi_dot share")
    stride_moduli = np.abs(gait.eigenvalues[1:]) ** 2
    for got, documented, unit in zip(stride_moduli, [0.9998, 0.9998, 0.980, 0.854, 0.484, 0.034, 0.0],
                                     [1e-4, 1e-4, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3], strict=True):
        assert_documented(got, documented, unit, "stride-map modulus")
    assert_documented(abs(heading) ** 2, 0.99984, 1e-5, "heading (stride map)")
    # Point feet, w = 0: the swing foot passes through the stance foot's contact point, so it
    # scuffs once and its clearance is zero (up to the passing instant's tolerance, 1e-10 of l).
    assert gait.step.scuffs == 1
    assert abs(gait.step.clearance) < 1e-10 * params.leg_length


# Rows of docs/gaits.md's heading table: slope, the two phi eigenvalues (step map) as quoted, the
# unit of their last digit, and their quoted distances from -1 with the unit of those.
HEADING_TABLE = [
    (2e-5, [-0.99999982, -0.99999284], 1e-8, [1.8e-7, 7.2e-6], [1e-8, 1e-7]),
    (1e-4, [-0.99999843, -0.99998006], 1e-8, [1.6e-6, 2.0e-5], [1e-7, 1e-6]),
    (5e-4, [-0.99998540, -0.99995138], 1e-8, [1.5e-5, 4.9e-5], [1e-6, 1e-6]),
    (0.002, [-0.99992 + 0.00005j, -0.99992 - 0.00005j], 1e-5, [9.6e-5, 9.6e-5], [1e-6, 1e-6]),
    (0.016, [-0.99967 + 0.0004j, -0.99967 - 0.0004j], 1e-5, [5e-4, 5e-4], [1e-4, 1e-4]),
]
# The seed's gait at those slopes (and at 0.001), on the branch docs/make_seed_case.py follows from
# the file's slope (GaitEvaluator, warm-started); 10 digits, which Newton polishes in 2-3 iterations.
Z_SEED_AT_SLOPE = {
    2e-5: [0.001501278798, -0.0007240137321, -4.637688485e-12, 0.0004915231227, -0.001785022817,
           0.3280257754, 0.001785022818, 0.3263040502],
    1e-4: [0.002563058401, -0.003372479638, 8.347866916e-11, 0.001400428077, -0.003047510696,
           0.5485809615, 0.003047510699, 0.5405608289],
    5e-4: [0.004362671797, -0.01585255872, 9.077855156e-10, 0.003797163102, -0.005187438097,
           0.8794486763, 0.005187438097, 0.8417456849],
    0.001: [0.005477189058, -0.0305385365, 2.100203898e-09, 0.005640882038, -0.006512856493,
            1.046900549, 0.006512856493, 0.9742625889],
    0.016: [0.01371646394, -0.3530378126, 6.108425585e-07, 0.01197063336, -0.01632102638,
            1.067485691, 0.01632102638, 0.226686117],
}


def test_heading_eigenvalue_against_slope(seed_gait):
    """docs/gaits.md's heading table: the seed's gait on a range of slopes, its two phi eigenvalues
    near -1 but not at it, real at small slopes and a complex pair above about 0.001 rad, both
    inside the unit circle. The table quotes the digits that a 4x finer integration grid confirms
    (the seed's steps span under three grid steps: at 0.016 the finer grid moves the pair by
    1.6e-5)."""
    gaits = {slope: solve_fixed_point(Walker(seed_gait.params.replace(slope=slope)), np.array(z))
             for slope, z in Z_SEED_AT_SLOPE.items()}
    gaits[0.002] = seed_gait
    for slope, documented, unit, distances, dist_units in HEADING_TABLE:
        fine = solve_fixed_point(Walker(gaits[slope].params, steps_per_time_unit=64),
                                 gaits[slope].fixed_point)
        for gait in (gaits[slope], fine):
            eigs = _phi_eigenvalues(gait)
            assert len(eigs) == 2, slope
            if np.iscomplexobj(documented[0]):  # a complex pair: the upper one first
                eigs = sorted(eigs, key=lambda e: -e.imag)
            for got, doc, dist, dist_unit in zip(eigs, documented, distances, dist_units, strict=True):
                imag_unit = 10 ** math.floor(math.log10(abs(doc.imag))) if doc.imag else unit
                assert_documented(got.real, doc.real, unit, f"slope {slope}: real part")
                assert_documented(got.imag, np.imag(doc), imag_unit, f"slope {slope}: imaginary part")
                assert_documented(abs(got + 1), dist, dist_unit, f"slope {slope}: distance from -1")
                assert abs(got) < 1  # the heading relaxes towards downhill
    # The pair is real at 5e-4 and complex at 0.001: it merges in between.
    assert all(e.imag == 0 for e in _phi_eigenvalues(gaits[5e-4]))
    assert all(abs(e.imag) > 1e-6 for e in _phi_eigenvalues(gaits[0.001]))


def test_toy_like_walker_heading_and_branch(toy_params):
    """docs/gaits.md: the toy-like walker of tests/conftest.py at 4.5 degrees (find_gait's gait,
    by continuation from its planar reduction) has step time 0.373 s and max |lambda| 6.02, and its
    phi eigenvalues are a split real pair, -1.016 and -0.861: its heading diverges from downhill."""
    gait = find_gait(toy_params)
    assert_documented(gait.step_time, 0.373, 1e-3, "step time (s)")
    assert_documented(gait.max_abs_eigenvalue, 6.02, 0.01, "max |eigenvalue|")
    eigs = sorted(_phi_eigenvalues(gait), key=lambda e: e.real)
    assert len(eigs) == 2 and all(e.imag == 0 for e in eigs)
    assert_documented(eigs[0].real, -1.016, 1e-3, "phi eigenvalue")
    assert_documented(eigs[1].real, -0.861, 1e-3, "phi eigenvalue")


# ------------------------------------------------------------ 2. the walker that cannot stand
def test_stable_gait_of_a_walker_that_cannot_stand(stable_gait):
    """docs/gaits.md section 2: no standing configuration is stable, on the ramp or on level
    ground; the margin, the closest configuration and how fast it falls."""
    params = stable_gait.params
    report = can_stand(params)
    assert not report.can_stand
    assert not report.can_stand_level
    assert_documented(1e3 * static_margin(params), 18.3, 0.1, "static margin (mm)")
    # Upright centre-of-mass height of static_margin: l + 2 m d_z / (2 m + M_h).
    upright = params.leg_length + 2 * params.leg_mass * params.com_offset[2] / params.total_mass
    assert_documented(1e3 * upright, 27.2, 0.1, "upright centre of mass (mm)")
    splayed = report.configuration("two feet, splayed legs")
    assert splayed.status == "unstable" and splayed.mode == "sideways (lean)"
    assert_documented(1.0 / splayed.growth_rate, 0.46, 0.01, "e-folding time (s)")
    assert_documented(1e3 * splayed.com_height, 26.4, 0.1, "splayed centre of mass (mm)")
    # The slowest-falling configuration is the one the report names.
    ramp = [c for c in report.configurations if not c.level]
    assert min(ramp, key=lambda c: c.growth_rate) is splayed
    parallel = report.configuration("two feet, parallel legs")
    assert parallel.status == "unstable" and "pitch" in parallel.mode  # falls fore-aft...
    assert params.foot_radius < parallel.com_height  # ... with r below the centre of mass
    assert stable_gait.max_abs_eigenvalue < 0.98  # 0.967 when the file was made


def test_stable_gait_figures(stable_gait):
    """docs/gaits.md section 2: the gait's step time, stride, lean and steer, and its step-map
    eigenvalues by modulus with the heading mode's share of the dominant pair."""
    gait = stable_gait
    assert gait.residual < 1e-10  # a gait (Newton's tolerance, model/gait.py)
    assert_documented(gait.step_time, 0.107, 1e-3, "step time (s)")
    assert_documented(100 * gait.stride_length, 4.7, 0.1, "stride (cm)")
    assert_documented(math.degrees(gait.lean_amplitude), 0.30, 0.01, "lean (deg)")
    assert_documented(math.degrees(gait.steer_amplitude), 2.7, 0.1, "steer (deg)")
    eigs = gait.eigenvalues
    assert np.all(np.abs(eigs) < 1)
    for got, documented in zip(np.abs(eigs), [0.967, 0.967, 0.939, 0.939, 0.611, 0.611, 0.344, 0.0],
                               strict=True):
        assert_documented(got, documented, 1e-3, "modulus")
    assert eigs[0].imag != 0 and eigs[2].imag != 0 and eigs[4].imag != 0  # three complex pairs
    assert_documented(eigs[0].real, -0.961, 1e-3, "dominant pair, real part")
    assert_documented(abs(eigs[0].imag), 0.111, 1e-3, "dominant pair, imaginary part")
    names = [name for name, _ in gait.dominant_components(0, n=3)]
    assert names == ["theta_sw_dot", "phi", "theta_st_dot"]  # swing rate, phi and stance rate
    heading, phi_share = heading_eigenvalue(gait)
    assert heading in (eigs[0], eigs[1])  # the heading mode is merged into the dominant pair
    assert_documented(phi_share, 0.23, 0.01, "phi share")


def test_stable_gait_scuffs_once_then_clears(stable_gait):
    """docs/gaits.md section 2: the swing foot scuffs once per step while the legs pass, and
    clears the ramp by 0.168 mm after they have passed. Against a slow reference: the swing foot's
    height sampled one point at a time on a 64x finer grid."""
    gait = stable_gait
    step = gait.step
    assert step.scuffs == 1
    assert_documented(1e3 * step.clearance, 0.168, 1e-3, "clearance (mm)")
    fine = Walker(gait.params, steps_per_time_unit=1024)
    dense = fine.step(gait.fixed_point, record=True)
    height, ahead = _swing_heights(fine, dense)
    passed = int(np.argmax(ahead > 0))  # first sample after the legs pass
    before = height[:passed]
    downward = np.flatnonzero((before[1:] <= 0) & (before[:-1] > 0))
    assert len(downward) == 1 and dense.scuffs == 1  # one scuff, the same on both grids
    # The legs pass between two fine samples: the height at that instant lies between theirs
    # (0.162 and 0.168 mm), and no later sample before the swing foot's highest point is lower.
    apex = passed + int(np.argmax(height[passed:]))
    assert min(height[passed - 1], height[passed]) <= step.clearance <= max(height[passed - 1],
                                                                            height[passed])
    assert np.min(height[passed:apex + 1]) >= step.clearance
    # Grid independence: the passing instant is solved on the flow, so the 64x finer grid gives
    # the same clearance to the integrator's accuracy (measured 1.4e-13 m; 1e-10 m = _PASS_TOL * l).
    assert abs(dense.clearance - step.clearance) < 1e-10


def test_perturbation_decays_at_predicted_rate(stable_gait):
    """A small perturbation along the dominant eigenvector (its real part, a complex pair) decays
    like |lambda_max|^n over 30 forward-simulated steps: its coordinate in the eigenbasis shrinks
    by |lambda_max|^30 = 0.37."""
    walker = Walker(stable_gait.params)
    vecs = stable_gait.eigenvectors
    lam = stable_gait.eigenvalues[0]
    v = np.real(vecs[:, 0])
    eps = 1e-5  # small enough that nonlinear terms (O(eps) relative) stay below the tolerance
    z = stable_gait.fixed_point + eps * v / np.linalg.norm(v)
    coords0 = np.linalg.solve(vecs, z - stable_gait.fixed_point)
    n = 30
    for _ in range(n):
        z = walker.step(z).z_plus
    coords = np.linalg.solve(vecs, z - stable_gait.fixed_point)
    ratio = abs(coords[0]) / abs(coords0[0])
    # rtol 1e-4: the nonlinear terms are O(eps) = 1e-5 relative (measured: 3e-7 when written).
    np.testing.assert_allclose(ratio, abs(lam) ** n, rtol=1e-4)
    assert_documented(ratio, 0.366736, 1e-6, "decay over 30 steps")
    assert_documented(abs(lam) ** n, 0.366736, 1e-6, "|lambda_max|^30")
    assert np.linalg.norm(z - stable_gait.fixed_point) < eps  # and the state itself came back


# ------------------------------------------------------------------------ 3. the Tinkertoy fit
def test_tinkertoy_fit_gait():
    """docs/gaits.md section 3 and docs/tinkertoy.md: the fitted walker's gait, where it misses
    the toy, that it is unstable, and that the walker cannot stand."""
    params = load_params(DATA / "params" / "tinkertoy.toml")
    gait = solve_fixed_point(Walker(params), np.array(Z_TINKERTOY))
    moduli = np.abs(gait.eigenvalues)
    # The fit's gait, not its partner across the fold: there the eigenvalue near 1 is above 1.
    assert moduli[2] < 1
    for got, documented in zip(gait.fixed_point, TINKERTOY_FIXED_POINT_DOC, strict=True):
        assert_documented(got, documented, 10.0 ** (math.floor(math.log10(abs(documented))) - 5),
                          "fixed point (six digits)")
    assert_documented(gait.stride_time, 0.732, 1e-3, "stride time (s)")
    assert_documented(gait.step_time, 0.3658, 1e-4, "step time (s)")
    assert_documented(100 * gait.stride_length, 5.29, 0.01, "advance per stride (cm)")
    assert_documented(math.degrees(gait.lean_amplitude), 1.16, 0.01, "tilt (deg)")
    assert_documented(math.degrees(gait.steer_amplitude), 7.95, 0.01, "steer (deg)")
    features = {"stride_time": gait.stride_time, "stride_length": gait.stride_length,
                "lean_amplitude": gait.lean_amplitude}
    for key, (measured, scale) in TOY_MEASURED.items():
        assert abs(features[key] - measured) > 2 * scale, key  # "more than twice the tolerance"
    for got, documented in zip(moduli, [4.383, 4.383, 1.000, 0.988, 0.988, 0.170, 0.073, 0.000],
                               strict=True):
        assert_documented(got, documented, 1e-3, "modulus")
    assert not gait.stable
    assert [name for name, _ in gait.dominant_components(0)] == ["theta_st", "theta_sw"]  # pitch
    heading, _ = heading_eigenvalue(gait)
    assert_documented(heading.real, -0.9818, 1e-4, "heading eigenvalue, real part")
    assert_documented(heading.imag, 0.1123, 1e-4, "heading eigenvalue, imaginary part")
    assert gait.step.scuffs == 0
    assert_documented(1e3 * gait.step.clearance, 0.037, 1e-3, "clearance (mm)")
    assert_documented(1e3 * static_margin(params), 40.2, 0.1, "static margin (mm)")
    report = can_stand(params)
    assert not report.can_stand
    splayed = report.configuration("two feet, splayed legs")
    assert splayed.mode == "sideways (lean)"
    assert_documented(1.0 / splayed.growth_rate, 0.212, 1e-3, "e-folding time (s)")
    assert_documented(1e3 * splayed.com_height, 44.5, 0.1, "centre of mass (mm)")
    assert_documented(1e3 * splayed.margin, 39.5, 0.1, "above the lateral centre (mm)")


def test_tinkertoy_gait_is_at_a_fold_and_says_which_slopes_keep_it():
    """docs/effects_study.md: the fit's gait sits on the fold of its branch (a real eigenvalue
    0.99978 = 1 - 2.2e-4), existing on steeper slopes only, so that any effect that costs it
    energy loses it; a user asking for one is told so. stable-toy's gait is nowhere near a fold."""
    from toywalk.model.gait import NEAR_FOLD, _fold_note

    gait = solve_fixed_point(Walker(load_params(DATA / "params" / "tinkertoy.toml")), np.array(Z_TINKERTOY))
    assert_documented(gait.fold_eigenvalue, 0.99978, 1e-5, "eigenvalue near 1")
    assert gait.summary()["fold_eigenvalue"] == gait.fold_eigenvalue
    note = _fold_note(gait, 16)
    # the side is solved, not assumed: on a ramp 0.1 % steeper the gait exists, 0.1 % shallower not
    assert "exists on a ramp 0.1 % steeper but not on one 0.1 % shallower" in note, note
    assert "try a steeper slope" in note and "0.999779" in note
    stable = find_gait(load_params(DATA / "params" / "stable-toy.toml"))
    assert np.min(np.abs(stable.eigenvalues - 1.0)) > 100 * NEAR_FOLD  # 0.75 (docs/gaits.md)
    assert stable.fold_eigenvalue is None and _fold_note(stable, 16) == ""
