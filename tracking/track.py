"""Video to trajectory: markers, leg poses, walker angles, heel strikes (pipeline.md, ``track``).

Per frame (:class:`Tracker`):

1. predict each body's pose from its last two (constant velocity) and search for markers only in
   regions of interest around the predicted corners of its markers that face the camera; the whole
   frame is searched when a body has no prediction (not yet found, or lost), at growing intervals
   while it stays lost;
2. estimate each body's pose in the camera frame from all its visible marker corners jointly
   (:func:`toywalk.tracking.pose.estimate_pose`), with ``(J^T J)^-1`` kept for the covariance.

After the last frame (:meth:`Tracker.finish`):

3. the ramp pose, measured from the ramp markers whenever the video shows them
   (:mod:`toywalk.tracking.ramp`): one pose fitted to all frames jointly (a fixed camera), else,
   if the frames disagree (a moving camera), each frame's own; a camera file's fixed
   ``ramp_pose`` is checked against it, refused if they disagree beyond the measurement's
   accuracy, and used where they agree or no ramp marker is seen;
4. the leg rotations in the ramp frame give ``steer, lean, pitch_left, pitch_right`` through
   :func:`toywalk.model.kinematics.angles_from_rotations` (one leg seen: steer and lean from that
   leg's hip axis, the other pitch a gap); standard deviations propagate
   ``sigma^2 (J^T J)^-1``, with the pixel noise ``sigma`` pooled over the video from the
   reprojection residuals, through the angle functions (finite differences);
5. frames whose angles jump away from both neighbouring stretches (a mirrored single-marker pose)
   become gaps; heel strikes and stance (:mod:`toywalk.tracking.events`) from the raw pitches;
6. a smoothed copy of the signals (Savitzky-Golay, Savitzky & Golay 1964, Anal. Chem. 36:1627,
   doi:10.1021/ac60214a047) over stretches without gaps or heel strikes (the rates jump there).

Missing samples are NaN, never invented. Times are the container's per-frame timestamps.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from pathlib import Path

import cv2
import numpy as np
from scipy.signal import savgol_coeffs, savgol_filter

from ..model.kinematics import angles_from_rotations, rotation
from ..model.trajectory import SIGNALS, TrajectoryTable
from .camera import Camera
from .detect import MarkerDetector, merge_regions
from .events import (
    fit_samples_per_side,
    heel_strikes,
    isolated_outliers,
    noise_sd,
    stance_from_events,
    step_samples,
)
from .joint import FEET, WalkerPose, fit_walker, rot_y, walker_from_legs
from .markers import MarkerLayout, body_points
from .pose import PoseEstimate, estimate_pose
from .ramp import fixed_ramp, measure_ramp

__all__ = ["FrameSource", "TrackError", "TrackResult", "Tracker", "angles_with_sd", "open_video",
           "track_frames", "track_video", "walker_angles", "walker_angles_with_sd"]

LEGS = {"left_leg": "L", "right_leg": "R"}
_WIDTH_SAMPLES = 25  # frames whose joint fits estimate the hip width (when not given)


class TrackError(ValueError):
    """Bad input to the tracker (unreadable video, size mismatch, no markers): one-line message."""


# --- video input ----------------------------------------------------------------------------------

class FrameSource:
    """Frames of a video file with the container's timestamps.

    Iterating yields ``(time, image)``: seconds (``CAP_PROP_POS_MSEC`` read after each frame, the
    presentation time of that frame) and a BGR array (rows, cols, 3). At the end it checks that as
    many frames decoded as the container declares and that the times increase, raising
    :class:`TrackError` otherwise (a truncated or corrupt file).
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            raise TrackError(f"video file not found: {self.path}")
        if not self.path.is_file():
            raise TrackError(f"not a video file: {self.path}")
        _check_container(self.path)
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise TrackError(f"cannot open video {self.path}: not a readable video file (corrupt or "
                             "truncated?)")
        self.declared_frames = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        self.width = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        self.height = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        self.nominal_fps = float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0)
        self.frames_read = 0
        self.decode_seconds = 0.0

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
                if not (math.isfinite(t) and t > last):
                    raise TrackError(f"{self.path}: frame {self.frames_read} has timestamp {t:.6g} s, "
                                     f"not after the previous {last:.6g} s: unusable timestamps")
                last = t
                self.frames_read += 1
                yield t, image
        finally:
            self._cap.release()
        if self.frames_read == 0:
            raise TrackError(f"{self.path}: no frame could be decoded (corrupt or empty video)")
        if self.declared_frames > 0 and self.frames_read < self.declared_frames:
            raise TrackError(f"{self.path}: decoded only {self.frames_read} of the "
                             f"{self.declared_frames} frames the container declares (truncated or corrupt)")


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


def open_video(path: str | Path) -> FrameSource:
    """A :class:`FrameSource` for ``path`` (raises :class:`TrackError` if it cannot be opened)."""
    return FrameSource(path)


# --- per-frame tracking ---------------------------------------------------------------------------

@dataclasses.dataclass
class _Body:
    name: str
    points: dict  # marker id -> (4, 3) corners in the body frame
    centres: np.ndarray  # (k, 3) marker centres
    normals: np.ndarray  # (k, 3) marker face normals
    ids: list
    sides: np.ndarray  # (k,) marker sides (m)
    history: list = dataclasses.field(default_factory=list)  # [(frame, time, rvec, tvec)]


