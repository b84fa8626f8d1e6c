"""Camera calibration from images of a ChArUco board (docs/cli.md, ``toywalk calibrate``).

ChArUco corners (chessboard corners located with the help of the ArUco markers between them) are
found in each view with ``cv2.aruco.CharucoDetector``, matched to the board's 3D points with
``CharucoBoard.matchImagePoints`` and passed to ``cv2.calibrateCamera`` (Zhang 2000, IEEE TPAMI
22:1330, doi:10.1109/34.888718; ChArUco: Garrido-Jurado et al. 2014, Pattern Recognit. 47:2280).
A poor calibration is refused, with the number that failed: too few usable views, too few
corners, or an RMS reprojection error above ``max_rms`` pixels.

The solve runs on one OpenCV thread: on several, ``calibrateCamera`` sums its normal equations in an
order that changes from run to run, and with the nearly interchangeable radial terms (k2, k3) the
same views gave k3 differing in the sixth digit (0.563280-0.563283 over four runs of the bundled
sample views). One thread gives one answer, for 0.1 s instead of 0.06 s.
"""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import cv2
import numpy as np
from toywalk.model.files import atomic_write_json

from .camera import Camera
from .detect import dictionary_by_name
from .planes import compose, draw_plane

__all__ = ["DEFAULT_BOARD", "BoardSpec", "CalibrationError", "CalibrationResult", "board_views",
           "calibrate", "save_calibration"]


class CalibrationError(ValueError):
    """The images cannot give a trustworthy calibration; the message says why, with the number."""


