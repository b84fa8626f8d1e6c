"""Several walks of one walker fitted together (toywalk.sysid.walks): one walk is the single fit,
a walk counted twice halves the variance, and three walks under known changes tell apart causes
that one walk leaves tied."""

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.gait import GaitNotFound
from toywalk.model.parameters import load_params, save_params
from toywalk.model.trajectory import TrajectoryTable, write_trajectory
from toywalk.sysid import walks as walks_module
from toywalk.sysid.fit import FitError, fit
from toywalk.sysid.naming import SEPARATION
from toywalk.sysid.walks import diagnose_walks, fit_walks, without_unweighed_contacts

from ..conftest import DATA
from .builders import simulated_walk
from .command import run

FREE = ["foot_radius", "com_offset[1]"]
NOISE = dict.fromkeys(("lean", "steer", "pitch_left", "pitch_right"), 0.002)


@pytest.fixture(scope="module")
def toy():
    return load_params(DATA / "params" / "stable-toy.toml")


def test_one_walk_is_the_single_fit_and_a_walk_twice_halves_the_variance(toy):
    """The joint problem of one walk is the single fit's (same NLP, the same optimum): the same
    estimates, SEs and chi-square; the same walk given twice doubles the chi-square and the
    information, so the estimates stay and the SEs shrink by sqrt(2)."""
    table, _ = simulated_walk(toy, 12, 0.002, 401)
    single = fit(table, toy, FREE, noise_sd=NOISE, check_jacobian=False)
    one = fit_walks([table], [toy], FREE, noise_sd=NOISE)
    assert single.success and one.success
    # IPOPT's tolerance 1e-10 on the same problem from the same start: measured equal to 1e-15
    assert_allclose([one.estimates[n] for n in FREE], [single.estimates[n] for n in FREE], rtol=1e-9)
    assert_allclose([one.std[n] for n in FREE], [single.std[n] for n in FREE], rtol=1e-6)
    assert one.chi2 == pytest.approx(single.chi2, rel=1e-9)
    twice = fit_walks([table, table], [toy, toy], FREE, noise_sd=NOISE)
    assert twice.chi2 == pytest.approx(2 * single.chi2, rel=1e-8)
    assert_allclose([twice.estimates[n] for n in FREE], [single.estimates[n] for n in FREE], rtol=1e-8)
    assert_allclose([twice.std[n] * math.sqrt(2) for n in FREE], [single.std[n] for n in FREE], rtol=1e-6)
    # the warm start: freeing one more parameter from a joint fit of the same walks
    more = fit_walks([table], [toy], FREE + ["effects.hip_damping"], noise_sd=NOISE, warm=one)
    assert more.success and more.chi2 <= one.chi2 + 1e-6


def test_a_walk_whose_gait_search_fails_starts_from_the_last_walks_gait(toy, monkeypatch):
    """When the gait search from scratch fails for a later walk's condition, its gait is solved
    from the last walk's: the joint fit is the one made without the failure."""
    import toywalk.sysid.problem as problem_module

    flatter = toy.replace(slope=0.95 * toy.slope)
    tables = [simulated_walk(p, 6, 0.002, 11 + k)[0] for k, p in enumerate((toy, flatter))]
    plain = fit_walks(tables, [toy, flatter], FREE, noise_sd=NOISE)
    search = problem_module.find_gait

    def failing(params, *args, **kwargs):
        if params.slope != toy.slope:
            raise GaitNotFound("continuation stalled (a test's failure)")
        return search(params, *args, **kwargs)

    monkeypatch.setattr(problem_module, "find_gait", failing)
    with pytest.raises(FitError, match="no gait"):
        fit(tables[1], flatter, FREE, noise_sd=NOISE)  # the failure is real for a single fit
    fallback = fit_walks(tables, [toy, flatter], FREE, noise_sd=NOISE)
    assert plain.success and fallback.success
    # the same optimum (IPOPT's tolerance 1e-10 on the same problem, from another start)
    assert_allclose([fallback.estimates[n] for n in FREE], [plain.estimates[n] for n in FREE], rtol=1e-6)
    assert fallback.chi2 == pytest.approx(plain.chi2, rel=1e-8)


