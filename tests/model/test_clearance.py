"""The swing foot's clearance over its whole swing (toywalk.model.walker.SwingClearance): against a
slow reference (the height sampled point by point on a 64x finer grid), independent of the
integration grid, for gaits, continuation points and simulations, and as a constraint of the gait
search and of the design searches (docs/gaits.md section 4)."""

import dataclasses
import json
import math

import numpy as np
import pytest
from toywalk.model import (
    GaitNotFound,
    Walker,
    can_stand,
    describe_scuffs,
    find_gait,
    load_params,
    simulate,
    solve_fixed_point,
    static_margin,
)
from toywalk.model.continuation import continue_branch
from toywalk.model.optimize import clearance_constraint, gait_features, minimise_max_eigenvalue

from ..conftest import DATA
from .documented import Z_CLEARING, Z_STABLE, assert_documented


@pytest.fixture(scope="module")
def stable_gait():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return solve_fixed_point(Walker(params), np.array(Z_STABLE))


def _heights(walker, step):
    """Swing-foot height over the ramp (m) at every recorded sample, one sample at a time."""
    return np.array([walker.guard(x, step.side)[0] for x in step.states])


def test_the_stable_walker_scuffs_before_the_legs_pass(stable_gait):
    """docs/gaits.md section 4: data/params/stable-toy.toml's swing foot rises 0.47 mm off the ramp
    after lift-off, comes down into it 5.6 mm behind the stance foot (a dip to -0.017 mm, a third of
    the way through the step), then clears it by 0.168 mm as the legs pass. Against the slow
    reference: the height sampled point by point on a 64x finer grid."""
    gait = stable_gait
    swing = gait.swing_clearance
    assert swing.where == "dip" and swing.dips == 1
    assert_documented(1e3 * swing.minimum, -0.017, 1e-3, "clearance (mm)")
    assert_documented(swing.phase, 0.34, 0.01, "where in the step")
    assert_documented(1e3 * swing.ahead, -5.6, 0.1, "ahead of the stance foot (mm)")
    assert_documented(1e3 * swing.beside, 34.7, 0.1, "beside the stance foot (mm)")
    assert_documented(1e3 * swing.at_passing, 0.168, 1e-3, "as the legs pass (mm)")
    assert_documented(1e3 * swing.apex, 2.62, 0.01, "apex (mm)")
    assert gait.clearance == swing.minimum < 0 < gait.step.clearance  # below the ramp, then clear
    assert gait.step.scuffs == 1  # the dip is the scuff the step map counts
    # Reference: the height at every sample of a 64x finer grid. The solved minimum lies below every
    # sample and within the height's change over half a fine step of it: h'' is about 2.5 m/s^2 at
    # the dip (0.47 mm down and back over about 0.02 s), so 0.5 h'' (dt/2)^2 = 4.6e-9 m for the fine
    # dt = sqrt(l/g)/1024 = 1.2e-4 s; tolerance 1e-8 m.
    fine = Walker(gait.params, steps_per_time_unit=1024)
    dense = fine.step(gait.fixed_point, record=True)
    height = _heights(fine, dense)
    assert np.all(height[1:-1] >= swing.minimum - 1e-15)  # round-off of the kernels
    k = int(np.argmin(height[1:len(height) // 2])) + 1  # the dip lies in the first half
    assert height[k] - swing.minimum < 1e-8
    assert abs(dense.times[k] - swing.time) < fine.dt
    # The apex and the lift-off rate against the same samples (the rate by a one-sided difference
    # over the first fine step: error 0.5 h'' dt, h'' about 10 m/s^2 at lift-off: 6e-4 m/s).
    assert 0 <= swing.apex - height.max() < 1e-8
    assert abs((height[1] - height[0]) / dense.times[1] - swing.lift_off_rate) < 1e-3
    assert_documented(swing.lift_off_rate, 0.077, 1e-3, "lift-off rate (m/s)")


def test_swing_clearance_does_not_depend_on_the_grid(stable_gait):
    """Each extremum and the passing instant are solved on the flow, so a 16x finer integration
    grid gives the same figures to the integrator's accuracy (the step map agrees with a 4x finer
    grid to about 1e-12, model/walker.py). Measured: 8e-17 m at the dip, a third of the way
    through the step, 1.5e-13 m as the legs pass and 1.9e-12 m at the apex, late in the step,
    where the default grid's error has grown; 3.3e-12 s in time. Tolerances 1e-11 m and 1e-11 s."""
    gait = stable_gait
    coarse = gait.swing_clearance
    fine = Walker(gait.params, steps_per_time_unit=256).step(gait.fixed_point, record=True).swing
    for name in ("minimum", "at_passing", "apex", "ahead", "beside"):
        assert abs(getattr(coarse, name) - getattr(fine, name)) < 1e-11, name
    assert abs(coarse.time - fine.time) < 1e-11
    assert coarse.dips == fine.dips and coarse.where == fine.where


def test_feet_on_one_line_cannot_clear():
    """docs/model.md section 6: a walker with w = 0 runs both feet on one line. The seed's point feet
    pass through each other as the legs pass (height 0 there, to the passing instant's tolerance
    1e-10 l), so the clearance over the whole swing is at most 0."""
    params = load_params(DATA / "params" / "seed-pointfoot.toml")
    z_seed = [0.0068691677560342185, -0.05803631223443323, 4.2840513469809e-09, 0.008068837555385303,
              -0.008168480883295554, 1.2064281809023907, 0.008168480883311213, 1.0683654791509936]
    gait = solve_fixed_point(Walker(params), np.array(z_seed))
    swing = gait.swing_clearance
    assert abs(swing.at_passing) < 1e-10 * params.leg_length
    assert swing.minimum <= swing.at_passing
    assert swing.beside < 1e-10 * params.leg_length  # not beside: in line
    # said as a touch, not as a foot below the ramp (toywalk gait said "goes below" of -1.1e-14 m);
    # a dip of a millionth of a leg, far beyond round-off, is below
    assert gait.swing_foot == "touches"
    dipped = dataclasses.replace(gait, steps=[dataclasses.replace(
        s, swing=dataclasses.replace(s.swing, minimum=-1e-6 * params.leg_length)) for s in gait.steps])
    assert dipped.swing_foot == "below"


def test_every_gait_continuation_point_and_simulation_reports_it(stable_gait):
    """The clearance is a gait property (summary, features), a column of continuation tables and
    a figure of every simulation."""
    gait = stable_gait
    summary = gait.summary()
    assert summary["clearance"] == gait.clearance
    assert summary["swing_clearance"]["minimum"] == gait.clearance
    assert summary["clearance_after_passing"] == gait.step.clearance
    assert set(summary["swing_clearance"]) == {"minimum", "time", "phase", "ahead", "beside",
                                               "at_passing", "apex", "lift_off_rate", "dips", "where"}
    assert gait_features(gait)["clearance"] == gait.clearance
    # A simulation from the fixed point repeats the gait: the same clearance every step (to the
    # fixed point's residual, 1e-11 in rad and rad/s, which moves heights by far less than 1e-12 m).
    walk = simulate(gait.params, gait.fixed_point, steps=2)
    assert walk.status == "completed"
    assert abs(walk.swing_clearance - gait.clearance) < 1e-12
    # Continuation: the column holds each point's own gait's clearance. Three points in w.
    branch = continue_branch(gait.params, "hip_width", gait.params.hip_width, 0.045, max_points=3,
                             z_start=gait.fixed_point, ds=0.5, ds_max=0.5)
    cols, rows = branch.table()
    column = rows[:, cols.index("clearance")]
    assert abs(column[0] - gait.clearance) < 1e-12
    end = find_gait(gait.params.replace(hip_width=branch.points[-1].value),
                    z_guess=branch.points[-1].fixed_point)
    assert abs(column[-1] - end.clearance) < 1e-9  # Newton's tolerance moves it a little
    assert rows[:, cols.index("clearance_ahead")][0] == gait.swing_clearance.ahead
    # Wider hips lift the swing foot (docs/gaits.md section 4): the clearance grows along w.
    assert np.all(np.diff(column) > 0)


def test_the_gait_search_refuses_a_gait_that_does_not_clear(stable_gait):
    """find_gait(min_clearance=...) returns only a gait that clears by that much, and otherwise
    says which clearances it found."""
    params, z = stable_gait.params, stable_gait.fixed_point
    assert find_gait(params, z_guess=z, min_clearance=-1e-4).clearance >= -1e-4
    with pytest.raises(GaitNotFound, match=r"clears? the ramp by 0\.5 mm.*-0\.0169 mm"):
        find_gait(params, z_guess=z, min_clearance=5e-4)
    with pytest.raises(ValueError, match="min_clearance"):
        find_gait(params, z_guess=z, min_clearance=math.nan)


def test_design_search_keeps_the_clearance(stable_gait):
    """minimise_max_eigenvalue(min_clearance=...) treats a gait that clears by less as infeasible
    (its history holds inf there) and returns a walker that clears. Over w from 0.1 m, where the
    gait clears by 0.75 mm: asked for 0.7 mm, the optimiser may not go below about w = 0.095 m."""
    start = find_gait(stable_gait.params.replace(hip_width=0.1), z_guess=stable_gait.fixed_point)
    assert 0.7e-3 < start.clearance < 0.8e-3
    result = minimise_max_eigenvalue(start, ["hip_width"], {"hip_width": (0.05, 0.16)}, maxiter=12,
                                     min_clearance=0.7e-3)
    assert result.gait.clearance >= 0.7e-3
    assert result.value == result.gait.max_abs_eigenvalue
    # max |eigenvalue| falls towards narrower hips (0.934 at w = 0.1 m, 0.914 at 0.095 m) while
    # the clearance falls below 0.7 mm near w = 0.0958 m (docs/clearance_search.csv): the search
    # stops at that bound, and every point it accepted lies on the clearing side of it.
    assert 0.0955 < result.params.hip_width < 0.1
    assert result.value < start.max_abs_eigenvalue
    finite = np.isfinite(result.history[:, 1])
    assert np.all(result.history[finite, 0] > 0.0955)
    # The joined constraint: the smaller of the two margins.
    joined = clearance_constraint(1e-3, lambda p, g: 5.0)
    assert joined(start.params, start) == pytest.approx(start.clearance - 1e-3, abs=0)
    assert clearance_constraint(None, None) is None


@pytest.fixture(scope="module")
def clearing_gait():
    params = load_params(DATA / "params" / "clearing-toy.toml")
    return solve_fixed_point(Walker(params), np.array(Z_CLEARING))


def test_the_clearing_walker_cannot_stand_walks_stably_and_clears(clearing_gait):
    """Issue 13, item 2 (docs/gaits.md section 4): data/params/clearing-toy.toml cannot stand, its
    gait is stable with every step-map eigenvalue inside |lambda| = 0.86 (margin 0.14 from the
    unit circle), and its swing foot clears the ramp by 3.48 mm over the whole swing (at least
    1 mm asked), lowest as the legs pass, with no dip and no scuff."""
    gait = clearing_gait
    params = gait.params
    assert gait.swing_foot == "clears"
    assert gait.residual < 1e-10  # a gait (Newton's tolerance, model/gait.py)
    report = can_stand(params)
    assert not report.can_stand and not report.can_stand_level
    assert_documented(1e3 * static_margin(params), 26.0, 0.1, "static margin (mm)")
    moduli = np.abs(gait.eigenvalues)
    assert np.all(moduli < 0.86)
    for got, documented in zip(moduli, [0.852, 0.852, 0.851, 0.836, 0.836, 0.809, 0.809, 0.0],
                               strict=True):
        assert_documented(got, documented, 1e-3, "modulus")
    swing = gait.swing_clearance
    assert gait.clearance >= 1e-3
    assert_documented(1e3 * swing.minimum, 3.48, 0.01, "clearance (mm)")
    assert swing.where == "legs passing" and swing.dips == 0 and gait.step.scuffs == 0
    assert_documented(swing.phase, 0.49, 0.01, "where in the step")
    assert_documented(1e3 * swing.beside, 106.6, 0.1, "beside the stance foot (mm)")
    assert_documented(1e3 * swing.apex, 4.28, 0.01, "apex (mm)")
    assert_documented(swing.lift_off_rate, 0.150, 1e-3, "lift-off rate (m/s)")
    assert_documented(gait.step_time, 0.184, 1e-3, "step time (s)")
    assert_documented(1e3 * gait.stride_length, 81.2, 0.1, "stride (mm)")
    assert_documented(math.degrees(gait.lean_amplitude), 1.92, 0.01, "lean (deg)")
    assert_documented(math.degrees(gait.steer_amplitude), 4.0, 0.1, "steer (deg)")
    # Lean lifts the swing foot: the legs pass when their pitches are equal (both feet share the
    # axle direction n, so C2 - C = -w n, which has no component along the heading), and then the
    # swing foot's height is -w sin(psi). The state there, by the integrator from the last sample.
    walker = Walker(params)
    step = walker.step(gait.fixed_point, record=True)
    i = int(np.searchsorted(step.times, swing.time)) - 1
    x = walker.eng.k["step"](step.states[i], swing.time - step.times[i], walker.p)[0].ravel()
    psi, pitch_st, pitch_sw = x[1], x[2], x[3]
    assert math.degrees(psi) < -1.8  # leaning onto the stance foot (measured -1.87 degrees)
    # Pitches equal to the passing instant's tolerance (1e-10 l of distance ahead, over a lever of
    # about l): 1e-9 rad (measured 3.9e-12); the height then to 1e-12 m (measured 2.9e-14).
    assert abs(pitch_st - pitch_sw) < 1e-9
    assert abs(swing.minimum + params.hip_width * math.sin(psi)) < 1e-12


def test_find_gait_starts_from_the_files_stored_start(clearing_gait, stable_gait):
    """The search from the planar reduction does not reach the clearing gait (its homotopy folds
    back at 32 % of the way: docs/gaits.md section 4), so data/params/clearing-toy.toml stores a
    start near it (Params.gait_start, rounded to 4 digits); find_gait converges from it to the
    same gait, to Newton's tolerance (1e-10, model/gait.py; 1e-9 on the state). A stored start
    that does not converge (a walker standing still) falls back to the usual search."""
    import dataclasses

    params = load_params(DATA / "params" / "clearing-toy.toml")
    assert params.gait_start is not None and params.gait_start != tuple(Z_CLEARING)
    gait = find_gait(params)
    np.testing.assert_allclose(gait.fixed_point, clearing_gait.fixed_point, rtol=0, atol=1e-9)
    stable = dataclasses.replace(stable_gait.params, gait_start=(0.0,) * 8)
    np.testing.assert_allclose(find_gait(stable).fixed_point, stable_gait.fixed_point, rtol=0,
                               atol=1e-9)


def test_the_clearing_gait_lies_near_a_fold(clearing_gait):
    """docs/gaits.md section 4: the stable gait's branch turns back at d_y = 0.1797 m, 3 % below
    the file's 0.1855 m, into the unstable partner gait (step 0.162 s, max |lambda| 1.84) that
    find_gait's continuation from the planar reduction reaches when it raises d_y first."""
    params = clearing_gait.params
    branch = continue_branch(params, "com_offset[1]", params.com_offset[1], 0.0, max_points=20,
                             z_start=clearing_gait.fixed_point)
    folds = [e for e in branch.events if e.kind == "fold"]
    assert branch.status == "turned back" and len(folds) == 1
    assert_documented(folds[0].value, 0.1797, 1e-4, "fold (m)")
    partner = branch.points[-1]
    assert_documented(partner.step_time, 0.162, 1e-3, "partner's step time (s)")
    assert partner.max_abs_eigenvalue > 1.5


def test_toywalk_gait_reports_it(capfd):
    """`toywalk gait` prints the clearance over the whole swing and where it occurs, and its JSON
    carries it beside the keys other tools read (docs/cli.md). The simplest walker's point foot
    dips 0.064 mm into the ramp 14 mm behind the stance foot (its feet pass through each other,
    w = 0)."""
    from toywalk.sysid.cli import main

    params = DATA / "params" / "simplest-walker.toml"
    assert main(["gait", "--params", str(params), "--json"]) == 0
    report = json.loads(capfd.readouterr().out)
    for key in ("step_time", "stride_length", "fixed_point", "eigenvalues", "max_abs_eigenvalue",
                "can_stand", "status"):  # docs/cli.md, `toywalk gait`
        assert key in report
    swing = report["swing_clearance"]
    assert report["clearance"] == swing["minimum"] < 0 and swing["where"] == "dip"
    assert_documented(1e3 * swing["minimum"], -0.064, 1e-3, "clearance (l = 1 m; mm)")
    assert_documented(1e3 * swing["ahead"], -13.9, 0.1, "ahead (mm)")
    assert main(["gait", "--params", str(params)]) == 0
    text = capfd.readouterr().out
    assert ("the swing foot goes 0.0638 mm below the ramp at its lowest (48 % into the step, 13.9 mm "
            "behind the stance foot); after the legs pass it touches the ramp (0 mm to round-off)") in text
    # the scuff it makes before the legs pass, in the words every command uses
    assert f"scuffs            {describe_scuffs(1, 1, swing['minimum'])}\n" in text


def test_scuffs_are_said_in_one_sentence():
    """describe_scuffs: the count over the steps, the depth in mm where the foot goes below the
    ramp beyond round-off, nothing for no scuffs, and counts that are not counts refused."""
    assert describe_scuffs(0, 16, -0.000536) == ""
    assert describe_scuffs(16, 16, -0.000536) == (
        "the swing foot scuffs the ramp before the legs pass, 16 times in 16 steps, down to 0.536 mm "
        "below it (the model lets it through)")
    assert "once a step, down to 0.0638 mm below it" in describe_scuffs(1, 1, -6.38e-5)
    assert "twice in 2 steps (the model" in describe_scuffs(2, 2)
    # within the resolution of 0 (the seed's feet pass at -1.1e-14 m): no depth
    assert "below it" not in describe_scuffs(1, 1, -1.1e-14, resolution=1e-9)
    for scuffs, steps in ((-1, 1), (1, 0), (1.5, 2), (True, 1)):
        with pytest.raises(ValueError, match="must be a count"):
            describe_scuffs(scuffs, steps)
