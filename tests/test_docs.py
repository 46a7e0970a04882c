"""The pages a user reads: the citation file, the README's commands, the length of the
sentences, the images' paths and the Python blocks.

``python -m pytest tests/test_docs.py -s`` prints each page's sentence figures (median and
longest, in words)."""

from __future__ import annotations

import re
import tomllib

import pytest
import yaml

from paper_repro import paths

ROOT = paths.repo_root()

# --- CITATION.cff: the Citation File Format 1.2.0, checked by hand -------------------------
# (cffconvert, the format's own validator, pins jsonschema < 4 against the pinned 4.26.)

CFF_KEYS = {"abstract", "authors", "cff-version", "commit", "contact", "date-released", "doi",
            "identifiers", "keywords", "license", "license-url", "message",
            "preferred-citation", "references", "repository", "repository-artifact",
            "repository-code", "title", "type", "url", "version"}
"""Every key CFF 1.2.0 allows at the top level (the schema forbids any other)."""

PERSON_KEYS = {"address", "affiliation", "alias", "city", "country", "email", "family-names",
               "fax", "given-names", "name-particle", "name-suffix", "orcid", "post-code",
               "region", "tel", "website"}
ENTITY_KEYS = {"address", "alias", "city", "country", "date-end", "date-start", "email", "fax",
               "location", "name", "orcid", "post-code", "region", "tel", "website"}

REFERENCE_TYPES = {
    "art", "article", "audiovisual", "bill", "blog", "book", "catalogue", "conference",
    "conference-paper", "data", "database", "dictionary", "edited-work", "encyclopedia",
    "film-broadcast", "generic", "government-document", "grant", "hearing", "historical-work",
    "legal-case", "legal-rule", "magazine-article", "manual", "map", "multimedia", "music",
    "newspaper-article", "pamphlet", "patent", "personal-communication", "proceedings",
    "report", "serial", "slides", "software", "software-code", "software-container",
    "software-executable", "software-virtual-machine", "sound-recording", "standard",
    "statute", "thesis", "unpublished", "video", "website"}
"""The reference types of CFF 1.2.0."""


def cff_problems(cff) -> list[str]:
    """What in the parsed ``CITATION.cff`` breaks CFF 1.2.0's schema (empty when valid)."""
    if not isinstance(cff, dict):
        return ["the file is not a YAML mapping"]
    problems = [f"top-level key {k!r} is not in CFF 1.2.0" for k in sorted(set(cff) - CFF_KEYS)]
    if cff.get("cff-version") != "1.2.0":
        problems.append(f"cff-version must be the string '1.2.0', got {cff.get('cff-version')!r}")
    for key in ("message", "title"):
        if not (isinstance(cff.get(key), str) and cff[key].strip()):
            problems.append(f"{key} must be a non-empty string")
    if cff.get("type", "software") not in ("software", "dataset"):
        problems.append(f"type must be 'software' or 'dataset', got {cff['type']!r}")
    if "version" in cff and not isinstance(cff["version"], str | int | float):
        problems.append("version must be a string or a number")
    if "keywords" in cff and not all(isinstance(k, str) for k in cff["keywords"]):
        problems.append("keywords must be strings")
    problems += _author_problems(cff.get("authors"), "authors", persons_only=False)
    for i, ref in enumerate(cff.get("references", [])):
        where = f"references[{i}]"
        if not isinstance(ref, dict):
            problems.append(f"{where} must be a mapping")
            continue
        if ref.get("type") not in REFERENCE_TYPES:
            problems.append(f"{where}.type {ref.get('type')!r} is not a CFF 1.2.0 type")
        if not (isinstance(ref.get("title"), str) and ref["title"].strip()):
            problems.append(f"{where}.title must be a non-empty string")
        problems += _author_problems(ref.get("authors"), f"{where}.authors", persons_only=True)
    return problems


def _author_problems(authors, where: str, persons_only: bool) -> list[str]:
    """A non-empty list of persons (family-names and given-names, strings) or, unless
    ``persons_only``, entities (a name)."""
    if not (isinstance(authors, list) and authors):
        return [f"{where} must be a non-empty list"]
    problems = []
    for i, a in enumerate(authors):
        if not isinstance(a, dict):
            problems.append(f"{where}[{i}] must be a mapping")
        elif "name" in a and not persons_only:
            problems += [f"{where}[{i}]: {k!r} is not a key of an entity"
                         for k in sorted(set(a) - ENTITY_KEYS)]
        else:
            problems += [f"{where}[{i}]: {k!r} is not a key of a person"
                         for k in sorted(set(a) - PERSON_KEYS)]
            problems += [f"{where}[{i}] needs {k} (a non-empty string)"
                         for k in ("family-names", "given-names")
                         if not (isinstance(a.get(k), str) and a[k].strip())]
    return problems


def load_cff() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))


def test_citation_file_is_valid_cff_1_2_0():
    problems = cff_problems(load_cff())
    assert not problems, "CITATION.cff breaks CFF 1.2.0:\n  " + "\n  ".join(problems)


