"""The heel strike on soft feet: the collision resolved in time by a compliant contact phase.

The seed's heel strike is instantaneous and plastic at the landing foot D, with no impulse on the
trailing foot (Coleman & Ruina 1998, eqs. 3-4). ``soft_heel`` replaces it, in the step map, by the
compliant phase of :mod:`toywalk.model.compliant` (docs/soft_feet.md): at the rigid model's heel
strike the walker leaves the rolling model, falls on MuJoCo-style spring-damper contacts at both
feet for a fixed span of :data:`toywalk.model.compliant.SPAN` contact time constants, and is
handed back to the rolling model with the landing foot as stance by the seed's plastic law
applied to what is left. The strength is the contact's time constant tau (MuJoCo's ``solref[0]``);
at tau = 0 the step map is the seed's, on the rigid code path, bit for bit.

Two of the contact's constants are fixed in this increment (module constants below): the
damping ratio (:data:`ZETA`, MuJoCo's default) and the friction coefficient (:data:`FRICTION`,
large: the rolling model's no-slip contact, regularised).

The phase models the seed's walker: :class:`toywalk.model.Walker` refuses ``soft_heel`` together
with another effect, and so do the fits. The fits' collocation transcription takes the phase
(:func:`toywalk.model.collocation.soft_link`), so a fit can free tau; a fit with it costs minutes
where a rigid one costs seconds, so it is not among the causes the discrepancy analysis tries by
default (:attr:`Effect.screened` is False) and is named with ``--effects``. Its change of the gait
is not monotonic in tau (:attr:`Effect.local` is False): the analysis fits it whatever its score
test at tau = 0 says (docs/soft_feet.md section 8).
"""

from __future__ import annotations

from .base import Effect

__all__ = ["FRICTION", "ZETA", "SoftHeel"]

#: The contact's damping ratio: critical, MuJoCo's default ``solref = (0.02, 1)``. A critically
#: damped landing of a lone mass does not bounce (docs/soft_feet.md section 2 on the rebound).
ZETA = 1.0
#: The feet's Coulomb friction coefficient. Large, so that the phase keeps the rolling model's
#: no-slip contact, regularised by the tangential spring-damper: the friction cap
#: ``F_t = F_raw mu N / sqrt((mu N)^2 + |F_raw|^2)`` departs from ``F_raw`` by relative
#: ``(|F_raw| / mu N)^2 / 2``. The clearing toy's landing foot asks, at its peak normal force, for
#: ``|F_t| / N`` = 1.42 without slip (measured at tau = 0.5 ms, 2026-11-28; friction 1 lets it slide,
#: docs/soft_feet.md section 2), so at 10 the cap takes about 1 % off the force there and the foot
#: barely slides. Not larger: the cap still lets a foot go smoothly as its normal force vanishes
#: (lift-off), over a range of N of ``|F_raw| / mu``, and a sharper release costs the fixed-step
#: integrator accuracy (the phase's energy balance at 20 steps per tau: 9e-5 relative at friction 1,
#: 1.2e-3 at 10, 1.3e-3 at 100). A realistic friction (brass on wood, about 0.3-0.5) would let the
#: landing foot slide, a different contact law that this increment does not model.
FRICTION = 10.0


class SoftHeel(Effect):
    """The contact time constant tau (s) of a compliant heel strike on spring-damper feet."""

    name = "soft_heel"
    unit = "s"
    null = 0.0
    # The order of MuJoCo's contact times for a model of the toy's size (the project's MuJoCo
    # check uses 1 ms by default, toywalk.model.mujoco_check) and of the brass strip's bending estimate,
    # 0.2-2.6 ms (docs/soft_feet.md section 4).
    typical = 1e-3
    # At 10 ms the phase (10 tau = 0.1 s) is more than half the toy's step (0.18 s).
    bounds = (0.0, 0.01)
    enters = "collision law"
    physics = ("the heel strike is resolved in time on spring-damper feet with time constant tau "
               "(MuJoCo's solref, critically damped), then the rolling model resumes")
    screened = False
    local = False
