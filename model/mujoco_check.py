"""The walker in an independent rigid-body engine (MuJoCo), as a new user would build it.

The model's assumptions are checked by an engine that knows nothing of them: soft contacts with
friction at both feet all the time (no guard, no ignored scuffing, no impulsive collision law),
feet of the same bottom curvatures, the same masses and inertias, the same slope. Built from a
parameter file, started from the model's fixed point, it shows whether the model's gait is one
that a physical walker could walk.

The MuJoCo model (Todorov, Erez & Tassa, IROS 2012, doi:10.1109/IROS.2012.6386109):

- the world is the slope frame S (model.md section 1): the ramp is the plane z = 0 and gravity is
  ``g (sin(alpha), 0, -cos(alpha))``;
- the left leg is a free body whose frame is the leg's body frame (origin at its hip point, b1
  forward, b2 along the axle, b3 up the leg); the right leg is its child, hinged about b2 at its hip
  point ``hip_width`` to the right; the axle's point mass is added to the left leg (it lies on the
  hinge axis, so which leg carries it does not matter);
- each foot is an oblate spheroid about the axle direction, centred where the model's torus is
  (``leg_length - foot_radius`` below the hip), equatorial radius ``foot_radius`` and polar
  semi-axis ``sqrt(foot_radius * foot_lateral_radius)``: around its whole rim its radius of
  curvature is ``foot_radius`` fore-aft and ``foot_lateral_radius`` sideways, as the torus's is.
  Its lowest point's height differs from the torus's by O(lean^4) (1e-4 mm at 5 degrees);
- contacts are the feet against the ramp only, with sliding friction and no contact couple
  (condim 3: the model's point contact rolls without slip and has no pivot friction), stiff
  (``solref`` time constant a few integration steps) and critically damped (plastic heel strikes).

Heel strikes are read from the contacts: a foot's contact that begins after it has been off the
ramp, ahead of the other foot's, is a heel strike; any other new contact of a foot is a scuff.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .kinematics import leg_poses, rotation
from .parameters import Params

__all__ = ["MujocoWalk", "build_mjcf", "initial_state", "walk_in_mujoco"]

# Contacts: the solver's time constant (s), critically damped. 1 ms is a few times shorter than
# anything the walkers do (steps of 0.1 s and more) and long enough that the heel strike is plastic:
# at 0.2 and 0.4 ms the landing foot of stable-toy widened to 110 mm hips bounced once, 4 ms after
# landing, at 1 ms it did not (measured, 1e-4 s steps). It must span several integration steps
# (MuJoCo's docs: at least two); the ramp then yields about g * (1 ms)^2 = 0.01 mm under the
# walker's weight.
_CONTACT_TIME = 1e-3
# A foot must have been off the ramp this long (s) before a new contact counts as a new touch, so
# that the solver's contact chatter within one touch is not counted twice.
_OFF_TIME = 2e-3


def _require_mujoco():
    try:
        import mujoco
    except ImportError as err:  # pragma: no cover - the extra is installed in the tests
        raise ImportError(
            "the MuJoCo check needs the mujoco package: pip install 'toywalk[test]' or pip install mujoco"
        ) from err
    return mujoco


def _num(values) -> str:
    """Numbers for MJCF, space-separated, every digit kept."""
    return " ".join(repr(float(v)) for v in values)


def _foot_axes(params: Params) -> tuple[float, float, float]:
    """Semi-axes (m) of the spheroid foot in the leg frame (b1, b2, b3)."""
    r, rho = params.foot_radius, params.foot_lateral_radius
    return r, math.sqrt(r * rho), r


def _leg_inertial(params: Params, mirror: bool, with_axle: bool) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia tensor about it), in the leg's body frame (kg, m, kg m^2)."""
    d = np.array(params.com_offset, dtype=float)
    inertia = params.inertia_tensor().copy()
    if mirror:  # the right leg is the mirror image (model.md section 2)
        d[1] = -d[1]
        flip = np.diag([1.0, -1.0, 1.0])
        inertia = flip @ inertia @ flip
    mass = params.leg_mass
    if not with_axle or params.axle_mass == 0.0:
        return mass, d, inertia
    axle = np.array([0.0, -0.5 * params.hip_width, 0.0])  # the axle's middle, right of the left hip
    total = mass + params.axle_mass
    com = (mass * d + params.axle_mass * axle) / total
    out = inertia.copy()
    for m, p in ((mass, d - com), (params.axle_mass, axle - com)):
        out += m * (p @ p * np.eye(3) - np.outer(p, p))  # parallel axes
    return total, com, out


