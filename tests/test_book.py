"""The book's builder: what it stages, and what it refuses before Sphinx starts. (The build
itself runs in tests/test_notebooks.py, from the notebooks those tests execute.)"""

import re

import pytest

from paper_repro.book import site
from paper_repro.studies.catalogue import STUDY_NOTEBOOKS


def test_a_missing_notebook_is_named_with_the_command_that_executes_it(tmp_path):
    with pytest.raises(ValueError) as info:
        site.stage(tmp_path / "executed", tmp_path / "src", quick=True)
    message = str(info.value)
    for name in site.notebook_names():
        assert f"  {name}: python -m paper_repro " in message
    assert "03_thrusts: python -m paper_repro reproduce --quick" in message
    for study, notebook in STUDY_NOTEBOOKS.items():
        assert f"{notebook}: python -m paper_repro study {study} --quick" in message
    assert "12_tuning: python -m paper_repro tune --quick" in message
    assert not (tmp_path / "src").exists()  # nothing staged


def test_every_notebook_and_every_page_is_in_a_table_of_contents():
    docs = site.docs_dir()
    pages = sorted(p for p in docs.rglob("*.md"))
    tocs = "\n".join(m for p in pages
                     for m in re.findall(r"```\{toctree\}(.*?)```", p.read_text(), re.S))
    entries = {line.strip().removeprefix("../") for line in tocs.splitlines()}
    for name in site.notebook_names():
        assert f"notebooks/{name}" in entries, f"{name} is in no toctree of docs/"
    for page in pages:
        rel = page.relative_to(docs).with_suffix("").as_posix()
        if rel == "index":
            continue
        leaf = rel.split("/")[-1]
        assert rel in entries or leaf in entries, f"docs/{rel}.md is in no toctree"


def test_without_strict_a_missing_notebook_is_its_source_saying_so(tmp_path):
    executed = tmp_path / "executed"
    executed.mkdir()
    lines = []
    src = site.stage(executed, tmp_path / "src", strict=False, log=lines.append)
    assert len(lines) == 1 and f"{len(site.notebook_names())} notebook(s)" in lines[0]
    import nbformat

    nb = nbformat.read(src / "notebooks" / "03_thrusts.ipynb", as_version=4)
    assert nb.cells[0].source.startswith("# ")
    assert "**Not executed on this machine**: `python -m paper_repro reproduce` runs it" in \
        nb.cells[0].source
    assert all(c.outputs == [] for c in nb.cells if c.cell_type == "code")


def test_mathjax_is_staged_with_the_pages(tmp_path):
    executed = tmp_path / "executed"
    executed.mkdir()
    for name in site.notebook_names():  # stand-ins: staging copies, it executes nothing
        (executed / f"{name}.ipynb").write_text("{}")
    src = site.stage(executed, tmp_path / "src")
    assert (src / "_static_book" / "mathjax" / site.MATHJAX).stat().st_size > 1e6
    assert (src / "conf.py").is_file() and (src / "index.md").is_file()
    assert sorted(p.stem for p in (src / "notebooks").glob("*.ipynb")) == site.notebook_names()
    assert (src / "figures" / "fig04_thrusts.png").is_file()
    # ... and beside the pages' folder, where a page of docs/theory/ finds them as in the
    # repository (../../figures/x.png)
    page = src / "theory" / "distance.md"
    assert (page.parent / "../../figures/tutorial_eta_sigma.png").resolve().is_file()
    assert not list((src / "figures").rglob("*.pdf"))


def test_the_browser_check_fails_a_notebook_page_without_a_figure(site_check, tmp_path):
    """A page that shows code and numbers but no figure fails, as does an image that does not
    load; a page whose output holds a loaded image passes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    site = tmp_path / "html"
    (site / "notebooks").mkdir(parents=True)
    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot([0, 1], [1, 0])
    fig.savefig(site / "notebooks" / "figure.png")
    plt.close(fig)
    page = ('<!doctype html><html><head><title>t</title><link rel="icon" href="data:,">'
            "</head><body>{}</body></html>")  # no icon to fetch: nothing answers 404 but ours
    for name in ("index", "reproduction"):
        (site / f"{name}.html").write_text(page.format("<p>a page</p>"))
    outputs = {"shown": '<div class="cell_output"><img src="figure.png" alt="f"></div>',
               "numbers": '<div class="cell_output"><pre>0.42</pre></div>',
               "broken": '<div class="cell_output"><img src="absent.png" alt="f"></div>'}
    for name, body in outputs.items():
        (site / "notebooks" / f"{name}.html").write_text(page.format(body))

    problems = site_check.check_site(site, tmp_path / "shots")

    def about(name):
        return [p for p in problems if p.startswith(f"notebooks/{name}.html")]

    assert about("shown") == []
    assert about("numbers") == ["notebooks/numbers.html: the page shows no figure (no image in "
                                "a cell's output)"]
    assert "notebooks/broken.html: image absent.png did not load" in about("broken")
    assert any("shows no figure" in p for p in about("broken"))
    assert not [p for p in problems if p.startswith(("index", "reproduction"))]
    assert len(list((tmp_path / "shots").glob("*.png"))) == 5  # every page, one screenshot
