"""The tracker's errors by phase of the step (tracking/accuracy_phase.py), on made-up tracks whose
errors are known: a bias locked to one phase of one foot's steps is found and removed, the SDs
are widened by what the bias's estimate leaves open, strike times' SDs are scaled, the file reads
back as written, and a file that is not one is refused in one line."""

import json
import subprocess

import numpy as np
import pytest
from toywalk.model.trajectory import SIGNALS, TrajectoryTable
from toywalk.tracking.accuracy_phase import AccuracyError, PhaseErrors, load_phase_errors, measure, step_phase
from toywalk.tracking.render import StepwiseSpline

from .synthetic import TOYWALK

STEP = 0.4  # s
RATE = 120.0  # frames/s
SD = 1e-3  # rad, the tracker's stated per-frame SD
#: The made-up tracker's bias: -5 mrad in pitch_left from 0.60 to 0.70 of a left-stance step.
BIAS, WHERE = -5e-3, (0.60, 0.70)


def _walk(seed: int, steps: int = 16, time_error: float = 2e-4, time_sd: float = 1e-4, right_error=None):
    """A tracked walk and its truth: white errors of ``SD`` everywhere plus :data:`BIAS`; strikes
    found ``time_error`` (SD; the right foot's ``right_error`` where given) off and stated with
    ``time_sd``."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, steps * STEP, 1.0 / RATE)
    strikes = np.arange(steps) * STEP
    feet = ["L" if k % 2 == 0 else "R" for k in range(steps)]
    truth = {k: 0.1 * np.sin(2 * np.pi * t / (2 * STEP) + i) for i, k in enumerate(SIGNALS)}
    stance = np.array([feet[min(int(x // STEP), steps - 1)] for x in t])
    phase = (t % STEP) / STEP
    measured = {k: v + rng.normal(0.0, SD, t.shape) for k, v in truth.items()}
    locked = (stance == "L") & (phase >= WHERE[0]) & (phase < WHERE[1])
    measured["pitch_left"][locked] += BIAS
    measured.update({f"{k}_sd": np.full(t.shape, SD) for k in SIGNALS})
    true_events = [{"time": float(s), "foot": f} for s, f in zip(strikes, feet, strict=True)]
    off = {"L": time_error, "R": time_error if right_error is None else right_error}
    found = [{"time": float(s + rng.normal(0.0, off[f])), "foot": f, "time_sd": time_sd}
             for s, f in zip(strikes, feet, strict=True)]
    return TrajectoryTable(t, measured, stance, found), TrajectoryTable(t, truth, stance, true_events)


@pytest.fixture(scope="module")
def errors():
    return measure([_walk(seed) for seed in range(3)])


def test_the_phase_locked_bias_is_found_where_it_is(errors):
    """Bins of 0.05 (120 frames/s, 48 frames a step: 20 bins); the bias is measured to 4 of its
    SEs (SD over the root of the bin's samples) in the two bins it fills, and elsewhere nothing
    beyond 4 SEs is found."""
    assert errors.bins == 20
    key = "pitch_left@L"
    inside = [12, 13]
    se = {k: SD / np.sqrt(np.maximum(errors.count[k], 1)) for k in errors.bias}
    np.testing.assert_allclose(errors.bias[key][inside], BIAS, atol=4 * se[key][inside].max())
    for k in errors.bias:
        rest = np.delete(np.arange(errors.bins), inside) if k == key else np.arange(errors.bins)
        assert np.all(np.abs(errors.bias[k][rest]) < 4 * se[k][rest]), k
    assert WHERE[0] < errors.largest()["pitch_left"]["phase"] < WHERE[1]
    # the walks' own bin means differ by their noise alone: SD about one SE of a walk's bin
    # (a third of the samples), under 3 of them in every bin
    assert np.all(errors.bias_sd[key] < 3 * SD / np.sqrt(np.maximum(errors.count[key] / 3, 1)))
    # a spread of SD about the bias: no excess where the tracker's SD says all (3 SE of a variance
    # from about 50 samples: 0.6 SD^2, so an excess of at most 0.8 SD)
    assert np.all(errors.excess_sd["lean@L"] < 0.8 * SD)


def test_a_walk_carries_the_bias_as_a_shared_error(errors):
    """Another walk with the same tracker: its values are left as tracked, and where the bias is
    its samples say so, an error shared with that phase of every step (``*_phase_sd`` about the
    bias's size, 5 mrad) and SDs widened by it; elsewhere the shared SD is a few SEs of a bin at
    most and the SDs nearly as stated (never narrowed)."""
    tracked, _ = _walk(11)
    carried = errors.apply(tracked, note="made up")
    phase, foot = step_phase(carried)
    sel = (foot == "L") & (phase >= WHERE[0]) & (phase < WHERE[1])
    rest = (foot == "L") & ((phase < WHERE[0] - 0.05) | (phase >= WHERE[1] + 0.05))
    np.testing.assert_array_equal(carried.signals["pitch_left"], tracked.signals["pitch_left"])
    shared = carried.signals["pitch_left_phase_sd"]
    assert np.all(np.abs(shared[sel] - abs(BIAS)) < 0.2 * abs(BIAS))
    assert np.all(shared[rest] < 0.2 * abs(BIAS))
    assert np.all(carried.signals["pitch_left_sd"] >= tracked.signals["pitch_left_sd"])
    assert np.all(carried.signals["pitch_left_sd"][sel] > 4 * SD)
    assert carried.metadata["tracker_errors"]["file"] == "made up"


def test_strike_times_sd_is_scaled_by_its_measured_z():
    """Strikes found 2e-4 s off and stated with 1e-4 s: the scale is about 2 (72 strikes a foot:
    the median absolute error's relative SE about 1/sqrt(2 x 0.37 x 72), 0.14), and the strikes'
    time_sd is multiplied by it; a tracker stating too large an SD keeps it (the scale never falls
    below 1)."""
    over = measure([_walk(seed, steps=48) for seed in range(3)])
    assert over.timing_scale["L"] == pytest.approx(2.0, rel=0.35)
    assert over.timing_scale["R"] == pytest.approx(2.0, rel=0.35)
    tracked, _ = _walk(5)
    fixed = over.apply(tracked)
    for e in fixed.events[:2]:
        assert e["time_sd"] == pytest.approx(1e-4 * over.timing_scale[e["foot"]])
    under = measure([_walk(seed, time_error=1e-5) for seed in range(3)])
    assert under.timing_scale == {"L": 1.0, "R": 1.0}


def test_one_misplaced_strike_does_not_set_the_scale():
    """One strike of 72 misplaced by 100 of its SDs (a hidden foot) would make that foot's RMS
    about 12;
    the scale is the typical strike's (about 2, as without it), and the calibration keeps the
    largest error and the RMS to show it."""
    walks = [_walk(seed, steps=48) for seed in range(3)]
    walks[0][0].events[3]["time"] += 100 * 1e-4
    errors = measure(walks)
    assert errors.timing_scale["R"] == pytest.approx(2.0, rel=0.35)
    worst = max(errors.timing_z[f]["largest"] for f in "LR")
    assert worst > 90 and max(errors.timing_z[f]["rms"] for f in "LR") > 10
    assert PhaseErrors.from_json(errors.to_json()).timing_z == errors.timing_z


def test_each_foots_strikes_get_their_own_scale():
    """The far leg's strikes are found worse than the near one's (compass-3d through video: 1.33
    and 0.52 of their SDs): right strikes 3e-4 s off, left ones 1e-5, both stated 1e-4; the
    right scale is about 3 (72 strikes: relative SE 0.14), the left one 1, and each strike's
    time_sd takes its own. A file of one number (before the feet were told apart) still reads."""
    split = measure([_walk(seed, steps=48, time_error=1e-5, right_error=3e-4) for seed in range(3)])
    assert split.timing_scale["R"] == pytest.approx(3.0, rel=0.35)
    assert split.timing_scale["L"] == 1.0
    fixed = split.apply(_walk(5)[0])
    right = next(e for e in fixed.events if e["foot"] == "R")
    left = next(e for e in fixed.events if e["foot"] == "L")
    assert right["time_sd"] == pytest.approx(1e-4 * split.timing_scale["R"])
    assert left["time_sd"] == pytest.approx(1e-4)
    data = split.to_json()
    data["timing_scale"] = 1.5
    assert PhaseErrors.from_json(data).timing_scale == {"L": 1.5, "R": 1.5}
    data["timing_scale"] = {"L": 0.5, "R": 2.0}
    with pytest.raises(AccuracyError, match="timing_scale"):
        PhaseErrors.from_json(data)


def test_a_missed_strike_leaves_its_interval_out():
    """Where the tracker missed a strike, the interval holding it (the same foot twice) has no
    phase: its errors would land in the wrong bins."""
    tracked, _ = _walk(2)
    del tracked.events[5]
    phase, foot = step_phase(tracked)
    gap = (tracked.time >= 4 * STEP) & (tracked.time < 6 * STEP)
    assert np.isnan(phase[gap]).all() and (foot[gap] == "").all()
    assert np.isfinite(phase[(tracked.time >= STEP) & (tracked.time < 4 * STEP)]).all()


def test_the_file_reads_back_as_written(errors, tmp_path):
    path = tmp_path / "a.json"
    path.write_text(json.dumps(errors.to_json()))
    back = load_phase_errors(path)
    assert isinstance(back, PhaseErrors) and back.bins == errors.bins
    for key in errors.bias:
        np.testing.assert_allclose(back.bias[key], errors.bias[key], rtol=1e-12)
        np.testing.assert_allclose(back.bias_sd[key], errors.bias_sd[key], rtol=1e-12)


def test_a_file_that_is_not_one_is_refused_in_one_line(errors, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"bins": 3}')
    with pytest.raises(AccuracyError, match="not a tracker-error file"):
        load_phase_errors(bad)
    data = errors.to_json()
    data["bias"]["lean@L"] = [0.0]
    bad.write_text(json.dumps(data))
    with pytest.raises(AccuracyError, match="20 finite numbers"):
        load_phase_errors(bad)
    video = tmp_path / "v.mp4"
    video.write_bytes(b"not read: the file is refused first")
    run = subprocess.run([TOYWALK, "track", str(video), "--accuracy", str(bad), "--out",
                          str(tmp_path / "t.csv")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1, run.stderr
    assert "20 finite numbers" in run.stderr
    assert not (tmp_path / "t.csv").exists()


def test_the_renderer_keeps_the_kink_of_a_heel_strike():
    """A walk's angles are smooth within a step and kinked at a strike (the rates jump). Sampled
    every 6.2 ms (simulate's spacing for a 0.15 m leg), the renderer's step-by-step spline stays
    within 1e-5 rad of the truth; one interpolant across the strikes (PCHIP) misses by more than
    1e-4 rad there, which is why the renderer splits at strikes."""
    from scipy.interpolate import PchipInterpolator

    def angle(t):  # a parabola in each step, continuous, its slope jumping from -4 to +4 rad/s
        x = (t % STEP) / STEP
        return 0.8 * (x - 0.5) ** 2 - 0.2

    samples = np.arange(0.0, 4 * STEP, 0.0062)
    strikes = [STEP, 2 * STEP, 3 * STEP]
    fine = np.linspace(samples[0], samples[-1], 4001)
    stepwise = StepwiseSpline(samples, angle(samples)[:, None], strikes)
    got = np.array([stepwise(t)[0] for t in fine])
    assert np.max(np.abs(got - angle(fine))) < 1e-5
    across = PchipInterpolator(samples, angle(samples))(fine)
    assert np.max(np.abs(across - angle(fine))) > 1e-4


@pytest.mark.slow
def test_accuracy_and_track_accuracy_from_the_command_line(tmp_path):
    """toywalk accuracy on one short render (4 steps of the toy-sized walker, about 15 s) writes
    the file and keeps its video; track --accuracy on that video carries it (the bias's
    uncertainty as *_phase_sd columns, the file named in the metadata); a file measured at another
    frame rate is refused in one line, and so is writing over the file."""
    from toywalk.model.trajectory import read_trajectory

    from ..conftest import DATA

    out = tmp_path / "a.json"
    params = str(DATA / "params" / "toy-sized.toml")
    made = subprocess.run([TOYWALK, "accuracy", "--params", params, "--walks", "1", "--steps", "4",
                           "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert made.returncode == 0, made.stderr
    assert "fewer than 3 walks" in made.stderr and "largest bias" in made.stdout
    errors = load_phase_errors(out)
    assert errors.walks == 1 and errors.bins == 20 and errors.source["fps"] == 120.0
    video = tmp_path / "a.walks" / "walk0.mp4"
    assert video.is_file()
    run = subprocess.run([TOYWALK, "track", str(video), "--accuracy", str(out), "--out",
                          str(tmp_path / "t.csv")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "tracker errors carried from" in run.stdout
    table = read_trajectory(tmp_path / "t.csv")
    assert np.isfinite(table.signals["pitch_left_phase_sd"]).sum() > 60  # two whole steps of 44 frames
    assert table.metadata["tracker_errors"]["file"] == str(out)
    data = json.loads(out.read_text())
    data["source"]["fps"] = 60.0
    other = tmp_path / "b.json"
    other.write_text(json.dumps(data))
    refused = subprocess.run([TOYWALK, "track", str(video), "--accuracy", str(other), "--out",
                              str(tmp_path / "u.csv")], capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and "measured at 60 frames/s" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1 and not (tmp_path / "u.csv").exists()
    again = subprocess.run([TOYWALK, "accuracy", "--params", params, "--out", str(out)],
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1
