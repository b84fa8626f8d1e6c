"""Friction in the hip hinge: viscous (``hip_damping``) and dry (``hip_coulomb``).

The legs turn on a shared axle; a Tinkertoy rod in a spool's hole rubs. The hinge torque acts on
the swing leg about the hip axis n and its reaction on the stance leg, so it does no work on the
rigid motion of the pair and dissipates ``-tau * (theta_sw' - theta_st')`` (model.md section 6).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import Context, Effect

if TYPE_CHECKING:
    import casadi as ca

__all__ = ["COULOMB_SMOOTHING", "HipCoulomb", "HipDamping", "coulomb_torque"]

#: Regularisation of dry friction: the relative rate (in sqrt(g/l) units) below which the torque
#: is not saturated. At 7.1 times this rate the torque is within 1 % of the Coulomb value
#: (tests/model/test_effects.py). For the toy (l = 0.15 m) it is 0.081 rad/s, under 5 % of the
#: relative hip rate for more than 95 % of a stable-toy step.
COULOMB_SMOOTHING = 0.01


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
