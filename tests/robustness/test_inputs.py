"""Corrupt, truncated, empty and mislabelled inputs, for every command that reads them.

Each case proves four things of the command given the bad file: it exits with status 2; stderr is
one line, ``toywalk CMD: error: ...``, that names the problem; it writes nothing (no output, no
companion, no temporary file: the folder's files are the same before and after); and an output
already at the ``--out`` path is left byte for byte as it was.

The sampling command's inputs (fit file, chain file, and its trajectory) are in
``test_sampling.py``, beside the real fit they need.
"""

from __future__ import annotations

import json
import subprocess

import cv2
import numpy as np
import pytest

from ..tracking.synthetic import TOYWALK
from .bad_trajectories import BINARY, TRAJECTORIES, bad_trajectory
from .conftest import CAMERA, MARKERS, STABLE_TOY, assert_refused, snapshot, toywalk, write

STORED = b"a result stored earlier: must survive a failed run\n"
GOOD_PARAMS = STABLE_TOY.read_text()


def _set(text: str, key: str, value: str) -> str:
    """A parameter file with ``key``'s line replaced."""
    lines = [f"{key} = {value}" if line.startswith(f"{key} =") else line for line in text.splitlines()]
    assert lines != text.splitlines(), key
    return "\n".join(lines) + "\n"


def _outputs(folder, command):
    """The command's output arguments, each already holding a stored result."""
    if command == "diagnose":
        report = folder / "report"
        report.mkdir()
        (report / "report.md").write_bytes(STORED)
        return ["--out", report]
    name = {"simulate": "out.csv", "render": "out.mp4", "fit": "out.json", "track": "out.csv",
            "calibrate": "out.json"}.get(command)
    if name is None:  # gait prints only
        return []
    (folder / name).write_bytes(STORED)
    extra = []
    if command == "track":
        (folder / "overlay.mp4").write_bytes(STORED)
        extra = ["--overlay", folder / "overlay.mp4"]
    return ["--out", folder / name, *extra]


def _refused_and_untouched(capfd, folder, argv, words):
    before = snapshot(folder)
    outcome = toywalk(capfd, *argv)
    assert_refused(outcome, *words)
    assert snapshot(folder) == before, "the failed run changed the output folder"


# --- parameter files ------------------------------------------------------------------------------

#: name: (file content, or None for a folder, or False for no file; words naming the problem).
PARAMS = {
    "empty": ("", ["is empty"]),
    "binary": (BINARY, ["not a TOML text file"]),
    "cut before its end": (GOOD_PARAMS[:GOOD_PARAMS.index("slope =")], ["missing parameter"]),
    "cut inside a list": (GOOD_PARAMS[:GOOD_PARAMS.index("com_offset =") + 20], ["not valid TOML"]),
    "a trajectory (mislabelled)": ("time,lean,steer,pitch_left,pitch_right,stance\n0,0,0,0,0,L\n",
                                   ["not valid TOML"]),
    "a camera file (mislabelled)": (CAMERA.read_text(), ["not valid TOML"]),
    "an unknown key": (GOOD_PARAMS.replace("[effects]", "bogus = 1\n\n[effects]"),
                       ["unknown parameter 'bogus'"]),
    "NaN": (_set(GOOD_PARAMS, "leg_mass", "nan"), ["leg_mass must be finite"]),
    "a number as a string": (_set(GOOD_PARAMS, "leg_mass", '"0.05"'), ["leg_mass must be a number"]),
    "a short vector": (_set(GOOD_PARAMS, "com_offset", "[0.0, 0.1]"), ["com_offset must be a list of 3"]),
    "a folder": (None, ["cannot read parameter file"]),
    "missing": (False, ["parameter file not found"]),
}


