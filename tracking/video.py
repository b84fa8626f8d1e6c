"""Video input for the tracker: a file's frames, each with its presentation time.

A phone films at a variable frame rate: the spacing of its frames follows the exposure time, and
the container (an MP4's time-to-sample table ``stts``, ISO/IEC 14496-12 section 8.6.1.2) holds
each frame's own time. The tracker uses those times, never ``index / fps``. OpenCV's FFmpeg back
end reports the presentation time of the frame just decoded as ``CAP_PROP_POS_MSEC``
(FFmpeg's best-effort timestamp; checked with opencv-python-headless 5.0 on MP4 files whose
``stts`` holds uneven deltas: tests/tracking/test_track_vfr.py).

Timestamp policies (:attr:`FrameSource.timestamp_policy`, recorded in the trajectory's metadata):

- ``"container"``: each frame's presentation time from the container, used as given; they must
  increase strictly (else the file is refused as corrupt);
- ``"nominal frame rate"``: a container that stamps no frame (the first two frames both at 0 ms,
  FFmpeg's answer for missing timestamps) is read at ``index / nominal_fps``, its declared rate.
"""

from __future__ import annotations

import math
import time as _time
from pathlib import Path

import cv2
import numpy as np

__all__ = ["TIMESTAMP_POLICIES", "FrameSource", "TrackError", "declared_fps", "declared_size",
           "open_video", "timestamp_summary"]

#: Timestamp policies (module docstring) and what each means, for the trajectory's metadata.
TIMESTAMP_POLICIES = {
    "container": "per-frame container timestamps (OpenCV CAP_PROP_POS_MSEC read after each frame: "
                 "the presentation time of that frame), not an assumed frame rate",
    "nominal frame rate": "the container stamps no frame: frame k at k / the container's nominal "
                          "frame rate (CAP_PROP_FPS)",
    "given": "the times given with the frames (toywalk.tracking.track.track_frames)",
}


def timestamp_summary(policy: str, times) -> dict:
    """A timestamp policy and the frame spacing it gave, for the trajectory's metadata.

    Parameters
    ----------
    policy : str
        A key of :data:`TIMESTAMP_POLICIES`.
    times : array_like, shape (n,)
        The frame times (s).

    Returns
    -------
    dict
        ``policy``, ``description`` (from :data:`TIMESTAMP_POLICIES`) and ``frame_interval_s``:
        the ``min``, ``median`` and ``max`` spacing of the frames (s; None with fewer than two).
    """
    if policy not in TIMESTAMP_POLICIES:
        raise ValueError(f"policy must be one of {', '.join(TIMESTAMP_POLICIES)}, got {policy!r}")
    gaps = np.diff(np.asarray(times, float))
    spread = None if not len(gaps) else {"min": float(gaps.min()), "median": float(np.median(gaps)),
                                         "max": float(gaps.max())}
    return {"policy": policy, "description": TIMESTAMP_POLICIES[policy], "frame_interval_s": spread}


class TrackError(ValueError):
    """Bad input to the tracker (unreadable video, size mismatch, no markers): one-line message."""


class FrameSource:
    """Frames of a video file with their presentation times.

    Iterating yields ``(time, image)``: seconds (by :attr:`timestamp_policy`, module docstring)
    and a BGR array (rows, cols, 3). At the end it checks that as many frames decoded as the
    container declares and that the times increase, raising :class:`TrackError` otherwise (a
    truncated or corrupt file).

    Parameters
    ----------
    path : str or Path
        The video file.
    decoder_threads : int, optional
        Threads FFmpeg may decode with (>= 1). None (the default) leaves the choice to OpenCV's
        FFmpeg back end, which uses as many as the machine has cores; a number opens the file with
        that back end and ``CAP_PROP_N_THREADS`` (1: decoding stays on the calling thread, for
        timing a single-threaded pipeline). Only FFmpeg's decoder threads: OpenCV's own are set by
        ``cv2.setNumThreads``. (The ``OPENCV_FFMPEG_CAPTURE_OPTIONS`` variable's ``threads;1``
        does not reach the decoder: checked with opencv-python-headless 5.0.)

    Attributes
    ----------
    width, height : int
        Image size (pixels).
    nominal_fps : float
        The container's declared frame rate (frames/s; 0 if none): for display, and for the
        ``"nominal frame rate"`` policy only.
    declared_frames : int
        Frames the container declares (0 if unknown).
    frames_read : int
        Frames decoded so far.
    decode_seconds : float
        Wall-clock time spent decoding (s).
    timestamp_policy : str or None
        A key of :data:`TIMESTAMP_POLICIES`, set once the first two frames are read.
    decoder_threads : int or None
        The decoder threads asked for (None: the back end's choice).
    """

    def __init__(self, path: str | Path, *, decoder_threads: int | None = None):
        self.path = Path(path)
        if not self.path.exists():
            raise TrackError(f"video file not found: {self.path}")
        if not self.path.is_file():
            raise TrackError(f"not a video file: {self.path}")
        if decoder_threads is not None and (isinstance(decoder_threads, bool)
                                            or not isinstance(decoder_threads, (int, np.integer))
                                            or decoder_threads < 1):
            raise ValueError(f"decoder_threads must be None or an integer >= 1, got {decoder_threads!r}")
        self.decoder_threads = None if decoder_threads is None else int(decoder_threads)
        _check_container(self.path)
        if self.decoder_threads is None:
            self._cap = cv2.VideoCapture(str(self.path))
        else:
            self._cap = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG,
                                         [cv2.CAP_PROP_N_THREADS, self.decoder_threads])
        if not self._cap.isOpened():
            raise TrackError(f"cannot open video {self.path}: not a readable video file (corrupt or "
                             "truncated?)")
        if self.decoder_threads is not None:
            got = int(self._cap.get(cv2.CAP_PROP_N_THREADS))
            if got != self.decoder_threads:
                self._cap.release()
                raise TrackError(f"{self.path}: asked FFmpeg for {self.decoder_threads} decoder "
                                 f"thread(s), the back end reports {got}")
        self.declared_frames = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        self.width = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        self.height = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self.nominal_fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.frames_read = 0
        self.decode_seconds = 0.0
        self.timestamp_policy: str | None = None
        self._times: list[float] = []

    def __iter__(self):
        last = -math.inf
        try:
            while True:
                start = _time.perf_counter()
                ok, image = self._cap.read()
                self.decode_seconds += _time.perf_counter() - start
                if not ok or image is None:
                    break
                t = self._cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0
                if self.frames_read == 1 and self.timestamp_policy is None:
                    self.timestamp_policy = "container" if t != 0.0 or last != 0.0 else \
                        self._unstamped()
                if self.timestamp_policy == "nominal frame rate":
                    t = self.frames_read / self.nominal_fps
                if not (math.isfinite(t) and t > last):
                    raise TrackError(f"{self.path}: frame {self.frames_read} has timestamp {t:.6g} s, "
                                     f"not after the previous {last:.6g} s: unusable timestamps")
                last = t
                self.frames_read += 1
                self._times.append(t)
                yield t, image
        finally:
            self._cap.release()
        if self.frames_read == 0:
            raise TrackError(f"{self.path}: no frame could be decoded (corrupt or empty video)")
        if self.timestamp_policy is None:  # one frame: its time is 0 either way
            self.timestamp_policy = "container"
        if self.declared_frames > 0 and self.frames_read < self.declared_frames:
            raise TrackError(f"{self.path}: decoded only {self.frames_read} of the "
                             f"{self.declared_frames} frames the container declares (truncated or corrupt)")

    def _unstamped(self) -> str:
        """The policy for a container whose first two frames are both at 0 ms (no timestamps)."""
        if not (math.isfinite(self.nominal_fps) and self.nominal_fps > 0):
            raise TrackError(f"{self.path}: the container stamps no frame with a time and declares no "
                             "frame rate: the frames' times are unknown")
        return "nominal frame rate"

    def timestamps(self) -> dict:
        """The timestamp policy used and the spacing of the frames read
        (:func:`timestamp_summary`), for the trajectory's metadata."""
        if self.timestamp_policy is None:
            raise RuntimeError("no timestamps yet: iterate over the frames first")
        return timestamp_summary(self.timestamp_policy, self._times)


