"""Effects that a walk on the ramp leaves tied, named from three walks analysed together: on the
ramp, on one at 0.8 of its slope and with the balance masses 1 cm further out (docs/diagnosis.md,
"Which second walk breaks the ties"). The hip's viscous friction and the stance foot's pivot
friction tie with each other and with the hip's dry friction (named through the command line in
tests/sysid/test_walks.py); a cross slope with an uneven build (both walk the toy at a steady steer
angle; docs/diagnose_effects.csv; tests/sysid/test_walks_ties_cross_slope.py, a module of its own
so that the suite's two workers share these long cases). Friction seeds as in
docs/tie_joint.csv."""

import pytest
from toywalk.model.parameters import load_params
from toywalk.sysid.naming import SEPARATION
from toywalk.sysid.walks import diagnose_walks

from ..conftest import DATA
from .test_fit import _walk

FREE = ["foot_radius", "com_offset[1]"]
FRICTIONS = ["hip_damping", "hip_coulomb", "pivot_friction"]


@pytest.mark.slow
@pytest.mark.parametrize(("effect", "truth", "seed", "rivals", "offsets"), [
    # 3 noise SDs beyond what the base fit mimics on one walk (docs/diagnose_effects.csv); measured
    # [4.88e-5, 5.21e-5], the rivals 148.8 (pivot friction) and more behind in chi-square
    ("hip_damping", 4.960607427935393e-05, 600, FRICTIONS, True),
    # measured [6.533e-4, 6.933e-4], the rivals 229.3 and more behind; the base fit from its cold
    # start failed on these walks at earlier versions of the fit (IPOPT's restoration), and
    # converges at this one (chi-square 5943.1); diagnose_walks refits a failed base from the best
    # candidate's fit
    ("pivot_friction", 0.0006534658516680863, 620, FRICTIONS, True),
])
def test_three_walks_name_an_effect_one_walk_leaves_tied(effect, truth, seed, rivals, offsets):
    assert_named_from_three_walks(effect, truth, seed, rivals, offsets)


def assert_named_from_three_walks(effect, truth, seed, rivals, offsets):
    """The three walks (seeds ``seed`` to ``seed + 2``) with ``effect`` at ``truth``, analysed
    together with ``rivals`` and the slope as candidates: ``effect`` named, ahead of every rival by
    the rule's margin, its interval holding the truth, its held-out prediction better."""
    toy = load_params(DATA / "params" / "stable-toy.toml")
    offset = list(toy.com_offset)
    offset[1] += 0.01
    bases = [toy, toy.replace(slope=0.8 * toy.slope), toy.replace(com_offset=offset)]
    tables = [_walk(b.replace(**{f"effects.{effect}": truth}), 12, 0.002, seed + k)[0]
              for k, b in enumerate(bases)]
    d = diagnose_walks(tables, bases, free=FREE, parameters=["slope"], effects=rivals, offsets=offsets)
    assert d.verdict == "discrepancy" and d.cause == f"effects.{effect}", d.evidence
    rows = [r for r in d.ranking if "lr" in r]
    named = next(r for r in rows if r["effect"] == d.cause)
    # ahead of every rival by the rule's margin
    assert all(named["lr"] - r["lr"] > SEPARATION for r in rows if r is not named)
    low, high = named["interval"][d.cause]
    assert low < truth < high
    # and it predicts the walks' held-out strides better (a condition of the rule, checked here
    # where it is reported: the two folds' chi-squares of the base and of the named model)
    held = d.gain["held_out"]
    assert held["candidate"] == d.cause and held["extended"] < held["base"], held
    assert named["held_out_gain"] == pytest.approx(held["base"] - held["extended"])
