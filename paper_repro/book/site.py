"""The book: the pages of ``docs/`` and the executed notebooks, one HTML site.

    python -m paper_repro book             # after reproduce (and, for their own flights, the
                                           # study commands and tune)
    python -m paper_repro book --quick     # from their --quick runs (notebooks/executed/quick/)

:func:`build` stages one Sphinx source folder, ``build/book/src``: the pages of ``docs/``,
every notebook as ``reproduce``, ``study`` or ``tune`` executed it (outputs included) under
``notebooks/``, the committed figures under ``figures/`` and MathJax (so that the formulas
render without a network). It then runs Sphinx (myst-nb
reads the notebooks, the book theme draws the site) with warnings as errors into
``build/book/html``.

A study notebook that its command has not executed here is drawn from the committed tables
(:func:`draw_from_tables`): papermill executes it on the committed study folder, with
``from_tables`` where it declares it (the flights it would fly are read from that folder), and
its figures go to ``build/book/drawn/``, never to ``figures/``. That takes seconds and flies
nothing. A notebook of ``reproduce`` that has not been executed is shown without outputs,
named with the command that executes it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from paper_repro import paths
from paper_repro.studies.catalogue import STUDY_NOTEBOOKS
from paper_repro.studies.reproduce import NOTEBOOKS

TUNING_NOTEBOOK = "12_tuning"
"""The notebook that ``python -m paper_repro tune`` executes on ``figures/tuning``."""

FIGURE_SUFFIXES = (".png", ".gif", ".svg")
"""What of ``figures/`` the pages may show (the PDFs, tables and arrays stay out)."""

MATHJAX = "tex-svg-full.js"
"""MathJax 3, SVG output with every TeX extension, one file: what the pages typeset with."""


def mathjax_file() -> Path:
    """MathJax as the django-static-mathjax package ships it (the ``book`` extra)."""
    import importlib.util

    spec = importlib.util.find_spec("mathjax")
    path = (Path(spec.submodule_search_locations[0]) / "static" / "mathjax" / "es5" / MATHJAX
            if spec is not None and spec.submodule_search_locations else None)
    if path is None or not path.is_file():
        raise ValueError("the book needs MathJax from the django-static-mathjax package: "
                         'python -m pip install -e ".[book]" -c constraints.txt')
    return path


def docs_dir() -> Path:
    """``docs/``: the book's pages and its Sphinx configuration."""
    return paths.repo_root() / "docs"


def book_dir() -> Path:
    """``build/book/`` (git-ignored): the staged sources and the site."""
    return paths.repo_root() / "build" / "book"


def executing_command(notebook: str, quick: bool = False) -> str:
    """The command that executes ``notebook`` into ``notebooks/executed/`` (``quick``: into
    its ``quick/`` folder)."""
    flag = " --quick" if quick else ""
    if notebook in {nb.name for nb in NOTEBOOKS}:
        return f"python -m paper_repro reproduce{flag}"
    study = {nb: name for name, nb in STUDY_NOTEBOOKS.items()}.get(notebook)
    if study is not None:
        return f"python -m paper_repro study {study}{flag}"
    return f"python -m paper_repro tune{flag}"


def notebook_names() -> list[str]:
    """Every notebook of ``notebooks/``, by name."""
    return sorted(p.stem for p in paths.notebooks_dir().glob("*.ipynb"))


