"""``toywalk track V.mp4 [--camera C.json] [--markers M.json] [--accuracy A.json] --out M.csv
[--overlay O.mp4]``.

Writes the trajectory files of the raw per-frame estimates (``M.csv``, ``M.events.csv``,
``M.json``: the input of ``fit``, errors independent from frame to frame) and of their smoothed
copy (``M.smoothed.csv`` and its companions), and optionally an overlay video with the detected
markers and each body's axes.

The ramp pose is measured from the ramp markers in the video (tracking/ramp.py). Without
``--camera`` the bundled camera's intrinsics are used, read out at the video's size where that
differs with the same aspect ratio, and its ramp pose is not (it is where ``render`` puts the
camera for the bundled walker, not where a user's camera stands); a camera file
given with a ``ramp_pose`` has it checked against the markers and refused, in one line naming the
angle, if they disagree. With ``--accuracy`` (from ``toywalk accuracy``) both files carry the
tracker's errors by phase of the step (tracking/accuracy_phase.py). Without ``--markers`` the
layout is the one ``render`` wrote beside the video (``V.markers.json``) if there is one, else
the bundled layout. ``M.json`` and the summary
line say which ramp pose, camera and layout were used.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import sys
from pathlib import Path

from toywalk.model.files import DATA_DIR as _DATA
from toywalk.model.files import software_version, strict_json

from .common import CommandError, output_path, refuse_overwrite

__all__ = ["cmd_track", "register"]



def register(subparsers) -> None:
    p = subparsers.add_parser("track", help="extract the walker's angles and heel strikes from a video")
    p.add_argument("video", help="video file (e.g. from toywalk render)")
    p.add_argument("--camera", default=None,
                   help="camera file; a ramp_pose in it is checked against the ramp markers (default: "
                        "the intrinsics of data/camera/default.json, scaled to the video's size, "
                        "the ramp pose measured)")
    p.add_argument("--markers", default=None,
                   help="marker layout (default: V.markers.json beside the video if render wrote "
                        "one, else data/markers/default.json)")
    p.add_argument("--out", required=True, help="trajectory file NAME.csv")
    p.add_argument("--overlay", default=None, help="write a video with detections drawn (.mp4)")
    p.add_argument("--hip-width", type=float, default=None,
                   help="distance between the legs' hip points along the axle (m); default: from "
                        "--params, else estimated from the video")
    p.add_argument("--params", default=None,
                   help="parameter TOML file of the walker filmed (only its hip_width is used)")
    p.add_argument("--exposure", default=None, metavar="SECONDS",
                   help="how long the shutter was open for each frame, as the camera states it "
                        "(1/150, or 0.0067 s): written to M.json as exposure_s, so that fit, sample "
                        "and diagnose read the model's mean over it (default: not stated, each frame "
                        "read at its time)")
    p.add_argument("--accuracy", default=None, metavar="A.json",
                   help="the tracker's errors by phase of the step, from toywalk accuracy on renders of "
                        "this walker filmed alike: carried as errors shared by phase and wider SDs "
                        "(the values left as tracked), so that "
                        "fit and diagnose take them for errors, not physics (default: not carried)")
    p.add_argument("--full-search", action="store_true",
                   help="search the whole frame every time instead of around predicted markers (slower)")
    p.set_defaults(func=cmd_track)


def _exposure(text: str | None) -> float | None:
    """``--exposure``: seconds, written as a number or as the fraction a camera shows (1/150)."""

    if text is None:
        return None
    num, slash, den = text.partition("/")
    try:
        value = float(num) / float(den) if slash else float(text)
    except (ValueError, ZeroDivisionError) as err:
        raise CommandError(f"--exposure must be seconds, e.g. 1/150 or 0.0067, got {text!r}") from err
    if not (math.isfinite(value) and value > 0):
        raise CommandError(f"--exposure must be a positive time in seconds, got {text!r}")
    return value


def _render_exposure(video: Path) -> tuple[float | None, str | None]:
    """The shutter time of a video ``render`` made, from the metadata it wrote beside it
    (``V.json``: the shutter open ``exposure`` of a frame interval where frames are blurred, a
    sharp frame an instant): (seconds, where from), or (None, None) for any other video."""
    import json

    from toywalk.tracking.render import output_paths

    path = output_paths(video)["metadata"]
    try:
        meta = json.loads(path.read_text())
        options = meta["options"]
        fraction, fps = float(options["exposure"]), float(options["fps"])
        blurred = meta["motion_blur"] is not None
    except (OSError, ValueError, KeyError, TypeError):
        return None, None
    if not (math.isfinite(fraction) and math.isfinite(fps) and 0 <= fraction <= 1 and fps > 0):
        return None, None
    return (fraction / fps if blurred else 0.0), f"{path.name}, written by render beside the video"


def _seconds(value: float) -> str:
    """A shutter time as a camera shows it: 1/150 s, else seconds."""
    if value > 0 and abs(1 / value - round(1 / value)) < 1e-6 * (1 / value):
        return f"1/{round(1 / value)} s"
    return f"{value:.4g} s"


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _default(given, kind: str, name: str) -> Path:
    if given is not None:
        return Path(given)
    path = _DATA / kind / name

    if not path.exists():
        raise CommandError(f"no --{'camera' if kind == 'camera' else 'markers'} given and the bundled "
                           f"default {path} is missing")
    return path


def _layout_path(given, video: Path) -> tuple[Path, str]:
    """The marker layout file and where it came from: --markers, the layout render wrote beside
    the video, or the bundled default."""
    if given is not None:
        return Path(given), "--markers"
    from toywalk.tracking.render import output_paths

    beside = output_paths(video)["markers"]
    if beside.is_file():
        return beside, "written by render beside the video"
    return _default(None, "markers", "default.json"), "bundled default"


def _bundled_lens(camera, video: Path):
    """The bundled camera's lens for ``video``, without its placement; how it is used (for
    ``M.json``); and what the summary line says of it (empty: nothing). Read out at the video's
    size where that differs with the same aspect ratio (``render --size`` films with that lens
    so; a phone's video modes are, to the calibration's accuracy, only where the mode does not
    crop)."""
    from toywalk.tracking.camera import CameraError
    from toywalk.tracking.video import declared_size

    camera = dataclasses.replace(camera, ramp_pose=None)
    size = declared_size(video)
    if size is None or size == camera.size:
        return camera, "bundled default: intrinsics only", ""
    try:
        scaled = camera.at_size(*size)
    except CameraError as err:
        raise CommandError(f"the video is {size[0]}x{size[1]} pixels and no --camera was given: the "
                           f"bundled lens ({camera.width}x{camera.height}) does not fit its aspect "
                           "ratio; calibrate the camera in this video mode (toywalk calibrate) and "
                           "pass --camera") from err
    return (scaled, f"bundled default: intrinsics only, scaled from {camera.width}x{camera.height} to "
            f"{size[0]}x{size[1]}", f"lens: the bundled one scaled to {size[0]}x{size[1]} (your camera's: "
            "calibrate, --camera); ")


def _phase_errors(path, video: Path):
    """The ``--accuracy`` file read (None without one); a frame rate other than the calibration's
    is refused: the tracker's errors by phase depend on the frames a step has."""
    if path is None:
        return None
    from toywalk.tracking.accuracy_phase import AccuracyError, load_phase_errors
    from toywalk.tracking.video import declared_fps

    try:
        errors = load_phase_errors(path)
    except AccuracyError as err:
        raise CommandError(str(err)) from err
    fps, measured = declared_fps(video), errors.source.get("fps")
    if fps and measured and abs(fps / float(measured) - 1) > 0.01:
        raise CommandError(f"--accuracy {path} was measured at {float(measured):g} frames/s and the video "
                           f"has {fps:g}: measure it again with toywalk accuracy --like {video}")
    return errors


