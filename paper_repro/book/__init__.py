"""The book: the pages of ``docs/`` and the executed notebooks as one HTML site.

=================  ==================================================================
``site``           stage the pages, notebooks and figures; draw the study notebooks from the
                   committed tables; build them with Sphinx
=================  ==================================================================
"""

from paper_repro.book.site import (
    FIGURE_SUFFIXES,
    Drawn,
    book_dir,
    build,
    committed_folder,
    docs_dir,
    draw_from_tables,
    executing_command,
    notebook_names,
    stage,
)

__all__ = [
    "book_dir",
    "build",
    "committed_folder",
    "docs_dir",
    "draw_from_tables",
    "Drawn",
    "executing_command",
    "FIGURE_SUFFIXES",
    "notebook_names",
    "stage",
]
