"""The return map estimated from measured strides: recovery of the model's Floquet multipliers
from a walk kicked off its cycle, the regression dilution of least squares under measurement noise
and its two corrections, the section states against the simulated truth, and unusable input.

The walker is the stable one of data/params/stable-toy.toml (docs/gaits.md section 2): step-map
eigenvalues -0.961 +/- 0.111i (|0.967|), -0.920 +/- 0.189i (|0.939|), ..., so stride-map
eigenvalues 0.911 +/- 0.213i (|0.935|), 0.810 +/- 0.348i (|0.882|), ... A walk on its limit cycle
holds no information about the map, so the test walks are kicked: after every heel strike the four
rates get independent N(0, kick) increments (process noise). The gait grazes the ramp (0.28 mm of
clearance), so it tolerates only small kicks: 0.002 rad/s makes it fall within 400 steps for some
seeds, 0.001 rad/s walks 1200 steps for every seed tried. Sampling at 240 per second (a
high-frame-rate video, about 26 samples per step of 0.107 s).
"""

import json
import math

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.trajectory import TrajectoryTable, read_trajectory, write_trajectory
from toywalk.model.walker import Walker
from toywalk.sysid.measurement import MeasurementError
from toywalk.sysid.returnmap import (
    ALL_COORDINATES,
    LATERAL_COORDINATES,
    ReturnMapError,
    return_map,
    return_maps,
    section_states,
)

from ..conftest import DATA

RATE = 240.0  # samples per second
STEPS = 1200  # steps of the long walks: 600 strides, 1/sqrt(600) = 0.041


def _kicked_walk(walker, z0, steps, kick, seed):
    """A walk of ``steps`` steps from ``z0`` (after a left heel strike), the rates kicked by
    N(0, ``kick``) rad/s after every heel strike, sampled at RATE as ``simulate`` does
    (model/simulate.py: the mirrored description integrated by ``Walker.step``, cubic Hermite
    interpolation of the integration grid, steer and lean mirrored back on right-stance steps).

    Returns ``(table, truth)``: the walk as a noise-free measurement (heel strikes including the one
    it starts from) and ``truth(phase)``, the physical public state at that phase of every step,
    shape (steps, 8), from the same splines.
    """
    rng = np.random.default_rng(seed)
    z, sign, t0 = np.array(z0, dtype=float), 1.0, 0.0
    times, states, stance, pieces = [], [], [], []
    events = [{"time": 0.0, "foot": "L"}]
    for _ in range(steps):
        side = int(sign)
        step = walker.step(z, record=True, side=side)
        derivs = np.array([walker.rhs(x, side) for x in step.states])
        spline = CubicHermiteSpline(step.times, step.states, derivs, axis=0)
        t1 = t0 + step.step_time
        grid = np.arange(math.ceil(t0 * RATE - 1e-9), math.ceil(t1 * RATE - 1e-9)) / RATE
        pub = np.array([walker.to_public(x) for x in spline(grid - t0)]).reshape(-1, 8)
        pub[:, :4] *= sign
        times.append(grid)
        states.append(pub)
        stance.append(np.full(len(grid), "L" if sign > 0 else "R"))
        pieces.append((step.step_time, spline, sign))
        events.append({"time": t1, "foot": "R" if sign > 0 else "L"})
        t0, sign = t1, -sign
        z = step.z_plus.copy()
        z[1::2] += rng.normal(0.0, kick, 4)  # phi_dot, psi_dot, theta_st_dot, theta_sw_dot
    x, st = np.concatenate(states), np.concatenate(stance)
    signals = {"lean": x[:, 2], "steer": x[:, 0],
               "pitch_left": np.where(st == "L", x[:, 4], x[:, 6]),
               "pitch_right": np.where(st == "R", x[:, 4], x[:, 6])}
    table = TrajectoryTable(np.concatenate(times), signals, st, events, {})

    def truth(phase):
        out = np.array([walker.to_public(spline(phase * duration)) for duration, spline, _ in pieces])
        out[:, :4] *= np.array([s for _, _, s in pieces])[:, None]
        return out

    return table, truth


