"""Shared test fixtures and paths."""

import math
import subprocess
import sys
from pathlib import Path

import pytest
from toywalk.model.parameters import Params

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"


def loaded_by(code: str, *modules: str) -> dict[str, bool]:
    """Which of ``modules`` a fresh interpreter has imported once it has run ``code``."""
    probe = f"{code}\nimport sys\nprint(*[m in sys.modules for m in {list(modules)!r}])"
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    return dict(zip(modules, (word == "True" for word in run.stdout.split()), strict=True))


@pytest.fixture
def toy_params() -> Params:
    """A toy-like walker (Coleman & Ruina 1998): 15 cm legs, spool feet with a 5 mm lateral radius,
    50 g legs whose centre of mass is low, about 2/3 of a leg length out and just behind the leg
    axis, on a 4.5 degree ramp. Its centre of mass is well above the feet's lateral curvature."""
    return Params(
        leg_length=0.15,
        foot_radius=0.03,
        foot_lateral_radius=0.005,
        hip_width=0.0,
        leg_mass=0.05,
        axle_mass=0.02,
        com_offset=(-0.005, 0.1, -0.11),
        inertia=(3e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0),
        slope=math.radians(4.5),
        gravity=9.81,
    )
