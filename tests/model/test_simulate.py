"""Forward simulation over many steps and the trajectory files."""


import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory

from ..conftest import DATA, loaded_by


@pytest.fixture(scope="module")
def compass():
    params = load_params(DATA / "params" / "compass-3d.toml")
    return params, find_gait(params)


def test_gait_repeats_step_after_step(compass):
    """From the fixed point, heel strikes come every step_time and the walker advances one step
    length per step; legs alternate; lean alternates sign with the stance leg (mirror symmetry)."""
    params, gait = compass
    traj = simulate(params, gait.fixed_point, 6, sample_rate=500.0)
    assert traj.status == "completed"
    times = np.array([e.time for e in traj.events])
    # The gait is unstable (|lambda| ~ 2.7): a 1e-12 fixed-point error grows to ~ 1e-9 in 6 steps.
    assert_allclose(np.diff(np.r_[0.0, times]), gait.step_time, rtol=1e-8)
    assert [e.foot for e in traj.events] == ["R", "L", "R", "L", "R", "L"]
    xs = np.array([e.x for e in traj.events])
    assert_allclose(np.diff(np.r_[0.0, xs]), gait.stride_length / 2, rtol=1e-7)
    # Mirror symmetry: lean at a sample in step 1 equals minus lean at the same phase of step 2.
    k = np.searchsorted(traj.times, 0.3 * gait.step_time)
    k2 = np.searchsorted(traj.times, 1.3 * gait.step_time)
    assert abs(traj.lean[k] + traj.lean[k2]) < 2e-3 * abs(traj.lean[k]) + 1e-4
    assert set(traj.stance) == {"L", "R"}


def test_unstable_gait_falls_with_status(compass):
    params, gait = compass
    z = gait.fixed_point.copy()
    z[3] += 0.3  # a lean-rate kick; the gait's lean mode grows by ~2.7 per step
    traj = simulate(params, z, 60)
    assert traj.status in ("fell", "no_heel_strike")
    assert len(traj.events) < 60
    assert len(traj.times) > 0  # the partial trajectory is kept


def test_trajectory_files_round_trip(compass, tmp_path):
    params, gait = compass
    traj = simulate(params, gait.fixed_point, 2, sample_rate=200.0)
    left, right = traj.pitches()
    signals = {"lean": traj.lean, "steer": traj.steer, "pitch_left": left, "pitch_right": right,
               "contact_x": traj.contact[:, 0], "contact_y": traj.contact[:, 1]}
    signals["lean"] = signals["lean"].copy()
    signals["lean"][3] = np.nan  # a gap: written as an empty cell, read back as NaN
    events = [{"time": e.time, "foot": e.foot, "x": e.x, "y": e.y} for e in traj.events]
    table = TrajectoryTable(traj.times, signals, traj.stance, events, {"units": {"time": "s"}})
    paths = write_trajectory(table, tmp_path / "walk.csv")
    assert [p.name for p in paths] == ["walk.csv", "walk.events.csv", "walk.json"]
    back = read_trajectory(tmp_path / "walk.csv")
    assert_allclose(back.time, traj.times, rtol=0, atol=0)
    assert np.isnan(back.signals["lean"][3])
    assert_allclose(back.signals["pitch_left"], left, rtol=0, atol=0)  # repr round-trips floats
    assert list(back.stance) == list(traj.stance)
    assert [e["foot"] for e in back.events] == [e.foot for e in traj.events]
    header = (tmp_path / "walk.csv").read_text().splitlines()[0]
    assert header.startswith("time,lean,steer,pitch_left,pitch_right,stance")
    # simulated strikes are exact: the events file keeps its four columns (docs/formats.md); measured
    # ones (the tracker's) add their time_sd, read back too
    assert (tmp_path / "walk.events.csv").read_text().splitlines()[0] == "time,foot,x,y"
    assert all("time_sd" not in e for e in back.events)
    measured = [{**e, "time_sd": 0.001 * (i + 1)} for i, e in enumerate(events)]
    measured[0]["time_sd"] = np.nan
    write_trajectory(TrajectoryTable(traj.times, signals, traj.stance, measured, {}), tmp_path / "m.csv")
    assert (tmp_path / "m.events.csv").read_text().splitlines()[0] == "time,foot,x,y,time_sd"
    back_sd = [e["time_sd"] for e in read_trajectory(tmp_path / "m.csv").events]
    assert np.isnan(back_sd[0]) and back_sd[1:] == [e["time_sd"] for e in measured[1:]]


def test_reading_a_trajectory_does_not_load_casadi():
    """A tool that only reads trajectories (a plotting script, the robustness suite's readers)
    should not pay CasADi's import (1.1 s): toywalk.model loads its submodules on first use. The
    same check fails when toywalk.model imports them eagerly, as it did."""
    code = ("from toywalk.model.trajectory import read_trajectory; "
            f"t = read_trajectory({str(DATA / 'sample' / 'walk.truth.csv')!r}); "
            "assert len(t.time) > 100")
    assert loaded_by(code, "casadi") == {"casadi": False}


def test_the_tracker_and_a_parameter_file_do_not_load_casadi():
    """``toywalk track`` and ``render`` read parameter files, whose effects table names the effect
    library: CasADi is imported only where an effect builds an expression (model/effects), so the
    tracker does not pay its import. The same check failed while the effects imported it at the
    top (toywalk.model.parameters -> toywalk.model.effects)."""
    code = ("import toywalk.tracking.track, toywalk.tracking.render; "
            "from toywalk.model.parameters import load_params; "
            f"p = load_params({str(DATA / 'params' / 'stable-toy.toml')!r}); "
            "assert p.leg_length > 0")
    assert loaded_by(code, "casadi") == {"casadi": False}
