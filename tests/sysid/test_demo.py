"""`toywalk demo`, the front door (issue 12): on the bundled sample video it tracks, fits, diagnoses,
samples and reports, and names the effect hidden in the video without being told it.

The demo runs once per module (about 2 minutes on two idle cores with the shorter posterior run
below); each test reads its output folder.
"""

import json
import re
import subprocess

import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import read_trajectory

from ..conftest import DATA
from ..tracking.strikes import match_strikes
from ..tracking.synthetic import TOYWALK

SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
SAMPLE = DATA / "sample"


def assert_reproduced(value, documented, unit, what):
    """``value`` is within one unit of the last digit of ``documented`` (quoted to a multiple of
    ``unit``).

    Not half a unit (rounding): the demo's figures pass through a calibration and the tracker, and
    the tracker's per-frame decisions turn round-off in the lens into up to 2e-5 rad in the angles
    (under half a percent of its 0.3 deg targets). Two runs whose calibrations differed by 1e-9
    (OpenCV's multithreaded solve, since made single-threaded; another machine's arithmetic can
    do the same) moved the lean-range z by 0.056, the cross-slope score z by
    0.055 and the held-out chi-square by 0.63, and one of them missed the rounding of 2425 by
    0.98."""
    assert abs(value - documented) <= unit * (1 + 1e-9), f"{what}: {value!r} vs {documented}"


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "out"
    # A shorter posterior run than the default 120 steps: the same stages, three minutes less.
    r = subprocess.run([TOYWALK, "demo", "--out", str(out), "--sample-steps", "40"],
                       capture_output=True, text=True, timeout=1800)
    return out, r


@pytest.mark.slow
def test_demo_names_the_hidden_effect(demo):
    """Issue 12, done means: the report names the effect hidden in the sample video, which the
    analysis reads only after it has named one (data/sample/truth.toml). Its estimate's 95 %
    interval covers the truth, and the named model predicts held-out strides better."""
    out, r = demo
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    truth = load_params(SAMPLE / "truth.toml")
    hidden = {k: v for k, v in truth.effects.items() if v != 0}
    assert len(hidden) == 1
    (name, value), = hidden.items()
    assert report["verdict"] == "discrepancy"
    assert report["cause"] == f"effects.{name}" and report["found"] == [f"effects.{name}"]
    diagnosis = json.loads((out / "diagnosis" / "report.json").read_text())
    row = next(r for r in diagnosis["ranking"] if r["effect"] == f"effects.{name}")
    lo, hi = row["interval"][f"effects.{name}"]
    assert lo < value < hi, (lo, value, hi)
    assert diagnosis["gain"]["extended"] < diagnosis["gain"]["base"]
    for stage in ("1. Calibrating", "2. Tracking", "3. Fitting", "4. Sampling",
                  "5. What the sample video hides"):
        assert stage in r.stdout


@pytest.mark.slow
def test_demo_writes_every_stage(demo):
    """Every stage's files are there and readable: the tracked walk, the fit, the diagnosis with
    its figures, the posterior's chain and figures, and the summary linking them."""
    out, r = demo
    assert r.returncode == 0, r.stderr[-2000:]
    for path in ("camera.json", "tracked.csv", "tracked.events.csv", "fit.json", "report.md", "report.json",
                 "diagnosis/report.md", "diagnosis/report.json", "diagnosis/residuals_by_phase.png",
                 "diagnosis/features.png", "diagnosis/candidates.png", "posterior/chain.h5",
                 "posterior/chain.json", "posterior/corner.png", "posterior/report.md"):
        assert (out / path).stat().st_size > 0, path
    fit = json.loads((out / "fit.json").read_text())
    assert fit["success"] and set(fit["free"]) == {"foot_radius", "com_offset[1]"}
    posterior = json.loads((out / "posterior" / "chain.json").read_text())
    assert any(n.startswith("effects.") for n in posterior["quantiles_5_50_95"])
    text = (out / "report.md").read_text()
    assert "![corner](posterior/corner.png)" in text and "## Diagnosis" in text


def _tracked(out):
    """(tracked trajectory, renderer's truth, frame interval s)."""
    tracked, truth = read_trajectory(out / "tracked.csv"), read_trajectory(SAMPLE / "walk.truth.csv")
    return tracked, truth, float(np.median(np.diff(truth.time)))


