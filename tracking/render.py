"""The synthetic video renderer: a trajectory drawn as the camera would film the walking toy.

Frame ``k`` of a video at ``fps`` frames per second shows the trajectory at ``t0 + k / fps``
(``t0`` = the trajectory's first sample unless ``start`` is given), or at ``frame_times[k]`` where
those are given (a variable-frame-rate video; the file itself is written at the constant rate
``fps``, as ``cv2.VideoWriter`` cannot stamp frames, so the given times are the truth's and a
caller re-stamps the container, e.g. tests/tracking/mp4times.py). The walker between samples is
interpolated: the four angles and the left hip point (both continuous through heel strikes) with
monotone cubic (PCHIP) interpolation, so that the rolling contact need not be re-integrated; the
stance leg switches at the heel-strike events. With motion blur the shutter is open over
``[t - e / (2 fps), t + e / (2 fps)]`` (``e`` = ``exposure``) and the frame averages renders
spread evenly over that interval: at least ``blur_subframes``, and as many more as keep the
walker's image from moving more than :data:`BLUR_STEP_PX` pixels between one render and the
next, so that the blur is continuous, as a real shutter's is, and never a multiple exposure of
sharp ghosts (which biases a marker detector); the truth is the state at ``t``.

Outputs, written atomically together (temporary names in the output folder, renamed at the end,
removed on any error or Ctrl-C):

- ``V.mp4`` (codec ``mp4v``) or ``V.avi`` (``MJPG``);
- ``V.truth.csv`` and ``V.truth.events.csv``: the trajectory format, one row per frame, with the
  angles drawn and the stance foot's contact point, and the heel strikes in the rendered span;
- ``V.json``: metadata (trajectory source, parameters, camera, marker layout, options, seed, frame
  times, occluders, gains). It is also the truth trajectory's metadata file, since
  ``model.trajectory`` names the metadata of ``V.truth.csv`` ``V.json``;
- ``V.camera.json``, ``V.markers.json``: the camera and the marker layout used, ready for
  ``toywalk track --camera ... --markers ...``.

A camera that follows the walker (a :class:`toywalk.tracking.scene.CameraPath`, the default for a
walk too long to frame from one place: :func:`default_filming`) moves during the shutter too: each
render of a blurred frame is drawn from the camera's pose at its instant. Its poses, frame by frame,
are in ``V.json`` (``camera_path``); ``V.camera.json`` then holds the lens without a ramp pose, as
the tracker must measure the ramp in every frame. A walker that leaves a camera's view is drawn
partly, or not at all, in those frames.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time as _time
from pathlib import Path

import cv2
import numpy as np
from toywalk.model.files import software_version as _version
from toywalk.model.files import staged_files
from toywalk.model.kinematics import lowest_point

from .camera import Camera, project
from .markers import LEGS, MarkerLayout, default_layout, marker_corners
from .scene import CameraPath, Scene, WalkerState, default_view

__all__ = ["BLUR_STEP_PX", "NOISE_LEVELS", "Filming", "Motion", "RenderError", "RenderOptions",
           "RenderResult", "StepwiseSpline", "default_filming", "draw_occluder", "occluder_schedule",
           "output_paths", "params_record", "render", "share_in_view", "shoot_times", "video_target",
           "write_shoot"]

_CODECS = {".mp4": "mp4v", ".avi": "MJPG"}

#: Motion blur: the most the walker's image (any vertex of its legs and flags) may move between
#: two of the renders a blurred frame averages, in pixels. At 1 px the average of the renders is
#: a continuous smear to within the edges' own anti-aliased width.
BLUR_STEP_PX = 1.0
#: The most renders averaged in one frame (a cost bound: 64 renders span 63 px of motion).
MAX_SUBFRAMES = 64


class RenderError(ValueError):
    """Bad render input (trajectory, options, output path); one line saying what and what to do."""


@dataclasses.dataclass(frozen=True)
class RenderOptions:
    """How to film: frame rate and the camera's imperfections.

    Attributes
    ----------
    fps : float
        Frame rate (frames/s).
    noise_sd : float
        Per-pixel Gaussian sensor noise, standard deviation in grey levels (0-255 scale).
    blur_subframes : int
        Motion blur on (> 1) or off (1), and the fewest renders averaged per frame; more are used
        where the walker moves fast (:data:`BLUR_STEP_PX`).
    exposure : float
        Shutter-open time as a fraction of the frame interval (used when ``blur_subframes > 1``).
    flicker : float
        Standard deviation of the per-frame exposure gain (relative; 0.02 = 2 %).
    occlusion : float
        Expected fraction of frames with an occluder (a bar or blob passing in front of the lens).
    jpeg_quality : int or None
        Extra JPEG compression of each frame (1-100) before the video codec; None = none.
    codec : str or None
        FourCC; None picks ``mp4v`` for .mp4 and ``MJPG`` for .avi.
    start : float or None
        Time of frame 0 (s); None = the trajectory's first sample.
    duration : float or None
        Length to render (s); None = to the trajectory's last sample.
    frame_times : tuple of float or None
        Times (s) of the frames, increasing, within the trajectory; None = ``t0 + k / fps`` from
        ``start`` and ``duration`` (which must be None when times are given). ``fps`` is then the
        video file's nominal rate and sets the shutter time ``exposure / fps``.
    shadows : bool
        Draw the walker's shadow on the ramp.
    level : int or None
        The ``--noise`` preset these options came from, if any (recorded in the metadata).
    """

    fps: float = 60.0
    noise_sd: float = 0.0
    blur_subframes: int = 1
    exposure: float = 0.5
    flicker: float = 0.0
    occlusion: float = 0.0
    jpeg_quality: int | None = None
    codec: str | None = None
    start: float | None = None
    duration: float | None = None
    frame_times: tuple | None = None
    shadows: bool = True
    level: int | None = None

    def __post_init__(self) -> None:
        def finite(name, lo=0.0, strict=False):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or (v <= lo if strict else v < lo):
                raise RenderError(f"{name} must be a finite number {'>' if strict else '>='} {lo}, got {v!r}")

        finite("fps", strict=True)
        finite("noise_sd")
        finite("exposure")
        finite("flicker")
        finite("occlusion")
        if self.exposure > 1:
            raise RenderError(f"exposure is a fraction of the frame interval, 0..1, got {self.exposure}")
        if self.occlusion > 1:
            raise RenderError(f"occlusion is a fraction of frames, 0..1, got {self.occlusion}")
        if not isinstance(self.blur_subframes, int) or isinstance(self.blur_subframes, bool) \
                or not 1 <= self.blur_subframes <= 64:
            raise RenderError(f"blur_subframes must be an integer 1..64, got {self.blur_subframes!r}")
        if self.jpeg_quality is not None and not (isinstance(self.jpeg_quality, int)
                                                  and 1 <= self.jpeg_quality <= 100):
            raise RenderError(f"jpeg_quality must be None or an integer 1..100, got {self.jpeg_quality!r}")
        if self.codec is not None and not (isinstance(self.codec, str) and len(self.codec) == 4):
            raise RenderError(f"codec must be a four-character code such as 'mp4v', got {self.codec!r}")
        if self.start is not None:
            finite("start", lo=-math.inf)
        if self.duration is not None:
            finite("duration", strict=True)
        if self.frame_times is not None:
            try:
                times = tuple(float(t) for t in self.frame_times)
            except (TypeError, ValueError) as err:
                raise RenderError(f"frame_times must be a sequence of times (s), "
                                  f"got {self.frame_times!r}") from err
            if not times or not all(math.isfinite(t) for t in times) or \
                    any(b <= a for a, b in zip(times, times[1:], strict=False)):
                raise RenderError("frame_times must be finite times (s), increasing strictly, at least one")
            if self.start is not None or self.duration is not None:
                raise RenderError("give frame_times or start/duration, not both")
            object.__setattr__(self, "frame_times", times)  # a tuple: the options stay hashable

    @classmethod
    def preset(cls, level: int, **overrides) -> RenderOptions:
        """Options of a ``--noise`` level (:data:`NOISE_LEVELS`), with keyword overrides."""
        if level not in NOISE_LEVELS:
            raise RenderError(f"noise level must be one of {', '.join(map(str, NOISE_LEVELS))}, "
                              f"got {level!r}")
        unknown = set(overrides) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise TypeError(f"unknown option(s): {', '.join(sorted(unknown))}")
        return cls(**{**NOISE_LEVELS[level], "level": level, **overrides})


#: ``--noise`` presets: 0 a perfect camera; 1 (default) light noise, mild blur, slight flicker;
#: 2 a poor webcam (stronger noise and blur, flicker, occasional occluders); 3 harsh (heavy noise,
#: full-frame blur, strong flicker, frequent occluders, JPEG artefacts).
NOISE_LEVELS = {
    0: {"noise_sd": 0.0, "blur_subframes": 1, "exposure": 0.0, "flicker": 0.0, "occlusion": 0.0,
        "jpeg_quality": None},
    1: {"noise_sd": 2.0, "blur_subframes": 3, "exposure": 0.4, "flicker": 0.02, "occlusion": 0.0,
        "jpeg_quality": None},
    2: {"noise_sd": 5.0, "blur_subframes": 5, "exposure": 0.8, "flicker": 0.05, "occlusion": 0.08,
        "jpeg_quality": None},
    3: {"noise_sd": 10.0, "blur_subframes": 7, "exposure": 1.0, "flicker": 0.10, "occlusion": 0.2,
        "jpeg_quality": 40},
}


@dataclasses.dataclass(frozen=True)
class RenderResult:
    """What :func:`render` wrote.

    Attributes
    ----------
    paths : dict of str to Path
        ``video``, ``truth``, ``metadata``, ``camera``, ``markers``.
    frame_times : ndarray, shape (n_frames,)
    seconds : float
        Wall-clock render time.
    in_view : ndarray, shape (n_frames,), or None
        Each frame's share of the walker's mesh vertices inside the image (:func:`share_in_view`;
        1 when the whole walker is filmed), or None where the renderer does not say.
    """

    paths: dict
    frame_times: np.ndarray
    seconds: float
    in_view: np.ndarray | None = None

    @property
    def n_frames(self) -> int:
        return len(self.frame_times)


def output_paths(out: str | Path) -> dict:
    """The files written for a video ``V.mp4``: video, truth (V.truth.csv), metadata (V.json),
    camera (V.camera.json), markers (V.markers.json). ``V`` may hold dots (``walk.level1.mp4``)."""
    out = Path(out)
    stem = out.with_suffix("")
    return {"video": out, "truth": stem.with_name(stem.name + ".truth.csv"),
            "metadata": stem.with_name(stem.name + ".json"),
            "camera": stem.with_name(stem.name + ".camera.json"),
            "markers": stem.with_name(stem.name + ".markers.json")}


# --- the walker's motion between samples ----------------------------------------------------------

class StepwiseSpline:
    """Values ``(n, m)`` at increasing ``times`` interpolated within each step: a cubic spline
    (not-a-knot) through the samples between two heel strikes, extended to the strikes on both
    sides (a kink there, where the rates jump, is kept instead of smoothed over). A step with fewer
    than two samples takes its neighbours' splines. Outside the samples' span it holds the end
    values.
    """

    def __init__(self, times: np.ndarray, values: np.ndarray, strikes):
        from scipy.interpolate import CubicSpline

        self.span = (float(times[0]), float(times[-1]))
        inner = [s for s in sorted(strikes) if self.span[0] < s < self.span[1]]
        piece = np.searchsorted(np.asarray(inner, float), times, side="right")
        self.bounds, self.splines = [], []
        for k in range(len(inner) + 1):
            sel = piece == k
            if sel.sum() < 2:
                continue
            self.bounds.append(inner[k - 1] if k > 0 else -math.inf)
            self.splines.append(CubicSpline(times[sel], values[sel], axis=0))

    def __call__(self, t: float) -> np.ndarray:
        t = float(np.clip(t, *self.span))
        k = max(0, int(np.searchsorted(self.bounds, t, side="right")) - 1)
        return self.splines[k](t)


class Motion:
    """The walker's placement at any time of a trajectory.

    Uses the samples whose four angles are present and whose stance is 'L' or 'R'. Where the
    trajectory has ``contact_x, contact_y`` the hips are placed from them (model.kinematics); where
    it has not, the stance foot's rolling is integrated from the angles (``v_O = omega x (O - C)``,
    docs/model.md section 3, trapezoidal), starting with the contact at the ramp origin, and at each
    stance change the new contact is the landing foot's lowest point.

    Between samples the angles and hips are interpolated step by step (:class:`StepwiseSpline`):
    a cubic spline through each step's samples, reaching to the heel strikes on both sides. Rates
    jump at a heel strike; one interpolant across it (PCHIP, as before) drew the legs up to 0.19
    degrees away from the walk it was given at ``simulate``'s sample spacing (6.2 ms, toy-sized
    walker), three times the tracker's noise and locked to the step's phase, a misfit no model
    can remove. Step by step it is 0.0004 degrees there (0.006 on the stable toy's 0.107 s steps).

    Parameters
    ----------
    table : TrajectoryTable
    params : Params
    """

    def __init__(self, table, params):
        from toywalk.model.kinematics import leg_poses

        self.params = params
        names = ("lean", "steer", "pitch_left", "pitch_right")
        missing = [n for n in names if n not in table.signals]
        if missing:
            raise RenderError(f"trajectory lacks column(s) {', '.join(missing)}")
        time = np.asarray(table.time, float)
        ang = np.column_stack([table.signals[n] for n in names])
        stance = np.asarray(table.stance)
        ok = np.all(np.isfinite(ang), axis=1) & np.isin(stance, ("L", "R")) & np.isfinite(time)
        if ok.sum() < 2:
            raise RenderError("the trajectory needs at least two samples with all four angles and a stance")
        time, ang, stance = time[ok], ang[ok], stance[ok]
        if np.any(np.diff(time) <= 0):
            raise RenderError("trajectory times must increase strictly")
        have_contact = ("contact_x" in table.signals and "contact_y" in table.signals
                        and np.all(np.isfinite(table.signals["contact_x"][ok]))
                        and np.all(np.isfinite(table.signals["contact_y"][ok])))
        self.contact_source = "trajectory" if have_contact else "integrated rolling"
        if have_contact:
            contact = np.column_stack([table.signals["contact_x"][ok], table.signals["contact_y"][ok]])
        else:
            contact = _integrate_contact(params, ang, stance)
        hips = np.empty((len(time), 3))
        for i in range(len(time)):
            lean, steer, pl, pr = ang[i]
            hips[i] = leg_poses(params, steer, lean, pl, pr, str(stance[i]), contact[i]).hip["L"]
        self.time, self.stance = time, stance
        self.events = sorted((float(e["time"]), str(e["foot"])) for e in table.events
                             if e.get("foot") in ("L", "R") and math.isfinite(float(e["time"])))
        self._interp = StepwiseSpline(time, np.column_stack([ang, hips]), [te for te, _ in self.events])

    @property
    def span(self) -> tuple[float, float]:
        return float(self.time[0]), float(self.time[-1])

    def angles(self, t: float) -> np.ndarray:
        """(lean, steer, pitch_left, pitch_right) (rad) at time ``t`` (clamped to the span)."""
        return self._interp(float(np.clip(t, *self.span)))[:4]

    def stance_at(self, t: float) -> str:
        """The stance leg at ``t``: the last sample's at or before ``t``, or a heel strike's after it."""
        i = max(0, int(np.searchsorted(self.time, t, side="right")) - 1)
        foot, t_i = str(self.stance[i]), self.time[i]
        for te, f in self.events:
            if t_i < te <= t:
                foot = f
        return foot

    def state(self, t: float) -> WalkerState:
        from toywalk.model.kinematics import rotation

        t = float(np.clip(t, *self.span))
        v = self._interp(t)
        lean, steer, pl, pr = v[:4]
        rot = {"L": rotation(steer, lean, pl), "R": rotation(steer, lean, pr)}
        hip_l = v[4:7]
        hip = {"L": hip_l, "R": hip_l - float(self.params.hip_width) * rot["L"][:, 1]}
        return WalkerState(rotation=rot, hip=hip)

    def contact(self, state: WalkerState, stance: str) -> np.ndarray:
        """The stance foot's lowest point (x, y) on the ramp (m), from the placed legs."""
        return lowest_point(self.params, state.rotation[stance], state.hip[stance])[:2]

    def hips(self, times) -> np.ndarray:
        """The mid-point of the two hip points (ramp frame, m), shape (k, 3), at ``times`` (k,)."""
        return np.array([0.5 * (s.hip["L"] + s.hip["R"]) for s in map(self.state, times)])


def _integrate_contact(params, ang: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """Contact points (n, 2) by integrating the stance foot's rolling (see :class:`Motion`)."""
    from toywalk.model.kinematics import leg_poses

    contact = np.zeros((len(ang), 2))
    for i in range(1, len(ang)):
        lean0, steer0, pl0, pr0 = ang[i - 1]
        lean1, steer1, pl1, pr1 = ang[i]
        s0, s1 = str(stance[i - 1]), str(stance[i])
        poses0 = leg_poses(params, steer0, lean0, pl0, pr0, s0, contact[i - 1])
        if s1 != s0:  # heel strike in between: the landing foot's lowest point
            contact[i] = lowest_point(params, poses0.rotation[s1], poses0.hip[s1])[:2]
            continue
        poses1 = leg_poses(params, steer1, lean1, pl1, pr1, s0, (0.0, 0.0))
        r0, r1 = poses0.rotation[s0], poses1.rotation[s0]
        dtheta = cv2.Rodrigues(r1 @ r0.T)[0].ravel()  # omega dt, ramp frame
        off0 = poses0.foot_centre[s0] - np.array([*contact[i - 1], 0.0])  # O - C
        off1 = poses1.foot_centre[s0]  # contact at the origin: O - C
        o1 = poses0.foot_centre[s0] + np.cross(dtheta, 0.5 * (off0 + off1))
        contact[i] = (o1 - off1)[:2]
    return contact


# --- camera imperfections -------------------------------------------------------------------------

def occluder_schedule(n_frames: int, fraction: float, width: int, height: int, fps: float, rng) -> list:
    """Occluder events: (first frame, n frames, kind, parameters), covering about ``fraction`` of
    the frames; a dark bar sweeping across (an arm, a pole) or a blurred blob (a finger on the lens)."""
    events = []
    if fraction <= 0 or n_frames == 0:
        return events
    k = 0
    mean_len = max(3, int(round(0.3 * fps)))  # about 0.3 s each
    while k < n_frames:
        gap = rng.exponential(mean_len * (1 - fraction) / fraction)
        k += int(gap)
        if k >= n_frames:
            break
        length = max(2, int(rng.integers(mean_len // 2, 2 * mean_len)))
        if rng.random() < 0.6:
            params = {"kind": "bar", "x0": float(rng.uniform(-0.2, 0.3) * width),
                      "x1": float(rng.uniform(0.7, 1.2) * width),
                      "width": float(rng.uniform(0.05, 0.12) * width),
                      "angle": float(rng.uniform(-0.3, 0.3)),
                      "colour": [float(c) for c in rng.uniform(20, 90, 3)]}
            if rng.random() < 0.5:
                params["x0"], params["x1"] = params["x1"], params["x0"]
        else:
            params = {"kind": "blob", "x": float(rng.uniform(0.2, 0.8) * width),
                      "y": float(rng.uniform(0.2, 0.8) * height),
                      "radius": float(rng.uniform(0.06, 0.15) * height),
                      "colour": [float(c) for c in rng.uniform(30, 110, 3)]}
        events.append((k, length, params))
        k += length
    return events


def draw_occluder(img: np.ndarray, event, k: int) -> None:
    first, length, p = event
    s = (k - first) / max(1, length - 1)
    h, w = img.shape[:2]
    if p["kind"] == "bar":
        x = p["x0"] + s * (p["x1"] - p["x0"])
        half = 0.5 * p["width"]
        dx = math.tan(p["angle"]) * h
        pts = np.array([[x - half, -1], [x + half, -1], [x + half + dx, h], [x - half + dx, h]])
        cv2.fillConvexPoly(img, np.round(pts * 16).astype(np.int32), p["colour"], cv2.LINE_AA, 4)
    else:
        mask = np.zeros((h, w), np.uint8)
        cv2.circle(mask, (int(p["x"]), int(p["y"])), int(p["radius"]), 255, -1, cv2.LINE_AA)
        blur = int(p["radius"] * 0.5) | 1
        mask = cv2.GaussianBlur(mask, (blur, blur), 0).astype(np.float32)[..., None] / 255
        col = np.array(p["colour"], np.float32)
        img[:] = np.clip(img * (1 - mask) + col * mask + 0.5, 0, 255).astype(np.uint8)


# --- the renderer ---------------------------------------------------------------------------------

def shoot_times(motion: Motion, options: RenderOptions) -> np.ndarray:
    t_first, t_last = motion.span
    if options.frame_times is not None:
        times = np.array(options.frame_times)
        if times[0] < t_first - 1e-12 or times[-1] > t_last + 1e-12:
            raise RenderError(f"frame_times {times[0]} .. {times[-1]} s reach outside the trajectory "
                              f"({t_first} .. {t_last} s)")
        return times
    t0 = t_first if options.start is None else float(options.start)
    t_end = t_last if options.duration is None else min(t_last, t0 + float(options.duration))
    if t0 < t_first - 1e-12 or t0 > t_last:
        raise RenderError(f"start {t0} s lies outside the trajectory ({t_first} .. {t_last} s)")
    n = int(math.floor((t_end - t0) * options.fps + 1e-9)) + 1
    return t0 + np.arange(n) / options.fps


#: Marker bodies (markers.BODIES) by their key in Scene.body_poses
_BODY_KEY = {**LEGS, "ramp": "ramp"}


class Filming:
    """A prepared shoot: the scene, the frame times and the imperfection schedule (gains,
    occluders), drawn from ``rng`` in a fixed order so that a seed reproduces every frame.

    Parameters
    ----------
    table, params, camera, layout, options, rng, path
        As for :func:`render`.
    hidden : callable, optional
        Frame index -> ids of the markers painted over in that frame (:meth:`_cover`): a flag
        hidden by the other leg, say.

    Attributes
    ----------
    motion : Motion
    scene : Scene
    times : ndarray, shape (n_frames,)
        Frame times (s).
    gains : ndarray, shape (n_frames,)
        Exposure gain of each frame.
    occluders : list
        (first frame, n frames, description) of each occluder.
    """

    def __init__(self, table, params, camera: Camera, layout: MarkerLayout, options: RenderOptions,
                 rng=None, path: CameraPath | None = None, hidden=None):
        if not isinstance(options, RenderOptions):
            raise TypeError(f"options must be RenderOptions, got {type(options).__name__}")
        if path is not None and not isinstance(path, CameraPath):
            raise TypeError(f"path must be a CameraPath or None, got {type(path).__name__}")
        if camera.ramp_pose is None and path is None:
            raise RenderError("the camera has no ramp_pose: the renderer needs a fixed camera or a path")
        self.options, self.path = options, path
        self.rng = np.random.default_rng(rng)
        self.motion = Motion(table, params)
        self.times = shoot_times(self.motion, options)
        if path is not None:  # the scene starts where the path does
            camera = dataclasses.replace(camera, ramp_pose=path.pose(float(self.times[0])))
        self.camera = camera
        self.scene = Scene(params, layout, camera, shadows=options.shadows)
        n = len(self.times)
        self.gains = (1.0 + options.flicker * self.rng.standard_normal(n) if options.flicker > 0
                      else np.ones(n))
        self.occluders = occluder_schedule(n, options.occlusion, camera.width, camera.height, options.fps,
                                    self.rng)
        self.blur = options.blur_subframes > 1 and options.exposure > 0
        self.subframes = np.zeros(n, dtype=int)  # renders averaged in each frame drawn (0: not yet)
        self._acc = np.empty((*self.scene.background.shape[:2], 3), np.float32)
        self._noise = np.empty((camera.height, camera.width, 3), np.float32)
        self.hidden = hidden
        self._markers = {m.id: m for m in layout.markers}

    def __len__(self) -> int:
        return len(self.times)

    def frame(self, k: int) -> np.ndarray:
        """Frame ``k``, uint8 (height, width, 3), BGR. Frames must be drawn in order 0, 1, ... for
        the noise to be reproducible (it is drawn from ``rng`` frame by frame)."""
        options, t = self.options, float(self.times[k])
        scene, motion = self.scene, self.motion
        offsets = self._shutter(t)
        self.subframes[k] = len(offsets)
        if len(offsets) == 1:
            self._place(t)
            canvas = scene.draw(motion.state(t))
        else:
            acc = self._acc
            acc[:] = 0
            for dt in offsets:
                self._place(t + dt)
                cv2.accumulate(scene.draw(motion.state(t + dt)), acc)
            canvas = cv2.convertScaleAbs(acc, alpha=1.0 / len(offsets))  # >= 0: rounds, saturates
        frame = scene.finish(canvas)
        if self.hidden is not None:
            self._cover(frame, k)
        for ev in self.occluders:
            if ev[0] <= k < ev[0] + ev[1]:
                draw_occluder(frame, ev, k)
        gain = float(self.gains[k])
        if options.noise_sd > 0:
            # OpenCV's generator (4x faster than NumPy's here), seeded from ``rng`` every frame
            cv2.setRNGSeed(int(self.rng.integers(1, 2**31 - 1)))
            cv2.randn(self._noise, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))  # every channel
            frame = cv2.addWeighted(frame.astype(np.float32), gain, self._noise, float(options.noise_sd),
                                    0.0, dtype=cv2.CV_8U)
        elif gain != 1.0:
            frame = cv2.convertScaleAbs(frame, alpha=gain)
        if options.jpeg_quality is not None:
            _, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, options.jpeg_quality])
            frame = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return frame

    def _cover(self, frame: np.ndarray, k: int) -> None:
        """Paint over the markers ``hidden(k)`` names in frame ``k``, in place: a grey
        quadrilateral over each whole flag (its white margin too) wherever it is while the shutter
        is open, as another body in front of it would hide it (before the sensor's noise), so that
        the tracker neither decodes nor recovers it."""
        ids = [int(i) for i in self.hidden(k)]
        if not ids:
            return
        t = float(self.times[k])
        half = 0.5 * self.options.exposure / self.options.fps
        for i in ids:
            if i not in self._markers:
                raise RenderError(f"hidden marker id {i} is not in the layout")
            marker = self._markers[i]
            outline = []
            for dt in (-half, 0.0, half):
                self._place(t + dt)
                rot, tvec = self.scene.body_poses(self.motion.state(t + dt))[_BODY_KEY[marker.body]]
                outline.append(project(self.scene.camera, marker_corners(marker, 1.2 * marker.margin),
                                       cv2.Rodrigues(rot)[0], tvec))
            hull = cv2.convexHull(np.round(np.concatenate(outline) * 16).astype(np.int32))
            cv2.fillConvexPoly(frame, hull, (90, 90, 90), cv2.LINE_AA, 4)

    def _place(self, t: float) -> None:
        """Put a moving camera where it is at time ``t`` (s)."""
        if self.path is not None:
            self.scene.set_pose(*self.path.pose(t))

    def _shutter(self, t: float) -> np.ndarray:
        """Times (s, relative to ``t``) of the renders averaged for the frame at ``t``: one without
        blur; else spread evenly over the open shutter, at least ``blur_subframes`` of them and
        enough that the walker's image moves at most :data:`BLUR_STEP_PX` between neighbours (its
        largest displacement over the shutter time, a chord, stands for the path), and, for a
        moving camera, the ramp's image under the walker too. Vertices behind the camera at either
        end of the shutter are not counted."""
        if not self.blur:
            return np.zeros(1)
        half = 0.5 * self.options.exposure / self.options.fps
        # for a moving camera, the ramp where the walker stands
        below = None if self.path is None else self.scene.walker_points(self.motion.state(t)) * [1, 1, 0]
        ends = []
        for dt in (half, -half):
            self._place(t + dt)
            pixels = self.scene.walker_pixels(self.motion.state(t + dt))
            ends.append(pixels if below is None else np.concatenate([pixels, self.scene.ramp_pixels(below)]))
        step = np.linalg.norm(ends[0] - ends[1], axis=1)
        moved = float(np.max(step[np.isfinite(step)])) if np.isfinite(step).any() else 0.0
        count = int(min(MAX_SUBFRAMES, max(self.options.blur_subframes, math.ceil(moved / BLUR_STEP_PX) + 1)))
        return np.linspace(-half, half, count)

    def write_video(self, path: str | Path) -> np.ndarray:
        """Draw every frame into an MPEG-4 video at ``path`` and return the true angles, shape
        (n_frames, 4) (rad, as :meth:`truth`'s). For quick studies: no truth files, metadata or
        staging, which :func:`render` writes."""
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), float(self.options.fps),
                                 self.camera.size)
        if not writer.isOpened():
            raise RenderError(f"cannot open an mp4v video writer for {path}")
        try:
            angles = []
            for k in range(len(self)):
                writer.write(self.frame(k))
                angles.append(self.truth(k)[0])
        finally:
            writer.release()
        return np.array(angles)

    def truth(self, k: int) -> tuple[np.ndarray, str, np.ndarray]:
        """(lean, steer, pitch_left, pitch_right) (rad), the stance leg and its contact (x, y) (m) at
        frame ``k``."""
        t = float(self.times[k])
        stance = self.motion.stance_at(t)
        return self.motion.angles(t), stance, self.motion.contact(self.motion.state(t), stance)


