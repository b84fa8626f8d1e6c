"""The dictionary of generalised forces at the walker's ports (model/effects/ports.py): the table,
every port-only term against its virtual-work definition, exact at zero, its AD Jacobian, the mirror
symmetry, the energy (springs conserve it, friction never adds it, heel-strike terms never gain it,
both arrests together included) and the identity of roll + pitch damping with rolling resistance."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.effects import CONTINUOUS, COULOMB_SMOOTHING, EFFECTS, LIBRARY, PORTS
from toywalk.model.equations import build_functions
from toywalk.model.gait import find_gait, solve_fixed_point
from toywalk.model.kinematics import rotation
from toywalk.model.parameters import PARAMETER_NAMES, Params, load_params
from toywalk.model.walker import Walker

from ..conftest import DATA
from .collision_reference import free_system, u_plus_old_labels
from .effect_reference import omega_partials, random_states, typical
from .walkers import FEET, GENERAL

#: The port-only terms, and those of them that act between collisions.
PORT_ONLY = [name for name, e in EFFECTS.items() if e.port_only]
PORT_CONTINUOUS = [name for name in PORT_ONLY if name in CONTINUOUS]
#: The conservative terms (within a step) and their energies (J) at internal states x (n, >= 4):
#: the springs, and the hinge bias, whose energy -k (theta_sw - theta_st) the relabelling at heel
#: strike does not keep (it does work over a step).
ENERGIES = {
    "hinge_stiffness": lambda k, x: 0.5 * k * (x[:, 3] - x[:, 2]) ** 2,
    "hinge_cubic_stiffness": lambda k, x: 0.25 * k * (x[:, 3] - x[:, 2]) ** 4,
    "hinge_bias": lambda k, x: -k * (x[:, 3] - x[:, 2]),
    "roll_stiffness": lambda k, x: 0.5 * k * x[:, 1] ** 2,
    "pitch_stiffness": lambda k, x: 0.5 * k * x[:, 2] ** 2,
}
DISSIPATIVE = [name for name in PORT_CONTINUOUS if name not in ENERGIES]
EZ = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def toy():
    params = load_params(DATA / "params" / "stable-toy.toml")
    return params, find_gait(params)




# -------------------------------------------------------------------------------------- table
def test_the_table_maps_every_port_and_form_to_one_parameter():
    """Every (port, form) names one registered strength; a form that is a library effect is that
    effect (no second parameter), every other is a port-only term, and every port-only term is in
    the table once."""
    forms = {port: {f for p, f in PORTS if p == port} for port, _ in PORTS}
    assert forms == {"hinge": {"angle", "rate", "dry", "angle3", "bias"},
                     "contact_roll": {"angle", "rate", "dry"}, "contact_pitch": {"angle", "rate", "dry"},
                     "contact_spin": {"rate", "dry"}, "heel_strike": {"spin_loss", "lean_loss"}}
    coincide = {key: t.coincides_with for key, t in PORTS.items() if t.coincides_with}
    assert coincide == {("hinge", "rate"): "hip_damping", ("hinge", "dry"): "hip_coulomb",
                        ("contact_spin", "rate"): "pivot_friction",
                        ("heel_strike", "spin_loss"): "impact_spin_arrest"}
    parameters = [t.parameter for t in PORTS.values()]
    assert len(set(parameters)) == len(parameters)
    assert sorted(t.parameter for t in PORTS.values() if not t.coincides_with) == sorted(PORT_ONLY)
    for term in PORTS.values():
        effect = EFFECTS[term.parameter]
        assert f"effects.{term.parameter}" in PARAMETER_NAMES and term.unit == effect.unit
        assert effect.port_only == (term.parameter not in LIBRARY)
        assert not effect.breaks_symmetry and effect.null == 0.0
        assert term.equation.startswith(("tau_hinge = ", "M_st = ", "u+ = "))


# ------------------------------------------------------------- continuous terms: the reference


def _reference_couples(name, k, params, q, u):
    """Couples (leg index 0 = stance, 1 = swing, M) from the definitions of docs/formats.md,
    "Ports and forms", with the axes built here from phi (not from the model)."""
    w_st = omega_partials(q)[0] @ u
    n = rotation(q[0], q[1], 0.0)[:, 1]
    heading = np.array([math.cos(q[0]), math.sin(q[0]), 0.0])
    pitch = np.cross(EZ, heading)
    eps = COULOMB_SMOOTHING * math.sqrt(params.gravity / params.leg_length)

    def dry(rate):
        return -k * rate / math.sqrt(rate**2 + eps**2)

    angle = q[3] - q[2]
    hinge = {"hinge_stiffness": -k * angle, "hinge_cubic_stiffness": -k * angle**3, "hinge_bias": k}
    if name in hinge:
        return [(1, hinge[name] * n), (0, -hinge[name] * n)]
    axis, torque = {
        "roll_damping": (heading, -k * (w_st @ heading)),
        "roll_coulomb": (heading, dry(w_st @ heading)),
        "roll_stiffness": (heading, -k * q[1]),
        "pitch_damping": (pitch, -k * (w_st @ pitch)),
        "pitch_coulomb": (pitch, dry(w_st @ pitch)),
        "pitch_stiffness": (pitch, -k * q[2] / math.cos(q[1])),
        "spin_coulomb": (EZ, dry(w_st @ EZ)),
    }[name]
    return [(0, torque * axis)]




@pytest.mark.parametrize("name", PORT_CONTINUOUS)
def test_port_terms_equal_their_virtual_work_definition(name):
    """M (u'_term - u'_seed) equals Q_j = sum_i M_i . d omega_i / du_j with the couples of the
    written definition and partial angular velocities from NumPy rotations; the power output
    equals -Q . u, is never negative for a friction term and is the rate of the energy for a
    spring (dE_term/dt by central differences along u)."""
    base = Params(**GENERAL, **FEET["torus"])
    k = 10 * EFFECTS[name].typical
    walker, seed = Walker(base.replace(**{f"effects.{name}": k})), Walker(base)
    i = CONTINUOUS.index(name)
    for x in random_states(np.random.default_rng(31), 6, contact=False):
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
        assert_allclose(power[i], -q_ref @ u, rtol=1e-8, atol=1e-14)
        assert np.all(np.delete(power, i) == 0.0)
        if name in ENERGIES:
            h = 1e-6
            rate = (ENERGIES[name](k, (q + h * u)[None]) - ENERGIES[name](k, (q - h * u)[None]))[0] / (2 * h)
            assert_allclose(power[i], rate, rtol=1e-7, atol=1e-12)  # O(h^2) differences
        else:
            assert power[i] >= 0.0


def test_the_stiffness_terms_are_forces_on_their_own_angle_alone():
    """The roll and pitch restoring couples were chosen conservative: their generalised forces
    are -k psi on psi and -k theta_st on theta_st, nothing on the other coordinates (the couple
    -k theta_st p without 1/cos psi would give -k theta_st cos psi, which has no potential)."""
    base = Params(**GENERAL, **FEET["torus"])
    generalised = build_functions(False)["generalised"]
    for name, j in (("roll_stiffness", 1), ("pitch_stiffness", 2)):
        p = base.replace(**{f"effects.{name}": 1.0}).input_vector(1.0)
        for x in random_states(np.random.default_rng(32), 3, contact=False):
            expected = np.zeros(4)
            expected[j] = -x[j]
            assert_allclose(generalised(x, p).full().ravel(), expected, rtol=0, atol=1e-15)
        assert np.all(generalised(x, base.input_vector(1.0)).full().ravel() == 0.0)


# ---------------------------------------------------------------- null, Jacobians, symmetry
def test_at_zero_the_step_map_is_the_seeds(toy):
    """Every port term at zero (and all the others): the step map from the stable toy's gait equals
    the one built without the effect library (the seed's equations, CasADi's virtual machine)."""
    params, gait = toy
    ours, seed = Walker(params), Walker(params, effects=False, compiled=False)
    z = gait.fixed_point + 1e-3
    a, b = ours.step(z), seed.step(z)
    # The same expressions with zero-strength terms added: round-off through one step.
    assert_allclose(a.z_plus, b.z_plus, rtol=0, atol=1e-12)
    assert abs(a.step_time - b.step_time) < 1e-14
    # The comparison can fail: a port term at 1e-3 of its typical strength moves the step.
    moved = Walker(params.replace(**{"effects.hinge_stiffness": 1e-3 * EFFECTS["hinge_stiffness"].typical}))
    assert np.abs(moved.step(z).z_plus - b.z_plus).max() > 1e-9


def test_ad_jacobians_of_the_port_terms_match_finite_differences(toy):
    """Every port-only term on at once, at half its typical strength: the step map's columns for
    each strength against central differences (1e-3 of the typical strength)."""
    params, gait = toy
    on = params.replace(**{f"effects.{n}": 0.5 * EFFECTS[n].typical for n in PORT_ONLY})
    z = gait.fixed_point
    step = Walker(on).step(z, params_jacobian=True)
    for name in PORT_ONLY:
        key = f"effects.{name}"
        h = 1e-3 * abs(EFFECTS[name].typical)
        up = Walker(on.replace(**{key: on.get(key) + h})).step(z)
        down = Walker(on.replace(**{key: on.get(key) - h})).step(z)
        fd_p = (up.z_plus - down.z_plus) / (2 * h)
        # Measured (2026-11-28): 1e-6 of the column's largest entry for the dry pitch couple
        # (truncation, (h / k)^2 times its curvature), 2e-7 for the roll stiffness (round-off:
        # the roll terms barely move the stable toy's step); a wrong column is wrong at O(1).
        column = step.jacobian_params[:, PARAMETER_NAMES.index(key)]
        assert_allclose(column, fd_p, atol=5e-6 * np.abs(fd_p).max(), err_msg=name)
        assert np.abs(fd_p).max() > 0  # the term does act on the step


@pytest.mark.parametrize("name", PORT_ONLY)
def test_each_port_term_keeps_a_step_periodic_gait(toy, name):
    """At its typical strength each term (symmetric) has a gait of the step map, and the step
    with the right leg in stance (the mirrored description) from it returns to it: the next step
    is the mirrored one. The typical strength visibly changes the gait or its stability
    (docs/effects.md: the roll terms act on the stability of a walker that leans 0.3 degrees)."""
    params, gait = toy
    changed = params.replace(**{f"effects.{name}": EFFECTS[name].typical})
    walker = Walker(changed)
    assert walker.period == 1
    found = solve_fixed_point(walker, gait.fixed_point)
    for side in (1, -1):
        # The fixed point solves P(z) = z to 1e-11 (solve_fixed_point's tolerance), the two sides
        # are the same expressions.
        assert_allclose(walker.step(found.fixed_point, side=side).z_plus, found.fixed_point, atol=1e-9)
    change = abs(found.step_time / gait.step_time - 1)
    assert change > 5e-3 or abs(found.max_abs_eigenvalue - gait.max_abs_eigenvalue) > 5e-3


# --------------------------------------------------------------------------------------- energy
def test_springs_conserve_energy_within_a_step(toy):
    """The conservative terms on at once (the springs at twice their typical strength, the hinge
    bias): kinetic + gravitational + their energies stay constant over a stable-toy step to the
    integrator's tolerance, and the power output integrates to their energies' change (the audit
    E(t) - E(0) + W(t) = 0 holds with springs). Without their energies the balance fails."""
    params, gait = toy
    on = params.replace(**{f"effects.{n}": 2 * EFFECTS[n].typical for n in ENERGIES})
    walker = Walker(on)
    step = walker.step(gait.fixed_point, record=True)
    energy = np.array([walker.energy(x) for x in step.states])
    stored = {n: ENERGIES[n](on.effects[n], step.states) for n in ENERGIES}
    total = energy + sum(stored.values())
    scale = params.total_mass * params.gravity * params.leg_length
    # RK8 at the walker's step: the library's effects balance to 1e-9 of m g l (test_effects.py).
    assert np.abs(total - total[0]).max() / scale < 1e-9
    assert np.abs(energy - energy[0]).max() / scale > 1e-4  # the check can fail
    for n in ENERGIES:
        taken = step.dissipated[:, CONTINUOUS.index(n)]
        assert np.abs(taken - (stored[n] - stored[n][0])).max() / scale < 1e-9, n
        assert np.ptp(stored[n]) / scale > 1e-6, n  # each term stores a measurable energy
    assert np.abs(energy - energy[0] + step.dissipated.sum(axis=1)).max() / scale < 1e-9


def test_friction_terms_take_energy_over_a_step(toy):
    """The dissipative port terms on at once: each takes energy over the step, and the walker's
    energy falls by what they took, to the integrator's tolerance. At 64 integration steps per
    time unit: a dry couple whose rate reverses (the stable toy's stance pitch rate does, 21 ms
    into the step) turns within 0.2 ms, a kink the default 16 steps integrate to 3e-8 of m g l
    (measured 2026-11-28; 3e-10 at 64)."""
    params, gait = toy
    walker = Walker(typical(params, DISSIPATIVE), steps_per_time_unit=64)
    step = walker.step(gait.fixed_point, record=True)
    energy = np.array([walker.energy(x) for x in step.states])
    lost = step.dissipated.sum(axis=1)
    scale = params.total_mass * params.gravity * params.leg_length
    assert np.abs(energy - energy[0] + lost).max() / scale < 1e-9
    taken = step.dissipated[-1, [CONTINUOUS.index(n) for n in DISSIPATIVE]]
    assert np.all(taken > 0) and np.all(np.diff(lost) >= -1e-15 * scale)


# ------------------------------------------------------------------------------ the heel strike
def _reference_collision(params, x, share, spin, lean):
    """Post-collision speeds (old labels), energy change and landing normal impulse from the free
    walker (tests/model/collision_reference.py, NumPy): impulses at D, a normal impulse
    lambda_C = share * Lambda at C, couples about e_z and about the heading on the landing leg for
    the arrested laws, blended multilinearly in (spin, lean)."""
    q, rates = x[:4], x[4:8]
    m_free, a_d, a_c = free_system(params, q)
    u_minus = np.zeros(7)
    u_minus[3:] = rates
    u_minus[:3] = -(a_c[:, 3:] @ rates)
    ratio = share / (1.0 - share)
    heading = np.array([math.cos(q[0]), math.sin(q[0]), 0.0])
    n = rotation(q[0], q[1], 0.0)[:, 1]
    columns = [EZ, heading, np.zeros(3), n]  # d omega_2 / d(phi', psi', th1', th2')
    rows = {"spin": EZ, "lean": heading}

    def solve(chosen):
        m = 10 + len(chosen)
        kkt = np.zeros((m, m))
        b = a_d.T if chosen else a_d.T + ratio * np.outer(a_c[2], EZ)
        kkt[:7, :7], kkt[:7, 7:10], kkt[7:10, :7] = m_free, -b, a_d
        for j, axis in enumerate(rows[c] for c in chosen):
            row = np.zeros(7)
            row[3:] = [axis @ c for c in columns]
            kkt[:7, 10 + j], kkt[10 + j, :7] = -row, row
        return np.linalg.solve(kkt, np.r_[m_free @ u_minus, np.zeros(m - 7)])[:10]

    u_plus, lead = np.zeros(7), 0.0
    for chosen, weight in (((), (1 - spin) * (1 - lean)), (("spin",), spin * (1 - lean)),
                           (("lean",), (1 - spin) * lean), (("spin", "lean"), spin * lean)):
        sol = solve(chosen)
        u_plus, lead = u_plus + weight * sol[:7], lead + weight * sol[9]
    d_kinetic = 0.5 * (u_plus @ m_free @ u_plus - u_minus @ m_free @ u_minus)
    return u_plus[3:], d_kinetic, lead, 0.5 * u_minus @ m_free @ u_minus


@pytest.mark.parametrize("feet", ["sphere", "torus"])
def test_lean_arrest_and_both_arrests_match_free_walker_impulses(feet):
    """The lean arrest, alone and with the spin arrest and the trailing share, equals a plastic
    impulse computation on the free walker from NumPy kinematics; the lean arrest at 1 leaves the
    landing foot no lean rate (psi'+ = 0)."""
    params = Params(**GENERAL, **FEET[feet])
    rng = np.random.default_rng(33)
    for share, spin, lean in ((0.0, 0.0, 0.6), (0.0, 0.7, 0.4), (0.2, 1.0, 1.0), (0.1, 0.3, 1.0)):
        walker = Walker(params.replace(**{"effects.impact_trailing_share": share,
                                          "effects.impact_spin_arrest": spin,
                                          "effects.impact_lean_arrest": lean}))
        for x in random_states(rng, 3, contact=False):
            expected, d_k, lead, before = _reference_collision(params, x, share, spin, lean)
            got = u_plus_old_labels(walker, walker.eng.k["collision"](x, walker.p)[0].ravel())
            rate = np.max(np.abs(x[4:8]))
            # Solves of 4 to 6 unknowns against 10 to 12: round-off level.
            assert_allclose(got, expected, atol=1e-9 * rate, err_msg=f"{share}, {spin}, {lean}")
            d_k_got, impulses, before_got = (np.ravel(a) for a in walker.eng.k["impact"](x, walker.p))
            assert_allclose(before_got[0], before, rtol=1e-12)
            assert_allclose(d_k_got[0], d_k, atol=1e-10 * abs(d_k) + 1e-15)
            assert_allclose(impulses[0], lead, atol=1e-9 * np.abs(impulses).max())
            if lean == 1.0:
                assert abs(got[1]) < 1e-12 * rate


def test_heel_strike_terms_never_gain_energy(toy):
    """On heel strikes the seed's law admits, perturbed about the stable toy's (angles 0.05 rad,
    rates 50 % + 0.5 sqrt(g/l)), the lean arrest, alone and with the spin arrest and the trailing
    share anywhere in their bounds, never gains energy, and the blend never gains on its corners
    (convexity)."""
    params, gait = toy
    seed = Walker(params)
    grid = (0.0, 0.5, 1.0)
    walkers = {(s, a, b): Walker(params.replace(**{"effects.impact_trailing_share": s,
                                                   "effects.impact_spin_arrest": a,
                                                   "effects.impact_lean_arrest": b}))
               for s in (0.0, 0.3) for a in grid for b in grid}
    rng = np.random.default_rng(34)
    found, losses = 0, []
    while found < 30:
        z = gait.step.z_minus.copy()
        z[[0, 2, 4, 6]] += rng.normal(0, 0.05, 4)
        z[[1, 3, 5, 7]] = (z[[1, 3, 5, 7]] * (1 + rng.normal(0, 0.5, 4))
                           + rng.normal(0, 0.5, 4) / params.time_scale)
        x = seed.full_state(z)
        h, ahead = seed.guard(x)
        if seed.guard(x + 1e-7 * seed.rhs(x))[0] >= h or ahead <= 0:
            continue
        if np.min(seed.eng.k["impact"](x, seed.p)[1]) < 0:
            continue
        found += 1
        gained = {key: w.eng.k["impact"](x, w.p)[0][0, 0] for key, w in walkers.items()}
        kinetic = seed.eng.k["impact"](x, seed.p)[2][0, 0]
        # Kinetic energy lost or kept to round-off (1e-12 of the kinetic energy before).
        assert max(gained.values()) <= 1e-12 * kinetic
        for s in (0.0, 0.3):
            corners = [gained[s, a, b] for a in (0.0, 1.0) for b in (0.0, 1.0)]
            assert gained[s, 0.5, 0.5] <= max(corners) + 1e-12 * kinetic
        losses.append(gained[0.0, 0.0, 1.0] - gained[0.0, 0.0, 0.0])
    assert max(losses) < 0  # the lean arrest takes energy on every one of these heel strikes


# ------------------------------------------------------------------------------------- identity
def test_roll_and_pitch_damping_together_are_rolling_resistance(toy):
    """h and p span the ramp plane: roll and pitch damping of equal strength are rolling
    resistance. The right-hand sides agree to round-off and the gaits to 1e-10."""
    params, gait = toy
    c = 3 * EFFECTS["rolling_resistance"].typical
    split = params.replace(**{"effects.roll_damping": c, "effects.pitch_damping": c})
    whole = params.replace(**{"effects.rolling_resistance": c})
    a, b = Walker(split), Walker(whole)
    for x in random_states(np.random.default_rng(35), 5, contact=False):
        assert_allclose(a.rhs(x), b.rhs(x), rtol=1e-13, atol=1e-13 * np.abs(b.rhs(x)).max())
        assert_allclose(a.dissipation(x).sum(), b.dissipation(x).sum(), rtol=1e-13)
    gait_a, gait_b = solve_fixed_point(a, gait.fixed_point), solve_fixed_point(b, gait.fixed_point)
    # Both solve P(z) = z to 1e-11 with maps equal to round-off.
    assert_allclose(gait_a.fixed_point, gait_b.fixed_point, rtol=0, atol=1e-10)
    assert abs(gait_a.step_time - gait_b.step_time) < 1e-10
    assert np.abs(gait_b.fixed_point - gait.fixed_point).max() > 1e-4  # rolling resistance acts
