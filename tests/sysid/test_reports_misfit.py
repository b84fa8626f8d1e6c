"""`toywalk sample` says the misfit of the model it samples: on stderr before the estimates, one
line each (the warnings of the fit it starts from, the failing posterior predictive checks), and at
the top of its report.md; the estimates carry their units."""

import json
import subprocess
import sys

import pytest

from ..conftest import DATA

TOY_SIZED = DATA / "params" / "toy-sized.toml"


def _run(*args):
    out = subprocess.run([sys.executable, "-m", "toywalk.sysid.cli", *map(str, args)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return out


@pytest.fixture(scope="module")
def misfit_walk(tmp_path_factory):
    """Six steps of the toy-sized walker with hip damping 1e-4 N m s/rad, 1 mrad noise, fitted by
    the base model (no damping) with the lateral offset free. Measured: the pitches miss by 7.1
    and 8.4 times their noise (the fit warns of it); chi-square, the lean range and both pitch
    ranges fail their checks by 8 to 900 SDs (40 draws; the steer's pass)."""
    folder = tmp_path_factory.mktemp("misfit")
    walk, fit = folder / "walk.csv", folder / "fit.json"
    _run("simulate", "--params", TOY_SIZED, "--steps", "6", "--effect", "hip_damping=1e-4",
         "--noise", "0.001", "--seed", "1", "--out", walk)
    _run("fit", walk, "--params", TOY_SIZED, "--free", "com_offset[1]", "--model", "periodic",
         "--out", fit)
    return folder, walk, fit


def test_sample_says_the_misfit_first(misfit_walk):
    folder, walk, fit = misfit_walk
    warnings = json.loads(fit.read_text())["warnings"]
    assert any("residual RMS is many times the noise" in w for w in warnings)  # what the fit said
    out = _run("sample", fit, walk, "--walkers", "4", "--steps", "8", "--ensembles", "2",
               "--out", folder / "chain.h5", "--report", folder / "posterior")
    lines = [line for line in out.stderr.splitlines() if line.startswith("warning: ")]
    assert lines[0] == f"warning: the fit it starts from warns: {warnings[0]}"
    checks = [line for line in lines if line.startswith("warning: posterior predictive checks fail")]
    assert len(checks) == 1 and "chi-square +" in checks[0], out.stderr
    # the estimates with their unit (m), after the warnings on a terminal's shared screen
    assert " m  90 % [" in out.stdout and "com_offset[1]" in out.stdout
    report = (folder / "posterior" / "report.md").read_text().splitlines()
    assert report[:3] == ["# Posterior of the fit's free parameters", "", "## Misfit"]
    assert report[4].startswith("- The fit it starts from warns: ")
    assert report[5].startswith("- Posterior predictive checks fail")
    assert "| com_offset[1] | m | " in "\n".join(report)
    assert json.loads((folder / "posterior" / "report.json").read_text())["misfit"][0].startswith(
        "the fit it starts from warns")
