"""Native code: build C once with the system compiler, cache it, call it without copies.

Two kinds of C are built here:

* CasADi functions turned into C (:class:`NativeFunction`): the SQP's linearisation,
  generated from the symbolic model;
* the stage-structured QP solver written for this package (``solvers/_riccati_qp.c``).

Shared libraries are keyed by a hash of their source and the compiler flags, and cached in
``$PAPER_REPRO_CACHE`` or ``~/.cache/paper_repro``, so each is compiled once per machine.

**Built in the background** (:func:`build_in_background`). A controller needs several
libraries, and gcc spends seconds to a minute on each. They are compiled at once, one gcc per
core, while the caller goes on; a function waits for its own library only when it is first
called. So a controller flies its first steps after the smallest library is built, not after
all of them.

**One instruction set for every machine** (:func:`arch_flags`). The flights are chaotic where
the Euclidean metric chatters: a difference in the last bit of one multiply-add grows into a
different trajectory within seconds. Built with ``-march=native``, the compiler vectorises
for the CPU it runs on, and where it uses 512-bit vectors (AVX-512) it fuses multiply-adds in
other places than with 256-bit ones: a 15,000-step Euclidean passage flew the same built for
``x86-64-v3`` as for this project's Intel machine's own ``native``, and left it at step 1,624
built for ``x86-64-v4``. So the C is built for the fixed level ``x86-64-v3`` (AVX2 and FMA,
every x86-64 CPU since 2015) wherever the CPU has it: the same instructions, hence the same
flights, on every such machine. A CPU without it (or another architecture) gets
``-march=native``; its flights may differ from the committed evidence in their last digits,
and the golden flights say by how much.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import time
import warnings
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import casadi as ca
import numpy as np

from paper_repro.paths import atomic_text, sha256_of

FLAGS = ("-O3", "-fPIC", "-shared")
"""Flags of every build, besides :func:`arch_flags`."""
PORTABLE_ARCH = "x86-64-v3"
"""The instruction set the C is built for wherever the CPU has it."""
_V3_FEATURES = frozenset({"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "movbe", "abm"})
"""The ``/proc/cpuinfo`` flags of x86-64-v3 (``abm``: lzcnt), besides the v2 baseline."""
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


def compiler() -> str | None:
    """The C compiler to use (``$CC`` or gcc or cc), ``None`` when there is none."""
    return shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")


def cache_dir() -> Path:
    path = Path(os.environ.get("PAPER_REPRO_CACHE", Path.home() / ".cache" / "paper_repro"))
    path.mkdir(parents=True, exist_ok=True)
    return path


@functools.cache
def arch_flags() -> tuple[str, ...]:
    """``-march`` of every build on this machine (:func:`arch_flags_for` its CPU)."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        lines = []
    cpu = next((set(ln.split(":", 1)[1].split()) for ln in lines if ln.startswith("flags")),
               set())
    return arch_flags_for(os.uname().machine, cpu)


def arch_flags_for(machine: str, cpu_flags: set[str]) -> tuple[str, ...]:
    """``-march`` for a CPU of architecture ``machine`` (``os.uname().machine``) with the
    ``/proc/cpuinfo`` flags ``cpu_flags``: :data:`PORTABLE_ARCH` on an x86-64 CPU that has
    it (the same code, so the same flights, on every such machine), else ``-march=native``."""
    if machine == "x86_64" and _V3_FEATURES <= set(cpu_flags):
        return (f"-march={PORTABLE_ARCH}",)
    return ("-march=native",)


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
    flags = (*FLAGS, *arch_flags(), *flags)
    # A native build depends on the CPU; a portable one only on its flags.
    cpu = _cpu_tag() if "-march=native" in flags else b""
    digest = hashlib.sha256(source + key_extra + " ".join(flags).encode() + cpu)
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
                _write_digest(out, lib)
                os.replace(out, lib)
            finally:
                out.unlink(missing_ok=True)
    return lib


def build_jobs() -> int:
    """How many compilers run at once: ``$PAPER_REPRO_BUILD_JOBS``, else one per core this
    process may use."""
    value = os.environ.get("PAPER_REPRO_BUILD_JOBS")
    if value is not None:
        if not value.isdigit() or int(value) < 1:
            raise ValueError(f"PAPER_REPRO_BUILD_JOBS must be an integer >= 1, got {value!r}")
        return int(value)
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
        os.cpu_count() or 1)


_BUILDERS: dict[int, ThreadPoolExecutor] = {}
"""One pool of compiler threads per process (a forked child starts its own)."""


def build_in_background(name: str, source: bytes, key_extra: bytes = b"",
                        flags: tuple[str, ...] = ()) -> Future:
    """:func:`build_library` in a pool of :func:`build_jobs` threads; the future's result is
    the library's path. The threads only wait for gcc, so they run in parallel. A process that
    ends waits for the builds it started: what it compiled stays in the cache."""
    pool = _BUILDERS.get(os.getpid())
    if pool is None:
        pool = _BUILDERS[os.getpid()] = ThreadPoolExecutor(build_jobs(),
                                                           thread_name_prefix="gcc")
    return pool.submit(build_library, name, source, key_extra, flags)


class DamagedLibraryWarning(UserWarning):
    """A damaged compiled library was moved aside and built again."""


