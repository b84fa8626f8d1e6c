"""The effects library (docs/model.md section 6): registry, exact null, independent references for every
new term, energy accounting, AD Jacobians, and the symmetry-breaking (stride-periodic) gaits."""

import math
import pickle

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.collocation import solve_collocation
from toywalk.model.effects import CONTINUOUS, COULOMB_SMOOTHING, EFFECTS, LIBRARY, coulomb_torque
from toywalk.model.gait import find_gait, solve_fixed_point
from toywalk.model.kinematics import rotation
from toywalk.model.parameters import PARAMETER_NAMES, ParameterError, Params, load_params
from toywalk.model.simulate import simulate
from toywalk.model.walker import StepFailure, Walker, _admissible

from ..conftest import DATA
from .collision_reference import free_system, u_plus_old_labels
from .effect_reference import omega_partials, random_states, typical
from .walkers import FEET, GENERAL

# The library's effects proper; the port-only terms of the registry have their own checks
# (tests/model/test_ports.py).
SYMMETRIC = [name for name in LIBRARY if not EFFECTS[name].breaks_symmetry]
LIBRARY_CONTINUOUS = [name for name in CONTINUOUS if name in LIBRARY]
EZ = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def toy():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return params, find_gait(params)




# ----------------------------------------------------------------------------------- registry
def test_registry_describes_every_effect():
    required = {"hip_damping", "hip_coulomb", "rolling_resistance", "pivot_friction",
                "impact_trailing_share", "asymmetry", "cross_slope"}
    assert required <= set(EFFECTS)
    assert len([e for e in EFFECTS.values() if e.enters == "collision law"]) >= 2
    for name, effect in EFFECTS.items():
        info = effect.describe()
        assert info["name"] == name and info["unit"] and info["physics"]
        assert info["enters"] in ("equations of motion", "contact couple", "collision law", "geometry")
        low, high = effect.bounds
        assert low <= effect.null <= high and low <= effect.typical <= high
        assert effect.typical != effect.null
        assert f"effects.{name}" in PARAMETER_NAMES
    assert set(LIBRARY_CONTINUOUS) == {"hip_damping", "hip_coulomb", "rolling_resistance", "pivot_friction"}


def test_parameter_files_name_effects_and_refuse_unknown_or_impossible(toy, tmp_path):
    params, _ = toy
    with pytest.raises(ParameterError, match="known: .*hip_damping"):
        params.replace(**{"effects.hip_dampingg": 1.0})
    with pytest.raises(ParameterError, match="physical bounds"):
        params.replace(**{"effects.hip_damping": -1e-4})  # a damper that feeds energy in
    with pytest.raises(ParameterError, match="finite"):
        params.replace(**{"effects.pivot_friction": math.nan})
    on = params.replace(**{"effects.hip_damping": 3e-4})
    vec = on.vector()
    assert vec[PARAMETER_NAMES.index("effects.hip_damping")] == 3e-4
    assert vec[PARAMETER_NAMES.index("effects.pivot_friction")] == 0.0  # silent file: null
    assert on.input_vector(-1.0)[-1] == -1.0
    # Parameter sets with effects pickle (process pools) and stay frozen.
    back = pickle.loads(pickle.dumps(on))
    assert back == on and back.vector().tobytes() == vec.tobytes()
    with pytest.raises(TypeError):
        back.effects["hip_damping"] = 1.0


# ----------------------------------------------------------------------- null: the seed's model