def _params_argv(command, params, walk, video):
    if command == "gait":
        return ["gait", "--params", params]
    if command == "simulate":
        return ["simulate", "--params", params, "--steps", "3"]
    if command == "render":
        return ["render", walk, "--params", params]
    if command == "fit":
        return ["fit", walk, "--params", params, "--free", "foot_radius"]
    if command == "diagnose":
        return ["diagnose", walk, "--params", params]
    return ["track", video, "--camera", video.with_suffix(".camera.json"), "--markers",
            video.with_suffix(".markers.json"), "--params", params]


@pytest.mark.parametrize("case", PARAMS)
@pytest.mark.parametrize("command", ["gait", "simulate", "render", "fit", "diagnose", "track"])
def test_bad_parameter_file(command, case, walk, video, tmp_path, capfd):
    """A bad parameter file: one line naming it and the problem, nothing written."""
    content, words = PARAMS[case]
    params = tmp_path / "walker.toml"
    if content is not False:
        write(params, content)
    argv = _params_argv(command, params, walk, video) + _outputs(tmp_path, command)
    _refused_and_untouched(capfd, tmp_path, argv, [*words, "walker.toml"])


@pytest.mark.parametrize("case, value, words", [
    ("negative mass", ("leg_mass", "-0.05"), ["leg_mass must be >= 0"]),
    ("foot radius past the leg length", ("foot_radius", "0.2"), ["must be smaller than leg_length"]),
    ("lateral radius past the fore-aft one", ("foot_lateral_radius", "0.05"), ["must not exceed"]),
    ("slope of 90 degrees or more", ("slope", "1.6"), ["slope must lie in (-pi/2, pi/2)"]),
    ("no gravity", ("gravity", "0.0"), ["gravity must be > 0"]),
    ("no leg length", ("leg_length", "0.0"), ["leg_length must be > 0"]),
    ("inertia not positive", ("inertia", "[-1e-4, 1e-5, 2e-4, 0.0, 0.0, 0.0]"), ["positive semi-definite"]),
    ("inertia no body has", ("inertia", "[1e-4, 1e-4, 5e-4, 0.0, 0.0, 0.0]"), ["triangle inequality"]),
])
def test_impossible_parameters(case, value, words, tmp_path, capfd):
    """Physically impossible parameters: ``toywalk gait`` names the field in one line."""
    params = write(tmp_path / "walker.toml", _set(GOOD_PARAMS, *value))
    assert_refused(toywalk(capfd, "gait", "--params", params), *words)


def test_uphill_walker_has_no_gait(tmp_path, capfd):
    """A possible walker on an uphill ramp has no gait (nothing supplies the energy the collisions
    take): one line saying so, not a failed solver's output."""
    params = write(tmp_path / "walker.toml", _set(GOOD_PARAMS, "slope", "-0.05"))
    _refused_and_untouched(capfd, tmp_path, ["simulate", "--params", params, "--steps", "3",
                                             *_outputs(tmp_path, "simulate")], ["no gait found"])


def test_effect_outside_its_bounds(tmp_path, capfd):
    """An effect's strength outside its physical bounds: one line naming them."""
    assert_refused(toywalk(capfd, "gait", "--params", STABLE_TOY, "--effect", "hip_damping=-1"),
                   "physical bounds")


# --- trajectory files (the cases: tests/robustness/bad_trajectories.py) --------------------------

@pytest.mark.parametrize("case", TRAJECTORIES)
@pytest.mark.parametrize("command", ["render", "fit", "diagnose"])
def test_bad_trajectory(command, case, walk, tmp_path, capfd):
    """A bad trajectory (its CSV, events or metadata file): one line naming the file and, where
    there is one, the row and column; nothing written."""
    traj, words = bad_trajectory(walk, tmp_path, case)
    argv = {"render": ["render", traj, "--params", STABLE_TOY],
            "fit": ["fit", traj, "--params", STABLE_TOY, "--free", "foot_radius"],
            "diagnose": ["diagnose", traj, "--params", STABLE_TOY]}[command]
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, command), words)


