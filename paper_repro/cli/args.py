"""Argument types shared by the commands: integers with a stated accepted range, and
output directories checked before anything flies."""

from __future__ import annotations

import argparse
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
