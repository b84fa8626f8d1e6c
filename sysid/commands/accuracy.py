"""``toywalk accuracy --params P.toml [--like V.mp4] --out A.json``: the tracker's errors by phase
of the step, measured on renders of the walker (tracking/accuracy_phase.py).

The walker's gait (from P.toml) is rendered ``--walks`` times as the video was filmed (``--like``
reads its frame rate and size, and, where ``render`` made it, its noise level and marker layout;
options given override them), on ramps a little shallower and steeper in turn, each render tracked
back and compared with its truth. The result, A.json, is read by ``toywalk track V.mp4 --accuracy
A.json``, which carries the tracker's bias by phase of the step as an error shared by that phase
of every step and widens the SDs. The rendered
videos stay in ``A.walks/`` beside A.json, the calibration's evidence.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from toywalk.model.files import software_version

from .common import CommandError, load_walker, output_path, parse_size, refuse_overwrite, say

__all__ = ["cmd_accuracy", "describe_phase_errors", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("accuracy", help="measure the tracker's errors by phase of the step on "
                                               "renders of the walker (for track --accuracy)")
    p.add_argument("--params", required=True, metavar="P.toml",
                   help="parameter TOML file of the walker filmed")
    p.add_argument("--like", metavar="V.mp4", help="film as this video was filmed: its frame rate and size, "
                                                   "and render's noise level and markers beside it")
    p.add_argument("--fps", type=float, default=None, help="frame rate (default: --like's, else 120)")
    p.add_argument("--noise", type=int, default=None,
                   help="render's imperfection preset 0-3 (default: --like's where render made it, else 1)")
    p.add_argument("--size", default=None, help="image size WxH (default: --like's, else 1280x720)")
    p.add_argument("--camera", default=None,
                   help="camera JSON with a ramp_pose (default: placed for the walk as render places it)")
    p.add_argument("--markers", default=None,
                   help="marker layout JSON (default: --like's V.markers.json, else the walker's default)")
    p.add_argument("--walks", type=int, default=5,
                   help="renders, each with its own noise seed, on ramps 5 and 10 %% either side of the "
                        "walker's (default 5; about a minute each)")
    p.add_argument("--steps", type=int, default=16, help="steps of each walk (default 16)")
    p.add_argument("--seed", type=int, default=0, help="first render's noise seed (default 0)")
    p.add_argument("--engine", choices=("scene", "mujoco"), default="scene",
                   help="renderer, as render --engine: the project's own (scene, default) or MuJoCo's")
    p.add_argument("--out", required=True, metavar="A.json", help="tracker-error file to write")
    p.set_defaults(func=cmd_accuracy)


def _like(video: Path) -> dict:
    """What ``--like`` says of the filming: fps, size, and render's noise level and layout file."""
    from toywalk.tracking.render import output_paths
    from toywalk.tracking.video import TrackError, declared_fps, declared_size

    if not video.is_file():
        raise CommandError(f"--like: video file not found: {video}")
    try:
        found = {"fps": declared_fps(video), "size": declared_size(video)}
    except (TrackError, OSError) as err:
        raise CommandError(f"--like: {str(err).splitlines()[0]}") from err
    beside = output_paths(video)
    try:
        found["noise"] = int(json.loads(beside["metadata"].read_text())["options"]["level"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    if beside["markers"].is_file():
        found["markers"] = beside["markers"]
    return found


def describe_phase_errors(errors) -> str:
    """One sentence: the largest bias and where, and the heel strikes' time_sd factor."""
    big = errors.largest()
    name, worst = max(big.items(), key=lambda kv: abs(kv[1]["bias"]))
    side = "left" if worst["foot"] == "L" else "right"
    return (f"largest bias {math.degrees(worst['bias']):+.3f} deg (walk to walk "
            f"{math.degrees(worst['sd']):.3f}) in {name} at {worst['phase']:.2f} of a {side}-stance step; "
            f"heel-strike time_sd times {errors.timing_scale['L']:.2f} (left strikes) and "
            f"{errors.timing_scale['R']:.2f} (right)")


def cmd_accuracy(args) -> int:
    from toywalk.model.files import atomic_write_text
    from toywalk.tracking.accuracy_phase import AccuracyError, measure_by_rendering
    from toywalk.tracking.camera import CameraError, load_camera
    from toywalk.tracking.markers import LayoutError, load_layout

    out = output_path(args.out, (".json",))
    folder = out.with_name(out.stem + ".walks")
    refuse_overwrite([out], [args.params, args.like, args.camera, args.markers])
    if folder.exists():
        raise CommandError(f"{folder} exists (the calibration's videos go there): remove it or choose "
                           "another --out")
    if not 1 <= args.walks <= 50 or not 3 <= args.steps <= 200:
        raise CommandError(f"--walks must be 1-50 and --steps 3-200, got {args.walks} and {args.steps}")
    like = _like(Path(args.like)) if args.like else {}
    fps = args.fps if args.fps is not None else like.get("fps") or 120.0
    if not (math.isfinite(fps) and 0 < fps <= 1000):
        raise CommandError(f"--fps must be a frame rate in (0, 1000], got {fps}")
    noise = args.noise if args.noise is not None else like.get("noise", 1)
    if noise not in (0, 1, 2, 3):
        raise CommandError(f"--noise must be 0, 1, 2 or 3, got {noise}")
    size = parse_size(args.size) if args.size else like.get("size") or (1280, 720)
    params = load_walker(args.params)
    try:
        camera = load_camera(args.camera) if args.camera else None
        markers = args.markers or like.get("markers")
        layout = load_layout(markers) if markers else None
    except (CameraError, LayoutError) as err:
        raise CommandError(str(err).splitlines()[0]) from err
    if camera is not None and camera.ramp_pose is None:
        raise CommandError(f"camera {args.camera} has no ramp_pose: the renders need a placed camera")
    say(f"rendering and tracking {args.walks} walk(s) of {args.steps} steps ({fps:g} fps, "
        f"{size[0]}x{size[1]}, noise level {noise}) into {folder}; about a minute each")
    try:
        errors = measure_by_rendering(params, folder, walks=args.walks, steps=args.steps, fps=fps,
                                      noise=noise, size=size, camera=camera, layout=layout, seed=args.seed,
                                      hip_width=float(params.hip_width), engine=args.engine,
                                      progress=lambda k, n: say(f"walk {k} of {n} tracked"))
    except AccuracyError as err:
        raise CommandError(str(err)) from err
    data = errors.to_json()
    data["source"].update({"params": str(args.params), "like": args.like, "camera_file": args.camera,
                           "markers_file": str(markers) if markers else None})
    data["software"] = software_version()
    atomic_write_text(out, json.dumps(data, indent=2) + "\n")
    print(f"measured the tracker on {errors.walks} walk(s), {errors.bins} phase bins a step, "
          f"{errors.strikes} heel strikes: {describe_phase_errors(errors)} -> {out}; use: toywalk track "
          f"VIDEO --accuracy {out}")
    if errors.walks < 3:
        print("toywalk accuracy: note: with fewer than 3 walks the bias's SE rests on the samples' scatter "
              "alone, not on the walks' spread", file=sys.stderr)
    return 0
