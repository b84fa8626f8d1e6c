"""What the documents state about the shipped walkers, for the tests that check the model
against them (docs/gaits.md, docs/tinkertoy.md; tests/README.md, "Documented numbers").

The fixed points (public state order) were found when the parameter files were made; Newton
polishes them, so they only need to be near the gait. A documented number is quoted to some
digits; ``assert_documented`` checks that the model, run as the documents say (default integration
grid), rounds to it: the tolerance is half a unit of the last quoted digit.
"""

import numpy as np
from toywalk.model import Walker, load_params, solve_fixed_point

from ..conftest import DATA

__all__ = ["Z_CLEARING", "Z_STABLE", "assert_documented", "shipped_gait"]

#: The gait of data/params/stable-toy.toml (docs/gaits.md).
Z_STABLE = [0.04661788900461893, -0.5141677402083711, -0.001876783030565294, 0.021718470946236697,
            -0.08694501480362028, 4.231073000769995, 0.08135087368205376, 2.3913296604495535]

#: The gait of data/params/clearing-toy.toml, from docs/make_clearance_design.py's result
#: re-solved at the file's rounded parameters.
Z_CLEARING = [0.07050947332653978, -0.46650017313326736, -0.010489277599679167, -0.4243942466228133,
              -0.18659626122490666, 3.228258310166639, 0.13667971250468633, 1.1314428232345919]


def assert_documented(value, documented, unit, what):
    """``value`` rounds to ``documented``, a number quoted to a multiple of ``unit``."""
    assert abs(value - documented) <= 0.5 * unit * (1 + 1e-9), f"{what}: {value!r} vs {documented}"


def shipped_gait(name: str):
    """The gait of ``data/params/<name>.toml`` ("stable-toy" or "clearing-toy"), Newton-polished
    from its documented fixed point."""
    start = {"stable-toy": Z_STABLE, "clearing-toy": Z_CLEARING}[name]
    return solve_fixed_point(Walker(load_params(DATA / "params" / f"{name}.toml")), np.array(start))
