"""The README's numbers are formatted from the committed tables (paper_repro.evidence.readme)."""

import pytest

from paper_repro.evidence import readme as report


def test_every_readme_block_is_what_its_table_renders():
    text = report.readme_path().read_text()
    found = report.blocks(text)
    assert set(found) == set(report.BLOCKS), "README blocks and report.BLOCKS differ"
    rendered = report.blocks(report.render(text))
    stale = [name for name in found
             if name not in report.MACHINE_BLOCKS and found[name] != rendered[name]]
    assert not stale, f"README blocks out of date (python -m paper_repro readme): {stale}"


def test_render_replaces_only_block_bodies_and_names_unknown_blocks():
    text = "intro\n<!-- begin timeline -->\nold\n<!-- end timeline -->\noutro\n"
    new = report.render(text)
    assert new.startswith("intro\n<!-- begin timeline -->\n| candidate |")
    assert new.endswith("<!-- end timeline -->\noutro\n") and "old" not in new
    assert report.render(new) == new  # idempotent
    with pytest.raises(ValueError, match="'nonsense' is unknown"):
        report.render("<!-- begin nonsense -->\nx\n<!-- end nonsense -->")


def test_a_bar_inside_a_cell_is_escaped():
    table = report.markdown_table(["max |Δu|"], [["1 | 2"]])
    assert table.splitlines()[0] == "| max \\|Δu\\| |" and "1 \\| 2" in table
