"""Building, caching and calling the package's C code."""

import os

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


def test_the_build_is_for_one_instruction_set_wherever_the_cpu_has_it(cache, monkeypatch):
    """Every x86-64 CPU with AVX2 and FMA gets the same -march (so the same code and the same
    flights, and a library key that does not name the CPU); a CPU without them, or another
    architecture, its own."""
    v3 = {"sse4_2", "avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "movbe", "abm", "avx512f"}
    portable = (f"-march={_native.PORTABLE_ARCH}",)
    assert _native.arch_flags_for("x86_64", v3) == portable
    assert _native.arch_flags_for("x86_64", v3 - {"avx512f"}) == portable
    assert _native.arch_flags_for("x86_64", v3 - {"fma"}) == ("-march=native",)
    assert _native.arch_flags_for("aarch64", v3) == ("-march=native",)
    source = b"double thrice(double x) { return 3 * x; }\n"
    lib = _native.build_library("thrice", source)
    if _native.arch_flags() == portable:  # another CPU model would find the same library
        monkeypatch.setattr(_native, "_cpu_tag", lambda: b"another CPU")
        assert _native.build_library("thrice", source) == lib


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


@pytest.mark.parametrize("start", ["call", "load"])
def test_a_function_built_in_the_background_is_the_same_function(cache, start):
    """Compiled by the pool of gcc threads and loaded at the first call (or load()), a
    function gives the outputs of the one built in the foreground, from the same library;
    once loaded, load() waits for nothing."""
    x = ca.SX.sym("x", 4)
    fn = ca.Function("later", [x], [ca.densify(ca.exp(x) * ca.sumsqr(x))])
    background = _native.NativeFunction(fn, background=True)
    assert background.source_bytes == len(_native.function_source(fn))
    background.inputs[0][:, 0] = [0.3, -1.0, 2.0, 0.0]
    if start == "load":
        assert background.load() >= 0.0
    background()
    foreground = _native.NativeFunction(fn)
    foreground.inputs[0][:, 0] = background.inputs[0][:, 0]
    foreground()
    assert background.outputs[0].tobytes() == foreground.outputs[0].tobytes()
    assert background.load() == 0.0
    assert len(list(cache.glob("later_*.so"))) == 1


def test_a_failed_background_build_is_reported_at_the_first_call(cache):
    future = _native.build_in_background("broken_later", b"this is not C either\n")
    with pytest.raises(RuntimeError, match="failed to build broken_later"):
        future.result()


@pytest.mark.parametrize("value", ["0", "-2", "two", ""])
def test_the_number_of_build_jobs_is_checked(monkeypatch, value):
    monkeypatch.setenv("PAPER_REPRO_BUILD_JOBS", value)
    with pytest.raises(ValueError, match="PAPER_REPRO_BUILD_JOBS must be an integer >= 1"):
        _native.build_jobs()


def test_the_number_of_build_jobs_defaults_to_the_cores(monkeypatch):
    monkeypatch.delenv("PAPER_REPRO_BUILD_JOBS", raising=False)
    assert _native.build_jobs() == len(os.sched_getaffinity(0))
    monkeypatch.setenv("PAPER_REPRO_BUILD_JOBS", "3")
    assert _native.build_jobs() == 3


def test_sparse_outputs_are_refused(cache):
    x = ca.SX.sym("x", 2)
    fn = ca.Function("sparse", [x], [ca.diag(x)])
    with pytest.raises(ValueError, match="must be dense"):
        _native.NativeFunction(fn)
