"""The synthetic video renderer: its truth is where the camera model says, options, files, CLI."""

import json
import math

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.kinematics import leg_poses
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory
from toywalk.model.walker import Walker
from toywalk.sysid.cli import main
from toywalk.tracking.camera import Camera, default_camera, load_camera, project, save_camera
from toywalk.tracking.markers import default_layout, load_layout, marker_corners
from toywalk.tracking.render import BLUR_STEP_PX, Filming, Motion, RenderError, RenderOptions, render
from toywalk.tracking.scene import Scene, default_camera_for, look_at

from ..conftest import DATA

COMPASS = DATA / "params" / "compass-3d.toml"
BODY = {"left_leg": "L", "right_leg": "R", "ramp": "ramp"}


@pytest.fixture(scope="module")
def compass():
    return load_params(COMPASS)


def _walk(params, duration=0.4, n=41, switch=None) -> TrajectoryTable:
    """A made-up (not dynamically consistent) stretch of walking: both pitches swing, the walker
    leans and steers, the stance foot's contact creeps forward; optionally a heel strike."""
    t = np.linspace(0.0, duration, n)
    signals = {"lean": 0.06 * np.sin(2 * np.pi * t / 0.9), "steer": 0.1 * np.sin(2 * np.pi * t / 0.9 + 1),
               "pitch_left": -0.2 + 0.9 * t, "pitch_right": 0.2 - 0.9 * t,
               "contact_x": 0.05 * t, "contact_y": np.zeros(n)}
    stance = np.full(n, "L")
    events = []
    if switch is not None:
        stance[t >= switch] = "R"
        events = [{"time": switch, "foot": "R", "x": math.nan, "y": math.nan}]
        # contact of the right foot after the switch: its lowest point at the switch
        k = int(np.searchsorted(t, switch))
        for i in range(k, n):
            poses = leg_poses(params, signals["steer"][i], signals["lean"][i], signals["pitch_left"][i],
                              signals["pitch_right"][i], "L", (signals["contact_x"][i], 0.0))
            o = poses.foot_centre["R"]
            signals["contact_x"][i], signals["contact_y"][i] = o[0], o[1]  # spherical foot: below O
    return TrajectoryTable(t, signals, stance, events, {"source": {"kind": "test"}})


def _detector(layout):
    par = cv2.aruco.DetectorParameters()
    par.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(layout.aruco_dictionary(), par)


