"""The naming rule written once (toywalk.sysid.naming): its order of questions, the judgement of
whether a model explains the data, and the noise reference that judgement uses."""

import math

import numpy as np
import pytest
from toywalk.model import load_params
from toywalk.model.effects import EFFECTS, LIBRARY
from toywalk.model.trajectory import TrajectoryTable
from toywalk.sysid.measurement import observations
from toywalk.sysid.naming import (
    RMS_FACTOR,
    SEPARATION,
    Candidate,
    Explanation,
    candidates,
    compatible,
    decide,
    feature_p,
    judge,
    noise_reference,
    parameter_note,
)
from toywalk.sysid.residuals import scatter_noise

from ..conftest import DATA


def _row(name, lr, p=1e-9):
    return {"effect": name, "lr": lr, "lr_p": p}


def _explains(ok=True):
    def explain(names):
        return Explanation(list(names), ok, [] if ok else ["held-out RMS over the noise: lean 1.80 noise SD"],
                           {"lean": 1.0 if ok else 1.8}, {"lean": 1.2}, {}, 0.97 if ok else 0.6)
    return explain


def test_a_decisive_candidate_that_predicts_and_explains_is_named():
    d = decide([_row("a", 100.0), _row("b", 100.0 - SEPARATION - 0.1)], 1e-3,
               explain=_explains(), held_out=lambda row: (50.0, ""))
    assert (d.verdict, d.cause, d.causes) == ("discrepancy", "a", ["a"])
    assert d.lead["held_out_gain"] == 50.0


def test_candidates_within_the_separation_are_tied_and_nothing_is_named():
    d = decide([_row("a", 100.0), _row("b", 100.0 - SEPARATION + 0.1)], 1e-3, explain=_explains(),
               held_out=lambda row: pytest.fail("a tie is not held out"))
    assert (d.verdict, d.cause, d.causes, d.tied) == ("discrepancy", "unexplained", [], True)


def test_no_better_prediction_of_held_out_strides_is_unexplained():
    d = decide([_row("a", 100.0)], 1e-3, explain=lambda n: pytest.fail("not asked"),
               held_out=lambda row: (-3.0, ""))
    assert d.cause == "unexplained" and "does not predict held-out strides better" in d.reason
    d = decide([_row("a", 100.0)], 1e-3, explain=lambda n: pytest.fail("not asked"),
               held_out=lambda row: (math.nan, "fold 1: Restoration_Failed"))
    assert d.cause == "unexplained" and "Restoration_Failed" in d.reason


def test_a_candidate_that_improves_but_does_not_explain_is_only_an_effective_description():
    d = decide([_row("effects.rolling_resistance", 700.0), _row("com_offset[0]", 100.0)], 1e-3,
               explain=_explains(False), held_out=lambda row: (7800.0, ""))
    assert d.verdict == "partly explained"
    # never presented as the cause: the cause field and the named causes stay empty of it
    assert d.cause == "unexplained" and d.causes == []
    assert d.lead["effect"] == "effects.rolling_resistance"
    assert "stand in for physics the library lacks" in d.reason and "60 %" in d.reason


def test_nothing_significant_is_unexplained():
    d = decide([_row("a", 3.0, p=0.08)], 1e-3, explain=lambda n: pytest.fail("not asked"))
    assert (d.verdict, d.cause, d.lead) == ("discrepancy", "unexplained", None)


def test_the_runner_up_is_named_beside_when_it_adds_to_the_best():
    d = decide([_row("a", 100.0), _row("b", 50.0)], 1e-3, explain=_explains(),
               held_out=lambda row: (10.0, ""), together=lambda best, runner: True)
    assert d.causes == ["a", "b"]