def _noisy(table, sd, seed, sd_column=None):
    """The walk with N(0, sd) added to every angle (rad); ``sd_column`` written as ``*_sd``."""
    rng = np.random.default_rng(seed)
    signals = {k: v + rng.normal(0.0, sd, v.shape) for k, v in table.signals.items()}
    if sd_column is not None:
        signals.update({f"{k}_sd": np.full(len(table.time), sd_column) for k in table.signals})
    return TrajectoryTable(table.time, signals, table.stance, [dict(e) for e in table.events], {})


def _mirrored(states, stance):
    out = states.copy()
    out[np.asarray(stance) == "R", :4] *= -1.0
    return out


def _dominant(eigenvalues):
    """The largest-modulus eigenvalue, of a complex pair the one with positive imaginary part."""
    top = eigenvalues[np.isclose(np.abs(eigenvalues), np.abs(eigenvalues[0]), rtol=1e-9)]
    return top[np.argmax(top.imag)]


@pytest.fixture(scope="module")
def toy():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return params, Walker(params), find_gait(params)


@pytest.fixture(scope="module")
def kicked(toy):
    """600 strides kicked by 0.001 rad/s: deviations of 0.017 rad in steer, 0.0017 rad in lean,
    0.012 / 0.018 rad in the pitches at mid-step."""
    _, walker, gait = toy
    return _kicked_walk(walker, gait.fixed_point, STEPS, 0.001, seed=0)


@pytest.fixture(scope="module")
def quiet(toy):
    """600 strides kicked by 0.0002 rad/s: a walk that stays within a few milliradians of its
    cycle, as small as the measurement noise below."""
    _, walker, gait = toy
    return _kicked_walk(walker, gait.fixed_point, STEPS, 0.0002, seed=0)


def test_stride_map_recovers_the_model_multipliers(toy, kicked):
    """Noise-free angles, the full state (the default): the largest stride-map multiplier is the
    model's within 1/sqrt(N) (N = 600 strides), by all three estimators. Reason for the tolerance:
    least squares on the linearised stride map (the gait's AD Jacobian squared, the same kicks, 600
    strides, 400 Monte Carlo walks) gives max |eigenvalue| 0.934 +/- 0.016; 1/sqrt(600) = 0.041
    is 2.6 of those."""
    _, _, gait = toy
    table, _ = kicked
    model = np.abs(gait.eigenvalues[0]) ** 2  # symmetric walker: stride = step map squared
    rm = return_map(table, rng=1)
    assert rm.coordinates == ALL_COORDINATES and rm.n_pairs == STEPS // 2 - 1
    tol = 1.0 / math.sqrt(rm.n_pairs)
    for est in rm.estimates.values():
        assert est.status == "ok", (est.method, est.message)
        assert abs(est.max_abs_eigenvalue - model) < tol, (est.method, est.max_abs_eigenvalue, model)
    # Without measurement noise the correction has nothing to remove: naive and corrected agree
    # to well within the sampling error (the noise estimate is the fourth-difference floor,
    # 2e-6 to 2e-5 rad, against 1e-2 rad of spread).
    assert abs(rm.corrected.max_abs_eigenvalue - rm.naive.max_abs_eigenvalue) < 0.1 * tol
    # Seven directions: the eighth, across the guard surface, holds no dynamics.
    assert rm.rank == 7 and rm.directions.shape == (8, 7)


def test_multipliers_do_not_depend_on_the_section_phase(toy, kicked):
    """The full state at phases 0.25, 0.5, 0.75: each within 1/sqrt(N) of the model, and within
    0.02 of each other (the same strides, so most of their sampling errors are shared; two
    5000-stride walks put the three phases' limits within 0.019 of each other)."""
    _, _, gait = toy
    table, _ = kicked
    model = np.abs(gait.eigenvalues[0]) ** 2
    full = return_maps(table, phases=(0.25, 0.5, 0.75), rng=2)
    tol = 1.0 / math.sqrt(full[0].n_pairs)
    for rm in full:
        for est in (rm.naive, rm.corrected):
            assert abs(est.max_abs_eigenvalue - model) < tol, (rm.phase, est.method, est.max_abs_eigenvalue)
    spread = np.ptp([rm.corrected.max_abs_eigenvalue for rm in full])
    assert spread < 0.02, spread


