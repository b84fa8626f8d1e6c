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


def _fd_jacobian(walker, z, eps):
    jac = np.zeros((8, 8))
    for i in range(8):
        dz = np.zeros(8)
        dz[i] = eps
        jac[:, i] = (walker.step(z + dz).z_plus - walker.step(z - dz).z_plus) / (2 * eps)
    return jac


def test_ad_jacobian_matches_central_differences_3d(compass):
    params, gait = compass
    walker = Walker(params)
    z = gait.fixed_point + 1e-3 * np.array([1.0, -2.0, 1.0, 2.0, 0.5, 1.0, -0.5, 2.0])
    step = walker.step(z, jacobian=True)
    # Central differences with h = 1e-5: truncation ~ h^2 |P'''| ~ 1e-9, round-off ~ 1e-16/h.
    fd = _fd_jacobian(walker, z, 1e-5)
    assert_allclose(step.jacobian, fd, atol=1e-6 * max(1.0, np.abs(fd).max()))
    # A Jacobian without the guard-time (saltation) correction is measurably wrong: the check
    # distinguishes the right answer from a plausible wrong one.
    assert np.abs(step.jacobian - fd).max() < 1e-3 * np.abs(fd).max()


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


def test_stride_map_is_two_steps(compass):
    """The stride map's Jacobian is the product of two step-map Jacobians (chain rule), and its
    eigenvalues at a symmetric gait are the squares of the step map's."""
    params, gait = compass
    walker = Walker(params)
    z2, jac = walker.stride(gait.fixed_point, jacobian=True)
    assert_allclose(z2, gait.fixed_point, atol=1e-10)
    stride_eigs = np.sort_complex(np.linalg.eigvals(jac))
    assert_allclose(stride_eigs, np.sort_complex(gait.eigenvalues**2), atol=1e-8 * np.abs(stride_eigs).max())
