"""The run cache: one closed-loop run described as data, flown once, stored atomically.

A :class:`RunSpec` is a small picklable value (a name, a full :class:`~paper_repro.config.Config`,
a step limit and labels for tables). Its :attr:`RunSpec.key` is the SHA-256 of the
configuration, the step limit and the fingerprint of the scene the configuration builds, so:

* the same spec always lands in the same folder ``<results>/<name>-<key[:12]>/``, and a second
  request only loads it (``reproduce`` redraws, an interrupted study redoes only what is
  missing);
* a changed parameter, or a scene generator that now builds other clouds, gives a new folder;
* a change of code that moves a flight changes the golden hash
  (:func:`paper_repro.evidence.golden.golden_hash`, part of the key) once the golden flights are
  written again, and every cached run is retired with it: nothing flown by older code is
  redrawn as if it were this code's. ``force=True`` flies again regardless.

:func:`ensure_result` writes a result into a private ``.partial`` folder and renames it into
place, so a crash, a killed worker or two workers racing on one spec never leave a folder that
looks complete. Both ``reproduce`` and ``study`` go through here.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from paper_repro import paths
from paper_repro.config import Config
from paper_repro.paths import atomic_text, json_hash

HASH_LENGTH = 12
"""Hex digits of the run key kept in a cache folder's name."""


@dataclass(frozen=True)
class RunSpec:
    """One closed-loop run: ``config`` flown for at most ``max_steps`` steps.

    Attributes
    ----------
    name : readable prefix of the cache folder (``paper-smooth``, ``mc-euclidean-s17``).
    config : the full configuration; its ``simulation`` part names the scene (scenario, seed)
        and the run kind.
    max_steps : step limit (one step is T_s).
    labels : ``(column, value)`` pairs shown in study tables (e.g. ``("eta", 0.3)``); they do
        not enter the key.
    """

    name: str
    config: Config
    max_steps: int
    labels: tuple = field(default=(), compare=False)

    def __post_init__(self):
        if not (isinstance(self.max_steps, int) and self.max_steps >= 1):
            raise ValueError(f"max_steps must be an integer >= 1, got {self.max_steps!r}")
        if not self.name or "/" in self.name:
            raise ValueError(f"name must be a non-empty folder name without '/', got "
                             f"{self.name!r}")

    def scene(self):
        """The scene this spec flies, built from ``config.simulation`` (scenario, seed, pace)."""
        from paper_repro.world.scenarios import mission_scene

        return mission_scene(self.config.simulation)

    @functools.cached_property
    def key(self) -> str:
        """SHA-256 (hex) of the configuration, ``max_steps`` and the scene's fingerprint
        (computed once per spec: building a random scene takes milliseconds to a second)."""
        return run_key(self.config, self.max_steps, self.scene().fingerprint())

    def directory(self, results_dir=None) -> Path:
        """Cache folder ``<results_dir>/<name>-<key[:12]>`` (``results/`` by default)."""
        base = Path(results_dir) if results_dir is not None else paths.results_dir()
        return base / f"{self.name}-{self.key[:HASH_LENGTH]}"


def run_key(config: Config, max_steps: int, scene_fingerprint: str) -> str:
    """SHA-256 (hex) of a run: ``config.key_dict()`` (:data:`~paper_repro.config_history.ADDED`),
    ``max_steps``, the scene fingerprint and the golden hash of the layer the run uses
    (:func:`~paper_repro.evidence.golden.layer_of`: the code's behaviour); and the OpenBLAS
    kernel, only when it is not the one :mod:`paper_repro._blas` asks for (so runs flown
    with another kernel never mix with the others)."""
    from paper_repro import _blas
    from paper_repro.evidence.golden import golden_hash, layer_of

    key = {"config": config.key_dict(), "max_steps": int(max_steps),
           "scene": scene_fingerprint, "golden": golden_hash(layer_of(config))}
    if (kernel := _blas.other_kernel()) is not None:
        key["blas"] = kernel
    return json_hash(key)


