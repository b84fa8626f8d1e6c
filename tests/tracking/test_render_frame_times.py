"""Rendering at given, uneven frame times (tracking/render.py ``RenderOptions.frame_times``), the
renderer's half of a variable-frame-rate video (test_track_vfr.py tracks one)."""

import pytest
from toywalk.tracking.render import RenderError, RenderOptions


def test_frame_times_are_kept_as_given():
    options = RenderOptions.preset(1, frame_times=[0.0, 0.013, 0.04])
    assert options.frame_times == (0.0, 0.013, 0.04)  # a tuple: options stay hashable
    hash(options)


@pytest.mark.parametrize(("times", "extra", "words"), [
    ([0.0, 0.02, 0.02], {}, "increasing strictly"),
    ([0.0, float("nan")], {}, "finite times"),
    ([], {}, "at least one"),
    ("abc", {}, "a sequence of times"),
    ([0.0, 0.02], {"duration": 1.0}, "not both"),
    ([0.0, 0.02], {"start": 0.0}, "not both"),
])
def test_bad_frame_times_are_refused(times, extra, words):
    with pytest.raises(RenderError, match=words):
        RenderOptions(frame_times=times, **extra)
