"""``toywalk render``: draw a trajectory as the camera would film the walking toy (tracking.render).

::

    toywalk render T.csv --params P.toml [--camera C.json] [--markers M.json] [--noise LEVEL]
                   [--seed S] [--fps F] [--size WxH] [--duration SEC] [--codec FOURCC]
                   [--engine scene|mujoco] --out V.mp4

Without ``--camera`` the camera frames the walk it is given
(:func:`toywalk.tracking.render.default_filming`): one fixed camera placed for the walker
(:func:`toywalk.tracking.scene.default_camera_for`; for the bundled compass-3d walker and a walk of
a few strides this is ``data/camera/default.json``), moved back to hold a longer walk, or, for a
walk too long for that, a camera that follows the walker down the ramp. Without ``--markers`` the
layout is :func:`toywalk.tracking.markers.default_layout` (``data/markers/default.json`` for that
walker), with ramp markers all along a followed walk. Both are also written next to the video
(``V.camera.json``, ``V.markers.json``). A walker that leaves a given camera's view is filmed partly
out of frame.
"""

from __future__ import annotations

import sys
from pathlib import Path

from .common import CommandError, output_path, parse_size, refuse_overwrite, scuffs_in

__all__ = ["cmd_render", "out_of_view_warning", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("render", help="render a trajectory to a synthetic video with its truth")
    p.add_argument("trajectory", help="trajectory file T.csv")
    p.add_argument("--params", required=True, help="parameter TOML file (the walker drawn)")
    p.add_argument("--camera", help="camera JSON with a ramp_pose (default: placed for the walker)")
    p.add_argument("--markers", help="marker layout JSON (default: the bundled layout for the walker)")
    p.add_argument("--noise", type=int, default=1, help="imperfection preset 0-3 (default 1)")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: drawn and recorded)")
    p.add_argument("--fps", type=float, default=60.0, help="frame rate (default 60)")
    p.add_argument("--size", help="image size WxH (default: the camera's, or 1280x720)")
    p.add_argument("--duration", type=float, default=None, help="seconds to render (default: all)")
    p.add_argument("--codec", default=None, help="FourCC (default mp4v for .mp4, MJPG for .avi)")
    p.add_argument("--engine", choices=("scene", "mujoco"), default="scene",
                   help="renderer: the project's own (scene, default) or MuJoCo's OpenGL one (mujoco)")
    p.add_argument("--out", required=True, help="video file V.mp4 or V.avi")
    p.set_defaults(func=cmd_render)


