"""data/params/paper-toy.toml, the inverse design of docs/make_paper_design.py (docs/paper_toy.md,
"Inverse design"): a rigid, frictionless walker with the toy's build whose gait meets the paper's
numbers within their intervals, that cannot stand, and whose gait is unstable as the document says.
"""

import math

import pytest
from toywalk.model import can_stand, find_gait, load_params

from ..conftest import DATA
from .documented import assert_documented

PARAMS = DATA / "params" / "paper-toy.toml"
DEG = math.pi / 180
# The paper's numbers as intervals, (centre, half-width) (Coleman & Ruina 1998, PRL 80:3658;
# docs/paper_toy.md): a stride is two steps; "no visible steer" is at most 1.5 deg.
INTERVALS = {
    "stride_time": (0.47, 0.03),       # s
    "stride_length": (0.013, 0.003),   # m
    "lean_amplitude": (4.0 * DEG, 1.5 * DEG),
    "steer_amplitude": (0.0, 1.5 * DEG),
}
SLOPE = (4.5 * DEG, 0.5 * DEG)
TOTAL_MASS = (0.120, 0.030)
# What docs/paper_toy.md quotes for this walker's gait (to the digits quoted there).
DOCUMENTED = {"max_abs_eigenvalue": (2.675, 0.001), "stride_time": (0.487, 0.001)}


@pytest.fixture(scope="module")
def gait():
    # find_gait starts from the file's [gait] start, as `toywalk gait --params` does.
    return find_gait(load_params(PARAMS))


def test_gait_meets_the_paper_numbers(gait):
    # The claim is the interval itself: the design was accepted with every number inside it, and
    # Newton polishes the same fixed point, so no tolerance beyond the interval is needed.
    for name, (centre, half) in INTERVALS.items():
        value = getattr(gait, name)
        assert abs(value - centre) <= half, f"{name} = {value!r} outside {centre} +- {half}"
    params = gait.params
    assert abs(params.slope - SLOPE[0]) <= SLOPE[1]
    assert abs(params.total_mass - TOTAL_MASS[0]) <= TOTAL_MASS[1]


def test_build_as_the_paper_describes(gait):
    # docs/make_paper_design.py's build relations (Coleman & Ruina 1998, "construction details"):
    # the legs' centres of mass about one leg length out (0.5-1.5 l), low (at most half a leg
    # above the foot bottom), above the feet's centre of curvature and just behind the leg axes.
    p = gait.params
    dx, dy, dz = p.com_offset
    height = p.leg_length + dz
    assert 0.5 <= dy / p.leg_length <= 1.5
    assert p.foot_radius <= height <= 0.5 * p.leg_length
    assert -0.02 <= dx <= 0.0


def test_cannot_stand(gait):
    report = can_stand(gait.params)
    assert not report.can_stand, report.reason


def test_stability_as_documented(gait):
    assert not gait.stable
    for name, (documented, unit) in DOCUMENTED.items():
        assert_documented(getattr(gait, name), documented, unit, name)
