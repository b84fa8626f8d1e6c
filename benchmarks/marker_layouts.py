"""Which marker layouts keep both legs well determined when flags are hidden (benchmarks/TRACKING.md,
"Marker layouts").

Usage::

    TOYWALK_CACHE=/tmp/twcache .venv/bin/python benchmarks/marker_layouts.py [--out FILE]

Filmed from one side, the near leg hides the far leg's flags for stretches of every stride. For
each shipped walker (compass-3d, toy-sized and stable-toy, data/params) and each layout

- ``default``: two flags a leg (:func:`toywalk.tracking.markers.default_layout`);
- ``third``: the default two and a third flag a leg on a mast 0.2 leg lengths above the hip
  (there is no room between the two nor below them, above the foot), turned 60 degrees towards
  the camera instead of 25 (so not parallel to either other flag): ``default_layout(params,
  third_flag=True)``;

it simulates 2 s of walking, renders it at noise level 1 (60 frames/s, seeds 100-102)
with flags painted over in three patterns

- ``none``: nothing hidden;
- ``one``: in turn for 12 frames each, the left leg's lower flag, the right leg's upper flag,
  nothing (as ``tests/tracking/test_occluded_leg.py``);
- ``both``: both of those at once for 12 frames, then nothing for 12;

tracks it with the render's camera and layout (no smoothing across frames: each frame's own
joint fit), and reports for each leg, over the frames in which one of its flags is hidden (all
frames for ``none``): frames tracked, RMS error of lean, steer and the leg's pitch (deg) and the
RMS of error over stated SD. Writes ``benchmarks/results/marker_layouts.json`` atomically. About 4
minutes on an idle 2-core machine.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TOYWALK = str(Path(sys.executable).with_name("toywalk"))
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")
WALKERS = {"compass-3d": 4, "toy-sized": 6, "stable-toy": 26}  # steps simulated (over 2 s)
STRETCH = 12  # frames a flag stays hidden
#: the flag hidden on each leg (default_layout's ids): the left leg's lower, the right leg's upper
HIDE = {"L": 1, "R": 2}
PATTERNS = {
    "none": lambda k: {},
    "one": lambda k: [{"L": HIDE["L"]}, {"R": HIDE["R"]}, {}][(k // STRETCH) % 3],
    "both": lambda k: [dict(HIDE), {}][(k // STRETCH) % 2],
}


def _layouts(params) -> dict:
    """The layouts compared (see the module docstring)."""
    from toywalk.tracking.markers import default_layout

    return {"default": default_layout(params), "third": default_layout(params, third_flag=True)}


def _case(table, params, layout, pattern, seed: int, folder: Path) -> dict:
    from toywalk.tracking.render import Filming, RenderOptions
    from toywalk.tracking.scene import default_camera_for
    from toywalk.tracking.track import track_video

    camera = default_camera_for(params)
    hide = PATTERNS[pattern]
    film = Filming(table, params, camera, layout, RenderOptions.preset(1, duration=2.0), seed,
                   hidden=lambda k: hide(k).values())
    video = folder / "v.mp4"
    truth = film.write_video(video)
    result, _ = track_video(video, camera, layout)
    n = len(truth)
    out = {"frames": n}
    for foot, pitch in (("L", "pitch_left"), ("R", "pitch_right")):
        frames = np.array([foot in hide(k) for k in range(n)]) if pattern != "none" else np.ones(n, bool)
        # tracked: the frames counted in which this leg has a pose (its pitch is finite; lean and
        # steer are finite whenever either leg has one)
        leg = {"frames": int(frames.sum()), "tracked": int(np.isfinite(result.raw[pitch][frames]).sum())}
        for name in ("lean", "steer", pitch):
            err = np.degrees(result.raw[name] - truth[:, SIGNALS.index(name)])[frames]
            sd = np.degrees(result.raw_sd[name])[frames]
            ok = np.isfinite(err) & np.isfinite(sd)
            key = "pitch" if name == pitch else name
            leg[f"{key}_rms_deg"] = float(np.sqrt(np.mean(err[ok] ** 2))) if ok.any() else None
            leg[f"{key}_z_rms"] = float(np.sqrt(np.mean((err[ok] / sd[ok]) ** 2))) if ok.any() else None
        out[foot] = leg
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "marker_layouts.json"))
    args = parser.parse_args(argv)
    from toywalk.model.files import atomic_write_json
    from toywalk.model.parameters import load_params
    from toywalk.model.trajectory import read_trajectory

    start = time.perf_counter()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for w, (walker, steps) in enumerate(WALKERS.items()):
            params_path = ROOT / "data" / "params" / f"{walker}.toml"
            r = subprocess.run([TOYWALK, "simulate", "--params", str(params_path), "--steps", str(steps),
                                "--out", str(folder / "walk.csv")], capture_output=True, text=True)
            if r.returncode != 0:
                print(r.stderr, file=sys.stderr)
                return 1
            params, table = load_params(params_path), read_trajectory(folder / "walk.csv")
            for name, layout in _layouts(params).items():
                for pattern in PATTERNS:
                    case = _case(table, params, layout, pattern, 100 + w, folder)
                    results.setdefault(walker, {}).setdefault(name, {})[pattern] = case
                    legs = " | ".join(
                        f"{f}: {case[f]['tracked']}/{case[f]['frames']} lean {case[f]['lean_rms_deg']:.3f} "
                        f"steer {case[f]['steer_rms_deg']:.3f} pitch {case[f]['pitch_rms_deg']:.3f} "
                        f"z {case[f]['pitch_z_rms']:.2f}" for f in "LR")
                    print(f"{walker:10s} {name:8s} {pattern:5s} {legs}", flush=True)
    atomic_write_json(args.out, {"walkers": results, "stretch_frames": STRETCH, "hidden_ids": HIDE,
                                 "run_seconds": time.perf_counter() - start})
    print(f"wrote {args.out} in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
