"""The synthetic scene the renderer draws: the walker's meshes, the textured ramp, the default camera.

Everything is scaled from the walker's parameters (leg length l), so a 15 cm toy and a 50 cm
compass walker both fill the frame. Geometry follows docs/model.md sections 1-2: each leg's body frame
has its origin at the hip point, ``b1`` forward, ``b2`` along the hip axis (left), ``b3`` along the
leg from foot to hip; the foot is a torus (tube radius rho, major radius r - rho about ``b2``) whose
centre lies on the leg axis at l - r below the hip.

Drawing is a painter's algorithm (faces sorted far to near, back faces of closed surfaces culled),
flat Lambert shading from one light direction, anti-aliased polygon fills, and printed markers
warped onto their flags with 4x supersampling so that their corners land where
:func:`toywalk.tracking.camera.project` says, to a small fraction of a pixel. The image is drawn
with an ideal pinhole camera on a canvas large enough to hold the distorted field of view, then
remapped with the camera's lens distortion.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import numpy as np

from .camera import Camera, default_camera, pose_matrix, undistort_pixels
from .markers import Marker, MarkerLayout, marker_corners, marker_pose_matrix

__all__ = ["FOLLOW_BEYOND", "CameraPath", "Scene", "WalkerState", "default_camera_for", "default_view",
           "follow_walk", "light_direction", "look_at"]

#: Direction towards the light in the ramp frame (unit): above, ahead and to the left of the walker.
_LIGHT = np.array([0.45, 0.5, 1.0])

# Colours (BGR, 0-255).
_ROD = {"L": (190, 95, 40), "R": (35, 125, 225)}  # Tinkertoy blue and orange rods
_SPOOL = (120, 175, 215)  # natural wood
_BRASS = (70, 165, 205)
_AXLE = (45, 45, 200)  # the red axle
_MASS = (95, 95, 105)  # steel balance masses
_STEM = (150, 150, 150)
_FLAG_BACK = (205, 205, 200)
_INK, _PAPER = 14, 242  # printed marker black and white (grey levels)
_AMBIENT = 0.38
_SUPERSAMPLE = 4  # marker warps
_SHIFT = 4  # fixed-point bits for cv2.fillConvexPoly
_NEAR = 1e-3  # m: faces closer than this to the camera plane are not drawn


def light_direction() -> np.ndarray:
    """Unit vector towards the light, ramp frame."""
    return _LIGHT / np.linalg.norm(_LIGHT)


@dataclasses.dataclass(frozen=True)
class WalkerState:
    """The walker's placement at one instant, ramp frame.

    Attributes
    ----------
    rotation : dict {'L', 'R'} -> ndarray (3, 3)
        Leg body axes as columns.
    hip : dict {'L', 'R'} -> ndarray (3,)
        Hip points (m).
    """

    rotation: dict
    hip: dict


# --- camera placement -----------------------------------------------------------------------------

def look_at(position, target, up) -> tuple[np.ndarray, np.ndarray]:
    """(rvec, tvec) ramp-to-camera of an OpenCV camera at ``position`` looking at ``target``."""
    fwd = np.asarray(target, float) - np.asarray(position, float)
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    rot = np.vstack([right, down, fwd])  # rows: camera axes in ramp coordinates
    return cv2.Rodrigues(rot)[0].ravel(), -rot @ np.asarray(position, float)


def _walk_box(params, walk=None) -> np.ndarray:
    """Corners, shape (8, 3), of the region the default camera must see: the walking corridor from
    behind the start to about three leg lengths down the ramp (several strides), up to the hips.
    With ``walk`` (mid-hip points, shape (k, 3), ramp frame, m) it grows where the walker leaves
    it: to 0.4 l ahead of the hips (the leading foot and the flags), 0.15 l behind them (the camera
    stands ahead: the corridor's own 0.4 l behind the start is for the trailing foot) and
    0.3 l + w/2 either side (the legs and their flags), so that a walk of a few strides keeps the
    corridor as it is."""
    ell, w = float(params.leg_length), float(params.hip_width)
    y_mid = -0.5 * w
    half = 0.8 * ell + 0.5 * w
    xs, ys, zs = (-0.4 * ell, 2.2 * ell), (y_mid - half, y_mid + half), (0.0, 1.0 * ell)
    if walk is not None:
        walk = np.asarray(walk, float).reshape(-1, 3)
        side = 0.3 * ell + 0.5 * w
        xs = (min(xs[0], walk[:, 0].min() - 0.15 * ell), max(xs[1], walk[:, 0].max() + 0.4 * ell))
        ys = (min(ys[0], walk[:, 1].min() - side), max(ys[1], walk[:, 1].max() + side))
    return np.array([[x, y, z] for x in xs for y in ys for z in zs])


def default_camera_for(params, width: int = 1280, height: int = 720, horizontal_fov_deg: float = 50.0,
                       distortion=(-0.08, 0.03, 0.0, 0.0, 0.0), camera_side: str = "right",
                       walk=None) -> Camera:
    """A fixed camera filming the walker come down the ramp, scaled from its leg length.

    The camera stands ahead (downhill) of the walker and to one side, 35 degrees off the walking
    line, 25 degrees above the ramp, upright with respect to gravity, at the distance that fits the
    walking corridor of :func:`_walk_box` (several strides; with ``walk``, hip points (k, 3) in the
    ramp frame (m), the whole walk) in the frame. From there it sees the legs' pitch (side-on
    component), lean (head-on component) and the forward-facing marker flags of
    :func:`toywalk.tracking.markers.default_layout`. The lens has mild barrel distortion, as a
    webcam's would.
    """
    if camera_side not in ("right", "left"):
        raise ValueError(f"camera_side must be 'right' or 'left', got {camera_side!r}")
    box = _walk_box(params, walk)
    target = box.mean(axis=0)
    az, el = math.radians(35.0), math.radians(25.0)
    sgn = -1.0 if camera_side == "right" else 1.0
    direction = np.array([math.cos(el) * math.cos(az), sgn * math.cos(el) * math.sin(az), math.sin(el)])
    alpha = float(params.slope)
    up = np.array([-math.sin(alpha), 0.0, math.cos(alpha)])  # against gravity, ramp frame
    base = default_camera(width, height, horizontal_fov_deg, distortion)
    k = base.matrix
    margin = 0.04 * width

    def fits(dist):
        rvec, tvec = look_at(target + dist * direction, target, up)
        cam = (pose_matrix(rvec, tvec)[:3, :3] @ box.T).T + tvec
        if np.any(cam[:, 2] <= 0):
            return False
        u = k[0, 0] * cam[:, 0] / cam[:, 2] + k[0, 2]
        v = k[1, 1] * cam[:, 1] / cam[:, 2] + k[1, 2]
        return (u.min() >= margin and u.max() <= width - 1 - margin and v.min() >= margin
                and v.max() <= height - 1 - margin)

    lo, hi = 0.5 * params.leg_length, 50.0 * params.leg_length
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    rvec, tvec = look_at(target + hi * direction, target, up)
    return Camera(width=width, height=height, matrix=k, distortion=base.distortion,
                  ramp_pose=(np.round(rvec, 9), np.round(tvec, 9)))


@dataclasses.dataclass(frozen=True)
class CameraPath:
    """A camera that moves without turning: the ramp-to-camera pose over time.

    Attributes
    ----------
    rvec, tvec : ndarray, shape (3,)
        The pose with the camera where it starts (rad, m).
    times : ndarray, shape (k,)
        Increasing times (s).
    offsets : ndarray, shape (k, 3)
        The camera centre's displacement from its start at those times (ramp frame, m),
        interpolated linearly between them and held beyond them.
    """

    rvec: np.ndarray
    tvec: np.ndarray
    times: np.ndarray
    offsets: np.ndarray

    def __post_init__(self) -> None:
        times = np.asarray(self.times, float).reshape(-1)
        offsets = np.asarray(self.offsets, float).reshape(-1, 3)
        if len(times) < 1 or len(offsets) != len(times) or np.any(np.diff(times) <= 0) \
                or not (np.all(np.isfinite(times)) and np.all(np.isfinite(offsets))):
            raise ValueError(f"a camera path needs increasing finite times and one finite offset (3,) "
                             f"each, got {len(times)} times and {len(offsets)} offsets")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "rvec", np.asarray(self.rvec, float).reshape(3))
        object.__setattr__(self, "tvec", np.asarray(self.tvec, float).reshape(3))

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(rvec, tvec) of the ramp in the camera frame at time ``t`` (s)."""
        offset = np.array([np.interp(t, self.times, self.offsets[:, j]) for j in range(3)])
        rot = pose_matrix(self.rvec, self.tvec)[:3, :3]
        return self.rvec.copy(), self.tvec - rot @ offset


