"""Argument types shared by the commands: integers and numbers with a stated accepted range,
positions, output directories checked before anything flies, and ``--set section.field=value``
for any field of the configuration."""

from __future__ import annotations

import argparse
import ast
import dataclasses
import json
import math
import tempfile
from pathlib import Path


def int_at_least(low: int):
    """An argparse type: an integer >= ``low``, with a message naming the accepted range."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be an integer >= {low}, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value

    return parse


positive_int = int_at_least(1)
non_negative_int = int_at_least(0)


def seed_list(text: str) -> list[int]:
    """An argparse type: scene seeds as ranges and single seeds joined by commas (``0-29``,
    ``2,3,5``, ``0-9,12``), each an integer >= 0; sorted, each seed once."""
    seeds = set()
    for part in text.split(","):
        lo, dash, hi = part.strip().partition("-")
        try:
            first, last = int(lo), int(hi) if dash else int(lo)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be seeds like 0-29 or 2,3,5 (integers >= 0), got {text!r}") from None
        if first < 0 or last < first:
            raise argparse.ArgumentTypeError(
                f"must be seeds like 0-29 or 2,3,5 (integers >= 0, ranges increasing), got "
                f"{text!r}")
        seeds.update(range(first, last + 1))
    return sorted(seeds)


def output_directory(option: str, text: str) -> Path:
    """Create the directory ``text`` (if new) and check that a file can be written into it,
    so that a run never flies and then fails to save; ``ValueError`` naming ``option``."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} must be a directory (existing or new), got the existing "
                         f"file {text!r}")
    try:  # permissions alone do not tell (root, read-only mounts): create and probe
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as exc:
        raise ValueError(f"{option} must be a writable directory, got {text!r} "
                         f"({exc.strerror or exc})") from None
    return path


def point(text: str) -> tuple[float, float, float]:
    """An argparse type: a position or offset ``x,y,z`` of three finite numbers, m."""
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(
            f"must be three finite numbers x,y,z (m, no spaces), got {text!r}")
    return values


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def setting(text: str) -> tuple[str, str, object]:
    """An argparse type: ``section.field=value`` for any field of
    :class:`~paper_repro.config.Config` (``distance.eta=0.2``, ``nmpc.q=[1,1,1,...]``).

    The value is read as JSON (numbers, ``true``, ``null``, lists), else as a Python literal
    (``True``, ``None``, tuples), else kept as text (``distance.metric=euclidean``); a list
    becomes a tuple, as in ``config.json``. Which names exist, and which values they accept,
    :func:`with_settings` checks.
    """
    name, equals, raw = text.partition("=")
    section, dot, field = name.strip().partition(".")
    if not (equals and dot and section and field):
        raise argparse.ArgumentTypeError(
            f"must be section.field=value (e.g. distance.eta=0.2), got {text!r}")
    try:
        value = json.loads(raw)
    except ValueError:
        try:
            value = ast.literal_eval(raw.strip())
        except (ValueError, SyntaxError):
            value = raw.strip()
    return section, field.strip(), tuple(value) if isinstance(value, list) else value


def with_settings(config, settings) -> object:
    """``config`` with the ``(section, field, value)`` of :func:`setting` (later ones win),
    each section rebuilt once and the whole checked once, by the dataclasses themselves: a
    value is accepted or refused exactly as in Python or a ``config.json``. An entry may carry
    a fourth item, how it was given (an option such as ``--window 3.5``), for the messages.

    Raises
    ------
    ValueError : an unknown section or field (naming it and the accepted ones), or a value the
        dataclasses refuse (their message, after the assignments that caused it).
    """
    changes: dict[str, dict] = {}
    given: dict[str, list[str]] = {}
    for section, field, value, *how in settings:
        label = how[0] if how else f"--set {section}.{field}={value!r}"
        sections = [f.name for f in dataclasses.fields(config)]
        if section not in sections:
            raise ValueError(f"{label}: unknown section {section!r}; accepted: "
                             f"{', '.join(sections)}")
        fields = [f.name for f in dataclasses.fields(getattr(config, section))]
        if field not in fields:
            raise ValueError(f"{label}: {section} has no field {field!r}; accepted: "
                             f"{', '.join(fields)}")
        changes.setdefault(section, {})[field] = value
        given.setdefault(section, []).append(label)
    parts = {}
    for section, fields in changes.items():
        try:
            parts[section] = dataclasses.replace(getattr(config, section), **fields)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"{', '.join(given[section])}: {section}.{exc}") from None
    try:
        return dataclasses.replace(config, **parts)
    except (ValueError, TypeError) as exc:
        every = ", ".join(g for section in given for g in given[section])
        raise ValueError(f"{every}: {exc}") from None
