"""`toywalk gait --basin`: the basin and hand launch of model/basin.py, printed and in JSON
(docs/cli.md; the numbers: docs/gaits.md section 5)."""

import json

import pytest

from ..conftest import DATA
from .command import run

CLEARING = DATA / "params" / "clearing-toy.toml"


def test_gait_basin_reports_radii_and_launches():
    out = run("gait", "--params", CLEARING, "--basin", "--directions", "2", "--json")
    assert out.returncode == 0, out.stderr
    basin = json.loads(out.stdout)["basin"]
    # docs/gaits.md section 5: 0.013 .. 0.24 along the 14 eigenvector directions
    assert len(basin["eigenvectors"]) == 14
    assert basin["eigenvector_radius"]["min"] == pytest.approx(0.013, abs=5e-4)
    assert basin["eigenvector_radius"]["max"] == pytest.approx(0.24, abs=5e-3)
    assert basin["random"]["n"] == 2 and len(basin["random"]["radii"]) == 2
    assert basin["scuffs_fail"] is True  # the clearing toy's gait does not scuff
    multiples = [round(row["tip_over_lean"], 9) for row in basin["hand_launch"]]
    assert 1.5 in multiples and 2.5 in multiples
    assert not any(row["recovered"] for row in basin["hand_launch"])  # docs/gaits.md section 5


def test_gait_basin_prints_it():
    out = run("gait", "--params", CLEARING, "--basin", "--directions", "1", "--seed", "3")
    assert out.returncode == 0, out.stderr
    assert "along eigenvectors" in out.stdout and "(1 directions, seed 3)" in out.stdout
    assert out.stdout.count("hand launch tipped") == 6
