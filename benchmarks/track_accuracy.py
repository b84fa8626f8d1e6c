"""Tracker accuracy and speed on rendered videos of known trajectories (benchmarks/TRACKING.md).

Usage::

    TOYWALK_CACHE=/tmp/twcache .venv/bin/python benchmarks/track_accuracy.py [--quick] [--out FILE]
    TOYWALK_CACHE=/tmp/twcache .venv/bin/python benchmarks/track_accuracy.py --throughput-only

For each walker (``compass-3d`` from data/params, a toy-sized walker, the test suite's, whose
gait is unstable but walks the six steps rendered, and ``stable-toy``, whose steps last 6.4 frames,
at level 1 only) it simulates a few steps from the gait, renders
them at 1280x720, 60 fps with the real renderer at noise levels 0-3 and once with frequent
occluders, tracks each video with the camera and marker files the renderer wrote, and compares
with the renderer's truth: RMS and max error per signal (deg, over the frames tracked), frames
left as gaps, heel strikes matched to the true ones (timing error in frames, missed, invented,
wrong foot).

Throughput, for every video rendered: a decode-only pass and a tracking pass over the same file,
each on one thread (``cv2.setNumThreads(1)`` and FFmpeg's decoder on one thread) and with the
libraries' default threads, the four passes alternated, best of ``--repeats`` each; the ratio is
tracking throughput over decode-only throughput. Each pass records its CPU time over wall time
and the threads that ran (from /proc/self/task), which check the pinning. Then the tracker's
stages are timed on one thread on the video with the lowest ratio (``stage_profile``).
``--throughput-only`` renders each walker's level-1 video and measures only that.

Writes ``benchmarks/results/track_accuracy.json`` (``--throughput-only``:
``track_throughput.json``) atomically (temporary file, then rename). The full run takes about
3-4 minutes on an idle 2-core machine (rendering dominates), several times that under load.
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

import cv2
import numpy as np

#: OpenCV's own thread count as the library starts (one per core), restored after pinned passes
_DEFAULT_CV_THREADS = cv2.getNumThreads()
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


#: Thread settings of the throughput passes: OpenCV's own threads (cv2.setNumThreads; ArUco's
#: detection and some image functions run parallel loops on them) and FFmpeg's decoder threads
#: (FrameSource(decoder_threads=...)). None: what the library chooses (OpenCV: one per core;
#: FFmpeg as opened by OpenCV: one per core, frame threading).
THREADS = {"one thread": {"opencv": 1, "decoder": 1}, "default threads": {"opencv": None, "decoder": None}}


def _thread_ticks() -> dict:
    """CPU time (clock ticks, user + system) of each thread of this process, by thread id."""
    out = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:  # not Linux: no per-thread counts
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended
            continue
        out[tid] = int(fields[11]) + int(fields[12])  # utime, stime (proc(5), fields 14-15)
    return out


def _probed(source, probe: dict):
    """``source``'s frames; with the last one declared, each thread's CPU time so far goes to
    ``probe["ticks"]`` (the reader's own threads end when it is released, after the last frame)."""
    for k, frame in enumerate(source, start=1):
        if k == source.declared_frames:
            probe["ticks"] = _thread_ticks()
        yield frame


def _timed_pass(video: Path, threads: dict, camera=None, layout=None) -> dict:
    """One pass over ``video`` with ``threads`` (a value of :data:`THREADS`): decode only (no
    camera) or tracking (``track_frames`` over the same reader). Wall and process CPU time (s),
    the threads that used CPU time during the pass (a thread must use one clock tick, 10 ms, to
    count), and for tracking the time its thread spent reading frames and in ``Tracker.process``."""
    from toywalk.tracking.track import track_frames
    from toywalk.tracking.video import open_video

    cv2.setNumThreads(_DEFAULT_CV_THREADS if threads["opencv"] is None else threads["opencv"])
    source = open_video(video, decoder_threads=threads["decoder"])
    ticks = _thread_ticks()
    probe = {}
    cpu, start = time.process_time(), time.perf_counter()
    if camera is None:
        n = sum(1 for _ in _probed(source, probe))
        process = None
    else:
        result = track_frames(_probed(source, probe), camera, layout)
        n, process = len(result.time), result.track_seconds
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    after = probe.get("ticks") or _thread_ticks()
    ran = sum(1 for tid, t in after.items() if t > ticks.get(tid, -1)) if after else None
    return {"frames": n, "wall": wall, "cpu": cpu, "threads_ran": ran, "read": source.decode_seconds,
            "process": process}


def _opencv_floor(video: Path, camera, layout) -> dict:
    """A one-thread tracking pass under :mod:`cProfile`: the time spent inside OpenCV's own calls
    (their exclusive time), reading frames apart, and within it ArUco's ``detectMarkers`` (ms/frame).
    What the tracker's Python and NumPy cost is the rest; compiled glue could remove that, not this."""
    import cProfile
    import pstats

    from toywalk.tracking.track import track_frames
    from toywalk.tracking.video import open_video

    functions = {f"<{name}>" for name in dir(cv2) if callable(getattr(cv2, name, None))}
    cv2.setNumThreads(1)
    profile = cProfile.Profile()
    profile.enable()
    result = track_frames(open_video(video, decoder_threads=1), camera, layout)
    profile.disable()
    cv2.setNumThreads(_DEFAULT_CV_THREADS)
    opencv = read = detect = 0.0
    for (path, _, name), (_, _, own, _, _) in pstats.Stats(profile).stats.items():
        if path != "~" or not (name in functions or "of 'cv2." in name):
            continue
        if "'cv2.VideoCapture'" in name:
            read += own
        else:
            opencv += own
            detect += own if "'detectMarkers'" in name else 0.0
    n = len(result.time)
    return {"opencv_ms_per_frame": 1e3 * opencv / n, "detect_markers_ms_per_frame": 1e3 * detect / n,
            "read_ms_per_frame_profiled": 1e3 * read / n}


def _throughput(videos: list[Path], repeats: int = 3) -> dict:
    """Decode-only and tracking passes over each video, one thread and default threads, the four
    passes alternated (decode, track; one thread, then default); best of ``repeats`` each."""
    from toywalk.tracking.camera import load_camera
    from toywalk.tracking.markers import load_layout

    out = {"method": f"per video: decode-only and tracking passes over the same file (the same "
                     f"reader, FrameSource), with each setting of 'threads', alternated, best of "
                     f"{repeats} each; ratio = tracking throughput / decode-only throughput (decode "
                     "time / tracking time; tracking includes its decoding). Times in ms/frame "
                     "(wall). cpu_per_wall: process CPU time over wall time of the best pass; "
                     "threads_ran: threads that used CPU time during it (at least 10 ms). One "
                     "thread also: opencv_ms_per_frame, the exclusive time inside OpenCV's calls "
                     "(reading frames apart) in one more tracking pass under cProfile, of which "
                     "detect_markers_ms_per_frame is ArUco's search; ceiling_ratio = decode / "
                     "(decode + opencv): the ratio with all Python and NumPy compiled away",
           "threads": THREADS, "opencv_default_threads": _DEFAULT_CV_THREADS,
           "cores": os.cpu_count(), "load_average_start": os.getloadavg(), "videos": {}}
    for video in videos:
        stem = video.with_suffix("")
        camera = load_camera(f"{stem}.camera.json")
        layout = load_layout(f"{stem}.markers.json")
        runs = {(kind, label): [] for label in THREADS for kind in ("decode", "track")}
        for _ in range(repeats):
            for label, threads in THREADS.items():
                runs["decode", label].append(_timed_pass(video, threads))
                runs["track", label].append(_timed_pass(video, threads, camera, layout))
        row = {}
        for label in THREADS:
            dec = min(runs["decode", label], key=lambda r: r["wall"])
            trk = min(runs["track", label], key=lambda r: r["wall"])
            n = trk["frames"]
            row[label] = {
                "frames": n, "decode_ms_per_frame": 1e3 * dec["wall"] / n,
                "track_ms_per_frame": 1e3 * trk["wall"] / n, "ratio": dec["wall"] / trk["wall"],
                "decode_cpu_per_wall": dec["cpu"] / dec["wall"],
                "track_cpu_per_wall": trk["cpu"] / trk["wall"],
                "decode_threads_ran": dec["threads_ran"], "track_threads_ran": trk["threads_ran"],
                # the best tracking pass split: reading frames, Tracker.process, and the rest
                # (finish: angles, SDs, strikes, smoothing)
                "track_read_ms_per_frame": 1e3 * trk["read"] / n,
                "track_process_ms_per_frame": 1e3 * trk["process"] / n,
                "track_finish_ms_per_frame": 1e3 * (trk["wall"] - trk["read"] - trk["process"]) / n,
                "decode_ms_per_frame_all": [1e3 * r["wall"] / n for r in runs["decode", label]],
                "track_ms_per_frame_all": [1e3 * r["wall"] / n for r in runs["track", label]]}
        # the ceiling of the design: decoding plus OpenCV's own calls, all else compiled away
        floor = _opencv_floor(video, camera, layout)
        one = row["one thread"]
        floor["ceiling_ratio"] = one["decode_ms_per_frame"] / (one["decode_ms_per_frame"] +
                                                               floor["opencv_ms_per_frame"])
        one.update(floor)
        out["videos"][video.stem] = row
        one, dflt = row["one thread"], row["default threads"]
        print(f"throughput {video.stem:28s} one thread: decode {one['decode_ms_per_frame']:.2f} track "
              f"{one['track_ms_per_frame']:.2f} ms/frame ratio {one['ratio']:.2f} (threads ran "
              f"{one['decode_threads_ran']}/{one['track_threads_ran']}) | default: decode "
              f"{dflt['decode_ms_per_frame']:.2f} track {dflt['track_ms_per_frame']:.2f} ratio "
              f"{dflt['ratio']:.2f} (threads ran {dflt['decode_threads_ran']}/{dflt['track_threads_ran']}) | "
              f"OpenCV's own calls {one['opencv_ms_per_frame']:.2f} ms/frame (detectMarkers "
              f"{one['detect_markers_ms_per_frame']:.2f}), ceiling {one['ceiling_ratio']:.2f}", flush=True)
    cv2.setNumThreads(_DEFAULT_CV_THREADS)
    out["load_average_end"] = os.getloadavg()
    return out


class _Stages:
    """Exclusive wall time (s) and calls of named stages: a wrapped function's time less that of
    the wrapped functions it calls."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._stack: list[float] = []  # per open call: time spent in wrapped callees
        self.group = "legs"  # what the detection in progress searches for (_grouped_detect)

    def wrap(self, name: str, fn):
        def timed(*args, **kwargs):
            self._stack.append(0.0)
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.perf_counter() - start
                inner = self._stack.pop()
                self.seconds[name] = self.seconds.get(name, 0.0) + spent - inner
                self.calls[name] = self.calls.get(name, 0) + 1
                if self._stack:
                    self._stack[-1] += spent
        return timed


def _grouped_detect(detect, stages: _Stages):
    """``MarkerDetector.detect`` timed, its stages named by what it searches: the legs' regions,
    the ramp's (the group whose regions were asked for last) or the whole frame."""
    timed = {}

    def grouped(image, regions=None, **kwargs):
        group = stages.group if regions is not None else "whole frame"
        stages.group = group
        if group not in timed:
            timed[group] = stages.wrap(f"detect: crops, grey, glue ({group})", detect)
        return timed[group](image, regions, **kwargs)
    return grouped


def _grouped_refine(refine, stages: _Stages):
    """``refine_corners`` of detected markers timed, by the group being detected."""
    timed = {}

    def grouped(*args, **kwargs):
        if stages.group not in timed:
            timed[stages.group] = stages.wrap(f"corner refinement ({stages.group})", refine)
        return timed[stages.group](*args, **kwargs)
    return grouped


def _grouped_regions(regions, stages: _Stages):
    """``Tracker._regions`` timed; it sets the group the next detection searches for."""
    timed = stages.wrap("regions of interest", regions)

    def grouped(body, pred, **kwargs):
        stages.group = "ramp" if body.name == "ramp" else "legs"
        return timed(body, pred, **kwargs)
    return grouped


class _TimedAruco:
    """An ArUco detector whose ``detectMarkers`` is a timed stage."""

    def __init__(self, detector, stages: _Stages):
        self._detector = detector
        self._stages = stages
        self._timed = {}

    def detectMarkers(self, image):  # noqa: N802 (OpenCV's name)
        group = self._stages.group
        if group not in self._timed:
            self._timed[group] = self._stages.wrap(f"ArUco detectMarkers ({group})",
                                                   self._detector.detectMarkers)
        return self._timed[group](image)

    def setDetectorParameters(self, params):  # noqa: N802 (OpenCV's name)
        self._detector.setDetectorParameters(params)


def _stage_profile(video: Path, repeats: int = 5) -> dict:
    """Where one thread's tracking time goes on ``video``: the tracker's stages timed by wrapping
    them (this process only; the tracker's code is unchanged), best of ``repeats`` passes by total.
    One thread: cv2.setNumThreads(1), FFmpeg's decoder on one thread."""
    from toywalk.tracking import detect, track
    from toywalk.tracking.camera import load_camera
    from toywalk.tracking.markers import load_layout
    from toywalk.tracking.video import open_video

    stem = video.with_suffix("")
    camera = load_camera(f"{stem}.camera.json")
    layout = load_layout(f"{stem}.markers.json")
    cv2.setNumThreads(1)
    best = None
    saved = detect.refine_corners, track.merge_regions
    try:
        for _ in range(repeats):
            stages = _Stages()
            detect.refine_corners = _grouped_refine(saved[0], stages)
            track.merge_regions = stages.wrap("regions of interest", saved[1])
            tracker = track.Tracker(camera, layout)
            d = tracker.detector
            d._detector = _TimedAruco(d._detector, stages)
            d._roi_detectors = {k: (params, _TimedAruco(det, stages))
                                for k, (params, det) in d._roi_detectors.items()}
            d.detect = _grouped_detect(d.detect, stages)
            d.recover = stages.wrap("recovery of missed markers", d.recover)
            d.follow = stages.wrap("ramp markers followed (refinement, code)", d.follow)
            tracker._predict = stages.wrap("regions of interest", tracker._predict)
            tracker._regions = _grouped_regions(tracker._regions, stages)
            tracker._fit_walker = stages.wrap("joint fit (legs)", tracker._fit_walker)
            tracker._fit_body = stages.wrap("ramp fit", tracker._fit_body)
            tracker._recover = stages.wrap("recovery of missed markers", tracker._recover)
            process = stages.wrap("process: rest", tracker.process)
            source = open_video(video, decoder_threads=1)
            frames = iter(source)
            read = stages.wrap("frame read", lambda it=frames: next(it, None))
            start = time.perf_counter()
            n = 0
            while (frame := read()) is not None:
                process(*frame)
                n += 1
            stages.wrap("finish (angles, SDs, strikes)", tracker.finish)()
            total = time.perf_counter() - start
            if best is None or total < best[0]:
                best = (total, n, stages)
    finally:
        detect.refine_corners, track.merge_regions = saved
        cv2.setNumThreads(_DEFAULT_CV_THREADS)
    total, n, stages = best
    return {"video": video.stem, "frames": n, "threads": THREADS["one thread"],
            "method": f"stages timed by wrapping them (exclusive times), best of {repeats} passes by "
                      "total; the wrappers add a few microseconds a call",
            "total_ms_per_frame": 1e3 * total / n,
            "stages_ms_per_frame": {k: 1e3 * v / n for k, v in
                                    sorted(stages.seconds.items(), key=lambda kv: -kv[1])},
            "calls_per_frame": {k: v / n for k, v in stages.calls.items()}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None,
                        help="the JSON report (default benchmarks/results/track_accuracy.json, with "
                             "--throughput-only track_throughput.json)")
    parser.add_argument("--quick", action="store_true", help="compass-3d at level 1 only")
    parser.add_argument("--throughput-only", action="store_true",
                        help="render each walker's level-1 video and measure throughput and the "
                             "per-stage profile only (no accuracy cases)")
    parser.add_argument("--repeats", type=int, default=None,
                        help="passes of each kind per video, best taken (default 3; 5 with "
                             "--throughput-only)")
    parser.add_argument("--keep", default=None, help="keep the rendered videos in this folder")
    args = parser.parse_args(argv)
    repeats = args.repeats or (5 if args.throughput_only else 3)
    if repeats < 1:
        parser.error(f"--repeats must be at least 1, got {repeats}")
    out = Path(args.out or ROOT / "benchmarks" / "results" /
               ("track_throughput.json" if args.throughput_only else "track_accuracy.json"))
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
        cases = [c for c in CASES if c[0] == "level1"] if args.quick or args.throughput_only else CASES
        videos = []
        for name, spec in walkers.items():
            traj = folder / f"{name}.walk.csv"
            _simulate(param_files[name], spec["steps"], traj)
            report["walkers"][name] = {"params": str(param_files[name].relative_to(ROOT)),
                                       "steps": spec["steps"], "cases": {}}
            for seed, (case, level, overrides) in enumerate(CASES, start=1):
                if case not in spec.get("cases", (case,)) or (case, level, overrides) not in cases:
                    continue
                video = folder / f"{name}.{case}.mp4"
                render_s = _render(traj, param_files[name], level, overrides, video, seed)
                videos.append(video)
                if args.throughput_only:
                    continue
                figure = (out.parent / f"track_{name}.png"
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
        report["throughput"] = _throughput(videos, repeats)
        rows = report["throughput"]["videos"]
        slowest = min(rows, key=lambda v: rows[v]["one thread"]["ratio"])
        report["stage_profile"] = _stage_profile(folder / f"{slowest}.mp4", max(repeats, 5))
        prof = report["stage_profile"]
        print(f"stages, one thread, {slowest} (ms/frame, total {prof['total_ms_per_frame']:.2f}): " +
              ", ".join(f"{k} {v:.2f}" for k, v in prof["stages_ms_per_frame"].items()))
    report["load_average_end"] = os.getloadavg()
    report["run_seconds"] = time.perf_counter() - started
    from toywalk.model.files import atomic_write_text

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