@pytest.mark.parametrize("feet", sorted(FEET))
def test_null_effects_equal_the_seed_model_pointwise(feet):
    """Every effect at null: right-hand side, energy, collision and guard equal those built without
    the effect library (the seed's equations, run in CasADi's virtual machine) to round-off."""
    params = Params(**GENERAL, **FEET[feet])
    ours, seed = Walker(params), Walker(params, effects=False, compiled=False)
    rng = np.random.default_rng(10)
    for x in random_states(rng, 10):
        for name in ("rhs", "collision", "energy", "guard", "impact"):
            a = np.concatenate([np.ravel(v) for v in ours.eng.k[name](x, ours.p)])
            b = np.concatenate([np.ravel(v) for v in seed.eng.k[name](x, seed.p)])
            # The same expressions with zero-strength terms added: agreement to round-off.
            assert_allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(b).max(), err_msg=name)
    # The comparison can fail: one effect on changes the right-hand side.
    on = Walker(params.replace(**{"effects.hip_damping": 1e-3}))
    assert np.abs(on.rhs(x) - seed.rhs(x)).max() > 1e-3


@pytest.mark.parametrize("name", ["compass-3d", "stable-toy", "seed-pointfoot"])
def test_null_effects_reproduce_gait_eigenvalues_and_a_30_step_walk(name):
    """Sphere (compass-3d), torus (stable-toy) and point (seed-pointfoot) feet: the gait, its
    eigenvalues and 30 steps from a perturbed start agree with the seed's equations."""
    params = load_params(DATA / "params" / f"{name}.toml")
    gait = find_gait(params)
    seed = solve_fixed_point(Walker(params, effects=False, compiled=False), gait.fixed_point)
    # Both solve P(z) = z to 1e-11 with exact Jacobians; their maps agree to round-off.
    assert_allclose(seed.fixed_point, gait.fixed_point, atol=1e-11)
    assert abs(seed.step_time - gait.step_time) < 1e-12 * max(1.0, gait.step_time) + 1e-14
    assert_allclose(np.sort_complex(seed.eigenvalues), np.sort_complex(gait.eigenvalues), atol=1e-9)
    ours, base = Walker(params), Walker(params, effects=False, compiled=False)
    z_a = z_b = gait.fixed_point + 1e-6
    for k in range(30):
        try:
            a, b = ours.step(z_a), base.step(z_b)
        except StepFailure as err:  # an unstable gait may fall: both must fall alike
            with pytest.raises(StepFailure) as info:
                base.step(z_b)
            assert info.value.status == err.status and k >= 10
            break
        # Round-off (1e-16) grows at most as |lambda_max|^k; the seed's case has 1.08 per step.
        tol = 1e-13 * max(1.0, gait.max_abs_eigenvalue) ** k
        assert_allclose(a.z_plus, b.z_plus, atol=tol * 1e3, err_msg=f"step {k}")
        assert abs(a.step_time - b.step_time) < tol * 1e2
        z_a, z_b = a.z_plus, b.z_plus


# ------------------------------------------------------ continuous effects: independent reference


def _reference_couples(name, k, params, q, u):
    """Couples (leg index, M) of docs/model.md section 6, from their physical definitions."""
    w_st, w_sw = (w @ u for w in omega_partials(q))
    n = rotation(q[0], q[1], 0.0)[:, 1]
    rel = u[3] - u[2]
    if name == "hip_damping":
        tau = -k * rel
    elif name == "hip_coulomb":
        eps = COULOMB_SMOOTHING * math.sqrt(params.gravity / params.leg_length)
        tau = -k * rel / math.sqrt(rel**2 + eps**2)
    elif name == "rolling_resistance":
        return [(0, -k * (w_st - (w_st @ EZ) * EZ))]
    elif name == "pivot_friction":
        return [(0, -k * (w_st @ EZ) * EZ)]
    return [(1, tau * n), (0, -tau * n)]