def rekey(results_dir=None) -> dict:
    """Move each cached run to the folder today's code keys it by, after a change of the
    configuration's layout that moves no flight (a setting added with a default, or moved to
    another part, :data:`~paper_repro.config_history.MOVED`): the cache is kept instead of
    flown again.

    A folder ``<name>-<key>`` is moved only when ``key`` is proven to be its run's key *as
    computed when it was written*: the SHA-256 of its stored configuration (as saved; with the
    step limit of the config or the default one), its stored scene fingerprint and today's
    golden hash. A result flown by code whose golden flights differ does not pass that test and
    stays where it is (today's code will fly its run again). A moved folder's ``config.json``
    is rewritten in today's layout, with its manifest.

    A folder whose run already has a folder under today's key (flown again meanwhile) is left
    as it is, and so is a damaged one (:func:`usable_or_set_aside` deals with those).

    Returns the counts ``{"moved", "current", "unproven", "duplicate", "damaged"}``.
    """
    from paper_repro.evidence.golden import golden_hash, layer_of
    from paper_repro.sim.result import DamagedResult, verify_result, write_manifest

    root = Path(results_dir) if results_dir is not None else paths.results_dir() / "runs"
    default_steps = Config().simulation.max_steps
    counts = {"moved": 0, "current": 0, "unproven": 0, "duplicate": 0, "damaged": 0}
    for d in sorted(p for p in root.iterdir() if p.is_dir()) if root.is_dir() else ():
        name, _, key = d.name.rpartition("-")
        if len(key) != HASH_LENGTH or not (d / "config.json").is_file():
            continue
        try:
            verify_result(d)
        except DamagedResult:
            counts["damaged"] += 1
            continue
        payload = json.loads((d / "config.json").read_text())
        saved, scene = payload["config"], payload["scene"]["fingerprint"]
        steps = saved["simulation"]["max_steps"]
        golden = golden_hash(layer_of(Config.from_dict(saved)))
        written = None
        for spec_steps in dict.fromkeys((steps, default_steps)):
            candidate = json.loads(json.dumps(saved))
            candidate["simulation"]["max_steps"] = spec_steps
            # keyed as saved (code before ADDED), or as Config.key_dict keys it (today's)
            for form in (candidate, _as_keyed(candidate)):
                if json_hash({"config": form, "max_steps": int(steps), "scene": scene,
                              "golden": golden})[:HASH_LENGTH] == key:
                    written = candidate
        if written is None:
            counts["unproven"] += 1
            continue
        new = run_key(Config.from_dict(written), steps, scene)[:HASH_LENGTH]
        today = json.loads(json.dumps(Config.from_dict(saved).to_dict(), default=str))
        if new == key and today == saved:
            counts["current"] += 1
            continue
        target = d.with_name(f"{name}-{new}")
        if target != d and target.exists():  # flown again meanwhile: that copy is the cache's
            counts["duplicate"] += 1
            continue
        payload["config"] = today
        atomic_text(d / "config.json", json.dumps(payload, indent=2, default=str) + "\n")
        write_manifest(d)
        if target != d:
            os.replace(d, target)
        counts["moved"] += 1
    return counts


def _as_keyed(config: dict) -> dict:
    """A stored configuration as :meth:`Config.key_dict` hashes it
    (:func:`~paper_repro.config_history.keyed`)."""
    from paper_repro.config_history import keyed

    return keyed(json.loads(json.dumps(config)), Config().to_dict())


def is_cached(directory) -> bool:
    """A complete, intact saved result lives in ``directory`` (its files match its manifest,
    see :func:`~paper_repro.sim.result.verify_result`)."""
    from paper_repro.sim.result import DamagedResult, verify_result

    try:
        verify_result(Path(directory))
    except DamagedResult:
        return False
    return True


class DamagedCacheWarning(UserWarning):
    """A damaged cache entry was moved aside and its run flown again."""