@pytest.mark.slow
def test_a_subset_of_coordinates_is_a_partial_observation(toy):
    """Lean and steer alone: the map seen through them has a largest multiplier that moves with
    the section phase (two 5000-stride walks: 0.919 to 0.925 at mid-step, 0.977 to 0.979 at 0.75),
    while the full state's does not (0.930 to 0.948). With 3000 strides (sampling error about
    0.007): the lateral estimates at 0.5 and 0.75 differ by more than 0.03, the full state's by
    less than 0.02. About 10 s."""
    _, walker, gait = toy
    table, _ = _kicked_walk(walker, gait.fixed_point, 6000, 0.001, seed=12)
    lateral = return_maps(table, phases=(0.5, 0.75), coordinates=LATERAL_COORDINATES, bootstrap=0)
    full = return_maps(table, phases=(0.5, 0.75), bootstrap=0)
    lat = [rm.corrected.max_abs_eigenvalue for rm in lateral]
    whole = [rm.corrected.max_abs_eigenvalue for rm in full]
    assert lat[1] - lat[0] > 0.03, lat
    assert abs(whole[1] - whole[0]) < 0.02, whole


def test_step_map_mirrors_the_right_stance_steps(toy, kicked):
    """The step map (every step, right-stance steps mirrored) has the step map's dominant
    eigenvalue -0.961 + 0.111i. Tolerance 0.06: least squares on the linearised step map (1200
    steps, 400 walks) puts the dominant eigenvalue within 0.052 of the model's in 95 % of walks.
    Without the mirror the lateral coordinates change sign every step and the check fails."""
    _, _, gait = toy
    table, _ = kicked
    model = _dominant(gait.eigenvalues)
    rm = return_map(table, kind="step", rng=3)
    assert rm.n_pairs == STEPS - 1 and rm.stance is None
    for est in (rm.naive, rm.corrected):
        assert abs(_dominant(est.eigenvalues) - model) < 0.06, (est.method, est.eigenvalues[:2], model)
    # The same strides as a stride map: its multiplier is the step map's squared, within the two
    # estimates' sampling errors (1/sqrt(N) each, N = 600 and 1200).
    stride = return_map(table, bootstrap=0)
    assert abs(stride.naive.max_abs_eigenvalue - rm.naive.max_abs_eigenvalue ** 2) < 2 / math.sqrt(600)
    # A constant offset of the measured lean and steer (0.01 rad, a camera rolled and turned
    # about the ramp) changes sign with the mirror. Centred per stance leg, it changes nothing;
    # centred as one sequence, it would be an alternation x_k+1 = -x_k, an eigenvalue -1.
    shifted = {k: v + 0.01 if k in ("lean", "steer") else v for k, v in table.signals.items()}
    shifted = TrajectoryTable(table.time, shifted, table.stance, table.events)
    offset = return_map(shifted, kind="step", bootstrap=0)
    assert np.allclose(offset.naive.eigenvalues, rm.naive.eigenvalues, atol=1e-9)
    x, _ = section_states(shifted).mirrored()
    one_mean = np.linalg.lstsq(x[:-1] - x[:-1].mean(axis=0), x[1:] - x[1:].mean(axis=0), rcond=None)[0]
    assert abs(np.linalg.eigvals(one_mean.T) + 1).min() < 0.01
    # Lean and steer alone see the mirror most plainly. Undo it (lean and steer of the
    # right-stance steps negated in the file) and their dominant eigenvalue changes sign.
    flipped = {k: np.where(table.stance == "R", -v, v) if k in ("lean", "steer") else v
               for k, v in table.signals.items()}
    for signals, near in ((table.signals, True), (flipped, False)):
        lateral = return_map(TrajectoryTable(table.time, signals, table.stance, table.events),
                             kind="step", coordinates=LATERAL_COORDINATES, bootstrap=0)
        assert (abs(_dominant(lateral.naive.eigenvalues) - model) < 0.06) == near, lateral.naive


