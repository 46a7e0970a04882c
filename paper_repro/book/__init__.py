"""The book: the pages of ``docs/`` and the executed notebooks as one HTML site.

=================  ==================================================================
``site``           stage the pages, notebooks and figures; build them with Sphinx
=================  ==================================================================
"""

from paper_repro.book.site import (
    FIGURE_SUFFIXES,
    book_dir,
    build,
    docs_dir,
    executing_command,
    notebook_names,
    stage,
)

__all__ = [
    "book_dir",
    "build",
    "docs_dir",
    "executing_command",
    "FIGURE_SUFFIXES",
    "notebook_names",
    "stage",
]
