"""``toywalk calibrate IMAGE... --out C.json``: camera calibration from ChArUco board views."""

from __future__ import annotations

from pathlib import Path

from .common import CommandError, output_path

__all__ = ["cmd_calibrate", "register"]


def register(subparsers) -> None:
    p = subparsers.add_parser("calibrate", help="calibrate the camera from images of a ChArUco board")
    p.add_argument("images", nargs="+", metavar="IMAGE", help="views of the board")
    p.add_argument("--out", required=True, help="camera file C.json to write")
    p.add_argument("--squares", default="7x5", help="board squares, COLSxROWS (default 7x5)")
    p.add_argument("--square-length", type=float, default=None, help="square side (m), default 0.04")
    p.add_argument("--marker-length", type=float, default=None, help="marker side (m), default 0.03")
    p.add_argument("--dictionary", default=None, help="ArUco dictionary, default DICT_4X4_50")
    p.add_argument("--max-rms", type=float, default=1.0, help="refuse above this RMS error (px)")
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> int:
    from toywalk.tracking.calibrate import (
        DEFAULT_BOARD,
        BoardSpec,
        CalibrationError,
        calibrate,
        save_calibration,
    )

    out = output_path(args.out, (".json",))
    for image in args.images:
        if not Path(image).is_file():
            raise CommandError(f"not an image file: {image}" if Path(image).exists() else
                               f"image not found: {image}")
    try:
        sx, sy = (int(v) for v in args.squares.lower().split("x"))
        board = BoardSpec(squares=(sx, sy),
                          square_length=args.square_length or DEFAULT_BOARD.square_length,
                          marker_length=args.marker_length or DEFAULT_BOARD.marker_length,
                          dictionary=args.dictionary or DEFAULT_BOARD.dictionary)
    except ValueError as err:
        raise CommandError(f"bad board description: {err}") from err
    try:
        result = calibrate(args.images, board, max_rms=args.max_rms)
    except CalibrationError as err:
        raise CommandError(str(err)) from err
    save_calibration(result, out)
    k = result.camera.matrix
    print(f"calibrated from {len(result.used)} of {len(args.images)} views ({result.n_corners} corners): "
          f"RMS {result.rms:.3f} px, fx {k[0, 0]:.1f} fy {k[1, 1]:.1f} cx {k[0, 2]:.1f} "
          f"cy {k[1, 2]:.1f} -> {out}")
    return 0