def _make_bodies(layout: MarkerLayout, names) -> dict[str, _Body]:
    out = {}
    for name in names:
        markers = layout.on(name)
        if not markers:
            continue
        pts = body_points(layout, name)
        ids = [m.id for m in markers]
        normals = np.array([cv2.Rodrigues(m.rvec.reshape(3, 1))[0][:, 2] for m in markers])
        out[name] = _Body(name=name, points=pts, ids=ids, centres=np.array([m.tvec for m in markers]),
                          normals=normals, sides=np.array([m.side for m in markers]))
    return out


class Tracker:
    """Frame-by-frame marker search and body poses; :meth:`finish` turns them into angles.

    Parameters
    ----------
    camera : Camera
    layout : MarkerLayout
    roi : bool
        Search regions of interest around predicted marker positions (default), and recover leg
        markers the detector missed where the joint fit or the prediction puts them (verified by
        their bits, :meth:`_recover`); False searches the whole frame every time and recovers
        nothing (slower; a reference for tests).
    max_full_search_interval : int
        While a body is lost, the whole frame is searched at intervals 1, 2, 4, ... frames, up to this.
    outlier_rms : float
        A body's fit with a larger RMS reprojection error (pixels) is retried without each of its
        markers in turn.
    hip_width : float, optional
        Distance between the legs' hip points along the axle (m; the parameter file's
        ``hip_width``). None estimates it as the median of the joint fits with the width free in
        the first 25 frames in which both legs show two markers or more; :meth:`finish` refits
        the frames fitted with another width.
    """

    def __init__(self, camera: Camera, layout: MarkerLayout, *, roi: bool = True,
                 max_full_search_interval: int = 16, outlier_rms: float = 0.5,
                 hip_width: float | None = None):
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a Camera, got {type(camera).__name__}")
        if not isinstance(layout, MarkerLayout):
            raise TypeError(f"layout must be a MarkerLayout, got {type(layout).__name__}")
        self.camera = camera
        self.layout = layout
        # the ramp markers are tracked even where the camera file fixes the ramp pose: they check it
        self.bodies = _make_bodies(layout, ["left_leg", "right_leg", "ramp"])
        if not any(name in self.bodies for name in LEGS):
            raise TrackError("the marker layout has no marker on either leg")
        if camera.ramp_pose is None and "ramp" not in self.bodies:
            raise TrackError("the camera file has no ramp_pose and the marker layout no ramp marker: "
                             "the ramp frame cannot be found")
        # each body's marker corners in its frame, (k, 4, 3), in the order of its ids
        self._corners = {name: np.array([b.points[i] for i in b.ids]).reshape(-1, 4, 3)
                         for name, b in self.bodies.items()}
        wanted = [i for b in self.bodies.values() for i in b.ids]
        self._owner = {i: b.name for b in self.bodies.values() for i in b.ids}
        self.detector = MarkerDetector(layout.dictionary, ids=wanted, camera=camera)
        self.roi = roi
        self.max_full_search_interval = int(max_full_search_interval)
        self.outlier_rms = float(outlier_rms)
        if hip_width is not None and not (math.isfinite(float(hip_width)) and float(hip_width) >= 0):
            raise ValueError(f"hip_width must be a length >= 0 (m) or None, got {hip_width!r}")
        self.hip_width_given = None if hip_width is None else float(hip_width)
        self._width_samples: list[float] = []
        self._width_in_use = (-1, math.nan)  # (samples, self.hip_width from them)
        self.walker: list[WalkerPose | None] = []
        self._observations: list[dict | None] = []
        self.times: list[float] = []
        self.poses: dict[str, list] = {name: [] for name in self.bodies}
        self.detections: list[dict] = []
        self.recovered: list[list[int]] = []  # per frame: leg marker ids found by recovery
        self.counts = {"frames": 0, "full_searches": 0, "roi_searches": 0}
        self._full_interval = 1
        self._last_full = -10**9
        self.track_seconds = 0.0

    # prediction and search regions
    def _predict(self, body: _Body, frame: int):
        hist = [h for h in body.history if frame - h[0] <= 3]
        if not hist:
            return None
        f1, _, r1, t1 = hist[-1]
        if len(hist) >= 2:
            f0, _, r0, t0 = hist[-2]
            k = (frame - f1) / (f1 - f0)
            # constant velocity; rvec increments of a few degrees add up to first order
            return r1 + k * (r1 - r0), t1 + k * (t1 - t0), (r1 - r0, t1 - t0)
        return r1, t1, (np.zeros(3), np.zeros(3))

    def _regions(self, body: _Body, pred) -> list:
        rvec, tvec, (dr, dt) = pred
        rot = cv2.Rodrigues(rvec.reshape(3, 1))[0]
        centres = body.centres @ rot.T + tvec
        normals = body.normals @ rot.T
        facing = np.einsum("ij,ij->i", normals, centres) < 0
        if not facing.any():
            return []
        # all facing markers' corners projected at once, (k, 4, 2)
        corners = self._corners[body.name][facing].reshape(-1, 3)
        uv = self._project(corners, rvec, tvec).reshape(-1, 4, 2)
        # margin: the marker's quiet zone plus how far a prediction error of one frame's motion
        # moves it (the motion itself is already in the prediction)
        motion = self._project(corners, rvec + dr, tvec + dt).reshape(-1, 4, 2) - uv
        seen = np.all(np.isfinite(uv), axis=(1, 2))
        uv, motion = uv[seen], motion[seen]
        if not len(uv):
            return []
        lo, hi = uv.min(axis=1), uv.max(axis=1)
        size = np.max(hi - lo, axis=1)
        moving = np.all(np.isfinite(motion), axis=(1, 2))
        reach = np.max(np.abs(np.where(moving[:, None, None], motion, 0.0)), axis=(1, 2))
        slack = np.where(moving, 0.35 * size + 8.0 + reach, 0.5 * size + 8.0)
        self._min_side = min(self._min_side, float(np.min(hi - lo)))
        return list(zip(lo[:, 0] - slack, lo[:, 1] - slack, hi[:, 0] + slack + 1, hi[:, 1] + slack + 1,
                        strict=True))

    def _project(self, points, rvec, tvec):
        uv, _ = cv2.projectPoints(points.reshape(-1, 1, 3), rvec.reshape(3, 1), tvec.reshape(3, 1),
                                  self.camera.matrix, self.camera.distortion)
        return uv.reshape(-1, 2)

    def process(self, t: float, image: np.ndarray) -> dict:
        """Track one frame (time ``t`` in s, BGR or grey image); returns this frame's record.

        The record holds ``markers`` (id -> corners (4, 2)) and ``poses`` (body -> PoseEstimate).
        """
        start = _time.perf_counter()
        frame = len(self.times)
        if frame == 0 and image.shape[1::-1] != self.camera.size:
            raise TrackError(f"the video frames are {image.shape[1]}x{image.shape[0]} pixels but the "
                             f"camera file describes {self.camera.width}x{self.camera.height}")
        preds = {name: self._predict(b, frame) if self.roi else None for name, b in self.bodies.items()}
        fixed = self.camera.ramp_pose
        if self.roi and preds.get("ramp") is None and fixed is not None and "ramp" in self.bodies:
            preds["ramp"] = (fixed[0], fixed[1], (np.zeros(3), np.zeros(3)))  # where the file says
        lost = [name for name, p in preds.items() if p is None]
        found: dict = {}
        searched_full = False
        # the legs' markers and the ramp's are sought apart: each group's regions with its own
        # smallest marker size (the detector's thresholds depend on it)
        searched = False
        for group in (tuple(LEGS), ("ramp",)):
            regions = []
            self._min_side = math.inf  # smallest predicted marker extent (pixels), set by _regions
            for name in group:
                if preds.get(name) is not None:
                    regions += self._regions(self.bodies[name], preds[name])
            if regions:
                more = self.detector.detect(image, merge_regions(regions, self.camera.width,
                                                                 self.camera.height),
                                            min_side=self._min_side)
                for i, c in more.items():  # a marker in both groups' regions: the first's find
                    found.setdefault(i, c)
                searched = True
        self.counts["roi_searches"] += searched
        # bodies predicted but not found in their regions count as lost
        for name, p in preds.items():
            if p is not None and not any(self._owner[i] == name for i in found):
                lost.append(name)
        # a ramp lost where the camera file fixes its pose is not worth whole-frame searches (its
        # markers are only a check of that pose); the first frame's search looks for it anyway
        lost = [name for name in lost if name in LEGS or fixed is None]
        if lost and frame - self._last_full >= self._full_interval:
            full = self.detector.detect(image)
            searched_full = True
            self.counts["full_searches"] += 1
            self._last_full = frame
            for i, c in full.items():
                found.setdefault(i, c)
        poses = {}
        for name, body in self.bodies.items():
            if name in LEGS:
                continue
            ids = [i for i in body.ids if i in found]
            if not ids:
                self.poses[name].append(None)
                continue
            guess = preds[name][:2] if preds[name] is not None else None
            est = self._fit_body(body, ids, found, guess)
            self.poses[name].append(est)
            if est is not None:
                poses[name] = est
                body.history.append((frame, t, est.rvec, est.tvec))
                del body.history[:-2]
        walker, used = self._fit_walker(found, preds)
        recovered = self._recover(image, found, preds, walker) if self.roi else {}
        if recovered:
            found = {**found, **recovered}
            walker, used = self._fit_walker(found, preds)
            self.counts["recovered"] = self.counts.get("recovered", 0) + len(recovered)
        if walker is not None and "hip_width" in walker.names:
            self._width_samples.append(walker.hip_width)
        self.recovered.append(sorted(recovered))
        self.walker.append(walker)
        self._observations.append(used)
        for name, foot in LEGS.items():
            if name not in self.bodies:
                continue
            if walker is None or foot not in walker.seen:
                self.poses[name].append(None)
                continue
            rvec, tvec = walker.leg_pose(foot)
            est = PoseEstimate(rvec=rvec, tvec=tvec, rms=walker.rms, n_points=walker.n_points[foot],
                               normal=np.full((6, 6), np.nan))  # see self.walker for the covariance
            self.poses[name].append(est)
            poses[name] = est
            self.bodies[name].history.append((frame, t, rvec, tvec))
            del self.bodies[name].history[:-2]
        if searched_full:
            still_lost = [n for n in lost if n not in poses]
            self._full_interval = (1 if not still_lost
                                   else min(2 * self._full_interval, self.max_full_search_interval))
        self.times.append(float(t))
        self.detections.append(found)
        self.counts["frames"] += 1
        self.track_seconds += _time.perf_counter() - start
        return {"markers": found, "poses": poses, "recovered": self.recovered[-1]}

    def _recover(self, image: np.ndarray, found: dict, preds: dict, walker) -> dict:
        """Leg markers the detector missed, found at their expected corners and verified by their
        bits (:meth:`toywalk.tracking.detect.MarkerDetector.recover`).

        Expected corners come from this frame's joint fit for a leg it saw (through other
        markers), else from the leg's constant-velocity prediction; only markers facing the
        camera (by more than 10 degrees from edge-on) and at least 12 px wide are sought.
        Returns id -> corners (4, 2).
        """
        out = {}
        for name, foot in LEGS.items():
            body = self.bodies.get(name)
            if body is None:
                continue
            missing = [k for k, i in enumerate(body.ids) if i not in found]
            if not missing:
                continue
            if walker is not None and foot in walker.seen:
                rvec, tvec = walker.leg_pose(foot)
            elif preds.get(name) is not None:
                rvec, tvec = preds[name][:2]
            else:
                continue
            rot = cv2.Rodrigues(np.asarray(rvec, float).reshape(3, 1))[0]
            tvec = np.asarray(tvec, float).reshape(3)
            for k in missing:
                centre = rot @ body.centres[k] + tvec
                if (rot @ body.normals[k]) @ centre > -0.17 * np.linalg.norm(centre):  # sin 10 deg
                    continue
                marker_id = body.ids[k]
                uv = self._project(body.points[marker_id], rvec, tvec)
                if not np.all(np.isfinite(uv)) or np.min(np.ptp(uv, axis=0)) < 12.0:
                    continue
                corners = self.detector.recover(image, marker_id, uv)
                if corners is not None:
                    out[marker_id] = corners
        return out

    @property
    def hip_width(self) -> float:
        """The hip width in use (m): the given one, else the median of the estimates so far (0 if
        none yet)."""
        if self.hip_width_given is not None:
            return self.hip_width_given
        # single estimates scatter about a small true width on both sides of 0
        return max(float(np.median(self._width_samples)), 0.0) if self._width_samples else 0.0

    def _leg_observations(self, found: dict, drop=None) -> dict:
        obs = {}
        for name, foot in LEGS.items():
            body = self.bodies.get(name)
            if body is None:
                continue
            ids = [i for i in body.ids if i in found and i != drop]
            if ids:
                obs[foot] = (np.concatenate([body.points[i] for i in ids]),
                             np.concatenate([found[i] for i in ids]), ids)
        return obs

    def _fit_walker(self, found: dict, preds: dict):
        """Joint fit of both legs (:mod:`toywalk.tracking.joint`) to this frame's leg markers.

        Starting points: the constant-velocity prediction of each seen leg; if that fit is poor
        (RMS above ``outlier_rms``) or there is no prediction, also each seen leg's own PnP pose
        (IPPE / SQPnP, nearest the prediction) taken as the axle frame. The best fit wins; among
        fits alike, the one nearest the prediction. A marker that disagrees with the others is
        dropped when leaving it out makes the fit much better.
        Returns (WalkerPose or None, the observations used).
        """
        obs = self._leg_observations(found)
        if not obs:
            return None, None
        best = self._best_walker(obs, preds)
        n_markers = sum(len(o[2]) for o in obs.values())
        if n_markers >= 3 and (best is None or best.rms > self.outlier_rms):
            trials = []
            for foot in obs:
                for i in obs[foot][2]:
                    sub = self._leg_observations(found, drop=i)
                    w = self._best_walker(sub, preds)
                    if w is not None:
                        trials.append((w, sub))
            if trials:
                w, sub = min(trials, key=lambda x: x[0].rms)
                if best is None or w.rms < 0.5 * best.rms:
                    self.counts["markers_dropped"] = self.counts.get("markers_dropped", 0) + 1
                    best, obs = w, sub
        if best is None:
            return None, None
        return best, {f: o[:2] for f, o in obs.items()}

    def _best_walker(self, obs: dict, preds: dict):
        if self._width_in_use[0] != len(self._width_samples):  # the median changes with the samples
            self._width_in_use = (len(self._width_samples), self.hip_width)
        width = self._width_in_use[1]
        # the hip width is a constant: estimated in the first frames that show it well, then fixed
        fit_width = self.hip_width_given is None and len(self._width_samples) < _WIDTH_SAMPLES and \
            len(obs) == 2 and all(len(o[2]) >= 2 for o in obs.values())
        data = {f: o[:2] for f, o in obs.items()}
        predicted = {}
        for name, foot in LEGS.items():
            p = preds.get(name)
            if p is not None:
                predicted[foot] = (cv2.Rodrigues(np.asarray(p[0], float).reshape(3, 1))[0],
                                   np.asarray(p[1], float).reshape(3))
        prefer = max(obs, key=lambda f: len(obs[f][2]))
        fits = []

        def attempt(legs, ref):
            if not all(f in legs for f in obs):
                return
            axle, pitch, hip = walker_from_legs(legs, width, prefer=ref)
            w = fit_walker(self.camera, data, (axle, pitch, hip), hip_width=width,
                           fit_hip_width=fit_width)
            if w is not None and np.isfinite(w.rms) and (not fit_width or abs(w.hip_width) < 10.0):
                fits.append(w)

        attempt(predicted, prefer)
        if fits and fits[0].rms <= self.outlier_rms:
            return fits[0]
        own = {}
        for name, foot in LEGS.items():
            if foot in obs:
                guess = preds[name][:2] if preds.get(name) is not None else None
                est = estimate_pose(self.camera, obs[foot][0], obs[foot][1], guess=guess)
                if est is not None:
                    own[foot] = (cv2.Rodrigues(est.rvec.reshape(3, 1))[0], est.tvec)
        for ref in obs:
            legs = {**predicted, **own} if ref in own else {}
            if ref in own:
                attempt(legs, ref)
        if not fits:
            return None
        best = min(fits, key=lambda w: w.rms)
        if predicted:
            alike = [w for w in fits if w.rms <= max(1.5 * best.rms, best.rms + 0.2)]

            def distance(w):
                return sum(_angle_between(w.rotation(f), predicted[f][0]) for f in w.seen
                           if f in predicted)

            best = min(alike, key=distance)
        return best

    def _fit_body(self, body: _Body, ids: list, found: dict, guess):
        """Pose from all visible markers; a marker that disagrees with the others (partly hidden,
        a wrong corner) is dropped when leaving it out makes the fit much better."""
        def fit(use):
            obj = np.concatenate([body.points[i] for i in use])
            img = np.concatenate([found[i] for i in use])
            return estimate_pose(self.camera, obj, img, guess=guess)

        est = fit(ids)
        if len(ids) >= 2 and (est is None or est.rms > self.outlier_rms):
            trials = [(fit([j for j in ids if j != i]), i) for i in ids]
            trials = [(e, i) for e, i in trials if e is not None]
            if trials:
                best, dropped = min(trials, key=lambda x: x[0].rms)
                if est is None or best.rms < 0.5 * est.rms:
                    self.counts["markers_dropped"] = self.counts.get("markers_dropped", 0) + 1
                    est = best
        return est

    def draw(self, image: np.ndarray, record: dict) -> np.ndarray:
        """The frame with the detected markers outlined and each body's axes drawn (in place)."""
        if record["markers"]:
            ids = np.array(list(record["markers"]), dtype=np.int32).reshape(-1, 1)
            corners = [c.reshape(1, 4, 2).astype(np.float32) for c in record["markers"].values()]
            cv2.aruco.drawDetectedMarkers(image, corners, ids)
        poses = dict(record["poses"])
        if self.camera.ramp_pose is not None:
            rv, tv = self.camera.ramp_pose
            cv2.drawFrameAxes(image, self.camera.matrix, self.camera.distortion, rv, tv, 0.05)
        for name, est in poses.items():
            length = 0.03 if name in LEGS else 0.05
            cv2.drawFrameAxes(image, self.camera.matrix, self.camera.distortion, est.rvec, est.tvec,
                              length)
        return image

    def finish(self, *, smoothing_window: int = 7, smoothing_order: int = 3) -> TrackResult:
        """Angles, their standard deviations, heel strikes, stance and smoothed signals."""
        n = len(self.times)
        if n == 0:
            raise TrackError("no frames to track")
        time = np.asarray(self.times)
        seen = {name: sum(p is not None for p in self.poses.get(name, [])) for name in LEGS}
        if not any(seen.values()):
            raise TrackError(f"no leg markers found in any of the {n} frames")
        walker = self._final_walker()
        pixel_sd = {name: _pooled_pixel_sd(self.poses[name]) for name in self.bodies if name not in LEGS}
        legs_sd = _pooled_walker_sd(walker)
        pixel_sd.update({name: legs_sd for name in LEGS if name in self.bodies})
        ramp = self._ramp_frame(n, pixel_sd.get("ramp"))
        raw = {k: np.full(n, np.nan) for k in SIGNALS}
        sd = {k: np.full(n, np.nan) for k in SIGNALS}
        for i in range(n):
            r_ramp = ramp.rotations[i]
            if r_ramp is None or walker[i] is None:
                continue
            values, sds = walker_angles_with_sd(r_ramp, walker[i], legs_sd,
                                                ramp.covariance[i] if ramp.per_frame else None)
            for k in SIGNALS:
                raw[k][i], sd[k][i] = values[k], sds[k]
        rejected = _inconsistent_frames(raw)
        for k in SIGNALS:
            raw[k][rejected] = np.nan
            sd[k][rejected] = np.nan
        self.counts["rejected_frames"] = int(rejected.sum())
        # 7 samples a side: on rendered video (blur, pose noise ~0.1 deg) they time the strikes
        # better than 5 (benchmarks/TRACKING.md); the kink still has 7 frames on each side at 60 fps
        events = heel_strikes(time, raw["pitch_left"], raw["pitch_right"], half_window=7)
        stance = stance_from_events(time, events, raw["pitch_left"], raw["pitch_right"])
        smooth, smooth_sd = _smooth(time, raw, sd, events, smoothing_window, smoothing_order)
        return TrackResult(time=time, raw=raw, raw_sd=sd, smooth=smooth, smooth_sd=smooth_sd,
                           stance=stance, events=events, pixel_sd=pixel_sd, ramp=ramp.summary,
                           frames_with=seen, counts=dict(self.counts),
                           smoothing={"method": "Savitzky-Golay", "window": smoothing_window,
                                      "order": smoothing_order},
                           poses={**self.poses, "walker": walker},
                           hip_width=self.hip_width,
                           hip_width_source="given" if self.hip_width_given is not None else
                           f"estimated: median of {len(self._width_samples)} frames' joint fits",
                           track_seconds=self.track_seconds)

    def _final_walker(self) -> list:
        """The per-frame joint fits, refitted with the final hip width when it was estimated."""
        if self.hip_width_given is not None or not self._width_samples:
            return list(self.walker)
        width = self.hip_width
        out = []
        for pose, obs in zip(self.walker, self._observations, strict=True):
            if pose is None or (abs(pose.hip_width - width) <= 1e-5 and "hip_width" not in pose.names):
                out.append(pose)  # already fitted with this width (to 0.01 mm)
                continue
            refit = fit_walker(self.camera, obs, (pose.axle, pose.pitch, pose.hip), hip_width=width)
            out.append(refit if refit is not None else pose)
        return out

    def _ramp_frame(self, n: int, ramp_sd):
        """The ramp frame (:class:`toywalk.tracking.ramp.RampFrame`): measured from the ramp markers
        where seen; a camera file's fixed pose checked against that (RampPoseError if they disagree)."""
        measured = None
        if "ramp" in self.bodies:
            measured = measure_ramp(self.camera, self.bodies["ramp"].points, self.detections,
                                    self.poses["ramp"], ramp_sd)
        if self.camera.ramp_pose is not None:
            return fixed_ramp(n, self.camera.ramp_pose, measured)
        if measured is None:
            raise TrackError(f"no ramp marker found in any of the {n} frames and the camera file has "
                             "no ramp_pose: the ramp frame is unknown")
        return measured


