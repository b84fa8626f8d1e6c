"""The disk cache of compiled code, and the virtual-machine fallback."""

import subprocess

import casadi as ca
import numpy as np
import pytest
from toywalk.model import compiled


def _function():
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p")
    return {"f": ca.Function("f_cache_test", [x, p], [ca.sin(x) * p + ca.dot(x, x)], ["x", "p"], ["y"])}


def test_second_compile_is_served_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    first = compiled.compile_functions("cachetest", _function(), verbose=False)
    libs = list(tmp_path.glob("cachetest-*.so"))
    assert len(libs) == 1
    # The second build of the same expressions must not call the compiler at all.
    def no_compiler(*args, **kwargs):
        raise AssertionError("the compiler ran although the cache holds this code")
    monkeypatch.setattr(subprocess, "run", no_compiler)
    second = compiled.compile_functions("cachetest", _function(), verbose=False)
    x = np.array([0.1, -0.4, 2.0])
    expected = np.sin(x) * 1.5 + x @ x
    np.testing.assert_allclose(np.array(first["f"](x, 1.5)).ravel(), expected, rtol=1e-15)
    np.testing.assert_allclose(np.array(second["f"](x, 1.5)).ravel(), expected, rtol=1e-15)
    # A different expression gets a different library (the key is a hash of the code).
    other = {"f": ca.Function("f_cache_test", [ca.SX.sym("x", 3), ca.SX.sym("p")], [ca.SX.zeros(3)])}
    monkeypatch.undo()
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    compiled.compile_functions("cachetest", other, verbose=False)
    assert len(list(tmp_path.glob("cachetest-*.so"))) == 2


def test_without_compiler_the_virtual_machine_is_used(monkeypatch):
    monkeypatch.setenv("TOYWALK_JIT", "0")
    fns = _function()
    out = compiled.compile_functions("cachetest", fns, verbose=False)
    assert out["f"] is fns["f"]


def test_failed_compile_falls_back_and_leaves_no_cache_entry(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    fns = _function()
    out = compiled.compile_functions("cachetest", fns, verbose=False)
    assert out["f"] is fns["f"]
    assert list(tmp_path.glob("*.so")) == []
    assert "virtual machine" in capsys.readouterr().err


@pytest.mark.parametrize("planar", [True, False])
def test_compiled_walker_matches_virtual_machine(planar):
    """The compiled right-hand side and the uncompiled CasADi function give the same numbers."""
    from toywalk.model.engine import engine
    from toywalk.model.equations import build_functions
    from toywalk.model.parameters import Params

    params = Params(leg_length=0.15, foot_radius=0.03, foot_lateral_radius=0.005, hip_width=0.0,
                    leg_mass=0.06, axle_mass=0.01, com_offset=(-0.005, 0.0, -0.11),
                    inertia=(2e-4, 3e-4, 2e-4, 0.0, 1e-5, 0.0), slope=0.0785, gravity=9.81)
    eng = engine(planar)
    x = np.linspace(-0.3, 0.4, eng.lay.nx)
    fast = eng.k["rhs"](x, params.input_vector())[0].ravel()
    slow = np.array(build_functions(planar)["rhs"](x, params.input_vector())).ravel()
    np.testing.assert_allclose(fast, slow, rtol=1e-13, atol=1e-13)