def render(table, params, camera: Camera, layout: MarkerLayout, options: RenderOptions | None = None,
           out_path: str | Path = "video.mp4", rng=None, *, source: str | dict | None = None,
           progress=None, path: CameraPath | None = None) -> RenderResult:
    """Render a trajectory to a video with its truth and metadata (module docstring).

    Parameters
    ----------
    table : TrajectoryTable
        Angles ``lean, steer, pitch_left, pitch_right`` (rad), ``stance``, ideally ``contact_x,
        contact_y`` (m) and the heel-strike events.
    params : Params
        The walker drawn (its geometry).
    camera : Camera
        With a fixed ``ramp_pose`` (unless ``path`` moves it); its image size and distortion are the
        video's.
    layout : MarkerLayout
        Markers on the legs and the ramp.
    options : RenderOptions, optional
        Defaults to ``RenderOptions.preset(1)``.
    out_path : str or Path
        ``V.mp4`` or ``V.avi``; its folder must exist.
    rng : int, Generator or None
        Seeds every random draw (noise, flicker, occluders): ``np.random.default_rng(rng)``.
    source : str or dict, optional
        Where the trajectory came from, for the metadata.
    progress : callable, optional
        Called as ``progress(k, n_frames)`` after each frame.
    path : CameraPath, optional
        The camera moves along it (its ramp pose at each instant; ``camera.ramp_pose`` is not used).

    Returns
    -------
    RenderResult
    """
    t_start = _time.perf_counter()
    options = RenderOptions.preset(1) if options is None else options
    paths, codec = video_target(out_path, options)
    seed = rng if isinstance(rng, (int, np.integer)) or rng is None else "generator"
    film = Filming(table, params, camera, layout, options, rng, path)
    write_shoot(film, table, params, layout, paths, codec=codec, lens=film.camera, source=source, seed=seed,
                progress=progress)
    return RenderResult(paths=paths, frame_times=film.times, seconds=_time.perf_counter() - t_start,
                        in_view=share_in_view(film))


