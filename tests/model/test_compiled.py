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
    monkeypatch.delenv("TOYWALK_JIT", raising=False)  # the undo restored a caller's TOYWALK_JIT=0
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


@pytest.mark.parametrize("planar", [True, False])
def test_native_interval_derivatives_match_the_symbolic_ones(planar):
    """The collocation interval compiled with its derivatives (model.collocation.native_interval)
    gives an NLP the same constraint Jacobian and Lagrangian Hessian as the SX function in the
    virtual machine, with the same sparsity (its derivative functions carry theirs), and its
    Jacobian agrees with central differences."""
    from toywalk.model.collocation import interval_equations, native_interval
    from toywalk.model.parameters import load_params

    from ..conftest import DATA

    degree, n_int = 4, 3
    symbolic, native = interval_equations(planar, degree), native_interval(planar, degree)
    if native.class_name() != "External":
        pytest.skip("no C compiler (or TOYWALK_JIT=0): the symbolic function serves")
    nd = symbolic.size1_in(0)
    rng = np.random.default_rng(3)
    params = load_params(DATA / "params" / ("compass-3d.toml" if not planar else "stable-toy.toml"))
    p_val = params.input_vector(1)
    x = ca.MX.sym("x", nd * (degree + 2) * n_int + n_int)
    parts = ca.vertsplit(x, list(np.cumsum([0, nd * n_int, nd * degree * n_int, nd * n_int, n_int])))
    args = [ca.reshape(parts[0], nd, n_int), ca.reshape(parts[1], nd * degree, n_int),
            ca.reshape(parts[2], nd, n_int), ca.reshape(parts[3], 1, n_int)]
    p = ca.MX.sym("p", len(p_val))
    x_val = np.r_[0.1 * rng.standard_normal(len(x.nz) - n_int), np.full(n_int, 0.05)]
    lam = rng.standard_normal(nd * (degree + 1) * n_int)
    out = {}
    for name, fn in (("symbolic", symbolic), ("native", native)):
        g = ca.vec(fn.map(n_int)(*args, ca.repmat(p, 1, n_int)))
        nlp = ca.nlpsol(f"check_{name}", "ipopt", {"x": x, "p": p, "f": 0, "g": g},
                        {"ipopt.print_level": 0, "print_time": False})
        jac = nlp.get_function("nlp_jac_g")(x_val, p_val)[1]
        hess = nlp.get_function("nlp_hess_l")(x_val, p_val, 0.0, lam)
        out[name] = (jac, hess)
    for k in range(2):
        a, b = out["symbolic"][k], out["native"][k]
        assert a.sparsity() == b.sparsity(), ("Jacobian", "Hessian")[k]
        # the same expressions evaluated by compiled C and by the virtual machine: round-off only
        np.testing.assert_allclose(np.array(b.nonzeros()), np.array(a.nonzeros()), rtol=1e-9, atol=1e-9)
    # central differences of one interval, step 1e-6: truncation error ~ 1e-12 x third derivative
    z = [x_val[:nd], x_val[nd:nd * (degree + 1)], x_val[nd * (degree + 1):nd * (degree + 2)], 0.05, p_val]
    jac_native = np.hstack([np.array(b) for b in native.jacobian()(*z, native(*z))[:4]])
    flat = np.r_[z[0], z[1], z[2], z[3]]
    sizes = np.cumsum([0, nd, nd * degree, nd])

    def at(v):
        pieces = (v[:sizes[1]], v[sizes[1]:sizes[2]], v[sizes[2]:sizes[3]], v[-1])
        return np.array(native(*pieces, p_val)).ravel()

    fd = np.column_stack([(at(flat + 1e-6 * e) - at(flat - 1e-6 * e)) / 2e-6 for e in np.eye(len(flat))])
    np.testing.assert_allclose(jac_native, fd, rtol=1e-6, atol=1e-6)


def _refuse():
    raise AssertionError("the functions were built although an indexed library serves")


