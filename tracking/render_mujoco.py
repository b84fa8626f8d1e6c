"""An independent renderer: a walk filmed by MuJoCo's OpenGL renderer instead of the project's own.

The tracker is tested on videos that :mod:`toywalk.tracking.render` draws; a tracker tuned on one
renderer's images can come to depend on its quirks (its edge anti-aliasing, its marker warps, its
flat shading). This module draws the same walk, markers and ramp board with another rasteriser:
MuJoCo's OpenGL renderer (Todorov, Erez & Tassa, IROS 2012, doi:10.1109/IROS.2012.6386109),
headless (EGL, or OSMesa), with its own lighting (a directional light that casts shadows, a
headlight, specular highlights), texture filtering (mipmaps) and multisample anti-aliasing.

The scene (an MJCF model, world frame = the ramp frame S of docs/model.md section 1):

- each leg is a mocap body whose frame is the leg's body frame (origin at its hip point, b1
  forward, b2 along the axle, b3 up the leg), placed at each instant from
  :class:`toywalk.tracking.render.Motion` (the renderer's own interpolation of the trajectory:
  the same poses, hence the same truth); its rod is a capsule, its hub a cylinder, its foot a
  sphere or, for a spool foot, an ellipsoid of the foot's two radii, its balance mass a sphere on
  an arm, the left leg's axle a capsule;
- each marker of the layout is a textured plane geom at its pose in its body, the printed face
  (cv2.aruco's marker with its white margin, as a PNG texture) exactly in the marker's plane, with
  a thin paper-grey box behind it (the flag's back) and, on a leg, a stem to the rod;
- the ramp is a plane a hair below z = 0 (under the ramp markers' faces), with a speckled texture,
  large enough to hold the ramp markers; a gradient skybox behind.

MuJoCo's camera is a pinhole with square pixels, the principal point at the image centre and no
lens distortion; it cannot reproduce a calibrated camera's. The camera filmed
(:func:`mujoco_camera`) keeps the requested camera's image size, vertical focal length fy (MuJoCo's
``fovy = 2 atan(h / (2 fy))``) and ramp pose, and has ``fx = fy``, principal point
``((w - 1) / 2, (h - 1) / 2)`` (OpenGL's viewport centre in OpenCV's pixel convention) and zero
distortion: that is the camera file written next to the video, for the tracker.

The camera's imperfections follow :class:`toywalk.tracking.render.RenderOptions` (its ``--noise``
presets): motion blur as the average of renders over the open shutter (as many as keep the
walker's image moving at most :data:`toywalk.tracking.render.BLUR_STEP_PX` between renders),
flicker gains, occluders, Gaussian sensor noise drawn from a seeded NumPy generator, optional JPEG
artefacts; ``shadows`` switches the light's shadow map. Outputs are those of
:func:`toywalk.tracking.render.render`, written atomically together: ``V.mp4``, ``V.truth.csv``
(+ events), ``V.json``, ``V.camera.json`` (the camera filmed), ``V.markers.json``.

OpenGL: one process loads one OpenGL platform, so the backend is chosen once
(:func:`gl_backend`): ``MUJOCO_GL`` if it names ``egl`` or ``osmesa``, else the first of them
that makes a context in a child process; the renderer then makes its context from that backend's
own class, whatever backend ``import mujoco`` bound by default (the same calls as
``mujoco.Renderer``: ``mjv_updateScene``, ``mjr_render``, ``mjr_readPixels``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import subprocess
import sys
import tempfile
import time as _time
from pathlib import Path

import cv2
import numpy as np

from .camera import Camera, pose_matrix
from .markers import Marker, MarkerLayout, marker_corners, marker_pose_matrix
from .render import (
    BLUR_STEP_PX,
    MAX_SUBFRAMES,
    Motion,
    RenderError,
    RenderOptions,
    RenderResult,
    draw_occluder,
    occluder_schedule,
    shoot_times,
    video_target,
    write_shoot,
)
from .scene import CameraPath, WalkerState

__all__ = ["GL_BACKENDS", "MSAA_SAMPLES", "MujocoScene", "MujocoUnavailable", "gl_backend",
           "mujoco_camera", "render_mujoco", "scene_mjcf"]

#: Headless OpenGL backends tried, in order (MuJoCo's names, as for ``MUJOCO_GL``).
GL_BACKENDS = ("egl", "osmesa")
#: Multisample anti-aliasing: samples per pixel of MuJoCo's offscreen buffer (its default, 4).
MSAA_SAMPLES = 4

_CODECS = {".mp4": "mp4v", ".avi": "MJPG"}
# Colours (RGB, 0-1): a different palette from tracking.scene's on purpose.
_ROD = {"L": (0.20, 0.35, 0.80), "R": (0.90, 0.45, 0.10)}
_HUB = (0.80, 0.68, 0.48)
_FOOT = (0.72, 0.60, 0.35)
_AXLE = (0.75, 0.15, 0.12)
_MASS = (0.42, 0.42, 0.46)
_STEM = (0.60, 0.60, 0.60)
_FLAG_BACK = (0.78, 0.78, 0.76)
_INK, _PAPER = 20, 235  # printed marker black and white (grey levels of the texture)
_CELL_PX = 32  # texture pixels per marker cell (a 4x4 marker: 192 px for its black square)
# The ramp's surface lies this far (in leg lengths) below its markers' faces, and a flag's back this
# far behind its face, so that the depth test never mixes them: 2e-3 l is 8x the depth buffer's
# resolution where the ramp is seen, at 4 l and 25 degrees with the near plane at 0.01 l (24 bits).
_GAP = 2e-3
# The near and far clipping planes (leg lengths): MuJoCo's znear and zfar are fractions of the
# model's extent, set to 10 l.
_EXTENT, _NEAR, _FAR = 10.0, 0.01, 1000.0


class MujocoUnavailable(RuntimeError):
    """MuJoCo, or a headless OpenGL backend for it, is missing; the message says what to do."""


def _require_mujoco():
    try:
        import mujoco
    except ImportError as err:
        raise MujocoUnavailable("the MuJoCo renderer needs the mujoco package: pip install mujoco") from err
    return mujoco


_PROBE = ("from mujoco.{0} import GLContext\n"
          "c = GLContext(8, 8)\n"
          "c.make_current()\n"
          "c.free()\n")


@functools.cache
def gl_backend() -> str:
    """The headless OpenGL backend MuJoCo renders with here: ``MUJOCO_GL`` if it names one of
    :data:`GL_BACKENDS`, else the first of them that makes a context in a child process (one
    process can load one OpenGL platform, so a failed try would spoil this one). It is written to
    ``MUJOCO_GL`` for a later ``import mujoco``.

    Raises
    ------
    MujocoUnavailable
        ``MUJOCO_GL`` names another backend, or none works (what each said is in the message).
    """
    chosen = os.environ.get("MUJOCO_GL", "").strip().lower()
    if chosen in GL_BACKENDS:
        return chosen
    if chosen:
        raise MujocoUnavailable(f"MUJOCO_GL={chosen!r} is not a headless backend; set it to one of "
                                f"{', '.join(GL_BACKENDS)} or unset it")
    platform = os.environ.get("PYOPENGL_PLATFORM", "").strip().lower()
    tried = []
    for name in (platform,) if platform in GL_BACKENDS else GL_BACKENDS:
        env = {**os.environ, "MUJOCO_GL": name, "PYOPENGL_PLATFORM": name}
        try:
            run = subprocess.run([sys.executable, "-c", _PROBE.format(name)], env=env, capture_output=True,
                                 text=True, timeout=120)
        except subprocess.TimeoutExpired:
            tried.append(f"{name}: no answer in 120 s")
            continue
        if run.returncode == 0:
            os.environ["MUJOCO_GL"] = name
            return name
        lines = run.stderr.strip().splitlines()
        tried.append(f"{name}: {lines[-1] if lines else f'exit status {run.returncode}'}")
    raise MujocoUnavailable("no headless OpenGL backend for MuJoCo works here (" + "; ".join(tried)
                            + "); install EGL (libegl1) or OSMesa (libosmesa6), or set MUJOCO_GL")


def _context_class(backend: str):
    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    return GLContext


def mujoco_camera(camera: Camera) -> Camera:
    """The camera MuJoCo films with in place of ``camera`` (module docstring): same image size,
    ``fy`` and ramp pose; ``fx = fy``, the principal point at the image centre, no distortion."""
    if not isinstance(camera, Camera):
        raise TypeError(f"camera must be a Camera, got {type(camera).__name__}")
    f = float(camera.matrix[1, 1])
    k = np.array([[f, 0.0, (camera.width - 1) / 2], [0.0, f, (camera.height - 1) / 2], [0.0, 0.0, 1.0]])
    return Camera(width=camera.width, height=camera.height, matrix=k, distortion=np.zeros(5),
                  ramp_pose=camera.ramp_pose)


# --- the MJCF scene -------------------------------------------------------------------------------

def _num(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def _rgba(rgb, alpha: float = 1.0) -> str:
    return _num([*rgb, alpha])


def _frame_attrs(rot: np.ndarray, pos) -> str:
    """MJCF position and orientation (``xyaxes``: the frame's first two axes) of a pose."""
    return f'pos="{_num(pos)}" xyaxes="{_num(rot[:, 0])} {_num(rot[:, 1])}"'


def _marker_texture(dictionary, marker: Marker) -> tuple[np.ndarray, float]:
    """The printed marker with its white margin (uint8, grey) and the plane's half side (m) that
    puts the black square's corners exactly at the marker's (the margin is rounded to pixels)."""
    side_px = (dictionary.markerSize + 2) * _CELL_PX
    margin_px = int(round(marker.margin / marker.side * side_px))
    img = cv2.aruco.generateImageMarker(dictionary, marker.id, side_px)
    img = np.where(img > 127, _PAPER, _INK).astype(np.uint8)
    img = cv2.copyMakeBorder(img, margin_px, margin_px, margin_px, margin_px, cv2.BORDER_CONSTANT,
                             value=_PAPER)
    return img, 0.5 * marker.side * (side_px + 2 * margin_px) / side_px


def _ramp_extent(params, layout: MarkerLayout) -> tuple[tuple[float, float], tuple[float, float]]:
    """(x range, y range) of the ramp board (m): the walking corridor, grown to hold the ramp
    markers with a tenth of a leg length to spare, and running 2.3 l past the last of them."""
    ell, w = float(params.leg_length), float(params.hip_width)
    y_mid = -0.5 * w
    half = 1.25 * ell + 0.5 * w
    xr, yr = [-1.8 * ell, 4.6 * ell], [y_mid - half, y_mid + half]
    for m in layout.on("ramp"):
        pts = marker_corners(m, m.margin)
        xr = [min(xr[0], pts[:, 0].min() - 0.1 * ell), max(xr[1], pts[:, 0].max() + 2.3 * ell)]
        yr = [min(yr[0], pts[:, 1].min() - 0.1 * ell), max(yr[1], pts[:, 1].max() + 0.1 * ell)]
    return (xr[0], xr[1]), (yr[0], yr[1])


def _leg_geoms(params, leg: str) -> list[str]:
    """MJCF geoms of one leg in its body frame (and, for the left leg, the axle)."""
    ell, r, rho, w = (float(params.leg_length), float(params.foot_radius),
                      float(params.foot_lateral_radius), float(params.hip_width))
    dx, dy, dz = (float(v) for v in params.com_offset)
    outboard = 1.0 if leg == "L" else -1.0
    rod = 0.025 * ell
    foot = np.array([0.0, 0.0, -(ell - r)])
    out = [f'<geom type="capsule" fromto="{_num([0, 0, 2.5 * rod])} {_num(foot)}" size="{rod!r}" '
           f'rgba="{_rgba(_ROD[leg])}"/>',
           f'<geom type="cylinder" fromto="0 {-1.6 * rod!r} 0 0 {1.6 * rod!r} 0" size="{2.2 * rod!r}" '
           f'rgba="{_rgba(_HUB)}"/>']
    if r <= 0:
        out.append(f'<geom type="sphere" pos="{_num(foot)}" size="{1.2 * rod!r}" rgba="{_rgba(_FOOT)}"/>')
    elif r - rho < 0.5 * rho:  # (nearly) a sphere
        out.append(f'<geom type="sphere" pos="{_num(foot)}" size="{r!r}" rgba="{_rgba(_FOOT)}"/>')
    else:  # a spool: an ellipsoid of the foot's two radii, where tracking.scene draws a torus
        out.append(f'<geom type="ellipsoid" pos="{_num(foot)}" size="{_num([r, rho, r])}" '
                   f'rgba="{_rgba(_FOOT)}"/>')
    mass_r = 0.07 * ell
    mass_c = np.array([dx, outboard * dy, dz])
    if abs(dy) > mass_r or abs(dx) > mass_r:
        out.append(f'<geom type="capsule" fromto="0 0 {dz!r} {_num(mass_c)}" size="{0.7 * rod!r}" '
                   f'rgba="{_rgba(_STEM)}"/>')
    out.append(f'<geom type="sphere" pos="{_num(mass_c)}" size="{mass_r!r}" rgba="{_rgba(_MASS)}"/>')
    if leg == "L":  # the axle through both hips; the right hip is w to the right (-b2)
        over = 3.0 * rod
        out.append(f'<geom type="capsule" fromto="0 {over!r} 0 0 {-(w + over)!r} 0" size="{0.8 * rod!r}" '
                   f'rgba="{_rgba(_AXLE)}"/>')
    return out


def _flag_geoms(params, marker: Marker, half: float, stem: bool) -> list[str]:
    """A marker's printed face (a textured plane in the marker's plane), the flag's back (a thin
    box behind it) and, on a leg, its stem, in its body's frame."""
    ell = float(params.leg_length)
    pose = marker_pose_matrix(marker)
    rot, centre = pose[:3, :3], pose[:3, 3]
    normal = rot[:, 2]
    thick = 0.004 * ell
    out = [f'<geom type="plane" {_frame_attrs(rot, centre)} size="{half!r} {half!r} {half!r}" '
           f'material="marker{marker.id}"/>',
           f'<geom type="box" {_frame_attrs(rot, centre - (thick + _GAP * ell) * normal)} '
           f'size="{half!r} {half!r} {thick!r}" rgba="{_rgba(_FLAG_BACK)}"/>']
    if stem:
        rod = 0.025 * ell
        end = centre - 0.5 * rod * normal
        root = np.array([0.0, 0.0, end[2]])
        if np.linalg.norm(end - root) > rod:
            out.append(f'<geom type="capsule" fromto="{_num(root)} {_num(end)}" size="{0.45 * rod!r}" '
                       f'rgba="{_rgba(_STEM)}"/>')
    return out


def _light_direction() -> np.ndarray:
    """Direction the light shines (ramp frame, unit): down from above, behind and to the right of
    the walker (tracking.scene's light is ahead and to its left)."""
    d = np.array([0.35, 0.45, -1.0])
    return d / np.linalg.norm(d)


def scene_mjcf(params, layout: MarkerLayout, camera: Camera, texture_dir: Path, *,
               shadows: bool = True, samples: int = MSAA_SAMPLES) -> str:
    """The MJCF of the filmed scene (module docstring); the marker textures are written to
    ``texture_dir`` as PNG files. ``camera`` is the camera filmed (:func:`mujoco_camera`), its
    ``ramp_pose`` where it starts."""
    dictionary = layout.aruco_dictionary()
    ell = float(params.leg_length)
    assets, world = [], []
    for m in layout.markers:
        img, _ = _marker_texture(dictionary, m)
        path = Path(texture_dir) / f"marker{m.id}.png"
        if not cv2.imwrite(str(path), img):
            raise RenderError(f"cannot write a marker texture to {path}")
        assets.append(f'<texture name="marker{m.id}" type="2d" file="{path}"/>')
        assets.append(f'<material name="marker{m.id}" texture="marker{m.id}" texrepeat="1 1" '
                      f'texuniform="false" specular="0.15" shininess="0.3"/>')
    xr, yr = _ramp_extent(params, layout)
    centre = [0.5 * (xr[0] + xr[1]), 0.5 * (yr[0] + yr[1]), -_GAP * ell]
    size = [0.5 * (xr[1] - xr[0]), 0.5 * (yr[1] - yr[0]), 0.25 * ell]
    world.append(f'<geom name="ramp" type="plane" pos="{_num(centre)}" size="{_num(size)}" material="ramp"/>')
    for m in layout.on("ramp"):
        world.extend(_flag_geoms(params, m, _marker_texture(dictionary, m)[1], stem=False)[:1])
    rot, c = _camera_frame(camera.ramp_pose)
    fovy = math.degrees(2.0 * math.atan(0.5 * camera.height / float(camera.matrix[1, 1])))
    world.append(f'<camera name="film" pos="{_num(c)}" xyaxes="{_num(rot[:, 0])} {_num(rot[:, 1])}" '
                 f'fovy="{fovy!r}"/>')
    light = _light_direction()
    world.append(f'<light name="sun" directional="true" pos="{_num(-3 * ell * light)}" dir="{_num(light)}" '
                 f'diffuse="0.55 0.55 0.52" specular="0.15 0.15 0.15" '
                 f'castshadow="{"true" if shadows else "false"}"/>')
    legs = []
    for leg, name in (("L", "left_leg"), ("R", "right_leg")):
        geoms = _leg_geoms(params, leg)
        for m in layout.on(name):
            geoms.extend(_flag_geoms(params, m, _marker_texture(dictionary, m)[1], stem=True))
        legs.append(f'<body name="{name}" mocap="true">' + "".join(geoms) + "</body>")
    ramp_tex = max(256, int(round(2048 * size[0] / (10 * ell))))
    return f"""<mujoco model="toywalk filmed scene">
  <compiler angle="radian"/>
  <option gravity="0 0 0"/>
  <statistic extent="{_EXTENT * ell!r}" center="{_num(centre)}"/>
  <visual>
    <global offwidth="{camera.width}" offheight="{camera.height}"/>
    <quality offsamples="{int(samples)}" shadowsize="4096"/>
    <map znear="{_NEAR / _EXTENT!r}" zfar="{_FAR / _EXTENT!r}" shadowclip="{2.0 * _EXTENT!r}"/>
    <headlight ambient="0.25 0.25 0.25" diffuse="0.25 0.25 0.25" specular="0.05 0.05 0.05"/>
  </visual>
  <default><geom contype="0" conaffinity="0"/></default>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.62 0.70 0.78" rgb2="0.25 0.27 0.30"
             width="256" height="256"/>
    <texture name="ramp" type="2d" builtin="flat" rgb1="0.80 0.66 0.50" mark="random" random="0.08"
             markrgb="0.62 0.48 0.34" width="{ramp_tex}" height="{ramp_tex}"/>
    <material name="ramp" texture="ramp" texrepeat="1 1" texuniform="false" specular="0.05"/>
    {"".join(assets)}
  </asset>
  <worldbody>
    {"".join(world)}
    {"".join(legs)}
  </worldbody>
</mujoco>
"""


def _camera_frame(ramp_pose) -> tuple[np.ndarray, np.ndarray]:
    """(axes, centre) of MuJoCo's camera for an OpenCV ramp-to-camera pose: axes as columns in the
    ramp frame, x right, y up, looking along -z (OpenCV's y and z turned over), and the camera's
    centre (m)."""
    pose = pose_matrix(*ramp_pose)
    r = pose[:3, :3]
    return np.column_stack([r[0], -r[1], -r[2]]), -r.T @ pose[:3, 3]


# --- rendering ------------------------------------------------------------------------------------

class MujocoScene:
    """The MuJoCo model of the filmed scene and an offscreen OpenGL context to draw it.

    Parameters
    ----------
    params : Params
    layout : MarkerLayout
    camera : Camera
        The camera to film with; MuJoCo films with :func:`mujoco_camera` of it (:attr:`camera`).
        Must have a ``ramp_pose`` (where a moving camera starts).
    shadows : bool
        The light casts shadows.
    samples : int
        Multisample anti-aliasing samples per pixel.

    Use as a context manager, or call :meth:`close`, to free the OpenGL context.
    """

    def __init__(self, params, layout: MarkerLayout, camera: Camera, *, shadows: bool = True,
                 samples: int = MSAA_SAMPLES):
        if not isinstance(layout, MarkerLayout):
            raise TypeError(f"layout must be a MarkerLayout, got {type(layout).__name__}")
        if not isinstance(camera, Camera):
            raise TypeError(f"camera must be a Camera, got {type(camera).__name__}")
        if camera.ramp_pose is None:
            raise RenderError("the camera has no ramp_pose: the renderer needs a fixed camera or a path")
        if isinstance(samples, bool) or not isinstance(samples, int) or not 0 <= samples <= 16:
            raise RenderError(f"samples must be an integer 0..16, got {samples!r}")
        backend = gl_backend()
        mujoco = _require_mujoco()
        self.camera = mujoco_camera(camera)
        self.params, self.layout, self.samples, self.backend = params, layout, samples, backend
        with tempfile.TemporaryDirectory(prefix="toywalk-mjtex-") as folder:
            self.mjcf = scene_mjcf(params, layout, self.camera, Path(folder), shadows=shadows,
                                   samples=samples)
            self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        self._mocap = {leg: int(self.model.body_mocapid[self.model.body(name).id])
                       for leg, name in (("L", "left_leg"), ("R", "right_leg"))}
        self._cam_id = self.model.camera("film").id
        self._gl = self._con = None
        try:
            self._gl = _context_class(backend)(camera.width, camera.height)
            self._gl.make_current()
            self._con = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_150.value)
        except (ImportError, OSError, RuntimeError) as err:
            self.close()
            why = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise MujocoUnavailable(f"cannot make a MuJoCo OpenGL context with {backend}: {why}") from err
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._con)
        self._scene = mujoco.MjvScene(self.model, maxgeom=1000)
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._view = mujoco.MjvCamera()
        self._view.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._view.fixedcamid = self._cam_id
        self._rect = mujoco.MjrRect(0, 0, camera.width, camera.height)
        self._rgb = np.empty((camera.height, camera.width, 3), np.uint8)
        self._mujoco = mujoco
        self._pose = camera.ramp_pose

    def __enter__(self) -> MujocoScene:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Free the OpenGL resources (idempotent)."""
        if self._con is not None:
            self._gl.make_current()
            self._con.free()
            self._con = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None

    def place(self, state: WalkerState, ramp_pose=None) -> None:
        """Put the legs at ``state`` and, with ``ramp_pose`` (rvec, tvec), the camera there."""
        mujoco = self._mujoco
        for leg, i in self._mocap.items():
            self.data.mocap_pos[i] = state.hip[leg]
            mujoco.mju_mat2Quat(self.data.mocap_quat[i], np.ascontiguousarray(state.rotation[leg]).ravel())
        if ramp_pose is not None:
            rot, c = _camera_frame(ramp_pose)
            self.model.cam_pos[self._cam_id] = c
            mujoco.mju_mat2Quat(self.model.cam_quat[self._cam_id], np.ascontiguousarray(rot).ravel())
            self._pose = ramp_pose
        mujoco.mj_forward(self.model, self.data)

    def draw(self, state: WalkerState, ramp_pose=None) -> np.ndarray:
        """The image of the walker at ``state`` (camera moved to ``ramp_pose`` if given), uint8
        (height, width, 3), BGR (OpenCV's order), top row first."""
        if self._con is None:
            raise RuntimeError("the scene's OpenGL context is closed")
        mujoco = self._mujoco
        self.place(state, ramp_pose)
        self._gl.make_current()
        mujoco.mjv_updateScene(self.model, self.data, self._option, self._perturb, self._view,
                               mujoco.mjtCatBit.mjCAT_ALL.value, self._scene)
        mujoco.mjr_render(self._rect, self._scene, self._con)
        mujoco.mjr_readPixels(self._rgb, None, self._rect, self._con)
        return np.ascontiguousarray(self._rgb[::-1, :, ::-1])  # OpenGL's rows run bottom up; RGB

    def walker_points(self, state: WalkerState) -> np.ndarray:
        """Ramp-frame points (m, 3) (m) that bound the walker's image: each leg's rod ends, foot,
        balance mass and flag corners."""
        return np.concatenate([self._points[leg] @ state.rotation[leg].T + state.hip[leg]
                               for leg in ("L", "R")])

    @functools.cached_property
    def _points(self) -> dict:
        ell, r = float(self.params.leg_length), float(self.params.foot_radius)
        dx, dy, dz = (float(v) for v in self.params.com_offset)
        out = {}
        for leg, body in (("L", "left_leg"), ("R", "right_leg")):
            side = 1.0 if leg == "L" else -1.0
            pts = [[0, 0, 0.0625 * ell], [0, 0, -ell], [r, 0, -(ell - r)], [-r, 0, -(ell - r)],
                   [dx, side * dy, dz]]
            out[leg] = np.concatenate([np.array(pts, float)]
                                      + [marker_corners(m, m.margin) for m in self.layout.on(body)])
        return out

    def pixels(self, points, ramp_pose=None) -> np.ndarray:
        """Pixels (m, 2) of ramp-frame points (m, 3) seen by the camera (at ``ramp_pose`` if given);
        NaN behind it."""
        pose = pose_matrix(*(self._pose if ramp_pose is None else ramp_pose))
        pc = np.asarray(points, float).reshape(-1, 3) @ pose[:3, :3].T + pose[:3, 3]
        k = self.camera.matrix
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = pc[:, :2] / pc[:, 2:] * [k[0, 0], k[1, 1]] + k[:2, 2]
        uv[pc[:, 2] <= 0] = np.nan
        return uv


@dataclasses.dataclass
class _Shoot:
    """A prepared MuJoCo shoot: the motion, frame times and imperfection schedule (drawn from
    ``rng`` in a fixed order: gains, occluders, then each frame's noise as it is drawn)."""

    motion: Motion
    scene: MujocoScene
    options: RenderOptions
    path: CameraPath | None
    rng: np.random.Generator
    times: np.ndarray
    gains: np.ndarray
    occluders: list
    subframes: np.ndarray

    def pose(self, t: float):
        return None if self.path is None else self.path.pose(t)

    def shutter(self, t: float) -> np.ndarray:
        """Render times (s, relative to ``t``): as :meth:`toywalk.tracking.render.Filming._shutter`,
        from the walker points of :meth:`MujocoScene.walker_points` (and, for a moving camera, the
        ramp under them)."""
        options, scene, motion = self.options, self.scene, self.motion
        if not (options.blur_subframes > 1 and options.exposure > 0):
            return np.zeros(1)
        half = 0.5 * options.exposure / options.fps
        below = None if self.path is None else scene.walker_points(motion.state(t)) * [1, 1, 0]
        ends = []
        for dt in (half, -half):
            pts = scene.walker_points(motion.state(t + dt))
            if below is not None:
                pts = np.concatenate([pts, below])
            ends.append(scene.pixels(pts, self.pose(t + dt) if self.path is not None else None))
        step = np.linalg.norm(ends[0] - ends[1], axis=1)
        moved = float(np.max(step[np.isfinite(step)])) if np.isfinite(step).any() else 0.0
        count = int(min(MAX_SUBFRAMES, max(options.blur_subframes, math.ceil(moved / BLUR_STEP_PX) + 1)))
        return np.linspace(-half, half, count)

    def frame(self, k: int) -> np.ndarray:
        """Frame ``k``, uint8 (height, width, 3), BGR; frames in order 0, 1, ... (the noise)."""
        t, options, scene, motion = float(self.times[k]), self.options, self.scene, self.motion
        offsets = self.shutter(t)
        self.subframes[k] = len(offsets)
        if len(offsets) == 1:
            image = scene.draw(motion.state(t), self.pose(t)).astype(np.float32)
        else:
            image = np.zeros((scene.camera.height, scene.camera.width, 3), np.float32)
            for dt in offsets:
                image += scene.draw(motion.state(t + dt), self.pose(t + dt))
            image /= len(offsets)
        image *= float(self.gains[k])
        if options.noise_sd > 0:
            image += float(options.noise_sd) * self.rng.standard_normal(image.shape, dtype=np.float32)
        frame = np.clip(np.rint(image), 0, 255).astype(np.uint8)
        for ev in self.occluders:
            if ev[0] <= k < ev[0] + ev[1]:
                draw_occluder(frame, ev, k)
        if options.jpeg_quality is not None:
            _, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, options.jpeg_quality])
            frame = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return frame

    def truth(self, k: int) -> tuple[np.ndarray, str, np.ndarray]:
        t = float(self.times[k])
        stance = self.motion.stance_at(t)
        return self.motion.angles(t), stance, self.motion.contact(self.motion.state(t), stance)


