"""The camera model: intrinsics, OpenCV distortion, projection and back-projection, JSON files.

Conventions (written once, used everywhere in ``tracking``):

- Pixel coordinates are OpenCV's ``(u, v)`` = (column, row), in pixels, the centre of the top-left
  pixel at (0, 0). Images themselves are NumPy arrays indexed ``[row, col]``.
- The camera frame is OpenCV's: x right, y down, z forward (optical axis).
- A pose ``(rvec, tvec)`` maps points of a body frame into the camera frame,
  ``X_cam = R(rvec) X_body + tvec`` (Rodrigues vector, metres). The ramp frame is docs/model.md's
  slope frame S (x downhill, y left, z along the ramp normal).
- Distortion coefficients are in OpenCV's order ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``.

All pixel-to-world conversion happens in the named functions of this module.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
from toywalk.model.files import atomic_write_json, read_json_object

__all__ = [
    "Camera",
    "CameraError",
    "backproject",
    "default_camera",
    "load_camera",
    "pose_matrix",
    "project",
    "save_camera",
    "undistort_pixels",
]


class CameraError(ValueError):
    """A camera file or camera argument is malformed."""


@dataclasses.dataclass(frozen=True)
class Camera:
    """A calibrated camera.

    Attributes
    ----------
    width, height : int
        Image size (pixels).
    matrix : ndarray, shape (3, 3)
        Intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (pixels).
    distortion : ndarray, shape (n,), n in {4, 5, 8, 12, 14}
        OpenCV distortion coefficients.
    ramp_pose : tuple of two ndarrays, shape (3,) each, or None
        (rvec, tvec) of the ramp frame in the camera frame, where the ramp is fixed relative to
        the camera; None when the ramp board is to be found in each frame.
    reprojection_error : float or None
        RMS reprojection error of the calibration (pixels), where known.
    """

    width: int
    height: int
    matrix: np.ndarray
    distortion: np.ndarray
    ramp_pose: tuple[np.ndarray, np.ndarray] | None = None
    reprojection_error: float | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int) and isinstance(self.height, int)
                and self.width > 0 and self.height > 0):
            raise CameraError(f"image size must be positive integers, got {self.width}x{self.height}")
        k = np.asarray(self.matrix, dtype=float)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise CameraError(f"camera matrix must be a finite 3x3 array, got shape {k.shape}")
        if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0, 0, 1]) or k[1, 0] != 0:
            raise CameraError("camera matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        d = np.asarray(self.distortion, dtype=float).ravel()
        if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
            raise CameraError(f"distortion must have 4, 5, 8, 12 or 14 finite coefficients, got {d.size}")
        object.__setattr__(self, "matrix", k)
        object.__setattr__(self, "distortion", d)
        if self.ramp_pose is not None:
            rvec, tvec = (np.asarray(v, dtype=float).reshape(3) for v in self.ramp_pose)
            object.__setattr__(self, "ramp_pose", (rvec, tvec))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels, OpenCV's order."""
        return self.width, self.height

    def at_size(self, width: int, height: int) -> Camera:
        """The same lens read out at ``width`` x ``height`` pixels, as a sensor's video modes are:
        focal lengths and principal point scale with the image (pixel centres at half-integers,
        so ``c' = (c + 0.5) s - 0.5``), while the distortion coefficients, in normalised image
        coordinates, and the ramp pose stay. The aspect ratio must be the same (within a pixel):
        another one crops the sensor, which no scaling describes.

        Raises
        ------
        CameraError
            Another aspect ratio, or a size that is not positive integers.
        """
        if not (isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer))
                and width > 0 and height > 0):
            raise CameraError(f"image size must be positive integers, got {width}x{height}")
        scale = width / self.width
        if abs(self.height * scale - height) > 1.0:
            raise CameraError(f"a {width}x{height} image is not the {self.width}x{self.height} "
                              "camera's aspect ratio: no scaling of its lens describes it")
        k = self.matrix.copy()
        k[:2, :2] *= scale
        k[:2, 2] = (k[:2, 2] + 0.5) * scale - 0.5
        return dataclasses.replace(self, width=int(width), height=int(height), matrix=k,
                                   reprojection_error=None if self.reprojection_error is None
                                   else self.reprojection_error * scale)

    def to_dict(self) -> dict:
        out = {
            "image_size": [self.width, self.height],
            "camera_matrix": self.matrix.tolist(),
            "distortion": self.distortion.tolist(),
        }
        if self.ramp_pose is not None:
            out["ramp_pose"] = {"rvec": self.ramp_pose[0].tolist(), "tvec": self.ramp_pose[1].tolist()}
        if self.reprojection_error is not None:
            out["reprojection_error_px"] = float(self.reprojection_error)
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Camera:
        """A camera from the JSON file's object: ``image_size`` [width, height] (positive integers),
        ``camera_matrix`` 3x3 and ``distortion`` (numbers), optional ``ramp_pose`` {rvec, tvec}
        (three numbers each) and ``reprojection_error_px``; other keys (a calibration's record)
        are ignored. :class:`CameraError` names the field that is missing or malformed."""
        bad = "malformed camera description"
        if not isinstance(data, dict):
            raise CameraError(f"{bad}: a JSON object is needed, got {type(data).__name__}")
        missing = [k for k in ("image_size", "camera_matrix", "distortion") if k not in data]
        if missing:
            raise CameraError(f"{bad}: missing key(s) {', '.join(missing)} (is this a camera file?)")
        size = data["image_size"]
        if not (isinstance(size, list) and len(size) == 2 and all(_is_count(v) for v in size)):
            raise CameraError(f"image size must be positive integers [width, height] (pixels, at most "
                              f"{MAX_IMAGE_SIDE}), got {_short(size)}")
        width, height = (int(v) for v in size)
        matrix = _numbers(data["camera_matrix"], "camera_matrix")  # its shape: __post_init__
        distortion = _numbers(data["distortion"], "distortion")
        if distortion.ndim != 1:
            raise CameraError(f"{bad}: distortion must be a flat list of numbers, got "
                              f"{_short(data['distortion'])}")
        pose = data.get("ramp_pose")
        ramp_pose = None
        if pose is not None:
            if not (isinstance(pose, dict) and {"rvec", "tvec"} <= set(pose)):
                raise CameraError(f"{bad}: ramp_pose must be an object with rvec and tvec, got "
                                  f"{_short(pose)}")
            ramp_pose = tuple(_numbers(pose[k], f"ramp_pose.{k}") for k in ("rvec", "tvec"))
            if any(v.shape != (3,) for v in ramp_pose):
                raise CameraError(f"{bad}: ramp_pose rvec and tvec must be three numbers each, got "
                                  f"{_short(pose)}")
        error = data.get("reprojection_error_px")
        if error is not None and not (_is_number(error) and _finite(error) and error >= 0):
            raise CameraError(f"{bad}: reprojection_error_px must be a number >= 0 (pixels), got "
                              f"{_short(error)}")
        return cls(width=width, height=height, matrix=matrix, distortion=distortion,
                   ramp_pose=ramp_pose, reprojection_error=None if error is None else float(error))


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _finite(value) -> bool:
    """A finite number (an integer too large for a float is not)."""
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


