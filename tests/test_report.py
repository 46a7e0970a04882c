"""The numbers of the README and the book's pages are formatted from the committed tables
(paper_repro.evidence.readme)."""

import pytest

from paper_repro.evidence import formatting
from paper_repro.evidence import readme as report


def test_every_block_of_every_page_is_what_its_table_renders():
    found = report.page_blocks()  # raises when a block is on two pages
    assert set(found) == set(report.BLOCKS), "the pages' blocks and report.BLOCKS differ"
    stale = [f"{page.name}:{name}" for name, (page, body) in found.items()
             if name not in report.MACHINE_BLOCKS
             and report.blocks(report.render(page.read_text()))[name] != body]
    assert not stale, f"blocks out of date (python -m paper_repro readme): {stale}"


def test_render_replaces_only_block_bodies_and_names_unknown_blocks():
    text = "intro\n<!-- begin timeline -->\nold\n<!-- end timeline -->\noutro\n"
    new = report.render(text)
    assert new.startswith("intro\n<!-- begin timeline -->\n| candidate |")
    assert new.endswith("<!-- end timeline -->\noutro\n") and "old" not in new
    assert report.render(new) == new  # idempotent
    with pytest.raises(ValueError, match="'nonsense' is unknown"):
        report.render("<!-- begin nonsense -->\nx\n<!-- end nonsense -->")


def test_a_bar_inside_a_cell_is_escaped():
    table = formatting.markdown_table(["max |Δu|"], [["1 | 2"]])
    assert table.splitlines()[0] == "| max \\|Δu\\| |" and "1 \\| 2" in table
