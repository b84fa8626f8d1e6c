"""Physics outside the library is never presented as a named cause: walks of tests/sysid/outside.py
analysed as a user would (diagnose's defaults, the walker's parameter file as the base model).
The rates over ten seeds of each kind are in docs/diagnosis.md ("Physics outside the library",
`docs/make_outside_validation.py`); these hold the cases the rule before it got wrong."""

import pytest
from toywalk.model.parameters import load_params
from toywalk.sysid.discrepancy import diagnose

from ..conftest import DATA
from . import outside

#: The base model's free parameters (docs/make_outside_validation.py).
FREE = ["foot_radius", "com_offset[1]"]


@pytest.mark.slow
def test_soft_contacts_are_an_effective_description_not_rolling_resistance():
    """MuJoCo's soft, overdamped, slipping contacts (seed 0): the rule before named rolling
    resistance (docs/outside_contact_before.csv) while its pitches' held-out RMS stayed at four
    times the noise; now it is an effective description that says what it leaves."""
    table = outside.walk("contact", 0)
    d = diagnose(table, load_params(DATA / "params" / "clearing-toy.toml"), model="periodic", free=FREE,
                 missing_force=False)  # the search: tests/sysid/test_missing_force.py
    assert d.causes == [] and d.cause == "unexplained", d.evidence
    assert d.verdict == "partly explained", d.evidence
    e = d.effective
    assert e["candidates"] == ["effects.rolling_resistance"] and not e["explains"]
    # measured 4.04 and 4.27 noise SDs, against a limit near 1.2: a misfit, not the noise
    assert min(e["remaining_in_noise_sd"][p] for p in ("pitch_left", "pitch_right")) > 2.0, e
    assert all(e["remaining_in_noise_sd"][k] > e["limit"][k] for k in ("pitch_left", "pitch_right"))
    assert "may stand in for physics the library lacks" in d.evidence


@pytest.mark.slow
def test_a_foot_profile_is_not_named_a_collision_law_and_a_mass_offset():
    """Feet whose fore-aft radius falls 14 % along the rim, in MuJoCo (seed 3): the rule before
    named the spin arrest and the vertical mass offset together (docs/outside_foot_profile_before.csv);
    the pair leaves the pitches' held-out RMS near ten times the noise."""
    table = outside.walk("foot_profile", 3)
    d = diagnose(table, load_params(DATA / "params" / "clearing-toy.toml"), model="periodic", free=FREE,
                 missing_force=False)  # the search: tests/sysid/test_missing_force.py
    assert d.causes == [] and d.cause == "unexplained", d.evidence
    assert d.verdict == "partly explained" and not d.effective["explains"], d.evidence
    # measured 10.3 and 8.7 noise SDs: far beyond any limit of the rule (1.1 widened by the noise
    # estimate's uncertainty, 1.2 here)
    assert min(d.effective["remaining_in_noise_sd"][p] for p in ("pitch_left", "pitch_right")) > 3.0
