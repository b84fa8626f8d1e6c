"""Multi-start fits: starts carried over from the shipped parameter sets, agreement on a walk with
one optimum, the verdict on distinct optima, and the command line."""

import json
import math
import shutil
from types import SimpleNamespace

import pytest
from numpy.testing import assert_allclose
from toywalk.model.parameters import load_params
from toywalk.sysid.fit import fit
from toywalk.sysid.multistart import DISTINCT_CHI2, DISTINCT_SE, carried_over, multi_start, shipped_starts
from toywalk.sysid.multistart import _optima as optima_of

from ..conftest import DATA
from .builders import simulated_walk
from .command import run

FREE = ["foot_radius", "com_offset[1]"]
# A smaller mesh than the fit's default (30): the starts are compared with one another, not with a
# simulation, and 20 intervals of degree 4 still solve the stable toy's gait far below the noise.
MESH = 20


@pytest.fixture(scope="module")
def toy():
    return load_params(DATA / "params" / "stable-toy.toml")


@pytest.fixture(scope="module")
def walk(toy):
    """7 steps of the stable toy with 0.002 rad noise (about what the tracker measures)."""
    table, _ = simulated_walk(toy, 7, 0.002, 3)
    return table


def test_shipped_sets_carry_over_in_dimensionless_form(toy):
    compass = load_params(DATA / "params" / "compass-3d.toml")
    free = [*FREE, "inertia[0]", "leg_mass", "slope", "effects.hip_damping", "gravity"]
    by_name = {s.source: s for s in shipped_starts(toy, free)}
    assert set(by_name) == {p.stem for p in (DATA / "params").glob("*.toml")}
    # By hand: the compass walker has 0.5 m legs and 2.5 kg in all; the toy 0.15 m and
    # 2 * 0.05 + 4.086e-5 kg (the files' values).
    length, mass = 0.15 / 0.5, (2 * 0.05 + 4.086e-5) / 2.5
    start = by_name["compass-3d"]
    expected = {"foot_radius": 0.1 * length, "com_offset[1]": 0.02 * length,
                "inertia[0]": 0.02 * mass * length**2, "leg_mass": 1.0 * mass, "slope": 0.03,
                "effects.hip_damping": 0.0, "gravity": toy.gravity}
    # Both sides are products of the files' decimals: equal to round-off.
    assert_allclose([start.values[n] for n in free], [expected[n] for n in free], rtol=1e-12)
    assert any("gravity has no dimensionless form" in note for note in start.notes)
    # A damping coefficient (N m s/rad) scales with m l^2 / sqrt(l / g); both walkers have g = 9.81.
    values, _ = carried_over(toy, compass.replace(**{"effects.hip_damping": 0.01}),
                             ["effects.hip_damping"])
    assert_allclose(values["effects.hip_damping"], 0.01 * mass * length**1.5, rtol=1e-12)
    # The point-foot seed's radius 0 is below the toy's sideways radius, which bounds it.
    seed = by_name["seed-pointfoot"]
    assert seed.values["foot_radius"] == toy.foot_lateral_radius
    assert any("clipped" in note for note in seed.notes)
    # The toy's own file carries over unchanged (the same walker: both ratios are 1).
    assert_allclose(by_name["stable-toy"].values["com_offset[1]"], toy.com_offset[1], rtol=1e-15)


