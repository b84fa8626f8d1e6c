"""Video to trajectory: markers, leg poses, walker angles, heel strikes (docs/cli.md, ``toywalk track``).

The stages, one module each: the video's frames and their times (:mod:`toywalk.tracking.video`),
per-frame tracking (this module's :class:`Tracker`), the angles and their SDs
(:mod:`toywalk.tracking.angles`), heel strikes (:mod:`toywalk.tracking.events`), smoothing
(:mod:`toywalk.tracking.smooth`) and the result (:mod:`toywalk.tracking.results`).
:func:`track_video` runs them on a file, :func:`track_frames` on any ``(time, image)`` sequence.

Per frame (:meth:`Tracker.process`):

1. predict each body's pose from its last two (constant velocity) and search for markers only in
   regions of interest around the predicted corners of its markers that face the camera; the whole
   frame is searched when a body has no prediction (not yet found, or lost), at growing intervals
   while it stays lost;
2. estimate each body's pose in the camera frame from all its visible marker corners jointly
   (:func:`toywalk.tracking.pose.estimate_pose`; both legs at once, :mod:`toywalk.tracking.joint`),
   with ``(J^T J)^-1`` kept for the covariance.

After the last frame (:meth:`Tracker.finish`):

3. the ramp pose, measured from the ramp markers whenever the video shows them
   (:mod:`toywalk.tracking.ramp`): one pose fitted to all frames jointly (a fixed camera), else,
   if the frames disagree (a moving camera), each frame's own; a camera file's fixed
   ``ramp_pose`` is checked against it, refused if they disagree beyond the measurement's
   accuracy, and used where they agree or no ramp marker is seen;
4. the leg rotations in the ramp frame give ``steer, lean, pitch_left, pitch_right`` and their
   standard deviations (:mod:`toywalk.tracking.angles`);
5. frames whose angles jump away from both neighbouring stretches (a mirrored single-marker pose)
   become gaps; heel strikes and stance (:mod:`toywalk.tracking.events`) from the raw pitches;
6. a smoothed copy of the signals (:mod:`toywalk.tracking.smooth`).

Missing samples are NaN, never invented. Times are the frames' own: the container's per-frame
timestamps (:mod:`toywalk.tracking.video`), uneven in a variable-frame-rate video.

:class:`TrackError`, :class:`FrameSource`, :func:`open_video`, :class:`TrackResult`,
:func:`walker_angles` and :func:`walker_angles_with_sd` are importable from here too, where they
were defined before the split.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from pathlib import Path

import cv2
import numpy as np
from scipy.special import chdtrc, fdtrc

from ..model.trajectory import SIGNALS
from .angles import (
    moderated_noise_scales,
    motion_smoothed,
    pooled_marker_sd,
    pooled_pixel_sd,
    pooled_walker_sd,
    residual_ratio,
    walker_angles,
    walker_angles_with_sd,
)
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
from .joint import WalkerPose, fit_walker, walker_from_legs
from .markers import LEGS, MarkerLayout, body_points
from .pose import PoseEstimate, estimate_pose
from .ramp import fixed_ramp, measure_ramp
from .results import TrackResult
from .smooth import smooth_signals
from .video import FrameSource, TrackError, open_video, timestamp_summary

__all__ = ["FrameSource", "TrackError", "TrackResult", "Tracker", "open_video", "track_frames",
           "track_video", "walker_angles", "walker_angles_with_sd"]

_WIDTH_SAMPLES = 25  # frames whose joint fits estimate the hip width (when not given)
#: A frame's joint fit is taken to show a wrong corner when its residual is this improbable at the
#: recent frames' noise (Tracker._drop_bad_corners)
_GATE_P = 1e-3
#: ... and a set of corners is dropped when the fall in the residual without them is this
#: improbable (F test). With 1e-3 as for the gate, the fast-stepping stable-toy's blurred frames
#: lost 10-16 corners a 1.2-s clip and its left pitch went 0.065-0.091 -> 0.070-0.098 degree RMS
#: (test_track_rendered.py, seeds 2-4); with 1e-5, 0-4 corners and 0.066-0.087, while the toy-sized
#: clip's passing frames keep their gain (left pitch mean -0.05 to -0.01 degree at 0.60-0.65 of the
#: step on four seeds, against -0.03 to +0.02 with 1e-3 and -0.28 to -0.42 without the drop)
_DROP_P = 1e-5
#: Corner sets (indices in a quad) a wrong edge line spoils: one edge's two corners, or all four.
#: Three corners (two edges) were tried too: dropping the three good ones of a quad whose fourth
#: is wrong lets the pitch absorb the wrong one (toy-sized walker: errors 0.25 degree where the
#: two-corner drop leaves 0.1)
_CORNER_SETS = tuple((k, (k + 1) % 4) for k in range(4)) + ((0, 1, 2, 3),)
#: The noise variance of the corner test is the median of this many recent fits', and the test
#: waits for this many (a median of fewer scatters too much)
_NOISE_FRAMES = 50
_NOISE_FRAMES_MIN = 10
#: A followed ramp marker's code is read at least every this many frames (its edges, within
#: 0.5 px of where it was predicted, are checked in every frame)
RAMP_CODE_EVERY = 8
#: A ramp marker sought and not found (hidden by the walker, an occluder) is sought again after
#: 2, 4, 8, then every 8 frames
_RAMP_WAIT = 8


def _longer_wait(interval: int, longest: int) -> int:
    """The next wait (frames) before searching again for something still unseen: twice the last,
    at most ``longest`` (a search that keeps failing costs little, and a return is soon noticed)."""
    return min(2 * interval, longest)


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

    Notes
    -----
    The constant-velocity prediction steps by frames, not seconds: it only places the search
    regions, whose margins hold a frame's motion. The frames' times (uneven at a variable frame
    rate) enter the heel strikes and the result.
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
        self._residual_variances: list[float] = []  # per joint fit: residual SS over its dof
        self.walker: list[WalkerPose | None] = []
        self._observations: list[dict | None] = []
        self.times: list[float] = []
        self.poses: dict[str, list] = {name: [] for name in self.bodies}
        self.detections: list[dict] = []
        self.recovered: list[list[int]] = []  # per frame: leg marker ids found by recovery
        self.counts = {"frames": 0, "full_searches": 0, "roi_searches": 0}
        self._full_interval = 1
        self._last_full = -10**9
        self._ramp_wait: dict[int, tuple[int, int]] = {}  # ramp id -> (next frame sought, interval)
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

    def _follow_ramp(self, image: np.ndarray, frame: int) -> dict:
        """The ramp markers of the last frame followed into this one
        (:meth:`toywalk.tracking.detect.MarkerDetector.follow`), each predicted from its corners
        in the last two frames at constant velocity (pixels a frame) and its code read every
        :data:`RAMP_CODE_EVERY` frames (and whenever it strays from its prediction)."""
        if not self.detections:
            return {}
        last = self.detections[-1]
        before = self.detections[-2] if len(self.detections) >= 2 else {}
        predicted = {i: 2 * c - before[i] if i in before else c
                     for i, c in last.items() if self._owner[i] == "ramp"}
        check = {i for i in predicted if (frame + i) % RAMP_CODE_EVERY == 0}
        return self.detector.follow(image, predicted, check=check) if predicted else {}

    def _regions(self, body: _Body, pred, skip=(), sought: list | None = None) -> list:
        """Search regions (pixels) around the body's markers that face the camera at the predicted
        pose, but those in ``skip`` (ids). With ``sought`` (a list), only markers predicted wholly
        within the frame are sought (the detector finds no marker the frame's edge cuts), and
        their ids are appended to it."""
        rvec, tvec, (dr, dt) = pred
        rot = cv2.Rodrigues(rvec.reshape(3, 1))[0]
        centres = body.centres @ rot.T + tvec
        normals = body.normals @ rot.T
        facing = np.einsum("ij,ij->i", normals, centres) < 0
        if skip:
            facing &= np.array([i not in skip for i in body.ids])
        if not facing.any():
            return []
        # all facing markers' corners projected at once, (k, 4, 2)
        corners = self._corners[body.name][facing].reshape(-1, 3)
        uv = self._project(corners, rvec, tvec).reshape(-1, 4, 2)
        if sought is not None:
            inside = np.all((uv >= 0) & (uv < self.camera.size), axis=(1, 2))
            sought.extend(int(i) for i in np.array(body.ids)[facing][inside])
            if not inside.any():
                return []
            uv, corners = uv[inside], corners.reshape(-1, 4, 3)[inside].reshape(-1, 3)
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
        """Track one frame.

        Parameters
        ----------
        t : float
            The frame's time (s), after the previous frame's.
        image : ndarray, shape (rows, cols[, 3])
            BGR or grey, the camera's size.

        Returns
        -------
        dict
            This frame's record: ``markers`` (id -> corners (4, 2), pixels), ``poses`` (body ->
            PoseEstimate) and ``recovered`` (leg marker ids found by :meth:`_recover`).
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
        # the ramp's markers are followed from their last corners; only those not followed are
        # sought by the detector, each at growing intervals while it stays unseen
        followed = self._follow_ramp(image, frame) if self.roi and "ramp" in self.bodies else {}
        found.update(followed)
        skip = set(followed) | {i for i, (due, _) in self._ramp_wait.items() if frame < due}
        sought: list[int] = []
        for group in (tuple(LEGS), ("ramp",)):
            regions = []
            self._min_side = math.inf  # smallest predicted marker extent (pixels), set by _regions
            for name in group:
                if preds.get(name) is not None:
                    ramp = name == "ramp"
                    regions += self._regions(self.bodies[name], preds[name], skip=skip if ramp else (),
                                             sought=sought if ramp else None)
            if regions:
                more = self.detector.detect(image, merge_regions(regions, self.camera.width,
                                                                 self.camera.height),
                                            min_side=self._min_side)
                for i, c in more.items():  # a marker in both groups' regions: the first's find
                    found.setdefault(i, c)
                searched = True
        self.counts["roi_searches"] += searched
        self.counts["ramp_followed"] = self.counts.get("ramp_followed", 0) + len(followed)
        for i in sought:  # ramp markers only
            if i in found:
                self._ramp_wait.pop(i, None)
            else:
                wait = _longer_wait(self._ramp_wait.get(i, (0, 1))[1], _RAMP_WAIT)
                self._ramp_wait[i] = (frame + wait, wait)
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
        if walker is not None and "hip_width" in walker.names and \
                all(n >= 8 for n in walker.n_points.values()):  # two flags a leg: well determined
            self._width_samples.append(walker.hip_width)
        self.recovered.append(sorted(recovered))
        if walker is not None and walker.dof > 0:
            self._residual_variances.append(2 * sum(walker.n_points.values()) * walker.rms**2 / walker.dof)
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
                                   else _longer_wait(self._full_interval, self.max_full_search_interval))
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
        """Per seen leg: (corners in its body frame (n, 3), their pixels (n, 2), each corner's
        marker id (n,), the marker ids, each corner's index in its marker (n,)), without marker
        ``drop``."""
        obs = {}
        for name, foot in LEGS.items():
            body = self.bodies.get(name)
            if body is None:
                continue
            ids = [i for i in body.ids if i in found and i != drop]
            if ids:
                obs[foot] = (np.concatenate([body.points[i] for i in ids]),
                             np.concatenate([found[i] for i in ids]),
                             np.concatenate([np.full(len(body.points[i]), i) for i in ids]), ids,
                             np.concatenate([np.arange(len(body.points[i])) for i in ids]))
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
        n_markers = sum(len(o[3]) for o in obs.values())
        if n_markers >= 3 and (best is None or best.rms > self.outlier_rms):
            trials = []
            for foot in obs:
                for i in obs[foot][3]:
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
        best, obs = self._drop_bad_corners(best, obs)
        return best, {f: o[:3] for f, o in obs.items()}

    def _noise_variance(self) -> float:
        """The pixel noise variance of a corner (pixels^2): the median over the last
        :data:`_NOISE_FRAMES` joint fits of their residual sum of squares over its degrees of
        freedom; NaN before :data:`_NOISE_FRAMES_MIN` such fits."""
        recent = self._residual_variances[-_NOISE_FRAMES:]
        return float(np.median(recent)) if len(recent) >= _NOISE_FRAMES_MIN else math.nan

    def _drop_bad_corners(self, best: WalkerPose, obs: dict) -> tuple[WalkerPose, dict]:
        """The joint fit without the corners of one marker that disagree with the rest, if the
        frame's residual and the drop are both significant; else ``best`` and ``obs`` unchanged.

        A flag partly hidden behind the other leg (its rod, its flag) keeps being detected while
        the covering edge crosses its quiet zone and then its border: the edge line fitted there
        is pulled by the occluder, moving the two corners it joins by 0.2-2 px (toy-sized walker,
        120 fps, noise 1: the far leg's lower flag for 3-5 frames each step as the legs pass),
        while the fit's RMS rises only to 0.08-0.4 px, under ``outlier_rms`` (0.5 px), and the
        far leg's pitch is biased by -0.2 to -0.9 degree. Here the fit's residual sum of squares
        is compared with its chi-square distribution at the recent frames' noise variance
        (:meth:`_noise_variance`); if it is improbable (:data:`_GATE_P`), each marker's corners
        are left out in turn by the sets one bad edge line or the whole quad would spoil
        (:data:`_CORNER_SETS`), and the set whose removal lowers the sum of squares most
        improbably is dropped if that is improbable enough (:data:`_DROP_P`). That second test
        is an F test against the reduced fit's own residual variance, so that a frame noisier
        than the recent ones throughout (motion blur at a heel strike) does not lose good corners
        (with the recent frames' variance instead, both tests at 1e-3, 193 corners were dropped
        on the toy-sized clip against 94, and the near leg's pitch after its heel strike went 0.12
        degree off). A leg keeps four corners at least (one quad: a pose of its own). Counts:
        ``corners_dropped``.
        """
        variance = self._noise_variance()
        cost = 2 * sum(best.n_points.values()) * best.rms**2
        if not math.isfinite(variance) or best.dof <= 0 or \
                chdtrc(best.dof, cost / variance) >= _GATE_P:
            return best, obs
        trials = list(self._corner_drops(best, obs))
        if not trials:
            return best, obs
        p, w, sub = min(trials, key=lambda x: x[0])
        if p >= _DROP_P:
            return best, obs
        self.counts["corners_dropped"] = self.counts.get("corners_dropped", 0) + \
            sum(len(o[0]) for o in obs.values()) - sum(len(o[0]) for o in sub.values())
        return w, sub

    def _corner_drops(self, best: WalkerPose, obs: dict):
        """For each marker and each of its :data:`_CORNER_SETS` that leaves its leg four corners:
        (the F test's probability of the drop's fall in the residual sum of squares, the joint fit
        without those corners, its observations); the fits start from ``best``."""
        cost = 2 * sum(best.n_points.values()) * best.rms**2
        init = (best.axle, best.pitch, best.hip)
        for foot, o in obs.items():
            for marker_id in o[3]:
                for corners in _CORNER_SETS:
                    keep = ~((o[2] == marker_id) & np.isin(o[4], corners))
                    if keep.sum() < 4:
                        continue
                    sub = {**obs, foot: (o[0][keep], o[1][keep], o[2][keep],
                                         [i for i in o[3] if np.any(o[2][keep] == i)], o[4][keep])}
                    w = fit_walker(self.camera, {f: s[:3] for f, s in sub.items()}, init,
                                   hip_width=best.hip_width, fit_hip_width="hip_width" in best.names)
                    if w is None or w.dof <= 0:
                        continue
                    rest = 2 * sum(w.n_points.values()) * w.rms**2
                    ratio = (cost - rest) / (2 * len(corners)) / max(rest / w.dof, 1e-300)
                    yield fdtrc(2 * len(corners), w.dof, ratio), w, sub

    def _best_walker(self, obs: dict, preds: dict):
        if self._width_in_use[0] != len(self._width_samples):  # the median changes with the samples
            self._width_in_use = (len(self._width_samples), self.hip_width)
        width = self._width_in_use[1]
        # the hip width is a constant: estimated in the first frames that show it well (both legs
        # through two flags each), then fixed; until such a frame, fitted in every frame that
        # shows both legs (a leg seen through one flag cannot be placed with a wrong width)
        fit_width = self.hip_width_given is None and len(obs) == 2 and (
            not self._width_samples
            or (len(self._width_samples) < _WIDTH_SAMPLES and all(len(o[3]) >= 2 for o in obs.values())))
        data = {f: o[:3] for f, o in obs.items()}
        predicted = {}
        for name, foot in LEGS.items():
            p = preds.get(name)
            if p is not None:
                predicted[foot] = (cv2.Rodrigues(np.asarray(p[0], float).reshape(3, 1))[0],
                                   np.asarray(p[1], float).reshape(3))
        prefer = max(obs, key=lambda f: len(obs[f][3]))
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
            # several markers on a board have no mirror ambiguity: a good fit from the last pose
            # is the pose
            return estimate_pose(self.camera, obj, img, guess=guess,
                                 trust_guess=self.outlier_rms if len(use) >= 2 else 0.0)

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

    def finish(self, *, smoothing_window: int = 7, smoothing_order: int = 3,
               one_marker_smoothing: bool = False) -> TrackResult:
        """Angles, their standard deviations, heel strikes, stance and smoothed signals.

        Parameters
        ----------
        smoothing_window, smoothing_order : int
            The Savitzky-Golay filter of the smoothed copy (:mod:`toywalk.tracking.smooth`).
        one_marker_smoothing : bool
            Replace a leg's pitch in the frames where its fit rests on one marker by its motion
            smoother's (:meth:`_one_marker_pitches`): 1.2-3 times more accurate there, but those
            frames' errors are then correlated with their neighbours', which the fit's
            measurement model (independent samples) does not know. Off by default.

        Returns
        -------
        TrackResult
            Its ``timestamps`` are left for the caller that knows the frames' source
            (:func:`track_frames`).

        Raises
        ------
        TrackError
            No frames, no leg marker in any frame, or no ramp frame.
        """
        n = len(self.times)
        if n == 0:
            raise TrackError("no frames to track")
        time = np.asarray(self.times)
        seen = {name: sum(p is not None for p in self.poses.get(name, [])) for name in LEGS}
        if not any(seen.values()):
            raise TrackError(f"no leg markers found in any of the {n} frames")
        walker = self._final_walker()
        pixel_sd = {name: pooled_pixel_sd(self.poses[name]) for name in self.bodies if name not in LEGS}
        legs_sd = pooled_walker_sd(walker)
        marker_sd = pooled_marker_sd(walker)
        ratios = [residual_ratio(w, legs_sd, marker_sd) if w is not None else (math.nan, 0) for w in walker]
        scales, prior = moderated_noise_scales([r for r, _ in ratios], [d for _, d in ratios])
        # sub-pixel corners are never better than 0.02 px (pooled_pixel_sd's floor): nor is a
        # frame's noise, scaled
        scales = np.maximum(scales, (0.02 / min([legs_sd, *marker_sd.values()])) ** 2)
        pixel_sd.update({name: legs_sd for name in LEGS if name in self.bodies})
        ramp = self._ramp_frame(n, pixel_sd.get("ramp"))
        raw = {k: np.full(n, np.nan) for k in SIGNALS}
        sd = {k: np.full(n, np.nan) for k in SIGNALS}
        for i in range(n):
            r_ramp = ramp.rotations[i]
            if r_ramp is None or walker[i] is None:
                continue
            values, sds = walker_angles_with_sd(r_ramp, walker[i], legs_sd,
                                                ramp.covariance[i] if ramp.per_frame else None, marker_sd,
                                                scale=float(scales[i]))
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
        if one_marker_smoothing:
            self._one_marker_pitches(time, raw, sd, walker, [e.time for e in events])
        stance = stance_from_events(time, events, raw["pitch_left"], raw["pitch_right"])
        smooth, smooth_sd = smooth_signals(time, raw, sd, events, smoothing_window, smoothing_order)
        return TrackResult(time=time, raw=raw, raw_sd=sd, smooth=smooth, smooth_sd=smooth_sd,
                           stance=stance, events=events, pixel_sd=pixel_sd, ramp=ramp.summary,
                           frames_with=seen, counts=dict(self.counts),
                           smoothing={"method": "Savitzky-Golay", "window": smoothing_window,
                                      "order": smoothing_order},
                           poses={**self.poses, "walker": walker},
                           hip_width=self.hip_width,
                           noise={"marker_pixel_sd": {int(k): float(v) for k, v in sorted(marker_sd.items())},
                                  "frame_scale": prior},
                           hip_width_source="given" if self.hip_width_given is not None else
                           f"estimated: median of {len(self._width_samples)} frames' joint fits"
                           if self._width_samples else "not measured (no frame showed both legs "
                           "through two flags each): fitted in each frame that showed both legs",
                           track_seconds=self.track_seconds)

    def _one_marker_pitches(self, time, raw: dict, sd: dict, walker: list, strikes: list) -> None:
        """A leg's pitch in the frames where its fit rests on one marker, from that frame's fit
        and the leg's continuity over time
        (:func:`toywalk.tracking.angles.motion_smoothed`, rate and acceleration free at the heel
        strikes), in place; other frames are left alone.

        One small marker fixes a leg's pitch several times less well than two (its lever arm
        about the axle is short): measured on rendered clips, pitch errors of 0.18-0.34 degree
        RMS against 0.04-0.16 with two markers, with SDs that cover them (error over SD about 1).
        The neighbouring frames' estimates, weighted by their SDs through a motion model whose
        looseness is fitted to the leg's own pitches, bring that down by 1.2-3 times
        (benchmarks/TRACKING.md, "One marker on a leg"). These frames' errors are then correlated
        with their neighbours'. Counts: ``one_marker_L``, ``one_marker_R`` (frames).
        """
        for foot in LEGS.values():
            key = "pitch_left" if foot == "L" else "pitch_right"
            one = np.array([w is not None and w.n_points.get(foot, 0) == 4 for w in walker]) & \
                np.isfinite(raw[key])
            self.counts[f"one_marker_{foot}"] = int(one.sum())
            # the motion model's looseness is fitted to the leg's samples: a dozen at least
            if not one.any() or np.sum(np.isfinite(raw[key])) < 12:
                continue
            mean, mean_sd, _ = motion_smoothed(time, raw[key], sd[key], strikes)
            raw[key][one] = mean[one]
            sd[key][one] = mean_sd[one]

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


