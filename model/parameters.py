"""The walker's physical parameters: a typed, immutable set with SI units, read from and written to TOML.

Names, meanings and units follow ``docs/model.md`` section 2, and the file's shape is the one of
``docs/formats.md``, "Parameters". Every quantity is a plain float (or a fixed-length tuple of
floats), so that a parameter set flattens to one vector (:meth:`Params.vector`) that the compiled
equations of motion take as a symbolic input: one compiled function serves every parameter set and
foot shape.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .effects import EFFECTS
from .files import atomic_write_text

__all__ = [
    "BASE_NAMES",
    "INPUT_NAMES",
    "N_INPUT",
    "N_PARAMS",
    "PARAMETER_NAMES",
    "ParamView",
    "ParameterError",
    "Params",
    "load_params",
    "parameter_unit",
    "save_params",
    "view",
]


class ParameterError(ValueError):
    """A parameter set is malformed or physically impossible; the message names the field."""


#: The walker's own parameters, in the order of :meth:`Params.vector` (vector components indexed).
BASE_NAMES: tuple[str, ...] = (
    "leg_length",
    "foot_radius",
    "foot_lateral_radius",
    "hip_width",
    "leg_mass",
    "axle_mass",
    "com_offset[0]",
    "com_offset[1]",
    "com_offset[2]",
    "inertia[0]",
    "inertia[1]",
    "inertia[2]",
    "inertia[3]",
    "inertia[4]",
    "inertia[5]",
    "slope",
    "gravity",
)

#: Flattened parameter vector, in the order of :meth:`Params.vector`: the walker's parameters,
#: then every registered effect's strength (``effects.NAME``, the null value where a file is silent).
PARAMETER_NAMES: tuple[str, ...] = BASE_NAMES + tuple(f"effects.{name}" for name in EFFECTS)

#: The compiled functions' parameter input (:meth:`Params.input_vector`): the parameter vector and
#: the side in stance (+1: the physical left leg; -1: the right leg, the description mirrored).
INPUT_NAMES: tuple[str, ...] = PARAMETER_NAMES + ("side",)

N_PARAMS = len(PARAMETER_NAMES)
N_INPUT = len(INPUT_NAMES)

_SCALARS = (
    "leg_length",
    "foot_radius",
    "foot_lateral_radius",
    "hip_width",
    "leg_mass",
    "axle_mass",
    "slope",
    "gravity",
)
_VECTORS = {"com_offset": 3, "inertia": 6}
_UNITS = {
    "gait.start": "rad and rad/s, the state just after a left heel strike",
    "leg_length": "m, hip axis to foot bottom",
    "foot_radius": "m, fore-aft radius of curvature (0 = point foot)",
    "foot_lateral_radius": "m, sideways radius of curvature (= foot_radius for a sphere)",
    "hip_width": "m",
    "leg_mass": "kg, one leg with its balance mass",
    "axle_mass": "kg",
    "com_offset": "m: forward, outboard, along the leg (up +)",
    "inertia": "kg m^2 about the leg's COM: xx, yy, zz, xy, xz, yz",
    "slope": "rad",
    "gravity": "m/s^2",
}
# The SI unit of each of the walker's own parameters, by name before any index (an effect's strength
# has its effect's unit, Effect.unit).
_SI_UNITS = {"leg_length": "m", "foot_radius": "m", "foot_lateral_radius": "m", "hip_width": "m",
             "leg_mass": "kg", "axle_mass": "kg", "com_offset": "m", "inertia": "kg m^2",
             "slope": "rad", "gravity": "m/s^2"}


def parameter_unit(name: str) -> str:
    """The SI unit of a parameter of :data:`PARAMETER_NAMES` (``"m"`` for ``com_offset[1]``,
    ``"N m s/rad"`` for ``effects.hip_damping``; ``"1"`` for a ratio).

    Raises
    ------
    ValueError
        ``name`` is not one of :data:`PARAMETER_NAMES`.
    """
    if name not in PARAMETER_NAMES:
        raise ValueError(f"unknown parameter {name!r} (known: {', '.join(PARAMETER_NAMES)})")
    if name.startswith("effects."):
        return EFFECTS[name.removeprefix("effects.")].unit
    return _SI_UNITS[name.split("[", 1)[0]]


# Relative round-off allowance for the inertia checks (eigenvalues, triangle inequality).
_INERTIA_RTOL = 1e-12


@dataclasses.dataclass(frozen=True)
class Params:
    """One walker: geometry, masses and ramp (SI units, docs/model.md section 2).

    Parameters
    ----------
    leg_length : float
        l (m), hip point to the bottom of the foot with the leg upright.
    foot_radius : float
        r (m), the foot's fore-aft radius of curvature; 0 is the seed's point foot.
    foot_lateral_radius : float
        rho (m), the foot's sideways radius of curvature, 0 <= rho <= r (rho = r: a sphere).
    hip_width : float
        w (m), distance along the axle between the two legs' hip points.
    leg_mass : float
        m (kg), mass of one leg with its balance mass.
    axle_mass : float
        M_h (kg), point mass at the middle of the axle.
    com_offset : tuple of 3 floats
        (d_x, d_y, d_z) (m), the left leg's centre of mass from its hip point in its body frame:
        forward, outboard, along the leg (negative = below the hip). The right leg is the mirror
        image (d_y -> -d_y).
    inertia : tuple of 6 floats
        (I_xx, I_yy, I_zz, I_xy, I_xz, I_yz) (kg m^2), the left leg's inertia tensor about its
        centre of mass in its body frame. The right leg has I_xy and I_yz negated.
    slope : float
        alpha (rad), ramp slope.
    gravity : float
        g (m/s^2).
    effects : mapping of str to float
        Strengths of the model's physical effects (docs/model.md section 6); empty is the seed's model.
    gait_start : tuple of 8 floats, optional
        A state near the walker's gait just after a left heel strike (docs/model.md section 1), where
        :func:`~toywalk.model.gait.find_gait` starts before searching. The file's optional
        ``[gait]`` table, ``start = [...]``: a designed walker whose gait the search does not reach
        from the planar reduction carries it. Not a parameter: it is kept by :meth:`replace`, left
        out of comparisons, and the search falls back to its usual starts when it does not converge.
    """

    leg_length: float
    foot_radius: float
    foot_lateral_radius: float
    hip_width: float
    leg_mass: float
    axle_mass: float
    com_offset: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]
    slope: float
    gravity: float
    effects: Mapping[str, float] = dataclasses.field(default_factory=dict)
    gait_start: tuple[float, ...] | None = dataclasses.field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.gait_start is not None:
            object.__setattr__(self, "gait_start", _as_vector("gait.start", self.gait_start, 8))
        for name in _SCALARS:
            object.__setattr__(self, name, _as_float(name, getattr(self, name)))
        for name, size in _VECTORS.items():
            object.__setattr__(self, name, _as_vector(name, getattr(self, name), size))
        effects = dict(self.effects)
        _check_effect_names(effects)
        for key, value in effects.items():
            effects[key] = _as_float(f"effects.{key}", value)
            low, high = EFFECTS[key].bounds
            if not low <= effects[key] <= high:
                raise ParameterError(
                    f"effects.{key} = {effects[key]!r} lies outside its physical bounds "
                    f"[{low}, {high}] ({EFFECTS[key].unit})"
                )
        object.__setattr__(self, "effects", _FrozenDict(effects))
        self._validate()

    # ----------------------------------------------------------------------------------------
    def _validate(self) -> None:
        for name in ("leg_length", "foot_radius", "foot_lateral_radius", "hip_width",
                     "leg_mass", "axle_mass"):
            if getattr(self, name) < 0:
                raise ParameterError(f"{name} must be >= 0 ({_UNITS[name]}), got {getattr(self, name)!r}")
        if self.leg_length <= 0:
            raise ParameterError(f"leg_length must be > 0 m, got {self.leg_length!r}")
        if self.gravity <= 0:
            raise ParameterError(f"gravity must be > 0 m/s^2, got {self.gravity!r}")
        if not -math.pi / 2 < self.slope < math.pi / 2:
            raise ParameterError(f"slope must lie in (-pi/2, pi/2) rad, got {self.slope!r}")
        if self.foot_radius >= self.leg_length:
            raise ParameterError(
                f"foot_radius ({self.foot_radius!r} m) must be smaller than leg_length "
                f"({self.leg_length!r} m)"
            )
        if self.foot_lateral_radius > self.foot_radius:
            raise ParameterError(
                f"foot_lateral_radius ({self.foot_lateral_radius!r} m) must not exceed "
                f"foot_radius ({self.foot_radius!r} m)"
            )
        if self.leg_mass + self.axle_mass <= 0:
            raise ParameterError("leg_mass and axle_mass are both zero: the walker has no mass")
        tensor = self.inertia_tensor()
        eig = np.linalg.eigvalsh(tensor)
        scale = max(float(np.max(np.abs(tensor))), 1e-300)
        if eig[0] < -_INERTIA_RTOL * scale:
            raise ParameterError(
                f"inertia is not positive semi-definite (principal moments {eig.tolist()} kg m^2)"
            )
        a, b, c = eig
        if a + b < c - _INERTIA_RTOL * scale * 10:
            raise ParameterError(
                "inertia violates the triangle inequality of a rigid body's principal moments "
                f"({eig.tolist()} kg m^2): no mass distribution has it"
            )
        if self.leg_mass == 0 and scale > 1e-300:
            raise ParameterError("inertia must be zero when leg_mass is zero")

    # ----------------------------------------------------------------------------------------
    def inertia_tensor(self) -> np.ndarray:
        """The left leg's inertia tensor about its centre of mass, body frame, shape (3, 3), kg m^2."""
        ixx, iyy, izz, ixy, ixz, iyz = self.inertia
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])

    def vector(self) -> np.ndarray:
        """The flattened parameter vector, shape (N_PARAMS,), in the order of :data:`PARAMETER_NAMES`."""
        return np.array(
            [
                self.leg_length,
                self.foot_radius,
                self.foot_lateral_radius,
                self.hip_width,
                self.leg_mass,
                self.axle_mass,
                *self.com_offset,
                *self.inertia,
                self.slope,
                self.gravity,
                *(self.effects.get(name, effect.null) for name, effect in EFFECTS.items()),
            ],
            dtype=float,
        )

    def input_vector(self, side: float = 1.0) -> np.ndarray:
        """The compiled functions' parameter input, shape (N_INPUT,) (:data:`INPUT_NAMES`).

        ``side`` is +1 for a step with the physical left leg in stance, -1 for the right leg.
        """
        if side not in (1.0, -1.0):
            raise ValueError(f"side must be +1 (left leg in stance) or -1 (right), got {side!r}")
        return np.append(self.vector(), float(side))

    @property
    def active_effects(self) -> tuple[str, ...]:
        """Names of the effects whose strength is not at its null value."""
        return tuple(k for k, v in self.effects.items() if v != EFFECTS[k].null)

    @property
    def breaks_symmetry(self) -> bool:
        """True when a symmetry-breaking effect is on: gaits repeat every stride, not every step."""
        return any(EFFECTS[k].breaks_symmetry for k in self.active_effects)

    @property
    def total_mass(self) -> float:
        """Mass of the whole walker (kg): two legs and the axle."""
        return 2.0 * self.leg_mass + self.axle_mass

    @property
    def time_scale(self) -> float:
        """sqrt(l / g) (s), the natural time unit of a pendulum of the leg's length."""
        return math.sqrt(self.leg_length / self.gravity)

    def replace(self, **changes: Any) -> Params:
        """A copy with some fields changed. Accepts flattened names too: ``com_offset[1]=0.1``."""
        data = self.to_dict()
        for key, value in changes.items():
            _set_flat(data, key, value)
        return dataclasses.replace(Params.from_dict(data), gait_start=self.gait_start)

    def get(self, name: str) -> float:
        """One flattened value by its file name: ``slope``, ``com_offset[1]``, ``effects.hip_damping``."""
        return float(_get_flat(self.to_dict(), name))

    # ----------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """Plain dictionary in the shape of the parameter file."""
        out: dict[str, Any] = {name: getattr(self, name) for name in _SCALARS}
        out["com_offset"] = list(self.com_offset)
        out["inertia"] = list(self.inertia)
        out["effects"] = dict(self.effects)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Params:
        """Build from a mapping in the shape of the parameter file; unknown or missing keys are errors."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"a parameter set must be a table, got {type(data).__name__}")
        known = set(_SCALARS) | set(_VECTORS) | {"effects", "gait"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ParameterError(
                f"unknown parameter {unknown[0]!r}; known: {', '.join(sorted(known))}"
            )
        missing = sorted((set(_SCALARS) | set(_VECTORS)) - set(data))
        if missing:
            raise ParameterError(f"missing parameter {missing[0]!r} ({_UNITS[missing[0]]})")
        effects = data.get("effects", {}) or {}
        if not isinstance(effects, Mapping):
            raise ParameterError("effects must be a table of name = value")
        _check_effect_names(effects)
        gait = data.get("gait", {}) or {}
        if not isinstance(gait, Mapping) or set(gait) - {"start"}:
            raise ParameterError("gait must be a table with one key, start = [8 numbers] (a state "
                                 "near the gait just after a left heel strike)")
        kwargs = {k: v for k, v in data.items() if k not in ("effects", "gait")}
        return cls(**kwargs, effects=dict(effects), gait_start=gait.get("start"))


@dataclasses.dataclass(frozen=True)
class ParamView:
    """Named views of a parameter input (NumPy or CasADi): the one place that knows the layout.

    Attributes are the parameter file's names (``com_offset`` shape (3,), ``inertia`` shape (6,)),
    ``effects`` (name -> strength, every registered effect) and ``side`` (None without one).
    """

    leg_length: Any
    foot_radius: Any
    foot_lateral_radius: Any
    hip_width: Any
    leg_mass: Any
    axle_mass: Any
    com_offset: Any
    inertia: Any
    slope: Any
    gravity: Any
    effects: dict
    side: Any


def view(p: Any) -> ParamView:
    """Named views of ``p``, a parameter vector (N_PARAMS) or input (N_INPUT), NumPy or CasADi."""
    size = p.shape[0] if hasattr(p, "shape") else len(p)
    if size not in (N_PARAMS, N_INPUT):
        raise ValueError(f"a parameter input has {N_PARAMS} or {N_INPUT} entries, got {size}")
    at = {name: i for i, name in enumerate(INPUT_NAMES)}
    scalars = {name: p[at[name]] for name in _SCALARS}
    return ParamView(
        **scalars,
        com_offset=p[at["com_offset[0]"]:at["com_offset[2]"] + 1],
        inertia=p[at["inertia[0]"]:at["inertia[5]"] + 1],
        effects={name: p[at[f"effects.{name}"]] for name in EFFECTS},
        side=p[at["side"]] if size == N_INPUT else None,
    )


class _FrozenDict(dict):
    """A dict that refuses changes, so that a frozen :class:`Params` stays frozen."""

    def _readonly(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("Params.effects is read-only; use Params.replace")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _readonly  # type: ignore
    __ior__ = _readonly  # type: ignore

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted(self.items())))

    def __reduce__(self):  # pickles (process pools) without going through the refused setters
        return (_FrozenDict, (dict(self),))


def _check_effect_names(effects: Mapping[str, Any]) -> None:
    for name in effects:
        if name not in EFFECTS:
            known = ", ".join(sorted(EFFECTS)) or "none yet"
            raise ParameterError(f"unknown effect parameter 'effects.{name}'; known: {known}")


def _as_float(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ParameterError(f"{name} must be a number, got {value!r}")
    try:
        out = float(value)
    except OverflowError:  # an integer too large for a float
        out = math.inf
    if not math.isfinite(out):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return out


def _as_vector(name: str, value: Any, size: int) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != size:
        raise ParameterError(f"{name} must be a list of {size} numbers ({_UNITS[name]}), got {value!r}")
    return tuple(_as_float(f"{name}[{i}]", v) for i, v in enumerate(value))


def _split_flat(name: str) -> tuple[str, int | None]:
    if name.endswith("]") and "[" in name:
        base, index = name[:-1].split("[", 1)
        try:
            return base, int(index)
        except ValueError as err:
            raise ParameterError(f"bad parameter index in {name!r}") from err
    return name, None


def _get_flat(data: dict[str, Any], name: str) -> Any:
    if name.startswith("effects."):
        key = name.split(".", 1)[1]
        _check_effect_names({key: 0.0})
        return data["effects"].get(key, EFFECTS[key].null)
    base, index = _split_flat(name)
    if base not in data or base == "effects":
        raise ParameterError(f"unknown parameter {name!r}")
    if index is None:
        if base in _VECTORS:
            raise ParameterError(f"{name!r} is a vector: name a component, e.g. {base}[0]")
        return data[base]
    if base not in _VECTORS or not 0 <= index < _VECTORS[base]:
        raise ParameterError(f"parameter {name!r} has no such component")
    return data[base][index]


def _set_flat(data: dict[str, Any], name: str, value: Any) -> None:
    if name in _VECTORS:  # a whole vector field; its value is validated by Params
        data[name] = value
        return
    _get_flat(data, name)  # validates the name
    if name.startswith("effects."):
        data["effects"][name.split(".", 1)[1]] = value
        return
    base, index = _split_flat(name)
    if index is None:
        data[base] = value
    else:
        data[base] = list(data[base])
        data[base][index] = value


def load_params(path: str | Path) -> Params:
    """Read a parameter TOML file (docs/formats.md, "Parameters"). Raises :class:`ParameterError`
    naming the field."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")  # TOML files are UTF-8 (toml.io)
    except FileNotFoundError as err:
        raise ParameterError(f"parameter file not found: {path}") from err
    except UnicodeDecodeError as err:
        raise ParameterError(f"{path} is not a TOML text file (not UTF-8 at byte {err.start})") from err
    except OSError as err:
        raise ParameterError(f"cannot read parameter file {path}: {err.strerror or err}") from err
    if not text.strip():
        raise ParameterError(f"parameter file {path} is empty")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ParameterError(f"{path} is not valid TOML: {str(err).splitlines()[0]}") from err
    try:
        return Params.from_dict(data)
    except ParameterError as err:
        raise ParameterError(f"{path}: {err}") from err


def save_params(params: Params, path: str | Path, header: str = "") -> None:
    """Write a parameter TOML file with unit comments, atomically (no half-written file)."""
    lines = [f"# {line}" for line in header.splitlines()]
    for name in _SCALARS[:6]:
        lines.append(f"{name} = {getattr(params, name)!r}  # {_UNITS[name]}")
    lines.append(f"com_offset = {[float(v) for v in params.com_offset]!r}  # {_UNITS['com_offset']}")
    lines.append(f"inertia = {[float(v) for v in params.inertia]!r}  # {_UNITS['inertia']}")
    for name in ("slope", "gravity"):
        lines.append(f"{name} = {getattr(params, name)!r}  # {_UNITS[name]}")
    lines.append("")
    lines.append("[effects]")
    for key, value in sorted(params.effects.items()):
        lines.append(f"{key} = {value!r}")
    if params.gait_start is not None:
        lines += ["", "[gait]", f"start = {[float(v) for v in params.gait_start]!r}  # near the gait "
                  "just after a left heel strike: phi, phi_dot, psi, psi_dot, theta_st, theta_st_dot, "
                  "theta_sw, theta_sw_dot (rad, rad/s)"]
    atomic_write_text(path, "\n".join(lines) + "\n")