def share_in_view(film: Filming) -> np.ndarray:
    """Each frame's share (0 to 1) of the walker's mesh vertices (legs and flags) that the camera
    sees inside its image at the frame's time: 1 when the whole walker is filmed, 0 when none of
    it is (a walk that leaves a given camera's view; the tracker makes such frames gaps).

    Returns
    -------
    ndarray, shape (n_frames,)
    """
    share = np.empty(len(film.times))
    for k, t in enumerate(film.times):
        t = float(t)
        rvec, tvec = film.camera.ramp_pose if film.path is None else film.path.pose(t)
        uv = project(film.camera, film.scene.walker_points(film.motion.state(t)), rvec, tvec)
        inside = (np.isfinite(uv).all(axis=1) & (uv[:, 0] >= 0) & (uv[:, 0] <= film.camera.width - 1)
                  & (uv[:, 1] >= 0) & (uv[:, 1] <= film.camera.height - 1))
        share[k] = inside.mean()
    return share


def video_target(out_path: str | Path, options: RenderOptions) -> tuple[dict, str]:
    """The files a render writes (:func:`output_paths`) and the video's codec; refuses a video
    that is not ``.mp4`` or ``.avi`` and a folder that does not exist."""
    paths = output_paths(out_path)
    video = paths["video"]
    suffix = video.suffix.lower()
    if suffix not in _CODECS:
        raise RenderError(f"the video must be a .mp4 or .avi file, got {video.name}")
    if not video.parent.is_dir():
        raise RenderError(f"output folder does not exist: {video.parent}")
    return paths, options.codec or _CODECS[suffix]