def track_frames(frames, camera: Camera, layout: MarkerLayout, *, overlay=None, roi: bool = True,
                 hip_width: float | None = None, **finish_options) -> TrackResult:
    """Track a sequence of frames.

    Parameters
    ----------
    frames : iterable of (float, ndarray)
        ``(time, image)``: each frame's time (s, increasing; a variable frame rate is fine) and
        its BGR or grey image (rows, cols[, 3]); a :class:`FrameSource` for a video file.
    camera : Camera
    layout : MarkerLayout
    overlay : callable, optional
        ``overlay(image)`` receives each annotated frame (:meth:`Tracker.draw`).
    roi : bool
        As in :class:`Tracker`.
    hip_width : float, optional
        As in :class:`Tracker` (m; None: estimated from the video).
    **finish_options
        Passed to :meth:`Tracker.finish` (``smoothing_window``, ``smoothing_order``).

    Returns
    -------
    TrackResult
        With ``timestamps`` the :class:`FrameSource`'s policy, or ``"given"`` for other frames.
    """
    tracker = Tracker(camera, layout, roi=roi, hip_width=hip_width)
    for t, image in frames:
        record = tracker.process(t, image)
        if overlay is not None:
            overlay(tracker.draw(image, record))
    result = tracker.finish(**finish_options)
    result.timestamps = frames.timestamps() if isinstance(frames, FrameSource) else \
        timestamp_summary("given", result.time)
    return result