@pytest.mark.parametrize("name", LIBRARY_CONTINUOUS)
def test_continuous_effects_equal_virtual_work_reference(name):
    """M (u'_effect - u'_seed) equals the generalised force by virtual work, Q_j = sum_i M_i .
    d omega_i / du_j, with partial angular velocities from NumPy rotations; the dissipation
    output equals -sum_i M_i . omega_i = -Q . u."""
    base = Params(**GENERAL, **FEET["torus"])
    k = 10 * EFFECTS[name].typical
    walker, seed = Walker(base.replace(**{f"effects.{name}": k})), Walker(base)
    rng = np.random.default_rng(11)
    for x in random_states(rng, 6):
        q, u = x[:4], x[4:8]
        partials = omega_partials(q)
        couples = _reference_couples(name, k, base, q, u)
        q_ref = sum(partials[leg].T @ m for leg, m in couples)
        m_mat = walker.eng.k["mass_matrix"](x, walker.p)[0]
        q_model = m_mat @ (walker.rhs(x)[4:8] - seed.rhs(x)[4:8])
        # Central differences of rotations at h = 1e-6: error ~1e-10 of the couples.
        assert_allclose(q_model, q_ref, atol=1e-8 * np.abs(q_ref).max() + 1e-15)
        assert np.abs(q_ref).max() > 0
        power = walker.dissipation(x)
        i = CONTINUOUS.index(name)
        expected = -sum(m @ (partials[leg] @ u) for leg, m in couples)
        assert_allclose(power[i], expected, rtol=1e-8)
        assert_allclose(power[i], -q_ref @ u, rtol=1e-8)
        assert power[i] >= 0.0  # every continuous effect dissipates
        assert np.all(np.delete(power, i) == 0.0)


def test_coulomb_regularisation():
    """Odd, bounded by T, dissipative, within 1 % of T sign(rate) beyond 7.1 eps (the stated
    smoothing), and half the Coulomb value at rate eps / sqrt(3)."""
    t, eps = 2e-3, 0.05
    rates = np.linspace(-1.0, 1.0, 2001)
    tau = coulomb_torque(t, rates, eps)
    assert_allclose(tau, -coulomb_torque(t, -rates, eps))
    assert np.all(np.abs(tau) <= t) and np.all(tau * rates <= 0)
    far = np.abs(rates) >= 7.1 * eps
    assert np.all(np.abs(tau[far] + t * np.sign(rates[far])) <= 0.01 * t)
    assert_allclose(coulomb_torque(t, eps / math.sqrt(3), eps), -t / 2)


# ------------------------------------------------------------------------------------ energy
def test_energy_lost_equals_integrated_dissipation(toy):
    """All continuous effects on at once: between collisions E(t) - E(0) + W(t) stays below 1e-9
    of m g l (W from the same Runge-Kutta steps as the state); without W the balance fails."""
    params, gait = toy
    walker = Walker(typical(params, LIBRARY_CONTINUOUS))
    step = walker.step(gait.fixed_point, record=True)
    energy = np.array([walker.energy(x) for x in step.states])
    lost = step.dissipated.sum(axis=1)
    scale = params.total_mass * params.gravity * params.leg_length
    assert np.abs(energy - energy[0] + lost).max() / scale < 1e-9
    assert lost[-1] / scale > 1e-4  # the check can fail: the dissipated energy is not negligible
    assert np.all(step.dissipated[-1, [CONTINUOUS.index(n) for n in LIBRARY_CONTINUOUS]] > 0)
    assert step.collision_loss > 0


def test_simulation_reports_energy_budget(toy):
    params, gait = toy
    traj = simulate(typical(params, LIBRARY_CONTINUOUS), gait.fixed_point, 4)
    assert len(traj.collision_losses) == 4 and np.all(traj.collision_losses > 0)
    assert set(traj.dissipated) == set(CONTINUOUS)
    assert all(traj.dissipated[name] > 0 for name in LIBRARY_CONTINUOUS)


