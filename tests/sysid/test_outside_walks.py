"""The generators of walks whose physics lies outside the effect library (tests/sysid/outside.py):
each makes the walk it says, and that walk differs from the model's by more than its noise.
These check the generators, not what the discrepancy analysis says of the walks
(docs/make_outside_validation.py measures that)."""

import numpy as np
import pytest
from toywalk.model import Walker, load_params, solve_fixed_point
from toywalk.model.effects import EFFECTS
from toywalk.model.parameters import PARAMETER_NAMES
from toywalk.model.simulate import simulate
from toywalk.model.trajectory import SIGNALS

from . import outside


def _angles(table) -> np.ndarray:
    """The four angles of a trajectory, shape (n, 4), columns SIGNALS."""
    return np.column_stack([table.signals[name] for name in SIGNALS])


def _rms(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """RMS difference of each column over the samples both have (rad), shape (4,)."""
    n = min(len(a), len(b))
    return np.sqrt(np.mean((a[:n] - b[:n]) ** 2, axis=0))


def _rigid(seed: int) -> np.ndarray:
    """The model's own walk of the clearing walker from the start the MuJoCo walks of ``seed``
    take (the gait's fixed point with the seed's first four draws on its rates), sampled as they
    are."""
    gait = outside.clearing_gait()
    z0 = outside.perturbed(gait.fixed_point, np.random.default_rng(seed), outside.START_SD)
    sim = simulate(gait.params, z0, outside.STEPS, sample_rate=outside.SAMPLE_RATE)
    return np.column_stack([sim.angles()[name] for name in SIGNALS])


def test_the_contact_walk_completes_and_is_not_the_models():
    """The clearing walker with soft, overdamped, slipping contacts walks its 20 heel strikes,
    alternating feet, sampled at 120 Hz; its noise is the seed's (the same walk twice, the noise
    of the stated SD); and its angles differ from the rigid model's walk from the same start by
    more than the noise. Measured, seeds 0, 2, 3: pitches 0.042-0.043 rad RMS (14 noise SDs),
    lean 0.008, steer 0.014-0.015; the mean step time 0.8-0.95 % longer than the model's gait's,
    where the checked build's walks (1 ms, critically damped, friction 2) are 0.3-1.5 % shorter.
    Bound: pitches above twice the noise SD (below it an analysis could take it for noise)."""
    clean = outside.contact_walk(0, noise=0.0)
    assert [e["foot"] for e in clean.events] == ["R", "L"] * (outside.STEPS // 2)
    assert np.allclose(np.diff(clean.time), 1 / outside.SAMPLE_RATE, rtol=0, atol=1e-9)  # time's round-off
    source = clean.metadata["source"]
    assert source["kind"] == "mujoco" and source["friction"] == outside.CONTACT["friction"]
    assert source["contact_time_constant"] == outside.CONTACT["contact_time"]
    assert source["contact_damping_ratio"] == outside.CONTACT["damping_ratio"]
    rms = _rms(_angles(clean), _rigid(0))
    assert np.all(rms[2:] > 2 * outside.NOISE), rms

    noisy = outside.contact_walk(0)
    again = outside.contact_walk(0)
    np.testing.assert_array_equal(_angles(noisy), _angles(again))
    # The noise's SD over 4 x 442 samples: within 3.4 % of the truth at 2 sigma; tolerance 10 %.
    sd = np.std(_angles(noisy) - _angles(clean))
    assert abs(sd / outside.NOISE - 1) < 0.1, sd
    assert np.all(noisy.signals["lean_sd"] == outside.NOISE)


def test_the_hinge_spring_at_zero_is_the_librarys_walk():
    """With k = 0 the test-only effect, registered in a fresh interpreter with CasADi's virtual
    machine, walks the stable toy exactly as the library does here with its compiled functions:
    the same gait and the same 20 steps sampled at 120 Hz. Measured: identical to the last bit
    (the virtual machine and the compiled code evaluate the same expressions in the same order);
    tolerance 1e-12 rad, round-off. This process's registry and parameter layout are untouched."""
    table, summary = outside.hinge_spring_gaits(0.0)
    toy = load_params(outside.DATA / "stable-toy.toml")
    gait = solve_fixed_point(Walker(toy), np.array(outside.STABLE_START))
    assert summary["step_time"] == pytest.approx(gait.step_time, rel=1e-12, abs=0)
    sim = simulate(toy, gait.fixed_point, outside.STEPS, sample_rate=outside.SAMPLE_RATE)
    np.testing.assert_array_equal(table.time, sim.times)
    model = np.column_stack([sim.angles()[name] for name in SIGNALS])
    np.testing.assert_allclose(_angles(table), model, rtol=0, atol=1e-12)
    np.testing.assert_allclose([e["time"] for e in table.events], [e.time for e in sim.events],
                               rtol=0, atol=1e-12)
    assert "hinge_spring" not in EFFECTS and "effects.hinge_spring" not in PARAMETER_NAMES


def test_the_hinge_spring_shortens_the_step_and_keeps_the_energy():
    """At k = 5e-3 N m/rad the stable toy's step is shorter and the spring dissipates nothing.

    Step time: the swing leg alone, a pendulum about the hip of gravity stiffness m g |d_z| =
    0.060 N m/rad made 8.3 % stiffer, would swing 4 % faster; the stance leg's motion, which the
    spring's reaction also drives, takes part of that. Measured -1.47 % (0.10656 to 0.10500 s);
    bounds -4 % (the swing leg alone) and -0.5 %, a third of the measured, far above the gait
    search's tolerance.

    Energy over the first step: the mechanical energy (kinetic and gravitational, the model's
    energy output, which knows nothing of the spring) swings by 6.8e-5 J as the spring stores and
    returns k (theta_sw - theta_st)^2 / 2, and their sum drifts by 4.8e-13 J (without the spring
    4.3e-13 J: the RK8 integration's error). Tolerance 1e-10 J, 200 times that and 7e5 times
    under the energy exchanged. The model's dissipation output for the spring integrates to the
    change of its stored energy (measured 2.6e-15 J apart; tolerance 1e-12 J): it exchanges
    energy, it loses none."""
    _, summary = outside.hinge_spring_gaits(outside.STIFFNESS)
    change = summary["step_time"] / summary["step_time_without"] - 1
    assert -0.04 < change < -0.005, change
    energy = summary["energy"]
    assert energy["stored_range"] > 1e-5  # the spring works: 6.8e-5 J measured
    assert energy["total_drift"] < 1e-10, energy
    assert energy["taken_minus_stored"] < 1e-12, energy
    assert summary["status"] == "completed"


def test_the_hinge_spring_is_the_port_dictionarys_hinge_stiffness():
    """The test-only spring is the physics of the library's port-only term ``hinge_stiffness``
    (the hinge port's angle form, not a default cause of diagnose): at the same stiffness the
    gaits agree (the same expressions, in the virtual machine there and compiled here: 1e-12)."""
    _, summary = outside.hinge_spring_gaits(outside.STIFFNESS)
    toy = load_params(outside.DATA / "stable-toy.toml")
    start = solve_fixed_point(Walker(toy), np.array(outside.STABLE_START)).fixed_point
    walker = Walker(toy.replace(**{"effects.hinge_stiffness": outside.STIFFNESS}))
    gait = solve_fixed_point(walker, start)
    assert summary["step_time"] == pytest.approx(gait.step_time, rel=1e-12, abs=0)
    np.testing.assert_allclose(summary["fixed_point"], gait.fixed_point, rtol=0, atol=1e-10)
    assert not EFFECTS["hinge_stiffness"].breaks_symmetry and EFFECTS["hinge_stiffness"].port_only


def test_the_hinge_spring_walk_is_the_seeds():
    """The noisy walk: 20 heel strikes; the start's perturbation drawn in the fresh interpreter
    and the noise here from one seed, so the walk is its noise-free walk plus exactly the seed's
    next draws (the same walk for the same seed), of the stated SD."""
    noisy = outside.hinge_spring_walk(3)
    assert len(noisy.events) == outside.STEPS
    clean, _ = outside.hinge_spring_gaits(outside.STIFFNESS, seed=3, perturb=True)
    rng = np.random.default_rng(3)
    rng.normal(0.0, outside.START_SD, 4)  # the start's perturbation
    for name in SIGNALS:
        expected = clean.signals[name] + rng.normal(0.0, outside.NOISE, clean.signals[name].shape)
        np.testing.assert_array_equal(noisy.signals[name], expected)
    # The noise's SD over 4 x 252 samples: within 4.5 % of the truth at 2 sigma; tolerance 10 %.
    sd = np.std(_angles(noisy) - _angles(clean))
    assert abs(sd / outside.NOISE - 1) < 0.1, sd


def test_the_foot_profile_is_not_the_spheroids():
    """The ellipsoid feet keep the torus's radii at the bottom (a^2 / c = r, b^2 / c = rho; to
    round-off). At aspect 1 they are the spheroid foot of the contact walk, to the last bit. At
    aspect 0.25 (fore-aft radius 14 % shorter at the ends of the roll) the walk completes its 20
    heel strikes and differs from the spheroid foot's walk from the same start, at the same
    contact settings, by more than the noise: measured (seed 0) pitches 0.0167 and 0.0164 rad
    RMS, lean 0.0033, steer 0.0056, where a start changed by 1e-6 rad/s moves the pitches by
    0.007 rad (the walk's own sensitivity). Bound: pitches above twice the noise SD. It also
    differs from the rigid model's walk by more than that."""
    params = outside.clearing_gait().params
    a, b, c = outside.profile_axes(params.foot_radius, params.foot_lateral_radius, outside.ASPECT)
    assert a**2 / c == pytest.approx(params.foot_radius, rel=1e-14)  # round-off of three operations
    assert b**2 / c == pytest.approx(params.foot_lateral_radius, rel=1e-14)
    spheroid = outside.foot_profile_walk(0, noise=0.0, aspect=1.0)
    np.testing.assert_array_equal(_angles(spheroid), _angles(outside.contact_walk(0, noise=0.0)))
    profile = outside.foot_profile_walk(0, noise=0.0)
    assert len(profile.events) == outside.STEPS
    assert profile.metadata["source"]["foot_axes"] == [a, b, c]
    rms = _rms(_angles(profile), _angles(spheroid))
    assert np.all(rms[2:] > 2 * outside.NOISE), rms
    assert np.all(_rms(_angles(profile), _rigid(0))[2:] > 2 * outside.NOISE)
