"""An independent check of the 3D heel strike: the free walker's mass matrix and contact
Jacobians built in NumPy from model.kinematics (not from the CasADi model), and the inverse of the
relabel and mirror that follow the collision (tests/model/test_equations.py,
tests/model/test_effects.py)."""

import numpy as np
from toywalk.model.kinematics import leg_poses

__all__ = ["free_system", "u_plus_old_labels"]


def u_plus_old_labels(walker, x_plus):
    """Invert relabel and mirror: the post-collision speeds in the old labels (3D)."""
    return np.array([-x_plus[4], -x_plus[5], x_plus[7], x_plus[6]])


def free_system(params, q):
    """Velocities of the walker's masses as linear maps of the free generalised speeds
    u = (v_H1 (3), phi', psi', theta_1', theta_2') (the hip point free, nothing on the ground),
    built in NumPy from model.kinematics (not from the CasADi model)."""
    phi, psi, th1, th2 = q
    poses = leg_poses(params, phi, psi, th1, th2, "L", (0.0, 0.0))
    r1, r2 = poses.rotation["L"], poses.rotation["R"]
    n = r1[:, 1]
    ez, ex_rot = np.array([0.0, 0.0, 1.0]), np.array([np.cos(phi), np.sin(phi), 0.0])
    w_rates = np.zeros((2, 3, 4))  # omega_i = W_i @ (phi', psi', th1', th2')
    for i in range(2):
        w_rates[i][:, 0], w_rates[i][:, 1] = ez, ex_rot
        w_rates[i][:, 2 + i] = n
    d = np.array(params.com_offset)
    d_right = d * [1, -1, 1]
    h1, h2 = poses.hip["L"], poses.hip["R"]
    g1, g2 = h1 + r1 @ d, h2 + r2 @ d_right
    axle = h1 - 0.5 * params.hip_width * n

    def point_jac(point, leg):  # v_P = v_H1 + omega_leg x (P - H1) (H2 and the axle lie on n)
        jac = np.zeros((3, 7))
        jac[:, :3] = np.eye(3)
        for k in range(4):
            jac[:, 3 + k] = np.cross(w_rates[leg][:, k], point - h1)
        return jac

    inertia = params.inertia_tensor()
    mirror = np.diag([1.0, -1.0, 1.0])
    i_world = [r1 @ inertia @ r1.T, r2 @ (mirror @ inertia @ mirror) @ r2.T]
    m_free = np.zeros((7, 7))
    for point, leg, mass in ((g1, 0, params.leg_mass), (g2, 1, params.leg_mass), (axle, 0, params.axle_mass)):
        jac = point_jac(point, leg)
        m_free += mass * jac.T @ jac
    for leg in range(2):
        wj = np.zeros((3, 7))
        wj[:, 3:] = w_rates[leg]
        m_free += wj.T @ i_world[leg] @ wj
    # Both feet share the offset C - O (docs/model.md section 2), and C is the origin: D = O2 - O1.
    c2 = poses.foot_centre["R"] - poses.foot_centre["L"]
    contact_jac = point_jac(c2, 1)  # velocity of leg 2's material point at D
    c1_jac = point_jac(np.zeros(3), 0)  # leg 1's material point at C (rolling before impact)
    return m_free, contact_jac, c1_jac