# -------------------------------------------------------------------------------- collisions
def _reference_collision(params, x, share, arrest):
    """Post-collision speeds, energy change and normal impulses from the free walker (impulses
    at D, a normal impulse lambda_C = share * Lambda at C, a couple about e_z on the landing leg
    for the arrested law), built from NumPy kinematics (tests/model/collision_reference.py)."""
    q, rates = x[:4], x[4:8]
    m_free, a_d, a_c = free_system(params, q)
    u_minus = np.zeros(7)
    u_minus[3:] = rates
    u_minus[:3] = -(a_c[:, 3:] @ rates)
    # lambda_C = share (P_Dz + lambda_C)  =>  lambda_C = share / (1 - share) P_Dz.
    ratio = share / (1.0 - share)
    b = a_d.T + ratio * np.outer(a_c[2], EZ)  # generalised impulse per unit P_D
    w2z = np.zeros(7)
    w2z[3:] = [EZ @ c for c in _omega_columns(q)]

    def solve(with_arrest):
        extra = 1 if with_arrest else 0
        kkt = np.zeros((10 + extra, 10 + extra))
        # The arrested law: the landing patch takes the whole impulse (no trailing share).
        kkt[:7, :7], kkt[:7, 7:10], kkt[7:10, :7] = m_free, -(a_d.T if with_arrest else b), a_d
        if with_arrest:
            kkt[:7, 10], kkt[10, :7] = -w2z, w2z
        sol = np.linalg.solve(kkt, np.r_[m_free @ u_minus, np.zeros(3 + extra)])
        return sol[:7], sol[7:10]

    u0, p0 = solve(False)
    u1, p1 = solve(True)
    u_plus = u0 + arrest * (u1 - u0)
    d_kinetic = 0.5 * (u_plus @ m_free @ u_plus - u_minus @ m_free @ u_minus)
    lead = (1 - arrest) * p0[2] + arrest * p1[2]
    before = 0.5 * u_minus @ m_free @ u_minus
    return u_plus[3:], d_kinetic, np.array([lead, (1 - arrest) * ratio * p0[2]]), before


def _omega_columns(q):
    """d omega_2 / d(phi', psi', th1', th2'): e_z, the steered x axis, 0, n."""
    n = rotation(q[0], q[1], 0.0)[:, 1]
    return [EZ, np.array([math.cos(q[0]), math.sin(q[0]), 0.0]), np.zeros(3), n]


def _heel_strike_states(params, gait, rng, n, spread=1.0):
    """Perturbed pre-impact states that are heel strikes the seed's law admits: the swing foot
    ahead and moving down, and non-negative normal impulses. ``spread`` 1 perturbs angles by
    0.05 rad and rates by 50 % plus 0.5 sqrt(g/l) (SDs)."""
    seed = Walker(params)
    found = 0
    while found < n:
        z = gait.step.z_minus.copy()
        z[[0, 2, 4, 6]] += rng.normal(0, 0.05 * spread, 4)
        z[[1, 3, 5, 7]] = (z[[1, 3, 5, 7]] * (1 + rng.normal(0, 0.5 * spread, 4))
                           + rng.normal(0, 0.5 * spread, 4) / params.time_scale)
        x = seed.full_state(z)
        h, ahead = seed.guard(x)
        if seed.guard(x + 1e-7 * seed.rhs(x))[0] >= h or ahead <= 0:
            continue
        if np.min(seed.eng.k["impact"](x, seed.p)[1]) < 0:
            continue
        found += 1
        yield x


@pytest.mark.parametrize("feet", sorted(FEET))
def test_collision_effects_match_free_walker_impulses(feet):
    """The trailing share and the spin arrest, built into the angular-momentum jump conditions,
    equal a plastic impulse computation on the free walker from NumPy kinematics."""
    params = Params(**GENERAL, **FEET[feet])
    rng = np.random.default_rng(12)
    for share, arrest in ((0.2, 0.0), (0.0, 0.7), (0.25, 1.0)):
        walker = Walker(params.replace(**{"effects.impact_trailing_share": share,
                                          "effects.impact_spin_arrest": arrest}))
        for x in random_states(rng, 4):
            expected, d_k, impulses, before = _reference_collision(params, x, share, arrest)
            got = u_plus_old_labels(walker, walker.eng.k["collision"](x, walker.p)[0].ravel())
            rate = np.max(np.abs(x[4:8]))
            # A 4x4 (or 5x5) solve against a 10x10 (11x11) one: round-off level.
            assert_allclose(got, expected, atol=1e-9 * rate, err_msg=f"{share}, {arrest}")
            d_k_got, imp_got, before_got = (np.ravel(a) for a in walker.eng.k["impact"](x, walker.p))
            assert_allclose(before_got[0], before, rtol=1e-12)
            assert_allclose(d_k_got[0], d_k, atol=1e-10 * abs(d_k) + 1e-15)
            assert_allclose(imp_got, impulses, atol=1e-9 * np.abs(impulses).max())


