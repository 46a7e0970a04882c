"""Point clouds read from scan files: NumPy arrays, text tables, PLY and PCD.

:func:`read_scan` returns the (m, 3) points of one file, in the file's own frame and units.
Every refusal is a ``ValueError`` that names the file and what is wrong with it.

=====================  ==============================================================
``.npy``               an (m, 3) array, or a structured array with fields x, y, z
``.npz``               an array ``points`` (m, 3), or arrays ``x``, ``y``, ``z``, or one
                       (m, 3) array under any name
``.csv .xyz .txt``     one point a line, columns split by commas, semicolons or spaces;
                       an optional header line naming the columns x, y, z; otherwise the
                       first three columns; lines starting with ``#`` are comments
``.ply``               the ``vertex`` element's x, y, z (ASCII or binary), read by plyfile
``.pcd``               the fields x, y, z (ASCII, binary or compressed), read by pypcd4
=====================  ==============================================================

PLY and PCD need the optional extra ``scans`` (:data:`SCANS_INSTALL`).
"""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import numpy as np

SCANS_INSTALL = 'python -m pip install -e ".[scans]" -c constraints.txt'
"""The command that installs the readers of PLY and PCD files (the extra ``scans``)."""


class _BadContent(ValueError):
    """A file parsed, but what it holds is not a scan (the readers' own refusals)."""


class MissingExtraError(ImportError, ValueError):
    """A reader of the optional extra ``scans`` is not installed. It is a ``ValueError`` too, so
    the command line reports it in one line, as any other refused input."""


