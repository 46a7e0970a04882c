"""The pages a user reads: the citation file, the README's commands, the length of the
sentences, the images' paths and the Python blocks.

``python -m pytest tests/test_docs.py -s`` prints each page's sentence figures (median and
longest, in words)."""

from __future__ import annotations

import tomllib

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
