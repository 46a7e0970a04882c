"""The committed evidence: the golden flights every evidence set is stamped with, and the tables
of the README and the book formatted from the committed tables.

=================  ==================================================================
``sets``           every evidence set and the command that makes it
``golden``         the golden flights and the stamps every evidence set carries
``regenerate``     the stale sets made again, one job per core, the speed tables last
``readme``         the tables of the README and the book, from the committed ones
``beyond``         those of the studies beyond the paper (map, guide, moving regions, tuning)
``hardware``       those of the flights against RotorPy (agreement, margins, cells)
``formatting``     how those tables write a rate, a share, a ratio, a time
=================  ==================================================================
"""

from paper_repro.evidence.formatting import markdown_table
from paper_repro.evidence.golden import (
    GOLDEN_FLIGHTS,
    INPUT_TOLERANCE,
    POSITION_TOLERANCE,
    GoldenFlight,
    check_golden,
    command_line,
    fly_golden,
    golden_hash,
    recomputed_golden_hash,
    set_hash,
    sha256_of,
    stale_evidence,
    stamp,
    stamped_hash,
    write_golden,
)
from paper_repro.evidence.readme import (
    BLOCKS,
    blocks,
    page_blocks,
    page_paths,
    readme_path,
    render,
)
from paper_repro.evidence.sets import EVIDENCE_SETS, SETS, EvidenceSet

__all__ = [
    "BLOCKS",
    "blocks",
    "check_golden",
    "command_line",
    "EVIDENCE_SETS",
    "EvidenceSet",
    "fly_golden",
    "GOLDEN_FLIGHTS",
    "golden_hash",
    "GoldenFlight",
    "INPUT_TOLERANCE",
    "markdown_table",
    "page_blocks",
    "page_paths",
    "POSITION_TOLERANCE",
    "readme_path",
    "recomputed_golden_hash",
    "render",
    "set_hash",
    "SETS",
    "sha256_of",
    "stale_evidence",
    "stamp",
    "stamped_hash",
    "write_golden",
]
