"""Tests of the parameter set: TOML round trip, validation naming the field, flattening, freezing."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from toywalk.model.parameters import (
    PARAMETER_NAMES,
    ParameterError,
    Params,
    load_params,
    parameter_unit,
    save_params,
)


def _toml(**overrides) -> str:
    """A valid parameter file with some lines replaced (value strings, TOML syntax)."""
    lines = {
        "leg_length": "0.15",
        "foot_radius": "0.03",
        "foot_lateral_radius": "0.005",
        "hip_width": "0.01",
        "leg_mass": "0.05",
        "axle_mass": "0.02",
        "com_offset": "[-0.005, 0.1, -0.11]",
        "inertia": "[3e-4, 1e-4, 3e-4, 1e-5, -2e-5, 0.0]",
        "slope": "0.0785",
        "gravity": "9.81",
    }
    lines.update(overrides)
    body = "\n".join(f"{k} = {v}" for k, v in lines.items() if v is not None)
    return body + "\n\n[effects]\n"


def _load(tmp_path, text: str) -> Params:
    path = tmp_path / "walker.toml"
    path.write_text(text)
    return load_params(path)


def test_toml_round_trip(tmp_path, toy_params):
    # Non-trivial values everywhere (products of inertia, negative offsets, reprs that are not
    # short decimals) so that a lossy writer would show.
    params = toy_params.replace(**{"inertia[3]": 1.0 / 3.0 * 1e-5, "slope": 0.1 + 1e-17})
    path = tmp_path / "p.toml"
    save_params(params, path, header="made by a test\nsecond line")
    loaded = load_params(path)
    assert loaded == params
    assert loaded.vector().tobytes() == params.vector().tobytes()  # bit for bit
    assert path.read_text().startswith("# made by a test\n# second line\n")
    assert not list(tmp_path.glob(".*.tmp"))  # the atomic write leaves no temporary file


def test_gait_start_is_read_kept_and_written(tmp_path, toy_params):
    """The optional ``[gait] start`` table (Params.gait_start): read, kept by replace (a fit or a
    continuation changes parameters, not where the search starts), left out of comparisons,
    written back, and refused with a named error when it is not 8 numbers or has other keys."""
    start = (0.07, -0.47, -0.01, -0.42, -0.19, 3.2, 0.14, 1.1)
    params = toy_params.replace(slope=0.05)
    with_start = dataclasses.replace(params, gait_start=start)
    assert with_start == params and with_start.gait_start == start
    assert with_start.replace(**{"com_offset[1]": 0.1}).gait_start == start
    path = tmp_path / "p.toml"
    save_params(with_start, path)
    assert load_params(path).gait_start == start and "[gait]" in path.read_text()
    save_params(params, path)
    assert load_params(path).gait_start is None and "[gait]" not in path.read_text()
    with pytest.raises(ParameterError, match="gait.start must be a list of 8 numbers"):
        _load(tmp_path, _toml() + "\n[gait]\nstart = [1.0, 2.0]\n")
    with pytest.raises(ParameterError, match="gait must be a table with one key"):
        _load(tmp_path, _toml() + "\n[gait]\nstart = [0, 0, 0, 0, 0, 0, 0, 0]\nguess = 1\n")


def test_valid_file_loads(tmp_path):
    params = _load(tmp_path, _toml())
    assert params.hip_width == 0.01
    assert params.inertia[4] == -2e-5


def test_zero_inertia_point_masses_are_allowed(tmp_path):
    # The simplest walker (Garcia et al. 1998) has point-mass legs: zero inertia must load.
    params = _load(tmp_path, _toml(inertia="[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]"))
    assert params.inertia == (0.0,) * 6


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ({"leg_length": "-0.15"}, "leg_length"),
        ({"leg_length": "0.0"}, "leg_length"),
        ({"hip_width": "-0.01"}, "hip_width"),
        ({"leg_mass": "-0.05"}, "leg_mass"),
        ({"axle_mass": "-1.0"}, "axle_mass"),
        ({"foot_lateral_radius": "-0.001"}, "foot_lateral_radius"),
        ({"gravity": "0.0"}, "gravity"),
        ({"slope": "2.0"}, "slope"),
        ({"foot_radius": "0.15"}, "foot_radius"),  # = leg_length
        ({"foot_radius": "0.2"}, "foot_radius"),  # > leg_length
        ({"foot_lateral_radius": "0.031"}, "foot_lateral_radius"),  # > foot_radius
        ({"leg_length": "nan"}, "leg_length"),
        ({"com_offset": "[0.0, nan, -0.1]"}, "com_offset[1]"),
        ({"inertia": "[3e-4, 1e-4, inf, 0.0, 0.0, 0.0]"}, "inertia[2]"),
        ({"slope": "true"}, "slope"),
        ({"gravity": '"9.81"'}, "gravity"),
        ({"com_offset": "[0.0, 0.1]"}, "com_offset"),  # a vector of the wrong length
        ({"inertia": "[1e-4, 1e-4, 1e-4, 0.0, 0.0, 0.0, 0.0]"}, "inertia"),
        ({"com_offset": "0.1"}, "com_offset"),
        # Principal moments (1, 1, -1) e-4: not positive semi-definite.
        ({"inertia": "[1e-4, 1e-4, -1e-4, 0.0, 0.0, 0.0]"}, "inertia"),
        # Product of inertia larger than the moments: eigenvalues 3e-4 and -1e-4.
        ({"inertia": "[1e-4, 1e-4, 1e-4, 2e-4, 0.0, 0.0]"}, "inertia"),
        # Principal moments (1, 1, 3) e-4: positive but 1 + 1 < 3, no mass distribution has them.
        ({"inertia": "[1e-4, 1e-4, 3e-4, 0.0, 0.0, 0.0]"}, "triangle"),
        ({"leg_mass": "0.0"}, "inertia"),  # a massless leg cannot have inertia
    ],
)
def test_bad_value_names_the_field(tmp_path, override, field):
    with pytest.raises(ParameterError, match=field.replace("[", r"\[").replace("]", r"\]")):
        _load(tmp_path, _toml(**override))


def test_unknown_key_is_named(tmp_path):
    with pytest.raises(ParameterError, match="unknown parameter 'leg_lenght'"):
        _load(tmp_path, _toml().replace("leg_length", "leg_lenght"))


def test_missing_key_is_named(tmp_path):
    with pytest.raises(ParameterError, match="missing parameter 'hip_width'"):
        _load(tmp_path, _toml(hip_width=None))


def test_unknown_effect_is_named(tmp_path):
    with pytest.raises(ParameterError, match="effects.no_such_effect"):
        _load(tmp_path, _toml() + "no_such_effect = 1.0\n")


def test_unknown_effect_refused_by_the_constructor_too(toy_params):
    with pytest.raises(ParameterError, match="effects.no_such_effect"):
        dataclasses.replace(toy_params, effects={"no_such_effect": 1.0})


def test_file_errors_are_parameter_errors(tmp_path):
    with pytest.raises(ParameterError, match="not found"):
        load_params(tmp_path / "absent.toml")
    with pytest.raises(ParameterError, match="not valid TOML"):
        _load(tmp_path, "leg_length = = 1\n")
    with pytest.raises(ParameterError, match="walker.toml"):  # the message names the file
        _load(tmp_path, _toml(leg_mass="-1.0"))


def test_vector_order_matches_names(toy_params):
    vec = toy_params.vector()
    # The walker's 17 parameters, then one strength per registered effect.
    from toywalk.model.effects import EFFECTS

    assert vec.shape == (len(PARAMETER_NAMES),) == (17 + len(EFFECTS),)
    for i, name in enumerate(PARAMETER_NAMES):
        assert vec[i] == toy_params.get(name), name
    # Spot checks against the fields themselves, independent of get().
    assert vec[PARAMETER_NAMES.index("com_offset[2]")] == toy_params.com_offset[2]
    assert vec[PARAMETER_NAMES.index("inertia[4]")] == toy_params.inertia[4]
    assert vec[PARAMETER_NAMES.index("gravity")] == toy_params.gravity


def test_replace_with_indexed_names(toy_params):
    new = toy_params.replace(**{"com_offset[1]": 0.2, "inertia[3]": 0.0, "slope": 0.0})
    assert new.com_offset == (toy_params.com_offset[0], 0.2, toy_params.com_offset[2])
    assert new.inertia[3] == 0.0 and new.inertia[:3] == toy_params.inertia[:3]
    assert new.slope == 0.0
    assert toy_params.com_offset[1] == 0.1  # the original is unchanged
    whole = toy_params.replace(com_offset=(0.0, 0.05, -0.1))
    assert whole.com_offset == (0.0, 0.05, -0.1)


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("com_offset[3]", "no such component"),
        ("com_offset[x]", "bad parameter index"),
        ("leg_lenght", "unknown parameter"),
        ("effects.no_such_effect", "effects.no_such_effect"),
    ],
)
def test_replace_rejects_bad_names(toy_params, name, match):
    with pytest.raises(ParameterError, match=match.replace("[", r"\[")):
        toy_params.replace(**{name: 0.1})


def test_replace_validates_the_result(toy_params):
    with pytest.raises(ParameterError, match="foot_lateral_radius"):
        toy_params.replace(foot_lateral_radius=1.0)
    with pytest.raises(ParameterError, match="com_offset"):
        toy_params.replace(com_offset=(0.0, 0.1))


def test_params_are_frozen(toy_params):
    with pytest.raises(dataclasses.FrozenInstanceError):
        toy_params.leg_length = 1.0  # type: ignore[misc]
    effects = toy_params.effects
    with pytest.raises(TypeError, match="read-only"):
        effects["hip_damping"] = 1.0  # type: ignore[index]
    for mutate in (
        lambda e: e.update({"x": 1.0}),
        lambda e: e.setdefault("x", 1.0),
        lambda e: e.pop("x", None),
        lambda e: e.clear(),
        lambda e: e.__ior__({"x": 1.0}),
    ):
        with pytest.raises(TypeError):
            mutate(effects)
    assert dict(toy_params.effects) == {}
    assert isinstance(toy_params.com_offset, tuple) and isinstance(toy_params.inertia, tuple)
    assert hash(toy_params) == hash(toy_params.replace(slope=toy_params.slope))


def test_derived_quantities(toy_params):
    assert toy_params.total_mass == pytest.approx(2 * 0.05 + 0.02, rel=1e-15)
    assert toy_params.time_scale == pytest.approx(math.sqrt(0.15 / 9.81), rel=1e-15)
    tensor = toy_params.inertia_tensor()
    np.testing.assert_array_equal(tensor, tensor.T)
    assert tensor[0, 1] == toy_params.inertia[3] and tensor[1, 2] == toy_params.inertia[5]


def test_every_parameter_has_its_unit(tmp_path, toy_params):
    """parameter_unit agrees with the unit comments save_params writes (the walker's own
    parameters) and with each effect's unit; an unknown name is refused."""
    from toywalk.model.effects import EFFECTS

    save_params(toy_params, tmp_path / "p.toml")
    comments = {line.split(" = ")[0]: line.split("# ", 1)[1]
                for line in (tmp_path / "p.toml").read_text().splitlines() if "  # " in line}
    for name in PARAMETER_NAMES:
        unit = parameter_unit(name)
        if name.startswith("effects."):
            assert unit == EFFECTS[name.removeprefix("effects.")].unit
        else:  # "m, hip axis to foot bottom", "kg m^2 about the leg's COM: ...", "m: forward, ..."
            comment = comments[name.split("[")[0]]
            assert comment == unit or comment[len(unit)] in ",: ", (name, unit, comment)
            assert comment.startswith(unit), (name, unit, comment)
    assert parameter_unit("com_offset[1]") == "m" and parameter_unit("inertia[3]") == "kg m^2"
    with pytest.raises(ValueError, match="unknown parameter 'lean_offset'"):
        parameter_unit("lean_offset")
