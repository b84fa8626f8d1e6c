"""How the tracked corners of the leg flags err, against the renderer's true corners, and what that
does to the stated SDs of the angles (benchmarks/TRACKING.md, "One marker on a leg", issue 14).

Usage::

    TOYWALK_CACHE=/tmp/twcache .venv/bin/python benchmarks/corner_errors.py [--seeds 1,2,3,4] \
        [--lossless] [--out FILE]

For the toy-sized walker (data/params/toy-sized.toml, 6 steps, 2 s) and each render seed it renders
the clip of ``tests/tracking/test_occluded_leg.py`` at noise level 1 (in turn for 12 frames each:
the left leg's lower flag hidden, the right leg's upper flag hidden, nothing hidden), tracks it with
the render's camera and layout, and compares each leg flag's corners in each frame with the true
ones (the flag's corners projected at the walker's state, averaged over the renders the frame's
shutter averages). ``--lossless`` writes the frames losslessly (FFV1) instead of as MPEG-4, to
separate the codec's share. Reported:

- ``modes``: each flag's corner errors (pixels) in its own image axes (along its top edge and
  across), resolved on an orthonormal basis of the eight corner coordinates: translation along and
  across, rotation, scale, and four others (shear and perspective); the variance of each, robustly
  (median of squares over that of a chi-square on one degree of freedom), over the flag's pooled SD
  squared (``TrackResult.noise``). Independent corner noise of that SD gives 1 for every mode.
- ``translation_correlation``: the correlation over frames of two flags' mean corner errors (image
  u with u, v with v), for each pair of flags, over the frames whose residual is at most 3 times its
  expectation (a flag the cover spoils where it overlaps the other leg's dominates otherwise).
- ``cases``: for each leg and the number of its flags the fit used (1 or 2), over the frames whose
  residual is at most 3 times its expectation: the RMS of the pitch error (each frame's own joint
  fit) over its SD from independent corner noise of the pooled SDs, unscaled (``z``); and the same
  error split into each flag's contribution (the fit's linear gain times that flag's corner
  errors): the RMS of the root of the sum of the contributions squared over the stated variance
  (``z_without_cross_terms``), and the same with each flag's contribution split further into its
  modes' (``z_modes_alone``). The first differs from ``z`` by the covariance of different flags'
  contributions, the second by that of one flag's modes too.
  The linearisation itself is checked: ``linear_error_correlation``, the correlation of the
  linearised error with the fit's actual error.

Writes ``benchmarks/results/corner_errors.json`` (``--lossless``: ``corner_errors_lossless.json``)
atomically. About a minute on an idle 2-core machine.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TOYWALK = str(Path(sys.executable).with_name("toywalk"))
STRETCH = 12  # frames a flag stays hidden, as tests/tracking/test_occluded_leg.py
HIDE = {"L": 1, "R": 2}  # the left leg's lower flag, the right leg's upper (default_layout's ids)
MODES = ("translation_along", "translation_across", "rotation", "scale",
         "other_1", "other_2", "other_3", "other_4")
#: frames whose residual exceeds its expectation this many times (a spoiled flag) are left out
RATIO_LIMIT = 3.0
_CHI2_1_MEDIAN = 0.4549364231195724  # median of a chi-square on one degree of freedom


def _hidden(k: int) -> dict:
    return [{}, {"L": HIDE["L"]}, {"R": HIDE["R"]}][(k // STRETCH) % 3]


def _mode_basis(quad: np.ndarray) -> np.ndarray:
    """Orthonormal basis (8, 8) of a flag's corner coordinates (x0, y0, x1, ...) in its own axes:
    translation along and across, rotation and scale about its centre, then the rest."""
    c = quad - quad.mean(axis=0)
    c = c / np.mean(np.hypot(c[:, 0], c[:, 1]))
    known = np.column_stack([np.tile([1.0, 0.0], 4), np.tile([0.0, 1.0], 4),
                             np.column_stack([-c[:, 1], c[:, 0]]).ravel(), c.ravel()])
    q, _ = np.linalg.qr(np.column_stack([known, np.eye(8)]))
    return q[:, :8]  # signs do not matter: only squares are used


def _true_corners(film, layout) -> list:
    """Per frame: leg marker id -> its true corners (4, 2) (pixels), averaged over the shutter."""
    from toywalk.tracking.camera import project
    from toywalk.tracking.markers import marker_corners

    body = {"left_leg": "L", "right_leg": "R"}
    legs = [m for m in layout.markers if m.body in body]
    out = []
    for k in range(len(film)):
        t = float(film.times[k])
        offsets = film._shutter(t)  # the renders the frame averages (the renderer's own rule)
        acc = {m.id: np.zeros((4, 2)) for m in legs}
        for dt in offsets:
            poses = film.scene.body_poses(film.motion.state(t + dt))
            for m in legs:
                rot, tvec = poses[body[m.body]]
                acc[m.id] += project(film.scene.camera, marker_corners(m), cv2.Rodrigues(rot)[0], tvec)
        out.append({i: v / len(offsets) for i, v in acc.items()})
    return out


def _frames(tracker, result, true, truth, camera) -> list:
    """Per usable frame: corner errors (2 n,), their marker ids (n,), the pitch gains (2, 2 n),
    the actual pitch errors (2,), flags per leg, the residual ratio, the marker SDs and the true
    corners."""
    from toywalk.tracking.angles import angle_jacobian, pooled_walker_sd, residual_ratio

    r_ramp = cv2.Rodrigues(np.asarray(camera.ramp_pose[0], float).reshape(3, 1))[0]
    marker_sd = result.noise["marker_pixel_sd"]
    # the tracker's final joint fits and the corners each used (its internals: this study compares
    # them with the truth)
    walker = tracker._final_walker()
    legs_sd = pooled_walker_sd(walker)
    rows = []
    for k, (pose, obs) in enumerate(zip(walker, tracker._observations, strict=True)):
        if pose is None or obs is None or pose.jacobian is None:
            continue
        err, labels = [], []
        for foot in ("L", "R"):  # the fit's order: the left leg's corners first
            if foot in obs:
                ids = np.asarray(obs[foot][2], int).ravel()
                pixels = np.asarray(obs[foot][1], float).reshape(-1, 2)
                for j, i in enumerate(ids):
                    err.append(pixels[j] - true[k][int(i)][j % 4])  # corners in ArUco's order
                    labels.append(int(i))
        base, jac = angle_jacobian(r_ramp, pose)
        gain = jac @ (pose.normal @ pose.jacobian.T)
        rows.append({"frame": k, "err": np.ravel(err), "labels": np.array(labels),
                     "gain": gain[2:], "pitch_error": (base - truth[k])[2:],
                     "n_flags": {f: pose.n_points.get(f, 0) // 4 for f in "LR"},
                     "ratio": residual_ratio(pose, legs_sd, marker_sd)[0], "sd": marker_sd, "quad": true[k]})
    return rows


def _clip(seed: int, lossless: bool, folder: Path) -> list:
    from toywalk.model.parameters import load_params
    from toywalk.model.trajectory import read_trajectory
    from toywalk.tracking.markers import default_layout
    from toywalk.tracking.render import Filming, RenderOptions
    from toywalk.tracking.scene import default_camera_for
    from toywalk.tracking.track import Tracker
    from toywalk.tracking.video import open_video

    params_path = ROOT / "data" / "params" / "toy-sized.toml"
    r = subprocess.run([TOYWALK, "simulate", "--params", str(params_path), "--steps", "6",
                        "--out", str(folder / "walk.csv")], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    params = load_params(params_path)
    camera, layout = default_camera_for(params), default_layout(params)
    film = Filming(read_trajectory(folder / "walk.csv"), params, camera, layout,
                   RenderOptions.preset(1, duration=2.0), seed, hidden=lambda k: _hidden(k).values())
    video = folder / ("v.avi" if lossless else "v.mp4")
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*("FFV1" if lossless else "mp4v")),
                             float(film.options.fps), camera.size)
    truth = []
    for k in range(len(film)):
        writer.write(film.frame(k))
        truth.append(film.truth(k)[0])
    writer.release()
    tracker = Tracker(camera, layout)
    for t, image in open_video(video):
        tracker.process(t, image)
    result = tracker.finish()
    return _frames(tracker, result, _true_corners(film, layout), np.array(truth), camera)


def _flag_axes(quad: np.ndarray) -> np.ndarray:
    """Rows: the flag's unit vector along its top edge and the one across (image axes)."""
    u = quad[1] - quad[0]
    u = u / np.linalg.norm(u)
    return np.array([u, [-u[1], u[0]]])


