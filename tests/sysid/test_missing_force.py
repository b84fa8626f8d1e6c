"""The shape of the missing force (sysid/missing_force.py): a hinge spring, which no library effect
is, hidden in a walk of the stable toy; the library's causes leave the walk unexplained, and the
search of the port dictionary finds the spring and nothing else. Rates over seeds and walkers:
docs/make_missing_force_validation.py (docs/diagnosis.md, "The shape of the missing force")."""

import pytest
from toywalk.model.parameters import load_params
from toywalk.model.simulate import gait_walk
from toywalk.sysid.discrepancy import diagnose
from toywalk.sysid.missing_force import term_sentence

from ..conftest import DATA

#: The spring (N m/rad): the pitches move by 0.4 degree over two steps, 3.5 noise SDs.
SPRING = 5e-3


@pytest.mark.slow
def test_a_hinge_spring_is_found_at_the_hinge_and_nothing_else():
    """12 steps, 2 mrad of noise, seed 1 (measured: hip dry friction and the slope tie, 117.7
    against 114.8; the search keeps hinge (angle), k = 0.005018 [0.004695, 0.005341], its second
    step's best term at p = 0.39)."""
    walker = load_params(DATA / "params" / "stable-toy.toml")
    table = gait_walk(walker.replace(**{"effects.hinge_stiffness": SPRING}), 12, noise=0.002, seed=1)
    d = diagnose(table, walker, free=["foot_radius", "com_offset[1]"], model="periodic", tie_design=False)
    assert d.cause == "unexplained"
    found = d.missing_force
    assert [t["parameter"] for t in found.terms] == ["effects.hinge_stiffness"], found.stop
    term = found.terms[0]
    assert term["port"] == "hinge" and term["form"] == "angle" and term["unit"] == "N m/rad"
    assert term["interval"][0] <= SPRING <= term["interval"][1]
    assert found.gain["selected"] < found.gain["base"]
    assert "tau_hinge = -k (theta_sw - theta_st)" in term_sentence(term)
    assert d.to_json()["missing_force"]["terms"][0]["coincides_with"] is None