def stage(executed: Path, src: Path, quick: bool = False, strict: bool = True,
          log=print, drawn: dict | None = None) -> Path:
    """Copy the pages, the executed notebooks and the figures into ``src`` (emptied first).

    The figures go to ``src/figures`` and to ``figures`` beside ``src``: a page in a folder
    of ``docs/`` (``docs/theory/``) reaches them as it does in the repository
    (``../../figures/x.png``), so it renders the same on a repository browser and in the book.

    ``drawn`` maps a notebook missing from ``executed`` to its :class:`Drawn` copy
    (:func:`draw_from_tables`), staged under a first cell that says what it was drawn from.
    Any other notebook missing from ``executed``: with ``strict``, a ``ValueError`` naming
    every missing one and the command that executes it, before anything is copied; without,
    its source (no outputs) under a first cell that says so and names that command, and one
    ``log`` line listing them."""
    drawn = drawn or {}
    missing = [n for n in notebook_names()
               if not (executed / f"{n}.ipynb").is_file() and n not in drawn]
    lines = [f"  {n}: {executing_command(n, quick)}" for n in missing]
    if missing and strict:
        raise ValueError(f"the book shows executed notebooks, and {executed} lacks "
                         f"{len(missing)} of them; execute them first:\n" + "\n".join(lines))
    if missing:
        log(f"book: {len(missing)} notebook(s) not executed, shown without outputs:\n"
            + "\n".join(lines))
    if src.exists():
        shutil.rmtree(src)
    shutil.copytree(docs_dir(), src, ignore=shutil.ignore_patterns("_build", "generated"))
    (src / "_static_book" / "mathjax").mkdir(parents=True, exist_ok=True)
    shutil.copy2(mathjax_file(), src / "_static_book" / "mathjax" / MATHJAX)
    (src / "notebooks").mkdir()
    for name in notebook_names():
        out = src / "notebooks" / f"{name}.ipynb"
        command = executing_command(name, quick)
        if (executed / f"{name}.ipynb").is_file():
            shutil.copy2(executed / f"{name}.ipynb", out)
        elif name in drawn:
            folder = paths.in_repo(committed_folder(name))
            _stage_with_note(drawn[name].notebook, out,
                             f"**Drawn from the committed tables** in `{folder}`: nothing was "
                             f"flown for this page. `{command}` flies the study again and "
                             "draws the page from its own tables.")
        else:
            _stage_with_note(paths.notebooks_dir() / f"{name}.ipynb", out,
                             f"**Not executed on this machine**: `{command}` runs it; this "
                             "page shows its code without outputs.")
    figures = paths.figures_dir()
    beside = [] if (src.parent / "figures").resolve() == figures.resolve() else [src.parent]
    for path in sorted(figures.rglob("*")):
        rel = path.relative_to(figures)
        if path.suffix in FIGURE_SUFFIXES and rel.parts[0] != "quick":
            for into in (folder / "figures" for folder in (src, *beside)):
                (into / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, into / rel)
    return src


@dataclass(frozen=True)
class Drawn:
    """A study notebook executed on its committed folder by :func:`draw_from_tables`.

    Attributes
    ----------
    notebook : the executed copy, ``<out>/<name>.ipynb``.
    figures : where it wrote its figures and tables, ``<out>/<name>/``.
    differing : the files it wrote whose committed namesakes in the study folder have other
        bytes (empty when the drawing is the committed one).
    reused : the copy of an earlier call, made from the same notebook, tables and code.
    """

    notebook: Path
    figures: Path
    differing: tuple[str, ...]
    reused: bool = False


def committed_folder(notebook: str) -> Path | None:
    """The committed folder a study notebook draws from: ``figures/studies/<study>``, or
    ``figures/tuning`` for ``12_tuning``; ``None`` for a notebook of ``reproduce``."""
    if notebook == TUNING_NOTEBOOK:
        return paths.tuning_dir()
    study = {nb: name for name, nb in STUDY_NOTEBOOKS.items()}.get(notebook)
    return paths.study_dir(study) if study is not None else None


def draw_from_tables(names, out: Path, log=print, workers: int | None = None) -> dict:
    """Execute each study notebook of ``names`` on its committed folder; returns
    ``{name: Drawn}``.

    The notebook gets that folder (``study_dir``, or ``tuning_dir``), ``figures_dir`` =
    ``out/<name>/`` and, where it declares it, ``from_tables=True``: the rows and figures of the
    flights it would fly or load are read from the folder. Nothing is flown and nothing under
    ``figures/`` is written. A copy is reused while the notebook, the folder's files and the
    package's code are those it was drawn from. ``workers``: notebooks at once (default one
    per core). A ``ValueError`` names a notebook that is not a study notebook or whose folder
    is missing, before anything is executed.
    """
    from concurrent.futures import ThreadPoolExecutor

    names = list(names)
    for name in names:
        folder = committed_folder(name)
        if folder is None:
            raise ValueError(f"{name} is not a study notebook; study notebooks: "
                             f"{sorted([*STUDY_NOTEBOOKS.values(), TUNING_NOTEBOOK])}")
        if not folder.is_dir():
            raise ValueError(f"{name} draws from {folder}, which does not exist: "
                             f"{executing_command(name)} makes it")
    if not names:
        return {}
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    code = _code_digest()
    n = max(1, min(len(names), workers or os.cpu_count() or 1))
    with ThreadPoolExecutor(n) as pool:
        drawn = dict(zip(names, pool.map(lambda name: _draw(name, out, code), names)))
    reused = [n for n, d in drawn.items() if d.reused]
    log(f"book: {len(drawn)} study notebook(s) drawn from the committed tables into "
        f"{paths.in_repo(out)} ({len(reused)} reused), nothing flown")
    for name, d in drawn.items():
        if d.differing:
            log(f"book: {name} drew {len(d.differing)} file(s) unlike the committed ones in "
                f"{paths.in_repo(committed_folder(name))}: {', '.join(d.differing)}")
    return drawn