def read_scan(path) -> np.ndarray:
    """The points of one scan file.

    Parameters
    ----------
    path : a file ending in one of :data:`SCAN_SUFFIXES` (case-insensitive).

    Returns
    -------
    (m, 3) float array, m ≥ 1, every coordinate finite, in the file's units.

    Raises
    ------
    ValueError : naming the file, when it is missing, has an unknown extension, cannot be
        parsed, has no x, y, z, holds no point or holds a non-finite coordinate.
    MissingExtraError : a ``.ply`` or ``.pcd`` file without the extra ``scans``.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"scan file {str(path)!r} does not exist (or is not a file)")
    suffix = path.suffix.lower()
    if suffix not in _READERS:
        raise ValueError(f"scan file {str(path)!r} has the unknown extension {suffix!r}; "
                         f"accepted: {', '.join(SCAN_SUFFIXES)}")
    reader = _READERS[suffix]
    try:
        points = reader(path)
    except MissingExtraError:
        raise
    except _BadContent as exc:
        raise ValueError(f"scan file {str(path)!r}: {exc}") from None
    except Exception as exc:  # a parser's own error (struct, EOF, pydantic, its own classes)
        first = (str(exc).strip().splitlines() or [""])[0]
        raise ValueError(f"scan file {str(path)!r} cannot be read as {suffix[1:].upper()}: "
                         f"{type(exc).__name__}: {first}") from None
    return _checked(path, points)


# --- the readers, one per format ---------------------------------------------------------------

def _read_npy(path: Path) -> np.ndarray:
    return _xyz_array(np.load(path, allow_pickle=False), "the array")


def _read_npz(path: Path) -> np.ndarray:
    with np.load(path, allow_pickle=False) as archive:
        names = list(archive.files)
        if "points" in names:
            return _xyz_array(archive["points"], "the array 'points'")
        if {"x", "y", "z"} <= set(names):
            return np.column_stack([np.ravel(archive[k]) for k in "xyz"])
        if len(names) == 1:
            return _xyz_array(archive[names[0]], f"the array {names[0]!r}")
    raise _BadContent(f"must hold an array 'points' (m, 3), arrays 'x', 'y', 'z', or a single "
                     f"(m, 3) array, got arrays {names}")


def _read_text(path: Path) -> np.ndarray:
    rows, columns = [], None
    with open(path, encoding="utf-8", errors="strict") as lines:
        for number, line in enumerate(lines, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = [f for f in re.split(r"[,;\s]+", text) if f]
            if columns is None and not rows and not _numeric(fields[0]):
                names = [f.strip("\"'").lower() for f in fields]
                if not {"x", "y", "z"} <= set(names):
                    raise _BadContent(f"the header line {number} must name columns x, y and z, "
                                     f"got {fields}")
                columns = [names.index(k) for k in "xyz"]
                continue
            take = columns or [0, 1, 2]
            if len(fields) <= max(take):
                raise _BadContent(f"line {number} has {len(fields)} column(s), needs x, y, z "
                                 f"(columns {[c + 1 for c in take]}): {text[:60]!r}")
            try:
                rows.append([float(fields[c]) for c in take])
            except ValueError:
                raise _BadContent(f"line {number} holds a value that is not a number: "
                                 f"{text[:60]!r}") from None
    return np.array(rows, float).reshape(-1, 3)


def _read_ply(path: Path) -> np.ndarray:
    plyfile = _optional("plyfile", path)
    data = plyfile.PlyData.read(str(path))
    elements = {e.name: e for e in data.elements}
    if "vertex" not in elements:
        raise _BadContent(f"has no 'vertex' element (has {sorted(elements)})")
    vertex = elements["vertex"]
    names = [p.name for p in vertex.properties]
    if not {"x", "y", "z"} <= set(names):
        raise _BadContent(f"its 'vertex' element must have the properties x, y and z, got "
                         f"{names}")
    return np.column_stack([np.asarray(vertex[k], float) for k in "xyz"])


def _read_pcd(path: Path) -> np.ndarray:
    pypcd4 = _optional("pypcd4", path)
    cloud = pypcd4.PointCloud.from_path(path)
    names = list(cloud.fields)
    if not {"x", "y", "z"} <= set(names):
        raise _BadContent(f"must have the fields x, y and z, got {names}")
    return np.asarray(cloud.numpy(("x", "y", "z")), float).reshape(-1, 3)


_READERS = {".npy": _read_npy, ".npz": _read_npz, ".csv": _read_text, ".xyz": _read_text,
            ".txt": _read_text, ".ply": _read_ply, ".pcd": _read_pcd}

SCAN_SUFFIXES = tuple(_READERS)
"""The extensions :func:`read_scan` accepts."""


# --- helpers -----------------------------------------------------------------------------------

def _optional(module: str, path: Path):
    """Import a reader of the extra ``scans`` at first use (the package runs without it)."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(
            f"scan file {str(path)!r}: reading {path.suffix.lower()} files needs the optional "
            f"extra 'scans' ({module} is not installed); install it with: {SCANS_INSTALL}"
        ) from None


def _xyz_array(array: np.ndarray, what: str) -> np.ndarray:
    """(m, 3) points of a plain (m, 3) array or of a structured array with fields x, y, z."""
    if array.dtype.names is not None:
        if not {"x", "y", "z"} <= set(array.dtype.names):
            raise _BadContent(f"{what} must have the fields x, y and z, got "
                             f"{list(array.dtype.names)}")
        return np.column_stack([np.ravel(array[k]).astype(float) for k in "xyz"])
    if array.ndim != 2 or array.shape[1] != 3:
        raise _BadContent(f"{what} must have the shape (m, 3) (columns x, y, z), got "
                         f"{array.shape}")
    if not np.issubdtype(array.dtype, np.number) or np.iscomplexobj(array):
        raise _BadContent(f"{what} must hold real numbers, got dtype {array.dtype}")
    return array.astype(float)


def _checked(path: Path, points: np.ndarray) -> np.ndarray:
    if len(points) == 0:
        raise ValueError(f"scan file {str(path)!r} holds no point")
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if len(bad):
        raise ValueError(f"scan file {str(path)!r} holds {len(bad)} point(s) with a non-finite "
                         f"coordinate (NaN or infinite), the first at index {bad[0]}")
    return points


def _numeric(text: str) -> bool:
    """True when ``text`` reads as a number ("nan" and "inf" too: the check of finite values
    refuses them later, naming the point)."""
    try:
        float(text)
    except ValueError:
        return False
    return True