def build_mjcf(params: Params, timestep: float = 1e-4, friction: float = 2.0) -> str:
    """The MuJoCo model of ``params`` (MJCF text; see the module's docstring).

    Parameters
    ----------
    params : Params
        A walker without effects and with round feet (``foot_lateral_radius`` > 0).
    timestep : float
        Integration step (s).
    friction : float
        Sliding friction coefficient of the feet on the ramp (the model assumes no slip).
    """
    if params.active_effects:
        raise ValueError(f"the MuJoCo walker has no effects; the parameter set has {params.active_effects}")
    if not params.foot_lateral_radius > 0.0:
        raise ValueError("the MuJoCo walker needs round feet (foot_lateral_radius > 0); "
                         f"got {params.foot_lateral_radius}")
    a, b, c = _foot_axes(params)
    centre = -(params.leg_length - params.foot_radius)
    g = params.gravity
    grav = (g * math.sin(params.slope), 0.0, -g * math.cos(params.slope))

    def inertial(mirror: bool, with_axle: bool) -> str:
        mass, com, i = _leg_inertial(params, mirror, with_axle)
        full = (i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])
        return (f'<inertial pos="{_num(com)}" mass="{_num([mass])}" fullinertia="{_num(full)}"/>')

    foot = (f'type="ellipsoid" size="{a!r} {b!r} {c!r}" pos="0 0 {centre!r}" contype="1" '
            f'conaffinity="0" condim="3" friction="{friction!r} 0 0" mass="0"')
    if not 4 * timestep <= _CONTACT_TIME:
        raise ValueError(f"timestep must be at most a quarter of the contact time constant "
                         f"{_CONTACT_TIME} s, got {timestep}")
    tc = _CONTACT_TIME
    return f"""<mujoco model="toywalk">
  <compiler angle="radian"/>
  <option timestep="{timestep!r}" gravity="{grav[0]!r} {grav[1]!r} {grav[2]!r}" integrator="RK4"
          cone="elliptic" impratio="10" noslip_iterations="10"/>
  <default><geom solref="{tc!r} 1" solimp="0.99 0.999 0.0001"/></default>
  <worldbody>
    <geom name="ramp" type="plane" size="0 0 1" contype="0" conaffinity="1" condim="3"
          friction="{friction!r} 0 0"/>
    <body name="left" pos="0 0 1">
      <freejoint name="left"/>
      {inertial(False, True)}
      <geom name="left_foot" {foot}/>
      <body name="right" pos="0 {-params.hip_width!r} 0">
        <joint name="hip" type="hinge" axis="0 1 0" damping="0"/>
        {inertial(True, False)}
        <geom name="right_foot" {foot}/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@dataclasses.dataclass
class MujocoWalk:
    """A walk in MuJoCo.

    Attributes
    ----------
    status : str
        ``"completed"`` (the steps asked for) or ``"fell"`` (a hip came down to half the leg
        length, or the time ran out first; ``message`` says which).
    message : str
    strikes : ndarray, shape (n, 3)
        Heel strikes: time (s), the landing foot's contact position along the ramp and across it (m).
    feet : list of str
        The landing foot of each heel strike, 'L' or 'R'.
    scuffs : int
        New contacts of a foot that were not heel strikes (the swing foot touching the ramp).
    steps : int
        Heel strikes that alternate feet (right, left, ...), counted from the start, which is the
        left foot's.
    step_times, step_lengths : ndarray, shape (steps,)
        Between successive alternating heel strikes, the start the first (s; m along the fall line,
        from contact point to contact point).
    duration : float
        Simulated time (s).
    """

    status: str
    message: str
    strikes: np.ndarray
    feet: list
    scuffs: int
    steps: int
    step_times: np.ndarray
    step_lengths: np.ndarray
    duration: float


def initial_state(params: Params, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's (qpos, qvel) for the public state ``z0`` just after a heel strike, left leg in
    stance, its foot's lowest point on the ramp at the origin (rolling: the contact at rest)."""
    phi, phid, psi, psid, th1, th1d, th2, th2d = map(float, z0)
    poses = leg_poses(params, phi, psi, th1, th2, "L", (0.0, 0.0))
    rot = poses.rotation["L"]
    # The spheroid's lowest point: its centre minus A e_z / sqrt(e_z' A e_z), A = R diag(a^2) R'.
    axes = np.array(_foot_axes(params))
    a_mat = rot @ np.diag(axes**2) @ rot.T
    ez = np.array([0.0, 0.0, 1.0])
    low = -a_mat @ ez / math.sqrt(ez @ a_mat @ ez)  # lowest point relative to the foot's centre
    centre = rot @ np.array([0.0, 0.0, -(params.leg_length - params.foot_radius)])
    hip = -low - centre  # the hip with the lowest point at the origin
    n = rotation(phi, psi, 0.0)[:, 1]
    omega = phid * ez + psid * rotation(phi, 0.0, 0.0)[:, 0] + th1d * n
    v_hip = np.cross(omega, hip)  # the contact point (origin) is at rest
    quat = _quaternion(rot)
    qpos = np.concatenate([hip, quat, [th2 - th1]])
    qvel = np.concatenate([v_hip, rot.T @ omega, [th2d - th1d]])
    return qpos, qvel


