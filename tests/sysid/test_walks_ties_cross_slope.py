"""A cross slope, which one walk leaves nearly tied with an uneven build (both walk the toy at a
steady steer angle), named from three walks analysed together (the walks and checks of
tests/sysid/test_walks_ties.py, in tests/sysid/verdicts.py; a module of its own so that the
suite's two workers share the long cases)."""

import pytest

from .verdicts import assert_named_from_three_walks


@pytest.mark.slow
def test_three_walks_name_a_cross_slope():
    """10 noise SDs beyond the base on one walk (1.067e-3 rad, 0.06 degree), the ramp's frame known
    (the nuisance offsets held). One walk leaves it 10.7 ahead of an uneven build
    (docs/diagnosis.md); three walks: first order 57.7 apart (sysid.design), measured 44.1, the
    interval [1.0547e-3, 1.0709e-3]. At 3 noise SDs the first-order gap is about 5: not enough."""
    assert_named_from_three_walks("cross_slope", 0.00106664430430518, 630, ["cross_slope", "asymmetry"],
                                  offsets=False)
