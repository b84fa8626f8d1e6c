"""Every gait of a walker (model/gait_search.py): the simplest walker's published gaits, and for the
3D walkers, every gait returned a distinct fixed point with the known one among them."""

import itertools

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve
from toywalk.model.gait import find_gait, state_scale
from toywalk.model.gait_search import FIXED_POINT_TOL, SAME_GAIT, all_gaits, follow_in_slope
from toywalk.model.parameters import load_params
from toywalk.model.walker import Walker

from ..conftest import DATA

# Garcia, Chatterjee, Ruina & Coleman 1998, J. Biomech. Eng. 120:281, at slope 0.009, step times in
# sqrt(l/g) (docs/model.md section 7): the stable long-period gait 3.8824637528506, the unstable
# short-period gait 3.096105868; published to four decimals, 3.8825 and 3.0961.
LONG_PERIOD, SHORT_PERIOD = 3.8825, 3.0961
GARCIA_SLOPE = 0.009


@pytest.fixture(scope="module")
def simplest():
    return load_params(DATA / "params" / "simplest-walker.toml")


@pytest.fixture(scope="module")
def simplest_search(simplest):
    return all_gaits(simplest)


@pytest.fixture(scope="module", params=["stable-toy", "clearing-toy", "tinkertoy"])
def search_3d(request):
    params = load_params(DATA / "params" / f"{request.param}.toml")
    return params, all_gaits(params)


def test_simplest_walker_long_period_gait(simplest_search):
    times = [round(f.gait.step_time, 4) for f in simplest_search.gaits]
    assert LONG_PERIOD in times, times
    long = simplest_search.gaits[times.index(LONG_PERIOD)].gait
    assert long.stable  # Garcia et al.: the long-period gait is stable at slope 0.009


def _garcia_step(theta, theta_dot, touch):
    """One step of Garcia et al.'s equations (J. Biomech. Eng. 120:281, 1998, eqs. 3-4: slope
    ``GARCIA_SLOPE``, m/M -> 0, g = l = 1, their angles), integrated by scipy as an independent
    reference: the step ends at the ``touch``-th time (0 first) the swing foot meets the ramp
    (phi = 2 theta) with the stance angle past -0.01 rad (the mid-stance scuff ignored, as they do).
    Returns theta and theta_dot after the heel strike, and the step time."""
    def rhs(_, x):
        th, thd, ph, phd = x
        return [thd, np.sin(th - GARCIA_SLOPE), phd,
                np.sin(th - GARCIA_SLOPE) + np.sin(ph) * (thd**2 - np.cos(th - GARCIA_SLOPE))]

    x0 = [theta, theta_dot, 2 * theta, (1 - np.cos(2 * theta)) * theta_dot]
    sol = solve_ivp(rhs, (0, 6), x0, events=lambda _, x: x[2] - 2 * x[0], rtol=1e-12, atol=1e-12)
    touches = [(t, x) for t, x in zip(sol.t_events[0], sol.y_events[0], strict=True) if x[0] < -0.01]
    t, x = touches[touch]
    return -x[0], np.cos(2 * x[0]) * x[1], t


def test_simplest_walker_short_period_gait_needs_a_second_touch(simplest, simplest_search):
    """Garcia's short-period gait (3.0961) is a fixed point of their equations only when the step
    goes on past the swing foot's first touch of the ramp after the legs pass; this model's step
    from that state ends sooner, as the legs pass, so the search does not return it (docs/gaits.md
    section 6)."""
    def residual(v, touch):
        theta, theta_dot, _ = _garcia_step(*v, touch)
        return [theta - v[0], theta_dot - v[1]]

    # The second touch: fsolve from near it (the reference is the step time, not the state).
    short = fsolve(residual, [0.19, -0.20], args=(1,), xtol=1e-12)
    assert round(_garcia_step(*short, 1)[2], 4) == SHORT_PERIOD
    # The same reference at the first touch is the long-period gait the search returns.
    long = fsolve(residual, [0.20, -0.20], args=(0,), xtol=1e-12)
    assert round(_garcia_step(*long, 0)[2], 4) == LONG_PERIOD
    # This model from the short-period state (our signs: theta_st = -theta, rates +; the swing
    # leg's rate cos(2 theta) times the stance leg's after the strike): its step ends as the legs
    # pass (measured 1.86), far from the fixed point, long before 3.0961.
    theta, rate = short[0], -short[1]
    z = np.array([0.0, 0.0, 0.0, 0.0, -theta, rate, theta, rate * np.cos(2 * theta)])
    step = Walker(simplest, planar=True).cycle(z)
    assert step.time < 2.5
    assert np.max(np.abs(step.z_plus - z)) > 0.1
    times = [round(f.gait.step_time, 4) for f in simplest_search.gaits]
    assert SHORT_PERIOD not in times