@pytest.mark.parametrize("command", ["render", "fit", "diagnose"])
def test_trajectory_given_as_another_kind_of_file(command, tmp_path, capfd):
    """A camera file where a trajectory belongs: refused by its name, before it is read."""
    argv = [command, CAMERA, "--params", STABLE_TOY] + (["--free", "foot_radius"] if command == "fit" else [])
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, command), [".csv"])


@pytest.mark.parametrize("command", ["fit", "diagnose"])
def test_walk_with_too_few_heel_strikes(command, walk, tmp_path, capfd):
    """A readable walk that cannot be fitted (one heel strike): one line, before any progress
    line or fit."""
    traj = tmp_path / "walk.csv"
    traj.write_bytes(walk.read_bytes())
    events = walk.with_name("walk.events.csv").read_text().splitlines()
    (tmp_path / "walk.events.csv").write_text("\n".join(events[:2]) + "\n")
    argv = [command, traj, "--params", STABLE_TOY] + (["--free", "foot_radius"] if command == "fit" else [])
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, command),
                           ["1 heel strike(s)", "at least 3"])


@pytest.mark.parametrize("option, value, words", [
    ("--effects", "warp_drive", ["unknown effect 'warp_drive'"]),
    ("--parameters", "com_offset[9]", ["has no such component"]),
    ("--free", "bogus", ["'bogus' is not a parameter"]),
    ("--alpha", "1.5", ["--alpha must be"]),
])
def test_diagnose_refuses_bad_names_before_fitting(option, value, words, walk, tmp_path, capfd):
    """Misspelt names and impossible settings are refused at once: one line, no progress line
    (they were refused only after the periodicity test's fits, or escaped as a traceback)."""
    argv = ["diagnose", walk, "--params", STABLE_TOY, option, value, *_outputs(tmp_path, "diagnose")]
    _refused_and_untouched(capfd, tmp_path, argv, words)


@pytest.mark.parametrize("prior, words", [
    ("effects.hip_damping=-1e-4,1e-4", ["mean -0.0001 outside the parameter's bounds [0, 1]"]),
    ("foot_radius=0.02,1e-3", ["a prior on 'foot_radius', which is not free"]),
    ("effects.hip_damping=1e-4,0", ["needs a finite mean and a positive sd"]),
    ("effects.hip_damping", ["--prior expects NAME=MEAN,SD"]),
])
def test_fit_refuses_a_bad_prior(prior, words, walk, tmp_path, capfd):
    """A prior whose mean the parameter cannot take (here a negative damping: a sign slipped), on a
    parameter not free, with no spread or not written NAME=MEAN,SD: one line, nothing written."""
    argv = ["fit", walk, "--params", STABLE_TOY, "--free", "effects.hip_damping", "--prior", prior,
            *_outputs(tmp_path, "fit")]
    _refused_and_untouched(capfd, tmp_path, argv, words)


# --- camera and marker layout files ---------------------------------------------------------------

_CAMERA = json.loads(CAMERA.read_text())
_LAYOUT = json.loads(MARKERS.read_text())

#: name: (content: text, bytes, a JSON-ready object, None for a folder or False for none; words).
CAMERAS = {
    "empty": ("", ["cannot read camera file"]),
    "binary": (BINARY, ["cannot read camera file"]),
    "cut short": (CAMERA.read_text()[:150], ["cannot read camera file"]),
    "a 2x3 matrix": ({**_CAMERA, "camera_matrix": [[1000, 0, 640], [0, 1000, 360]]}, ["3x3"]),
    "NaN in the matrix": (CAMERA.read_text().replace("1372.4844291261174", "NaN", 1),
                          ["camera_matrix must be a list of finite numbers"]),
    "an infinite image size": ({**_CAMERA, "image_size": [1e999, 720]}, ["image size"]),
    "a fractional image size": ({**_CAMERA, "image_size": [1280.5, 720]}, ["image size"]),
    "three distortion coefficients": ({**_CAMERA, "distortion": [0.0, 0.0, 0.0]}, ["4, 5, 8, 12 or 14"]),
    "a ramp pose without tvec": ({**_CAMERA, "ramp_pose": {"rvec": [0, 0, 0]}}, ["ramp_pose"]),
    "a marker layout (mislabelled)": (_LAYOUT, ["missing key(s) image_size"]),
    "a JSON list": ([1, 2], ["must hold a JSON object"]),
    "nested too deep": ("[" * 100_000 + "]" * 100_000, ["cannot read camera file"]),
    "a folder": (None, ["cannot read camera file"]),
    "missing": (False, ["camera file not found"]),
}