def write_shoot(shoot, table, params, layout: MarkerLayout, paths: dict, *, codec: str, lens: Camera,
                source=None, seed=None, renderer: dict | None = None, progress=None) -> None:
    """Draw every frame of a prepared shoot into ``paths["video"]`` and write its truth, the truth's
    metadata, the lens and the markers beside it: all or nothing (staged in a hidden folder beside
    the video and moved into place last; a failure removes what was already moved).

    Parameters
    ----------
    shoot : Filming or toywalk.tracking.render_mujoco's shoot
        With ``motion, options, path, times, gains, occluders, subframes`` and ``frame(k)``,
        ``truth(k)`` (frames drawn in order).
    table, params, layout
        As for :func:`render`.
    paths : dict
        :func:`output_paths`.
    codec : str
        FourCC of the video writer.
    lens : Camera
        The camera filmed with (for a moving camera, at the first frame: ``V.camera.json`` then
        has no ramp pose).
    source, seed
        For the metadata.
    renderer : dict, optional
        Which renderer drew the frames, for the metadata (none: this module's).
    progress : callable, optional
        Called as ``progress(k, n_frames)`` after each frame.
    """
    from toywalk.model.trajectory import TrajectoryTable, write_trajectory

    video, options, path, motion, times = paths["video"], shoot.options, shoot.path, shoot.motion, shoot.times
    n = len(times)
    truth_events = paths["truth"].with_name(paths["truth"].stem + ".events.csv")
    keys = ["truth_events", "truth", "metadata", "camera", "markers", "video"]  # the video last
    finals = {**paths, "truth_events": truth_events}
    writer = None
    # all or nothing: staged beside the video, renamed into place when every file is written
    with staged_files([finals[key] for key in keys]) as staged_list:
        staged = dict(zip(keys, staged_list, strict=True))
        try:
            writer = cv2.VideoWriter(str(staged["video"]), cv2.VideoWriter_fourcc(*codec), float(options.fps),
                                     (lens.width, lens.height))
            if not writer.isOpened():
                raise RenderError(f"cannot open a {codec} video writer for {video.name}")
            truth = np.empty((n, 6))
            stances = []
            poses = []  # a moving camera's ramp pose in each frame (rvec, tvec), at the frame's time
            for k in range(n):
                writer.write(shoot.frame(k))
                truth[k, :4], stance, truth[k, 4:] = shoot.truth(k)
                stances.append(stance)
                if path is not None:
                    poses.append(np.concatenate(path.pose(float(times[k]))).tolist())
                if progress is not None:
                    progress(k + 1, n)
            writer.release()
            writer = None
            check = cv2.VideoCapture(str(staged["video"]))
            ok = check.isOpened()
            check.release()
            if not ok or staged["video"].stat().st_size == 0:
                raise RenderError(f"the {codec} video writer produced no readable file")
            events = [{"time": te, "foot": f, "x": math.nan, "y": math.nan} for te, f in motion.events
                      if times[0] <= te <= times[-1]]
            for ev in table.events:  # keep the contact positions where the trajectory has them
                for e in events:
                    if abs(e["time"] - float(ev["time"])) < 1e-12:
                        e["x"], e["y"] = float(ev.get("x", math.nan)), float(ev.get("y", math.nan))
            blur = options.blur_subframes > 1 and options.exposure > 0
            meta = {
                "units": {"time": "s", "angles": "rad", "contact": "m"},
                "source": {"kind": "render truth", "video": video.name, "trajectory": source,
                           "trajectory_source": table.metadata.get("source"),
                           "contact": motion.contact_source,
                           "interpolation": "PCHIP (angles, left hip point)"},
                "timestamps": (("frame k shows the trajectory at t0 + k / fps" if options.frame_times is None
                                else "frame k shows the trajectory at frame_times[k] (given; the video file "
                                     "is stamped t0 + k / fps)")
                               + "; with motion blur the shutter is open over t +- exposure / (2 fps)"),
                "motion_blur": {"renders_per_frame": shoot.subframes.tolist(), "max_step_px": BLUR_STEP_PX}
                if blur else None,
                "contact": "the stance foot's lowest point, from the drawn geometry",
                "video": video.name,
                "truth": paths["truth"].name,
                "size": [lens.width, lens.height],
                "fps": options.fps,
                "frames": n,
                "codec": codec,
                "frame_times": times.tolist(),
                "params": params_record(params),
                "camera": lens.to_dict(),
                "camera_path": None if path is None else {
                    "kind": "moves without turning (tracking.scene.CameraPath)",
                    "frames": "ramp pose (rvec, tvec) in each frame, at the frame's time",
                    "poses": poses},
                "markers": layout.to_dict(),
                "options": dataclasses.asdict(options),
                "seed": int(seed) if isinstance(seed, np.integer) else seed,
                "occluders": [{"first_frame": a, "frames": b, **p} for a, b, p in shoot.occluders],
                "gains": shoot.gains.tolist(),
                "software": _version(),
            }
            if renderer is not None:
                meta["renderer"] = renderer
            signals = {"lean": truth[:, 0], "steer": truth[:, 1], "pitch_left": truth[:, 2],
                       "pitch_right": truth[:, 3], "contact_x": truth[:, 4], "contact_y": truth[:, 5]}
            # the truth's metadata file NAME.json (model.trajectory's naming) is V.json itself
            truth_table = TrajectoryTable(times, signals, stances, events, meta)
            written = write_trajectory(truth_table, staged["truth"])
            if written[2] != staged["metadata"]:
                raise RuntimeError(f"unexpected trajectory metadata name {written[2]}")
            # a moving camera's lens only: its ramp pose changes from frame to frame
            lens_file = lens if path is None else dataclasses.replace(lens, ramp_pose=None)
            staged["camera"].write_text(json.dumps(lens_file.to_dict(), indent=2) + "\n")
            staged["markers"].write_text(json.dumps(layout.to_dict(), indent=2) + "\n")
            if written[1] != staged["truth_events"]:
                raise RuntimeError(f"unexpected trajectory events name {written[1]}")
        except BaseException:
            if writer is not None:
                writer.release()
            raise


