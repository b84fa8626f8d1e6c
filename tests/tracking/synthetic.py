"""Synthetic images for the tracking tests: planar textures (ArUco markers, ChArUco boards) drawn
into a frame at a known pose through a camera with lens distortion.

Each output pixel is the mean of ``ss x ss`` sub-pixel samples; each sample's ray (undistorted with
the camera's model) is intersected with the texture's plane and the texture is sampled bilinearly.
This is exact up to the supersampling, distortion included, unlike a homography warp.
"""

import cv2
import numpy as np
from toywalk.tracking.camera import undistort_pixels


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


def marker_texture(dictionary, marker_id, pixels=240, margin_cells=1.5, bits=4):
    """ArUco marker image with a white margin of ``margin_cells`` cells; returns (texture, scale)
    where scale is the textured width over the marker's (black square's) side."""
    cells = bits + 2
    img = cv2.aruco.generateImageMarker(dictionary, marker_id, pixels)
    pad = int(round(margin_cells * pixels / cells))
    return cv2.copyMakeBorder(img, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=255), \
        (pixels + 2 * pad) / pixels


def draw_marker(image, camera, dictionary, marker_id, side, rvec, tvec, ss=3):
    """An ArUco marker of side ``side`` (m) in its marker frame at pose (rvec, tvec), white margin."""
    tex, scale = marker_texture(dictionary, marker_id)
    h = side * scale / 2
    return draw_plane(image, camera, tex, (-h, h, -h, h), rvec, tvec, ss=ss)


def compose(pose_a, pose_b):
    """Pose a∘b: X -> R_a (R_b X + t_b) + t_a, as (rvec, tvec)."""
    ra = cv2.Rodrigues(np.asarray(pose_a[0], float).reshape(3, 1))[0]
    rb = cv2.Rodrigues(np.asarray(pose_b[0], float).reshape(3, 1))[0]
    r = ra @ rb
    t = ra @ np.asarray(pose_b[1], float).reshape(3) + np.asarray(pose_a[1], float).reshape(3)
    return cv2.Rodrigues(r)[0].ravel(), t


def look_at(position, target, up=(0.0, 0.0, 1.0)):
    """(rvec, tvec) of the world frame in the camera frame of a camera at ``position`` looking at
    ``target`` with ``up`` upwards in the image."""
    position, target = np.asarray(position, float), np.asarray(target, float)
    f = target - position
    f /= np.linalg.norm(f)
    right = np.cross(f, np.asarray(up, float))
    right /= np.linalg.norm(right)
    down = np.cross(f, right)
    r = np.vstack([right, down, f])
    return cv2.Rodrigues(r)[0].ravel(), -r @ position


def walker_scene_camera(width=1280, height=720):
    """A camera downhill and to the right of the walking line, looking back up the ramp at the
    walker (ramp frame: x downhill, y left, z up), with mild barrel distortion."""
    from toywalk.tracking.camera import Camera, default_camera

    base = default_camera(width, height)
    pose = look_at([0.75, -0.30, 0.28], [0.25, 0.0, 0.06])
    return Camera(width=width, height=height, matrix=base.matrix,
                  distortion=np.array([-0.05, 0.02, 0.0, 0.0, 0.0]), ramp_pose=pose)


def render_walker_frame(camera, layout, params, angles, stance, contact, noise=2.0, rng=None,
                        background=150, bodies_drawn=("ramp", "left_leg", "right_leg"), ss=3):
    """A grey frame of the walker's markers (legs at ``angles`` = (lean, steer, pitch_left,
    pitch_right), stance foot and contact point (m)) and the ramp markers; Gaussian pixel noise of
    SD ``noise`` grey levels."""
    from toywalk.model.kinematics import leg_poses

    rng = np.random.default_rng(rng)
    image = np.full((camera.height, camera.width), background, np.uint8)
    dictionary = layout.aruco_dictionary()
    lean, steer, pl, pr = angles
    legs = leg_poses(params, steer, lean, pl, pr, stance, contact)
    ramp = camera.ramp_pose
    bodies = {"ramp": ramp,
              "left_leg": compose(ramp, (cv2.Rodrigues(legs.rotation["L"])[0].ravel(), legs.hip["L"])),
              "right_leg": compose(ramp, (cv2.Rodrigues(legs.rotation["R"])[0].ravel(), legs.hip["R"]))}
    # far things first: ramp, then the leg farther from the camera
    depth = {b: bodies[b][1][2] for b in ("left_leg", "right_leg")}
    order = ["ramp"] + sorted(depth, key=lambda b: -depth[b])
    for body in order:
        if body not in bodies_drawn:
            continue
        for m in layout.on(body):
            pose = compose(bodies[body], (m.rvec, m.tvec))
            rot = cv2.Rodrigues(np.asarray(pose[0]).reshape(3, 1))[0]
            if rot[:, 2] @ pose[1] >= 0:  # facing away
                continue
            draw_marker(image, camera, dictionary, m.id, m.side, *pose, ss=ss)
    if noise > 0:
        image = np.clip(image + rng.normal(0, noise, image.shape), 0, 255).astype(np.uint8)
    return image, bodies


#: The console command (not ``python -m toywalk.sysid.cli``: run as ``__main__`` that module's
#: ``CommandError`` is a different class from the one the command modules import and raise).
TOYWALK = str(__import__("pathlib").Path(__import__("sys").executable).parent / "toywalk")
