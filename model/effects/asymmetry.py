"""Effects that break the left-right mirror symmetry: unequal legs and a sideways-tilted ramp.

With either, a step with the left leg in stance differs from one with the right: the step map in
the mirrored description (docs/model.md section 4) depends on the side in stance, the periodic gait
repeats every stride (two steps), and the walker turns or drifts sideways ("slight directional
drift", Coleman & Ruina 1998). The side enters the compiled functions as the input ``side``
(+1: the physical left leg in stance, the description is the physical one; -1: the right leg in
stance, the description is mirrored y -> -y).
"""

from __future__ import annotations

from .base import Effect

# CasADi is imported where an expression is built, so that reading parameter files (the tracker
# does) does not load it (effects/base.py).

__all__ = ["Asymmetry", "CrossSlope"]


class Asymmetry(Effect):
    """The legs' lateral mass offsets differ by a fraction a of the nominal one: the left leg's is
    ``d_y (1 + a/2)``, the right leg's ``d_y (1 - a/2)`` (the mean is unchanged; the inertia about
    each leg's own centre of mass is kept)."""

    name = "asymmetry"
    unit = "1"
    null = 0.0
    typical = 0.005
    bounds = (-0.5, 0.5)
    enters = "geometry"
    breaks_symmetry = True
    physics = ("the left leg's lateral mass offset is d_y (1 + a/2), the right leg's d_y (1 - a/2): "
               "the walker turns")

    def com_offsets(self, k, ctx, d_st, d_sw):
        import casadi as ca

        half = 0.5 * k * ctx.side
        return (ca.vertcat(d_st[0], d_st[1] * (1 + half), d_st[2]),
                ca.vertcat(d_sw[0], d_sw[1] * (1 - half), d_sw[2]))


class CrossSlope(Effect):
    """The ramp tilted sideways by beta (rad), its left edge higher for beta > 0: gravity in the
    ramp frame is ``g (sin alpha, -cos alpha sin beta, -cos alpha cos beta)``."""

    name = "cross_slope"
    unit = "rad"
    null = 0.0
    typical = 0.01
    bounds = (-0.2, 0.2)
    enters = "geometry"
    breaks_symmetry = True
    physics = "the ramp tilted sideways by beta (left edge up for beta > 0): the walker drifts"

    def gravity(self, k, ctx, gvec):
        import casadi as ca

        alpha, g = ctx.params.slope, ctx.params.gravity
        return g * ca.vertcat(ca.sin(alpha), -ctx.side * ca.cos(alpha) * ca.sin(k),
                              -ca.cos(alpha) * ca.cos(k))