def test_measurement_noise_dilutes_least_squares(toy, quiet):
    """0.005 rad of noise on a walk that stays close to its cycle: least squares is biased toward
    zero, the errors-in-variables and the instrumental estimates are not.

    The section states then vary between steps by more than their noise in one direction only
    (signal-to-noise variance ratio 1.9 to 3.8 in four walks, the others below 0.25, dropped with a
    warning), so each estimate is of the map seen through it. The checks: each estimate against
    the model's step multiplier within 3 of its own bootstrap standard errors (naive about 0.02,
    the corrections 0.02 to 0.04); the naive one fails it by far (0.67 to 0.79 in four walks, the
    model 0.967). The errors-in-variables estimate is also checked against what it is consistent
    for: the noise-free regression of the true section states on the kept direction (0.983 to
    0.988 in those walks)."""
    _, _, gait = toy
    table, truth = quiet
    model = abs(gait.eigenvalues[0])
    rm = return_map(_noisy(table, 0.005, seed=4), kind="step", rng=5)
    # The noise estimate (fourth differences) is the truth within 2 % (about 6000 differences per
    # signal: sampling error 1 %).
    for name, sd in rm.sections.noise_sd.items():
        assert rm.sections.noise_source[name] == "fourth differences"
        assert abs(sd / 0.005 - 1) < 0.02, (name, sd)
    assert 1 <= rm.rank < 8 and any("S_00 - Sigma_noise is near singular" in w for w in rm.warnings)
    naive, corrected, iv = rm.naive, rm.corrected, rm.instrumental
    assert naive.max_abs_eigenvalue < model - 3 * naive.max_abs_sd, (naive.max_abs_eigenvalue, model)
    for est in (corrected, iv):
        assert est.status == "ok"
        assert abs(est.max_abs_eigenvalue - model) < 3 * est.max_abs_sd, (est.method, est.max_abs_eigenvalue)
    # What the corrected estimate targets: the true section states (mirrored), projected on the
    # kept directions, regressed one step ahead.
    x = _mirrored(truth(0.5), rm.sections.stance)
    z = (x[:-1] - x[:-1].mean(axis=0)) @ rm.directions
    y = x[1:] - x[1:].mean(axis=0)
    coef = np.linalg.lstsq(z, y, rcond=None)[0]  # (rank, 8)
    target = np.max(np.abs(np.linalg.eigvals(rm.directions.T @ coef.T)))
    assert abs(corrected.max_abs_eigenvalue - target) < 3 * corrected.max_abs_sd, (corrected, target)
    assert abs(naive.max_abs_eigenvalue - target) > 3 * naive.max_abs_sd


def test_section_states_match_the_simulated_truth(kicked):
    """Angles and rates at two phases of every step against the simulation's state there, with
    0.003 rad of noise: the errors over their reported standard deviations have an RMS of one
    within 0.1 and a mean within 0.15 (1200 steps: sampling errors 0.02 and 0.03; the margin
    allows the local quartic's bias, below 0.1 of an SD; four walks gave RMS 0.95 to 1.04 and means
    within 0.09)."""
    table, truth = kicked
    noisy = _noisy(table, 0.003, seed=6)
    for phase in (0.25, 0.5):
        sec = section_states(noisy, phase)
        assert sec.valid.all() and len(sec.step) == STEPS
        err = sec.states - truth(phase)
        sd = np.sqrt(np.einsum("nii->ni", sec.covariance))
        z = err / sd
        rms = np.sqrt(np.mean(z**2, axis=0))
        assert np.all(np.abs(rms - 1) < 0.1), (phase, rms)
        assert np.all(np.abs(z.mean(axis=0)) < 0.15), (phase, z.mean(axis=0))
        # The reported SDs are the noise's, not the spread's: angle 0.001 to 0.002 rad, rate
        # 0.1 to 0.3 rad/s, from about 13 samples in the window.
        assert np.all((sd[:, ::2] > 0.001) & (sd[:, ::2] < 0.002))
        assert np.all((sd[:, 1::2] > 0.1) & (sd[:, 1::2] < 0.3))


