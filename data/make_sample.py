"""Make data/sample/: the demo's video of a walker with an effect the analysis is not told about.

    .venv/bin/python data/make_sample.py

The walker is data/params/clearing-toy.toml (it cannot stand, walks stably and clears its swing
foot) with one effect of the library switched on (``HIDDEN``): its balance masses sit unequally far
out, the left one 0.46 mm further and the right one 0.46 mm nearer than the nominal 185.5 mm
(``asymmetry`` 0.005, a builder's millimetre), so that it walks a gait that repeats every stride, not
every step, and turns slowly. Why this effect: on this walker the trailing foot's share of the
heel-strike impulse, the other candidate tried (0.03), changes the gait along the same direction
as a 0.13 mm shift of the legs' centre of mass backward, and the analysis rightly calls the two
indistinguishable from a walk on its cycle (chi-square 3586 against 3584); an uneven build leaves
a left-right signature that no symmetric parameter can mimic. Its gait is simulated for ``STEPS``
steps from the fixed point, sampled at 5 kHz (the renderer interpolates between samples: at
``simulate``'s default spacing the walker drawn departs from the model by up to 1.7 mrad), filmed by
``toywalk render`` at ``FPS`` frames/s with noise level 1 (sensor noise, motion blur, flicker,
MPEG-4) by the default camera, which follows the walker as a person panning would. Why 60
frames/s: a phone's ordinary rate, 11 frames a step of this walker, and a file under 5 MB (OpenCV's
MPEG-4 writer has no quality setting and spends about 27 kB a frame on the sensor noise: at 120
frames/s the video was 9.3 MB; tracked and analysed alike, ``docs/diagnosis.md``).

Written into data/sample/:

- ``walk.mp4``: the video; ``walk.camera.json`` its camera's lens (the ramp pose is measured from
  the ramp markers in every frame); ``walk.markers.json`` the marker layout;
- ``calibration/view-NN.jpg``: ``VIEWS`` views of the default ChArUco board (7 x 5 squares of
  40 mm) through the same lens, as a person calibrating the camera would take them
  (``toywalk.tracking.calibrate.board_views``, JPEG quality 92); ``toywalk calibrate`` recovers
  the lens from them;
- ``walker.toml``: the parameter file a builder would write from measurements, the walker's
  geometry and masses with the foot radius and the balance mass's sideways offset measured a few
  per cent off (``MEASURED``), no effects: the demo's base model;
- ``truth.toml``: the parameters the video was made with, the effect included; the demo reads it
  only after its analysis, to compare.

Every number here is recorded in data/README.md with the files' hashes.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params, save_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, write_trajectory
from toywalk.tracking.calibrate import board_views
from toywalk.tracking.camera import load_camera

DATA = Path(__file__).resolve().parent
#: The effect hidden in the video and its strength.
HIDDEN = {"effects.asymmetry": 0.005}
#: The builder's measurements of the two quantities the demo fits (the truth: 10.66 mm, 185.5 mm).
MEASURED = {"foot_radius": 0.0110, "com_offset[1]": 0.1880}
STEPS = 16
FPS = 60
SEED = 2026
SAMPLE_RATE = 5000.0
VIEWS = 8


def main() -> int:
    out = DATA / "sample"
    out.mkdir(exist_ok=True)
    base = load_params(DATA / "params" / "clearing-toy.toml")
    truth = base.replace(**HIDDEN)
    gait = find_gait(truth)
    print(f"truth's gait: step {gait.step_time:.4f} s, max |eigenvalue| {gait.max_abs_eigenvalue:.3f}, "
          f"clearance {1e3 * gait.clearance:.2f} mm", flush=True)
    traj = simulate(truth, gait.fixed_point, STEPS, sample_rate=SAMPLE_RATE)
    if traj.status != "completed":
        print(f"the walk did not complete: {traj.message}", file=sys.stderr)
        return 1
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right,
               "contact_x": traj.contact[:, 0], "contact_y": traj.contact[:, 1]}
    events = [{"time": e.time, "foot": e.foot, "x": e.x, "y": e.y} for e in traj.events]
    header = ("The parameters data/sample/walk.mp4 was made with (data/make_sample.py): "
              "data/params/clearing-toy.toml with " + ", ".join(f"{k} = {v}" for k, v in HIDDEN.items())
              + ".\nThe demo reads this only after its analysis, to compare.")
    save_params(truth, out / "truth.toml", header=header)
    measured = base.replace(**MEASURED)
    save_params(measured, out / "walker.toml", header=(
        "The sample walker as a builder would measure it (data/make_sample.py): the geometry and "
        "masses of\ndata/params/clearing-toy.toml, the foot radius and the balance mass's sideways "
        "offset measured\na few per cent off, no effects. The demo's base model."))
    with tempfile.TemporaryDirectory() as tmp:
        walk = Path(tmp) / "simulated.csv"
        write_trajectory(TrajectoryTable(traj.times, signals, traj.stance, events, {}), walk)
        video = Path(tmp) / "walk.mp4"
        subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", "render", str(walk), "--params",
                        str(out / "truth.toml"), "--noise", "1", "--seed", str(SEED), "--fps",
                        str(FPS), "--out", str(video)], check=True)
        shutil.copy(video, out / "walk.mp4")
        for name in ("walk.markers.json", "walk.json", "walk.truth.csv", "walk.truth.events.csv"):
            shutil.copy(Path(tmp) / name, out / name)
        camera = json.loads((Path(tmp) / "walk.camera.json").read_text())
        camera.pop("ramp_pose", None)  # a lens, as a calibration gives it
        (out / "walk.camera.json").write_text(json.dumps(camera, indent=2) + "\n")
    views = out / "calibration"
    shutil.rmtree(views, ignore_errors=True)
    views.mkdir()
    for k, image in enumerate(board_views(load_camera(out / "walk.camera.json"), VIEWS, seed=SEED), 1):
        cv2.imwrite(str(views / f"view-{k:02d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 92])
    return 0


if __name__ == "__main__":
    sys.exit(main())
