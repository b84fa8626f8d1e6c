"""Tracker accuracy and speed on rendered videos of known trajectories (benchmarks/TRACKING.md).

Usage::

    TOYWALK_CACHE=/tmp/twcache .venv/bin/python benchmarks/track_accuracy.py [--quick] [--out FILE]

For each walker (``compass-3d`` from data/params, a toy-sized walker, the test suite's, whose
gait is unstable but walks the six steps rendered, and ``stable-toy``, whose steps last 6.4 frames,
at level 1 only) it simulates a few steps from the gait, renders
them at 1280x720, 60 fps with the real renderer at noise levels 0-3 and once with frequent
occluders, tracks each video with the camera and marker files the renderer wrote, and compares
with the renderer's truth: RMS and max error per signal (deg, over the frames tracked), frames
left as gaps, heel strikes matched to the true ones (timing error in frames, missed, invented,
wrong foot). Throughput: a decode-only pass and a tracking pass over the same video, alternated,
best of three each; the ratio is tracking throughput over decode-only throughput.

Writes ``benchmarks/results/track_accuracy.json`` atomically (temporary file, then rename).
It takes about 3-4 minutes on one core (rendering dominates).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TOYWALK = str(Path(sys.executable).with_name("toywalk"))
SIGNALS = ("lean", "steer", "pitch_left", "pitch_right")


#: stable-toy: 6.4 frames a step at 60 fps (the fast-step case); level 1 only, 18 steps (1.9 s).
WALKERS = {"compass-3d": {"steps": 8}, "toy": {"steps": 6},
           "stable-toy": {"steps": 18, "cases": ("level1",)}}
#: the presets, then one imperfection at a time on a perfect camera (seeds follow the order)
CASES = [("level0", 0, {}), ("level1", 1, {}), ("level2", 2, {}), ("level3", 3, {}),
         ("level1+occlusion", 1, {"occlusion": 0.25}),
         ("noise-only", 0, {"noise_sd": 10.0}), ("blur-only", 0, {"blur_subframes": 2, "exposure": 1.0}),
         ("occlusion-only", 0, {"occlusion": 0.5})]


def _simulate(params_path: Path, steps: int, out: Path) -> None:
    r = subprocess.run([TOYWALK, "simulate", "--params", str(params_path), "--steps", str(steps),
                        "--out", str(out)], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(f"simulate failed: {r.stderr.strip()}")


def _render(traj: Path, params_path: Path, level: int, overrides: dict, out: Path, seed: int) -> float:
    from toywalk.model.parameters import load_params
    from toywalk.model.trajectory import read_trajectory
    from toywalk.tracking.markers import default_layout
    from toywalk.tracking.render import RenderOptions, render
    from toywalk.tracking.scene import default_camera_for

    params = load_params(params_path)
    start = time.perf_counter()
    render(read_trajectory(traj), params, default_camera_for(params), default_layout(params),
           RenderOptions.preset(level, **overrides), out, rng=seed, source={"trajectory": str(traj)})
    return time.perf_counter() - start


#: cases drawn as figures (benchmarks/results/track_<walker>.png): tracked against truth
FIGURES = {("compass-3d", "level1"), ("toy", "level1"), ("stable-toy", "level1")}


def _figure(result, truth, title: str, out: Path) -> None:
    """The four signals tracked (points with 2-SD bars) over the truth (line), their errors, and the
    heel strikes (true: grey lines; measured: dashed, L blue, R red)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 2, figsize=(12, 9), sharex=True, gridspec_kw={"width_ratios": [3, 2]})
    t = result.time - result.time[0]
    for row, k in enumerate(SIGNALS):
        ax, ax_err = axes[row]
        ax.plot(t, np.degrees(truth.signals[k]), "k-", lw=1, label="truth")
        ax.errorbar(t, np.degrees(result.raw[k]), yerr=2 * np.degrees(result.raw_sd[k]), fmt=".", ms=3,
                    lw=0.6, color="tab:orange", label="tracked (2 SD)")
        err = np.degrees(result.raw[k] - truth.signals[k])
        ax_err.plot(t, err, ".", ms=3, color="tab:orange")
        ax_err.fill_between(t, -2 * np.degrees(result.raw_sd[k]), 2 * np.degrees(result.raw_sd[k]),
                            color="tab:orange", alpha=0.2, lw=0)
        ax_err.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{k} (deg)")
        ax_err.set_ylabel("error (deg)")
        for a in (ax, ax_err):
            for e in truth.events:
                a.axvline(e["time"] - result.time[0], color="0.6", lw=0.8)
            for e in result.events:
                a.axvline(e.time - result.time[0], color="tab:blue" if e.foot == "L" else "tab:red",
                          lw=0.8, ls="--")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    axes[-1, 1].set_xlabel("time (s)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    plt.close(fig)


def _track_case(video: Path, figure: Path | None = None) -> dict:
    from toywalk.model.trajectory import read_trajectory
    from toywalk.tracking.accuracy import match_strikes, signal_errors
    from toywalk.tracking.camera import load_camera
    from toywalk.tracking.markers import load_layout
    from toywalk.tracking.track import track_video

    stem = video.with_suffix("")
    camera = load_camera(f"{stem}.camera.json")
    layout = load_layout(f"{stem}.markers.json")
    start = time.perf_counter()
    result, source = track_video(video, camera, layout)
    wall = time.perf_counter() - start
    truth = read_trajectory(f"{stem}.truth.csv")
    measured = result.table()
    out = {"frames": len(result.time), "signals": signal_errors(measured, truth)}
    times = [e["time"] for e in truth.events]
    step = float(np.median(np.diff(times))) if len(times) > 1 else 0.4
    out["heel_strikes"] = match_strikes(truth.events, measured.events, step,
                                        float(np.median(np.diff(truth.time))))
    out["hip_width_m"] = result.hip_width
    out["counts"] = result.counts
    out["track_ms_per_frame"] = 1e3 * wall / len(result.time)
    if figure is not None:
        s = out["signals"]
        _figure(result, truth, f"{video.name}: RMS error lean {s['lean']['rms_deg']:.2f}, steer "
                f"{s['steer']['rms_deg']:.2f}, pitches {s['pitch_left']['rms_deg']:.2f} / "
                f"{s['pitch_right']['rms_deg']:.2f} deg; strikes {out['heel_strikes']['found']}/"
                f"{out['heel_strikes']['true']}", figure)
    return out


def _throughput(video: Path, repeats: int = 3) -> dict:
    """Decode-only and tracking passes over one video, alternated; best of ``repeats`` each."""
    from toywalk.tracking.camera import load_camera
    from toywalk.tracking.markers import load_layout
    from toywalk.tracking.track import open_video, track_video

    stem = video.with_suffix("")
    camera = load_camera(f"{stem}.camera.json")
    layout = load_layout(f"{stem}.markers.json")
    decode, track = [], []
    n = 0
    for _ in range(repeats):
        start = time.perf_counter()
        n = sum(1 for _ in open_video(video))
        decode.append(time.perf_counter() - start)
        start = time.perf_counter()
        track_video(video, camera, layout)
        track.append(time.perf_counter() - start)
    return {"video": video.name, "frames": n, "decode_ms_per_frame": 1e3 * min(decode) / n,
            "track_ms_per_frame": 1e3 * min(track) / n, "ratio": min(decode) / min(track),
            "method": f"best of {repeats} alternated passes each; ratio = tracking throughput / "
                      "decode-only throughput (decode time / tracking time, tracking includes decode)"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "track_accuracy.json"))
    parser.add_argument("--quick", action="store_true", help="compass-3d at level 1 only")
    parser.add_argument("--keep", default=None, help="keep the rendered videos in this folder")
    args = parser.parse_args(argv)
    os.environ.setdefault("TOYWALK_CACHE", "/tmp/twcache")
    started = time.perf_counter()
    report = {"about": "tracker accuracy on rendered videos (1280x720, 60 fps) against the renderer's "
                       "truth; errors in degrees over tracked frames, heel-strike timing in frames",
              "load_average_start": os.getloadavg(), "walkers": {}, "throughput": None}
    with tempfile.TemporaryDirectory(prefix="track_accuracy_") as tmp:
        folder = Path(args.keep) if args.keep else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        param_files = {"compass-3d": ROOT / "data" / "params" / "compass-3d.toml",
                       "toy": ROOT / "data" / "params" / "toy-sized.toml",
                       "stable-toy": ROOT / "data" / "params" / "stable-toy.toml"}
        walkers = {"compass-3d": WALKERS["compass-3d"]} if args.quick else WALKERS
        cases = [c for c in CASES if c[0] == "level1"] if args.quick else CASES
        for name, spec in walkers.items():
            traj = folder / f"{name}.walk.csv"
            _simulate(param_files[name], spec["steps"], traj)
            report["walkers"][name] = {"params": str(param_files[name].relative_to(ROOT)),
                                       "steps": spec["steps"], "cases": {}}
            for seed, (case, level, overrides) in enumerate(cases, start=1):
                if case not in spec.get("cases", (case,)):
                    continue
                video = folder / f"{name}.{case}.mp4"
                render_s = _render(traj, param_files[name], level, overrides, video, seed)
                figure = (Path(args.out).parent / f"track_{name}.png"
                          if (name, case) in FIGURES and not args.quick else None)
                res = _track_case(video, figure)
                res.update({"noise_level": level, "overrides": overrides, "seed": seed,
                            "render_s": render_s})
                report["walkers"][name]["cases"][case] = res
                s = res["signals"]
                hs = res["heel_strikes"]
                print(f"{name:10s} {case:17s} " + " ".join(
                    f"{k} {s[k]['rms_deg']:.3f}" if s[k]["rms_deg"] is not None else f"{k} -"
                    for k in SIGNALS) + f" gaps {s['pitch_left']['gaps']}/{res['frames']}"
                      f" strikes {hs['found']}/{hs['true']} missed {hs['missed']} invented "
                      f"{hs['invented']} foot {hs['wrong_foot']} rms {hs['timing_rms_frames']}", flush=True)
        report["throughput"] = _throughput(folder / "compass-3d.level1.mp4")
        print(f"throughput: decode {report['throughput']['decode_ms_per_frame']:.2f} ms/frame, track "
              f"{report['throughput']['track_ms_per_frame']:.2f} ms/frame, ratio "
              f"{report['throughput']['ratio']:.2f}")
    report["load_average_end"] = os.getloadavg()
    report["run_seconds"] = time.perf_counter() - started
    from toywalk.model.files import atomic_write_text

    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, json.dumps(report, indent=2, default=_jsonable) + "\n")
    print(f"wrote {out} in {report['run_seconds']:.0f} s")
    return 0


def _jsonable(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return str(value)


if __name__ == "__main__":
    sys.exit(main())