def test_missing_samples_are_left_out(kicked):
    """A tracker loses markers: 10 % of every angle's samples missing (NaN, empty cells in the
    file). The windows use the rest, the fourth differences the runs of five that remain (0.9^5:
    about 60 % of them), and the errors still match the reported SDs (RMS within 0.1 of 1)."""
    table, truth = kicked
    noisy = _noisy(table, 0.003, seed=10)
    rng = np.random.default_rng(11)
    for values in noisy.signals.values():
        values[rng.random(len(values)) < 0.1] = np.nan
    sec = section_states(noisy)
    assert sec.valid.all()
    assert all(abs(sd / 0.003 - 1) < 0.03 for sd in sec.noise_sd.values()), sec.noise_sd
    z = (sec.states - truth(0.5)) / np.sqrt(np.einsum("nii->ni", sec.covariance))
    assert np.all(np.abs(np.sqrt(np.mean(z**2, axis=0)) - 1) < 0.1)


def test_given_sds_and_strike_timing(kicked):
    """*_sd columns replace the noise estimate and are checked against the samples; heel-strike
    timing errors (events' time_sd) enter the covariance, and without them the errors would be
    several times the reported SDs."""
    table, truth = kicked
    estimated = section_states(_noisy(table, 0.003, seed=7))
    given = section_states(_noisy(table, 0.003, seed=7, sd_column=0.003))
    assert set(given.noise_source.values()) == {"*_sd columns"}
    # Same noise, once estimated (within 2 %) and once given: covariances within 4 %.
    assert np.allclose(given.covariance, estimated.covariance, rtol=0.04, atol=0)
    wrong = return_map(_noisy(table, 0.003, seed=7, sd_column=0.0015), bootstrap=0)
    assert any("disagrees with the samples' scatter" in w and "too small" in w for w in wrong.warnings)
    # Strike times measured with 2 ms errors (half a frame at 240 per second), and said so.
    rng = np.random.default_rng(8)
    jittered = _noisy(table, 0.003, seed=7)
    for ev in jittered.events:
        ev["time"] += rng.normal(0.0, 0.002)
        ev["time_sd"] = 0.002
    sec = section_states(jittered)
    assert sec.timing
    z = (sec.states - truth(0.5)) / np.sqrt(np.einsum("nii->ni", sec.covariance))
    assert np.all(np.abs(np.sqrt(np.mean(z**2, axis=0)) - 1) < 0.1)
    # The check can fail: the same errors over the SDs without the timing term.
    z_untimed = (sec.states - truth(0.5)) / np.sqrt(np.einsum("nii->ni", estimated.covariance))
    assert np.sqrt(np.mean(z_untimed[:, 6] ** 2)) > 3  # the swing pitch, moving at 6 rad/s


def test_a_missed_strike_leaves_the_longest_run_with_its_timing(kicked):
    """A tracker missed the 11th strike: the sections are those of the longest run of complete
    steps (measurement.complete_steps), each with its own strikes' time SDs (the whole walk's
    strike list against the run's steps had raised a shape mismatch)."""
    table, truth = kicked
    noisy = _noisy(table, 0.003, seed=7)
    for ev in noisy.events:
        ev["time_sd"] = 0.002
    events = noisy.events[:10] + noisy.events[11:]
    gapped = TrajectoryTable(noisy.time, noisy.signals, noisy.stance, events, noisy.metadata)
    sec = section_states(gapped)
    assert sec.timing and len(sec.step) == len(noisy.events) - 1 - 11  # steps 11 onwards
    whole = section_states(noisy)
    np.testing.assert_allclose(sec.states, whole.states[11:], rtol=0, atol=1e-12)


def test_a_walk_on_its_cycle_holds_no_information(toy):
    """200 steps exactly on the cycle, 0.003 rad of noise: every direction's spread is noise (the
    largest sample eigenvalue of 8 noise directions from 99 pairs lies near (1 + sqrt(8/99))^2 =
    1.65, below the threshold 2), so there is no estimate, and the warning says why."""
    _, walker, gait = toy
    table, _ = _kicked_walk(walker, gait.fixed_point, 200, 0.0, seed=0)
    rm = return_map(_noisy(table, 0.003, seed=9), bootstrap=10)
    assert rm.rank == 0
    assert any("stays on its cycle within the measurement noise" in w for w in rm.warnings)
    for est in rm.estimates.values():
        assert est.status == "failed" and math.isnan(est.max_abs_eigenvalue)
    json.dumps(rm.to_json(), allow_nan=False)
    # Forced to fit the noise (a tiny min_snr): x_k-1 does not predict x_k, and the instrumental
    # estimate is flagged (first-stage F below 10).
    forced = return_map(_noisy(table, 0.003, seed=9), min_snr=1e-6, bootstrap=0)
    assert forced.rank >= 1 and forced.instrumental.status == "unreliable"
    assert any(w.startswith("weak instrument") for w in forced.warnings)