@pytest.mark.parametrize("name", ["stable-toy", "compass-3d", "tinkertoy", "toy-sized", "seed-pointfoot"])
def test_collision_effects_never_gain_energy(name):
    """On heel strikes the seed's law admits (widely perturbed about each shipped 3D walker's), the
    collision-law effects anywhere in their bounds never gain energy; the trailing share never
    pulls on a foot and the trailing foot does take its share; the spin arrest's blend never gains
    on the law it starts from (convexity)."""
    params = load_params(DATA / "params" / f"{name}.toml")
    gait = find_gait(params)
    rng = np.random.default_rng(13)
    high = EFFECTS["impact_trailing_share"].bounds[1]
    walkers = {(s, k): Walker(params.replace(**{"effects.impact_trailing_share": s,
                                                "effects.impact_spin_arrest": k}))
               for s in (0.0, 0.5 * high, high) for k in (0.0, 0.5, 1.0)}
    for x in _heel_strike_states(params, gait, rng, 30):
        for (s, k), w in walkers.items():
            d_k, impulses, ke = (np.ravel(a) for a in w.eng.k["impact"](x, w.p))
            assert d_k[0] <= 1e-12 * ke, (s, k)
            if k == 0.0:
                assert np.min(impulses) >= -1e-12 * np.abs(impulses).sum(), s
                if s > 0:
                    assert impulses[1] > 0
        for s in (0.0, high):
            ends = [w_k.eng.k["impact"](x, w_k.p)[0][0, 0] for w_k in (walkers[s, 0.0], walkers[s, 1.0])]
            mid = walkers[s, 0.5].eng.k["impact"](x, walkers[s, 0.5].p)[0][0, 0]
            assert mid <= max(ends) + 1e-12 * ke


@pytest.mark.parametrize("name", ["stable-toy", "compass-3d", "tinkertoy", "toy-sized"])
def test_spin_arrest_grips_near_gaits_and_refuses_to_pull(name):
    """Arresting the landing foot's spin needs a compressive normal impulse. It has one on heel
    strikes near each shipped walker with a rounded foot (angles within 0.01 rad, rates within
    10 % + 0.1 sqrt(g/l) of the gait's); far from a gait it can need a pull, and then the step
    fails as inadmissible instead of walking on (measured: 0 of 200 states at this spread, 6-17 %
    at four times it, for stable-toy and tinkertoy; the point-footed seed case pulls in 10 % even
    here, so it is left out: a point has no patch to grip with)."""
    params = load_params(DATA / "params" / f"{name}.toml")
    gait = find_gait(params)
    rng = np.random.default_rng(14)
    arrested = Walker(params.replace(**{"effects.impact_spin_arrest": 1.0}))
    for x in _heel_strike_states(params, gait, rng, 30, spread=0.2):
        impulses = np.ravel(arrested.eng.k["impact"](x, arrested.p)[1])
        assert impulses[0] > 0
    pulling = next(x for x in _heel_strike_states(params, gait, np.random.default_rng(15), 400)
                   if np.ravel(arrested.eng.k["impact"](x, arrested.p)[1])[0] < 0) \
        if name in ("stable-toy", "tinkertoy") else None
    if pulling is not None:
        d_k, impulses, ke = (np.ravel(a).copy() for a in arrested.eng.k["impact"](pulling, arrested.p))
        with pytest.raises(StepFailure) as info:
            _admissible(float(d_k[0]), impulses, float(ke[0]))
        assert info.value.status == "inadmissible_impact"