def test_judge_holds_the_held_out_rms_to_the_noise_widened_by_its_uncertainty():
    n = 2000  # samples of a signal held out: the RMS itself is then known to 1/sqrt(2 n) = 1.6 %
    noise = {"lean": {"sd": 1e-3, "rel_se": 0.02}, "steer": {"sd": 1e-3, "rel_se": 0.02},
             "pitch_left": {"sd": None, "why": "correlated"}}
    walk = {"rms": {"lean": 1.02e-3, "steer": 1.4e-3, "pitch_left": 5e-3},
            "rms_base": {"lean": 2e-3, "steer": 2e-3, "pitch_left": 6e-3},
            "n": {"lean": n, "steer": n, "pitch_left": n}}
    e = judge(["x"], held=[("", walk, noise)], patterns=[], features=[])
    # limit: 1.1 * exp(3 * hypot(0.02, 0.0158)) = 1.19; lean at 1.02 passes, steer at 1.40 does not
    assert e.limit["lean"] == pytest.approx(RMS_FACTOR * math.exp(3 * math.hypot(0.02, 1 / math.sqrt(2 * n))))
    assert not e.explains and e.shortfalls == ["held-out RMS over the noise: steer 1.40 noise SD"]
    assert "pitch_left" in e.not_judged and "pitch_left" not in e.remaining
    # share of the excess over the noise removed, in noise units: (4 - 1.0404 + 4 - 1.96) / (3 + 3)
    assert e.share == pytest.approx((4 - 1.02**2 + 4 - 1.4**2) / 6)
    walk["rms"]["steer"] = 1.05e-3
    assert judge(["x"], held=[("", walk, noise)], patterns=[], features=[]).explains


def test_judge_fails_a_missed_feature_a_pattern_and_coloured_residuals():
    class Report:
        systematic = ["stance_pitch"]

    features = {"lean_range": {"z": 4.0}, "duration": {"z": 1.0}, "steer_range": {"z": math.nan}}
    # two finite features at alpha 0.01: p below 0.005 is missed, as 4.0 SE is on the normal law
    # (p = 6e-5); over a 10-step walk's own scatter (Student's t, 9 dof) 3.7 SE has p = 0.005
    assert feature_p({"z": 4.0}) == pytest.approx(6.334e-5, rel=1e-3)
    assert feature_p({"z": -3.7, "dof": 9}) == pytest.approx(0.00492, rel=1e-2)
    e = judge(["x"], held=None, patterns=[(" (walk 2)", Report())], features=[("", features)],
              whiteness={"lean": 1e-6, "steer": 0.4})
    assert not e.explains and len(e.shortfalls) == 3
    assert "stance_pitch (walk 2)" in e.shortfalls[0] and "lean_range +4.0 SE" in e.shortfalls[1]
    features["lean_range"]["dof"] = 4  # the same misfit over 5 steps' scatter: p = 0.016, kept
    assert judge(["x"], held=None, patterns=[], features=[("", features)]).explains
    assert "lean (Ljung-Box" in e.shortfalls[2] and "steer" not in e.shortfalls[2]
    assert math.isnan(e.share)


