"""One OpenBLAS kernel for every flight.

NumPy (and CasADi, for IPOPT's linear solver) bundle OpenBLAS. At load time OpenBLAS picks
the kernels written for the CPU it finds (``SkylakeX`` with AVX-512, ``Haswell`` with AVX2
only), unless the variable ``OPENBLAS_CORETYPE`` names one. Two kernels add the same
products in different orders, so they round differently. Most flights absorb that last bit.
A flight whose solver makes a discrete choice on it (an active set, an iteration count) does
not: two CPUs that both run every instruction of the evidence can still fly apart.

So paper_repro asks OpenBLAS for one kernel, :data:`KERNEL`, through ``OPENBLAS_CORETYPE``,
before NumPy loads it. Every x86-64-v3 CPU runs it, the level the C is built for
(:func:`paper_repro._native.arch_flags`), so such CPUs fly the same flights. The variable
``PAPER_REPRO_BLAS`` overrides the choice: a kernel's name, or ``system`` to leave
``OPENBLAS_CORETYPE`` as the environment sets it. The pin acts on Linux x86-64 only, and
only if ``paper_repro`` (or this module) is imported before NumPy: ``python -m paper_repro``,
every benchmark script and the test suite do so. :func:`check_kernel` refuses to stamp
evidence made with a kernel other than the one asked for.
"""

from __future__ import annotations

import functools
import os
import platform

VARIABLE = "OPENBLAS_CORETYPE"
"""The environment variable OpenBLAS reads, once, when it loads."""

CHOICE = "PAPER_REPRO_BLAS"
"""The environment variable that overrides :func:`wanted_kernel`: a kernel's name, or
``"system"``."""

KERNEL = "Haswell"
"""The kernel asked for: the one OpenBLAS writes for AVX2 and FMA, which every x86-64-v3 CPU
runs, AVX-512 or not."""

NEEDS = frozenset({"avx2", "fma"})
"""The CPU flags :data:`KERNEL` needs."""

X86_KERNELS = ("Prescott", "Core2", "Penryn", "Dunnington", "Nehalem", "Atom", "Opteron",
               "Opteron_SSE3", "Barcelona", "Bobcat", "Nano", "Sandybridge", "Bulldozer",
               "Piledriver", "Steamroller", "Excavator", "Haswell", "Zen", "SkylakeX",
               "Cooperlake", "SapphireRapids")
"""The x86-64 kernels ``PAPER_REPRO_BLAS`` may name (OpenBLAS's own names for them)."""


@functools.cache
def cpu_flags() -> frozenset[str]:
    """The flags of this CPU as Linux lists them in ``/proc/cpuinfo`` (empty elsewhere)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    return frozenset(line.partition(":")[2].split())
    except OSError:
        pass
    return frozenset()


def _x86_64() -> bool:
    """Whether this machine is x86-64, where OpenBLAS's kernels are :data:`X86_KERNELS`."""
    return platform.machine() in ("x86_64", "AMD64")


def wanted_kernel(flags: frozenset[str] | None = None) -> str | None:
    """The kernel paper_repro asks for on a CPU with ``flags`` (this one by default):
    :data:`KERNEL` if it has :data:`NEEDS`, else ``None`` (another architecture, or an x86-64
    CPU below v3), where OpenBLAS chooses alone."""
    if flags is None:
        if platform.system() != "Linux" or not _x86_64():
            return None
        flags = cpu_flags()
    return KERNEL if NEEDS <= flags else None


def pin() -> str | None:
    """Set ``OPENBLAS_CORETYPE`` to ``PAPER_REPRO_BLAS`` if that names a kernel, to
    :func:`wanted_kernel` if it is unset; leave it alone if it is ``system``. Return the
    kernel asked of OpenBLAS (``None``: OpenBLAS chooses). A name OpenBLAS does not know
    (on x86-64) is refused, naming the variable."""
    choice = os.environ.get(CHOICE, "").strip()
    if choice and choice != "system" and _x86_64() and choice.lower() not in {
            k.lower() for k in X86_KERNELS}:
        raise ValueError(f"{CHOICE} must be 'system' or one of {', '.join(X86_KERNELS)}, "
                         f"got {choice!r}")
    kernel = wanted_kernel() if not choice else None if choice == "system" else choice
    if kernel is not None:
        os.environ[VARIABLE] = kernel
    return os.environ.get(VARIABLE)


@functools.cache
def numpy_kernel() -> str | None:
    """The kernel NumPy's OpenBLAS runs (``threadpoolctl``), or ``None`` if NumPy was built
    with another BLAS."""
    import numpy  # noqa: F401  (loads the BLAS that threadpoolctl inspects)
    from threadpoolctl import threadpool_info

    for lib in threadpool_info():
        if lib.get("internal_api") == "openblas" and "numpy" in lib.get("filepath", ""):
            return lib.get("architecture")
    return None


def other_kernel() -> str | None:
    """The kernel NumPy runs when it is not the one :func:`wanted_kernel` gives this CPU (it
    was overridden, or NumPy loaded first), else ``None``. A run flown with another kernel is
    cached under another key (:func:`paper_repro.studies.runs.run_key`)."""
    wanted, running = wanted_kernel(), numpy_kernel()
    if wanted is None or running is None or running.lower() == wanted.lower():
        return None
    return running


def check_kernel() -> None:
    """Raise ``RuntimeError`` if NumPy's OpenBLAS does not run the kernel asked for: NumPy was
    loaded before paper_repro could ask (module docstring), or this CPU cannot run it."""
    asked = os.environ.get(VARIABLE)
    running = numpy_kernel()
    if asked and running and running.lower() != asked.lower():
        raise RuntimeError(
            f"NumPy's OpenBLAS runs the {running} kernel, not {asked} ({VARIABLE}): either "
            "NumPy was imported before paper_repro (import paper_repro first, or set "
            f"{VARIABLE}={asked} in the environment), or this CPU cannot run {asked} (choose "
            f"another with {CHOICE}). Then make the evidence again.")


pin()