def cmd_render(args) -> int:
    import math

    import numpy as np
    from toywalk.model.parameters import ParameterError, load_params
    from toywalk.model.trajectory import read_trajectory, trajectory_paths
    from toywalk.tracking.camera import CameraError, load_camera
    from toywalk.tracking.markers import LayoutError, default_layout, load_layout
    from toywalk.tracking.render import RenderError, RenderOptions, default_filming, output_paths, render

    out = output_path(args.out, (".mp4", ".avi"))
    traj_path = Path(args.trajectory)
    if traj_path.suffix != ".csv":
        raise CommandError(f"the trajectory must be a .csv file, got {traj_path}")
    refuse_overwrite(output_paths(out).values(),
                     [*trajectory_paths(traj_path), args.params, args.camera, args.markers])
    if args.noise not in (0, 1, 2, 3):
        raise CommandError(f"--noise must be 0, 1, 2 or 3, got {args.noise}")
    if not (math.isfinite(args.fps) and 0 < args.fps <= 1000):
        raise CommandError(f"--fps must be a frame rate in (0, 1000], got {args.fps}")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise CommandError(f"--duration must be positive seconds, got {args.duration}")
    if args.codec is not None and len(args.codec) != 4:
        raise CommandError(f"--codec must be a four-character code such as mp4v or MJPG, got {args.codec!r}")
    size = parse_size(args.size) if args.size else None
    try:
        params = load_params(args.params)
    except ParameterError as err:
        raise CommandError(str(err).splitlines()[0]) from err
    try:
        table = read_trajectory(traj_path)
    except FileNotFoundError as err:
        raise CommandError(f"trajectory file not found: {traj_path}") from err
    except (ValueError, OSError, UnicodeDecodeError) as err:
        raise CommandError(f"cannot read trajectory: {str(err).splitlines()[0]}") from err
    try:
        options = RenderOptions.preset(args.noise, fps=float(args.fps), duration=args.duration,
                                       codec=args.codec)
    except RenderError as err:
        raise CommandError(str(err).splitlines()[0]) from err
    path = None
    if args.camera:
        try:
            camera = load_camera(args.camera)
        except CameraError as err:
            raise CommandError(str(err).splitlines()[0]) from err
        if size is not None and size != camera.size:
            raise CommandError(f"--size {size[0]}x{size[1]} differs from the camera's image size "
                               f"{camera.width}x{camera.height}; drop --size or use a matching camera")
        if camera.ramp_pose is None:
            raise CommandError(f"camera {args.camera} has no ramp_pose: the renderer needs a fixed camera")
        layout = None
    else:
        try:
            camera, path, layout = default_filming(table, params, *(size or (1280, 720)), options)
        except RenderError as err:
            raise CommandError(str(err).splitlines()[0]) from err
    try:
        if args.markers:
            layout = load_layout(args.markers)
        elif layout is None:
            layout = default_layout(params)
    except LayoutError as err:
        raise CommandError(str(err).splitlines()[0]) from err
    seed = args.seed if args.seed is not None else int(np.random.SeedSequence().entropy % (2**32))
    draw, errors = render, (RenderError,)
    if args.engine == "mujoco":
        from toywalk.tracking.render_mujoco import MujocoUnavailable, render_mujoco
        draw, errors = render_mujoco, (RenderError, MujocoUnavailable)
    try:
        progress = _progress if sys.stderr.isatty() else None
        result = draw(table, params, camera, layout, options, out, rng=seed,
                      source={"trajectory": str(traj_path), "params": str(args.params),
                              "camera": args.camera or "default_filming(trajectory, params)",
                              "markers": args.markers or "default_layout(params)"},
                      progress=progress, path=path)
    except errors as err:
        raise CommandError(str(err).splitlines()[0]) from err
    if progress is not None:
        sys.stderr.write("\n")
    shot = "fixed camera" if path is None else "camera following the walker"
    engine = "" if args.engine == "scene" else " by MuJoCo"
    print(f"rendered {result.n_frames} frames{engine} ({camera.width}x{camera.height}, {options.fps:g} fps, "
          f"noise level {args.noise}, seed {seed}, {shot}) in {result.seconds:.1f} s -> {out}; truth in "
          f"{result.paths['truth'].name}")
    scuffs = scuffs_in(table, params.leg_length)
    if scuffs:  # the video shows the foot in the ramp there
        print(f"note: {scuffs}", file=sys.stderr)
    if result.in_view is not None and np.any(result.in_view < 1):
        print(out_of_view_warning(result.frame_times, result.in_view), file=sys.stderr)
    return 0


def out_of_view_warning(times, in_view) -> str:
    """One line saying in how many frames, and from when to when, the walker is partly or wholly
    outside the image (``in_view``: each frame's share of it inside, shape (n,))."""
    import numpy as np

    times, in_view = np.asarray(times, float), np.asarray(in_view, float)
    partly = np.flatnonzero(in_view < 1)
    gone = int(np.sum(in_view == 0))
    return (f"warning: the walker is not wholly in the camera's view in {len(partly)} of {len(times)} "
            f"frames ({times[partly[0]]:.2f}-{times[partly[-1]]:.2f} s; none of it in {gone}): the "
            "tracker makes frames it cannot measure gaps. Without --camera the camera frames the walk")


def _progress(k: int, n: int) -> None:
    if k == n or k % 10 == 0:
        sys.stderr.write(f"\rframe {k}/{n}")
        sys.stderr.flush()