#: Largest image side (pixels) a camera file may give: past any camera's sensor, and a renderer
#: asked for such frames would try to allocate gigabytes each.
MAX_IMAGE_SIDE = 65536


def _is_count(value) -> bool:
    """An image side: a positive integer up to :data:`MAX_IMAGE_SIDE`, also written as a float
    (1280.0)."""
    return (_is_number(value) and _finite(value) and 1 <= value <= MAX_IMAGE_SIDE
            and float(value).is_integer())


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _numbers(value, what: str) -> np.ndarray:
    """A JSON array (nested lists, at most three deep) of finite numbers as a float array."""
    def flat(v, depth=0):
        if isinstance(v, list) and depth < 3:
            for item in v:
                yield from flat(item, depth + 1)
        else:
            yield v

    if not isinstance(value, list) or not all(_is_number(v) and _finite(v) for v in flat(value)):
        raise CameraError(f"malformed camera description: {what} must be a list of finite numbers, "
                          f"got {_short(value)}")
    try:
        return np.array(value, dtype=float)
    except ValueError as err:  # ragged rows
        raise CameraError(f"malformed camera description: {what} must be a regular array of "
                          f"numbers, got {_short(value)}") from err


def load_camera(path: str | Path) -> Camera:
    """Read a camera JSON file; a clear :class:`CameraError` for a missing or malformed file."""
    data = read_json_object(path, "camera file", CameraError)
    try:
        return Camera.from_dict(data)
    except CameraError as err:
        raise CameraError(f"{path}: {err}") from err


def save_camera(camera: Camera, path: str | Path) -> None:
    """Write a camera JSON file atomically."""
    atomic_write_json(path, camera.to_dict())


def default_camera(width: int = 1280, height: int = 720, horizontal_fov_deg: float = 40.0,
                   distortion=(0.0, 0.0, 0.0, 0.0, 0.0), ramp_pose=None) -> Camera:
    """A pinhole camera with square pixels, the principal point at the image centre."""
    f = 0.5 * width / math.tan(math.radians(horizontal_fov_deg) / 2)
    k = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    return Camera(width=width, height=height, matrix=k, distortion=np.array(distortion, float),
                  ramp_pose=ramp_pose)


def pose_matrix(rvec, tvec) -> np.ndarray:
    """4x4 homogeneous transform of a pose (rvec, tvec)."""
    out = np.eye(4)
    out[:3, :3] = cv2.Rodrigues(np.asarray(rvec, dtype=float).reshape(3, 1))[0]
    out[:3, 3] = np.asarray(tvec, dtype=float).reshape(3)
    return out


def project(camera: Camera, points, rvec, tvec) -> np.ndarray:
    """Pixels (u, v), shape (n, 2), of body-frame points, shape (n, 3) (m), seen with pose (rvec, tvec).

    Points behind the camera come back as NaN.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    uv, _ = cv2.projectPoints(pts, np.asarray(rvec, float).reshape(3, 1),
                              np.asarray(tvec, float).reshape(3, 1), camera.matrix, camera.distortion)
    uv = uv.reshape(-1, 2)
    depth = (pose_matrix(rvec, tvec)[:3, :3] @ pts.T).T[:, 2] + np.asarray(tvec, float).reshape(3)[2]
    uv[depth <= 0] = np.nan
    return uv


def undistort_pixels(camera: Camera, pixels) -> np.ndarray:
    """Normalised image coordinates (x/z, y/z), shape (n, 2), of pixels (u, v), shape (n, 2)."""
    px = np.asarray(pixels, dtype=float).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    out = cv2.undistortPoints(px, camera.matrix, camera.distortion, None, None, None, criteria)
    return out.reshape(-1, 2)


def backproject(camera: Camera, pixels) -> np.ndarray:
    """Unit rays in the camera frame, shape (n, 3), through pixels (u, v), shape (n, 2)."""
    xy = undistort_pixels(camera, pixels)
    rays = np.column_stack([xy, np.ones(len(xy))])
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)