LAYOUTS = {
    "empty": ("", ["cannot read marker layout file"]),
    "binary": (BINARY, ["cannot read marker layout file"]),
    "cut short": (MARKERS.read_text()[:300], ["cannot read marker layout file"]),
    "a duplicate id": ({**_LAYOUT, "markers": _LAYOUT["markers"] + _LAYOUT["markers"][:1]},
                       ["marker id 0 appears more than once"]),
    "an id outside the dictionary": ({**_LAYOUT, "markers": [{**_LAYOUT["markers"][0], "id": 50}]},
                                     ["marker id 50 is not in DICT_4X4_50"]),
    "an unknown dictionary": ({**_LAYOUT, "dictionary": "DICT_9X9_1"}, ["ArUco dictionary"]),
    "a side as a string": ({**_LAYOUT, "markers": [{**_LAYOUT["markers"][0], "side": "0.075"}]},
                           ["side must be a number"]),
    "an unknown body": ({**_LAYOUT, "markers": [{**_LAYOUT["markers"][0], "body": "head"}]},
                        ["body must be one of"]),
    "NaN in a pose": ({**_LAYOUT, "markers": [{**_LAYOUT["markers"][0], "tvec": [0, float("nan"), 0]}]},
                      ["tvec must be three finite numbers"]),
    "no markers": ({**_LAYOUT, "markers": []}, ["non-empty list"]),
    "a camera file (mislabelled)": (_CAMERA, ["unknown key(s)"]),
    "a folder": (None, ["cannot read marker layout file"]),
    "missing": (False, ["marker layout file not found"]),
}


def _json_file(path, content):
    if content is not False:
        write(path, json.dumps(content) if isinstance(content, (dict, list)) else content)
    return path


@pytest.mark.parametrize("case", CAMERAS)
@pytest.mark.parametrize("command", ["render", "track"])
def test_bad_camera_file(command, case, walk, video, tmp_path, capfd):
    """A bad camera file: one line naming the file and the field, nothing written."""
    content, words = CAMERAS[case]
    camera = _json_file(tmp_path / "cam.json", content)
    argv = (["render", walk, "--params", STABLE_TOY, "--camera", camera] if command == "render" else
            ["track", video, "--camera", camera, "--markers", video.with_suffix(".markers.json")])
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, command), words)


@pytest.mark.parametrize("case", LAYOUTS)
@pytest.mark.parametrize("command", ["render", "track"])
def test_bad_marker_layout(command, case, walk, video, tmp_path, capfd):
    """A bad marker layout: one line naming the file and the marker or key, nothing written."""
    content, words = LAYOUTS[case]
    layout = _json_file(tmp_path / "layout.json", content)
    argv = (["render", walk, "--params", STABLE_TOY, "--markers", layout] if command == "render" else
            ["track", video, "--camera", video.with_suffix(".camera.json"), "--markers", layout])
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, command), words)


