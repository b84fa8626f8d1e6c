"""What the tracker found in a video (:class:`TrackResult`), and its trajectory-file table.

The per-frame angles are the raw estimates, their errors independent from frame to frame (the
input of ``fit``); the smoothed copy is for display (:mod:`toywalk.tracking.smooth`). Times are
the frames' own (:mod:`toywalk.tracking.video`; ``timestamps`` says how they were read).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..model.trajectory import SIGNALS, TrajectoryTable

__all__ = ["TrackResult"]


@dataclasses.dataclass
class TrackResult:
    """What :meth:`toywalk.tracking.track.Tracker.finish` found.

    ``n`` below is the number of frames.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Frame timestamps (s).
    raw, raw_sd : dict of str -> ndarray, shape (n,)
        Per-frame angles ``lean, steer, pitch_left, pitch_right`` (rad) and their SDs; NaN = gap.
    smooth, smooth_sd : dict of str -> ndarray, shape (n,)
        The same, smoothed (see ``smoothing``).
    stance : ndarray of str, shape (n,)
        ``'L'``, ``'R'``, or ``''`` where unknown.
    events : list of HeelStrike
        :class:`toywalk.tracking.events.HeelStrike`, in time order.
    pixel_sd : dict body -> float
        Pooled reprojection noise (pixels).
    ramp : dict
        Where the ramp pose came from, and the pose.
    frames_with : dict body -> int
        Frames in which each leg's pose was found.
    counts : dict
        Frames, whole-frame and region searches.
    smoothing : dict
        The smoothing method and its settings.
    poses : dict
        Per frame: ``walker``, the joint leg fits (:class:`~toywalk.tracking.joint.WalkerPose` or
        None); each leg's pose derived from them; the ramp's own fits.
    track_seconds : float
        Wall-clock time spent tracking (s).
    hip_width : float
        The hip width used (m) and, in ``hip_width_source``, where it came from.
    noise : dict
        The legs' pixel noise model: ``marker_pixel_sd`` (marker id -> pixels,
        :func:`toywalk.tracking.angles.pooled_marker_sd`) and ``frame_scale``, the prior of each
        frame's noise scale (:func:`toywalk.tracking.angles.moderated_noise_scales`).
    timestamps : dict
        How the frame times were read (:func:`toywalk.tracking.video.timestamp_summary`):
        ``policy``, ``description``, ``frame_interval_s``; empty until the caller that knows the
        frames' source sets it (:func:`toywalk.tracking.track.track_frames` does).
    """

    time: np.ndarray
    raw: dict
    raw_sd: dict
    smooth: dict
    smooth_sd: dict
    stance: np.ndarray
    events: list
    pixel_sd: dict
    ramp: dict
    frames_with: dict
    counts: dict
    smoothing: dict
    poses: dict
    track_seconds: float = 0.0
    hip_width: float = math.nan
    hip_width_source: str = ""
    noise: dict = dataclasses.field(default_factory=dict)
    timestamps: dict = dataclasses.field(default_factory=dict)

    def table(self, *, smoothed: bool = False, metadata=None) -> TrajectoryTable:
        """The trajectory-file table (docs/formats.md, "Trajectory") of the raw (default) or smoothed signals.

        Parameters
        ----------
        smoothed : bool
            The smoothed copy instead of the raw per-frame estimates.
        metadata : dict, optional
            The table's metadata (``NAME.json``).

        Returns
        -------
        TrajectoryTable
            The angles and their ``*_sd`` columns, the stance and the heel strikes (contact
            positions unknown: NaN).
        """
        values, sds = (self.smooth, self.smooth_sd) if smoothed else (self.raw, self.raw_sd)
        signals = {k: values[k] for k in SIGNALS}
        signals.update({f"{k}_sd": sds[k] for k in SIGNALS})
        events = [{"time": e.time, "foot": e.foot, "x": math.nan, "y": math.nan, "time_sd": e.time_sd}
                  for e in self.events]
        return TrajectoryTable(self.time, signals, self.stance, events, metadata or {})