#: What the first bytes of a video file are for its suffix: an ISO base-media (MP4, QuickTime)
#: file starts with a box whose type is at bytes 4-8 (ISO/IEC 14496-12; QuickTime files may open
#: with moov, mdat or a free-space box); an AVI file is a RIFF file of form "AVI " (bytes 8-12).
_CONTAINERS = {
    ".mp4": ("MP4", lambda head: head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide")),
    ".m4v": ("MP4", lambda head: head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"skip", b"wide")),
    ".mov": ("QuickTime", lambda head: head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"skip",
                                                     b"wide", b"pnot")),
    ".avi": ("AVI", lambda head: head[:4] == b"RIFF" and head[8:12] == b"AVI "),
}


def _check_container(path: Path) -> None:
    """Refuse a file whose first bytes are not the container its suffix names (an image, a text
    file or a video cut at its start): FFmpeg would otherwise guess, e.g. read an MP4 that lost its
    first bytes as a raw stream with invented timestamps."""
    kind = _CONTAINERS.get(path.suffix.lower())
    if kind is None:
        return
    try:
        with open(path, "rb") as fh:
            head = fh.read(12)
    except OSError as err:
        raise TrackError(f"cannot read video {path}: {err.strerror or err}") from err
    if not head:
        raise TrackError(f"cannot open video {path}: the file is empty")
    if not kind[1](head):
        raise TrackError(f"cannot open video {path}: not an {kind[0]} file (its first bytes are not "
                         f"an {kind[0]} header): a mislabelled file, or a video cut at its start")


def _declared(path: str | Path, *props: int) -> tuple[float, ...] | None:
    """The container's values of OpenCV capture properties ``props``, without decoding a frame;
    None where the file cannot be opened."""
    cap = cv2.VideoCapture(str(path))
    try:
        return tuple(float(cap.get(p) or 0.0) for p in props) if cap.isOpened() else None
    finally:
        cap.release()


def declared_fps(path: str | Path) -> float:
    """The frame rate a video's container declares (frames/s; 0 where it declares none or cannot
    be opened), without decoding a frame."""
    fps = (_declared(path, cv2.CAP_PROP_FPS) or (0.0,))[0]
    return fps if math.isfinite(fps) and fps > 0 else 0.0


def declared_size(path: str | Path) -> tuple[int, int] | None:
    """The frame size (width, height) in pixels a video's stream declares, without decoding a
    frame; None where the file cannot be opened."""
    got = _declared(path, cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT)
    size = (0, 0) if got is None else (int(got[0]), int(got[1]))
    return size if min(size) > 0 else None


def open_video(path: str | Path, *, decoder_threads: int | None = None) -> FrameSource:
    """A :class:`FrameSource` for ``path``.

    Parameters
    ----------
    path : str or Path
        The video file.
    decoder_threads : int, optional
        As in :class:`FrameSource` (None: the back end's choice).

    Returns
    -------
    FrameSource

    Raises
    ------
    TrackError
        If the file is missing, not the container its suffix names, or cannot be opened.
    ValueError
        If ``decoder_threads`` is not None or an integer >= 1.
    """
    return FrameSource(path, decoder_threads=decoder_threads)