def _assert_distinct_fixed_points(params, search):
    walker = Walker(params, planar=search.gaits[0].gait.planar)
    scale = state_scale(params)
    active = slice(4, 8) if walker.planar else slice(0, 8)
    for found in search.gaits:
        z = found.gait.fixed_point
        # A fresh walker's step from the fixed point returns to it (the search's own check, redone).
        residual = np.max(np.abs((walker.cycle(z).z_plus - z)[active] / scale[active]))
        assert residual < FIXED_POINT_TOL, (found.how, residual)
    for a, b in itertools.combinations(search.gaits, 2):
        gap = np.max(np.abs((a.gait.fixed_point - b.gait.fixed_point) / scale))
        step_gap = abs(a.gait.step_time - b.gait.step_time) / a.gait.step_time
        assert gap > SAME_GAIT or step_gap > SAME_GAIT, (a.how, b.how)
    times = [f.gait.step_time for f in search.gaits]
    assert times == sorted(times)


def test_simplest_walker_gaits_are_distinct_fixed_points(simplest, simplest_search):
    assert simplest_search.gaits
    _assert_distinct_fixed_points(simplest, simplest_search)


def test_3d_gaits_are_distinct_fixed_points(search_3d):
    params, search = search_3d
    assert search.gaits
    assert not search.gaits[0].gait.planar
    _assert_distinct_fixed_points(params, search)


def test_3d_known_gait_is_among_those_found(search_3d):
    params, search = search_3d
    known = find_gait(params)
    scale = state_scale(params)
    # The same gait: within the search's own sameness tolerance (both are Newton solutions to 1e-11).
    gaps = [np.max(np.abs((f.gait.fixed_point - known.fixed_point) / scale)) for f in search.gaits]
    assert min(gaps) <= SAME_GAIT, gaps


def test_repeated_starts_merge(simplest):
    long_start = np.array([0.0, 0.0, 0.0, 0.0, -0.2, 0.2, 0.2, 0.2 * np.cos(0.4)])
    search = all_gaits(simplest, starts=[("again", long_start), ("and again", long_start)])
    assert search.starts >= 2 and search.converged >= 2
    assert sum(f.found_from for f in search.gaits) == search.converged
    # Both extra starts reach the long-period gait, already found: no new entry.
    assert all(f.how not in ("again", "and again") for f in search.gaits)


def test_bad_input(simplest):
    with pytest.raises(ValueError, match="shape"):
        all_gaits(simplest, starts=[("short", np.zeros(3))])
    with pytest.raises(ValueError, match="seed"):
        all_gaits(simplest, n_random=3)
    with pytest.raises(ValueError, match="n_random"):
        all_gaits(simplest, n_random=-1, seed=0)


def test_families_in_slope_pass_through_their_gaits(search_3d):
    """Each gait followed in slope a little either way (follow_in_slope) starts from itself, every
    gait on it is a fixed point of a fresh walker at its slope, and a side that turns back at a
    fold comes back to another gait of the catalogue: the clearing toy's two gaits are one family
    through a fold at 3.34 degrees (docs/gaits.md section 6), the Tinkertoy fit's two likewise (it
    sits on its fold, docs/effects_study.md)."""
    params, search = search_3d
    own = params.slope
    families = follow_in_slope(params, search, 0.96 * own, 1.04 * own, max_points=40)
    assert [f.gait for f in families] == list(range(len(search.gaits)))
    scale = state_scale(params)
    for family in families:
        gait = search.gaits[family.gait].gait
        first = [b.points[0] for b in family.branches]
        assert first and all(p.value == own and abs(p.step_time - gait.step_time) < 1e-12 for p in first)
        middle = family.points[len(family.points) // 2]
        walker = Walker(params.replace(slope=middle.value), planar=gait.planar)
        active = slice(4, 8) if gait.planar else slice(0, 8)
        step = walker.step(middle.fixed_point)
        assert np.max(np.abs((step.z_plus - middle.fixed_point)[active] / scale[active])) < 1e-9
        assert abs(step.step_time - middle.step_time) < 1e-9 * middle.step_time
    joined = {(f.gait, f.joins) for f in families if f.joins is not None}
    if len(search.gaits) == 2:  # clearing toy and tinkertoy: each half of the fold reaches the other
        assert joined == {(0, 1), (1, 0)}, [f.why or [b.status for b in f.branches] for f in families]


def test_simplest_walker_family_loses_stability_where_published(simplest, simplest_search):
    """Followed up in slope from 0.009, the long-period gait loses stability through a period
    doubling at 0.0150884 (Garcia et al. 1998: 0.0151; the recomputed boundary of docs/model.md
    section 7); the continuation locates it to its solver's tolerance."""
    families = follow_in_slope(simplest, simplest_search, simplest.slope, 0.016, max_points=60)
    long = next(f for f in families if round(simplest_search.gaits[f.gait].gait.step_time, 4) == LONG_PERIOD)
    events = [e for e in long.up.events if e.kind == "loses stability"]
    assert len(events) == 1 and "-1" in events[0].detail
    assert abs(events[0].value - 0.0150884) < 1e-6
