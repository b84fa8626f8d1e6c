"""Synthetic images for the tracking tests: planar textures (ArUco markers, ChArUco boards) drawn
into a frame at a known pose through a camera with lens distortion.

Each output pixel is the mean of ``ss x ss`` sub-pixel samples; each sample's ray (undistorted with
the camera's model) is intersected with the texture's plane and the texture is sampled bilinearly.
This is exact up to the supersampling, distortion included, unlike a homography warp.
"""

import cv2
import numpy as np
from toywalk.tracking.planes import compose, draw_plane  # noqa: F401 (the tests import them from here)


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