def track_video(path: str | Path, camera: Camera, layout: MarkerLayout, *, overlay: str | Path | None = None,
                roi: bool = True, hip_width: float | None = None,
                **finish_options) -> tuple[TrackResult, FrameSource]:
    """Track a video file; optionally write an overlay video (MPEG-4) to ``overlay``.

    Each frame's time is its presentation time in the container (:mod:`toywalk.tracking.video`;
    ``result.timestamps`` records the policy used). The overlay is written to a temporary name
    and renamed into place only if tracking succeeds.

    Parameters
    ----------
    path : str or Path
        The video file.
    camera : Camera
        Its image size must be the video's.
    layout : MarkerLayout
    overlay : str or Path, optional
        An ``.mp4`` file to write the annotated frames to (played at the nominal frame rate).
    roi, hip_width, **finish_options
        As for :func:`track_frames`.

    Returns
    -------
    result : TrackResult
    source : FrameSource
        Frame counts, decode time, nominal frame rate.

    Raises
    ------
    TrackError
        An unreadable video, a size other than the camera's, no markers.
    """
    source = open_video(path)
    if (source.width, source.height) != camera.size:
        raise TrackError(f"the video is {source.width}x{source.height} pixels but the camera file "
                         f"describes {camera.width}x{camera.height}: calibrate the camera in the "
                         "video mode it filmed in (toywalk calibrate)")
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
