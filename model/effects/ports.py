"""The dictionary of generalised forces at the walker's mechanical ports, as model terms.

When no effect of the library explains a measured walk, the force the model misses acts somewhere
on the walker. Its mechanical ports are where a force can enter: the hip hinge (a torque between
the legs about the axle), the stance contact (a couple from the ramp about each of three axes) and
the heel strike (the collision law). At each port the dictionary has a few forms (a function of
an angle, of a rate, dry friction, ...). Each (port, form) is one effect of the registry, with one
strength parameter that is a symbolic input of the compiled functions and exact at zero; where a
form is a library effect (the hinge's viscous form is ``hip_damping``), it is that effect, not a
second parameter. The forms that are not library effects are port-only (:attr:`Effect.port_only`):
named explicitly they fit like any effect, but the analysis does not try them by default.

Sign conventions (docs/formats.md, "Ports and forms"): ``tau_hinge`` acts on the swing leg about
the hip axis n (to the left of the described stance leg), ``-tau_hinge`` on the stance leg; ``M_st``
is the couple on the stance leg from the ramp, along the heading ``h = Rz(phi) e_x``, the in-plane
hip axis ``p = Rz(phi) e_y`` or the ramp normal ``e_z``; angles and rates are those of the state
(docs/model.md section 1), in the step's mirrored description, so that every term is the same physical
term with either leg in stance.
"""

from __future__ import annotations

import dataclasses

from .base import Effect
from .contact import (
    PitchCoulomb,
    PitchDamping,
    PitchStiffness,
    PivotFriction,
    RollCoulomb,
    RollDamping,
    RollStiffness,
    SpinCoulomb,
)
from .hip import HingeBias, HingeCubicStiffness, HingeStiffness, HipCoulomb, HipDamping
from .impact import ImpactLeanArrest, ImpactSpinArrest

__all__ = ["PORTS", "Port"]


@dataclasses.dataclass(frozen=True)
class Port:
    """One term of the dictionary: a form of the generalised force at one port.

    Attributes
    ----------
    port, form : str
        Where the term acts (``hinge``, ``contact_roll``, ``contact_pitch``, ``contact_spin``,
        ``heel_strike``) and how (``angle``, ``rate``, ``dry``, ``angle3``, ``bias``;
        ``spin_loss``, ``lean_loss``).
    effect : type of Effect
        The effect unit that is the term.
    equation : str
        The term as text for reports, with its sign convention.
    """

    port: str
    form: str
    effect: type[Effect]
    equation: str

    @property
    def parameter(self) -> str:
        """The strength's name (its key in a parameter file's ``[effects]`` table)."""
        return self.effect.name

    @property
    def unit(self) -> str:
        """SI unit of the strength."""
        return self.effect.unit

    @property
    def coincides_with(self) -> str | None:
        """The library effect the term is, or None for a port-only term."""
        return None if self.effect.port_only else self.effect.name


_DRY = "T r / sqrt(r^2 + eps^2), eps = 0.01 sqrt(g/l)"
_TERMS = (
    Port("hinge", "angle", HingeStiffness, "tau_hinge = -k (theta_sw - theta_st)"),
    Port("hinge", "rate", HipDamping, "tau_hinge = -c (theta_sw' - theta_st')"),
    Port("hinge", "dry", HipCoulomb, f"tau_hinge = -{_DRY}, r = theta_sw' - theta_st'"),
    Port("hinge", "angle3", HingeCubicStiffness, "tau_hinge = -k (theta_sw - theta_st)^3"),
    Port("hinge", "bias", HingeBias, "tau_hinge = k (k < 0 drives the swing leg forward)"),
    Port("contact_roll", "angle", RollStiffness, "M_st = -k psi h"),
    Port("contact_roll", "rate", RollDamping, "M_st = -c psi' h   (psi' = omega_st . h)"),
    Port("contact_roll", "dry", RollCoulomb, f"M_st = -{_DRY} h, r = psi'"),
    Port("contact_pitch", "angle", PitchStiffness, "M_st = -k theta_st p / cos psi"),
    Port("contact_pitch", "rate", PitchDamping,
         "M_st = -c (omega_st . p) p   (omega_st . p = theta_st' cos psi)"),
    Port("contact_pitch", "dry", PitchCoulomb, f"M_st = -{_DRY} p, r = omega_st . p"),
    Port("contact_spin", "rate", PivotFriction, "M_st = -c (omega_st . e_z) e_z"),
    Port("contact_spin", "dry", SpinCoulomb, f"M_st = -{_DRY} e_z, r = omega_st . e_z"),
    Port("heel_strike", "spin_loss", ImpactSpinArrest,
         "u+ = u0 + k (u_arrested - u0), u_arrested: plastic law with omega_landing . e_z = 0"),
    Port("heel_strike", "lean_loss", ImpactLeanArrest,
         "u+ = u0 + k (u_arrested - u0), u_arrested: plastic law with omega_landing . h = 0"),
)

#: The dictionary, by (port, form). The contact's spin has no ``angle`` form: the heading phi is no
#: angle of the contact (the foot's heading at touchdown would be, and the state does not keep
#: it), so ``-k phi`` would be a spring to a fixed direction on the ramp.
PORTS: dict[tuple[str, str], Port] = {(t.port, t.form): t for t in _TERMS}
