"""Planar textures drawn into an image through a camera with lens distortion: the ChArUco board
views of a synthetic calibration (``board_views``), and the tests' markers.

Each output pixel is the mean of ``ss x ss`` sub-pixel samples; each sample's ray (undistorted with
the camera's model) is intersected with the texture's plane and the texture is sampled bilinearly.
This is exact up to the supersampling, distortion included, unlike a homography warp.
"""

from __future__ import annotations

import cv2
import numpy as np

from .camera import undistort_pixels

__all__ = ["compose", "draw_plane"]


def draw_plane(image, camera, texture, extent, rvec, tvec, ss=3):
    """Draw ``texture`` (grey uint8, rows x cols) covering ``extent`` = (x0, x1, y0, y1) (m) of the
    plane z = 0 of a body at pose (rvec, tvec) into ``image`` (grey uint8), in place.

    Texture column 0 is at x0, row 0 at y1 (the texture's top is +y, as ArUco's marker frame)."""
    x0, x1, y0, y1 = extent
    corners = np.array([[x0, y1, 0], [x1, y1, 0], [x1, y0, 0], [x0, y0, 0]], float)
    uv, _ = cv2.projectPoints(corners, np.asarray(rvec, float), np.asarray(tvec, float),
                              camera.matrix, camera.distortion)
    uv = uv.reshape(-1, 2)
    lo = np.maximum(np.floor(uv.min(axis=0)).astype(int) - 2, 0)
    hi = np.minimum(np.ceil(uv.max(axis=0)).astype(int) + 3, [image.shape[1], image.shape[0]])
    if np.any(hi <= lo):
        return image
    cols, rows = np.arange(lo[0], hi[0]), np.arange(lo[1], hi[1])
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    su = (cols[:, None] + offs[None, :]).ravel()
    sv = (rows[:, None] + offs[None, :]).ravel()
    uu, vv = np.meshgrid(su, sv)
    rays = np.column_stack([undistort_pixels(camera, np.column_stack([uu.ravel(), vv.ravel()])),
                            np.ones(uu.size)])
    rot = cv2.Rodrigues(np.asarray(rvec, float).reshape(3, 1))[0]
    t = np.asarray(tvec, float).reshape(3)
    normal = rot[:, 2]
    lam = (normal @ t) / (rays @ normal)
    pts = (lam[:, None] * rays - t) @ rot  # body-frame points
    h, w = texture.shape
    tx = (pts[:, 0] - x0) / (x1 - x0) * w - 0.5
    ty = (y1 - pts[:, 1]) / (y1 - y0) * h - 0.5
    inside = (lam > 0) & (tx >= -0.5) & (tx <= w - 0.5) & (ty >= -0.5) & (ty <= h - 0.5)
    sampled = cv2.remap(texture.astype(np.float32), tx.reshape(uu.shape).astype(np.float32),
                        ty.reshape(uu.shape).astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE).ravel()
    patch = image[lo[1]:hi[1], lo[0]:hi[0]].astype(np.float32)
    old = np.repeat(np.repeat(patch, ss, axis=0), ss, axis=1).ravel()
    mixed = np.where(inside, sampled, old).reshape(len(rows) * ss, len(cols) * ss)
    mixed = mixed.reshape(len(rows), ss, len(cols), ss).mean(axis=(1, 3))
    image[lo[1]:hi[1], lo[0]:hi[0]] = np.clip(np.rint(mixed), 0, 255).astype(np.uint8)
    return image


def compose(pose_a, pose_b):
    """Pose a∘b: X -> R_a (R_b X + t_b) + t_a, as (rvec, tvec)."""
    ra = cv2.Rodrigues(np.asarray(pose_a[0], float).reshape(3, 1))[0]
    rb = cv2.Rodrigues(np.asarray(pose_b[0], float).reshape(3, 1))[0]
    r = ra @ rb
    t = ra @ np.asarray(pose_b[1], float).reshape(3) + np.asarray(pose_a[1], float).reshape(3)
    return cv2.Rodrigues(r)[0].ravel(), t
