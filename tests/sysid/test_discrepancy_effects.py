"""Effects hidden at the edge of detection: the strength that moves the stable toy's gait by three
noise SDs (docs/make_diagnose_validation.py, `magnitude`; the table in docs/diagnosis.md, "Each
effect of the library hidden in turn"). In a file of its own so that it runs beside
tests/sysid/test_discrepancy.py, which hides the trailing-foot share at its library strength."""

import pytest
from toywalk.model.parameters import load_params
from toywalk.sysid.discrepancy import diagnose

from ..conftest import DATA
from .test_fit import _walk

FREE = ["foot_radius", "com_offset[1]"]


@pytest.mark.slow
def test_rolling_resistance_three_noise_sds_is_named():
    """Rolling resistance (a contact couple) at 7.557e-5 N m s/rad, the strength that moves the
    gait by 3 noise SDs (largest change of any angle over a stride; the library's typical 2e-4
    moves it by about 8, scaling linearly): named, its 95 % interval holding the truth
    (measured: [6.95e-5, 9.06e-5], hip damping the runner-up 15.7 behind in chi-square)."""
    toy = load_params(DATA / "params" / "stable-toy.toml")
    truth = 7.557e-5
    table, _ = _walk(toy.replace(**{"effects.rolling_resistance": truth}), 12, 0.002, 202)
    d = diagnose(table, toy, free=FREE, model="periodic")
    assert d.verdict == "discrepancy" and d.cause == "effects.rolling_resistance", d.evidence
    row = next(r for r in d.ranking if r["effect"] == d.cause)
    low, high = row["interval"][d.cause]
    assert low < truth < high
    assert d.gain["extended"] < d.gain["base"]