def follow_walk(camera: Camera, params, times, hips) -> CameraPath:
    """``camera`` (placed by :func:`default_camera_for` for the default corridor) following a walk
    down the ramp, as a camera carried alongside would: it stands still until the walker's hips
    pass the corridor's centre, then moves along the ramp's x axis, without turning, keeping them
    there. The displacement is the hips' own smoothed by a Gaussian of 2 sqrt(l/g) (about a step),
    so that the camera does not sway with each step.

    Parameters
    ----------
    times : array_like, shape (k,)
        Evenly spaced times (s).
    hips : array_like, shape (k, 3)
        The walker's mid-hip point at those times (ramp frame, m).
    """
    from scipy.ndimage import gaussian_filter1d

    times = np.asarray(times, float).reshape(-1)
    hips = np.asarray(hips, float).reshape(-1, 3)
    if camera.ramp_pose is None:
        raise ValueError("the camera to move must have a ramp_pose (where it starts)")
    if len(times) != len(hips) or len(times) < 2 or not np.allclose(np.diff(times), times[1] - times[0]):
        raise ValueError("follow_walk needs evenly spaced times and one hip point (3,) for each")
    hold = float(_walk_box(params).mean(axis=0)[0])
    ahead = np.maximum(hips[:, 0] - hold, 0.0)
    sigma = 2.0 * math.sqrt(float(params.leg_length) / float(params.gravity)) / (times[1] - times[0])
    offsets = np.zeros((len(times), 3))
    offsets[:, 0] = gaussian_filter1d(ahead, sigma, mode="nearest")
    return CameraPath(*camera.ramp_pose, times, offsets)


#: The default camera frames a whole walk from one place (:func:`default_camera_for` with the walk)
#: while it stands at most this many times as far away as the camera framing the default corridor
#: (its markers keep 80 % of their size or more, as at 25-30 px wide for the bundled layouts at
#: 1280x720, where the tracker meets its targets); beyond that it follows the walker.
FOLLOW_BEYOND = 1.25


def default_view(params, times, hips, width: int = 1280,
                 height: int = 720) -> tuple[Camera, CameraPath | None]:
    """The camera filming a walk by default: (camera, None), one fixed camera framing the whole
    walk, or, for a walk too long for that (:data:`FOLLOW_BEYOND`), (camera, path), the camera
    framing the default corridor and following the walker (:func:`follow_walk`). ``times`` and
    ``hips`` as for :func:`follow_walk`."""
    def distance(camera, box):  # from the camera's centre to the box's (m)
        rot = pose_matrix(*camera.ramp_pose)[:3, :3]
        return float(np.linalg.norm(-rot.T @ camera.ramp_pose[1] - box.mean(axis=0)))

    near = default_camera_for(params, width, height)
    whole = default_camera_for(params, width, height, walk=hips)
    if distance(whole, _walk_box(params, hips)) <= FOLLOW_BEYOND * distance(near, _walk_box(params)):
        return whole, None
    return near, follow_walk(near, params, times, hips)