def _inconsistent_frames(raw: dict) -> np.ndarray:
    """Frames (bool, shape (n,)) whose angles jump away from both neighbouring stretches.

    A leg seen through one small marker can give a mirrored pose whose residual is as small as
    the true one's; the angles then jump by degrees for a frame or two, which neither the frames
    before nor those after explain (:func:`toywalk.tracking.events.isolated_outliers`; a heel
    strike bends the pitches but keeps them continuous). Such frames become gaps: a missing
    sample, not a wrong one.
    """
    n = len(next(iter(raw.values())))
    bad = np.zeros(n, dtype=bool)
    # the fits on either side must fit inside a step, or a heel strike bends both (fast steps)
    count = fit_samples_per_side(step_samples(raw["pitch_left"], raw["pitch_right"]), 5)
    for k in SIGNALS:
        y = raw[k]
        sd = noise_sd(y)
        if np.isfinite(sd) and np.sum(np.isfinite(y)) > 12:
            bad |= isolated_outliers(y, max(sd, 1e-5), count=count)
    return bad


def _angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (rad) of the rotation taking ``b`` to ``a`` (both (3, 3))."""
    return float(np.arccos(np.clip((np.trace(a @ b.T) - 1) / 2, -1.0, 1.0)))


def _pooled_pixel_sd(poses) -> float:
    """Pixel noise SD pooled over frames, robustly: the median over frames of each frame's residual
    RMS corrected for the six fitted parameters (``rms * sqrt(2n / (2n - 6))``), scaled so that
    it estimates the SD for Gaussian noise (the median of a chi distribution lies below its RMS)."""
    values = [p.rms * math.sqrt(2 * p.n_points / (2 * p.n_points - 6))
              for p in poses if p is not None and 2 * p.n_points > 6]
    if not values:
        return 0.5  # pixels: a conservative guess when no frame has redundant points
    dof = np.median([2 * p.n_points - 6 for p in poses if p is not None and 2 * p.n_points > 6])
    from scipy.stats import chi

    ratio = chi.median(dof) / math.sqrt(dof)  # median of rms/sigma for dof degrees of freedom
    return max(float(np.median(values)) / ratio, 0.02)  # floor: sub-pixel corners are never better


def _pooled_walker_sd(poses) -> float:
    """Pixel noise SD pooled over the joint leg fits, as :func:`_pooled_pixel_sd`."""
    good = [p for p in poses if p is not None and p.dof > 0]
    if not good:
        return 0.5  # pixels: a conservative guess when no frame has redundant points
    values = [p.rms * math.sqrt((p.dof + len(p.names)) / p.dof) for p in good]
    dof = float(np.median([p.dof for p in good]))
    from scipy.stats import chi

    ratio = chi.median(dof) / math.sqrt(dof)
    return max(float(np.median(values)) / ratio, 0.02)


def walker_angles(r_ramp: np.ndarray, pose: WalkerPose) -> np.ndarray:
    """(lean, steer, pitch_left, pitch_right) (rad) of a joint leg pose; NaN for an unseen leg.

    ``r_ramp`` (3, 3) rotates the ramp frame into the camera frame. The hip axis b2 gives steer
    and lean (``b2 = Rz(steer) Rx(lean) e_y``, model.md section 1), each leg its pitch about it.
    """
    axle = r_ramp.T @ pose.axle
    b2 = axle[:, 1]
    lean = math.asin(float(np.clip(b2[2], -1.0, 1.0)))
    steer = math.atan2(-b2[0], b2[1])
    base = rotation(steer, lean, 0.0).T @ axle
    pitches = []
    for f in FEET:
        if f in pose.seen:
            local = base @ rot_y(pose.pitch[f])
            pitches.append(math.atan2(local[0, 2], local[2, 2]))
        else:
            pitches.append(math.nan)
    return np.array([lean, steer, *pitches])


def walker_angles_with_sd(r_ramp: np.ndarray, pose: WalkerPose, pixel_sd: float,
                          ramp_covariance=None) -> tuple[dict, dict]:
    """Angles of a joint leg pose and their SDs (dicts of SIGNALS name -> rad).

    The covariance ``pixel_sd^2 (J^T J)^-1`` of the fit is propagated through
    :func:`walker_angles` by finite differences. It is inflated by ``(rms / rms_expected)^2`` when
    the frame's residual exceeds what the pooled pixel noise explains (blur, a bent edge): such
    a pose is less certain than its Jacobian says. ``ramp_covariance`` (3, 3), rad^2, of the ramp
    rotation's error about its own axes (:mod:`toywalk.tracking.ramp`), where it is this frame's
    own, is propagated alike and added.
    """
    base = walker_angles(r_ramp, pose)
    angular = [j for j, name in enumerate(pose.names) if name in ("d1", "d3", "pitch_L", "pitch_R")]
    h = 1e-7
    jac = np.zeros((4, len(angular)))
    for c, j in enumerate(angular):
        step = np.zeros(len(pose.names))
        step[j] = h
        jac[:, c] = (walker_angles(r_ramp, pose.perturbed(step)) - base) / h
    jac = np.nan_to_num(jac)
    cov = pose.normal[np.ix_(angular, angular)] * pixel_sd**2
    if pose.dof > 0:
        expected = pixel_sd * math.sqrt(pose.dof / (pose.dof + len(pose.names)))
        cov = cov * max(1.0, (pose.rms / expected) ** 2)
    var = np.einsum("ij,jk,ik->i", jac, cov, jac)
    if ramp_covariance is not None and np.all(np.isfinite(ramp_covariance)):
        turned = np.zeros((4, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = h
            turned[:, j] = (walker_angles(r_ramp @ cv2.Rodrigues(step)[0], pose) - base) / h
        turned = np.nan_to_num(turned)
        var = var + np.einsum("ij,jk,ik->i", turned, np.asarray(ramp_covariance, float), turned)
    sd = np.sqrt(np.maximum(var, 0.0))
    sd[~np.isfinite(base)] = np.nan
    names = ("lean", "steer", "pitch_left", "pitch_right")
    return dict(zip(names, base, strict=True)), dict(zip(names, sd, strict=True))


def _angles(r_ramp: np.ndarray, rvecs: dict) -> np.ndarray:
    """(lean, steer, pitch_left, pitch_right) from leg rvecs (camera frame); NaN for a missing leg."""
    rot = {f: r_ramp.T @ cv2.Rodrigues(np.asarray(v, float).reshape(3, 1))[0] for f, v in rvecs.items()}
    if "L" in rot and "R" in rot:
        steer, lean, pl, pr = angles_from_rotations(rot["L"], rot["R"])
        return np.array([lean, steer, pl, pr])
    foot, r = next(iter(rot.items()))
    b2 = r[:, 1]
    lean = float(np.arcsin(np.clip(b2[2], -1.0, 1.0)))
    steer = float(np.arctan2(-b2[0], b2[1]))
    local = rotation(steer, lean, 0.0).T @ r
    pitch = float(np.arctan2(local[0, 2], local[2, 2]))
    return np.array([lean, steer, pitch if foot == "L" else np.nan, pitch if foot == "R" else np.nan])


def angles_with_sd(r_ramp: np.ndarray, legs: dict) -> tuple[dict, dict]:
    """Walker angles and their SDs from leg orientations seen by the camera.

    Parameters
    ----------
    r_ramp : ndarray, shape (3, 3)
        Rotation of the ramp frame into the camera frame.
    legs : dict {'L', 'R'} -> (rvec, covariance)
        Each seen leg's rotation (camera frame, Rodrigues, rad) and its 3x3 covariance (rad^2).

    Returns
    -------
    values, sds : dict of SIGNALS name -> float (rad); NaN for the pitch of a leg not seen.
    """
    base = _angles(r_ramp, {f: v[0] for f, v in legs.items()})
    var = np.zeros(4)
    h = 1e-6
    for foot, (_, cov) in legs.items():
        jac = np.zeros((4, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = h
            shifted = {f: (np.asarray(v[0], float) + step if f == foot else v[0]) for f, v in legs.items()}
            jac[:, j] = (_angles(r_ramp, shifted) - base) / h
        jac = np.nan_to_num(jac)
        var += np.einsum("ij,jk,ik->i", jac, cov, jac)
    sd = np.sqrt(var)
    sd[~np.isfinite(base)] = np.nan
    names = ("lean", "steer", "pitch_left", "pitch_right")
    return dict(zip(names, base, strict=True)), dict(zip(names, sd, strict=True))


def _smooth(time, raw, sd, events, window, order):
    """Savitzky-Golay smoothing over stretches free of gaps and heel strikes (rates jump there)."""
    smooth = {k: v.copy() for k, v in raw.items()}
    smooth_sd = {k: v.copy() for k, v in sd.items()}
    gain = math.sqrt(float(np.sum(savgol_coeffs(window, order) ** 2)))
    cuts = np.searchsorted(time, [e.time for e in events])
    for k in raw:
        ok = np.isfinite(raw[k])
        seg_id = np.cumsum(np.concatenate([[0], (np.diff(ok.astype(int)) != 0).astype(int)]))
        breaks = np.zeros(len(time), dtype=int)
        breaks[cuts[cuts < len(time)]] = 1
        seg_id = seg_id * 10**6 + np.cumsum(breaks)
        for s in np.unique(seg_id[ok]):
            idx = np.flatnonzero((seg_id == s) & ok)
            if len(idx) >= window:
                smooth[k][idx] = savgol_filter(raw[k][idx], window, order, mode="interp")
                smooth_sd[k][idx] = sd[k][idx] * gain
    return smooth, smooth_sd


# --- results --------------------------------------------------------------------------------------

@dataclasses.dataclass
class TrackResult:
    """What :meth:`Tracker.finish` found.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Frame timestamps (s).
    raw, raw_sd : dict of str -> ndarray, shape (n,)
        Per-frame angles ``lean, steer, pitch_left, pitch_right`` (rad) and their SDs; NaN = gap.
    smooth, smooth_sd : dict of str -> ndarray, shape (n,)
        The same, smoothed (see ``smoothing``).
    stance : ndarray of str, shape (n,)
    events : list of HeelStrike
    pixel_sd : dict body -> float
        Pooled reprojection noise (pixels).
    ramp : dict
        Where the ramp pose came from, and the pose.
    frames_with : dict body -> int
        Frames in which each leg's pose was found.
    counts : dict
        Frames, whole-frame and region searches.
    poses : dict
        Per frame: ``walker``, the joint leg fits (:class:`~toywalk.tracking.joint.WalkerPose` or
        None); each leg's pose derived from them; the ramp's own fits.
    hip_width : float
        The hip width used (m) and, in ``hip_width_source``, where it came from.
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

    def table(self, *, smoothed: bool = False, metadata=None) -> TrajectoryTable:
        """The trajectory-file table of the raw (default) or smoothed signals."""
        values, sds = (self.smooth, self.smooth_sd) if smoothed else (self.raw, self.raw_sd)
        signals = {k: values[k] for k in SIGNALS}
        signals.update({f"{k}_sd": sds[k] for k in SIGNALS})
        events = [{"time": e.time, "foot": e.foot, "x": math.nan, "y": math.nan, "time_sd": e.time_sd}
                  for e in self.events]
        return TrajectoryTable(self.time, signals, self.stance, events, metadata or {})