@pytest.mark.parametrize(("value", "words"), [
    ("abc", ["--exposure", "seconds", "'abc'"]), ("0", ["--exposure", "positive"]),
    ("=-1/150", ["--exposure", "positive"]), ("1/0", ["--exposure", "seconds"]),
    ("nan", ["--exposure", "positive"]),
    ("1/10", ["--exposure 1/10", "longer than the frame interval"]),  # the video is at 30 frames/s
])
def test_bad_exposure(value, words, video, tmp_path, capfd):
    """``track --exposure`` that is no shutter time, or one longer than a frame: one line naming
    it, nothing written."""
    # a value starting with '-' goes as --exposure=VALUE, else argparse takes it for an option
    argv = ["track", video, "--camera", video.with_suffix(".camera.json"), "--markers",
            video.with_suffix(".markers.json")]
    argv += [f"--exposure{value}"] if value.startswith("=") else ["--exposure", value]
    _refused_and_untouched(capfd, tmp_path, argv + _outputs(tmp_path, "track"), words)


def test_track_does_not_overwrite_the_videos_own_files(video, tmp_path, capfd):
    """``track V.mp4 --out V.csv`` would write its metadata over the V.json render wrote beside the
    video (which holds the shutter time ``track`` reads): refused in one line, nothing written; as
    is an overlay over the video itself."""
    copy = tmp_path / "v.mp4"
    for name in ("tiny.mp4", "tiny.json", "tiny.camera.json", "tiny.markers.json"):
        (tmp_path / name.replace("tiny", "v")).write_bytes((video.parent / name).read_bytes())
    for extra in (["--out", copy.with_suffix(".csv")], ["--out", tmp_path / "m.csv", "--overlay", copy]):
        before = snapshot(tmp_path)
        outcome = toywalk(capfd, "track", copy, *extra)
        assert_refused(outcome, "would overwrite the input", "choose another --out name")
        assert snapshot(tmp_path) == before


def test_track_states_the_exposure(video, tmp_path, capfd):
    """The shutter time goes into M.json as ``exposure_s`` (what the fit reads) and into the summary
    line: from ``--exposure`` as given, from the metadata render wrote beside its video (0.4 of a
    frame at 30 frames/s by default), and not stated for a video without one."""
    base = ["track", video, "--camera", video.with_suffix(".camera.json"), "--markers",
            video.with_suffix(".markers.json")]
    for extra, seconds, said in ((["--exposure", "1/100"], 0.01, "exposure 1/100 s (--exposure)"),
                                 ([], 0.4 / 30, "exposure 1/75 s (tiny.json, written by render")):
        out = tmp_path / f"m{len(extra)}.csv"
        outcome = toywalk(capfd, *base, *extra, "--out", out)
        assert outcome.code == 0 and said in outcome.out, outcome.out
        assert json.loads(out.with_suffix(".json").read_text())["exposure_s"] == pytest.approx(seconds)
    alone = tmp_path / "alone.mp4"
    alone.write_bytes(video.read_bytes())  # the same frames, no render metadata beside them
    outcome = toywalk(capfd, *base[:1], alone, *base[2:], "--out", tmp_path / "alone.csv")
    assert outcome.code == 0 and "exposure not stated" in outcome.out, outcome.out
    assert "exposure_s" not in json.loads((tmp_path / "alone.json").read_text())


# --- videos and images ----------------------------------------------------------------------------

def _png() -> bytes:
    return cv2.imencode(".png", np.full((240, 320, 3), 200, np.uint8))[1].tobytes()


