"""Tracking throughput of this tree against an earlier commit's, on the same videos, in one run.

    python benchmarks/track_before_after.py --before COMMIT --videos DIR [--repeats 3] [--out FILE]

Each video ``V.mp4`` of DIR (with ``V.camera.json`` and ``V.markers.json`` beside it, as
``track_accuracy.py --keep DIR`` leaves them) is decoded alone and tracked by both trees, the
three passes alternated, each in its own process on one thread (``cv2.setNumThreads(1)``,
FFmpeg's decoder on one thread), best of ``--repeats``. The earlier tree is checked out with
``git worktree`` into a temporary folder and imported in place of this one. Times are wall times
per frame of decoding, and of tracking including its own decoding and ``finish``; ratio = decode
time over tracking time. Writes JSON (default benchmarks/results/track_before_after.json).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_PASS = r"""
import sys, time, cv2
cv2.setNumThreads(1)
from toywalk.tracking.camera import load_camera
from toywalk.tracking.markers import load_layout
from toywalk.tracking.video import open_video
video, kind = sys.argv[1], sys.argv[2]
stem = video[:-4]
if kind == "decode":
    start = time.perf_counter()
    n = sum(1 for _ in open_video(video, decoder_threads=1))
else:
    from toywalk.tracking.track import Tracker
    tracker = Tracker(load_camera(stem + ".camera.json"), load_layout(stem + ".markers.json"))
    start = time.perf_counter()
    n = 0
    for t, image in open_video(video, decoder_threads=1):
        tracker.process(t, image)
        n += 1
    tracker.finish()
print(n, time.perf_counter() - start)
"""


def _run(video: Path, kind: str, pythonpath: str | None) -> tuple[int, float]:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    r = subprocess.run([sys.executable, "-c", _PASS, str(video), kind], capture_output=True, text=True,
                       env=env, cwd=tempfile.gettempdir(), timeout=900)
    if r.returncode != 0:
        raise RuntimeError(f"{kind} pass on {video.name} failed: {r.stderr.strip().splitlines()[-1]}")
    n, seconds = r.stdout.split()
    return int(n), float(seconds)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="the earlier commit")
    parser.add_argument("--videos", required=True, help="folder of videos with their camera and marker files")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "track_before_after.json"))
    args = parser.parse_args(argv)
    videos = sorted(p for p in Path(args.videos).glob("*.mp4") if Path(f"{str(p)[:-4]}.camera.json").exists())
    if not videos:
        parser.error(f"no video with a camera file in {args.videos}")
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", args.before], capture_output=True,
                            text=True, check=True).stdout.strip()
    here = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()
    report = {"about": __doc__.split("\n\n")[1].strip(), "before": commit, "after": here,
              "load_average_start": os.getloadavg(), "repeats": args.repeats, "videos": {}}
    with tempfile.TemporaryDirectory(prefix="track_before_") as tmp:
        tree, package = Path(tmp) / "tree", Path(tmp) / "package" / "toywalk"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "-q", "--detach", str(tree), commit],
                       check=True)
        try:
            package.mkdir(parents=True)
            (package / "__init__.py").write_text("")
            for name in ("model", "tracking", "sysid", "data"):
                (package / name).symlink_to(tree / name)
            for video in videos:
                best: dict[str, float] = {}
                for _ in range(args.repeats):
                    for kind, path in (("decode", None), ("before", str(package.parent)), ("after", None)):
                        n, seconds = _run(video, "decode" if kind == "decode" else "track", path)
                        best[kind] = min(best.get(kind, float("inf")), seconds / n)
                row = {"frames": n, **{f"{k}_ms_per_frame": 1e3 * v for k, v in best.items()},
                       "ratio_before": best["decode"] / best["before"],
                       "ratio_after": best["decode"] / best["after"],
                       "speedup": best["before"] / best["after"]}
                report["videos"][video.stem] = row
                print(f"{video.stem:28s} decode {row['decode_ms_per_frame']:.2f} ms/frame, tracking "
                      f"{row['before_ms_per_frame']:.2f} -> {row['after_ms_per_frame']:.2f} "
                      f"(x{row['speedup']:.2f}); ratio {row['ratio_before']:.2f} -> {row['ratio_after']:.2f}",
                      flush=True)
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)
    report["load_average_end"] = os.getloadavg()
    from toywalk.model.files import atomic_write_text

    atomic_write_text(Path(args.out), json.dumps(report, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
