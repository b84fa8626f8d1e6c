"""Parameter recovery through rendered and tracked video (issue 9): a walk simulated with a known
foot radius, lateral mass offset and trailing-foot impact share is filmed by the renderer
(`toywalk render`, noise level 1: sensor noise, motion blur, flicker, MPEG-4), tracked back
(`toywalk track`) and fitted (`toywalk.sysid.fit.fit`) from a start 10 % off the truth.

test_fit.py recovers the same three parameters from the simulated angles with white noise; here
the measurement is the tracker's: its angles with their per-sample SDs (`*_sd` columns) and its
heel strikes with their `time_sd`.

Filming choices, each measured on this walker (stable-toy, step time 0.109 s):

- 180 frames/s, 19.6 frames a step. At 60 frames/s (6.5 frames a step) the tracker's heel-strike
  finder, even on the model's own angles sampled at the frames (with 0 or 1 mrad of white noise,
  four frame phases), finds 11-13 of 13 strikes, and in three of the phases all of one foot's
  strikes are 3-33 ms off;
  and the tracked pitches of the tenth of a step before a strike are biased by -3 to -6 mrad (the
  swing leg is fastest there). At 75-120 frames/s the finder finds between none and 12 of the 13,
  some of them 20-40 ms off. From 150 frames/s on it finds all 13; at 180, in these videos, to
  0.24-0.48 ms RMS.
- The trajectory handed to the renderer is sampled at 5 kHz. The renderer interpolates the angles
  between samples (PCHIP, across the heel strikes too): at `simulate`'s default spacing (6.2 ms)
  the walker drawn departs from the model by up to 1.7 mrad, more than the tracker's noise; at
  5 kHz by at most 0.02 mrad.
"""

import subprocess

import numpy as np
import pytest
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory
from toywalk.sysid.fit import fit
from toywalk.tracking.camera import save_camera
from toywalk.tracking.markers import default_layout, save_layout
from toywalk.tracking.scene import default_camera_for

from ..conftest import DATA
from ..tracking.synthetic import TOYWALK

PARAMS = DATA / "params" / "stable-toy.toml"
FREE = ["foot_radius", "com_offset[1]", "effects.impact_trailing_share"]
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
#: The trailing foot's share of the heel-strike impulse, as in test_fit.py: a third of its bound
#: (0.3), and it changes the step time by 2 % (0.1066 to 0.1089 s).
SHARE = 0.1
#: Twelve steps as in test_fit.py: eleven strikes in the video (the walk starts on the first, at
#: t = 0, unseen), ten complete steps, about 800 tracked angles.
STEPS = 12
#: Frames per second (module docstring: where the strike finder works for this walker).
FPS = 180
#: Trajectory samples per second handed to the renderer (module docstring).
SAMPLE_RATE = 5000.0