def load_library(name: str, source: bytes, key_extra: bytes = b"",
                 flags: tuple[str, ...] = ()) -> ctypes.CDLL:
    """:func:`build_library`, then load it. A library is loaded only when it matches the
    SHA-256 recorded when it was built (``<library>.sha256``); one that does not, or that
    the loader refuses (truncated, not a shared object), is moved aside to
    ``<library>.damaged`` with a :class:`DamagedLibraryWarning` and built again. A library of
    an older cache without a record is recorded once it loads."""
    lib = build_library(name, source, key_extra, flags)
    record = lib.with_name(f"{lib.name}.sha256")
    try:
        # Never hand the loader an unchecked file: mapping a truncated library can kill the
        # process (SIGBUS) instead of raising.
        if record.is_file():
            if record.read_text().strip() != sha256_of(lib):
                raise OSError("it does not match the SHA-256 recorded when it was built")
        elif not _whole_elf(lib):
            raise OSError("it is shorter than its ELF header says (truncated)")
        loaded = ctypes.CDLL(str(lib))
    except OSError as exc:
        aside = lib.with_name(f"{lib.name}.{os.getpid()}.damaged")
        try:
            os.replace(lib, aside)
        except FileNotFoundError:  # another process set it aside first
            pass
        record.unlink(missing_ok=True)
        warnings.warn(f"damaged compiled library {lib} ({exc}); moved to {aside.name}, "
                      "building it again", DamagedLibraryWarning, stacklevel=2)
        return ctypes.CDLL(str(build_library(name, source, key_extra, flags)))
    if not record.is_file():
        _write_digest(lib, lib)
    return loaded


def function_source(fn: ca.Function) -> bytes:
    """The C CasADi generates for ``fn``."""
    with tempfile.TemporaryDirectory() as tmp:
        gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
        gen.add(fn)
        return Path(gen.generate(str(Path(tmp)) + os.sep)).read_bytes()


def _write_digest(built: Path, lib: Path) -> None:
    """Record the SHA-256 of ``built`` as ``<lib>.sha256`` (atomically)."""
    atomic_text(lib.with_name(f"{lib.name}.sha256"), sha256_of(built) + "\n")


def _whole_elf(path: Path) -> bool:
    """The file is an ELF object at least as long as its section header table's end (the
    table is written last, so a truncated library fails this)."""
    with open(path, "rb") as f:
        head = f.read(64)
    if len(head) < 64 or head[:4] != b"\x7fELF":
        return False
    if head[4] != 2:  # 32-bit: e_shoff at 0x20 (4 bytes), e_shentsize/e_shnum at 0x2E/0x30
        shoff = int.from_bytes(head[0x20:0x24], "little")
        size, count = (int.from_bytes(head[i:i + 2], "little") for i in (0x2E, 0x30))
    else:
        shoff = int.from_bytes(head[0x28:0x30], "little")
        size, count = (int.from_bytes(head[i:i + 2], "little") for i in (0x3A, 0x3C))
    return Path(path).stat().st_size >= shoff + size * count




class NativeFunction:
    """A CasADi function compiled to C and called through ctypes on fixed buffers.

    ``inputs[i]`` and ``outputs[i]`` are NumPy arrays (column-major, as CasADi stores them)
    that stay at one address: fill the inputs in place, call, read the outputs. This skips
    CasADi's argument conversion, which costs more than small functions themselves. Every
    output must be dense.

    With ``background=True`` the library is compiled by :func:`build_in_background` and
    loaded at the first call (or :meth:`load`); the buffers exist at once.
    """

    def __init__(self, fn: ca.Function, background: bool = False):
        for i in range(fn.n_out()):
            if not fn.sparsity_out(i).is_dense():
                raise ValueError(f"output {fn.name_out(i)!r} of {fn.name()} must be dense")
        self.name = fn.name()
        self.inputs = [np.zeros(fn.size_in(i), order="F") for i in range(fn.n_in())]
        self.outputs = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
        self._source = function_source(fn)
        self._key_extra = ca.__version__.encode()
        self._fn = None
        self._build = (build_in_background(self.name, self._source, self._key_extra)
                       if background else None)
        self._builder = os.getpid()
        if not background:
            self.load()

    @property
    def source_bytes(self) -> int:
        """The size of the generated C, bytes."""
        return len(self._source)

    def load(self) -> float:
        """Load the library (waiting for its build, if one runs); the seconds spent waiting,
        0 once loaded."""
        if self._fn is not None:
            return 0.0
        start = time.perf_counter()
        if self._build is not None and (self._builder == os.getpid() or self._build.done()):
            self._build.result()  # a build error surfaces here, at the first call
        # (in a forked child the parent's build thread does not exist: load_library builds)
        lib = load_library(self.name, self._source, key_extra=self._key_extra)
        sz = [ctypes.c_longlong() for _ in range(4)]
        getattr(lib, f"{self.name}_work")(*[ctypes.byref(v) for v in sz])
        n_arg, n_res, n_iw, n_w = (v.value for v in sz)
        self._arg = (_DOUBLE_P * max(n_arg, len(self.inputs)))(
            *[a.ctypes.data_as(_DOUBLE_P) for a in self.inputs])
        self._res = (_DOUBLE_P * max(n_res, len(self.outputs)))(
            *[r.ctypes.data_as(_DOUBLE_P) for r in self.outputs])
        self._iw = (ctypes.c_longlong * max(n_iw, 1))()
        self._w = (ctypes.c_double * max(n_w, 1))()
        self._lib, self._fn = lib, getattr(lib, self.name)
        return time.perf_counter() - start

    def __call__(self) -> None:
        if self._fn is None:
            self.load()
        if self._fn(self._arg, self._res, self._iw, self._w, 0):
            raise RuntimeError(f"{self.name} failed")