def _summary(rows: list) -> dict:
    """The statistics of the module docstring over the frames ``rows``."""
    modes, means = {}, []
    cases = {}
    for row in rows:
        err, labels = row["err"].reshape(-1, 2), row["labels"]
        flag_mean, row["flag_frames"] = {}, []
        for i in np.unique(labels):
            idx = np.flatnonzero(labels == i)
            if len(idx) != 4:
                continue
            axes = _flag_axes(row["quad"][int(i)])
            local = (err[idx] @ axes.T).ravel()
            basis = _mode_basis(row["quad"][int(i)] @ axes.T)
            row["flag_frames"].append((np.ravel([[2 * j, 2 * j + 1] for j in idx]), axes, basis))
            modes.setdefault(int(i), []).append(basis.T @ local / row["sd"][int(i)])
            flag_mean[int(i)] = err[idx].mean(axis=0)
        if row["ratio"] > RATIO_LIMIT:
            continue
        means.append(flag_mean)
        variances = np.repeat([row["sd"][int(i)] ** 2 for i in labels], 2)
        for j, foot in enumerate("LR"):
            n = row["n_flags"][foot]
            if n == 0:
                continue
            g = row["gain"][j]
            case = cases.setdefault(f"{foot}_{n}", {"z2": [], "parts2": [], "modes2": [], "linear": [],
                                                   "actual": []})
            stated = float(np.sum(g**2 * variances))
            linear = float(g @ row["err"])
            case["z2"].append(linear**2 / stated)
            parts = [float(g[np.repeat(labels == i, 2)] @ row["err"][np.repeat(labels == i, 2)])
                     for i in np.unique(labels)]
            case["parts2"].append(sum(p**2 for p in parts) / stated)
            case["modes2"].append(sum(
                float(np.sum((basis.T @ (g[idx2].reshape(4, 2) @ axes.T).ravel()
                              * (basis.T @ (row["err"][idx2].reshape(4, 2) @ axes.T).ravel())) ** 2))
                for idx2, axes, basis in row["flag_frames"]) / stated)
            case["linear"].append(linear)
            case["actual"].append(float(row["pitch_error"][j]))
    out = {"modes": {}, "translation_correlation": {}, "cases": {}}
    for i, vs in sorted(modes.items()):
        v = np.array(vs)
        out["modes"][str(i)] = {"frames": len(v), **{name: float(np.median(v[:, c] ** 2) / _CHI2_1_MEDIAN)
                                                      for c, name in enumerate(MODES)}}
    ids = sorted(modes)
    for a in ids:
        for b in ids:
            if b <= a:
                continue
            pairs = np.array([np.concatenate([m[a], m[b]]) for m in means if a in m and b in m])
            if len(pairs) < 10:
                continue
            c = np.corrcoef(pairs.T)
            out["translation_correlation"][f"{a}-{b}"] = {"frames": len(pairs), "u": float(c[0, 2]),
                                                          "v": float(c[1, 3])}
    for key, case in sorted(cases.items()):
        out["cases"][key] = {
            "frames": len(case["z2"]), "z": math.sqrt(float(np.mean(case["z2"]))),
            "z_without_cross_terms": math.sqrt(float(np.mean(case["parts2"]))),
            "z_modes_alone": math.sqrt(float(np.mean(case["modes2"]))),
            "linear_error_correlation": float(np.corrcoef(case["linear"], case["actual"])[0, 1])}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,2,3,4", help="render seeds, comma-separated")
    parser.add_argument("--lossless", action="store_true", help="write FFV1 instead of MPEG-4")
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    from toywalk.model.files import atomic_write_json

    out = args.out or str(ROOT / "benchmarks" / "results" /
                          ("corner_errors_lossless.json" if args.lossless else "corner_errors.json"))
    seeds = [int(s) for s in args.seeds.split(",")]
    start = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            clip = _clip(seed, args.lossless, Path(tmp))
            print(f"seed {seed}: {len(clip)} frames", flush=True)
            rows.extend(clip)
    summary = _summary(rows)
    for key, case in summary["cases"].items():
        print(f"{key}: {case['frames']} frames, z {case['z']:.2f}, without cross terms "
              f"{case['z_without_cross_terms']:.2f}, modes alone {case['z_modes_alone']:.2f} "
              f"(linearised error vs actual: r = "
              f"{case['linear_error_correlation']:.3f})")
    for i, m in summary["modes"].items():
        print(f"flag {i}: " + ", ".join(f"{name} {m[name]:.2f}" for name in MODES))
    for pair, c in summary["translation_correlation"].items():
        print(f"flags {pair}: translation correlation u {c['u']:.2f}, v {c['v']:.2f} ({c['frames']} frames)")
    atomic_write_json(out, {**summary, "walker": "toy-sized", "seeds": seeds, "clip_seconds": 2.0,
                            "noise_level": 1, "codec": "FFV1" if args.lossless else "mp4v",
                            "stretch_frames": STRETCH, "hidden_ids": HIDE, "ratio_limit": RATIO_LIMIT,
                            "run_seconds": time.perf_counter() - start})
    print(f"wrote {out} in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
