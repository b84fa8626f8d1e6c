"""The walkers and scenes the tracker's tests film: a toy-sized walker with smooth made-up
motion (tests/tracking/test_track.py, test_ramp_pose.py, test_render_frame.py), and the compass
walker standing in a known pose before its default camera, with the corners its markers show
(tests/tracking/test_track_joint.py, test_pixel_noise.py)."""

import cv2
import numpy as np
from toywalk.model.kinematics import leg_poses
from toywalk.model.parameters import Params
from toywalk.tracking.joint import walker_from_legs
from toywalk.tracking.markers import body_points, default_layout
from toywalk.tracking.scene import default_camera_for

__all__ = ["COMPASS", "COMPASS_ANGLES", "NAMES", "TOY", "compass_scene", "motion", "start_near"]

#: The toy-sized walker (SI units): 15 cm legs, spool feet.
TOY = Params(leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.0,
             leg_mass=0.05, axle_mass=0.02, com_offset=(-0.005, 0.1, -0.11),
             inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0), slope=0.0785, gravity=9.81)
#: The tracker's angles in the order ``motion`` gives them.
NAMES = ("lean", "steer", "pitch_left", "pitch_right")


def motion(t):
    """Smooth made-up angles (rad) of a walker rolling down the ramp: (angles, contact)."""
    w = 2 * np.pi / 0.75  # stride frequency of the toy (rad/s)
    angles = (0.04 * np.sin(w * t), 0.15 * np.cos(w * t), 0.25 * np.sin(w * t), -0.25 * np.sin(w * t))
    return angles, (0.1 + 0.2 * t, 0.0)


#: The compass walker of data/params/compass-3d.toml (SI units).
COMPASS = Params(leg_length=0.5, foot_radius=0.1, foot_lateral_radius=0.1, hip_width=0.1, leg_mass=1.0,
                 axle_mass=0.5, com_offset=(0.0, 0.02, -0.3), inertia=(0.02, 0.02, 0.01, 0.0, 0.0, 0.0),
                 slope=0.03, gravity=9.81)
#: The compass walker's pose in ``compass_scene``.
COMPASS_ANGLES = (0.2, -0.05, -0.25, 0.3)  # steer, lean, pitch_left, pitch_right (rad)


def compass_scene():
    """(camera, ramp rotation, true leg poses {foot: (R, hip)}, corners {foot: {id: (object points,
    pixels)}}) of compass-3d standing at ``COMPASS_ANGLES`` before its default camera."""
    camera = default_camera_for(COMPASS)
    layout = default_layout(COMPASS)
    r_ramp = cv2.Rodrigues(camera.ramp_pose[0].reshape(3, 1))[0]
    t_ramp = camera.ramp_pose[1].reshape(3)
    legs = leg_poses(COMPASS, *COMPASS_ANGLES, "R", (0.2, 0.0))
    corners = {}
    truth = {}
    for name, foot in (("left_leg", "L"), ("right_leg", "R")):
        rot = r_ramp @ legs.rotation[foot]
        hip = r_ramp @ legs.hip[foot] + t_ramp
        truth[foot] = (rot, hip)
        pts = body_points(layout, name)
        corners[foot] = {i: (p, cv2.projectPoints(p, cv2.Rodrigues(rot)[0], hip, camera.matrix,
                                                  camera.distortion)[0].reshape(-1, 2))
                         for i, p in pts.items()}
    return camera, r_ramp, truth, corners


def start_near(truth, tilt=0.03):
    """A start for the joint fit: the true leg poses ``truth`` ({foot: (R, hip)}, as
    ``compass_scene`` gives them) turned by a few degrees (``tilt``, rad) and moved 1 cm."""
    kick = cv2.Rodrigues(np.array([tilt, -tilt, 0.5 * tilt]))[0]
    legs = {f: (kick @ r, h + 0.01) for f, (r, h) in truth.items()}
    return walker_from_legs(legs, 0.08, prefer="R")