def default_filming(table, params, width: int = 1280, height: int = 720,
                    options: RenderOptions | None = None) -> tuple[Camera, CameraPath | None, MarkerLayout]:
    """How ``toywalk render`` films a trajectory when given no camera and no marker layout:
    (camera, path, layout). One fixed camera frames the walk filmed (the span ``options`` render)
    where it can do so from near enough (path None); a longer walk is followed along the ramp
    (:func:`toywalk.tracking.scene.default_view`), with the ramp markers of
    :func:`toywalk.tracking.markers.default_layout` laid on as far as the camera will look."""
    motion = Motion(table, params)
    frames = shoot_times(motion, RenderOptions() if options is None else options)
    t0, t1 = float(frames[0]), float(frames[-1])
    # 200 Hz: the path's linear pieces are far shorter than a frame interval at 60 fps
    times = np.linspace(t0, t1, max(2, int(math.ceil((t1 - t0) * 200.0)) + 1))
    camera, path = default_view(params, times, motion.hips(times), width, height)
    reach = None
    if path is not None:  # the default rows reach 2.3 l, the corridor's front 2.2 l ahead
        reach = 2.3 * float(params.leg_length) + float(np.max(path.offsets[:, 0]))
    return camera, path, default_layout(params, reach=reach)


def params_record(params) -> dict:
    from toywalk.model.parameters import PARAMETER_NAMES

    return dict(zip(PARAMETER_NAMES, (float(v) for v in params.vector()), strict=True))