def _draw(name: str, out: Path, code: str) -> Drawn:
    """One notebook of :func:`draw_from_tables` (a thread's task)."""
    from paper_repro.studies.reproduce import declared_parameters, execute_notebook, notebook_path

    folder, figures = committed_folder(name), out / name
    source = notebook_path(name)
    params = {"tuning_dir" if name == TUNING_NOTEBOOK else "study_dir": str(folder),
              "figures_dir": str(figures)}
    if "from_tables" in declared_parameters(source):
        params["from_tables"] = True
    digest = hashlib.sha256(code.encode())
    for path in [source, *sorted(p for p in folder.rglob("*") if p.is_file())]:
        digest.update(paths.in_repo(path).encode() + path.read_bytes())
    digest.update(repr(sorted(params.items())).encode())
    key, notebook = out / f"{name}.key", out / f"{name}.ipynb"
    reused = key.is_file() and key.read_text() == digest.hexdigest() and notebook.is_file()
    if not reused:
        key.unlink(missing_ok=True)
        if figures.exists():
            shutil.rmtree(figures)
        figures.mkdir(parents=True)
        execute_notebook(source, notebook, params)
        key.write_text(digest.hexdigest())
    differing = tuple(p.name for p in sorted(figures.iterdir()) if p.is_file()
                      and (folder / p.name).is_file()
                      and p.read_bytes() != (folder / p.name).read_bytes())
    return Drawn(notebook, figures, differing, reused)


def _code_digest() -> str:
    """SHA-256 of the package's Python sources: a drawn copy is as old as the code."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*.py")):
        digest.update(str(path.relative_to(package)).encode() + path.read_bytes())
    return digest.hexdigest()


def _stage_with_note(notebook: Path, out: Path, note: str) -> None:
    """``notebook`` copied to ``out`` with ``note`` under the title of its first cell."""
    import nbformat

    nb = nbformat.read(notebook, as_version=4)
    title, rest = (nb.cells[0].source.split("\n", 1) + [""])[:2]
    nb.cells[0].source = f"{title}\n\n{note}\n{rest}"
    nbformat.write(nb, out)


def _require_book_stack() -> None:
    """The ``book`` extra, checked before anything is staged."""
    import importlib.util

    absent = [m for m in ("sphinx", "myst_nb", "sphinx_book_theme")
              if importlib.util.find_spec(m) is None]
    if absent:
        raise ValueError(f"the book needs {', '.join(absent)}: "
                         'python -m pip install -e ".[book]" -c constraints.txt')


def build(quick: bool = False, executed: Path | None = None, out: Path | None = None,
          log=print, strict: bool = False) -> Path:
    """Stage and build the site; returns its ``index.html``. ``executed``: where the executed
    notebooks are (default :func:`paper_repro.paths.executed_dir`); ``out``: the book's
    folder (default :func:`book_dir`); ``strict``: refuse to build without every notebook
    executed by its command (see :func:`stage`). Without ``strict``, a study notebook missing
    from ``executed`` is drawn from the committed tables into ``out/drawn``
    (:func:`draw_from_tables`). Sphinx's warnings are errors: a ``RuntimeError`` carries its
    output."""
    _require_book_stack()
    executed = Path(executed) if executed is not None else paths.executed_dir(quick)
    out = Path(out) if out is not None else book_dir()
    drawn = {}
    if not strict:
        t0 = time.perf_counter()
        drawable = [n for n in notebook_names() if not (executed / f"{n}.ipynb").is_file()
                    and committed_folder(n) is not None and committed_folder(n).is_dir()]
        drawn = draw_from_tables(drawable, out / "drawn", log=log)
        if drawn:
            log(f"book: drawn in {time.perf_counter() - t0:.1f} s")
    src = stage(executed, out / "src", quick, strict=strict, log=log, drawn=drawn)
    html = out / "html"
    log(f"book: {len(notebook_names())} notebooks from {executed}"
        + (f" and {out / 'drawn'}" if drawn else "") + f"; building {html}")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q",
                           "-b", "html", str(src), str(html)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"sphinx-build failed ({proc.returncode}):\n{proc.stderr[-8000:]}")
    index = html / "index.html"
    log(f"book: {index}")
    return index