def test_an_indexed_library_is_loaded_without_building(tmp_path, monkeypatch):
    """``cached_functions`` builds and compiles once; then the index its sources' hash names
    serves the library without calling the builder. Another hash of the sources (any change to
    the model's code), an index whose library is gone, and an unreadable index each send it back
    to the builder, which the code's own hash then serves from the cache without compiling."""
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    x = np.array([0.1, -0.4, 2.0])
    expected = np.sin(x) * 1.5 + x @ x
    first = compiled.cached_functions("cachetest", "v1", _function, verbose=False)
    np.testing.assert_allclose(np.array(first["f"](x, 1.5)).ravel(), expected, rtol=1e-15)
    index, = tmp_path.glob("cachetest-*.index.json")
    again = compiled.cached_functions("cachetest", "v1", _refuse, verbose=False)
    np.testing.assert_allclose(np.array(again["f"](x, 1.5)).ravel(), expected, rtol=1e-15)
    assert again["f"].class_name() == "External"

    def no_compiler(*args, **kwargs):
        raise AssertionError("the compiler ran although the cache holds this code")
    monkeypatch.setattr(subprocess, "run", no_compiler)
    built = []

    def build():
        built.append(1)
        return _function()
    # another variant, another index
    compiled.cached_functions("cachetest", "v2", build, verbose=False)
    # the model's sources changed
    monkeypatch.setattr(compiled, "_sources_digest", lambda: "edited")
    compiled.cached_functions("cachetest", "v1", build, verbose=False)
    monkeypatch.undo()
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    monkeypatch.setattr(subprocess, "run", no_compiler)
    # an unreadable index is rewritten
    index.write_text("{not json")
    out = compiled.cached_functions("cachetest", "v1", build, verbose=False)
    np.testing.assert_allclose(np.array(out["f"](x, 1.5)).ravel(), expected, rtol=1e-15)
    assert compiled.cached_functions("cachetest", "v1", _refuse, verbose=False)
    # its library gone: built, and compiled again
    monkeypatch.undo()
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    for lib in tmp_path.glob("cachetest-*.so"):
        lib.unlink()
    compiled.cached_functions("cachetest", "v1", build, verbose=False)
    assert len(built) == 4
    assert len(list(tmp_path.glob("cachetest-*.so"))) == 1


def test_an_indexed_library_with_derivatives_keeps_them(tmp_path, monkeypatch):
    """``cached_with_derivatives`` loaded from its index still brings its own derivatives: an
    NLP's Jacobian of the loaded function equals the symbolic one's."""
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    fn = _function()["f"]
    compiled.cached_with_derivatives("cachetest", lambda: fn, verbose=False)
    loaded = compiled.cached_with_derivatives("cachetest", _refuse, verbose=False)
    assert loaded.class_name() == "External"
    x, p = ca.MX.sym("x", 3), ca.MX.sym("p")
    jac = ca.Function("j", [x, p], [ca.jacobian(loaded(x, p), x), ca.hessian(ca.sum1(loaded(x, p)), x)[0]])
    ref = ca.Function("r", [x, p], [ca.jacobian(fn(x, p), x), ca.hessian(ca.sum1(fn(x, p)), x)[0]])
    x0 = [0.1, -0.4, 2.0]
    for a, b in zip(jac(x0, 1.5), ref(x0, 1.5), strict=True):
        np.testing.assert_allclose(np.array(a), np.array(b), rtol=1e-14, atol=1e-14)


def test_a_read_only_cache_serves_without_an_index(tmp_path, monkeypatch):
    """A cache of compiled libraries that cannot be written (shared between machines, mounted
    read-only: here every file it would create is refused) still serves them: no index is
    written, and the functions are built to find them."""
    monkeypatch.setenv("TOYWALK_CACHE", str(tmp_path))
    monkeypatch.delenv("TOYWALK_JIT", raising=False)
    compiled.compile_functions("cachetest", _function(), verbose=False)

    def read_only(*args, **kwargs):
        raise OSError(30, "Read-only file system")
    monkeypatch.setattr(compiled.tempfile, "NamedTemporaryFile", read_only)
    monkeypatch.setattr(compiled.tempfile, "TemporaryDirectory", read_only)
    out = compiled.cached_functions("cachetest", "v1", _function, verbose=False)
    assert out["f"].class_name() == "External"
    assert not list(tmp_path.glob("*.index.json")) and not list(tmp_path.glob("*.tmp"))
