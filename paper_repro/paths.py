"""Where things live in the repository, so that notebooks work from any working directory.

The repository root is the folder above this package (the package is installed in editable
mode, ``pip install -e .``); set ``PAPER_REPRO_ROOT`` to point elsewhere, e.g. for a
non-editable install.

=====================  ===========================================================
``figures_dir()``      committed figures of the full mission and the summary CSV
``figures_dir(True)``  figures of a ``--quick`` run (git-ignored)
``results_dir()``      cached simulation results, one folder per config hash (git-ignored)
``notebooks_dir()``    the notebook sources (stored without outputs)
``executed_dir()``     executed copies written by papermill (git-ignored)
``study_dir(name)``    a study's table and figures, ``figures/studies/<name>``
``tuning_dir()``       the tuning study and its figures, ``figures/tuning``
``golden_dir()``       the golden flights, ``figures/golden``
``in_repo(path)``      a path as messages show it: relative to the root when inside it
=====================  ===========================================================
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from pathlib import Path

ROOT_ENV = "PAPER_REPRO_ROOT"


def repo_root() -> Path:
    """The repository root: ``$PAPER_REPRO_ROOT`` if set, else the folder above the package."""
    env = os.environ.get(ROOT_ENV)
    return Path(env).resolve() if env else Path(__file__).resolve().parents[1]


def figures_dir(quick: bool = False) -> Path:
    """``figures/`` (full mission, committed) or ``figures/quick/`` (git-ignored)."""
    base = repo_root() / "figures"
    return base / "quick" if quick else base


def results_dir() -> Path:
    """``results/``: the simulation cache (git-ignored)."""
    return repo_root() / "results"


def notebooks_dir() -> Path:
    """``notebooks/``: the notebook sources."""
    return repo_root() / "notebooks"


def executed_dir(quick: bool = False) -> Path:
    """``notebooks/executed/`` (or its ``quick/`` subfolder): papermill's executed copies."""
    base = notebooks_dir() / "executed"
    return base / "quick" if quick else base


def study_dir(name: str, quick: bool = False) -> Path:
    """Committed home of a study's table and figures: ``figures/studies/<name>`` (or
    ``figures/quick/studies/<name>``, git-ignored)."""
    return figures_dir(quick) / "studies" / name


def tuning_dir(quick: bool = False) -> Path:
    """Committed home of the tuning study and its figures: ``figures/tuning`` (or
    ``figures/quick/tuning``, git-ignored)."""
    return figures_dir(quick) / "tuning"


def golden_dir() -> Path:
    """``figures/golden/``: the committed golden flights and ``golden.json``."""
    return figures_dir() / "golden"


def in_repo(path) -> str:
    """``path`` relative to the repository root when it lies inside it, else absolute: how
    messages name a file."""
    p = Path(path).resolve()
    try:
        return str(p.relative_to(repo_root()))
    except ValueError:
        return str(p)


def atomic_write(path: Path, write: Callable[[Path], object]) -> None:
    """``write(tmp)`` into a temporary file beside ``path``, then rename it over ``path``: a
    reader never sees half a file. The temporary file ends with ``path``'s suffix, for writers
    that choose a format by it. The one atomic writer of the package."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    write(tmp)
    os.replace(tmp, path)


def atomic_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`)."""
    atomic_write(path, lambda tmp: tmp.write_text(text))


def json_hash(payload: dict) -> str:
    """The SHA-256 of ``payload`` as compact JSON with sorted keys (what is not JSON as its
    ``str``), hex: the one hash of a set of settings or of files."""
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def sha256_of(path: Path) -> str:
    """The SHA-256 of a file's bytes, hex (read in blocks of 1 MiB)."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()