def test_starts_that_reach_one_optimum_agree(toy, walk):
    """From 10 % off, from a start with 2.6 times the foot radius and half the lateral mass
    offset (the toy-sized walker's values) and from a copy of the user's start the fit ends at one
    optimum; a start with no gait is reported, not fatal. The best is the single fit from the
    user's start."""
    user = toy.replace(**{"foot_radius": 1.1 * toy.foot_radius,
                          "com_offset[1]": 0.97 * toy.com_offset[1]})
    starts = {
        "far": toy.replace(**{"foot_radius": 0.03, "com_offset[1]": 0.1}),
        "copy": user,
        # A 14 cm foot radius on 15 cm legs: find_gait finds no gait there.
        "no-gait": toy.replace(**{"foot_radius": 0.14}),
    }
    result = multi_start(walk, user, FREE, starts=starts, n_intervals=MESH, check_jacobian=False)
    runs = {r["source"]: r for r in result.runs}
    assert list(runs) == ["user, copy", "far", "no-gait"]  # the copy is fitted once
    assert runs["no-gait"]["status"] == "skipped" and "no gait" in runs["no-gait"]["reason"]
    assert any("1 start(s) skipped" in note for note in result.warnings)
    assert result.agree and len(result.optima) == 1
    # Sources in the order of chi-square: which of equal fits is lowest is round-off.
    assert sorted(result.optima[0]["sources"]) == ["copy", "far", "user"]
    # The far start began hundreds of standard errors away (so agreeing is not trivial).
    far = runs["far"]
    moved = far["start"]["foot_radius"] - far["estimates"]["foot_radius"]
    assert abs(moved) > 100 * far["std"]["foot_radius"]

    single = fit(walk, user, FREE, n_intervals=MESH, check_jacobian=False)
    assert single.success
    # One optimum: IPOPT's tolerance (1e-10) and the noise model re-estimated from residuals
    # leave the estimates 1e-7 relative apart, far below 1e-3 SE; another optimum would be
    # DISTINCT_SE apart.
    for name in FREE:
        assert_allclose(result.best.estimates[name], single.estimates[name],
                        atol=1e-3 * single.std[name])
        assert_allclose(far["estimates"][name], single.estimates[name], atol=1e-3 * single.std[name])
    # The same chi-square: the far start was fitted under the user's start's noise model.
    assert_allclose([result.best.chi2, far["chi2"]], single.chi2, atol=1e-3)
    report = json.loads(json.dumps(result.to_json()))  # JSON-ready
    assert report["agree"] and sorted(report["best_from"]) == ["copy", "far", "user"]


def _runs(*specs):
    """FitResult-like runs: (source, success, chi2, foot_radius, its SE)."""
    runs, results = [], []
    for source, success, chi2, value, se in specs:
        runs.append({"source": source, "sources": [source], "success": success,
                     "status": "Solve_Succeeded" if success else "Maximum_Iterations_Exceeded",
                     "chi2": chi2, "estimates": {"foot_radius": value}, "std": {"foot_radius": se}})
        results.append(SimpleNamespace(success=success, chi2=chi2))
    return runs, results


def test_distinct_optima_are_reported_with_numbers():
    """The verdict's logic on FitResult-like runs: the stable toy's walks with two free
    parameters gave one optimum from every start tried (shipped sets, far starts), so no real
    fit here has a second one."""
    runs, results = _runs(("stable-toy", True, 812.3, 0.0116, 0.0002),
                          ("user", True, 812.9, 0.0117, 0.0002),       # 0.35 SE: the same
                          ("compass-3d", True, 1540.2, 0.0301, 0.0003),  # 51 SE, +728: distinct
                          ("toy-sized", False, 2000.0, 0.05, 0.001))     # not converged
    optima, warnings = optima_of(runs, results, ["foot_radius"])
    assert [o["sources"] for o in optima] == [["stable-toy", "user"], ["compass-3d"]]
    assert [r["optimum"] for r in runs] == [0, 0, 1, None]
    assert warnings[0] == ("starts disagree: 2 distinct optima; the best (chi2 812.3, from "
                           "stable-toy, user) and chi2 1540.2 (from compass-3d): foot_radius "
                           "0.0116 vs 0.0301")
    assert "toy-sized (Maximum_Iterations_Exceeded, chi2 2000.0)" in warnings[1]

    # Both criteria are needed. Far apart in SE at nearly equal chi-square: one optimum, with a
    # warning that the data do not separate them.
    runs, results = _runs(("a", True, 812.3, 0.0116, 0.0002),
                          ("b", True, 812.3 + 0.9 * DISTINCT_CHI2, 0.0301, 0.0003))
    optima, warnings = optima_of(runs, results, ["foot_radius"])
    assert len(optima) == 1 and "do not tell them apart" in warnings[0]
    # Far apart in chi-square, within DISTINCT_SE combined SEs: one optimum, no warning.
    se = 0.0002
    runs, results = _runs(("a", True, 812.3, 0.0116, se),
                          ("b", True, 900.0, 0.0116 + 0.9 * DISTINCT_SE * math.sqrt(2) * se, se))
    optima, warnings = optima_of(runs, results, ["foot_radius"])
    assert len(optima) == 1 and not warnings
    # ... and just past it: two.
    runs[1]["estimates"]["foot_radius"] = 0.0116 + 1.1 * DISTINCT_SE * math.sqrt(2) * se
    optima, warnings = optima_of(runs, results, ["foot_radius"])
    assert len(optima) == 2 and warnings[0].startswith("starts disagree: 2 distinct optima")


