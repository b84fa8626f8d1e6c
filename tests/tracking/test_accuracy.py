"""Tracked-against-truth statistics on hand-made trajectories whose errors are known."""

import math

import numpy as np
import pytest
from toywalk.model.trajectory import SIGNALS, TrajectoryTable
from toywalk.tracking.accuracy import match_strikes, signal_errors


def _table(time, offset_deg, sd_deg=None, events=()):
    signals = {k: np.full(len(time), 0.1) + np.radians(offset_deg) for k in SIGNALS}
    if sd_deg is not None:
        signals.update({f"{k}_sd": np.full(len(time), np.radians(sd_deg)) for k in SIGNALS})
    return TrajectoryTable(time, signals, np.full(len(time), "L"), events)


def test_signal_errors_of_a_known_offset():
    t = np.arange(10) / 60
    truth = _table(t, 0.0)
    measured = _table(t, 0.2, sd_deg=0.1)
    measured.signals["lean"][[2, 5]] = np.nan  # two gaps
    measured.signals["steer"][3] += np.radians(1.0)  # one sample 1.2 deg off
    out = signal_errors(measured, truth)
    assert out["lean"]["gaps"] == 2 and out["lean"]["rms_deg"] == pytest.approx(0.2)
    assert out["lean"]["z_rms"] == pytest.approx(2.0)  # 0.2 deg errors over 0.1 deg SDs
    assert out["steer"]["max_deg"] == pytest.approx(1.2)
    assert out["steer"]["rms_deg"] == pytest.approx(math.sqrt((9 * 0.04 + 1.44) / 10))
    assert signal_errors(_table(t, 0.2), truth)["pitch_left"]["z_rms"] is None  # no SD column
    with pytest.raises(ValueError, match="sample times differ"):
        signal_errors(_table(t[:-1], 0.0), truth)


def test_strikes_matched_within_half_a_step():
    dt, step = 1 / 60, 0.4
    true = [{"time": 0.4 * k, "foot": "LR"[k % 2]} for k in range(1, 5)]
    measured = [{"time": 0.4 + 0.5 * dt, "foot": "R", "time_sd": 0.25 * dt},  # 0.5 frame late
                {"time": 0.8 - 0.25 * dt, "foot": "R", "time_sd": 0.25 * dt},  # wrong foot
                # 1.2 s missed: the nearest measured strike is more than half a step away
                {"time": 1.6, "foot": "L"},  # exact, no SD
                {"time": 2.5, "foot": "R"}]  # invented
    out = match_strikes(true, measured, step, dt)
    assert (out["true"], out["found"], out["missed"], out["invented"], out["wrong_foot"]) == (4, 4, 1, 1, 1)
    assert out["timing_rms_frames"] == pytest.approx(math.sqrt((0.25 + 0.0625 + 0) / 3))
    assert out["timing_max_frames"] == pytest.approx(0.5)
    assert out["timing_z_rms"] == pytest.approx(math.sqrt((4 + 1) / 2))  # the two with an SD
    assert match_strikes(true, [], step, dt)["missed"] == 4
