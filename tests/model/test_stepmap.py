"""The step map: AD Jacobians against finite differences, convergence of the fixed-step flow."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from toywalk.model.gait import find_gait
from toywalk.model.parameters import load_params
from toywalk.model.walker import StepFailure, Walker

from ..conftest import DATA


@pytest.fixture(scope="module")
def compass():
    params = load_params(DATA / "params" / "compass-3d.toml")
    return params, find_gait(params)


def _fd_jacobian(fun, z, h):
    """Five-point central differences of ``fun`` at ``z``: truncation error O(h^4)."""
    cols = []
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = h
        cols.append((fun(z - 2 * dz) - 8 * fun(z - dz) + 8 * fun(z + dz) - fun(z + 2 * dz)) / (12 * h))
    return np.array(cols).T


# A start 1e-3 off the gait, so that the two steps of a stride differ.
_OFF_GAIT = 1e-3 * np.array([1.0, -2.0, 1.0, 2.0, 0.5, 1.0, -0.5, 2.0])


def test_ad_jacobian_matches_central_differences_3d(compass):
    params, gait = compass
    walker = Walker(params)
    z = gait.fixed_point + _OFF_GAIT
    step = walker.step(z, jacobian=True)
    fd = _fd_jacobian(lambda q: walker.step(q).z_plus, z, 5e-5)
    # Difference quotients with h = 5e-5: measured error 1.4e-10 (it falls 16x per halving of h
    # from 4e-4 to 1e-4, the O(h^4) truncation; below 5e-5 the step map's round-off, ~1e-14 / h,
    # takes over). 2e-8 is 100x that, and ~1e-9 of the largest entry (12.5).
    atol = 2e-8
    assert_allclose(step.jacobian, fd, rtol=0, atol=atol)
    # The plausible wrong answer: the same Jacobian without the heel-strike-time (saltation)
    # correction, i.e. minus (d z_plus / d step_time at fixed start) (x) (d step_time / d z0).
    # d z_plus / d step_time is the collision's derivative along the flow at z_minus, here by
    # central differences of the public collision map (error ~1e-10, nothing next to the gap).
    z_minus = step.z_minus
    flow = walker.to_public(walker.rhs(walker.full_state(z_minus))[: walker.lay.n_dyn])
    along = (walker.collide(z_minus + 1e-6 * flow) - walker.collide(z_minus - 1e-6 * flow)) / 2e-6
    no_saltation = step.jacobian - np.outer(along, step.time_gradient)
    # It misses the differences by O(1) (measured 13), far outside the tolerance above: the check
    # tells the right Jacobian from this wrong one.
    assert np.abs(no_saltation - fd).max() > 1e4 * atol


def test_parameter_jacobian_matches_central_differences(compass):
    params, gait = compass
    walker = Walker(params)
    step = walker.step(gait.fixed_point, params_jacobian=True)
    names = ["slope", "leg_length", "com_offset[1]", "inertia[0]", "hip_width"]
    from toywalk.model.parameters import PARAMETER_NAMES

    for name in names:
        k = PARAMETER_NAMES.index(name)
        h = 1e-6 * max(1.0, abs(params.get(name)))
        up = Walker(params.replace(**{name: params.get(name) + h})).step(gait.fixed_point)
        down = Walker(params.replace(**{name: params.get(name) - h})).step(gait.fixed_point)
        fd = (up.z_plus - down.z_plus) / (2 * h)
        assert_allclose(step.jacobian_params[:, k], fd, atol=1e-5 * max(1.0, np.abs(fd).max()),
                        err_msg=name)
        fd_t = (up.step_time - down.step_time) / (2 * h)
        assert_allclose(step.time_gradient_params[k], fd_t, atol=1e-5 * max(1.0, abs(fd_t)))


def test_time_gradient_matches_central_differences(compass):
    params, gait = compass
    walker = Walker(params)
    step = walker.step(gait.fixed_point, jacobian=True)
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = 1e-6
        fd = (walker.step(gait.fixed_point + dz).step_time
              - walker.step(gait.fixed_point - dz).step_time) / 2e-6
        assert abs(step.time_gradient[i] - fd) < 1e-6 * max(1.0, abs(fd))


def test_default_resolution_is_converged(compass):
    """The default 16 steps per sqrt(l/g) agree with 4x the resolution to 1e-10 (order-8 method:
    the error falls by 4^8 ~ 6.6e4 per refinement, so this bounds the default's own error)."""
    params, gait = compass
    fine = Walker(params, steps_per_time_unit=64).step(gait.fixed_point, jacobian=True)
    coarse = Walker(params).step(gait.fixed_point, jacobian=True)
    assert_allclose(coarse.z_plus, fine.z_plus, atol=1e-10)
    assert abs(coarse.step_time - fine.step_time) < 1e-10 * params.time_scale
    assert_allclose(coarse.jacobian, fine.jacobian, atol=1e-8 * np.abs(fine.jacobian).max())


def test_bad_start_fails_with_status(compass):
    params, _ = compass
    walker = Walker(params)
    z = np.zeros(8)
    z[2] = 1.2  # leaning 70 degrees: falls sideways
    z[4], z[6] = -0.2, 0.2
    with pytest.raises(StepFailure) as info:
        walker.step(z)
    assert info.value.status in ("fell", "no_heel_strike")
    with pytest.raises(ValueError, match="8 components"):
        walker.step(np.zeros(7))
    with pytest.raises(ValueError, match="finite"):
        walker.step(np.full(8, np.nan))


def test_stride_map_matches_differences_of_two_steps(compass):
    """The stride map P_R o P_L against two explicit steps: its end state, its Jacobian against
    difference quotients of the two steps, and the gradient of its duration likewise. Off the
    gait, so that the two steps' Jacobians differ and their order matters."""
    params, gait = compass
    walker = Walker(params)

    def two_steps(q):
        first = walker.step(q)
        second = walker.step(first.z_plus, side=-1)
        return second.z_plus, first.step_time + second.step_time

    z = gait.fixed_point + _OFF_GAIT
    z2, jac = walker.stride(z, jacobian=True)
    assert_allclose(z2, two_steps(z)[0], rtol=0, atol=0)  # the same arithmetic: bit for bit
    fd = _fd_jacobian(lambda q: two_steps(q)[0], z, 2.5e-5)
    # h = 2.5e-5: measured error 1.8e-8 (O(h^4): 4.7e-6 at h = 1e-4, 2.9e-7 at 5e-5; the stride
    # map is more curved than one step); round-off ~1e-14 / h = 4e-10. 2e-6 is 100x the error and
    # ~3e-8 of the largest entry (60).
    atol = 2e-6
    assert_allclose(jac, fd, rtol=0, atol=atol)
    # The wrong composition (first step's Jacobian applied last) has the same eigenvalues at a
    # symmetric gait but misses here by 2.3: the check tells the two apart.
    first = walker.step(z, jacobian=True)
    second = walker.step(first.z_plus, jacobian=True, side=-1)
    assert np.abs(first.jacobian @ second.jacobian - fd).max() > 1e4 * atol
    grad = walker.cycle(z, jacobian=True, steps=2).time_gradient
    fd_time = _fd_jacobian(lambda q: np.full(8, two_steps(q)[1]), z, 2.5e-5)[0]
    # Entries up to 20 s per unit of state; measured error 1.8e-9 (O(h^4) as above); 1e-7 is 50x.
    assert_allclose(grad, fd_time, rtol=0, atol=1e-7)


def test_clearance_does_not_depend_on_the_grid(compass):
    """The compass walker's swing foot dips after the legs pass: its clearance is that interior
    minimum, sampled on the integration grid and refined by a parabola, so it converges as the grid
    is refined (the lowest sample before heel strike, which tends to 0, is not a minimum)."""
    params, gait = compass
    clearance = {n: Walker(params, steps_per_time_unit=n).step(gait.fixed_point, record=True).clearance
                 for n in (16, 64, 256)}
    # The parabola's vertex is off by O(dt^3): measured 1.2e-6 m at 16 steps per time unit and
    # 2.0e-8 m at 64 (62x less for 4x finer, 4^3 = 64), against 256. Tolerances 2x those.
    assert abs(clearance[16] - clearance[256]) < 2.5e-6
    assert abs(clearance[64] - clearance[256]) < 4e-8
    # A dip of 6.2 mm, well clear of the ramp (the lowest grid sample after the legs pass would
    # say 1.7 mm at 16 steps and 0.13 mm at 64: the last one before heel strike).
    assert clearance[256] > 1e-3
    # The step map alone does not compute it.
    assert np.isnan(Walker(params).step(gait.fixed_point).clearance)
