"""The spin arrested at heel strike (a collision parameter), the one effect of the library that
no other test hides: a single walk names it. Strength and seed of docs/diagnose_effects.csv
(docs/diagnosis.md, "Each effect of the library hidden in turn"), so a failure here is a change in
that table. Elsewhere: rolling resistance and the trailing foot's share
(test_discrepancy_effects.py, test_discrepancy.py), an uneven build from rendered and tracked
video (test_demo.py), and the effects one walk leaves tied, from three walks (test_walks.py,
test_walks_ties.py)."""

import pytest

from .verdicts import assert_named


@pytest.mark.slow
def test_the_spin_arrested_at_heel_strike_is_named():
    """A tenth of the landing foot's spin arrested (0.1011, 3.1 noise SDs beyond what the base
    fit mimics; seed 207): named (measured: 95 % [0.0897, 0.1119], the slope the runner-up 125.8
    behind in chi-square)."""
    assert_named("effects.impact_spin_arrest", 0.10108097089540881, 207)
