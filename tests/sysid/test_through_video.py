"""Through video on a walker the demo was not built for (docs/diagnosis.md, "Through video"): the
toy-sized walker (data/params/toy-sized.toml) walked 16 steps from its gait with hip damping 1e-4
hidden, and with nothing hidden, filmed as the README films (`render --fps 120 --noise 1 --seed
0`) and tracked back (`track`); the files here are those tracks as they came (`through_video/
effect.*`, `null.*`), the render's heel strikes (`*.truth.events.csv`) and the tracker's errors
measured by `toywalk accuracy --like` on five renders of the walker's own gait with other seeds
(`accuracy.json`, seeds 100-104). The analysis sees the tracks with those errors carried, as
`track --accuracy` writes them; `diagnose` runs with its defaults and the foot radius and
lateral mass offset free, as docs/make_video_validation.py runs it over five seeds (there: 5 of 5
named with the interval holding the truth, 4 of 5 walks with nothing hidden adequate).

Tracked as they came, without the carried errors, the same walks once named the effect and
then called it `unexplained` for the tracker's own pattern repeated every step (issue 45)."""

import csv
import json

import numpy as np
import pytest
from toywalk.model.trajectory import read_trajectory, write_trajectory
from toywalk.tracking.accuracy import match_strikes
from toywalk.tracking.accuracy_phase import load_phase_errors

from ..conftest import DATA
from .command import run

HERE = DATA.parent / "tests" / "sysid" / "through_video"
PARAMS = DATA / "params" / "toy-sized.toml"
TRUTH = 1e-4  # N m s/rad, the hidden hip damping


def _carried(kind: str, folder):
    """The track as `track --accuracy accuracy.json` writes it (the tracker is deterministic:
    the same angles and strikes, with the errors carried)."""
    out = folder / f"{kind}.csv"
    errors = load_phase_errors(HERE / "accuracy.json")
    write_trajectory(errors.apply(read_trajectory(HERE / f"{kind}.csv"), note="accuracy.json"), out)
    return out


def _diagnosed(kind: str, folder) -> dict:
    done = run("diagnose", _carried(kind, folder), "--params", PARAMS, "--free", "foot_radius,com_offset[1]",
               "--out", folder / "report")
    assert done.returncode in (0, 1), done.stderr
    return json.loads((folder / "report" / "report.json").read_text())


@pytest.mark.slow
def test_the_hidden_hip_damping_is_named_through_video(tmp_path):
    report = _diagnosed("effect", tmp_path)
    assert report["verdict"] == "discrepancy" and report["cause"] == "effects.hip_damping", report["cause"]
    row = next(r for r in report["ranking"] if r["effect"] == "effects.hip_damping")
    low, high = row["interval"]["effects.hip_damping"]
    assert low <= TRUTH <= high, (low, high)
    # The interval carries the tracker's errors shared by phase (measured 1.9 times as wide as with
    # every sample's error its own, docs/diagnosis.md): an interval that ignored them would miss.
    assert row["shared_widening"] > 1.2


@pytest.mark.slow
def test_nothing_hidden_is_adequate_through_video(tmp_path):
    report = _diagnosed("null", tmp_path)
    assert report["verdict"] == "adequate", (report["verdict"], report.get("cause"))


def test_heel_strike_times_are_as_uncertain_as_stated():
    """Carried, the strikes' time errors over their time_sd have an RMS between 0.7 and 1.5 (the
    issue's range; these two walks: 1.47 with the effect, 0.97 without, 1.24 together); as they
    came the SDs are the tracker's own."""
    z = []
    errors = load_phase_errors(HERE / "accuracy.json")
    for kind in ("effect", "null"):
        tracked = errors.apply(read_trajectory(HERE / f"{kind}.csv"), note="accuracy.json")
        with open(HERE / f"{kind}.truth.events.csv", newline="") as fh:
            truth = [{"time": float(r["time"]), "foot": r["foot"]} for r in csv.DictReader(fh)]
        step = float(np.median(np.diff([e["time"] for e in truth])))
        found = match_strikes(truth, tracked.events, step, float(np.median(np.diff(tracked.time))))
        assert found["missed"] == 0 and found["invented"] == 0
        z += [v for values in found["timing_z_by_foot"].values() for v in values]
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert len(z) == 30 and 0.7 <= rms <= 1.5, rms
