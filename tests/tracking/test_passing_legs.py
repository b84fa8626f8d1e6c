"""The far leg's pitch where the near leg passes in front of its lower flag: a clip of the
toy-sized walker by the project's renderer (noise level 1, 120 fps, the camera following it as
``toywalk render`` films by default), tracked and compared with the renderer's truth.

Filmed from the right, the right leg's rod and flags cross the left leg's lower flag when the
left leg is 22-28 degrees ahead of the right. The flag stays detected while the rod covers its
white margin and then the edge of its black square, and the edge line fitted there moves the two
corners it joins by 0.2-2 px. Before the tracker dropped such corners (Tracker._drop_bad_corners)
the left pitch in those frames was 0.16-0.30 degree low on average (16 steps, four noise seeds:
-0.28 to -0.42 degree in the worst twentieth of the step), against +-0.03 elsewhere.
"""

import dataclasses
import subprocess

import numpy as np
import pytest
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import read_trajectory
from toywalk.tracking.render import Filming, RenderOptions, default_filming
from toywalk.tracking.track import track_video

from ..conftest import DATA
from .synthetic import TOYWALK

#: deg: the left leg's pitch less the right's in which the right leg covers the left's lower flag
#: (from 28 on, the flag is mostly hidden and the leg is seen through its upper flag alone, whose
#: pitch scatters by 0.2-0.3 degree a frame)
PASSING = (22.0, 27.0)


@pytest.mark.slow
def test_far_leg_pitch_is_unbiased_where_the_legs_pass(tmp_path):
    params_path = DATA / "params" / "toy-sized.toml"
    r = subprocess.run([TOYWALK, "simulate", "--params", str(params_path), "--steps", "6",
                        "--out", str(tmp_path / "walk.csv")], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    params = load_params(params_path)
    table = read_trajectory(tmp_path / "walk.csv")
    options = RenderOptions.preset(1, fps=120)
    camera, path, layout = default_filming(table, params, options=options)
    film = Filming(table, params, camera, layout, options, 11, path=path)
    truth = film.write_video(tmp_path / "v.mp4")  # (lean, steer, pitch_left, pitch_right)
    result, _ = track_video(tmp_path / "v.mp4", dataclasses.replace(camera, ramp_pose=None), layout)
    assert np.all(np.isfinite(result.raw["pitch_left"]))  # no frame lost to the dropped corners
    relative = np.degrees(truth[:, 2] - truth[:, 3])
    passing = (relative >= PASSING[0]) & (relative < PASSING[1])
    assert passing.sum() >= 12, passing.sum()  # three passings at least (17 frames in 6 steps)
    err = np.degrees(result.raw["pitch_left"] - truth[:, 2])[passing]
    # Measured on this clip (seed 11, as here, and 12): mean +0.002 and -0.046 degree with the
    # corners dropped, spread 0.09-0.12 a frame, so +-0.03 for its 17 frames; -0.18 and -0.23
    # without. 0.1 degree is two to three such errors of the mean from either.
    assert abs(err.mean()) < 0.1, (err.mean(), err)
