"""ArUco marker detection in a whole frame or in regions of interest, with sub-pixel corners.

Corners come back in OpenCV's ArUco order (top-left, top-right, bottom-right, bottom-left of the
marker as printed), as pixels ``(u, v)`` of the full frame (``camera.py`` conventions), whatever
region was searched. Detection uses OpenCV's class API (``cv2.aruco.ArucoDetector``; Garrido-Jurado
et al. 2014, Pattern Recognit. 47:2280, doi:10.1016/j.patcog.2014.01.005). Corners are then refined
by :func:`refine_corners`: sub-pixel points on each of the marker's four outer edges (where the
intensity profile across the edge crosses half-way between black and white), a straight line fitted
to each edge (in undistorted coordinates when a camera is given, so lens distortion does not bend
it), and the corners as the lines' intersections. On rendered markers this is about three times as
accurate as ``cornerSubPix`` on the corners themselves, which is biased at the non-right-angled
corners that perspective makes.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from .camera import undistort_pixels

__all__ = ["MarkerDetector", "Region", "dictionary_by_name", "marker_matches", "merge_regions",
           "refine_corners"]

_NEXT, _PREV = [1, 2, 3, 0], [3, 0, 1, 2]  # a quad's next and previous corners

#: A region of interest ``(x0, y0, x1, y1)``: columns x0..x1-1, rows y0..y1-1 (pixels).
Region = tuple[int, int, int, int]


def dictionary_by_name(name: str) -> cv2.aruco.Dictionary:
    """The predefined ArUco dictionary called ``name`` (e.g. ``"DICT_4X4_50"``)."""
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"unknown ArUco dictionary {name!r}; expected a name such as 'DICT_4X4_50'")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


def merge_regions(regions, width: int, height: int) -> list[Region]:
    """Clip regions to the image and merge overlapping ones (their bounding box) until none overlap."""
    boxes = []
    for x0, y0, x1, y1 in regions:
        box = [max(0, int(x0)), max(0, int(y0)), min(width, int(x1)), min(height, int(y1))]
        if box[2] - box[0] >= 8 and box[3] - box[1] >= 8:
            boxes.append(box)
    merged = True
    while merged and len(boxes) > 1:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    boxes[i] = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])]
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return [tuple(b) for b in boxes]


def _sample(gray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear samples of grey images at pixels (u, v) (two arrays of one shape).

    ``gray`` is one image (an array, or a :class:`_Shifted` crop) for all points, or a sequence
    of images, one for each item along the first axis of ``u`` and ``v`` (items sharing an image
    object are sampled together).
    """
    if isinstance(gray, (list, tuple)):
        if len(gray) != len(u):
            raise ValueError(f"need one image per item: {len(gray)} images for {len(u)} items")
        groups: dict[int, tuple] = {}
        for k, g in enumerate(gray):
            groups.setdefault(id(g), (g, []))[1].append(k)
        if len(groups) == 1:
            return _sample(gray[0], u, v)
        out = np.empty(u.shape)
        for g, items in groups.values():
            if items[-1] - items[0] == len(items) - 1:  # consecutive items (a region's): a view
                items = slice(items[0], items[-1] + 1)
            out[items] = _sample(g, u[items], v[items])
        return out
    if isinstance(gray, _Shifted):
        u, v = u - gray.offset[0], v - gray.offset[1]
        gray = gray.crop
    # rows of the last axis' length: cv2.remap takes maps of fewer than 32767 rows and columns
    cols = u.shape[-1] if u.ndim > 1 else 1
    out = cv2.remap(gray, u.reshape(-1, cols).astype(np.float32), v.reshape(-1, cols).astype(np.float32),
                    cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return out.reshape(u.shape).astype(float)


@functools.lru_cache
def _along(samples: int) -> np.ndarray:
    """Where the edge profiles cross an edge: ``samples`` fractions of its length (read-only)."""
    s = np.linspace(0.15, 0.85, samples)
    s.flags.writeable = False
    return s


def refine_corners(gray, corners: np.ndarray, camera=None, *, samples: int = 12,
                   iterations: int = 1) -> np.ndarray:
    """Sub-pixel corners of dark marker squares on a light margin from rough ones.

    Parameters
    ----------
    gray : ndarray, shape (rows, cols), uint8 or float, or a sequence of m of them
        The image, or one image per marker.
    corners : ndarray, shape (4, 2) or (m, 4, 2)
        Rough corners (u, v) in ArUco's order, of one marker or of m; a marker's are returned
        unchanged if one of its edges cannot be measured.
    camera : Camera, optional
        Fit the edge lines in undistorted coordinates.
    samples : int
        Points measured along each edge.

    Returns
    -------
    ndarray, the shape of ``corners``
    """
    c = np.asarray(corners, float)
    if c.shape[-2:] != (4, 2) or c.ndim not in (2, 3):
        raise ValueError(f"corners must have shape (4, 2) or (m, 4, 2), got {c.shape}")
    return _refine(gray, c.reshape(-1, 4, 2), camera, samples, iterations)[0].reshape(c.shape)


def _refine(gray, corners: np.ndarray, camera, samples: int, iterations: int, *,
            coarse: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_corners` of m quads at once (shape (m, 4, 2)), and whether every edge of
    each could be measured (shape (m,); else its rough corners are returned).

    ``gray`` is one image for all quads or a sequence of one per quad (see :func:`_sample`).
    The quads are independent: each is refined exactly as it would be alone, over a band of its
    own width; the profiles of narrower bands are padded to the widest and the padding masked.

    ``coarse`` is for rough corners pixels off (a predicted quad): each edge is sought over a
    wider band (0.16 of the side, at most 8 px), half-way between the median darkest and lightest
    samples of that edge's profiles, at the outermost dark-to-light crossing (so bits inside the
    border do not capture it). It converges from farther but is biased by blur; finish with the
    default mode, which is unbiased once centred.
    """
    c0 = np.asarray(corners, float).reshape(-1, 4, 2)
    c = c0.copy()
    ok = np.ones(len(c0), dtype=bool)
    s = _along(samples)
    for _ in range(iterations):
        act = np.flatnonzero(ok)
        if not len(act):
            break
        a = c[act]  # (A, 4, 2); edge k runs from corner k to corner k + 1
        along = a[:, _NEXT] - a
        length = np.sqrt(along[..., 0] ** 2 + along[..., 1] ** 2)  # (A, 4)
        side = length.mean(axis=1)
        # px: about the black border cell, at most (fmin: the most for corners not finite)
        reach = np.fmax(1.5, np.fmin(8.0 if coarse else 4.0, (0.16 if coarse else 0.12) * side))
        nt = (4 * reach).astype(int) + 1  # samples across each edge, (A,)
        width = int(nt.max())
        index = np.arange(width)
        # np.linspace(-reach, reach, nt), term by term, padded on to the widest band
        spacing = (2 * reach) / (nt - 1)
        steps = index * spacing[:, None] - reach[:, None]  # (A, T)
        band = (index < nt[:, None])[:, None, None, :]  # (A, 1, 1, T): within each quad's band
        direction = along / length[..., None]
        normal = direction[..., ::-1] * [1.0, -1.0]
        centred = a - a.mean(axis=1, keepdims=True)
        outward = normal[..., 0] * centred[..., 0] + normal[..., 1] * centred[..., 1] < 0
        normal[outward] *= -1.0
        base = a[:, :, None, :] + s[:, None] * along[:, :, None, :]  # (A, 4, S, 2)
        across = steps[:, None, None, :]
        u = base[..., 0, None] + across * normal[:, :, None, None, 0]  # (A, 4, S, T)
        v = base[..., 1, None] + across * normal[:, :, None, None, 1]
        images = [gray[i] for i in act] if isinstance(gray, (list, tuple)) else gray
        prof = _sample(images, u, v)  # (A, 4, S, T): dark inside -> light outside
        rows = prof.reshape(-1, width)  # one profile a row
        line = np.arange(len(rows))
        if coarse:
            darkest = np.where(band, prof, np.inf).min(axis=-1)
            lightest = np.where(band, prof, -np.inf).max(axis=-1)
            lo = np.repeat(np.median(darkest, axis=2)[:, :, None], samples, axis=2)
            hi = np.repeat(np.median(lightest, axis=2)[:, :, None], samples, axis=2)
            level = 0.5 * (lo + hi)
            up = (prof[..., :-1] < level[..., None]) & (prof[..., 1:] >= level[..., None]) & band[..., 1:]
            j = width - 1 - np.argmax(up[..., ::-1], axis=-1)  # after the outermost upward crossing
            valid = (hi - lo > 20.0) & up.any(axis=-1)
        else:
            # means of the band's first and last thirds (sums of whole grey levels: exact in any
            # order, so the same as np.mean's)
            third = nt // 3
            ends = np.zeros((len(act), width, 2))
            ends[:, :, 0] = index < third[:, None]
            ends[:, :, 1] = (index >= (nt - third)[:, None]) & (index < nt[:, None])
            sums = np.matmul(prof.reshape(len(act), -1, width), ends).reshape(prof.shape[:-1] + (2,))
            lo = sums[..., 0] / third[:, None, None]
            hi = sums[..., 1] / third[:, None, None]
            level = 0.5 * (lo + hi)
            above = (prof >= level[..., None]) & band
            j = np.argmax(above, axis=-1)
            valid = (hi - lo > 20.0) & above.any(axis=-1) & (j > 0)  # 20 grey levels of contrast
        j = np.minimum(np.maximum(j, 1), (nt - 1)[:, None, None])
        p1 = rows[line, j.ravel()].reshape(j.shape)
        p0 = rows[line, j.ravel() - 1].reshape(j.shape)
        with np.errstate(divide="ignore", invalid="ignore"):
            f = (level - p0) / (p1 - p0)
        # no crossing (0/0), or a profile level where it should step (x/0): not finite either way,
        # and NaN rather than inf, which would warn when multiplied by a zero normal component
        f[~np.isfinite(f)] = np.nan
        start = steps[np.arange(len(act))[:, None, None], j - 1]
        offset = start + f * (steps[:, 1] - steps[:, 0])[:, None, None]
        edge = base + offset[..., None] * normal[:, :, None, :]  # (A, 4, S, 2)
        # A profile with no crossing at all (flat: 0/0) means a partly covered or smeared quad:
        # it is not refined. Refining such quads from their other profiles was tried and was
        # worse (toy-sized walker, noise level 1 with occluders: strike timing 0.11 -> 0.34 frame,
        # lean 0.08 -> 0.13 degree RMS; benchmarks/TRACKING.md).
        flat = np.any(~np.isfinite(offset), axis=(1, 2))
        valid &= np.isfinite(offset)
        measured = np.all(valid.sum(axis=2) >= 4, axis=1) & ~flat
        if not measured.all():
            ok[act[~measured]] = False
            act, a, side, edge, valid = (x[measured] for x in (act, a, side, edge, valid))
            if not len(act):
                break
        if camera is not None:
            edge = undistort_pixels(camera, edge.reshape(-1, 2)).reshape(edge.shape)
        # total-least-squares line of each edge's valid points, in closed form
        w = valid.astype(float)
        mean = np.einsum("aks,aksd->akd", w, edge) / w.sum(axis=2)[..., None]
        dev = (edge - mean[:, :, None, :]) * w[..., None]
        sxx = np.einsum("aks,aks->ak", dev[..., 0], dev[..., 0])
        syy = np.einsum("aks,aks->ak", dev[..., 1], dev[..., 1])
        sxy = np.einsum("aks,aks->ak", dev[..., 0], dev[..., 1])
        angle = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # direction of largest spread
        nx, ny = -np.sin(angle), np.cos(angle)
        # corner k joins edges k-1 and k: the cross product of their lines (b1, b2, b3)
        b1, b2, b3 = nx, ny, -(nx * mean[..., 0] + ny * mean[..., 1])
        a1, a2, a3 = b1[:, _PREV], b2[:, _PREV], b3[:, _PREV]
        px, py, pz = a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1
        meet = ~np.any(np.abs(pz) < 1e-12, axis=1)
        new = np.stack([px / pz, py / pz], axis=-1)
        if camera is not None:
            flat, _ = cv2.projectPoints(np.column_stack([new.reshape(-1, 2), np.ones(new.size // 2)]),
                                        np.zeros(3), np.zeros(3), camera.matrix, camera.distortion)
            new = flat.reshape(new.shape)
        moved = new - c0[act]
        near = ~(np.max(np.sqrt(moved[..., 0] ** 2 + moved[..., 1] ** 2), axis=1) > 0.5 * side)
        keep = meet & near
        ok[act[~keep]] = False
        c[act[keep]] = new[keep]
    c[~ok] = c0[~ok]
    return c, ok


#: px: ArUco's corners lie on its outline polygon, a median 0.9 px from the edge-line corners on
#: every shipped walker's clips (90th percentile 1.0-1.9 px per flag). A first refinement step a
#: third beyond that median marks an outline displaced by smear, refined again
#: (:func:`_refine_smeared`). Measured on test_occluded_leg.py's stable-toy clip (left pitch, degree
#: RMS): 0.19 at 1.0 or 1.2 px, 0.28 at 1.5, 0.31 at 1.8, 0.42 without.
_SMEARED_STEP = 1.2


def _refine_smeared(gray, rough: np.ndarray, refined: np.ndarray, camera, *, more: int = 2) -> np.ndarray:
    """Refine again, up to ``more`` times, the quads (m, 4, 2) whose first edge-line step from
    ArUco's ``rough`` corners to ``refined`` exceeds :data:`_SMEARED_STEP`.

    When the smear is about as wide as the fine band, the band's end thirds (its dark and light
    levels) take in the edge's own slope on the side it lies, so one step falls short: a smeared
    flag's corners 3.1 px off, steps 1.9, 0.67, 0.24 px, then 0.6 px off (stable-toy,
    test_occluded_leg.py); a 5-px box smear 2-3 px off, 0.49-0.89 px after one step and
    0.07-0.13 after this (test_detect_smear.py). A step is kept only if it is at most half the
    one before: one that does not shrink is an edge of something covering the flag taking the
    quad (3.4, then 2.9 px). A 7-px smear converges too slowly for that rule and keeps about 1 px.

    Quads with an ordinary first step are refined once. Refining every quad to convergence gives
    better corners (the 16-step walk of test_ramp_pose.py: leg-flag corner RMS 0.065-0.132 ->
    0.049-0.111 px) but lowers the hip width estimated from the frames (34.62-34.67 -> 34.54-34.59
    mm, true 34.67; the fastest frames most), which turns lean and steer (steer mean -0.036 to
    -0.070 degree); with the true width given, they are within 0.015 degree of zero either way
    (benchmarks/TRACKING.md).
    """
    out = np.array(refined, float)
    step = np.max(np.linalg.norm(out - rough, axis=2), axis=1)
    active = np.flatnonzero(np.isfinite(step) & (step > _SMEARED_STEP))
    for _ in range(more):
        if not len(active):
            break
        images = [gray[i] for i in active] if isinstance(gray, (list, tuple)) else gray
        again = refine_corners(images, out[active], camera)
        moved = np.max(np.linalg.norm(again - out[active], axis=2), axis=1)
        shrinks = np.isfinite(moved) & (moved <= 0.5 * step[active])
        out[active[shrinks]] = again[shrinks]
        step[active] = moved
        # a quad that did not move (its edges not measurable) would only come back unchanged
        active = active[shrinks & (moved > 0)]
    return out


def _cell_means(gray, corners: np.ndarray, cells: int, per_cell: int = 3) -> np.ndarray:
    """Mean grey level of the central half of each cell of a marker's grid, shape (cells, cells).

    The quad ``corners`` (4, 2; ArUco's order, the black square's corners) is mapped to the
    canonical square ``[0, cells]^2`` by a homography (``cv2.getPerspectiveTransform``); each
    cell is sampled at ``per_cell^2`` points spread over its central half, away from the blur
    at the cell boundaries.
    """
    canon = np.array([[0, 0], [cells, 0], [cells, cells], [0, cells]], np.float32)
    h = cv2.getPerspectiveTransform(canon, np.asarray(corners, np.float32).reshape(4, 2))
    offs = (np.arange(per_cell) + 0.5) / per_cell * 0.5 + 0.25  # central half of the cell
    grid = (np.arange(cells)[:, None] + offs[None, :]).ravel()  # (cells * per_cell,)
    x, y = np.meshgrid(grid, grid)  # rows follow y (the marker's rows), columns x
    pts = cv2.perspectiveTransform(np.column_stack([x.ravel(), y.ravel()]).reshape(-1, 1, 2)
                                   .astype(np.float64), h).reshape(x.shape + (2,))
    values = _sample(gray, pts[..., 0], pts[..., 1])  # (cells * per_cell, cells * per_cell)
    return values.reshape(cells, per_cell, cells, per_cell).mean(axis=(1, 3))


def marker_matches(gray, corners: np.ndarray, dictionary: cv2.aruco.Dictionary, marker_id: int, *,
                   max_bit_errors: int = 1, max_border_errors: int = 1, min_contrast: float = 20.0) -> bool:
    """Whether the quad ``corners`` in ``gray`` shows marker ``marker_id`` of ``dictionary``.

    The marker's grid of cells (its bits plus the black border) is read through the homography
    of the quad (:func:`_cell_means`), each cell's mean thresholded at Otsu's level of all the
    samples (Otsu 1979, IEEE Trans. Syst. Man Cybern. 9:62, doi:10.1109/TSMC.1979.4310076).
    It matches when at most ``max_border_errors`` border cells are light, at most
    ``max_bit_errors`` inner bits differ from the dictionary's (in the orientation the corner
    order gives), no other id of the dictionary, in any rotation, is as close, and the light and
    dark cells differ by at least ``min_contrast`` grey levels (an empty region has no code).

    Parameters
    ----------
    gray : ndarray, shape (rows, cols)
        Grey image.
    corners : ndarray, shape (4, 2)
        Pixels (u, v) of the black square's corners, ArUco's order.
    dictionary : cv2.aruco.Dictionary
    marker_id : int
    """
    read = _read_code(gray, corners, dictionary, marker_id, max_border_errors=max_border_errors,
                      min_contrast=min_contrast)
    if read is None or read[0] > max_bit_errors:
        return False
    errors, inner = read
    cells = int(dictionary.markerSize) + 2
    others = min((dictionary.getDistanceToId(inner, j, True) for j in range(len(dictionary.bytesList))
                  if j != int(marker_id)), default=cells * cells)
    return errors < others


def _read_code(gray, corners: np.ndarray, dictionary: cv2.aruco.Dictionary, marker_id: int, *,
               max_border_errors: int = 1, min_contrast: float = 20.0):
    """The inner bits the quad ``corners`` shows (:func:`marker_matches`) and how many differ from
    marker ``marker_id``'s: (errors, bits as uint8 (k, k)), or None when the quad shows no code (too
    little contrast, more than ``max_border_errors`` light border cells)."""
    bits = int(dictionary.markerSize)
    cells = bits + 2
    means = _cell_means(gray, corners, cells)
    if not np.all(np.isfinite(means)):
        return None
    levels = np.clip(np.rint(means), 0, 255).astype(np.uint8)
    level, _ = cv2.threshold(levels.reshape(1, -1), 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    # the cells as Otsu saw them (whole grey levels): it puts its threshold at the dark class's
    # top, so a dark cell of mean 1.2 would be light against the unrounded means
    light = levels > level
    if light.all() or not light.any():
        return None
    if means[light].mean() - means[~light].mean() < min_contrast:
        return None
    border = np.ones((cells, cells), dtype=bool)
    border[1:-1, 1:-1] = False
    if int(light[border].sum()) > max_border_errors:
        return None
    inner = light[1:-1, 1:-1].astype(np.uint8)
    return int(np.sum(inner.astype(bool) != _code(dictionary, int(marker_id)))), inner


_CODES: dict = {}


def _code(dictionary: cv2.aruco.Dictionary, marker_id: int) -> np.ndarray:
    """Marker ``marker_id``'s inner bits (bool (k, k), True = light), kept once computed."""
    key = (bytes(dictionary.bytesList[marker_id].ravel()), int(dictionary.markerSize))
    if key not in _CODES:
        cells = int(dictionary.markerSize) + 2
        _CODES[key] = cv2.aruco.generateImageMarker(dictionary, int(marker_id), cells)[1:-1, 1:-1] > 127
    return _CODES[key]


class _Shifted:
    """A crop that samples like the full frame (for refine_corners with a camera)."""

    def __init__(self, crop, offset):
        self.crop, self.offset = crop, offset


class MarkerDetector:
    """Find ArUco markers of one dictionary, in a whole image or in regions of interest.

    Parameters
    ----------
    dictionary : str
        OpenCV's name of the predefined dictionary, e.g. ``"DICT_4X4_50"``.
    ids : iterable of int, optional
        The marker ids of interest; others are ignored. None keeps all.
    camera : Camera, optional
        Lens model used when refining corners (edges are straight only once undistorted).
    """

    def __init__(self, dictionary: str = "DICT_4X4_50", *, ids=None, camera=None):
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE  # refine_corners does it
        self._params = params
        self.camera = camera
        self._dictionary = dictionary_by_name(dictionary)
        self._detector = cv2.aruco.ArucoDetector(self._dictionary, params)
        self._min_rate, self._max_rate = params.minMarkerPerimeterRate, params.maxMarkerPerimeterRate
        # Detectors for regions around markers of known size (min_side in detect), whose
        # parameters are set for each region. Around markers at least 30 px wide the smallest
        # adaptive-threshold window (3 px, for tiny markers) finds nothing the 13 and 23 px ones
        # miss; it cost 40 % of the detection time before short outlines were skipped, 15 % since.
        self._roi_detectors = {}
        for large in (False, True):
            roi_params = cv2.aruco.DetectorParameters()
            roi_params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
            if large:
                roi_params.adaptiveThreshWinSizeMin = 13
            self._roi_detectors[large] = (roi_params, cv2.aruco.ArucoDetector(self._dictionary, roi_params))
        self.dictionary = dictionary
        self.ids = None if ids is None else frozenset(int(i) for i in ids)

    def detect(self, image: np.ndarray, regions=None, *, min_side: float = 0.0) -> dict[int, np.ndarray]:
        """Markers found in ``image`` (grey or BGR, shape (rows, cols[, 3])).

        Parameters
        ----------
        regions : list of Region, optional
            Search only these (non-overlapping, see :func:`merge_regions`) regions; None searches
            the whole image.
        min_side : float
            The smallest extent (pixels) across a marker sought, in regions: outlines shorter
            than that (noise, mostly) are not examined, and from 30 px on the adaptive
            thresholds skip the smallest window (both faster, no loss for such markers).

        Returns
        -------
        dict of int to ndarray, shape (4, 2)
            Corner pixels (u, v) of the full image, by marker id. An id found twice (a printing or
            dictionary clash) is dropped rather than guessed.
        """
        if image.ndim not in (2, 3):
            raise ValueError(f"image must have shape (rows, cols) or (rows, cols, 3), got {image.shape}")
        height, width = image.shape[:2]
        if regions is None or not 0 < min_side < math.inf:
            params, detector = None, self._detector
        else:
            params, detector = self._roi_detectors[min_side >= 30.0]
        if regions is None:
            regions = [(0, 0, width, height)]
        ids, rough, images = [], [], []
        for x0, y0, x1, y1 in regions:
            crop = image[y0:y1, x0:x1]
            if crop.ndim == 3:
                crop = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
            if params is not None:
                # ArUco's perimeter is the outline's pixel count, at least twice the quad's largest
                # extent: a marker has to look half its predicted size to be skipped. Noise
                # outlines shorter than that took about 70 % of the detection time.
                params.minMarkerPerimeterRate = min(max(min_side / max(crop.shape[:2]), self._min_rate),
                                                    self._max_rate)
                detector.setDetectorParameters(params)
            corners, found_ids, _ = detector.detectMarkers(crop)
            if found_ids is None:
                continue
            gray = _Shifted(crop, np.array([x0, y0], dtype=float))  # samples in full-frame pixels
            for c, i in zip(corners, found_ids.ravel(), strict=True):
                if self.ids is None or int(i) in self.ids:
                    ids.append(int(i))
                    rough.append(c.reshape(4, 2).astype(float) + gray.offset)
                    images.append(gray)
        found: dict[int, np.ndarray] = {}
        clashes: set[int] = set()
        if not ids:
            return found
        # all markers of all regions refined at once; the lens model needs full-frame pixels
        rough = np.array(rough)
        refined = _refine_smeared(images, rough, refine_corners(images, rough, self.camera), self.camera)
        # An edge the refinement could not fit (too short, cut by the crop) gives NaN: keep the
        # detector's own corners rather than a broken marker.
        finite = np.all(np.isfinite(refined), axis=(1, 2))
        for i, r, c, ok in zip(ids, refined, rough, finite, strict=True):
            if i in found:
                clashes.add(i)
            found[i] = r if ok else c
        for i in clashes:
            del found[i]
        return found

    def follow(self, image: np.ndarray, predicted: dict, *, check=None, max_move: float = 1.5,
               max_bit_errors: int = 1) -> dict[int, np.ndarray]:
        """Markers found where they are predicted, without ArUco's search.

        For markers whose image moves little and smoothly from frame to frame (a fixed camera's
        ramp markers, or a panning camera's predicted at constant velocity), each predicted quad
        is refined by the edge lines of :func:`refine_corners` (as a detected marker's rough
        corners are, all markers at once) and kept when every corner lies within ``max_move``
        pixels of its prediction and its area within 10 % of the predicted one's. The markers in
        ``check``, and any that moved more than a third of ``max_move`` from its prediction, must
        also show their own code in their cells to ``max_bit_errors`` bits (continuity has already
        named them, so unlike :meth:`recover` no other id is compared). A marker that fails
        (covered, moved more than predicted, too near the frame's edge) is left to :meth:`detect`.

        Parameters
        ----------
        image : ndarray, shape (rows, cols[, 3])
        predicted : dict of int to ndarray, shape (4, 2)
            Predicted corners (full-frame pixels, ArUco's order) by marker id.
        check : collection of int, optional
            Ids whose code is read in any case (default: all).

        Returns
        -------
        dict of int to ndarray, shape (4, 2)
            The markers followed: refined corners by id.
        """
        ids, quads, crops = [], [], []
        for marker_id, corners in predicted.items():
            pred = np.asarray(corners, float).reshape(4, 2)
            if not np.all(np.isfinite(pred)):
                continue
            # padded by the refinement's widest band and the motion allowed
            crop = _crop_around(image, pred, max_move + 8.0)
            if crop is None:
                continue
            ids.append(int(marker_id))
            quads.append(pred)
            crops.append(crop)
        out: dict[int, np.ndarray] = {}
        if not ids:
            return out
        quads = np.array(quads)
        refined, ok = _refine(crops, quads, self.camera, 12, 1)
        moved = np.max(np.hypot(*np.moveaxis(refined - quads, -1, 0)), axis=1)  # NaN where not finite
        ratio = np.abs(_quad_area(refined)) / np.maximum(np.abs(_quad_area(quads)), 1e-9)
        keep = ok & (moved <= max_move) & (ratio > 0.9) & (ratio < 1.1)
        for k in np.flatnonzero(keep):
            marker_id, new, gray = ids[k], refined[k], crops[k]
            if moved[k] > max_move / 3 or check is None or marker_id in check:
                read = _read_code(gray, new, self._dictionary, marker_id)
                if read is None or read[0] > max_bit_errors:
                    continue
            out[marker_id] = new
        return out

    def recover(self, image: np.ndarray, marker_id: int, corners: np.ndarray, *, search: float = 6.0,
                max_bit_errors: int = 1) -> np.ndarray | None:
        """Find marker ``marker_id`` near predicted ``corners`` where the detector missed it.

        ArUco rejects markers whose corners blur (motion blur near heel strike) at its polygon
        stage, although their edges and bits are plainly visible. Here the predicted quad
        (4, 2; pixels (u, v), ArUco's order), shifted by up to ``search`` pixels, is refined by
        the edge lines of :func:`refine_corners`, and the result is accepted only if its bits are
        those of ``marker_id`` (:func:`marker_matches`) and its area is within 30 % of the
        predicted one.

        Returns
        -------
        ndarray, shape (4, 2), or None
            The refined corners (full-frame pixels), or None if no shift gives a verified marker.
        """
        pred = np.asarray(corners, float).reshape(4, 2)
        if not np.all(np.isfinite(pred)):
            return None
        gray = _crop_around(image, pred, search + 8.0)
        if gray is None:
            return None  # too near the frame's edge to measure all four edges
        area = abs(_quad_area(pred))
        step = max(1.5, min(4.0, 0.12 * float(np.mean(np.linalg.norm(np.roll(pred, -1, axis=0) - pred,
                                                                        axis=1)))))
        shifts = np.array(_search_shifts(step, search))
        # the prediction itself first (it is usually right), then every other shift at once; the
        # nearest shift that gives a verified marker wins
        for batch in (shifts[:1], shifts[1:]):
            if not len(batch):
                continue
            rough, ok = _refine(gray, pred[None] + batch[:, None, :], self.camera, 12, 2, coarse=True)
            if not ok.any():
                continue
            refined, fine = _refine(gray, rough[ok], self.camera, 12, 2)
            ratio = np.abs(_quad_area(refined)) / area
            good = fine & np.all(np.isfinite(refined), axis=(1, 2)) & (ratio > 0.7) & (ratio < 1.3)
            # (shifts that converge to one quad are each read: reading a blurred code is marginal,
            # and quads 0.05 px apart were seen to read differently)
            for quad in refined[good]:
                if marker_matches(gray, quad, self._dictionary, marker_id, max_bit_errors=max_bit_errors):
                    return quad
        return None


def _crop_around(image: np.ndarray, quad: np.ndarray, pad: float) -> _Shifted | None:
    """The grey crop of ``image`` holding ``quad`` (4, 2; pixels) with ``pad`` pixels on every side,
    as a :class:`_Shifted` sampling in full-frame pixels; None when that box leaves the frame."""
    height, width = image.shape[:2]
    lo = np.floor(quad.min(axis=0) - pad).astype(int)
    hi = np.ceil(quad.max(axis=0) + pad).astype(int) + 1
    if lo[0] < 0 or lo[1] < 0 or hi[0] > width or hi[1] > height:
        return None
    crop = image[lo[1]:hi[1], lo[0]:hi[0]]
    if crop.ndim == 3:
        crop = cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY)
    return _Shifted(crop, lo.astype(float))


def _quad_area(c: np.ndarray):
    """Signed area (pixels^2) of a quad (4, 2) (shoelace formula), or of each of m quads (m, 4, 2)."""
    x, y = c[..., 0], c[..., 1]
    area = 0.5 * np.sum(x * y[..., _NEXT] - y * x[..., _NEXT], axis=-1)
    return float(area) if c.ndim == 2 else area


def _search_shifts(step: float, search: float) -> list[np.ndarray]:
    """Shifts (pixels) of a predicted quad to try, nearest first: a grid of ``step`` within
    ``search`` of zero (the edge refinement converges from within about one step)."""
    k = int(search // step)
    shifts = [np.array([i * step, j * step]) for i in range(-k, k + 1) for j in range(-k, k + 1)]
    return sorted(shifts, key=lambda v: float(np.hypot(*v)))