def test_a_short_walk_fits_fewer_directions(kicked):
    """40 steps, 19 stride pairs: 5 pairs per unknown allow 2 directions and the intercept; the
    warning gives the numbers."""
    table, _ = kicked
    short = TrajectoryTable(table.time, table.signals, table.stance, table.events[:41])
    rm = return_map(short, bootstrap=0)
    assert rm.n_pairs == 19 and rm.rank == 2 and rm.directions.shape == (8, 2)
    assert any(w.startswith("19 stride pairs for a 8-coordinate map") for w in rm.warnings)
    assert np.count_nonzero(np.abs(rm.naive.eigenvalues) > 1e-9) == 2


def test_unusable_input_is_one_clear_line(kicked):
    table, _ = kicked
    events = table.events
    cases = {
        "usable stride pair": TrajectoryTable(table.time, table.signals, table.stance, events[:11]),
        "at least 3": TrajectoryTable(table.time, table.signals, table.stance, events[:2]),
        "no lean column": TrajectoryTable(table.time, {k: v for k, v in table.signals.items()
                                                       if k != "lean"}, table.stance, events),
    }
    for match, bad in cases.items():
        with pytest.raises(ReturnMapError, match=match) as info:
            return_map(bad, bootstrap=0)
        assert "\n" not in str(info.value)
    # 5 strides give 4 pairs: enough for one coordinate (3 needed), not for four (6).
    few = TrajectoryTable(table.time, table.signals, table.stance, events[:11])
    assert return_map(few, coordinates=("phi",), bootstrap=0).n_pairs == 4
    # A pitch-only map does not need lean and steer.
    pitch_only = {k: v for k, v in table.signals.items() if k.startswith("pitch")}
    rm = return_map(TrajectoryTable(table.time, pitch_only, table.stance, events),
                    coordinates=("theta_st", "theta_sw"), bootstrap=0)
    assert rm.sections.signals == ("pitch_left", "pitch_right")
    options = [{"kind": "strides"}, {"stance": "X"}, {"coordinates": ("phi", "yaw")},
               {"coordinates": "phi"}, {"coordinates": ("phi", "phi")}, {"phase": 1.5},
               {"width": 0.0}, {"degree": 0}, {"min_snr": 0.0}, {"bootstrap": -1}]
    for option in options:
        with pytest.raises(ReturnMapError) as info:
            return_map(table, **option)
        assert "\n" not in str(info.value), option
    assert issubclass(ReturnMapError, MeasurementError) and issubclass(ReturnMapError, ValueError)
    with pytest.raises(TypeError):
        return_map(table, phases=0.5)  # a misspelled keyword is an error


def test_result_to_json_from_a_trajectory_file(kicked, tmp_path):
    """The walk through the trajectory files of docs/formats.md (repr round-trips every float), then the
    result as JSON without NaN."""
    table, _ = kicked
    write_trajectory(table, tmp_path / "walk.csv")
    rm = return_map(read_trajectory(tmp_path / "walk.csv"), bootstrap=20, rng=0)
    assert np.array_equal(rm.naive.eigenvalues, return_map(table, bootstrap=0).naive.eigenvalues)
    data = json.loads(json.dumps(rm.to_json(), allow_nan=False))
    assert data["kind"] == "stride" and data["coordinates"] == list(ALL_COORDINATES)
    assert set(data["estimates"]) == {"naive", "corrected", "instrumental"}
    est = data["estimates"]["corrected"]
    assert est["max_abs_eigenvalue"] == rm.corrected.max_abs_eigenvalue
    assert len(est["eigenvalues"]) == 8
    assert est["eigenvalues"][0]["abs"] == pytest.approx(est["max_abs_eigenvalue"], rel=1e-12)
    assert data["sections"]["noise_source"]["lean"] == "fourth differences"
    assert np.shape(data["directions"]) == (8, rm.rank)