#: name: (content as a function of the good video's bytes, or None (folder) or False (none); words).
VIDEOS = {
    "random bytes": (lambda good: np.random.default_rng(0).bytes(len(good)), ["not an MP4 file"]),
    "zero bytes": (lambda good: b"", ["the file is empty"]),
    "cut in half": (lambda good: good[:len(good) // 2], ["cannot open video"]),
    "cut at its start": (lambda good: good[len(good) // 3:], ["not an MP4 file"]),
    "a trajectory (mislabelled)": (lambda good: b"time,lean\n0,0\n", ["not an MP4 file"]),
    "an image (mislabelled)": (lambda good: _png(), ["not an MP4 file"]),
    "a folder": (None, ["not a video file"]),
    "missing": (False, ["video file not found"]),
}


@pytest.mark.parametrize("case", VIDEOS)
def test_bad_video(case, video, tmp_path, capfd):
    """``toywalk track`` of a video that is not one (or no longer a whole one): one line, no
    trajectory, no overlay, stored ones kept."""
    content, words = VIDEOS[case]
    bad = tmp_path / "walk.mp4"
    if content is not False:
        write(bad, None if content is None else content(video.read_bytes()))
    argv = ["track", bad, "--camera", video.with_suffix(".camera.json"), "--markers",
            video.with_suffix(".markers.json"), *_outputs(tmp_path, "track")]
    _refused_and_untouched(capfd, tmp_path, argv, words)


def test_video_of_another_size(video, tmp_path, capfd):
    """A camera file for another image size than the video's (the default 1280x720 camera for a
    320x240 video): one line naming both sizes."""
    argv = ["track", video, "--camera", CAMERA, "--markers", video.with_suffix(".markers.json"),
            *_outputs(tmp_path, "track")]
    _refused_and_untouched(capfd, tmp_path, argv, ["320x240", "1280x720"])


@pytest.mark.parametrize("case, content, words", [
    ("random bytes", BINARY, ["not an image file"]),
    ("zero bytes", b"", ["not an image file"]),
    ("a text file", "time,lean\n", ["not an image file"]),
    ("a folder", None, ["not an image file"]),
    ("missing", False, ["image not found"]),
    ("an image without the board", _png(), ["usable view"]),
])
def test_bad_calibration_image(case, content, words, tmp_path, capfd):
    """``toywalk calibrate`` of a file that is not an image of the board: one line, and a camera
    file already at ``--out`` kept."""
    image = tmp_path / "view.png"
    if content is not False:
        write(image, content)
    _refused_and_untouched(capfd, tmp_path, ["calibrate", image, *_outputs(tmp_path, "calibrate")], words)


# --- outputs --------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, words", [
    (["simulate", "--params", STABLE_TOY, "--steps", "2", "--out", "{tmp}/walk.txt"], [".csv"]),
    (["simulate", "--params", STABLE_TOY, "--steps", "2", "--out", "{tmp}/no/walk.csv"],
     ["output folder does not exist"]),
    (["fit", "{walk}", "--params", STABLE_TOY, "--free", "foot_radius", "--out", "{tmp}/fit.csv"],
     [".json"]),
    (["render", "{walk}", "--params", STABLE_TOY, "--out", "{tmp}/video.gif"], [".mp4 or .avi"]),
    (["diagnose", "{walk}", "--params", STABLE_TOY, "--out", "{tmp}/stored.txt"], ["must name a folder"]),
    (["demo", "--out", "{tmp}/stored.txt"], ["must name a folder"]),
])
def test_bad_output_path(argv, words, walk, tmp_path, capfd):
    """An output path of the wrong kind, or in a folder that does not exist: one line, and a file
    already there is kept."""
    (tmp_path / "stored.txt").write_bytes(STORED)
    argv = [str(a).format(tmp=tmp_path, walk=walk) for a in argv]
    _refused_and_untouched(capfd, tmp_path, argv, words)


def test_console_script_prints_one_line(walk, tmp_path):
    """Through the installed console script (a separate process: what a user or another tool
    runs): a random-bytes video and a binary parameter file each give one line on stderr and
    exit status 2 — no traceback, no FFmpeg or decoder chatter."""
    (tmp_path / "v.mp4").write_bytes(np.random.default_rng(1).bytes(20000))
    (tmp_path / "p.toml").write_bytes(BINARY)
    for argv in (["track", tmp_path / "v.mp4", "--out", tmp_path / "m.csv"],
                 ["simulate", "--params", tmp_path / "p.toml", "--steps", "2", "--out", tmp_path / "w.csv"]):
        r = subprocess.run([TOYWALK, *map(str, argv)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("toywalk "), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.toml", "v.mp4"]