def test_inadmissible_impact_is_a_step_failure():
    """Massless legs (the simplest walker's point-mass limit) cannot take a trailing impulse
    without gaining energy: the step says so instead of returning a gait."""
    params = load_params(DATA / "params" / "simplest-walker.toml")
    gait = find_gait(params)
    walker = Walker(params.replace(**{"effects.impact_trailing_share": 0.1}), planar=True)
    with pytest.raises(StepFailure) as info:
        walker.step(gait.fixed_point)
    assert info.value.status == "inadmissible_impact"


# ------------------------------------------------------------------------------ AD Jacobians
def test_ad_jacobians_with_effects_match_finite_differences(toy):
    """Every symmetric effect on at once: the step map's state and parameter Jacobians (effect
    strengths included) against central differences."""
    params, gait = toy
    on = typical(params, SYMMETRIC)
    walker = Walker(on)
    z = gait.fixed_point  # any state that completes a step (all effects together have no gait near)
    step = walker.step(z, params_jacobian=True)
    scale = np.array([1.0, 1.0 / params.time_scale] * 4)
    eps = 1e-6 * scale
    fd = np.zeros((8, 8))
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = eps[i]
        fd[:, i] = (walker.step(z + dz).z_plus - walker.step(z - dz).z_plus) / (2 * eps[i])
    # Central differences at h ~ 1e-6: truncation ~1e-12 |P'''|, round-off ~1e-16 / h.
    assert_allclose(step.jacobian, fd, atol=2e-6 * np.abs(fd).max())
    for name in SYMMETRIC:
        key = f"effects.{name}"
        k = PARAMETER_NAMES.index(key)
        h = 1e-4 * EFFECTS[name].typical
        up = Walker(on.replace(**{key: on.get(key) + h})).step(z)
        down = Walker(on.replace(**{key: on.get(key) - h})).step(z)
        fd_p = (up.z_plus - down.z_plus) / (2 * h)
        assert_allclose(step.jacobian_params[:, k], fd_p, atol=1e-6 * np.abs(fd_p).max(), err_msg=name)
        assert np.abs(fd_p).max() > 0  # the effect does act on the step


# ------------------------------------------------------------------------- symmetry breaking
def test_cross_slope_gait_walks_down_the_tilted_plane(toy):
    """A ramp tilted sideways is a steeper ramp whose fall line is turned: the stride gait heads
    down the true fall line, atan2(-cos(a) sin(b), sin(a)), at the step time of the untilted walker
    on slope asin(sqrt(sin^2 a + cos^2 a sin^2 b)) (an exact equivalence)."""
    params, _ = toy
    beta = 0.01
    gait = find_gait(params.replace(**{"effects.cross_slope": beta}))
    assert gait.period == 2
    a = params.slope
    expected = math.atan2(-math.cos(a) * math.sin(beta), math.sin(a))
    tilted = math.asin(math.hypot(math.sin(a), math.cos(a) * math.sin(beta)))
    steeper = find_gait(params.replace(slope=tilted))
    assert abs(gait.heading - expected) < 1e-9
    assert abs(gait.step_time - steeper.step_time) < 1e-11
    assert abs(gait.stride_length - steeper.stride_length * math.cos(expected)) < 1e-11
    # Its stride-map eigenvalues are the untilted step map's, squared (two steps).
    assert_allclose(np.sort(np.abs(gait.eigenvalues)), np.sort(np.abs(steeper.eigenvalues) ** 2), atol=1e-8)


