"""The book: the pages of ``docs/`` and the executed notebooks, one HTML site.

    python -m paper_repro book             # after reproduce, the study commands and tune
    python -m paper_repro book --quick     # from their --quick runs (notebooks/executed/quick/)

:func:`build` stages one Sphinx source folder, ``build/book/src``: the pages of ``docs/``,
every notebook as ``reproduce``, ``study`` or ``tune`` executed it (outputs included) under
``notebooks/``, the committed figures under ``figures/`` and MathJax (so that the formulas
render without a network). It then runs Sphinx (myst-nb
reads the notebooks, the book theme draws the site) with warnings as errors into
``build/book/html``. Nothing is executed: a notebook that has not been executed is named
with the command that executes it, before Sphinx starts.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from paper_repro import paths
from paper_repro.studies.catalogue import STUDY_NOTEBOOKS
from paper_repro.studies.reproduce import NOTEBOOKS

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
          log=print) -> Path:
    """Copy the pages, the executed notebooks and the figures into ``src`` (emptied first).

    The figures go to ``src/figures`` and to ``figures`` beside ``src``: a page in a folder
    of ``docs/`` (``docs/theory/``) reaches them as it does in the repository
    (``../../figures/x.png``), so it renders the same on a repository browser and in the book.

    A notebook missing from ``executed``: with ``strict``, a ``ValueError`` naming every
    missing one and the command that executes it, before anything is copied; without, its
    source (no outputs) under a first cell that says so and names that command, and one
    ``log`` line listing them (a first look at the book after ``reproduce`` alone: the study
    commands take far longer)."""
    missing = [n for n in notebook_names() if not (executed / f"{n}.ipynb").is_file()]
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
        if name in missing:
            _stage_unexecuted(name, src / "notebooks" / f"{name}.ipynb",
                              executing_command(name, quick))
        else:
            shutil.copy2(executed / f"{name}.ipynb", src / "notebooks" / f"{name}.ipynb")
    figures = paths.figures_dir()
    beside = [] if (src.parent / "figures").resolve() == figures.resolve() else [src.parent]
    for path in sorted(figures.rglob("*")):
        rel = path.relative_to(figures)
        if path.suffix in FIGURE_SUFFIXES and rel.parts[0] != "quick":
            for into in (folder / "figures" for folder in (src, *beside)):
                (into / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(path, into / rel)
    return src


def _stage_unexecuted(name: str, out: Path, command: str) -> None:
    """The source of notebook ``name`` under a first cell saying it was not executed."""
    import nbformat

    nb = nbformat.read(paths.notebooks_dir() / f"{name}.ipynb", as_version=4)
    title, rest = (nb.cells[0].source.split("\n", 1) + [""])[:2]
    nb.cells[0].source = (f"{title}\n\n**Not executed on this machine**: `{command}` runs "
                          f"it; this page shows its code without outputs.\n{rest}")
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
    executed (see :func:`stage`). Sphinx's warnings are errors: a ``RuntimeError`` carries
    its output."""
    _require_book_stack()
    executed = Path(executed) if executed is not None else paths.executed_dir(quick)
    out = Path(out) if out is not None else book_dir()
    src = stage(executed, out / "src", quick, strict=strict, log=log)
    html = out / "html"
    log(f"book: {len(notebook_names())} notebooks from {executed}; building {html}")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q",
                           "-b", "html", str(src), str(html)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"sphinx-build failed ({proc.returncode}):\n{proc.stderr[-8000:]}")
    index = html / "index.html"
    log(f"book: {index}")
    return index