def test_the_cff_check_catches_what_the_schema_forbids():
    broken = {"cff-version": 1.2, "title": "", "authors": [{"given-names": "A."}],
              "colour": "red", "references": [{"type": "preprint", "authors": []}]}
    text = "\n".join(cff_problems(broken))
    for part in ("'colour'", "cff-version", "message", "title", "needs family-names",
                 "'preprint'", "references[0].title", "references[0].authors"):
        assert part in text, part


def test_citation_names_this_version_the_license_and_the_papers_authors():
    cff = load_cff()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert str(cff["version"]) == project["version"]
    assert cff["license"] == project["license"]["text"]
    assert "MIT License" in (ROOT / "LICENSE").read_text()
    paper = cff["references"][0]
    assert paper["title"] == "Point-to-Cloud NMPC with Smooth Avoidance Constraints"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    citing = readme[readme.index("## Citing"):]
    assert paper["title"].replace("NMPC", "{NMPC}") in citing
    for a in paper["authors"]:  # the README's BibTeX names the same authors
        assert f"{a['family-names']}, {a['given-names']}" in citing
    assert f"version = {{{project['version']}}}" in citing


# --- Short sentences ---------------------------------------------------------------------

MEDIAN_WORDS, MAX_WORDS, MAX_LINES = 22, 60, 250
"""A page's median sentence, its longest sentence (words) and its length (lines)."""

_ABBREVIATIONS = ("e.g.", "i.e.", "eq.", "Eq.", "Fig.", "Figs.", "fig.", "al.", "vs.", "cf.",
                  "Sec.", "approx.", "No.", "etc.")
_END = re.compile(r"(?<=[.!?])[\"')\]*_]*\s+")


def all_pages() -> list[str]:
    """README.md, environment.md and every page of ``docs/``, relative to the root."""
    docs = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs").rglob("*.md")
                  if "generated" not in p.parts)
    return ["README.md", "environment.md", *docs]


def prose(text: str) -> list[str]:
    """The paragraphs of a Markdown page, each on one line: fenced blocks, tables, headings,
    HTML comments and lines that are only an image left out; a list item starts a
    paragraph, without its marker."""
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    paragraphs, current, fence = [], [], None
    for line in text.splitlines():
        stripped = line.strip()
        if fence is not None:
            if stripped.startswith(fence):
                fence = None
            continue
        match = re.match(r"(`{3,}|~{3,}|:{3,})", stripped)
        if match:
            fence = match.group(1)
            paragraphs.append(" ".join(current))
            current = []
            continue
        skip = (not stripped or stripped.startswith(("|", "#", "$$"))
                or re.fullmatch(r"!\[[^\]]*\]\([^)]*\)", stripped))
        starts_item = re.match(r"([-*+]|\d+\.)\s", stripped)
        if skip or starts_item:
            paragraphs.append(" ".join(current))
            current = []
        if not skip:
            current.append(stripped[starts_item.end():] if starts_item else stripped)
    paragraphs.append(" ".join(current))
    return [p for p in paragraphs if p.strip()]


def sentences(paragraph: str) -> list[str]:
    """A paragraph cut after each '.', '!' or '?' that ends a word and is no abbreviation."""
    out, start = [], 0
    for match in _END.finditer(paragraph):
        before = paragraph[start:match.start()].split()
        if before and before[-1].lstrip("(") in _ABBREVIATIONS:
            continue
        out.append(paragraph[start:match.start()])
        start = match.end()
    out.append(paragraph[start:])
    return [s for s in out if word_count(s)]


def word_count(sentence: str) -> int:
    """Tokens between spaces that hold a letter or a digit."""
    return sum(1 for token in sentence.split() if re.search(r"\w", token))


def sentence_figures(page: str) -> tuple[float, int, int, str]:
    """Median and largest sentence length (words), line count, and the longest sentence."""
    import statistics

    text = (ROOT / page).read_text(encoding="utf-8")
    found = [s for p in prose(text) for s in sentences(p)]
    lengths = [word_count(s) for s in found]
    longest = max(found, key=word_count) if found else ""
    return (statistics.median(lengths) if lengths else 0.0, max(lengths, default=0),
            len(text.splitlines()), longest)


def test_sentences_are_cut_where_a_sentence_ends():
    paragraph = ("The NMPC is local, e.g. in front of a wall (Fig. 2). It stalls at 0.01 m/s. "
                 "`rti` flies. Does it?")
    assert [word_count(s) for s in sentences(paragraph)] == [12, 5, 2, 2]
    page = ("# Title\n\nOne two.\n\n| a | b |\n|---|---|\n\n```python\nx = 1. Y = 2\n```\n"
            "- Three\n  four.\n1. Five. Six\n")
    assert prose(page) == ["One two.", "Three four.", "Five. Six"]


@pytest.mark.parametrize("page", all_pages())
def test_sentences_are_short_and_pages_are_not_long(page):
    median, longest, lines, sentence = sentence_figures(page)
    print(f"\n{page}: median {median:g} words, max {longest}, {lines} lines")
    assert median <= MEDIAN_WORDS, f"{page}: the median sentence has {median:g} words"
    assert longest <= MAX_WORDS, f"{page}: a sentence of {longest} words: {sentence}"
    assert lines <= MAX_LINES, f"{page}: {lines} lines"