def test_fit_command_multistart(tmp_path):
    """``--multistart DIR``: one line per start, the verdict, and the runs in the fit file. Two
    sets keep it short (without DIR it is every shipped set): the toy-sized walker, and the
    stable toy's own, which is the user's start and is fitted once. ``--model auto`` adds the
    periodicity test's two fits and is not run here."""
    params = DATA / "params" / "stable-toy.toml"
    sets = tmp_path / "sets"
    sets.mkdir()
    for name in ("stable-toy", "toy-sized"):
        shutil.copy(DATA / "params" / f"{name}.toml", sets)
    walk = tmp_path / "walk.csv"
    assert run("simulate", "--params", params, "--steps", "7", "--noise", "0.002", "--seed", "5",
               "--out", walk).returncode == 0
    out = run("fit", walk, "--params", params, "--free", ",".join(FREE), "--model", "periodic",
              "--intervals", MESH, "--multistart", sets, "--out", tmp_path / "fit.json")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    for k, name in enumerate(("user, stable-toy", "toy-sized")):
        # either of IPOPT's successes (the toy-sized start, stepped from the measured strikes to
        # the model's, ends at the acceptable level: the same optimum, checked below)
        assert any(line.startswith((f"start {k + 1} ({name}): Solve_Succeeded",
                                    f"start {k + 1} ({name}): Solved_To_Acceptable_Level"))
                   for line in lines), lines
    assert "multistart (periodic): the starts agree" in out.stdout
    report = json.loads((tmp_path / "fit.json").read_text())
    block = report["multistart"]
    assert block["agree"] and len(block["runs"]) == 2 and len(block["optima"]) == 1
    assert report["success"] and report["jacobian_check"]  # the best fit is checked
    # The same optimum (a re-run from it when another start wins moves chi2 by round-off only).
    assert_allclose(report["chi2"], block["optima"][0]["chi2"], atol=1e-3)

    bad = run("fit", walk, "--params", params, "--free", "foot_radius", "--multistart",
              tmp_path / "nope", "--out", tmp_path / "bad.json")
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1
    assert "--multistart" in bad.stderr and not (tmp_path / "bad.json").exists()


@pytest.mark.slow
def test_another_start_winning_is_checked_from_its_own_optimum(toy, tmp_path, monkeypatch):
    """When a start other than the user's is best (at one optimum that is round-off: the fit
    command's test above once saw the toy-sized start win, on its walk), the best fit is fitted
    once more for its Jacobian check, continued from its own optimum. Started afresh from its
    parameters alone, that fit ran to IPOPT's 500-iteration cap. Here the toy-sized start is made
    the winner on that walk."""
    import toywalk.sysid.multistart as ms
    from toywalk.model.trajectory import read_trajectory

    def last_first(runs, results, free):
        optima, warnings = optima_of(runs, results, free)
        for o in optima:
            o["runs"] = sorted(o["runs"], key=lambda k: -k)  # the last run (toy-sized) first
        return optima, warnings

    monkeypatch.setattr(ms, "_optima", last_first)
    walk = tmp_path / "walk.csv"
    assert run("simulate", "--params", DATA / "params" / "stable-toy.toml", "--steps", "7", "--noise",
               "0.002", "--seed", "5", "--out", walk).returncode == 0
    sized = load_params(DATA / "params" / "toy-sized.toml")
    result = multi_start(read_trajectory(walk), toy, FREE, starts={"toy-sized": sized}, n_intervals=MESH,
                         model="periodic", check_jacobian=True)
    won = next(r for r in result.runs if r["source"] == "toy-sized")
    assert result.best.success, result.best.status
    assert result.best.jacobian_check  # the check was made, on the toy-sized start's optimum
    # continued from the optimum: the same fit (IPOPT's tolerance)
    assert_allclose(result.best.chi2, won["chi2"], atol=1e-3)
