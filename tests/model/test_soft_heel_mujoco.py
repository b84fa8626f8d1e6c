"""The model's compliant heel strike (toywalk.model.compliant) against MuJoCo's
(toywalk.model.mujoco_check.strike_in_mujoco): the clearing toy at its gait's heel strike, both
engines from the same state, ``solref = (2 ms, 1)``, friction 10 (the ``soft_heel`` effect's),
MuJoCo's impedance flat at d = 0.9999 (docs/soft_feet.md, "Against MuJoCo's heel strike");
and a short walk with the same contact (section 7, "Long walks against MuJoCo"). About 2.5 s
(the gait 1 s, MuJoCo's strike 0.5 s, its 6-step walk 1.3 s)."""

import numpy as np
import pytest
from toywalk.model import Walker, load_params, solve_fixed_point
from toywalk.model.compliant import SoftContact, compliant_strike
from toywalk.model.effects.soft import FRICTION, ZETA

from ..conftest import DATA
from .documented import Z_CLEARING

pytest.importorskip("mujoco")
from toywalk.model.mujoco_check import (  # noqa: E402
    STRIKE_SOLIMP,
    strike_differences,
    strike_in_mujoco,
    touchdown_predictions,
    walk_in_mujoco,
)

TAU = 2e-3  # s


@pytest.fixture(scope="module")
def strikes():
    params = load_params(DATA / "params" / "clearing-toy.toml")
    walker = Walker(params)
    z_minus = walker.step(solve_fixed_point(walker, np.array(Z_CLEARING)).fixed_point).z_minus
    model = compliant_strike(params, walker.full_state(z_minus), SoftContact(TAU, ZETA, FRICTION))
    return model, strike_in_mujoco(params, z_minus, TAU)