def _two_slopes():
    """compass-3d with hip damping hidden (0.002 N m s/rad), 16 steps on its slope and on 0.8
    of it, noise 0.002 rad stated (`toywalk simulate --noise 0.002`, seeds 31 and 32)."""
    walker = load_params(DATA / "params" / "compass-3d.toml")
    tables, walkers = [], []
    for seed, factor in ((31, 1.0), (32, 0.8)):
        w = walker.replace(slope=walker.slope * factor)
        table, _ = simulated_walk(w.replace(**{"effects.hip_damping": 0.002}), 16, 0.002, seed)
        sds = {f"{n}_sd": np.full(len(table.time), 0.002) for n in list(table.signals)}
        tables.append(TrajectoryTable(table.time, {**table.signals, **sds}, table.stance,
                                      table.events, {}))
        walkers.append(w)
    return tables, walkers


@pytest.mark.slow
def test_walks_on_two_slopes_reach_the_model_strikes_through_the_stage_path():
    """Where the joint fit's jump from the measured strikes to the model's ends far above the
    aligned misfit (walks._JUMP_LIMIT), it goes again through the single fit's blends
    (problem.STAGE_PATH). compass-3d with hip damping hidden (0.002 N m s/rad), 16 steps on
    its slope and on 0.8 of it (`toywalk simulate --noise 0.002`, seeds 31 and 32): in one jump
    the base fit ended at chi-square 3.2e6 on 5362 residuals with the lateral offset at 0.179 m
    (truth 0.02); through the path at 8113, the offset 0.0172 (the fit's other free parameter, the
    foot radius, 10 % large, takes up what it can of the damper the base model lacks)."""
    tables, walkers = _two_slopes()
    base = fit_walks(tables, walkers, FREE)
    assert base.success, base.status
    # the base model, lacking the damper, leaves 1.5 per residual (measured on each walk alike):
    # a bound of 2 is 300 times below the wrong minimum's 595
    assert base.chi2 < 2.0 * base.n_residuals, base.chi2
    assert abs(base.estimates["com_offset[1]"] - 0.02) < 0.2 * 0.02, base.estimates


@pytest.mark.slow
def test_a_base_stuck_in_another_minimum_is_screened_and_beaten_again(monkeypatch):
    """Where the joint base fit ends in another minimum (made here by the old one-jump stages on
    the walks above), the base refitted from the best candidate's fit undercuts it: the
    screening is redone at that base, and the candidates' fits that stood above it are refitted
    from it. Before, the scores stayed at the first base (about 1500, where a score cannot
    exceed the residuals' norm) and the dry friction's likelihood ratio read 0, p = 1."""
    monkeypatch.setattr(walks_module, "_JUMP_LIMIT", math.inf)  # the jump, never the path
    tables, walkers = _two_slopes()
    d = diagnose_walks(tables, walkers, model="periodic", free=FREE, effects=["hip_damping", "hip_coulomb"],
                       parameters=[], workers=2)
    assert d.cause == "effects.hip_damping", d.evidence
    bound = math.sqrt(d.base.chi2)  # a score is the residuals' projection on a unit vector
    assert all(abs(r["score_z"]) <= bound for r in d.ranking), d.ranking
    lr = {r["effect"]: r["lr"] for r in d.ranking}
    # through the stage path the dry friction trails the damper by about 600 on these walks
    # (`toywalk diagnose` on the same walks: 2440.5 and 1827.6): refitted, it is significant
    assert lr["effects.hip_coulomb"] > 100 and lr["effects.hip_damping"] > lr["effects.hip_coulomb"], lr


