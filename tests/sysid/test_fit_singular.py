"""No number from a singular problem: a fit whose information is singular along a direction says
which estimates the data do not determine and gives them no standard error (NaN, null in JSON,
"not determined" on the terminal), and the default model falls back to the periodic one where the
transient one cannot determine the free parameters. The walker: toy-sized, unstable (max
|eigenvalue| 6.0), so a transient's free start explains what the parameters would."""

import json
import math

import numpy as np
import pytest
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import write_trajectory
from toywalk.model.walker import STATE_NAMES
from toywalk.sysid.fit import fit

from ..conftest import DATA
from .builders import simulated_walk
from .command import run

FREE = ["foot_radius", "com_offset[1]"]
TOY_SIZED = DATA / "params" / "toy-sized.toml"


@pytest.fixture(scope="module")
def walk():
    """8 steps of toy-sized with hip damping 1e-4 (the newcomer's effect), 0.002 rad of noise."""
    base = load_params(TOY_SIZED)
    table, _ = simulated_walk(base.replace(**{"effects.hip_damping": 1e-4}), 8, 0.002, 3)
    return base, table


def test_a_singular_transient_fit_gives_no_standard_error(walk):
    base, table = walk
    r = fit(table, base, FREE, model="transient", check_jacobian=False)
    assert r.success
    assert set(FREE) <= set(r.undetermined)
    assert all(math.isnan(r.std[n]) for n in FREE)
    assert any(w.startswith("not determined by these data") for w in r.warnings)
    # the offsets stay determined, with standard errors of the noise's order over ~500 samples
    # (measured 3e-5 to 1.8e-4 rad); a pseudo-inverse of the unscaled information gave them no
    # variance at all (2e-28 rad on 16 steps)
    for name in ("lean_offset", "steer_offset", "pitch_offset"):
        assert 1e-6 < r.std[name] < 1e-2, (name, r.std[name])


@pytest.mark.slow
def test_fit_by_default_says_what_is_not_determined_and_uses_the_periodic_model(tmp_path):
    """`toywalk fit` with its defaults, as a newcomer runs it: the walk starts 1e-5 rad/s off the
    unstable walker's cycle (its stance pitch rate; the misfit grows six-fold a step), the
    transient model cannot determine the foot radius, so the periodic model is used and says so;
    no standard error of a singular fit is printed."""
    truth = load_params(TOY_SIZED).replace(**{"effects.hip_damping": 1e-4})
    gait = find_gait(truth)
    z0 = np.array(gait.fixed_point, float)
    z0[STATE_NAMES.index("theta_st_dot")] += 1e-5
    table, _ = simulated_walk(truth, 8, 0.002, 3, gait=gait, z0=z0)
    write_trajectory(table, tmp_path / "walk.csv")
    out = run("fit", tmp_path / "walk.csv", "--params", TOY_SIZED, "--free", ",".join(FREE),
              "--out", tmp_path / "f.json")
    assert out.returncode == 0, out.stderr
    report = json.loads((tmp_path / "f.json").read_text())
    assert report["model"] == "periodic", out.stdout
    assert report["periodicity"]["fallback"] and "does not determine" in report["periodicity"]["message"]
    # toy-sized's swing foot goes 0.5 mm below the ramp before the legs pass: said as gait says it
    gait_line = next(line for line in out.stdout.splitlines() if line.startswith("fitted gait"))
    assert "the swing foot scuffs the ramp before the legs pass, once a step" in gait_line
    assert report["gait"]["scuffs"] == 1 and report["gait"]["swing_clearance"] < 0
    for name in FREE:  # a periodic fit determines them: a standard error of the walk's order
        se = report["std"][name]
        assert se is not None and se > 1e-9, (name, se)  # the singular transient printed 2.2e-15
