"""`toywalk demo`, the front door: every stage runs on bundled data and the video it renders is
tracked back to the issue-4 targets."""

import re
import subprocess

import pytest

from ..tracking.synthetic import TOYWALK


@pytest.mark.slow
def test_demo_runs_every_stage_and_tracks_its_video(tmp_path):
    r = subprocess.run([TOYWALK, "demo", "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    for name in ("gait.json", "walk.csv", "video.mp4", "video.truth.csv", "tracked.csv",
                 "tracked.events.csv", "tracked.smoothed.csv", "tracked.overlay.mp4"):
        assert (tmp_path / name).is_file(), name
    rms = dict(re.findall(r"^\s+(\w+)\s+RMS error ([\d.]+) deg", r.stdout, re.M))
    assert set(rms) == {"lean", "steer", "pitch_left", "pitch_right"}, r.stdout
    # issue 4 targets (measured 0.03-0.12 deg, 18 of 18 strikes at 0.07 frame)
    assert all(float(v) <= (0.5 if k == "steer" else 0.3) for k, v in rms.items()), rms
    found, true, timing = re.search(r"heel strikes (\d+) found, (\d+) true .*timing RMS ([\d.]+) frame",
                                    r.stdout).groups()
    assert found == true and float(timing) <= 0.25