def render_mujoco(table, params, camera: Camera, layout: MarkerLayout, options: RenderOptions | None = None,
                  out_path: str | Path = "video.mp4", rng=None, *, source: str | dict | None = None,
                  progress=None, path: CameraPath | None = None,
                  samples: int = MSAA_SAMPLES) -> RenderResult:
    """Render a trajectory to a video with MuJoCo, with its truth and metadata (module docstring).

    Parameters
    ----------
    table, params, layout, options, out_path, rng, source, progress, path
        As for :func:`toywalk.tracking.render.render`; ``options`` defaults to
        ``RenderOptions.preset(1)``.
    camera : Camera
        Its image size, ``fy`` and ramp pose are filmed with (:func:`mujoco_camera`; its
        distortion and principal point are not: ``V.camera.json`` holds the camera filmed).
    samples : int
        Multisample anti-aliasing samples per pixel (:data:`MSAA_SAMPLES`).

    Returns
    -------
    RenderResult
        ``paths`` as :func:`toywalk.tracking.render.output_paths`.

    Raises
    ------
    RenderError
        Bad input (trajectory, options, output path).
    MujocoUnavailable
        No mujoco package or no headless OpenGL backend.
    """
    t_start = _time.perf_counter()
    options = RenderOptions.preset(1) if options is None else options
    if not isinstance(options, RenderOptions):
        raise TypeError(f"options must be RenderOptions, got {type(options).__name__}")
    if path is not None and not isinstance(path, CameraPath):
        raise TypeError(f"path must be a CameraPath or None, got {type(path).__name__}")
    paths, codec = video_target(out_path, options)
    seed = rng if isinstance(rng, (int, np.integer)) or rng is None else "generator"
    generator = np.random.default_rng(rng)
    motion = Motion(table, params)
    times = shoot_times(motion, options)
    if path is not None:  # the scene starts where the path does
        camera = dataclasses.replace(camera, ramp_pose=path.pose(float(times[0])))
    n = len(times)
    gains = 1.0 + options.flicker * generator.standard_normal(n) if options.flicker > 0 else np.ones(n)
    occluders = occluder_schedule(n, options.occlusion, camera.width, camera.height, options.fps, generator)
    with MujocoScene(params, layout, camera, shadows=options.shadows, samples=samples) as scene:
        shoot = _Shoot(motion, scene, options, path, generator, times, gains, occluders,
                       np.zeros(n, dtype=int))
        renderer = {"engine": "mujoco", "mujoco": scene._mujoco.__version__, "gl_backend": scene.backend,
                    "msaa_samples": samples, "module": "toywalk.tracking.render_mujoco",
                    "camera_requested": camera.to_dict()}
        write_shoot(shoot, table, params, layout, paths, codec=codec, lens=scene.camera, source=source,
                    seed=seed, renderer=renderer, progress=progress)
    return RenderResult(paths=paths, frame_times=times, seconds=_time.perf_counter() - t_start)