@dataclasses.dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board.

    Attributes
    ----------
    squares : (int, int)
        Squares along x (columns) and y (rows).
    square_length, marker_length : float
        Chessboard square side and ArUco marker side (m).
    dictionary : str
        OpenCV's name of the marker dictionary.
    """

    squares: tuple[int, int] = (7, 5)
    square_length: float = 0.04
    marker_length: float = 0.03
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        sx, sy = (int(v) for v in self.squares)
        if sx < 3 or sy < 3:
            raise ValueError(f"squares must be at least (3, 3), got {self.squares}")
        if not 0 < self.marker_length < self.square_length:
            raise ValueError(f"need 0 < marker_length < square_length (m), got {self.marker_length} "
                             f"and {self.square_length}")
        dictionary_by_name(self.dictionary)
        object.__setattr__(self, "squares", (sx, sy))

    def board(self) -> cv2.aruco.CharucoBoard:
        """The OpenCV board object."""
        return cv2.aruco.CharucoBoard(self.squares, self.square_length, self.marker_length,
                                      dictionary_by_name(self.dictionary))

    @property
    def n_corners(self) -> int:
        """Inner chessboard corners."""
        return (self.squares[0] - 1) * (self.squares[1] - 1)

    def to_dict(self) -> dict:
        return {"type": "charuco", "squares": list(self.squares), "square_length": self.square_length,
                "marker_length": self.marker_length, "dictionary": self.dictionary}


#: 7 x 5 squares of 40 mm with 30 mm DICT_4X4_50 markers (fits on A4 paper at 28 x 20 cm).
DEFAULT_BOARD = BoardSpec()


@dataclasses.dataclass
class CalibrationResult:
    """A calibration and how it was obtained.

    Attributes
    ----------
    camera : Camera
        With ``reprojection_error`` set (RMS, pixels).
    rms : float
        RMS reprojection error (pixels).
    per_view_rms : list of float
        RMS reprojection error of each used view (pixels).
    used, rejected : list of str
        Names of the views used and of those rejected, with the reason.
    n_corners : int
        Corners used in all.
    board : BoardSpec
    std_intrinsics : ndarray
        Standard deviations of fx, fy, cx, cy, k1, k2, p1, p2, k3 (pixels or unitless).
    """

    camera: Camera
    rms: float
    per_view_rms: list
    used: list
    rejected: list
    n_corners: int
    board: BoardSpec
    std_intrinsics: np.ndarray

    def to_dict(self) -> dict:
        out = self.camera.to_dict()
        out["calibration"] = {
            "method": "ChArUco corners, cv2.calibrateCamera (k1, k2, p1, p2, k3)",
            "board": self.board.to_dict(), "rms_px": self.rms,
            "views_used": self.used, "views_rejected": self.rejected,
            "per_view_rms_px": self.per_view_rms, "corners": self.n_corners,
            "std": dict(zip(["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"],
                            map(float, self.std_intrinsics), strict=False)),
        }
        return out


def board_views(camera: Camera, n: int = 10, noise: float = 1.5, seed: int = 0,
                board: BoardSpec = DEFAULT_BOARD) -> list[np.ndarray]:
    """Synthetic views of ``board`` through ``camera`` (grey images, its size), as a person would
    take them: the board tilted up to 0.5 rad about each axis and turned up to 0.3 rad, off
    centre, at the distance where it spans about 55 % of the image's width (0.85 to 1.15 of it),
    on a grey background with grey-level noise of SD ``noise``. For a calibration whose truth is
    known (``toywalk calibrate``'s tests, the bundled sample's lens)."""
    rng = np.random.default_rng(seed)
    px = 100  # texture pixels per square
    sx, sy = board.squares
    tex = board.board().generateImage((sx * px, sy * px))
    w, h = sx * board.square_length, sy * board.square_length
    reach = camera.matrix[0, 0] * w / (0.55 * camera.width)
    views = []
    for _ in range(n):
        tilt = rng.uniform(-0.5, 0.5, 2)
        # board-to-camera: centre the board, tilt it, put it at about ``reach``, off centre
        centre = (np.zeros(3), np.array([-w / 2, -h / 2, 0.0]))
        tilted = compose((np.array([tilt[0], tilt[1], rng.uniform(-0.3, 0.3)]), np.zeros(3)), centre)
        depth = reach * rng.uniform(0.85, 1.15)
        pose = compose((np.zeros(3), depth * np.array([rng.uniform(-0.12, 0.12),
                                                       rng.uniform(-0.08, 0.08), 1.0])), tilted)
        image = np.full((camera.height, camera.width), 90, np.uint8)
        # board frame: y down the printed image, so the texture is flipped for draw_plane's +y-up rows
        draw_plane(image, camera, np.flipud(tex), (0.0, w, 0.0, h), *pose, ss=2)
        views.append(np.clip(image + rng.normal(0, noise, image.shape), 0, 255).astype(np.uint8))
    return views


def _load_image(item, name: str) -> np.ndarray:
    if isinstance(item, np.ndarray):
        image = item
    else:
        path = Path(item)
        if not path.exists():
            raise CalibrationError(f"image not found: {path}")
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise CalibrationError(f"cannot read image {path}: not an image file")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim != 2:
        raise CalibrationError(f"{name}: expected a grey or BGR image, got shape {image.shape}")
    return image


def calibrate(images, board: BoardSpec = DEFAULT_BOARD, *, max_rms: float = 1.0, min_views: int = 4,
              min_corners: int = 8, names=None) -> CalibrationResult:
    """Calibrate a camera from views of a ChArUco board.

    Parameters
    ----------
    images : sequence of ndarray or path
        Views of the board (grey or BGR arrays, or image files), all of one size.
    board : BoardSpec
    max_rms : float
        Refuse a calibration whose RMS reprojection error exceeds this (pixels).
    min_views : int
        Refuse with fewer usable views (a view is usable with at least ``min_corners`` corners).
    names : sequence of str, optional
        Names of the views for messages (default: file names or ``image[k]``).

    Raises
    ------
    CalibrationError
        Unreadable images, mixed sizes, too few usable views, or an RMS error above ``max_rms``.
    """
    images = list(images)
    if names is None:
        names = [str(x) if not isinstance(x, np.ndarray) else f"image[{k}]" for k, x in enumerate(images)]
    cboard = board.board()
    detector = cv2.aruco.CharucoDetector(cboard)
    size = None
    obj_pts, img_pts, used, rejected = [], [], [], []
    for item, name in zip(images, names, strict=True):
        image = _load_image(item, name)
        if size is None:
            size = image.shape[::-1]
        elif image.shape[::-1] != size:
            raise CalibrationError(f"{name} is {image.shape[1]}x{image.shape[0]} pixels, the first image "
                                   f"{size[0]}x{size[1]}: all views must come from one camera setting")
        corners, ids, _, _ = detector.detectBoard(image)
        count = 0 if ids is None else len(ids)
        if count < min_corners:
            rejected.append(f"{name}: {count} board corners (need {min_corners})")
            continue
        obj, img = cboard.matchImagePoints(corners, ids)
        obj = obj.reshape(-1, 3).astype(np.float32)
        if np.linalg.matrix_rank(obj[:, :2] - obj[:, :2].mean(axis=0), tol=1e-9) < 2:
            rejected.append(f"{name}: the corners found lie on one line")
            continue
        obj_pts.append(obj)
        img_pts.append(img.reshape(-1, 1, 2).astype(np.float32))
        used.append(name)
    if len(used) < min_views:
        raise CalibrationError(f"only {len(used)} usable view(s) of the board out of {len(images)} "
                               f"(need {min_views}, each with >= {min_corners} corners); take more "
                               "sharp views of the whole board at varied angles")
    flags = 0
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    with _one_opencv_thread():  # reproducible (module docstring)
        rms, k, d, _, _, std_in, _, per_view = cv2.calibrateCameraExtended(
            obj_pts, img_pts, size, None, None, flags=flags, criteria=criteria)
    rms = float(rms)
    if not np.isfinite(rms) or rms > max_rms:
        raise CalibrationError(f"RMS reprojection error {rms:.3g} px exceeds the limit {max_rms:g} px: "
                               "blurred, badly printed or non-flat board, or a wrong board description")
    camera = Camera(width=int(size[0]), height=int(size[1]), matrix=k, distortion=d.ravel()[:5],
                    reprojection_error=rms)
    return CalibrationResult(camera=camera, rms=rms, per_view_rms=[float(v) for v in per_view.ravel()],
                             used=used, rejected=rejected, n_corners=int(sum(len(o) for o in obj_pts)),
                             board=board, std_intrinsics=np.asarray(std_in).ravel()[:9])


@contextlib.contextmanager
def _one_opencv_thread():
    """OpenCV limited to one thread inside the block; the caller's setting restored after it."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(threads)


def save_calibration(result: CalibrationResult, path: str | Path) -> None:
    """Write the camera file with the calibration record (board, errors, views) atomically."""
    atomic_write_json(path, result.to_dict())
