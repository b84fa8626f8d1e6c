"""The library of physical effects that extend the seed's model (model.md section 6).

Each effect is a named, documented extension with its own parameters that reduces exactly to the
base model at its null value. The registry :data:`EFFECTS` maps each effect parameter name (the key
used in a parameter file's ``[effects]`` table) to its description. The base model of this release
has no effects registered yet; a parameter file naming one is refused with the list of known names.
"""

from __future__ import annotations

import dataclasses

__all__ = ["EFFECTS", "Effect"]


@dataclasses.dataclass(frozen=True)
class Effect:
    """One effect parameter.

    Parameters
    ----------
    name : str
        Key in the parameter file's ``[effects]`` table.
    unit : str
        SI unit of the parameter.
    null : float
        Value at which the model reduces exactly to the seed's.
    typical : float
        A magnitude that visibly changes the toy's gait.
    physics : str
        One line of physics.
    """

    name: str
    unit: str
    null: float
    typical: float
    physics: str


#: Registry of effect parameters by name.
EFFECTS: dict[str, Effect] = {}
