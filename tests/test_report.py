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


def test_the_lateral_pace_quoted_is_the_printed_set_ups_clock():
    """The pages' time constant is the lever table's printed row, and that row is what
    analysis.clock computes for the default configuration now."""
    from paper_repro.analysis.clock import clock
    from paper_repro.config import Config
    from paper_repro.evidence import beyond

    tau = clock(Config()).tau_lateral_s
    assert f"τ ≈ {tau:.0f} s" in beyond.lateral_pace()
    assert f"/{tau:.0f} s." in beyond.lateral_pace()


def test_the_levers_table_keeps_every_run_of_its_csv():
    """One row per lever and crossing set; its collision cells add up to the CSV's."""
    import re

    import pandas as pd

    from paper_repro import paths
    from paper_repro.evidence import beyond

    csv = pd.read_csv(paths.figures_dir() / "studies" / "moving_levers" / "levers.csv")
    rows = beyond.moving_levers().splitlines()[2:]
    groups = csv.groupby(["scenes", "lever"], sort=False)
    assert len(rows) == groups.ngroups
    for row, ((scenes, lever), g) in zip(rows, groups):
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        assert cells[:2] == [scenes, f"`{lever}`"]
        for cell, metric in zip(cells[3:5], ("smooth", "euclidean")):
            counts = [int(n) for n in re.match(r"([\d / ]+) of", cell)[1].split(" / ")]
            assert counts == g.loc[g["metric"] == metric, "collisions"].tolist()
        assert cells[6] == f"{g['completed'].sum()}/{g['runs'].sum()}"


def test_the_held_out_block_names_every_run_that_collides_or_does_not_complete():
    """Each crossing and run the sentences name is one of the table's, and every such run of
    the table is named."""
    import re

    import pandas as pd

    from paper_repro import paths
    from paper_repro.evidence import beyond

    runs = pd.read_csv(paths.figures_dir() / "studies" / "moving_heldout" / "table.csv")
    text = beyond.moving_heldout().split("\n\n", 1)[1]
    named = {}
    for part, sentence in zip(("collide", "ended"), text.split(". The runs")):
        for seed, inside in re.findall(r"crossing (\d+) \(([^)]*)\)", sentence):
            listed = inside.split(": ", 1)[1].split("; ")[0].split(", ")
            named.setdefault(part, set()).update((int(seed), *p.split()) for p in listed)
    hit = runs[runs["collision"].astype(bool)]
    ended = runs[runs["outcome"] != "completed"]
    for part, want in (("collide", hit), ("ended", ended)):
        assert named.get(part, set()) == {(int(r.scene_seed), r.prediction, r.metric)
                                          for r in want.itertuples()}, part