# --- Images: from the page's own folder on a repository browser, staged in the book --------

_IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")


def book_conf():
    """``docs/conf.py`` as a module (it is Sphinx's configuration, not a package module)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("book_conf", ROOT / "docs" / "conf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("page", all_pages())
def test_every_image_resolves_from_its_page_and_in_the_staged_book(page):
    from paper_repro.book.site import FIGURE_SUFFIXES

    text = (ROOT / page).read_text(encoding="utf-8")
    for target in _IMAGE.findall(text):
        if "://" in target:
            continue
        assert (ROOT / page).parent.joinpath(target).resolve().is_file(), \
            f"{page}: the image {target} is not there, relative to the page's folder"
    if not page.startswith("docs/"):
        return
    docname = page.removeprefix("docs/").removesuffix(".md")
    staged = book_conf().figures_from_the_book(docname, text)
    src = ROOT / "docs"  # the book stages docs/ as its source, figures/ inside it
    for target in _IMAGE.findall(staged):
        path = (src / docname).parent.joinpath(target).resolve()
        rel = path.relative_to(src.resolve())
        assert rel.parts[0] == "figures", f"{page}: {target} is not staged by the book"
        assert path.suffix in FIGURE_SUFFIXES
        assert paths.figures_dir().joinpath(*rel.parts[1:]).is_file(), f"{page}: {target}"


def test_the_book_moves_only_image_paths_into_the_repository_figures():
    move = book_conf().figures_from_the_book
    assert move("reproduction", "![a](../figures/x.png)") == "![a](figures/x.png)"
    assert move("studies/eta", "![a](../../figures/s/x.png)") == "![a](../figures/s/x.png)"
    text = "[table](../figures/x.csv) ![b](figures/y.png) ![c](../../figures/z.png)"
    assert move("reproduction", text) == text


# --- The README's commands ------------------------------------------------------------------


def test_the_readme_gives_every_command_one_line():
    from paper_repro.cli.parser import COMMANDS

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("## The commands"):]
    section = section[:section.index("\n## ")]
    listed = re.findall(r"^- `([a-z]+)`: ", section, re.M)
    assert listed == list(COMMANDS), f"the README lists {listed}, the CLI has {list(COMMANDS)}"


# --- The pages' Python blocks run as pasted --------------------------------------------------

NO_RUN = "<!-- no-run -->"
"""Put on the line before a ```python block that cannot run in a test (a long flight)."""


_BLOCK = re.compile(r"(?:^(<!-- no-run -->)\s*\n)?^```python\n(.*?)^```", re.S | re.M)


def python_blocks() -> list[tuple[str, int, str]]:
    """(page, line, code) of every ```python block not marked :data:`NO_RUN`."""
    found = []
    for page in all_pages():
        text = (ROOT / page).read_text(encoding="utf-8")
        for match in _BLOCK.finditer(text):
            if not match.group(1):
                found.append((page, text[:match.start(2)].count("\n") + 1, match.group(2)))
    return found


@pytest.mark.slow
@pytest.mark.parametrize("page, line, code", python_blocks(),
                         ids=[f"{p}:{n}" for p, n, _ in python_blocks()])
def test_every_python_block_of_the_pages_runs(page, line, code, tmp_path):
    import os
    import subprocess
    import sys

    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg", PAPER_REPRO_ROOT=str(ROOT))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, f"{page}, the block at line {line}:\n{proc.stderr[-3000:]}"


def test_the_blocks_are_found_and_a_marked_block_is_left_out():
    assert {p for p, _, _ in python_blocks()} >= {"README.md", "docs/usage.md",
                                                   "docs/own_model.md"}
    text = f"a\n{NO_RUN}\n```python\nx = 1\n```\n```python\ny = 2\n```\n"
    assert [m.group(2) for m in _BLOCK.finditer(text) if not m.group(1)] == ["y = 2\n"]


# --- Links into the glossary ----------------------------------------------------------------


def github_slug(heading: str) -> str:
    """The anchor GitHub (and MyST's ``myst_heading_anchors``) gives a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_every_link_into_the_glossary_names_one_of_its_headings():
    glossary = (ROOT / "docs" / "glossary.md").read_text(encoding="utf-8")
    anchors = {github_slug(h) for h in re.findall(r"^#{1,3} (.+)$", glossary, re.M)}
    assert len(anchors) == len(re.findall(r"^#{1,3} ", glossary, re.M)), "two equal headings"
    assert github_slug("RTI (real-time iteration)") == "rti-real-time-iteration"
    assert github_slug("Sampling time T_s") == "sampling-time-t_s"
    for page in all_pages():
        text = (ROOT / page).read_text(encoding="utf-8")
        for anchor in re.findall(r"glossary\.md#([^)\s`]+)\)", text):
            assert anchor in anchors, f"{page} links glossary.md#{anchor}, which is no heading"
