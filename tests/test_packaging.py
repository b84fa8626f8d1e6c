"""The package as a user installs it from a wheel, not from the source tree: every subpackage
(the effects library was once left out), the bundled data, found where the commands look, and
the licence."""

import glob
import subprocess
import sys
import sysconfig
import zipfile

import pytest

from .conftest import DATA

ROOT = DATA.parent


@pytest.mark.slow
def test_the_wheel_carries_the_code_and_the_data(tmp_path):
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", str(ROOT),
                            "-w", str(tmp_path / "dist")], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr[-2000:]
    wheel, = glob.glob(str(tmp_path / "dist" / "toywalk-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names), "no LICENSE in the wheel"
    site = tmp_path / "site"
    install = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target",
                              str(site), wheel], capture_output=True, text=True, timeout=600)
    assert install.returncode == 0, install.stderr[-2000:]
    # -S: no site hooks, so the source tree's editable install is out of the way; the
    # dependencies come from this environment's site-packages, toywalk from the wheel alone.
    code = """
import sys
from pathlib import Path
from toywalk.model.files import DATA_DIR as _DATA
from toywalk.sysid.cli import main
import toywalk.sysid.commands.demo
import toywalk.model.effects, toywalk.tracking.calibrate
site = Path(sys.argv[1]).resolve()
assert _DATA.is_relative_to(site), _DATA
for name in ("params/clearing-toy.toml", "camera/default.json", "markers/default.json",
             "sample/walk.mp4", "sample/walker.toml", "sample/calibration/view-08.jpg",
             "paper/measurements.csv"):
    assert (_DATA / name).is_file(), name
assert main(["effects"]) == 0
"""
    env = {"PYTHONPATH": f"{site}:{sysconfig.get_paths()['purelib']}", "PATH": "/usr/bin:/bin"}
    run = subprocess.run([sys.executable, "-S", "-c", code, str(site)], capture_output=True, text=True,
                         timeout=300, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "asymmetry" in run.stdout