def test_asymmetric_gait_collocation_equals_stride_shooting_and_walk_turns(toy):
    """Unequal legs: a stride-periodic gait. The two-step BVP by collocation equals the stride
    map's fixed point by shooting (1e-8), and 40 simulated steps drift sideways by 20 times the
    predicted drift per stride."""
    params, _ = toy
    walker_params = params.replace(**{"effects.asymmetry": EFFECTS["asymmetry"].typical})
    gait = find_gait(walker_params)
    assert gait.period == 2 and gait.steps[0].step_time != gait.steps[1].step_time
    assert abs(gait.stride_displacement[1]) > 1e-3  # a visible drift: a few mm per stride
    coll = solve_collocation(walker_params, gait.fixed_point + 1e-3)
    assert coll.success, coll.status
    assert_allclose(coll.fixed_point, gait.fixed_point, atol=1e-8)
    assert abs(coll.step_time - gait.step_time) < 1e-8
    assert_allclose(np.sort_complex(coll.eigenvalues), np.sort_complex(gait.eigenvalues), atol=1e-7)
    assert gait.stable
    traj = simulate(walker_params, gait.fixed_point, 40)
    assert traj.status == "completed"
    last = traj.events[-1]
    # A stable gait started on its fixed point stays on it: the drift is linear to 1e-8.
    assert_allclose([last.x, last.y], 20 * gait.stride_displacement, rtol=1e-8)


def test_continuation_in_a_symmetry_breaking_effect_follows_stride_gaits(toy):
    """Continuing in cross_slope follows fixed points of the stride map from the symmetric gait;
    every point is a stride gait (residual of the stride map below the corrector's tolerance)."""
    from toywalk.model.continuation import continue_branch

    params, gait = toy
    branch = continue_branch(params, "effects.cross_slope", 0.0, 0.004, max_points=30,
                             z_start=gait.fixed_point)
    assert branch.status == "reached" and branch.period == 2
    assert len(branch.points) >= 3
    for point in branch.points[1:]:
        walker = Walker(params.replace(**{"effects.cross_slope": point.value}), period=2)
        cycle = walker.cycle(point.fixed_point)
        assert np.max(np.abs(cycle.z_plus - point.fixed_point)) < 1e-9
    # The stride map of the symmetric start has the step map's eigenvalues squared.
    assert_allclose(np.sort(np.abs(branch.points[0].eigenvalues)),
                    np.sort(np.abs(gait.eigenvalues) ** 2), atol=1e-9)


def test_stride_jacobians_with_symmetry_breaking_effects_match_finite_differences(toy):
    """Unequal legs and a tilted ramp: the stride map's AD Jacobian (two steps, both sides) and its
    columns for the two symmetry-breaking strengths against central differences."""
    params, gait = toy
    on = params.replace(**{"effects.asymmetry": 0.003, "effects.cross_slope": 0.005})
    walker = Walker(on)
    assert walker.period == 2
    z = gait.fixed_point
    cycle = walker.cycle(z, params_jacobian=True)
    scale = np.array([1.0, 1.0 / params.time_scale] * 4)
    fd = np.zeros((8, 8))
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = 1e-6 * scale[i]
        fd[:, i] = (walker.cycle(z + dz).z_plus - walker.cycle(z - dz).z_plus) / (2 * dz[i])
    # Central differences at h ~ 1e-6 through two steps: truncation ~1e-12 |P'''|, round-off ~1e-10.
    assert_allclose(cycle.jacobian, fd, atol=2e-6 * np.abs(fd).max())
    for name in ("asymmetry", "cross_slope"):
        key = f"effects.{name}"
        h = 1e-6
        up = Walker(on.replace(**{key: on.get(key) + h})).cycle(z)
        down = Walker(on.replace(**{key: on.get(key) - h})).cycle(z)
        fd_p = (up.z_plus - down.z_plus) / (2 * h)
        k = PARAMETER_NAMES.index(key)
        assert_allclose(cycle.jacobian_params[:, k], fd_p, atol=1e-6 * np.abs(fd_p).max(), err_msg=name)
        assert np.abs(fd_p).max() > 0


