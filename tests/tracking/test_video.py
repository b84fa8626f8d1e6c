"""Video input (tracking/video.py): each frame's presentation time read from the container, the
timestamp policy recorded, unusable times refused; and the test helper that gives an MP4 file
uneven frame times (mp4times.py), checked by OpenCV's reading of the files it writes."""

import os

import cv2
import numpy as np
import pytest
from toywalk.tracking import video
from toywalk.tracking.video import FrameSource, TrackError, timestamp_summary

from .mp4times import read_boxes, set_frame_times

TIMESCALE = 90000  # ticks/s: the MPEG clock, the times below are whole ticks


def _write(path, n: int, fps: float = 30.0) -> None:
    """``n`` frames of 64x48 pixels, each showing its number."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (64, 48))
    for k in range(n):
        image = np.zeros((48, 64, 3), np.uint8)
        cv2.putText(image, str(k), (4, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.2, (255, 255, 255), 2)
        writer.write(image)
    writer.release()


def _images(path) -> list:
    capture = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, image = capture.read()
        if not ok:
            break
        out.append(image)
    capture.release()
    return out


@pytest.mark.parametrize("moov_first", [False, True], ids=["moov-last", "moov-first"])
def test_uneven_frame_times_are_read_back(tmp_path, moov_first):
    """A phone-like file: intervals from 11 to 67 ms (a dropped frame or two), read by OpenCV
    (CAP_PROP_POS_MSEC) as written, every frame in its place, also with the chunk offsets moved
    (moov before mdat)."""
    path = tmp_path / "v.mp4"
    _write(path, 12)
    images = _images(path)
    deltas = [1500, 3000, 1000, 6000, 1500, 1500, 2000, 1000, 3000, 1500, 1500]  # ticks
    times = np.concatenate([[0], np.cumsum(deltas)]) / TIMESCALE
    set_frame_times(path, times, TIMESCALE, moov_first=moov_first)
    order = [b.kind for b in read_boxes(path)]
    assert (order.index(b"moov") < order.index(b"mdat")) == moov_first
    source = FrameSource(path)
    frames = list(source)
    # milliseconds as a double, divided by 1000: the ticks to a rounding (1e-16 s)
    np.testing.assert_allclose([t for t, _ in frames], times, rtol=0, atol=1e-12)
    # the coded frames are untouched: each decodes to the same image as before
    assert len(frames) == len(images)
    for (_, image), before in zip(frames, images, strict=True):
        np.testing.assert_array_equal(image, before)
    stamps = source.timestamps()
    assert stamps["policy"] == "container" and "CAP_PROP_POS_MSEC" in stamps["description"]
    spread = stamps["frame_interval_s"]
    assert spread["min"] == pytest.approx(1000 / TIMESCALE)
    assert spread["max"] == pytest.approx(6000 / TIMESCALE)


def test_helper_refuses_times_it_cannot_store(tmp_path):
    path = tmp_path / "v.mp4"
    _write(path, 3)
    with pytest.raises(ValueError, match="whole multiples"):
        set_frame_times(path, [0.0, 0.05 + 1e-6, 0.1], TIMESCALE)
    with pytest.raises(ValueError, match="3 frames, 2 times"):
        set_frame_times(path, [0.0, 0.1], TIMESCALE)


class _Capture:
    """A stand-in for ``cv2.VideoCapture`` whose frames carry the given times (ms)."""

    def __init__(self, msec, fps):
        self.msec, self.fps, self.k = list(msec), fps, 0

    def isOpened(self):  # noqa: N802 (OpenCV's name)
        return True

    def get(self, prop):
        return {cv2.CAP_PROP_FRAME_COUNT: len(self.msec), cv2.CAP_PROP_FRAME_WIDTH: 8,
                cv2.CAP_PROP_FRAME_HEIGHT: 6, cv2.CAP_PROP_FPS: self.fps,
                cv2.CAP_PROP_POS_MSEC: self.msec[self.k - 1] if self.k else 0.0}[prop]

    def read(self):
        if self.k == len(self.msec):
            return False, None
        self.k += 1
        return True, np.zeros((6, 8, 3), np.uint8)

    def release(self):
        pass


@pytest.fixture
def fake_video(tmp_path, monkeypatch):
    """A function making a FrameSource over frames with the given times (ms) and nominal rate."""
    path = tmp_path / "v.mp4"
    path.write_bytes(b"\0\0\0\x10ftypisom\0\0\0\0")  # an MP4 header, for the container check

    def make(msec, fps):
        monkeypatch.setattr(video.cv2, "VideoCapture", lambda _: _Capture(msec, fps))
        return FrameSource(path)
    return make


def test_unstamped_frames_take_the_nominal_rate(fake_video):
    source = fake_video([0.0] * 5, 25.0)
    assert [t for t, _ in source] == [k / 25.0 for k in range(5)]
    assert source.timestamps()["policy"] == "nominal frame rate"


def test_unstamped_frames_without_a_rate_are_refused(fake_video):
    with pytest.raises(TrackError, match="stamps no frame with a time and declares no frame rate"):
        list(fake_video([0.0] * 5, 0.0))


def test_times_that_go_back_are_refused(fake_video):
    with pytest.raises(TrackError, match="frame 3 has timestamp 0.02 s, not after the previous 0.04 s"):
        list(fake_video([0.0, 20.0, 40.0, 20.0, 60.0], 50.0))


def test_timestamp_summary():
    got = timestamp_summary("given", [0.0, 0.01, 0.03, 0.04])
    assert got["policy"] == "given"
    assert got["frame_interval_s"] == pytest.approx({"min": 0.01, "median": 0.01, "max": 0.02})
    assert timestamp_summary("given", [0.0])["frame_interval_s"] is None
    with pytest.raises(ValueError, match="policy must be one of"):
        timestamp_summary("guessed", [0.0, 1.0])


def _threads_that_ran(before: dict) -> int:
    """Threads of this process that used CPU time since ``before`` (tid -> utime + stime ticks)."""
    return sum(1 for tid, ticks in _thread_ticks().items() if ticks > before.get(tid, -1))


def _thread_ticks() -> dict:
    out = {}
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended
            continue
        out[tid] = int(fields[11]) + int(fields[12])  # utime, stime (proc(5), from field 3 on)
    return out


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads in Linux's /proc")
def test_decoder_threads_pinned_to_one(tmp_path):
    """decoder_threads=1: the same frames and times as the back end's default, decoded with no
    thread of FFmpeg's own (no thread other than the caller's starts during the decoding)."""
    path = tmp_path / "v.mp4"
    _write(path, 40)
    default = list(FrameSource(path))
    before_tasks = set(os.listdir("/proc/self/task"))
    source = FrameSource(path, decoder_threads=1)
    assert source.decoder_threads == 1
    before = _thread_ticks()
    frames = []
    for frame in source:
        frames.append(frame)
        if len(frames) == 20:  # mid-file: FFmpeg's frame threads would be running now
            assert set(os.listdir("/proc/self/task")) <= before_tasks
    assert _threads_that_ran(before) <= 1  # the caller's (0 if decoding took < 1 tick)
    assert [t for t, _ in frames] == [t for t, _ in default]
    for (_, image), (_, ref) in zip(frames, default, strict=True):
        np.testing.assert_array_equal(image, ref)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "1"])
def test_decoder_threads_refused(tmp_path, bad):
    path = tmp_path / "v.mp4"
    _write(path, 2)
    with pytest.raises(ValueError, match="decoder_threads must be None or an integer >= 1"):
        FrameSource(path, decoder_threads=bad)
