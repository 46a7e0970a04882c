"""Building, caching and calling the package's C code."""

import casadi as ca
import numpy as np
import pytest

from paper_repro import _native

pytestmark = pytest.mark.skipif(_native.compiler() is None, reason="no C compiler")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PAPER_REPRO_CACHE", str(tmp_path))
    return tmp_path


def test_a_library_is_built_once_and_then_taken_from_the_cache(cache):
    source = b"double twice(double x) { return 2 * x; }\n"
    lib = _native.build_library("twice", source)
    assert lib.parent == cache and lib.exists()
    stamp = lib.stat().st_mtime_ns
    assert _native.build_library("twice", source) == lib
    assert lib.stat().st_mtime_ns == stamp  # not rebuilt
    other = _native.build_library("twice", source + b"/* changed */\n")
    assert other != lib  # another source, another key
    assert [p.name for p in cache.iterdir() if p.name.startswith(".")] == []  # no leftovers


def test_a_compiler_error_is_reported_with_its_message(cache):
    with pytest.raises(RuntimeError, match="failed to build broken"):
        _native.build_library("broken", b"this is not C\n")
    assert list(cache.iterdir()) == []


def test_native_function_matches_casadi(cache):
    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2, 2)
    fn = ca.Function("probe", [x, p], [ca.sin(x) * p[0, 1], ca.densify(ca.mtimes(p, p))])
    native = _native.NativeFunction(fn)
    xv, pv = np.array([0.1, -2.0, 3.0]), np.array([[1.0, 2.0], [3.0, 4.0]])
    native.inputs[0][:, 0] = xv
    native.inputs[1][:] = pv
    native()
    expected = [np.asarray(v).ravel(order="F") for v in fn(xv, pv)]
    for got, want in zip(native.outputs, expected):
        np.testing.assert_allclose(got, want, rtol=1e-15)


def test_sparse_outputs_are_refused(cache):
    x = ca.SX.sym("x", 2)
    fn = ca.Function("sparse", [x], [ca.diag(x)])
    with pytest.raises(ValueError, match="must be dense"):
        _native.NativeFunction(fn)