def _quaternion(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    w = math.sqrt(max(0.0, 1.0 + np.trace(rot))) / 2.0
    if w > 1e-6:
        return np.array([w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w),
                         (rot[1, 0] - rot[0, 1]) / (4 * w)])
    raise ValueError("rotation too far from the identity for this start")  # not for a walker


def walk_in_mujoco(params: Params, z0: np.ndarray, steps: int = 20, timestep: float = 1e-4,
                   friction: float = 2.0, max_time: float | None = None) -> MujocoWalk:
    """Start the MuJoCo walker at the public state ``z0`` (just after a heel strike, left leg in
    stance) and run it until ``steps`` heel strikes after the start, a fall, or ``max_time``.

    Parameters
    ----------
    params : Params
    z0 : ndarray, shape (8,)
        The model's state just after a heel strike (model.md section 1), e.g. a gait's fixed point.
    steps : int
        Heel strikes to walk.
    timestep : float
        MuJoCo's integration step (s).
    friction : float
        Sliding friction coefficient.
    max_time : float, optional
        Give up after this long (s); default 3 s per step asked for.

    Returns
    -------
    MujocoWalk
    """
    mujoco = _require_mujoco()
    z0 = np.asarray(z0, dtype=float)
    if z0.shape != (8,) or not np.all(np.isfinite(z0)):
        raise ValueError(f"z0 must be a finite state of 8 components, got {z0!r}")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    model = mujoco.MjModel.from_xml_string(build_mjcf(params, timestep, friction))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_state(params, z0)
    mujoco.mj_forward(model, data)
    feet = {"L": model.geom("left_foot").id, "R": model.geom("right_foot").id}
    bodies = {"L": model.body("left").id, "R": model.body("right").id}
    max_time = 3.0 * steps if max_time is None else max_time
    last_touch = {"L": 0.0, "R": 0.0}  # both feet are on the ramp at the start
    strikes: list[tuple[float, float, float]] = []
    landed: list[str] = []
    scuffs = 0
    status, message = "fell", f"no {steps} heel strikes within {max_time:.3g} s"
    while data.time < max_time:
        mujoco.mj_step(model, data)
        touching = {}
        for i in range(data.ncon):
            con = data.contact[i]
            for foot, gid in feet.items():
                if gid in (con.geom1, con.geom2):
                    touching[foot] = con.pos[:2].copy()
        for foot, pos in touching.items():
            if data.time - last_touch[foot] > _OFF_TIME:  # a new touch
                other = "R" if foot == "L" else "L"
                if pos[0] > _foot_position(data, model, bodies[other], params)[0]:
                    strikes.append((data.time, float(pos[0]), float(pos[1])))
                    landed.append(foot)
                else:
                    scuffs += 1
            last_touch[foot] = data.time
        hips = [data.xpos[bodies[k]][2] for k in ("L", "R")]
        if min(hips) < 0.5 * params.leg_length:
            status, message = "fell", f"a hip came down to half the leg length at t = {data.time:.3f} s"
            break
        if len(strikes) >= steps:
            status, message = "completed", f"{steps} heel strikes in {data.time:.3f} s"
            break
    # The start is a heel strike of the left foot at the origin; count the strikes that alternate.
    feet_seq = ["L", *landed]
    n_alt = 1
    while n_alt < len(feet_seq) and feet_seq[n_alt] != feet_seq[n_alt - 1]:
        n_alt += 1
    arr = np.array(strikes).reshape(-1, 3)
    if status == "completed" and n_alt < len(feet_seq):
        status, message = "fell", f"the same foot struck twice running at t = {arr[n_alt - 1, 0]:.3f} s"
    good = np.vstack([np.zeros((1, 3)), arr])[:n_alt]
    return MujocoWalk(status=status, message=message, strikes=arr, feet=landed, scuffs=scuffs,
                      steps=n_alt - 1, step_times=np.diff(good[:, 0]), step_lengths=np.diff(good[:, 1]),
                      duration=float(data.time))


def _foot_position(data, model, body: int, params: Params) -> np.ndarray:
    """The foot's centre (m, world frame) of the leg ``body``."""
    rot = data.xmat[body].reshape(3, 3)
    return data.xpos[body] + rot @ np.array([0.0, 0.0, -(params.leg_length - params.foot_radius)])