def cmd_track(args) -> int:
    from toywalk.model.trajectory import trajectory_paths, write_trajectory
    from toywalk.tracking.camera import CameraError, load_camera
    from toywalk.tracking.events import legs_passing
    from toywalk.tracking.markers import LayoutError, load_layout
    from toywalk.tracking.ramp import RampPoseError
    from toywalk.tracking.track import TrackError, track_video

    video = Path(args.video)
    out = output_path(args.out, (".csv",))
    overlay = Path(args.overlay) if args.overlay else None
    if overlay is not None and (overlay.suffix.lower() != ".mp4" or not overlay.parent.exists()):
        raise CommandError(f"--overlay must name a .mp4 file in an existing folder, got {overlay}")
    if not video.is_file():
        raise CommandError(f"not a video file: {video}" if video.exists() else
                           f"video file not found: {video}")
    from toywalk.tracking.render import output_paths

    smooth_path = out.with_name(out.stem + ".smoothed.csv")
    # the video's own files too (the metadata render wrote beside it holds its shutter time)
    refuse_overwrite([*trajectory_paths(out), *trajectory_paths(smooth_path), overlay],
                     [p for p in (*output_paths(video).values(), args.camera, args.markers, args.params)
                      if p is not None and Path(p).exists()])
    hip_width = args.hip_width
    if hip_width is not None and not (math.isfinite(hip_width) and hip_width >= 0):
        raise CommandError(f"--hip-width must be a length >= 0 (m), got {hip_width}")
    if hip_width is None and args.params is not None:
        from toywalk.model.parameters import load_params

        try:
            hip_width = float(load_params(args.params).hip_width)
        except (OSError, ValueError) as err:
            raise CommandError(f"cannot read --params {args.params}: {str(err).splitlines()[0]}") from err
    exposure, exposure_from = _exposure(args.exposure), "--exposure"
    if exposure is None:
        exposure, exposure_from = _render_exposure(video)
    else:
        from toywalk.tracking.video import declared_fps

        fps = declared_fps(video)
        if fps and exposure > (1 + 1e-9) / fps:  # checked before tracking writes the overlay
            raise CommandError(f"--exposure {args.exposure} is longer than the frame interval (1/{fps:.4g} "
                               "s): a shutter cannot stay open beyond it")
    camera_path = _default(args.camera, "camera", "default.json")
    markers_path, markers_from = _layout_path(args.markers, video)
    phase_errors = _phase_errors(args.accuracy, video)
    try:
        camera = load_camera(camera_path)
        lens, lens_said = "as given", ""
        if args.camera is None:  # the bundled camera's lens, not its placement
            camera, lens, lens_said = _bundled_lens(camera, video)
        layout = load_layout(markers_path)
        result, source = track_video(video, camera, layout, overlay=overlay, roi=not args.full_search,
                                     hip_width=hip_width)
    except (CameraError, LayoutError, TrackError, RampPoseError) as err:
        raise CommandError(str(err)) from err
    n = len(result.time)
    gaps = {k: int(sum(1 for v in result.raw[k] if math.isnan(v))) for k in result.raw}
    metadata = {
        "source": {"kind": "video", "video": str(video), "sha256": _sha256(video),
                   "frames": n, "width": source.width, "height": source.height,
                   "nominal_fps": source.nominal_fps},
        "timestamps": result.timestamps["description"],
        "timestamp_policy": result.timestamps,
        "units": {"time": "s", "angles": "rad", "sd": "rad"},
        "camera": {"file": str(camera_path),
                   "use": lens,
                   **camera.to_dict()},
        "markers": {"file": str(markers_path), "from": markers_from, "dictionary": layout.dictionary,
                    "description": layout.description},
        "ramp_pose": result.ramp,
        "pixel_sd": result.pixel_sd,
        "leg_noise": strict_json(result.noise),  # an infinite prior_dof (frames alike): null
        "frames_with_leg": result.frames_with,
        "gaps": gaps,
        "search": result.counts,
        "pose_method": "both legs fitted jointly to all visible leg-marker corners, sharing the hip "
                       "axis (steer, lean) with hip points hip_width apart (tracking/joint.py); "
                       "frames whose angles jump away from both neighbouring stretches are gaps",
        "hip_width": {"value_m": result.hip_width, "source": result.hip_width_source},
        "sd_method": "joint-fit covariance (J^T J)^-1 J^T S J (J^T J)^-1 with S each corner's variance, "
                     "its marker's pixel SD pooled over the video from the reprojection residuals "
                     "(leg_noise.marker_pixel_sd), times each frame's noise scale: its residual "
                     "moderated by all frames' (empirical Bayes; with fewer than 10 frames, its residual "
                     "ratio where above 1: leg_noise.frame_scale.method), never under 0.02 px; "
                     "propagated to "
                     "the angles; the ramp pose's error added where each frame has its own (a moving "
                     "camera), else stated in ramp_pose.sd_deg (one bias common to all frames)",
        "events_method": "kink (rate jump) in both leg pitches, continuous piecewise-quadratic "
                         "breakpoint fit; the leading leg strikes; contact position unknown",
        "software": software_version(),
    }
    if exposure is not None:
        metadata["exposure_s"] = exposure
        metadata["exposure"] = (f"the shutter open for exposure_s seconds centred on each frame's time "
                                f"({exposure_from}): each sample is the angles' mean over it")
    raw_meta = {**metadata, "signals": "raw per-frame estimates",
                "smoothed_copy": smooth_path.name}
    smooth_meta = {**metadata, "signals": f"smoothed: {result.smoothing}, over stretches without gaps "
                                          "or heel strikes; sd scaled by the filter's noise gain"}
    raw, smooth = result.table(metadata=raw_meta), result.table(smoothed=True, metadata=smooth_meta)
    if phase_errors is not None:
        raw, smooth = (phase_errors.apply(t, note=str(args.accuracy)) for t in (raw, smooth))
    write_trajectory(smooth, smooth_path)
    try:
        write_trajectory(raw, out)
    except BaseException:
        for p in trajectory_paths(smooth_path):
            p.unlink(missing_ok=True)
        raise
    both = sum(1 for i in range(n) if not (math.isnan(result.raw["pitch_left"][i])
                                           or math.isnan(result.raw["pitch_right"][i])))
    print(f"tracked {n} frames ({both} with both legs), {len(result.events)} heel strikes; "
          f"ramp pose: {result.ramp['source']}; {lens_said}markers: {markers_path.name} ({markers_from}); "
          + (f"exposure {_seconds(exposure)} ({exposure_from})" if exposure is not None else
             "exposure not stated, each frame read at its time (--exposure)") + f" -> {out}")
    if phase_errors is not None:
        from .accuracy import describe_phase_errors

        print(f"tracker errors carried from {args.accuracy}: {describe_phase_errors(phase_errors)}")
    passings = legs_passing(result.raw["pitch_left"], result.raw["pitch_right"])
    # The strikes found against the legs' passings, once a step (one fewer or more at the walk's
    # ends, and one more where a strike falls in a gap): more missing means missed strikes.
    missed = len(result.events) < passings - 2
    if n and (both < 0.9 * n or len(result.events) < 3 or missed):
        # The files are written (a user may still want the angles), but fit and diagnose need
        # both legs and heel strikes, at least three: say so now, with the likely cause.
        print(f"toywalk track: warning: a leg was lost in {n - both} of {n} frames and "
              f"{len(result.events)} heel strikes were found (fit needs 3) where the legs passed "
              f"each other {passings} times (once a step); fast legs blur at low frame rates or "
              "long exposures: film at 120 frames/s or more, or check the overlay (--overlay)",
              file=sys.stderr)
    return 0