@pytest.mark.slow
def test_held_out_folds_in_processes_and_on_dask_are_the_serial_ones(toy, tmp_path):
    """The joint analysis runs its fits side by side (``workers``, ``scheduler``): the held-out
    prediction of two walks fitted together is the same in this process, in two local processes
    and on a Dask cluster (a real one, on the loopback address)."""
    from distributed import LocalCluster
    from toywalk.sysid.walks import held_out_walks

    flatter = toy.replace(slope=0.95 * toy.slope)
    tables = [simulated_walk(p, 6, 0.002, 31 + k)[0] for k, p in enumerate((toy, flatter))]
    whole = fit_walks(tables, [toy, flatter], FREE, noise_sd=NOISE)
    serial = held_out_walks(tables, [toy, flatter], whole)
    local = held_out_walks(tables, [toy, flatter], whole, workers=2)
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
                      processes=True) as cluster:
        dask = held_out_walks(tables, [toy, flatter], whole, scheduler=cluster.scheduler_address)
    assert serial["success"] and len(serial["by_walk"]) == 2, serial
    # the same NLPs from the same starts; IPOPT's iterations are deterministic, so the results
    # agree to round-off (measured: equal)
    for other in (local, dask):
        assert_allclose(other["by_walk"], serial["by_walk"], rtol=1e-9)


def test_walks_of_the_base_model_are_adequate_and_nothing_is_fitted(toy):
    """Two walks of the stable toy with nothing hidden, no free parameter (the command's default):
    the score tests stacked over the walks find no candidate significant, so the base is adequate
    and no candidate is fitted, as in the single walk's analysis (docs/tie_null.csv: 40 of 40
    adequate with three walks and two free parameters)."""
    flatter = toy.replace(slope=0.9 * toy.slope)
    tables = [simulated_walk(p, 8, 0.002, 900 + k)[0] for k, p in enumerate((toy, flatter))]
    d = diagnose_walks(tables, [toy, flatter], noise_sd=NOISE, model="periodic")
    assert d.verdict == "adequate" and d.cause is None, d.evidence
    assert d.extended == {} and all("lr" not in r for r in d.ranking)
    assert len(d.residuals) == 2 and not any(r.systematic for r in d.residuals)
    assert d.residuals_extended is None
    # every candidate screened (measured largest |z| 0.84; Bonferroni's level over the library's
    # candidates is about |z| 3)
    assert len(d.ranking) > 8 and all(abs(r["score_z"]) < 3.0 for r in d.ranking)
    # each walk's gait features at the base fit, none for a cause
    assert len(d.features) == 2 and "lean_range" in d.features[1] and d.features_extended is None


def test_contact_positions_without_sds_are_left_out():
    """A simulation's contact positions come without SDs: the joint analysis leaves them out
    (their noise would come from a misfit-inflated residual), unless the file or noise_sd gives
    their SDs."""
    events = [{"time": 0.0, "foot": "L", "x": 0.0, "y": 0.0},
              {"time": 0.1, "foot": "R", "x": 0.04, "y": -0.1}]
    table = TrajectoryTable(np.arange(3.0) * 0.05, {"lean": np.zeros(3)}, ["L", "L", "R"], events, {})
    bare = without_unweighed_contacts(table)
    assert [sorted(e) for e in bare.events] == [["foot", "time"]] * 2
    assert without_unweighed_contacts(table, {"contact_x": 1e-3, "contact_y": 1e-3}) is table
    with_sd = TrajectoryTable(table.time, table.signals, table.stance,
                              [{**e, "x_sd": 1e-3, "y_sd": 1e-3} for e in events], {})
    assert without_unweighed_contacts(with_sd) is with_sd


def test_bad_input_is_refused(toy, tmp_path):
    table, _ = simulated_walk(toy, 4, 0.002, 1)
    with pytest.raises(FitError, match="one parameter set per walk"):
        fit_walks([table, table], [toy], FREE)
    with pytest.raises(FitError, match="one parameter set per walk"):
        fit_walks([], [], FREE)
    # the command line: three walks with two parameter files, or one walk with two, are refused
    # with one line before any fit, and no report folder is left
    write_trajectory(table, tmp_path / "w.csv")
    save_params(toy, tmp_path / "w.toml")
    walk, params = tmp_path / "w.csv", tmp_path / "w.toml"
    for walks, files, message in (([walk] * 3, [params] * 2, "3 walks need one --params each"),
                                  ([walk], [params] * 2, "one walk takes one --params")):
        out = run("diagnose", *walks, *[a for f in files for a in ("--params", f)], "--out", tmp_path / "r")
        assert out.returncode != 0 and message in out.stderr, out.stderr
        assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "r").exists()


