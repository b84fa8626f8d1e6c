"""Contact couples at the stance foot: rolling resistance and pivot (spin) friction.

The seed's contact is a point that rolls without slip and transmits no couple. A real foot rolls
on a small deformed patch (the brass shim on a wooden ramp), which resists rolling and spinning.
Both couples act on the stance leg; the ramp, at rest, takes the reaction, so each dissipates
``-M . omega_st`` (model.md section 6).
"""

from __future__ import annotations

from .base import Effect

# CasADi is imported where an expression is built, so that reading parameter files (the tracker
# does) does not load it (effects/base.py).

__all__ = ["PivotFriction", "RollingResistance"]


class RollingResistance(Effect):
    """``M = -c (omega_st - (omega_st . e_z) e_z)``: resists the stance foot's rolling, fore-aft
    and sideways (the tangential part of its angular velocity)."""

    name = "rolling_resistance"
    unit = "N m s/rad"
    null = 0.0
    typical = 2e-4
    bounds = (0.0, 1.0)
    enters = "contact couple"
    physics = "viscous couple opposing the stance foot's rolling (tangential angular velocity)"

    def couples(self, k, ctx):
        import casadi as ca

        ez = ctx.ez
        tangential = ctx.w1 - ca.dot(ctx.w1, ez) * ez
        return [(1, -k * tangential)]


class PivotFriction(Effect):
    """``M = -c (omega_st . e_z) e_z``: resists the stance foot's spin about the ramp normal, which
    the seed's model leaves free (the toy shows "no visible variation in phi")."""

    name = "pivot_friction"
    unit = "N m s/rad"
    null = 0.0
    typical = 1e-3
    bounds = (0.0, 1.0)
    enters = "contact couple"
    physics = "viscous couple about the ramp normal opposing the stance foot's spin"

    def couples(self, k, ctx):
        import casadi as ca

        ez = ctx.ez
        return [(1, -k * ca.dot(ctx.w1, ez) * ez)]
