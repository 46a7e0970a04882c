"""Native code: build C once with the system compiler, cache it, call it without copies.

Two kinds of C are built here:

* CasADi functions turned into C (:class:`NativeFunction`): the SQP's linearisation,
  generated from the symbolic model;
* the stage-structured QP solver written for this package (``_stage_qp.c``).

Shared libraries are keyed by a hash of their source, the compiler flags and the CPU (the
flags include ``-march=native``) and cached in ``$PAPER_REPRO_CACHE`` or
``~/.cache/paper_repro``, so each is compiled once per machine.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca
import numpy as np

FLAGS = ("-O3", "-march=native", "-fPIC", "-shared")
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


def compiler() -> str | None:
    """The C compiler to use (``$CC`` or gcc or cc), ``None`` when there is none."""
    return shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")


def cache_dir() -> Path:
    path = Path(os.environ.get("PAPER_REPRO_CACHE", Path.home() / ".cache" / "paper_repro"))
    path.mkdir(parents=True, exist_ok=True)
    return path


def _cpu_tag() -> bytes:
    """What -march=native depends on: the CPU model and its feature flags."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return os.uname().machine.encode()
    keep = [ln for ln in lines if ln.startswith(("model name", "flags"))][:2]
    return "\n".join(keep).encode()


def build_library(name: str, source: bytes, key_extra: bytes = b"",
                  flags: tuple[str, ...] = ()) -> Path:
    """Compile C ``source`` into a shared library (once per source, flags and CPU);
    ``key_extra`` also enters the cache key (e.g. the version of the code generator), and
    ``flags`` are added to :data:`FLAGS` (e.g. ``-DNAME=value``)."""
    cc = compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set CC or install gcc)")
    flags = (*FLAGS, *flags)
    digest = hashlib.sha256(source + key_extra + " ".join(flags).encode() + _cpu_tag())
    key = digest.hexdigest()[:16]
    lib = cache_dir() / f"{name}_{key}.so"
    if not lib.exists():
        # Built under a private name in the cache folder, then renamed: the rename is atomic,
        # so processes of a parallel sweep never load a half-written library.
        out = lib.with_name(f".{lib.name}.{os.getpid()}.tmp")
        with tempfile.TemporaryDirectory() as tmp:
            src = Path(tmp) / f"{name}.c"
            src.write_bytes(source)
            try:
                result = subprocess.run([cc, *flags, str(src), "-o", str(out), "-lm"],
                                        capture_output=True, text=True)
                if result.returncode:
                    raise RuntimeError(f"{cc} failed to build {name}:\n{result.stderr}")
                os.replace(out, lib)
            finally:
                out.unlink(missing_ok=True)
    return lib


def function_library(fn: ca.Function) -> Path:
    """The shared library of a CasADi function's generated C (built once, cached)."""
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
        gen.add(fn)
        source = Path(gen.generate(str(Path(tmp)) + os.sep)).read_bytes()
    return build_library(fn.name(), source, key_extra=ca.__version__.encode())


class NativeFunction:
    """A CasADi function compiled to C and called through ctypes on fixed buffers.

    ``inputs[i]`` and ``outputs[i]`` are NumPy arrays (column-major, as CasADi stores them)
    that stay at one address: fill the inputs in place, call, read the outputs. This skips
    CasADi's argument conversion, which costs more than small functions themselves. Every
    output must be dense.
    """

    def __init__(self, fn: ca.Function):
        for i in range(fn.n_out()):
            if not fn.sparsity_out(i).is_dense():
                raise ValueError(f"output {fn.name_out(i)!r} of {fn.name()} must be dense")
        self.name = fn.name()
        self._lib = ctypes.CDLL(str(function_library(fn)))
        self._fn = getattr(self._lib, self.name)
        self.inputs = [np.zeros(fn.size_in(i), order="F") for i in range(fn.n_in())]
        self.outputs = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        sz = [ctypes.c_longlong() for _ in range(4)]
        getattr(self._lib, f"{self.name}_work")(*[ctypes.byref(v) for v in sz])
        n_arg, n_res, n_iw, n_w = (v.value for v in sz)
        self._arg = (_DOUBLE_P * max(n_arg, fn.n_in()))(
            *[a.ctypes.data_as(_DOUBLE_P) for a in self.inputs])
        self._res = (_DOUBLE_P * max(n_res, fn.n_out()))(
            *[r.ctypes.data_as(_DOUBLE_P) for r in self.outputs])
        self._iw = (ctypes.c_longlong * max(n_iw, 1))()
        self._w = (ctypes.c_double * max(n_w, 1))()

    def __call__(self) -> None:
        if self._fn(self._arg, self._res, self._iw, self._w, 0):
            raise RuntimeError(f"{self.name} failed")