@pytest.mark.slow
def test_three_walks_name_hip_dry_friction(toy, tmp_path):
    """The stable toy with hip dry friction hidden (3 noise SDs beyond the base, as in
    docs/diagnose_effects.csv), walked on its ramp, on one at 0.8 of the slope and with its balance
    masses 1 cm further out (docs/diagnosis.md, "Which second walk breaks the ties"), analysed
    together by the command line with the three friction effects and the slope as candidates: dry
    friction is named, ahead of the viscous damper by more than the rule's margin (one walk leaves
    them 1 to 4 apart), and its interval holds the truth."""
    truth = 1.796e-4  # N m
    offset = list(toy.com_offset)
    offset[1] += 0.01
    bases = [toy, toy.replace(slope=0.8 * toy.slope), toy.replace(com_offset=offset)]
    args = ["diagnose"]
    for k, b in enumerate(bases):
        write_trajectory(simulated_walk(b.replace(**{"effects.hip_coulomb": truth}), 12, 0.002, 500 + k)[0],
                         tmp_path / f"walk{k}.csv")
        save_params(b, tmp_path / f"walk{k}.toml")
        args.append(tmp_path / f"walk{k}.csv")
    for k in range(3):
        args += ["--params", tmp_path / f"walk{k}.toml"]
    r = run(*args, "--free", ",".join(FREE), "--effects", "hip_damping,hip_coulomb,pivot_friction",
             "--parameters", "slope", "--model", "periodic", "--out", tmp_path / "report")
    assert r.returncode == 0, r.stderr
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert report["cause"] == "effects.hip_coulomb", report["evidence"]
    row = {r["effect"]: r for r in report["ranking"]}
    # first order 149 (docs/tie_design.csv); fitted 173.9 on these seeds, 156.3 on seeds 400-402
    assert row["effects.hip_coulomb"]["lr"] - row["effects.hip_damping"]["lr"] > SEPARATION
    low, high = row["effects.hip_coulomb"]["interval"]["effects.hip_coulomb"]
    assert low < truth < high  # measured 1.770e-4 [1.715e-4, 1.825e-4]
    # every walk weighed by its own samples' scatter (no noise given, no SDs in the files)
    assert {w["noise_source"] for w in report["base"]["walks"]} == {"scatter within steps"}
    assert (tmp_path / "report" / "candidates.png").stat().st_size > 0
    # each walk's residuals tested for a pattern repeated every step: the named cause leaves none
    assert len(report["residuals"]) == 3 and not any(r["systematic"] for r in report["residuals_extended"])
    assert (tmp_path / "report" / "residuals_by_phase.png").stat().st_size > 0
    text = (tmp_path / "report" / "report.md").read_text()
    assert "3 walks together" in text
    # the named cause predicts the walks' held-out strides better: reported, printed, per walk
    held = report["gain"]["held_out"]
    assert held["candidate"] == "effects.hip_coulomb" and held["extended"] < held["base"], held
    assert len(held["by_walk"]["base"]) == 3 and "Held-out prediction by stride" in text
    assert "held-out chi-square (alternate strides of every walk)" in r.stdout
    # each walk's gait features, base and named cause: the cause brings the worst misfit closer
    worst = [max(abs(v["z"]) for v in f.values() if v["z"] is not None) for f in report["features"]]
    after = [max(abs(v["z"]) for v in f.values() if v["z"] is not None) for f in report["features_extended"]]
    assert len(worst) == len(after) == 3 and max(after) < max(worst), (worst, after)
    assert "## Gait features" in text
