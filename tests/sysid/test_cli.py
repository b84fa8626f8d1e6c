"""The `toywalk` command line: outputs, and bad input giving one clear line and no output file."""

import json
import subprocess
import sys

import pytest

from ..conftest import DATA

SIMPLEST = DATA / "params" / "simplest-walker.toml"
COMPASS = DATA / "params" / "compass-3d.toml"


def run(*args):
    return subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=600)


def test_gait_json_has_the_documented_keys():
    out = run("gait", "--params", SIMPLEST, "--json")
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    for key in ("step_time", "stride_length", "fixed_point", "eigenvalues", "max_abs_eigenvalue",
                "can_stand", "status"):
        assert key in report
    assert set(report["fixed_point"]) == {"phi", "phi_dot", "psi", "psi_dot", "theta_st",
                                          "theta_st_dot", "theta_sw", "theta_sw_dot"}
    assert abs(report["step_time"] - 3.8824637528506) < 1e-6  # anchors.md, g = l = 1
    assert {"re", "im"} <= set(report["eigenvalues"][0])


def test_gait_text_output():
    out = run("gait", "--params", COMPASS)
    assert out.returncode == 0, out.stderr
    assert "max |eigenvalue|" in out.stdout


@pytest.mark.parametrize("content, message", [
    ("leg_length = 1.0\nbogus = 2\n", "unknown parameter 'bogus'"),
    ("leg_length = [\n", "not valid TOML"),
])
def test_bad_parameter_files(tmp_path, content, message):
    bad = tmp_path / "bad.toml"
    bad.write_text(content)
    out = run("gait", "--params", bad)
    assert out.returncode == 2
    assert message in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1


def test_missing_parameter_file(tmp_path):
    out = run("simulate", "--params", tmp_path / "nope.toml", "--steps", "3", "--out", tmp_path / "t.csv")
    assert out.returncode == 2
    assert "not found" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_no_gait_is_a_clear_error(tmp_path):
    """A passive walker going uphill has no gait (collisions lose energy, nothing supplies it):
    one line, exit 2, no output."""
    uphill = tmp_path / "uphill.toml"
    uphill.write_text(SIMPLEST.read_text().replace("slope = 0.009", "slope = -0.05"))
    out = run("simulate", "--params", uphill, "--steps", "3", "--out", tmp_path / "t.csv")
    assert out.returncode == 2
    assert "no gait found" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "t.csv").exists()


def test_simulate_writes_trajectory_files(tmp_path):
    out = run("simulate", "--params", COMPASS, "--steps", "4", "--noise", "0.001", "--seed", "7",
              "--out", tmp_path / "walk.csv")
    assert out.returncode == 0, out.stderr
    for name in ("walk.csv", "walk.events.csv", "walk.json"):
        assert (tmp_path / name).exists()
    meta = json.loads((tmp_path / "walk.json").read_text())
    assert meta["noise_sd"] == 0.001 and meta["source"]["seed"] == 7
    assert len((tmp_path / "walk.events.csv").read_text().splitlines()) == 5  # header + 4 strikes
    again = run("simulate", "--params", COMPASS, "--steps", "4", "--noise", "0.001", "--seed", "7",
                "--out", tmp_path / "again.csv")
    assert again.returncode == 0
    # The seed makes the noise reproducible.
    assert (tmp_path / "again.csv").read_text() == (tmp_path / "walk.csv").read_text()


def test_unknown_effect_is_refused(tmp_path):
    out = run("simulate", "--params", COMPASS, "--steps", "2", "--effect", "warp_drive=1",
              "--out", tmp_path / "t.csv")
    assert out.returncode == 2 and "unknown effect" in out.stderr