def _strikes(tracked, truth, dt, events=None):
    """The demo's measured strikes (or ``events``) against the true ones in the clip; the tracker
    seeks strikes more than 3 frames from the ends."""
    true = [e for e in truth.events if truth.time[0] <= e["time"] <= truth.time[-1]]
    seek = (truth.time[0] + 3 * dt, truth.time[-1] - 3 * dt)
    return match_strikes(true, tracked.events if events is None else events, dt, seek=seek)


@pytest.mark.slow
def test_demo_video_is_tracked_to_the_targets(demo):
    """The tracked walk against the truth the sample video was rendered from
    (data/sample/walk.truth.csv, read by the demo only after its analysis), and what the demo
    prints about it."""
    out, r = demo
    assert r.returncode == 0, r.stderr[-2000:]
    tracked, truth, dt = _tracked(out)
    np.testing.assert_allclose(tracked.time, truth.time, rtol=0, atol=1e-4)  # container timestamps
    printed = dict(re.findall(r"^\s+(\w+)\s+RMS error ([\d.]+) deg", r.stdout, re.M))
    assert set(printed) == set(SIGNALS), r.stdout
    for name in SIGNALS:
        err = np.degrees(tracked.signals[name] - truth.signals[name])
        # noise level 1 hides no marker (measured: 0 gaps in 175 frames)
        assert np.isfinite(err).all(), (name, int((~np.isfinite(err)).sum()))
        rms = np.sqrt(np.mean(err**2))
        # issue 4: lean and pitch RMS <= 0.3 deg, steer <= 0.5 deg (measured 0.01-0.04)
        assert rms <= (0.5 if name == "steer" else 0.3), (name, rms)
        # what the demo prints is this number, to its two decimals
        assert abs(float(printed[name]) - rms) <= 0.005 + 1e-9, (name, printed[name], rms)
    strikes = _strikes(tracked, truth, dt)
    # 16 steps: the 15 strikes after the first are in the clip, none within 3 frames of an end
    assert len(strikes.pairs) + len(strikes.missed) == 15
    # one to one, same foot, within half a frame: none missed, none invented
    assert not strikes.missed and not strikes.invented, strikes.describe(dt)
    errors = np.array(strikes.errors) / dt
    # issue 4: timing RMS <= a quarter frame (measured 0.03)
    timing = np.sqrt(np.mean(errors**2))
    assert timing <= 0.25, errors
    found, true, shown = re.search(r"heel strikes (\d+) found, (\d+) true .*timing RMS ([\d.]+) frame",
                                   r.stdout).groups()
    assert (int(found), int(true)) == (len(tracked.events), 15), r.stdout
    assert abs(float(shown) - timing) <= 0.005 + 1e-9, (shown, timing)


@pytest.mark.slow
def test_strike_check_tells_wrong_strikes_from_right(demo):
    """The strikes of the test above, spoiled as a tracker could spoil them, each fail: a missed
    strike with an invented one (the count unchanged), every foot swapped, one strike a frame
    late."""
    out, _ = demo
    tracked, truth, dt = _tracked(out)
    events = [dict(e) for e in tracked.events]
    assert not _strikes(tracked, truth, dt, events).missed  # unspoiled: the test above
    gone = events.pop(5)
    invented = {**gone, "time": gone["time"] + 5 * dt}  # half a step (11 frames) later, between strikes
    spoiled = _strikes(tracked, truth, dt, events + [invented])
    assert (len(spoiled.missed), len(spoiled.invented)) == (1, 1)
    events.insert(5, gone)
    swapped = [{**e, "foot": "L" if e["foot"] == "R" else "R"} for e in events]
    spoiled = _strikes(tracked, truth, dt, swapped)
    assert not spoiled.pairs and len(spoiled.missed) == len(spoiled.invented) == 15
    late = [{**e, "time": e["time"] + dt} if k == 7 else e for k, e in enumerate(events)]
    spoiled = _strikes(tracked, truth, dt, late)
    assert (len(spoiled.missed), len(spoiled.invented)) == (1, 1)