def test_the_strikes_start_from_the_same_state(strikes):
    """At touchdown both engines hold the same walker: MuJoCo's angles and rates read back from its
    legs' frames are the model's to round-off (the start is lowered 1 nm; tolerance 1e-9)."""
    model, mujoco = strikes
    np.testing.assert_allclose(mujoco.times, model.times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mujoco.angles[0], model.states[0, [4, 3, 5, 6]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(mujoco.rates[0], model.states[0, [11, 10, 12, 13]], rtol=0, atol=1e-9)


def test_after_the_phase_the_angles_and_rates_agree(strikes):
    """At the phase's end (10 tau = 20 ms) MuJoCo's angles and rates are the model's within 5 mrad
    and 0.06 rad/s. Measured (MuJoCo - model; lean, steer, pitch_left, pitch_right): +0.05, -0.73,
    +0.80, -2.54 mrad; -0.000, +0.002, -0.032, -0.020 rad/s (at 5 us steps; 20 us steps give
    -0.013 and -0.016 rad/s on the pitches, 1.25 us the same as 5 us to 3e-3 rad/s). What differs
    between the two laws (docs/soft_feet.md): MuJoCo's constraint at d = 0.9999 makes each foot's
    penetration follow the reference spring-damper in acceleration, so its force carries an extra
    ``-m_eff a_0`` (the rest of the walker's pull on the contact) and at touchdown the trailing foot
    is pinned (a stiffer landing: 20.5 N against 16.0); it holds the weight at no penetration
    where the model's spring sinks 41 um (0.3 mrad of a 0.15 m leg); its friction is a damper
    with a no-slip pass, the model's a spring-damper at 10 times N; its effective mass is
    updated. Tolerances twice the measured. What would fail: no phase at all (the strike changes
    pitch_left's rate by -4.8 rad/s over it), a swapped leg or a sign (the rates at the end,
    0.41, 0.62, -0.55, 2.26 rad/s, would differ by 0.8 to 2.8 rad/s), MuJoCo at 4 ms against the
    model at 2 ms, compared at the same 20 ms (-0.10 rad/s on pitch_left). What would not: the
    rigid strike followed by 20 ms of rolling (8e-3 rad/s from the model's phase end;
    docs/soft_feet.md section 2: the limit is the seed's law), and MuJoCo at 1 ms (0.025 rad/s):
    10 tau after touchdown the state has forgotten tau to O(tau)."""
    d = strike_differences(*strikes)
    assert np.all(np.abs(d["angles_end"]) < 5e-3), d["angles_end"]
    assert np.all(np.abs(d["rates_end"]) < 0.06), d["rates_end"]


def test_the_landing_force_and_its_duration_agree(strikes):
    """The landing foot's peak normal force, MuJoCo's over the model's, lies in [1, 1.4]: measured
    20.53 N / 15.99 N = 1.28, at touchdown in both. MuJoCo's is larger by construction (both extra
    terms push: the force that cancels the walker's downward pull, 1.7 N, and the trailing foot
    pinned at touchdown, 2.8 N; MuJoCo's peak after its first step is 17.7 N). The impact pulse
    (touchdown to the force's first minimum, ``impact_pulse``) agrees within 15 %: measured 6.00
    against 6.30 ms (5 %). A 2x wrong tau fails both: the peak goes as 1 / tau (MuJoCo at 4 ms
    gives 10.75 N, 0.67 of the model's at 2 ms) and the pulse as tau (11.8 ms at 4 ms)."""
    d = strike_differences(*strikes)
    ratio = d["mujoco"]["peak_force"] / d["model"]["peak_force"]
    assert 1.0 <= ratio <= 1.4, ratio
    pulses = d["mujoco"]["pulse"], d["model"]["pulse"]
    assert abs(pulses[0] / pulses[1] - 1.0) < 0.15, pulses


def test_strike_in_mujoco_refuses_bad_arguments(strikes):
    """A wrong state, time constant or step count is refused, naming the argument."""
    params = load_params(DATA / "params" / "clearing-toy.toml")
    z = np.array(Z_CLEARING)
    with pytest.raises(ValueError, match="z_minus"):
        strike_in_mujoco(params, z[:7], TAU)
    with pytest.raises(ValueError, match="contact_time"):
        strike_in_mujoco(params, z, -TAU)
    with pytest.raises(ValueError, match="substeps"):
        strike_in_mujoco(params, z, TAU, substeps=0)
    with pytest.raises(ValueError, match="solimp"):
        strike_in_mujoco(params, z, TAU, solimp=(1.5, 0.9, 0.001))
    with pytest.raises(ValueError, match="same times"):
        strike_differences(strikes[0], strike_in_mujoco(params, z, TAU, span=5))


WALK_TAU = 1e-3  # s
WALK_STEPS = 6


@pytest.fixture(scope="module")
def short_walk():
    """The clearing toy's rigid gait walked 6 steps in MuJoCo with the model's contact
    (``solref = (1 ms, 1)``, d = 0.9999, friction 10, RK4 at tau / 40), as
    docs/make_soft_heel_walks.py walks it; about 1.5 s."""
    params = load_params(DATA / "params" / "clearing-toy.toml")
    gait = solve_fixed_point(Walker(params), np.array(Z_CLEARING))
    walk = walk_in_mujoco(params, gait.fixed_point, steps=WALK_STEPS, timestep=WALK_TAU / 40,
                          friction=FRICTION, contact_time=WALK_TAU, damping_ratio=ZETA,
                          solimp=STRIKE_SOLIMP)
    return params, gait, walk


def test_in_a_walk_the_model_follows_mujocos_flow_but_not_its_strike(short_walk):
    """docs/soft_feet.md section 7. From MuJoCo's state 10 tau after each heel strike, the model's
    rolling flow predicts MuJoCo's next touchdown within 0.1 ms: measured +0.039 ms mean, 0.040 ms
    RMS over 100 steps, a nearly constant lag (+0.032 ms at 10 us steps), 0.02 % of the step: the
    creep, chatter and penetration of MuJoCo's continuous contact add almost nothing. Two steps,
    with the model's own compliant strike in place of MuJoCo's once, put MuJoCo's touchdown later
    by 0.75-2.25 ms (measured +1.51 ms mean over 100 steps, 1.52 RMS; the isolated strike of
    section 6 carried one step: +1.19 ms at tau / 400, +1.54 at tau / 40): MuJoCo's strike
    lengthens the next step by about 0.8 %, the nearly constant offset that makes its walk
    wander. Tolerances: the flow's 0.1 ms is 2.5 times the measured mean (single steps of this
    walk: 0.029-0.054 ms); the strike's band half to one and a half times the measured mean. What
    would fail: a flow that did not match (a wrong state read from MuJoCo: a swapped leg or sign
    changes the step by milliseconds) or strikes that agreed (0 ms)."""
    params, gait, walk = short_walk
    assert walk.steps == WALK_STEPS, walk.message
    np.testing.assert_allclose(walk.public_state(0), gait.fixed_point, rtol=0, atol=1e-12)
    flow = touchdown_predictions(walk, params, 10 * WALK_TAU)
    assert np.all(np.abs(flow) < 1e-4), flow
    soft = params.replace(**{"effects.soft_heel": WALK_TAU})
    strike = touchdown_predictions(walk, soft, 10 * WALK_TAU, steps=2)
    assert 0.75e-3 < np.nanmean(strike) < 2.25e-3, strike


def test_touchdown_predictions_refuse_bad_arguments(short_walk):
    """A walk that is not a MujocoWalk, a negative delay or a step count below 1 is refused,
    naming the argument."""
    params, _, walk = short_walk
    with pytest.raises(TypeError, match="walk"):
        touchdown_predictions(walk.times, params, 0.01)
    with pytest.raises(ValueError, match="delay"):
        touchdown_predictions(walk, params, -0.01)
    with pytest.raises(ValueError, match="steps"):
        touchdown_predictions(walk, params, 0.01, steps=0)
