"""Runs that fail for a reason of the physics or the numerics, not of the input files: a walker
that falls, and a fit whose solver (IPOPT) stops before it converges. Each is a result, reported
as one: a non-zero exit status, a line that says what happened, no traceback, and the files it
writes whole and marked with their status.
"""

from __future__ import annotations

import functools
import json
import subprocess
import sys

from toywalk.model.trajectory import read_trajectory

from .conftest import STABLE_TOY, TOY_SIZED, toywalk


def test_walker_that_falls(tmp_path, capfd):
    """toy-sized's gait is unstable (max |eigenvalue| 6.0): released at its fixed point it falls
    within 20 steps. The walk until the fall is the result: status 1 (not 2, bad input), the
    summary line says how it ended and where, nothing on stderr, and the trajectory is written
    whole, its metadata saying so. The gait multiplies the start's round-off six-fold a step, so
    how the collapse ends after ~20 steps depends on the machine's round-off: a hip reaching the
    ramp (`fell`), or a strike with the legs together, from which no step can start
    (`no_heel_strike`; seen with other package builds). Either is a physical failure."""
    out = tmp_path / "walk.csv"
    outcome = toywalk(capfd, "simulate", "--params", TOY_SIZED, "--steps", "40", "--out", out)
    assert outcome.code == 1, outcome.err
    assert outcome.err_lines == []
    lines = outcome.out.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(("fell: step ", "no_heel_strike: step ")), outcome.out
    walk = read_trajectory(out)  # the three files, whole and readable
    assert walk.metadata["status"] in ("fell", "no_heel_strike")
    assert lines[0].startswith(walk.metadata["status"]) and walk.metadata["message"] in lines[0]
    assert 1 < len(walk.events) < 40 and walk.time[-1] > walk.events[-2]["time"]
    if walk.metadata["status"] == "fell":  # the samples go on past the last strike to the fall
        assert walk.time[-1] > walk.events[-1]["time"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.csv", "walk.events.csv", "walk.json"]


def test_fit_that_does_not_converge(walk, tmp_path, capfd, monkeypatch):
    """IPOPT stopped after one iteration (its iteration limit, as a fit from far off or of a walk
    the model cannot follow would reach): status 1, the solver's status in the summary, one line on
    stderr saying the fit did not succeed, and the fit file written whole with that status (it is
    a record of the attempt; `toywalk sample` refuses it)."""
    import toywalk.sysid.fit as fit_module

    monkeypatch.setattr(fit_module, "fit", functools.partial(fit_module.fit, max_iter=1))
    out = tmp_path / "fit.json"
    outcome = toywalk(capfd, "fit", walk, "--params", STABLE_TOY, "--free", "foot_radius",
                      "--model", "periodic", "--intervals", "10", "--out", out)
    assert outcome.code == 1
    assert outcome.err_lines == [f"toywalk fit: the fit did not succeed (Maximum_Iterations_Exceeded "
                                 f"after 1 iterations): {out} records the attempt and its warnings; "
                                 "its estimates are not a usable optimum (a model far from the walk "
                                 "may converge aligned on the measured heel strikes: --strikes "
                                 "measured)"], outcome.err
    assert outcome.out.strip().splitlines()[-1] == f"Maximum_Iterations_Exceeded in 1 iterations -> {out}"
    report = json.loads(out.read_text())
    assert report["success"] is False and report["status"] == "Maximum_Iterations_Exceeded"
    assert [p.name for p in tmp_path.iterdir()] == ["fit.json"]  # no temporary file left


def test_track_warns_when_the_walk_cannot_be_fitted(video, tmp_path, capfd):
    """A clip too short (13 frames, 0.4 s: fewer than three heel strikes) tracks, and the files
    are written whole, but fit and diagnose will refuse it: track says so at once, in one warning
    line naming the count, instead of leaving the user to find out a command later."""
    out = tmp_path / "m.csv"
    outcome = toywalk(capfd, "track", video, "--camera", video.with_suffix(".camera.json"),
                      "--markers", video.with_suffix(".markers.json"), "--out", out)
    assert outcome.code == 0, outcome.err
    table = read_trajectory(out)
    assert len(table.events) < 3
    lines = outcome.err_lines
    assert len(lines) == 1 and lines[0].startswith("toywalk track: warning: "), outcome.err
    assert f"{len(table.events)} heel strikes were found (fit needs 3)" in lines[0]


def test_a_reader_that_stops_early_gets_no_traceback():
    """`toywalk effects --json | head -c 50`: the reader closes the pipe before the command writes.
    The command stops quietly with status 141 (128 + SIGPIPE, as a shell reports a Unix tool
    stopped by a closed pipe), not with Python's BrokenPipeError traceback."""
    with subprocess.Popen([sys.executable, "-m", "toywalk.sysid.cli", "effects", "--json"],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE) as proc:
        proc.stdout.close()  # before the command has imported its modules, so before it writes
        err = proc.stderr.read().decode()
        assert proc.wait(timeout=120) == 141, err
    assert err == ""


def test_track_warns_when_heel_strikes_are_missed(tmp_path, capfd, monkeypatch):
    """Strikes missed while the legs are tracked (a swing too fast for the frame rate: a 1080p,
    30 frames/s clip of clearing-toy, 5 frames a step, gave 4 strikes for 10 steps, and track said
    nothing) leave fit a walk with holes. Track compares the strikes it found with the times the
    legs passed each other, once a step, and warns where more than two are missing. Here the
    strike finder is made to drop every other strike of a clip where it finds them all: more than
    the three fit needs are left, so only the comparison can warn."""
    import toywalk.tracking.track as track_module
    from toywalk.sysid.cli import main

    for folder in ("all", "some"):
        (tmp_path / folder).mkdir()
    walk, video = tmp_path / "walk.csv", tmp_path / "clip.mp4"
    assert main(["simulate", "--params", str(STABLE_TOY), "--steps", "12", "--seed", "4",
                 "--out", str(walk)]) == 0
    assert main(["render", str(walk), "--params", str(STABLE_TOY), "--size", "640x360",
                 "--seed", "2", "--out", str(video)]) == 0
    outcome = toywalk(capfd, "track", video, "--out", tmp_path / "all" / "m.csv")
    assert outcome.code == 0 and outcome.err_lines == [], outcome.err
    found = len(read_trajectory(tmp_path / "all" / "m.csv").events)
    finder = track_module.heel_strikes
    monkeypatch.setattr(track_module, "heel_strikes", lambda *a, **k: finder(*a, **k)[::2])
    outcome = toywalk(capfd, "track", video, "--out", tmp_path / "some" / "m.csv")
    assert outcome.code == 0, outcome.err
    kept = len(read_trajectory(tmp_path / "some" / "m.csv").events)
    assert 3 <= kept < found - 2, (kept, found)
    lines = outcome.err_lines
    assert len(lines) == 1 and f"{kept} heel strikes were found (fit needs 3) where the legs passed " \
        "each other" in lines[0], outcome.err