def _sine_walk(rng, steps=16, rate=120.0, sd=0.002, smooth=False):
    """Smooth angles (a sine a step), white noise of SD ``sd`` (a three-sample running mean of it
    when ``smooth``), heel strikes every 0.5 s."""
    t = np.arange(0.0, steps * 0.5, 1.0 / rate)
    noise = {k: rng.normal(0.0, sd, t.size) for k in ("lean", "steer", "pitch_left", "pitch_right")}
    if smooth:
        noise = {k: np.convolve(v, np.ones(3) / 3, mode="same") for k, v in noise.items()}
    signals = {k: 0.05 * np.sin(2 * np.pi * t + i) + noise[k] for i, k in enumerate(noise)}
    stance = np.where((t // 0.5) % 2 == 0, "L", "R")
    events = [{"time": 0.5 * k, "foot": "L" if k % 2 == 0 else "R"} for k in range(steps + 1)]
    return TrajectoryTable(t, signals, stance, events, {})


def test_the_scatter_and_its_standard_error_are_honest_on_white_noise():
    """The noise reference without a model: over 60 white-noise walks the scatter's SD is the
    true one, its spread what rel_se says (within the spread's own sampling error, 9 % at 60
    walks), and the reference takes it; a running mean of the noise is refused."""
    rng = np.random.default_rng(5)
    sds, rel = [], []
    for _ in range(60):
        s = scatter_noise(observations(_sine_walk(rng)))["lean"]
        sds.append(s["sd"] / 0.002)
        rel.append(s["rel_se"])
    assert np.mean(sds) == pytest.approx(1.0, abs=3 * np.std(sds) / math.sqrt(60))
    assert np.std(sds, ddof=1) / np.mean(rel) == pytest.approx(1.0, abs=0.3)
    ref = noise_reference(observations(_sine_walk(rng)), {"lean": 9.0}, "estimated from residuals")
    assert ref["lean"]["sd"] == pytest.approx(0.002, rel=0.1)  # never the residual RMS of 9 rad
    smooth = noise_reference(observations(_sine_walk(rng, smooth=True)), {}, "estimated from residuals")
    assert smooth["lean"]["sd"] is None and "correlated" in smooth["lean"]["why"]
    given = noise_reference(observations(_sine_walk(rng)), {"lean": 0.003}, "file")
    assert given["lean"] == {"sd": 0.003, "rel_se": 0.0}


def test_a_named_held_parameter_says_a_measured_value_outranks_it():
    slope = Candidate("slope", "parameter", 0.0262, (-1.5, 1.5), 0, 0.02, False)
    note = parameter_note({"effect": "slope", "estimate": {"slope": 0.0251}}, slope)
    assert "slope is named at 0.0251 where the parameter file says 0.0262" in note
    damper = Candidate("effects.hip_damping", "effect", 0.0, (0.0, 1.0), 1, 2e-4, False)
    assert parameter_note({"effect": damper.name, "estimate": {damper.name: 1e-4}}, damper) == ""


def test_the_default_candidates_are_the_librarys_effects_not_the_port_terms():
    """diagnose's default causes are the library's eight effects, as before the dictionary of port
    terms joined the registry; a port term is a candidate where it is named."""
    params = load_params(DATA / "params" / "stable-toy.toml")
    effects = [c.name for c in candidates(params) if c.kind == "effect"]
    assert effects == ["effects.hip_damping", "effects.hip_coulomb", "effects.rolling_resistance",
                       "effects.pivot_friction", "effects.impact_trailing_share",
                       "effects.impact_spin_arrest", "effects.asymmetry", "effects.cross_slope"]
    assert any(e.port_only for e in EFFECTS.values())  # the check can fail: port terms are registered
    named = candidates(params, effects=["hinge_stiffness", "impact_lean_arrest"], parameters=[])
    assert [c.name for c in named] == ["effects.hinge_stiffness", "effects.impact_lean_arrest"]
    assert named[0].prior_sd == EFFECTS["hinge_stiffness"].typical


def test_no_causes_asked_for_leaves_only_the_missing_forces_search(tmp_path):
    """``--effects none --parameters none``: no candidate, which only the search of the port
    dictionary can use; without it, and in the analyses of several walks, a one-line refusal
    before any fit. Causes asked for that are all free still refuse as before."""
    from toywalk.sysid.commands.diagnose import _split
    from toywalk.sysid.discrepancy import diagnose
    from toywalk.sysid.naming import DiagnoseError
    from toywalk.sysid.walks import diagnose_walks

    params = load_params(DATA / "params" / "stable-toy.toml")
    assert _split("none") == [] and _split(" None ") == [] and _split(None) is None
    assert candidates(params, effects=[], parameters=[]) == []
    table = TrajectoryTable([0.0, 1.0], {}, ["L", "L"])  # never read: the refusal comes first
    with pytest.raises(DiagnoseError, match="no candidate causes to test"):
        diagnose(table, params, effects=[], parameters=[], missing_force=False)
    with pytest.raises(DiagnoseError, match="no candidate causes to test"):
        diagnose_walks([table], [params], effects=[], parameters=[])
    with pytest.raises(DiagnoseError, match="all free or fixed"):
        candidates(params, free=["slope"], effects=[], parameters=["slope"])


def test_the_soft_heel_is_a_candidate_on_the_seed_s_walker_only():
    """``library`` stands for the library's effects, so ``library,soft_heel`` adds the compliant
    heel strike, which the fits take only with no other effect on or free: it is left out beside
    an effect, and a pair of it and an effect is never fitted."""
    params = load_params(DATA / "params" / "clearing-toy.toml")
    names = [c.name for c in candidates(params, [], ["library", "soft_heel"], [])]
    assert names == [f"effects.{e}" for e in LIBRARY] + ["effects.soft_heel"]
    assert "effects.soft_heel" not in [c.name for c in candidates(params, [], None, [])]
    damped = params.replace(**{"effects.hip_damping": 1e-4})
    assert "effects.soft_heel" not in [c.name for c in candidates(damped, [], ["library", "soft_heel"], [])]
    assert "effects.soft_heel" not in [c.name for c in candidates(params, ["effects.hip_damping"],
                                                                  ["soft_heel"], None)]
    assert not compatible("effects.soft_heel", "effects.hip_damping")
    assert compatible("effects.soft_heel", "com_offset[0]") and compatible("slope", "effects.hip_damping")