def usable_or_set_aside(directory, warn=None) -> bool:
    """True when ``directory`` holds an intact result. A folder there that is not one
    (truncated, not valid JSON, an array missing, changed since saved) is moved aside to
    ``<folder>.damaged`` (never deleted), ``warn`` gets one line naming it and what is wrong
    (default: a :class:`DamagedCacheWarning`), and the answer is False: fly the run again."""
    from paper_repro.sim.result import DamagedResult, verify_result

    d = Path(directory)
    if not d.exists():
        return False
    try:
        verify_result(d)
        return True
    except DamagedResult as exc:
        aside = d.with_name(f"{d.name}.damaged")
        n = 1
        while aside.exists():
            n += 1
            aside = d.with_name(f"{d.name}.damaged-{n}")
        try:
            os.replace(d, aside)
        except FileNotFoundError:  # another process set it aside first
            return False
        line = f"damaged cache entry: {exc}; moved to {aside.name}, flying the run again"
        if warn is None:
            import warnings

            warnings.warn(line, DamagedCacheWarning, stacklevel=3)
        else:
            warn(line)
        return False


def ensure_result(spec: RunSpec, results_dir=None, force: bool = False,
                  progress: bool | None = None, controller=None,
                  warn=None, needs: tuple[str, ...] = ()) -> tuple[Path, bool]:
    """The cache folder of ``spec``, flying the run first if it is missing, damaged (moved
    aside with one warning line, :func:`usable_or_set_aside`), saved without what it
    ``needs`` (:func:`holds`) or forced (``force``).

    Parameters
    ----------
    spec : the run.
    results_dir : the cache's root (default ``results/``).
    force : fly again even when a complete result exists.
    progress : closed-loop progress bar (default: when writing to a terminal).
    controller : a built controller for ``spec.config`` to reuse (it is reset before flying).
    warn : where the line about a damaged entry goes (default: a warning).
    needs : what the caller reads of the result besides the flight (``("scan",)``: a figure
        that draws the scans), see :func:`holds`.

    Returns (folder, simulated).
    """
    out = spec.directory(results_dir)
    if not force and usable_or_set_aside(out, warn) and holds(out, spec, needs):
        return out, False
    store(fly(spec, controller=controller, progress=progress), out)
    return out, True


def holds(directory, spec: RunSpec, needs: tuple[str, ...] = ()) -> bool:
    """The result saved in ``directory`` holds what its use needs: each of ``needs``
    (:meth:`~paper_repro.sim.result.SimulationResult.has` names them), and the velocities it
    handed the controller when ``spec`` predicts moving regions. A result saved before the
    loop logged them is flown again, once, by the caller that needs them."""
    from paper_repro.sim.result import read_arrays

    names = ["scan_index" if n == "scan" else n for n in needs]
    if spec.config.nmpc.prediction != "static":
        names.append("region_velocities")
    return set(names) <= set(read_arrays(directory, *names))


def fly(spec: RunSpec, controller=None, progress: bool | None = None):
    """Fly one run: the single call of :func:`~paper_repro.sim.loop.simulate` behind every
    cached result (``reproduce`` and ``study`` alike)."""
    from paper_repro.sim.loop import simulate

    return simulate(spec.config, controller=controller, max_steps=spec.max_steps,
                    progress=progress)


def store(result, out) -> Path:
    """Save ``result`` into ``out`` atomically: written under a private name, then renamed.

    A folder already at ``out`` is replaced (a forced re-flight, or a result missing what its
    run needs). When another process renames its complete copy into place between that
    removal and our rename, the rename fails and its copy is kept (both flew the same spec);
    ours is discarded. A reader never sees a half-written folder.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.partial")
    result.save(partial)
    if out.exists():
        shutil.rmtree(out, ignore_errors=True)
    try:
        os.rename(partial, out)
    except OSError:  # another writer's complete copy is there now
        shutil.rmtree(partial, ignore_errors=True)
        if not is_cached(out):
            raise
    return out
