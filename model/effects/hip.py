"""Torques in the hip hinge: friction, viscous (``hip_damping``) and dry (``hip_coulomb``), and
the hinge port's further terms (``hinge_stiffness``, ``hinge_cubic_stiffness``, ``hinge_bias``).

The legs turn on a shared axle; a Tinkertoy rod in a spool's hole rubs. The hinge torque acts on
the swing leg about the hip axis n and its reaction on the stance leg, so it does no work on the
rigid motion of the pair and takes the power ``-tau * (theta_sw' - theta_st')`` (docs/model.md
section 6): dissipated by friction; for a spring, the rate of change of the energy it stores.

The port terms are port-only (:attr:`Effect.port_only`): the dictionary of generalised forces at
the hinge (:data:`toywalk.model.effects.ports.PORTS`), not causes the analysis tries by default.
Every one is written in the description of the step (the swing leg, the stance leg), which the
mirror maps onto itself, so none breaks the left-right symmetry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import Context, Effect

if TYPE_CHECKING:
    import casadi as ca

__all__ = ["COULOMB_SMOOTHING", "HingeBias", "HingeCubicStiffness", "HingeStiffness", "HipCoulomb",
           "HipDamping", "coulomb_torque"]

#: Regularisation of dry friction: the relative rate (in sqrt(g/l) units) below which the torque
#: is not saturated. At 7.1 times this rate the torque is within 1 % of the Coulomb value
#: (tests/model/test_effects.py). For the toy (l = 0.15 m) it is 0.081 rad/s, under 5 % of the
#: relative hip rate for more than 95 % of a stable-toy step.
COULOMB_SMOOTHING = 0.01


def _hip_angle(ctx: Context) -> ca.SX:
    return ctx.q4[3] - ctx.q4[2]


def _relative_rate(ctx: Context) -> ca.SX:
    return ctx.u4[3] - ctx.u4[2]


def _hinge_pair(tau: ca.SX, ctx: Context) -> list[tuple[int, ca.SX]]:
    return [(2, tau * ctx.n), (1, -tau * ctx.n)]


def coulomb_torque(strength, rate, smoothing_rate):
    """Regularised dry-friction torque ``-T rate / sqrt(rate^2 + eps^2)`` (N m).

    Smooth (so that the flow and its AD Jacobians exist), odd, bounded by T, dissipative for every
    rate, and within ``1 - 1/sqrt(1 + (rate/eps)^2)`` of ``-T sign(rate)`` (1 % at 7.1 eps).
    Works on numbers and on CasADi expressions alike.
    """
    return -strength * rate / (rate**2 + smoothing_rate**2) ** 0.5


class HipDamping(Effect):
    """Viscous hinge friction: ``tau = -c (theta_sw' - theta_st')`` on the swing leg about n."""

    name = "hip_damping"
    unit = "N m s/rad"
    null = 0.0
    typical = 2e-4
    bounds = (0.0, 1.0)
    enters = "equations of motion"
    physics = "viscous torque -c (theta_sw' - theta_st') at the hip hinge, reaction on the stance leg"

    def couples(self, k, ctx):
        return _hinge_pair(-k * _relative_rate(ctx), ctx)


class HipCoulomb(Effect):
    """Dry hinge friction, regularised (:func:`coulomb_torque`, :data:`COULOMB_SMOOTHING`)."""

    name = "hip_coulomb"
    unit = "N m"
    null = 0.0
    typical = 5e-4
    bounds = (0.0, 1.0)
    enters = "equations of motion"
    physics = ("dry-friction torque of magnitude T opposing the hinge's relative rate, smoothed "
               "below 0.01 sqrt(g/l)")

    def couples(self, k, ctx):
        tau = coulomb_torque(k, _relative_rate(ctx), COULOMB_SMOOTHING * ctx.rate_unit)
        return _hinge_pair(tau, ctx)


class HingeStiffness(Effect):
    """A torsion spring in the hinge: ``tau = -k (theta_sw - theta_st)`` on the swing leg about n.

    Conservative: the power it takes, ``k (theta_sw - theta_st) (theta_sw' - theta_st')``, is the
    rate of change of its energy ``k (theta_sw - theta_st)^2 / 2``, which the relabelling at heel
    strike leaves unchanged (the hip angle changes sign).
    """

    name = "hinge_stiffness"
    unit = "N m/rad"
    null = 0.0
    # The stable toy's swing leg is a pendulum of gravity stiffness m g |d_z| = 0.060 N m/rad about
    # the hip: 5e-3 makes it 8 % stiffer, and shortens the step by 1.5 % (docs/effects.md).
    typical = 5e-3
    # Negative stiffness (a hinge that pushes the legs apart, an over-centre spring) is physical;
    # 0.05 N m/rad is most of the gravity stiffness of the stable toy's swing leg.
    bounds = (-0.05, 1.0)
    enters = "equations of motion"
    physics = "torsion spring in the hinge: torque -k (theta_sw - theta_st) on the swing leg"
    port_only = True

    def couples(self, k, ctx):
        return _hinge_pair(-k * _hip_angle(ctx), ctx)


class HingeCubicStiffness(Effect):
    """A hardening spring in the hinge: ``tau = -k (theta_sw - theta_st)^3`` on the swing leg about
    n, conservative with energy ``k (theta_sw - theta_st)^4 / 4``."""

    name = "hinge_cubic_stiffness"
    unit = "N m/rad^3"
    null = 0.0
    # The stable toy's hip angle reaches 0.17 rad at heel strike: 0.2 N m/rad^3 is a stiffness of
    # 3 k theta^2 = 0.017 N m/rad there (29 % of the swing leg's gravity stiffness) and near none
    # while the legs pass; it shortens the step by 1.1 % (docs/effects.md).
    typical = 0.2
    # Softening (k < 0) is admitted down to -2 N m/rad^3, a stiffness 3 k theta^2 = -0.17 N m/rad
    # at heel strike, three times the swing leg's gravity stiffness reversed; the upper bound only
    # excludes absurd values (100 N m/rad^3: 8.7 N m/rad at heel strike).
    bounds = (-2.0, 100.0)
    enters = "equations of motion"
    physics = "hardening hinge spring: torque -k (theta_sw - theta_st)^3 on the swing leg"
    port_only = True

    def couples(self, k, ctx):
        return _hinge_pair(-k * _hip_angle(ctx) ** 3, ctx)


class HingeBias(Effect):
    """A constant hinge torque ``tau = +k`` on the swing leg about n, its reaction on the stance
    leg: the same physical torque on whichever leg swings, so the term keeps the mirror symmetry.

    Positive theta tilts a leg's foot back (uphill), so ``k > 0`` holds the swing leg back and
    ``k < 0`` drives it forward. Within a step its power is the rate of change of
    ``-k (theta_sw - theta_st)``, but the legs swap at heel strike: over a step it does the work
    ``k * Delta(theta_sw - theta_st)``, which does not vanish on a gait (the hip angle goes from
    positive to negative). It is the hinge's term that feeds (k < 0) or takes (k > 0) energy each
    step, like a hip actuator, where the springs store and return it. A torque fixed to one
    physical leg instead (the offset of a spring's rest angle) would break the symmetry; see
    docs/effects.md.
    """

    name = "hinge_bias"
    unit = "N m"
    null = 0.0
    # Over a stable-toy step the hip angle turns by about 0.34 rad: 5e-4 N m does 0.17 mJ of work
    # a step, 14 % of the collision's 1.24 mJ loss; driving the swing leg, it lengthens the step by
    # 3.9 % (docs/effects.md).
    typical = -5e-4
    bounds = (-0.1, 0.1)
    enters = "equations of motion"
    physics = "constant torque +k on the swing leg about the hip axis (k < 0 drives it forward)"
    port_only = True

    def couples(self, k, ctx):
        return _hinge_pair(k, ctx)