def test_markers_are_drawn_where_the_camera_model_projects_them(compass):
    """The key check of the renderer's truth: ArUco finds every leg marker of a noise-free frame,
    drawn with lens distortion, at the corners camera.project gives for the true leg poses.

    Tolerance: ArUco's own sub-pixel corner refinement is biased by 0.1-0.25 px for 30-120 px
    markers (measured on ideal pixel-aligned markers), so 0.35 px RMS over all corners and 0.6 px
    for any one marker; the mean offset (a half-pixel convention error would show there) < 0.1 px.
    """
    layout = default_layout(compass)
    motion = Motion(_walk(compass), compass)
    state = motion.state(0.2)
    target = 0.5 * (state.hip["L"] + state.hip["R"]) + [0, 0, -0.2]
    az, el = math.radians(35), math.radians(25)
    position = target + 1.6 * np.array([math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az),
                                        math.sin(el)])
    base = default_camera(1280, 720, 45.0, distortion=(-0.08, 0.03, 0.0, 0.0, 0.0))
    camera = Camera(1280, 720, base.matrix, base.distortion,
                    ramp_pose=look_at(position, target, np.array([0.0, 0.0, 1.0])))
    scene = Scene(compass, layout, camera)
    detector = _detector(layout)
    diffs, seen = [], set()
    for t in (0.0, 0.2, 0.4):
        state = motion.state(t)
        img = scene.finish(scene.draw(state))
        assert img.shape == (720, 1280, 3)
        poses = scene.body_poses(state)
        corners, ids, _ = detector.detectMarkers(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
        assert ids is not None
        for c, i in zip(corners, ids.ravel(), strict=True):
            marker = layout.by_id(int(i))
            rot, tvec = poses[BODY[marker.body]]
            truth = project(camera, marker_corners(marker), cv2.Rodrigues(rot)[0], tvec)
            d = c.reshape(4, 2) - truth
            assert np.sqrt(np.mean(np.sum(d**2, axis=1))) < 0.6, (t, int(i), d)
            diffs.append(d)
            seen.add(int(i))
    assert {m.id for m in layout.on("left_leg") + layout.on("right_leg")} <= seen
    diffs = np.concatenate(diffs)
    assert np.sqrt(np.mean(np.sum(diffs**2, axis=1))) < 0.35
    assert np.all(np.abs(diffs.mean(axis=0)) < 0.1)


def test_default_camera_sees_every_marker_on_a_real_walk_frame(compass):
    """With the bundled camera and layout (both derived from the parameters), ArUco finds all four
    leg markers and at least four ramp markers at the start of a walk."""
    camera = load_camera(DATA / "camera" / "default.json")
    assert_allclose(camera.matrix, default_camera_for(compass).matrix)
    assert_allclose(np.concatenate(camera.ramp_pose), np.concatenate(default_camera_for(compass).ramp_pose),
                    atol=1e-8)
    layout = load_layout(DATA / "markers" / "default.json")
    film = Filming(_walk(compass), compass, camera, layout, RenderOptions.preset(0, duration=0.05))
    _, ids, _ = _detector(layout).detectMarkers(cv2.cvtColor(film.frame(0), cv2.COLOR_BGR2GRAY))
    ids = set(ids.ravel().tolist())
    assert {0, 1, 2, 3} <= ids
    assert len(ids & {m.id for m in layout.on("ramp")}) >= 4


# The stable walker's gait (data/params/stable-toy.toml, public state order) to six digits: near
# enough for three steps. Its torus feet make the contact's offset from the foot centre turn with
# the foot, so the rolling rule matters (for the compass walker's spheres it is constant).
STABLE_GAIT = [0.0466179, -0.514168, -0.00187678, 0.0217185, -0.086945, 4.23107, 0.0813509, 2.39133]
MIRROR = np.diag([1.0, -1.0, 1.0])


def _model_points(walker, steer, lean, pitch_left, pitch_right, stance):
    """The walker's points relative to the stance contact from the symbolic model (Walker.points:
    rows C, O1, H1, axle, H2, O2, C2, ...), in the physical frame: the model describes a right-leg
    stance mirrored (docs/model.md section 4)."""
    if stance == "L":
        return walker.points(np.array([steer, lean, pitch_left, pitch_right, 0, 0, 0, 0, 0, 0]))
    return walker.points(np.array([-steer, -lean, pitch_right, pitch_left, 0, 0, 0, 0, 0, 0])) @ MIRROR


def test_motion_places_the_legs_where_the_model_does(compass):
    """At the samples, the placed hips are the symbolic model's (an implementation independent of
    model.kinematics, which Motion uses), and so are the feet: a foot centre lies l - r along the
    leg's b3 axis from its hip, so the rotations' b3 columns are checked too, and the hips' offset
    (w along b2) checks b2."""
    walker = Walker(compass)
    table = _walk(compass, switch=0.2)
    motion = Motion(table, compass)
    sig = table.signals
    for i in (0, 10, 25, 40):  # both stances: the switch is at sample 20
        t = table.time[i]
        state = motion.state(t)
        stance = str(table.stance[i])
        pts = _model_points(walker, sig["steer"][i], sig["lean"][i], sig["pitch_left"][i],
                            sig["pitch_right"][i], stance)
        contact = np.array([sig["contact_x"][i], sig["contact_y"][i], 0.0])
        other = "R" if stance == "L" else "L"
        # Positions of 0.5 m legs from two implementations: round-off, ~1e-16 m; 1e-12 m.
        for leg, hip_row, foot_row in ((stance, 2, 1), (other, 4, 5)):
            assert_allclose(state.hip[leg], contact + pts[hip_row], rtol=0, atol=1e-12)
            foot = state.hip[leg] - (compass.leg_length - compass.foot_radius) * state.rotation[leg][:, 2]
            assert_allclose(foot, contact + pts[foot_row], rtol=0, atol=1e-12)
        assert motion.stance_at(t) == stance
        assert_allclose(motion.contact(state, stance), contact[:2], rtol=0, atol=1e-12)


def test_motion_integrates_the_rolling_as_the_model_does():
    """Without contact columns Motion integrates the stance foot's rolling (trapezoidal) and, at a
    heel strike, puts the new contact at the landing foot's lowest point at the last sample before
    it. On three simulated steps (both stances) with the contact columns dropped: between heel
    strikes the contact advances as the model's integrated contact does, with the trapezoidal
    rule's order; across a heel strike it jumps as the rule says, by the model's swing foot's
    lowest point at the sample before."""
    params = load_params(DATA / "params" / "stable-toy.toml")
    walker = Walker(params)
    errors = {}
    for rate in (800.0, 1600.0):  # Hz
        # 64 integration steps per sqrt(l/g): the model's contact between them (cubic Hermite) is
        # then good to ~1e-12 m, below the rule's error at these rates (16 steps: ~1e-9 m).
        walk = simulate(params, np.array(STABLE_GAIT), steps=3, sample_rate=rate, steps_per_time_unit=64)
        assert walk.status == "completed"
        left, right = walk.pitches()
        signals = {"lean": walk.lean, "steer": walk.steer, "pitch_left": left, "pitch_right": right}
        motion = Motion(TrajectoryTable(walk.times, signals, walk.stance), params)
        assert motion.contact_source == "integrated rolling"
        placed = np.array([motion.contact(motion.state(t), str(s))
                           for t, s in zip(walk.times, walk.stance, strict=True)])
        within, strikes = [], 0
        for i in range(1, len(walk.times)):
            advance = placed[i] - placed[i - 1]
            if walk.stance[i] == walk.stance[i - 1]:
                within.append(np.max(np.abs(advance - (walk.contact[i] - walk.contact[i - 1]))))
            else:
                strikes += 1
                before = _model_points(walker, walk.steer[i - 1], walk.lean[i - 1], left[i - 1],
                                       right[i - 1], str(walk.stance[i - 1]))
                # The same geometry from two implementations: round-off, 1e-12 m.
                assert_allclose(advance, before[6, :2], rtol=0, atol=1e-12)
        assert strikes == 2
        errors[rate] = max(within)
    # The trapezoidal rule's error per sample interval is O(dt^3): measured 4.0e-10 m at 800 Hz and
    # 8.0x less at 1600 Hz. A first-order rule (forward Euler on the rolling) has O(dt^2): 7.1e-10 m
    # and 4x. 1e-9 m bounds the first; a ratio above 6 tells the orders apart.
    assert errors[800.0] < 1e-9
    assert errors[800.0] / errors[1600.0] > 6


def _small_camera(params):
    return default_camera_for(params, 320, 180)


def test_motion_blur_is_a_continuous_smear_not_ghosts(toy_params):
    """A blurred frame averages renders spread over the open shutter, enough of them that the
    walker's image moves at most BLUR_STEP_PX between neighbours: twice as many renders then
    change the frame by little, while the fewest asked for (3) leave ghosts that differ from the
    smear by far more. Pitch rates of 0.9 rad/s over a 0.2 s shutter (5 fps, exposure 1) move the
    legs' image by tens of pixels."""
    table = _walk(toy_params, duration=0.4, n=41)
    cam, layout = default_camera_for(toy_params, 640, 360), default_layout(toy_params)
    film = Filming(table, toy_params, cam, layout, RenderOptions(fps=5, blur_subframes=3, exposure=1.0), 0)
    frame = film.frame(1).astype(float)
    count, t, half = int(film.subframes[1]), float(film.times[1]), 0.1
    moved = np.max(np.linalg.norm(film.scene.walker_pixels(film.motion.state(t + half))
                                  - film.scene.walker_pixels(film.motion.state(t - half)), axis=1))
    assert moved > 10 * BLUR_STEP_PX
    assert moved / (count - 1) <= BLUR_STEP_PX < moved / (count - 2)  # enough renders, and no more

    def smear(n):
        acc = np.zeros(frame.shape)
        for dt in np.linspace(-half, half, n):
            acc += film.scene.finish(film.scene.draw(film.motion.state(t + dt))).astype(float)
        return acc / n

    finer, ghosts = np.abs(smear(2 * count - 1) - frame), np.abs(smear(3) - frame)
    # Halving a 1 px step moves each edge's share of the smear by at most 1/count of its contrast
    # (here about 200/28 = 7 grey levels; 3 measured) and leaves most pixels alone (0.02 mean);
    # the three ghosts differ from the smear by up to an edge's whole contrast (88 measured).
    assert finer.mean() < 0.1 and finer.max() < 8
    assert ghosts.max() > 5 * finer.max() and ghosts.mean() > 5 * finer.mean()


def test_options_change_the_image_reproducibly(toy_params):
    table = _walk(toy_params, duration=0.1, n=11)
    cam, layout = _small_camera(toy_params), default_layout(toy_params)

    def frames(options, seed):
        film = Filming(table, toy_params, cam, layout, options, seed)
        return np.array([film.frame(k) for k in range(len(film))]).astype(float), film

    clean, _ = frames(RenderOptions(fps=30), 0)
    noisy, _ = frames(RenderOptions(fps=30, noise_sd=6.0), 1)
    again, _ = frames(RenderOptions(fps=30, noise_sd=6.0), 1)
    other, _ = frames(RenderOptions(fps=30, noise_sd=6.0), 2)
    assert np.array_equal(noisy, again)  # the seed reproduces every frame
    assert not np.array_equal(noisy, other)
    # per-pixel Gaussian noise of SD 6 grey levels (rounding adds 1/12 variance; clipping is rare)
    assert np.std(noisy - clean) == pytest.approx(6.0, rel=0.05)
    flick, film = frames(RenderOptions(fps=30, flicker=0.1), 3)
    ratio = flick.mean(axis=(1, 2, 3)) / clean.mean(axis=(1, 2, 3))
    assert_allclose(ratio, film.gains, atol=0.01)  # the gain recorded is the gain applied (saturation)
    blurred, _ = frames(RenderOptions(fps=30, blur_subframes=5, exposure=1.0), 0)
    assert not np.array_equal(blurred, clean) and np.abs(blurred - clean).max() > 20
    occl, film = frames(RenderOptions(fps=30, occlusion=1.0), 4)
    assert film.occluders and not np.array_equal(occl, clean)
    jpeg, _ = frames(RenderOptions(fps=30, jpeg_quality=20), 0)
    assert 0 < np.abs(jpeg - clean).mean() < 10
    presets = [RenderOptions.preset(level) for level in (0, 1, 2, 3)]
    assert [p.noise_sd for p in presets] == sorted(p.noise_sd for p in presets)
    with pytest.raises(TypeError, match="unknown option"):
        RenderOptions.preset(1, nosie_sd=1.0)
    with pytest.raises(RenderError, match="noise level"):
        RenderOptions.preset(7)
    with pytest.raises(RenderError, match="exposure"):
        RenderOptions(exposure=2.0)


# a name with dots (walk.level1.mp4) keeps all of them in its files' names: walk.level1.json
@pytest.mark.parametrize("name, fourcc", [("v.mp4", "mp4v"), ("v.avi", "MJPG"), ("v.level1.mp4", "mp4v")])
def test_video_files_read_back(tmp_path, toy_params, name, fourcc):
    table = _walk(toy_params, duration=0.3, n=31, switch=0.15)
    out = tmp_path / name
    result = render(table, toy_params, _small_camera(toy_params), default_layout(toy_params),
                    RenderOptions.preset(1, fps=30), out, rng=7)
    assert result.n_frames == 10  # frames at 0, 1/30, ..., 9/30 s within [0, 0.3]
    cap = cv2.VideoCapture(str(out))
    read_as = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode().lower()
    assert read_as in {"mp4v": ("mp4v", "fmp4"), "MJPG": ("mjpg",)}[fourcc]  # FFmpeg says FMP4
    n = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        assert frame.shape == (180, 320, 3)
        n += 1
    cap.release()
    assert n == 10
    truth = read_trajectory(tmp_path / (out.stem + ".truth.csv"))
    assert_allclose(truth.time, np.arange(10) / 30)
    assert list(truth.stance) == ["L"] * 5 + ["R"] * 5  # heel strike at 0.15 s = frame 4.5
    assert truth.events[0]["foot"] == "R"
    meta = json.loads((tmp_path / (out.stem + ".json")).read_text())
    assert meta["frames"] == 10 and meta["seed"] == 7 and meta["codec"] == fourcc
    assert truth.metadata["frames"] == 10  # V.json is also the truth trajectory's metadata
    assert load_layout(tmp_path / (out.stem + ".markers.json")).dictionary == "DICT_4X4_50"
    assert load_camera(tmp_path / (out.stem + ".camera.json")).size == (320, 180)
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_write_video_gives_the_frames_and_their_truth(tmp_path, toy_params):
    """Filming.write_video (the studies' quick path): every frame in the file, in order, at the
    camera's size, and the true angles of each. Each frame read back, less the mean frame, is
    most like the frame of the same index drawn again with the same seed (correlation 0.82-0.92
    after MPEG-4 coding, at most 0.69 with any other frame)."""
    table = _walk(toy_params, duration=0.3, n=31, switch=0.15)

    def film():
        return Filming(table, toy_params, _small_camera(toy_params), default_layout(toy_params),
                       RenderOptions.preset(1, fps=30), 7)

    truth = film().write_video(tmp_path / "v.mp4")
    again = film()
    drawn = np.array([again.frame(k).astype(float) for k in range(len(again))])
    mean = drawn.mean(axis=0)
    drawn -= mean
    assert truth.shape == (10, 4)
    assert_allclose(truth, [again.truth(k)[0] for k in range(10)])
    cap = cv2.VideoCapture(str(tmp_path / "v.mp4"))
    for k in range(10):
        ok, frame = cap.read()
        assert ok and frame.shape == (180, 320, 3)
        likeness = [np.corrcoef(frame.ravel() - mean.ravel(), d.ravel())[0, 1] for d in drawn]
        assert np.argmax(likeness) == k and likeness[k] > 0.75, likeness
    assert not cap.read()[0]
    cap.release()


def test_interrupted_render_leaves_nothing(tmp_path, toy_params):
    def stop(k, n):
        if k == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render(_walk(toy_params, duration=0.3, n=31), toy_params, _small_camera(toy_params),
               default_layout(toy_params), RenderOptions(fps=30), tmp_path / "v.mp4", rng=0, progress=stop)
    assert list(tmp_path.iterdir()) == []


# --- the command line -----------------------------------------------------------------------------

@pytest.fixture
def walk_csv(tmp_path, compass):
    path = tmp_path / "walk.csv"
    write_trajectory(_walk(compass, duration=0.1, n=11), path)
    return path


def test_cli_renders(tmp_path, walk_csv, capsys):
    out = tmp_path / "out" / "v.mp4"
    out.parent.mkdir()
    code = main(["render", str(walk_csv), "--params", str(COMPASS), "--size", "320x180", "--fps", "30",
                 "--noise", "2", "--seed", "3", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert sorted(p.name for p in out.parent.iterdir()) == [
        "v.camera.json", "v.json", "v.markers.json", "v.mp4", "v.truth.csv", "v.truth.events.csv"]
    assert json.loads((out.parent / "v.json").read_text())["options"]["level"] == 2


def _bad_camera(tmp_path, compass):
    path = tmp_path / "cam.json"
    save_camera(default_camera_for(compass, 640, 360), path)
    return path


@pytest.mark.parametrize("case", ["missing trajectory", "bad params", "malformed camera", "size mismatch",
                                  "missing columns", "bad markers", "bad noise", "clobbers input",
                                  "bad suffix"])
def test_cli_bad_input_one_line_no_file(tmp_path, walk_csv, compass, capsys, case):
    out = tmp_path / "o" / "v.mp4"
    out.parent.mkdir()
    args = ["render", str(walk_csv), "--params", str(COMPASS), "--out", str(out)]
    if case == "missing trajectory":
        args[1] = str(tmp_path / "nope.csv")
    elif case == "bad params":
        bad = tmp_path / "p.toml"
        bad.write_text("leg_length = 1.0\nbogus = 2\n")
        args[3] = str(bad)
    elif case == "malformed camera":
        cam = tmp_path / "c.json"
        cam.write_text('{"image_size": [640, 360]}')
        args += ["--camera", str(cam)]
    elif case == "size mismatch":
        args += ["--camera", str(_bad_camera(tmp_path, compass)), "--size", "320x180"]
    elif case == "missing columns":
        walk_csv.write_text("time,lean,steer,pitch_left,stance\n0,0,0,0,L\n0.1,0,0,0,L\n")
    elif case == "bad markers":
        m = tmp_path / "m.json"
        m.write_text('{"dictionary": "DICT_4X4_50", "markers": []}')
        args += ["--markers", str(m)]
    elif case == "bad noise":
        args += ["--noise", "9"]
    elif case == "clobbers input":
        args[-1] = str(walk_csv.with_suffix(".mp4"))  # its V.json would be the trajectory's walk.json
    elif case == "bad suffix":
        args[-1] = str(out.with_suffix(".gif"))
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1, err
    assert list(out.parent.iterdir()) == []
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
