"""Shared test fixtures and paths."""

import math
from pathlib import Path

import pytest
from toywalk.model.parameters import Params

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data"

#: The suite's longest files, longest first (seconds in `make test`, 2026-11-27: 138 down to 38).
#: They are run first, so that `make test`'s two processes end together: a process that draws
#: a long file last keeps the other waiting (longest-first scheduling). Only an order: a file
#: missing here, or one that has grown, runs all the same.
LONGEST_FIRST = (
    "sysid/test_walks_ties.py", "sysid/test_walks.py", "sysid/test_fit.py",
    "tracking/test_ramp_pose.py", "sysid/test_demo.py", "sysid/test_sample.py",
    "tracking/test_occluded_leg.py", "sysid/test_summary.py", "sysid/test_multistart.py",
    "sysid/test_transient.py", "sysid/test_walks_ties_cross_slope.py",
    "sysid/test_fit_misspecified.py", "sysid/test_discrepancy_effects.py", "test_notebooks.py",
    "sysid/test_discrepancy.py", "tracking/test_track_rendered.py", "tracking/test_track_mujoco.py",
)


def pytest_collection_modifyitems(config, items):
    """Put the files of :data:`LONGEST_FIRST` first, in its order; a file's tests stay together
    and in their order, and every other file keeps its place after them."""
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    here = Path(__file__).resolve().parent

    def key(item):
        try:
            name = item.path.resolve().relative_to(here).as_posix()
        except ValueError:
            name = ""
        return rank.get(name, len(rank))
    items.sort(key=key)  # stable: the rest keep the collection's order


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