def _run(*args):
    r = subprocess.run([TOYWALK, *map(str, args)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def truth():
    return load_params(PARAMS).replace(**{"effects.impact_trailing_share": SHARE})


@pytest.fixture(scope="module")
def filmed(truth, tmp_path_factory):
    """The walk simulated, filmed and tracked: (tracked walk, the renderer's truth)."""
    folder = tmp_path_factory.mktemp("video")
    gait = find_gait(truth)
    traj = simulate(truth, gait.fixed_point, STEPS, sample_rate=SAMPLE_RATE)
    assert traj.status == "completed", traj.message
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right,
               "contact_x": traj.contact[:, 0], "contact_y": traj.contact[:, 1]}
    events = [{"time": e.time, "foot": e.foot, "x": e.x, "y": e.y} for e in traj.events]
    write_trajectory(TrajectoryTable(traj.times, signals, traj.stance, events, {}), folder / "walk.csv")
    # One camera and one marker layout for both commands. The renderer draws the geometry of
    # PARAMS (the impact share does not change it).
    save_camera(default_camera_for(truth), folder / "camera.json")
    save_layout(default_layout(truth), folder / "markers.json")
    _run("render", folder / "walk.csv", "--params", PARAMS, "--camera",
         folder / "camera.json", "--markers", folder / "markers.json", "--noise", 1, "--seed", 1,
         "--fps", FPS, "--out", folder / "video.mp4")
    _run("track", folder / "video.mp4", "--camera", folder / "camera.json", "--markers",
         folder / "markers.json", "--out", folder / "tracked.csv")
    return read_trajectory(folder / "tracked.csv"), read_trajectory(folder / "video.truth.csv")


def _start(truth):
    """10 % off the truth in each free parameter."""
    return truth.replace(**{"foot_radius": 1.1 * truth.foot_radius,
                            "com_offset[1]": 0.9 * truth.com_offset[1],
                            "effects.impact_trailing_share": 1.1 * SHARE})


def _assert_recovered(result, truth):
    assert result.success, result.status
    for name in FREE:
        err = result.estimates[name] - truth.get(name)
        assert abs(err) < 3 * result.std[name], (name, err / result.std[name], result.estimates[name])
        # The data do determine it (measured: 0.2-0.6 % of the value).
        assert result.std[name] < 0.1 * abs(truth.get(name)), name


@pytest.mark.slow
def test_fit_through_video_recovers_foot_radius_mass_offset_and_impact_share(filmed, truth):
    """The whole pipeline: the tracked walk as `toywalk track` writes it, SDs and strikes included.
    The measured strikes are data, not the model's clock (sysid/measurement.py): aligned on them
    as if exact, the fit was biased by 4-12 SE (render seeds 1-3; strike-time errors of 0.24-0.48
    ms RMS where the legs swing at 8.5 rad/s); `strikes="measured"` still does that, and the check
    below fails for it (the last lines)."""
    tracked, _ = filmed
    result = fit(tracked, _start(truth), FREE)
    # The tracker's SDs are used as given, and the residuals are no larger than they say: for ~800
    # residuals with honest SDs the reduced chi-square is 1 +- 0.05; the tracker's SDs are if
    # anything too large (measured: error over SD has an RMS of 0.6-0.8 against the truth), so
    # above 1.2 the model misses the video by more than the tracker's noise.
    assert result.noise_source == "file"
    reduced = result.to_json()["reduced_chi2"]
    assert reduced < 1.2, result.residual_rms
    # From below: SDs too large hide misfit and widen every interval. Measured 0.46 (render seed
    # of this test); 0.2 fails a tracker whose SDs are over 2.2 times its errors (1.5 times more
    # inflated than now).
    assert reduced > 0.2, reduced
    _assert_recovered(result, truth)
    aligned = fit(tracked, _start(truth), FREE, strikes="measured", check_jacobian=False)
    with pytest.raises(AssertionError):
        _assert_recovered(aligned, truth)


@pytest.mark.slow
def test_tracked_angles_with_the_true_strike_times_recover_the_parameters(filmed, truth):
    """The same tracked angles, cut into steps at the renderer's heel-strike times instead of the
    tracker's: the angles alone carry the parameters. (The strikes are given without `time_sd`,
    so the fit takes each as uniform within a frame.)"""
    tracked, rendered = filmed
    inside = [{"time": e["time"], "foot": e["foot"]} for e in rendered.events
              if tracked.time[0] < e["time"] < tracked.time[-1]]
    # The tracker finds every strike the video shows, each by the right foot.
    assert [e["foot"] for e in tracked.events] == [e["foot"] for e in inside]
    table = TrajectoryTable(tracked.time, tracked.signals, tracked.stance, inside, {})
    result = fit(table, _start(truth), FREE, check_jacobian=False)
    _assert_recovered(result, truth)
    for name in SIGNALS:
        # Residuals at or below the tracker's stated noise (measured: 0.59-0.74 of its RMS SD).
        sd = np.sqrt(np.nanmean(tracked.signals[f"{name}_sd"] ** 2))
        assert result.residual_rms[name] < sd, (name, result.residual_rms[name], sd)
