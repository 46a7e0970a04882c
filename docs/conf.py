"""Sphinx configuration of the book (``python -m paper_repro book``).

The builder (:mod:`paper_repro.book.site`) stages these pages, the executed notebooks and
the figures into one source folder and builds it with warnings as errors. Sphinx executes no
notebook: each shows the outputs its command gave it, or, for a study notebook not executed
here, those of the builder's drawing from the committed tables.

A page links its images from its own folder in the repository (``../figures/x.png`` from
``docs/``), so that they show on a repository browser. The staged folder holds the figures
one level down, beside the pages (``figures/x.png``): :func:`figures_from_the_book` moves
each image path up one folder as Sphinx reads the page.
"""

project = "paper_repro"
author = "the paper_repro authors"
copyright = "the paper_repro authors"  # noqa: A001 - Sphinx's name

extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.autosummary",
              "sphinx.ext.napoleon", "sphinx.ext.mathjax"]

nb_execution_mode = "off"          # the outputs are the executed copies' own
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3

autosummary_generate = True
autodoc_member_order = "bysource"
autodoc_typehints = "none"         # the docstrings give units and shapes
napoleon_numpy_docstring = True
napoleon_google_docstring = False

# MathJax 3 (SVG output, every TeX extension in one file) from the django-static-mathjax
# package, staged into _static_book/mathjax/ by the builder and served with the site: the
# formulas render without a network (Sphinx would load MathJax from a CDN).
html_static_path = ["_static_book"]
mathjax_path = "mathjax/tex-svg-full.js"

html_theme = "sphinx_book_theme"
html_context = {"default_mode": "light"}
html_title = "paper_repro"
html_favicon = "_static_book/favicon.png"
html_theme_options = {"show_toc_level": 2, "navigation_with_keys": False}
html_last_updated_fmt = None       # no date: a rebuild of the same sources is the same site
exclude_patterns = ["_build", "**.ipynb_checkpoints"]


# The docstrings write |Δu| and |k′ − k| as mathematicians do; reStructuredText would read a
# substitution there. Bars outside ``literals`` are escaped before autodoc parses them.
import re  # noqa: E402

_LITERAL = re.compile(r"(``.*?``)")


def _escape_bars(app, what, name, obj, options, lines):
    for i, line in enumerate(lines):
        if "|" in line and not line.lstrip().startswith(("|", "+")):
            lines[i] = "".join(part if part.startswith("``") else part.replace("|", r"\|")
                               for part in _LITERAL.split(line))


_IMAGE = re.compile(r"(!\[[^\]]*\]\()((?:\.\./)*)figures/")
"""A Markdown image whose path climbs to the repository's ``figures/``."""


def figures_from_the_book(docname: str, text: str) -> str:
    """``text`` of page ``docname`` with each image path into the repository's ``figures/``
    (one ``../`` more than the page's depth under ``docs/``) made to point at the staged
    ``figures/`` (one less). Other paths, and links that are not images, are left alone."""
    depth = docname.count("/")

    def staged(match):
        ups = match.group(2)
        return match.group(1) + ("../" * depth if ups == "../" * (depth + 1) else ups) + "figures/"

    return _IMAGE.sub(staged, text)


def _read_figures_from_the_book(app, docname, source):
    source[0] = figures_from_the_book(docname, source[0])


def setup(app):
    app.connect("autodoc-process-docstring", _escape_bars)
    app.connect("source-read", _read_figures_from_the_book)