def track_frames(frames, camera: Camera, layout: MarkerLayout, *, overlay=None, roi: bool = True,
                 hip_width: float | None = None, **finish_options) -> TrackResult:
    """Track an iterable of ``(time, image)``; ``overlay(image)`` receives each annotated frame.

    ``hip_width`` (m) as in :class:`Tracker` (None: estimated from the video)."""
    tracker = Tracker(camera, layout, roi=roi, hip_width=hip_width)
    for t, image in frames:
        record = tracker.process(t, image)
        if overlay is not None:
            overlay(tracker.draw(image, record))
    return tracker.finish(**finish_options)


def track_video(path: str | Path, camera: Camera, layout: MarkerLayout, *, overlay: str | Path | None = None,
                roi: bool = True, hip_width: float | None = None,
                **finish_options) -> tuple[TrackResult, FrameSource]:
    """Track a video file; optionally write an overlay video (MPEG-4) to ``overlay``.

    Returns the result and the :class:`FrameSource` (frame counts, decode time). The overlay is
    written to a temporary name and renamed into place only if tracking succeeds.
    """
    source = open_video(path)
    if (source.width, source.height) != camera.size:
        raise TrackError(f"the video is {source.width}x{source.height} pixels but the camera file "
                         f"describes {camera.width}x{camera.height}")
    writer = None
    tmp = None
    sink = None
    if overlay is not None:
        overlay = Path(overlay)
        tmp = overlay.with_name(f".{overlay.stem}.tmp{overlay.suffix}")
        fps = source.nominal_fps if source.nominal_fps > 0 else 30.0  # playback rate only
        writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, camera.size)
        if not writer.isOpened():
            raise TrackError(f"cannot write the overlay video {overlay}")
        sink = writer.write
    try:
        result = track_frames(source, camera, layout, overlay=sink, roi=roi, hip_width=hip_width,
                              **finish_options)
        if writer is not None:
            writer.release()
            writer = None
            tmp.replace(overlay)
    finally:
        if writer is not None:
            writer.release()
        if tmp is not None:
            tmp.unlink(missing_ok=True)
    return result, source