# --- meshes ---------------------------------------------------------------------------------------

class _MeshBuilder:
    """Faces as quads (triangles repeat a vertex), flat normals, colours, culling flags."""

    def __init__(self):
        self.quads, self.normals, self.colours, self.closed = [], [], [], []

    def add(self, quads, normals, colour, closed=True):
        quads = np.asarray(quads, float).reshape(-1, 4, 3)
        self.quads.append(quads)
        self.normals.append(np.asarray(normals, float).reshape(-1, 3))
        self.colours.append(np.tile(np.asarray(colour, float), (len(quads), 1)))
        self.closed.append(np.full(len(quads), closed))

    def build(self):
        if not self.quads:
            return (np.zeros((0, 4, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool))
        return (np.concatenate(self.quads), np.concatenate(self.normals), np.concatenate(self.colours),
                np.concatenate(self.closed))

    def cylinder(self, p0, p1, radius, colour, sides=10, segments=1, caps=True):
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        axis = p1 - p0
        length = np.linalg.norm(axis)
        if length <= 0 or radius <= 0:
            return
        a = axis / length
        e1 = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(a, e1)
        ang = np.linspace(0, 2 * np.pi, sides + 1)
        ring = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2  # (sides+1, 3)
        ts = np.linspace(0, 1, segments + 1)
        quads, normals = [], []
        for j in range(segments):
            c0, c1 = p0 + ts[j] * axis, p0 + ts[j + 1] * axis
            for i in range(sides):
                quads.append([c0 + radius * ring[i], c0 + radius * ring[i + 1],
                              c1 + radius * ring[i + 1], c1 + radius * ring[i]])
                mid = 0.5 * (ring[i] + ring[i + 1])
                normals.append(mid / np.linalg.norm(mid))
        self.add(quads, normals, colour)
        if caps:
            for c, n in ((p0, -a), (p1, a)):
                pts = c + radius * ring[:-1]
                # a cap as a fan of quads (c, p_i, p_i+1, p_i+1): convex pieces
                fan = [[c, pts[i], pts[(i + 1) % sides], pts[(i + 1) % sides]] for i in range(sides)]
                self.add(fan, np.tile(n, (sides, 1)), colour)

    def sphere(self, centre, radius, colour, n_u=14, n_v=8):
        centre = np.asarray(centre, float)
        us = np.linspace(0, 2 * np.pi, n_u + 1)
        vs = np.linspace(-np.pi / 2, np.pi / 2, n_v + 1)

        def point(u, v):
            return np.array([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)])

        quads, normals = [], []
        for j in range(n_v):
            for i in range(n_u):
                q = [point(us[i], vs[j]), point(us[i + 1], vs[j]), point(us[i + 1], vs[j + 1]),
                     point(us[i], vs[j + 1])]
                n = point(0.5 * (us[i] + us[i + 1]), 0.5 * (vs[j] + vs[j + 1]))
                quads.append([centre + radius * p for p in q])
                normals.append(n)
        self.add(quads, normals, colour)

    def torus(self, centre, axis, major, tube, colour, n_u=28, n_v=8):
        """Tube of radius ``tube`` around the circle of radius ``major`` about ``axis``."""
        centre, axis = np.asarray(centre, float), np.asarray(axis, float) / np.linalg.norm(axis)
        e1 = np.cross(axis, [1.0, 0, 0] if abs(axis[0]) < 0.9 else [0, 1.0, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        us = np.linspace(0, 2 * np.pi, n_u + 1)
        vs = np.linspace(0, 2 * np.pi, n_v + 1)

        def normal(u, v):
            radial = np.cos(u) * e1 + np.sin(u) * e2
            return np.cos(v) * radial + np.sin(v) * axis

        def point(u, v):
            radial = np.cos(u) * e1 + np.sin(u) * e2
            return centre + major * radial + tube * normal(u, v)

        quads, normals = [], []
        for j in range(n_v):
            for i in range(n_u):
                quads.append([point(us[i], vs[j]), point(us[i + 1], vs[j]), point(us[i + 1], vs[j + 1]),
                              point(us[i], vs[j + 1])])
                normals.append(normal(0.5 * (us[i] + us[i + 1]), 0.5 * (vs[j] + vs[j + 1])))
        self.add(quads, normals, colour)


def _leg_mesh(params, leg: str, markers: tuple[Marker, ...]):
    """Faces of one leg in its body frame (and, for the left leg, the axle)."""
    ell, r, rho, w = (float(params.leg_length), float(params.foot_radius),
                      float(params.foot_lateral_radius), float(params.hip_width))
    dx, dy, dz = (float(v) for v in params.com_offset)
    outboard = 1.0 if leg == "L" else -1.0
    rod = 0.025 * ell
    b = _MeshBuilder()
    foot = np.array([0.0, 0.0, -(ell - r)])
    b.cylinder([0, 0, 2.5 * rod], foot, rod, _ROD[leg], sides=10, segments=8)
    # the hub at the hip (a Tinkertoy spool on the axle)
    b.cylinder([0, -1.6 * rod, 0], [0, 1.6 * rod, 0], 2.2 * rod, _SPOOL, sides=12)
    major = r - rho
    if r <= 0:
        b.sphere(foot, 1.2 * rod, _BRASS)
    elif major < 0.5 * rho:  # (nearly) a sphere
        b.sphere(foot + [0, 0, 0], rho if major <= 0 else r, _SPOOL, n_u=18, n_v=10)
    else:  # a spool: a wooden web with a brass rim
        b.torus(foot, [0, 1.0, 0], major, rho, _BRASS, n_u=32, n_v=8)
        half = 0.8 * rho
        b.cylinder(foot + [0, -half, 0], foot + [0, half, 0], major, _SPOOL, sides=24)
    # balance mass on an arm, centred at the leg's centre of mass offset
    mass_r = 0.07 * ell
    mass_c = np.array([dx, outboard * dy, dz])
    if abs(dy) > mass_r or abs(dx) > mass_r:
        b.cylinder([0, 0, dz], mass_c, 0.7 * rod, _STEM, sides=8)
    b.sphere(mass_c, mass_r, _MASS)
    if leg == "L":  # the axle through both hips; the right hip is w to the right (-b2)
        over = 3.0 * rod
        b.cylinder([0, over, 0], [0, -(w + over), 0], 0.8 * rod, _AXLE, sides=10, segments=2)
    return b.build()


def _stem_mesh(params, marker: Marker):
    """The stem holding a flag: from the leg axis to just behind the flag's centre (body frame)."""
    rod = 0.025 * float(params.leg_length)
    pose = marker_pose_matrix(marker)
    end = pose[:3, 3] - 0.5 * rod * pose[:3, 2]
    root = np.array([0.0, 0.0, end[2]])
    b = _MeshBuilder()
    if np.linalg.norm(end - root) > rod:
        b.cylinder(root, end, 0.45 * rod, _STEM, sides=6, caps=False)
    return b.build()


# --- marker textures ------------------------------------------------------------------------------

class _MarkerTexture:
    """A printed marker with its white margin at several resolutions (a small mip chain)."""

    def __init__(self, dictionary, marker: Marker):
        cells = dictionary.markerSize + 2
        self.levels = []
        for px in (2, 4, 8, 16, 32, 64):
            side = cells * px
            margin_px = int(round(marker.margin / marker.side * side))
            img = cv2.aruco.generateImageMarker(dictionary, marker.id, side)
            img = np.where(img > 127, _PAPER, _INK).astype(np.uint8)
            img = cv2.copyMakeBorder(img, margin_px, margin_px, margin_px, margin_px, cv2.BORDER_CONSTANT,
                                     value=_PAPER)
            self.levels.append(img)
        # margin actually printed (m), so that the black square's corners are exact
        self.margin = margin_px / side * marker.side
        self.ones = [np.full(img.shape, 255, np.uint8) for img in self.levels]

    def level(self, size_px: float) -> int:
        for k, img in enumerate(self.levels):
            if img.shape[0] >= size_px:
                return k
        return len(self.levels) - 1


# --- the scene ------------------------------------------------------------------------------------

class Scene:
    """Static parts drawn once (background, ramp, ramp markers), the walker drawn per instant.

    Parameters
    ----------
    params : Params
    layout : MarkerLayout
    camera : Camera
        Must have a ``ramp_pose``.
    shadows : bool
        Draw the walker's (soft) shadow on the ramp.
    """

    def __init__(self, params, layout: MarkerLayout, camera: Camera, shadows: bool = True):
        if camera.ramp_pose is None:
            raise ValueError("the renderer needs a camera with a fixed ramp_pose")
        self.params, self.layout, self.camera, self.shadows = params, layout, camera, shadows
        self.light = light_direction()
        rv, tv = camera.ramp_pose
        pose = pose_matrix(rv, tv)
        self.r_cam, self.t_cam = pose[:3, :3], pose[:3, 3]
        self._setup_canvas()
        dictionary = layout.aruco_dictionary()
        self.meshes = {}
        self.flags = {}
        for leg, body in (("L", "left_leg"), ("R", "right_leg")):
            markers = layout.on(body)
            self.meshes[leg] = _leg_mesh(params, leg, markers)
            flags = []
            for m in markers:
                tex = _MarkerTexture(dictionary, m)
                flags.append((m, tex, marker_corners(m, tex.margin),
                              marker_pose_matrix(m)[:3, 2], _stem_mesh(params, m)))
            self.flags[leg] = flags
        # every vertex of each leg's mesh and flags, leg frame (for how far the image moves)
        self._vertices = {leg: np.concatenate([self.meshes[leg][0].reshape(-1, 3)]
                                              + [corners for _m, _t, corners, _n, _s in self.flags[leg]])
                          for leg in ("L", "R")}
        self._dictionary = dictionary
        self.background = self._draw_static(dictionary)
        self._home = (self.r_cam, self.t_cam, self.background)  # the pose it was drawn for
        self._reference = None  # static layers for a moved camera (see set_pose)
        self._buffers = None  # and the arrays it is drawn in
        self._stale = False

    # a moving camera
    def set_pose(self, rvec, tvec) -> None:
        """Move the camera (same lens) to the ramp-to-camera pose (rvec, tvec) for what follows.

        The walker is drawn from there. The static scene is the ramp (a plane) in front of a
        backdrop fixed to the image, so its image from any pose is the image of the ramp from a
        reference pose warped by the homography between the two (exact for the pinhole canvas;
        the lens distortion comes after, in :meth:`finish`), resampled bilinearly. The reference is
        ray cast on a canvas grown by a quarter of its size on every side, and again from the
        current pose whenever the view leaves it.
        """
        pose = pose_matrix(rvec, tvec)
        rot, t = pose[:3, :3], pose[:3, 3]
        if np.array_equal(rot, self.r_cam) and np.array_equal(t, self.t_cam):
            return
        self.r_cam, self.t_cam = rot, t
        self._stale = True

    def _static(self) -> np.ndarray:
        """The static scene's canvas image (uint8) from the current pose."""
        if self._stale:
            home_r, home_t, home = self._home
            if np.array_equal(self.r_cam, home_r) and np.array_equal(self.t_cam, home_t):
                self.background = home
            else:
                self.background = self._moved_static()
            self._stale = False
        return self.background

    def _moved_static(self) -> np.ndarray:
        wc, hc = self.canvas_size
        if self._reference is None or not self._covered(self._reference[3]):
            pad = int(round(0.25 * max(wc, hc)))
            img, on_ramp = self._static_layers(self._dictionary, pad)
            size = (wc + 2 * pad, hc + 2 * pad)
            # premultiplied ramp layer and its coverage (INTER_AREA averages 2x2 blocks: linear)
            ramp = cv2.resize(np.where(on_ramp[..., None], img, np.float32(0)), size,
                              interpolation=cv2.INTER_AREA)
            cover = cv2.resize(on_ramp.astype(np.float32), size, interpolation=cv2.INTER_AREA)
            sky = cv2.resize(_gradient(2 * hc, 2 * wc), (wc, hc), interpolation=cv2.INTER_AREA)
            k = self.k_canvas.copy()
            k[0, 2] += pad
            k[1, 2] += pad
            self._reference = (ramp, cover, sky, _plane_homography(k, self.r_cam, self.t_cam))
        ramp, cover, sky, h_ref = self._reference
        warp = _plane_homography(self.k_canvas, self.r_cam, self.t_cam) @ np.linalg.inv(h_ref)
        # ramp + sky (1 - cover), rounded, into arrays kept from call to call, with OpenCV's
        # arithmetic: a moving camera asks for this at every instant drawn, and NumPy's, broadcasting
        # the cover over the colours into new arrays, took 2.4 times as long (10.8 against 4.5 ms
        # at 1330 x 760, one thread; the same image to the bit)
        if self._buffers is None:
            self._buffers = (np.empty((hc, wc, 3), np.float32), np.empty((hc, wc), np.float32),
                             np.empty((hc, wc, 3), np.float32), np.empty((hc, wc, 3), np.uint8))
        warped, uncovered, out, image = self._buffers
        cv2.warpPerspective(ramp, warp, (wc, hc), dst=warped, flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        cv2.warpPerspective(cover, warp, (wc, hc), dst=uncovered, flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        np.subtract(1, uncovered, out=uncovered)
        cv2.merge([uncovered] * 3, dst=out)
        cv2.multiply(sky, out, dst=out)
        cv2.add(out, warped, dst=out)
        out += 0.5
        np.clip(out, 0, 255, out=out)
        np.copyto(image, out, casting="unsafe")  # truncated: rounded, with the 0.5 above
        return image

    def _covered(self, h_ref: np.ndarray) -> bool:
        """Whether every corner of the canvas sees the ramp plane in front of the camera at a
        point inside the reference canvas of ``h_ref`` (then the whole canvas does: a homography
        maps the canvas to a convex quadrilateral)."""
        wc, hc = self.canvas_size
        corners = np.array([[0, 0, 1], [wc - 1, 0, 1], [wc - 1, hc - 1, 1], [0, hc - 1, 1]], float).T
        plane = np.linalg.solve(_plane_homography(self.k_canvas, self.r_cam, self.t_cam), corners)
        if np.any(np.abs(plane[2]) < 1e-12):
            return False
        xy = plane[:2] / plane[2]
        depth = self.r_cam[2, :2] @ xy + self.t_cam[2]
        ref = h_ref @ np.vstack([xy, np.ones(4)])
        rows, cols = self._reference[0].shape[:2]
        u, v = ref[0] / ref[2], ref[1] / ref[2]
        return bool(np.all(depth > 0) and np.all(ref[2] > 0) and np.all((u >= 0) & (u <= cols - 1))
                    and np.all((v >= 0) & (v <= rows - 1)))

    # canvas: an undistorted pinhole image covering the distorted one
    def _setup_canvas(self):
        cam = self.camera
        w, h = cam.width, cam.height
        self.distorted = bool(np.any(cam.distortion != 0))
        if not self.distorted:
            self.k_canvas, self.canvas_size, self.maps = cam.matrix.copy(), (w, h), None
            return
        vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
        pix = np.column_stack([uu.ravel(), vv.ravel()])
        xy = undistort_pixels(cam, pix)
        k = cam.matrix
        u_id = k[0, 0] * xy[:, 0] + k[0, 1] * xy[:, 1] + k[0, 2]
        v_id = k[1, 1] * xy[:, 1] + k[1, 2]
        pad = 3.0
        u0 = max(np.floor(u_id.min() - pad), -w)
        v0 = max(np.floor(v_id.min() - pad), -h)
        u1 = min(np.ceil(u_id.max() + pad), 2 * w)
        v1 = min(np.ceil(v_id.max() + pad), 2 * h)
        self.k_canvas = k.copy()
        self.k_canvas[0, 2] -= u0
        self.k_canvas[1, 2] -= v0
        self.canvas_size = (int(u1 - u0) + 1, int(v1 - v0) + 1)
        self.maps = ((u_id - u0).reshape(h, w).astype(np.float32),
                     (v_id - v0).reshape(h, w).astype(np.float32))

    def finish(self, canvas: np.ndarray) -> np.ndarray:
        """The camera's image (height, width, 3) from a canvas: apply the lens distortion."""
        if self.maps is None:
            return canvas
        return cv2.remap(canvas, self.maps[0], self.maps[1], cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)

    def _shade(self, normals_ramp: np.ndarray) -> np.ndarray:
        lam = normals_ramp @ self.light
        return _AMBIENT + (1 - _AMBIENT) * np.clip(lam, 0, None)

    # static: background and ramp, ray cast at 2x supersampling
    def _draw_static(self, dictionary) -> np.ndarray:
        """The canvas image (uint8) of the static scene from the current pose."""
        img, _ = self._static_layers(dictionary)
        small = cv2.resize(img, self.canvas_size, interpolation=cv2.INTER_AREA)
        return np.clip(small + 0.5, 0, 255).astype(np.uint8)

    def _static_layers(self, dictionary, pad: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The static scene ray cast at 2x supersampling on the canvas grown by ``pad`` pixels on
        every side: (image, float32 (rows, cols, 3); whether each sample hits the ramp, bool)."""
        ss = 2
        wc, hc = self.canvas_size
        wc, hc = wc + 2 * pad, hc + 2 * pad
        k = self.k_canvas.copy()
        k[0, 2] += pad
        k[1, 2] += pad
        uu = np.arange(wc * ss, dtype=np.float32)[None, :]
        vv = np.arange(hc * ss, dtype=np.float32)[:, None]
        y = ((vv + 0.5) / ss - 0.5 - np.float32(k[1, 2])) / np.float32(k[1, 1])
        x = ((uu + 0.5) / ss - 0.5 - np.float32(k[0, 2]) - np.float32(k[0, 1]) * y) / np.float32(k[0, 0])
        # rays in the ramp frame: d = R^T (x, y, 1); camera centre c = -R^T t
        rt = self.r_cam.T.astype(np.float32)
        c = (-self.r_cam.T @ self.t_cam).astype(np.float32)
        dx = rt[0, 0] * x + rt[0, 1] * y + rt[0, 2]
        dy = rt[1, 0] * x + rt[1, 1] * y + rt[1, 2]
        dz = rt[2, 0] * x + rt[2, 1] * y + rt[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -c[2] / dz
        hit = s > 0
        px, py = s * dx, s * dy  # in place from here: these arrays are large (10-20 million samples)
        del dx, dy, dz
        px += c[0]
        py += c[1]
        px[~hit] = np.nan
        py[~hit] = np.nan
        bg = _gradient(hc * ss, wc * ss)
        # ramp extent and wood texture
        ell, w = float(self.params.leg_length), float(self.params.hip_width)
        y_mid = -0.5 * w
        half = 1.25 * ell + 0.5 * w
        xr = (-1.8 * ell, 4.6 * ell)
        yr = (y_mid - half, y_mid + half)
        for m in self.layout.on("ramp"):  # the ramp is large enough to hold its markers
            pts = marker_corners(m, m.margin)
            xr = (min(xr[0], pts[:, 0].min() - 0.1 * ell), max(xr[1], pts[:, 0].max() + 0.1 * ell))
            yr = (min(yr[0], pts[:, 1].min() - 0.1 * ell), max(yr[1], pts[:, 1].max() + 0.1 * ell))
        # and runs on 2.3 leg lengths past its last marker, as far as the default layout's (a camera
        # following the walker down a long ramp sees that far ahead)
        ramp_x = [m.tvec[0] for m in self.layout.on("ramp")]
        if ramp_x and max(ramp_x) + 2.3 * ell > xr[1] + 1e-6 * ell:
            xr = (xr[0], max(ramp_x) + 2.3 * ell)
        tex, ppm = _wood_texture(tuple(map(float, xr)), tuple(map(float, yr)), ell)
        tu = (px - xr[0]) * ppm - 0.5
        tv = (yr[1] - py) * ppm - 0.5
        on_ramp = hit & (px >= xr[0]) & (px <= xr[1]) & (py >= yr[0]) & (py <= yr[1])
        # samples off the ramp read one texel: the plane runs to the horizon, and reflecting its far
        # coordinates into the texture made the remap read all over it (3x slower); their values
        # are not used
        wood = cv2.remap(tex, np.where(on_ramp, tu, np.float32(-10)), np.where(on_ramp, tv, np.float32(-10)),
                         cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT).astype(np.float32)
        shade = float(self._shade(np.array([0.0, 0.0, 1.0])))
        wood *= shade
        img = cv2.copyTo(wood, on_ramp.view(np.uint8), bg)  # into bg, on the ramp
        hs, ws = img.shape[:2]
        for m in self.layout.on("ramp"):
            tex_m = _MarkerTexture(dictionary, m)
            src = tex_m.levels[-1]
            n = src.shape[0]
            half_m = m.side / 2 + tex_m.margin
            corners = marker_corners(m, tex_m.margin) @ self.r_cam.T + self.t_cam
            if np.any(corners[:, 2] <= _NEAR):
                continue  # (partly) behind the camera: not drawn
            uv = (self._to_pixels(corners, k) + 0.5) * ss - 0.5
            c0, r0 = np.maximum(np.floor(uv.min(axis=0)).astype(int) - 2, 0)
            c1, r1 = np.minimum(np.ceil(uv.max(axis=0)).astype(int) + 3, [ws, hs])
            if c1 <= c0 or r1 <= r0:
                continue
            win = (slice(r0, r1), slice(c0, c1))
            pose = marker_pose_matrix(m)
            rel_x, rel_y = px[win] - pose[0, 3], py[win] - pose[1, 3]
            a = pose[0, 0] * rel_x + pose[1, 0] * rel_y  # marker-frame coordinates (flat on the ramp)
            b = pose[0, 1] * rel_x + pose[1, 1] * rel_y
            mu = np.nan_to_num(((a + half_m) / (2 * half_m) * n - 0.5).astype(np.float32), nan=-10)
            mv = np.nan_to_num(((half_m - b) / (2 * half_m) * n - 0.5).astype(np.float32), nan=-10)
            val = cv2.remap(src, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            cover = cv2.remap(np.full_like(src, 255), mu, mv, cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0).astype(np.float32) / 255
            cover = (cover * on_ramp[win])[..., None]
            img[win] = img[win] * (1 - cover) + (val.astype(np.float32) * shade)[..., None] * cover
        return img, on_ramp

    # per instant
    def body_poses(self, state: WalkerState) -> dict:
        """Body -> camera (rotation (3, 3), translation (3,)) for 'L', 'R' and the ramp."""
        out = {"ramp": (self.r_cam, self.t_cam)}
        for leg in ("L", "R"):
            out[leg] = (self.r_cam @ state.rotation[leg], self.r_cam @ state.hip[leg] + self.t_cam)
        return out

    def walker_pixels(self, state: WalkerState) -> np.ndarray:
        """Canvas pixels (m, 2) of every vertex of the legs' meshes and flags at ``state``, the same
        vertices in the same order at every instant; NaN for those behind the camera."""
        return self.ramp_pixels(self.walker_points(state))

    def ramp_pixels(self, points) -> np.ndarray:
        """Canvas pixels (m, 2) of ramp-frame points (m, 3) (m); NaN for those behind the camera."""
        pc = np.asarray(points, float).reshape(-1, 3) @ self.r_cam.T + self.t_cam
        uv = self._to_pixels(pc)
        uv[pc[:, 2] <= _NEAR] = np.nan
        return uv

    def walker_points(self, state: WalkerState) -> np.ndarray:
        """Ramp-frame positions (m, 3) of the vertices of :meth:`walker_pixels` at ``state``."""
        return np.concatenate([self._vertices[leg] @ state.rotation[leg].T + state.hip[leg]
                               for leg in ("L", "R")])

    def draw(self, state: WalkerState, out: np.ndarray | None = None) -> np.ndarray:
        """The ideal (undistorted) canvas image of the walker at ``state``, uint8 (hc, wc, 3)."""
        img = self._static().copy() if out is None else out
        poses = self.body_poses(state)
        if self.shadows:
            self._draw_shadow(img, poses, state)
        # painted far to near: the legs' faces, then each flag with its stem, in one stable order
        polys, colours, depths = [], [], []
        for leg in ("L", "R"):
            rot, t = poses[leg]
            pts, cols, depth = self._faces(self.meshes[leg], rot, t, state.rotation[leg])
            polys.extend(pts)
            colours.extend(cols)
            depths.append(depth)
        n_faces = len(polys)
        flags = []
        for leg in ("L", "R"):
            rot, t = poses[leg]
            rot_r = state.rotation[leg]
            for _m, tex, corners, normal, stem in self.flags[leg]:
                pc = corners @ rot.T + t
                if pc[:, 2].min() <= _NEAR:
                    continue
                front = (rot @ normal) @ pc.mean(axis=0) < 0
                lam = abs(float((rot_r @ normal) @ self.light))
                shade_f = _AMBIENT + (1 - _AMBIENT) * lam
                flags.append((self._to_pixels(pc[None])[0], tex, front, shade_f,
                              self._faces(stem, rot, t, rot_r)))
                depths.append([pc[:, 2].mean()])
        order = np.argsort(-np.concatenate(depths), kind="stable")
        for i in order.tolist():
            if i < n_faces:
                cv2.fillConvexPoly(img, polys[i], colours[i], cv2.LINE_AA, _SHIFT)
                continue
            uvq, tex, front, shade_f, (stem_pts, stem_cols, stem_depth) = flags[i - n_faces]
            if not front:  # the flag's back, then the stem in front of it
                _fill(img, uvq, [c * shade_f for c in _FLAG_BACK])
            for j in np.argsort(-stem_depth).tolist():
                cv2.fillConvexPoly(img, stem_pts[j], stem_cols[j], cv2.LINE_AA, _SHIFT)
            if front:  # the stem behind, then the printed face
                _warp_flag(img, uvq, tex, shade_f)
        return img

    def _faces(self, mesh, rot, t, rot_r):
        """Visible faces of a body-frame mesh: (fixed-point pixels for :func:`_fill`, a list of f
        int32 arrays (4, 2); colours, a list of f BGR lists; depths (f,))."""
        quads, normals, colours, closed = mesh
        q = quads.reshape(-1, 3) @ rot.T + t
        q = q.reshape(-1, 4, 3)
        n = normals @ rot.T
        n_ramp = normals @ rot_r.T
        centroid = q.mean(axis=1)
        facing = np.einsum("ij,ij->i", n, centroid) < 0
        keep = (q[:, :, 2].min(axis=1) > _NEAR) & (facing | ~closed)
        shade = self._shade(np.where((facing | closed)[:, None], n_ramp, -n_ramp))
        pts = np.round(self._to_pixels(q[keep]) * (1 << _SHIFT)).astype(np.int32)
        return list(pts), (colours[keep] * shade[keep, None]).tolist(), centroid[keep, 2]

    def _to_pixels(self, pts_cam: np.ndarray, k=None) -> np.ndarray:
        k = self.k_canvas if k is None else k
        z = pts_cam[..., 2]
        u = k[0, 0] * pts_cam[..., 0] / z + k[0, 1] * pts_cam[..., 1] / z + k[0, 2]
        v = k[1, 1] * pts_cam[..., 1] / z + k[1, 2]
        return np.stack([u, v], axis=-1)

    def _draw_shadow(self, img: np.ndarray, poses: dict, state: WalkerState) -> None:
        """Darken the ramp under the walker: faces facing the light, projected along it onto z = 0."""
        pts = []
        for leg in ("L", "R"):
            quads, normals, _, _ = self.meshes[leg]
            lit = normals @ (state.rotation[leg].T @ self.light) > 0
            pts.append(quads[lit].reshape(-1, 3) @ state.rotation[leg].T + state.hip[leg])
        pts = np.concatenate(pts)
        lgt = self.light
        s = pts[:, 2] / lgt[2]
        flat = pts - s[:, None] * lgt
        flat[:, 2] = 0.0
        cam = flat @ self.r_cam.T + self.t_cam
        if np.any(cam[:, 2] <= _NEAR):
            return
        uv = self._to_pixels(cam).reshape(-1, 4, 2)
        hc, wc = img.shape[:2]
        lo = np.floor(uv.reshape(-1, 2).min(axis=0)).astype(int) - 8
        hi = np.ceil(uv.reshape(-1, 2).max(axis=0)).astype(int) + 8
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, [wc - 1, hc - 1])
        if np.any(hi <= lo):
            return
        mask = np.zeros((hi[1] - lo[1] + 1, hi[0] - lo[0] + 1), np.uint8)
        pts_i = np.round((uv - lo) * (1 << _SHIFT)).astype(np.int32)
        for poly in pts_i:
            cv2.fillConvexPoly(mask, poly, 255, cv2.LINE_8, _SHIFT)
        blur = max(3, int(0.01 * self.camera.width) | 1)
        mask = cv2.GaussianBlur(mask, (blur, blur), 0)
        roi = img[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
        factor = 1.0 - 0.45 * mask.astype(np.float32) / 255
        roi[:] = np.clip(roi * factor[..., None] + 0.5, 0, 255).astype(np.uint8)


def _gradient(rows: int, cols: int) -> np.ndarray:
    """The backdrop behind the ramp: a vertical grey-blue gradient, float32 (rows, cols, 3)."""
    grad = np.linspace(0, 1, rows, dtype=np.float32)
    column = np.empty((rows, 1, 3), np.float32)
    for ch, (top, bottom) in enumerate(((190, 120), (180, 110), (170, 100))):
        column[:, 0, ch] = top + (bottom - top) * grad
    return np.repeat(column, cols, axis=1)


def _plane_homography(k: np.ndarray, rot: np.ndarray, t: np.ndarray) -> np.ndarray:
    """3x3 map from ramp-plane points (x, y, 1) (z = 0, m) to homogeneous pixels of a pinhole
    canvas with intrinsics ``k``, the ramp at pose (rot, t) in the camera frame."""
    return k @ np.column_stack([rot[:, 0], rot[:, 1], t])


def _fill(img: np.ndarray, uv: np.ndarray, colour) -> None:
    pts = np.round(uv * (1 << _SHIFT)).astype(np.int32)
    cv2.fillConvexPoly(img, pts, [float(c) for c in colour], cv2.LINE_AA, _SHIFT)


def _warp_flag(img: np.ndarray, uv: np.ndarray, tex: _MarkerTexture, shade: float) -> None:
    """Composite a marker flag (texture with coverage) onto ``img`` at the quad ``uv`` (4, 2)."""
    hc, wc = img.shape[:2]
    lo = np.floor(uv.min(axis=0)).astype(int) - 1
    hi = np.ceil(uv.max(axis=0)).astype(int) + 1
    lo_c = np.maximum(lo, 0)
    hi_c = np.minimum(hi, [wc - 1, hc - 1])
    if np.any(hi_c < lo_c):
        return
    ss = _SUPERSAMPLE
    size = hi_c - lo_c + 1
    dst = ((uv - lo_c) + 0.5) * ss - 0.5
    extent = max(np.linalg.norm(dst[1] - dst[0]), np.linalg.norm(dst[3] - dst[0]))
    k = tex.level(extent)
    src_img, ones = tex.levels[k], tex.ones[k]
    m = src_img.shape[0]
    src = np.array([[-0.5, -0.5], [m - 0.5, -0.5], [m - 0.5, m - 0.5], [-0.5, m - 0.5]], np.float32)
    h = cv2.getPerspectiveTransform(src, dst.astype(np.float32))
    dsize = (int(size[0] * ss), int(size[1] * ss))
    val = cv2.warpPerspective(src_img, h, dsize, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                              borderValue=0)
    cover = cv2.warpPerspective(ones, h, dsize, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                                borderValue=0)
    val = cv2.resize(val, (int(size[0]), int(size[1])), interpolation=cv2.INTER_AREA).astype(np.float32)
    cover = cv2.resize(cover, (int(size[0]), int(size[1])), interpolation=cv2.INTER_AREA)
    cover = cover.astype(np.float32)[..., None] / 255
    roi = img[lo_c[1]:hi_c[1] + 1, lo_c[0]:hi_c[0] + 1]
    out = roi * (1 - cover) + (val * shade)[..., None] * cover
    roi[:] = np.clip(out + 0.5, 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=4)
def _wood_texture(xr, yr, ell) -> tuple[np.ndarray, float]:
    """A plywood-like texture (uint8 BGR) covering the ramp, and its pixels per metre.

    Fixed internal seed: the ramp looks the same in every video (the render's own ``rng`` is for the
    camera noise)."""
    ppm = 400.0 / ell  # texture pixels per metre: about the screen density near the default camera
    nx = int(math.ceil((xr[1] - xr[0]) * ppm))
    ny = int(math.ceil((yr[1] - yr[0]) * ppm))
    gen = np.random.default_rng(20240521)
    yy = np.arange(ny, dtype=np.float32)[:, None] / ppm
    coarse = cv2.resize(gen.standard_normal((max(2, ny // 40), max(2, nx // 200))).astype(np.float32),
                        (nx, ny), interpolation=cv2.INTER_CUBIC)
    grain = np.sin(2 * np.pi * (yy / (0.013 * ell) + 0.8 * coarse)) * 0.5 + 0.5
    fine = cv2.resize(gen.standard_normal((ny // 3 + 1, nx // 3 + 1)).astype(np.float32), (nx, ny),
                      interpolation=cv2.INTER_LINEAR)
    board = (yy - yr[0]) / (0.5 * ell)  # boards half a leg length wide
    plank = np.floor(board) % 2
    seam = np.abs(board - np.round(board)) * 0.5 * ell < 0.002 * ell  # a thin dark seam between boards
    light = (1.0 - 0.10 * grain - 0.05 * plank + 0.03 * fine) * np.where(seam, 0.6, 1.0)
    tex = np.empty((ny, nx, 3), np.float32)
    for ch, base in enumerate((150.0, 185.0, 212.0)):
        tex[..., ch] = base * light
    return np.clip(tex, 0, 255).astype(np.uint8), ppm