@pytest.mark.slow
def test_demo_diagnosis_is_the_documented_one(demo):
    """docs/diagnosis.md ("Through rendered and tracked video") quotes the demo's diagnosis of the
    sample video: each figure here to the digits quoted there (assert_reproduced: within one unit of
    the last digit). The demo is deterministic (one video, fixed seeds), so a change to the
    tracker, the fit or the analysis that moves a quoted figure fails here, and the document is
    then updated with it."""
    out, r = demo
    assert r.returncode == 0, r.stderr[-2000:]
    d = json.loads((out / "diagnosis" / "report.json").read_text())
    features = {k: v["z"] for k, v in d["features"].items()}
    # the base model misses the lean and steer ranges by -8.7 and -6.5 SE; the legs' pitch
    # ranges differ by 5.0 (swing) and 7.1 (stance) SE where the model has them equal
    assert_reproduced(features["lean_range"], -8.7, 0.1, "lean range (SE)")
    assert_reproduced(features["steer_range"], -6.5, 0.1, "steer range (SE)")
    assert_reproduced(-features["swing_pitch_range_right_minus_left"], 5.0, 0.1, "swing pitch (SE)")
    assert_reproduced(features["stance_pitch_range_right_minus_left"], 7.1, 0.1, "stance pitch (SE)")
    # screening: asymmetry z = +28.1, cross_slope +25, slope -17.7
    score = {row["effect"]: row["score_z"] for row in d["ranking"]}
    assert_reproduced(score["effects.asymmetry"], 28.1, 0.1, "asymmetry score z")
    # The cross slope's column is mostly a lean offset; the remainder the fit cannot mimic is
    # settled only to about 0.1 % (28.45 projected with an SVD basis, 28.48 with a least-squares
    # solve): quoted to the unit
    assert_reproduced(score["effects.cross_slope"], 25, 1, "cross_slope score z")
    assert_reproduced(score["slope"], -17.7, 0.1, "slope score z")
    # named: asymmetry 0.00506, 95 % [0.00485, 0.00527]
    row = next(row for row in d["ranking"] if row["effect"] == "effects.asymmetry")
    assert_reproduced(row["estimate"]["effects.asymmetry"], 0.00506, 1e-5, "asymmetry")
    lo, hi = row["interval"]["effects.asymmetry"]
    assert_reproduced(lo, 0.00485, 1e-5, "interval, lower end")
    assert_reproduced(hi, 0.00527, 1e-5, "interval, upper end")
    # held-out chi-square 1415 to 402 (the noise of the file's SDs their RMS, 1479 to 420 with
    # their median); max |eigenvalue| 0.900 to 0.809
    assert_reproduced(d["gain"]["base"], 1415, 1, "held-out chi-square, base")
    assert_reproduced(d["gain"]["extended"], 402, 1, "held-out chi-square, extended")
    assert_reproduced(d["gain"]["max_abs_eigenvalue"]["base"], 0.900, 1e-3, "max |eigenvalue|, base")
    assert_reproduced(d["gain"]["max_abs_eigenvalue"]["extended"], 0.809, 1e-3,
                      "max |eigenvalue|, extended")
    # against the truth: the named model's foot radius 2.6 SE low (0.05 mm), the lateral offset
    # 0.5 SE (read at each frame's time, not over its shutter: 4.6 SE, 0.08 mm and 0.8 SE)
    truth = json.loads((out / "report.json").read_text())["parameters_against_truth"]
    assert_reproduced(-truth["foot_radius"]["z"], 2.6, 0.1, "foot radius (SE)")
    foot_mm = 1e3 * (truth["foot_radius"]["truth"] - truth["foot_radius"]["estimate"])
    assert_reproduced(foot_mm, 0.05, 0.01, "foot radius (mm)")
    assert_reproduced(abs(truth["com_offset[1]"]["z"]), 0.5, 0.1, "lateral offset (SE)")


@pytest.mark.slow
def test_demo_calibrates_the_videos_lens(demo):
    """The lens calibrated from the bundled board views against the one the video was rendered
    with (data/sample/walk.camera.json): every intrinsic within 4 of the calibration's own
    standard errors (a calibration that ignored distortion or swapped fx and fy would miss by tens)."""
    out, r = demo
    assert r.returncode == 0, r.stderr[-2000:]
    lens = json.loads((out / "report.json").read_text())["lens_errors"]
    assert set(lens) == {"fx", "fy", "cx", "cy", "k1", "k2"}
    for name, e in lens.items():
        assert abs(e["error"]) < 4 * e["se"], (name, e)