def test_planar_reduction_carries_the_symmetric_effects():
    """For a planar-symmetric walker the planar system's right-hand side and collision with
    hip, rolling and impact effects on equal the 3D system's at phi = psi = 0: the planar
    reduction is exact with effects too (and pivot friction, spin arrest vanish there)."""
    params = Params(**{**GENERAL, "hip_width": 0.0, "com_offset": (-0.005, 0.0, -0.11),
                       "inertia": (2e-4, 3e-4, 2e-4, 0.0, 2e-5, 0.0)}, **FEET["sphere"])
    on = params.replace(**{"effects.hip_damping": 1e-3, "effects.hip_coulomb": 1e-3,
                           "effects.rolling_resistance": 1e-3, "effects.pivot_friction": 1e-3,
                           "effects.impact_trailing_share": 0.2, "effects.impact_spin_arrest": 0.5})
    planar, full = Walker(on, planar=True), Walker(on)
    rng = np.random.default_rng(16)
    for _ in range(5):
        th1, th2 = rng.uniform(-0.3, 0.3, 2)
        w1, w2 = rng.normal(0, 2, 2)
        xp = np.array([th1, th2, w1, w2, 0.0])
        x3 = np.array([0, 0, th1, th2, 0, 0, w1, w2, 0, 0])
        rhs3 = full.rhs(x3)
        assert_allclose(planar.rhs(xp)[2:4], rhs3[6:8], rtol=1e-12, atol=1e-12)
        assert_allclose(rhs3[4:6], 0.0, atol=1e-12)
        assert_allclose(planar.dissipation(xp), full.dissipation(x3), rtol=1e-12, atol=1e-15)
        c3 = full.eng.k["collision"](x3, full.p)[0].ravel()
        cp = planar.eng.k["collision"](xp, planar.p)[0].ravel()
        assert_allclose(cp[:4], c3[[2, 3, 6, 7]], rtol=1e-11, atol=1e-12)


def test_geometry_effects_match_numpy_kinematics():
    """Unequal legs and a tilted ramp against NumPy (model.kinematics, not the CasADi model):
    the legs' centres of mass from the hips and rotations with per-leg offsets, on either side in
    stance, and the potential energy in the tilted gravity field."""
    from toywalk.model.kinematics import leg_poses

    a, beta = 0.2, 0.05
    params = Params(**GENERAL, **FEET["torus"]).replace(**{"effects.asymmetry": a,
                                                          "effects.cross_slope": beta})
    walker = Walker(params)
    d = np.array(params.com_offset)
    rng = np.random.default_rng(17)
    for x in random_states(rng, 4):
        x[4:8] = 0.0  # at rest: the energy is the potential alone
        for side in (1, -1):
            poses = leg_poses(params, *x[:4], "L", (0.0, 0.0))
            # The described stance leg is the physical left one (side +1) or right one (-1).
            d_st = d * [1, 1 + 0.5 * a * side, 1]
            d_sw = d * [1, -(1 - 0.5 * a * side), 1]
            g1 = poses.hip["L"] + poses.rotation["L"] @ d_st
            g2 = poses.hip["R"] + poses.rotation["R"] @ d_sw
            pts = walker.points(x, side)
            assert_allclose(pts[7], g1, atol=1e-14)
            assert_allclose(pts[8], g2, atol=1e-14)
            alpha, g = params.slope, params.gravity
            gvec = g * np.array([math.sin(alpha), -side * math.cos(alpha) * math.sin(beta),
                                 -math.cos(alpha) * math.cos(beta)])
            contact = np.r_[x[8], x[9], 0.0]
            axle = poses.hip["L"] - 0.5 * params.hip_width * poses.rotation["L"][:, 1]
            masses = ((params.leg_mass, g1), (params.leg_mass, g2), (params.axle_mass, axle))
            expected = -sum(m * gvec @ (contact + p) for m, p in masses)
            assert_allclose(walker.energy(x, side), expected, rtol=1e-13, atol=1e-16)
