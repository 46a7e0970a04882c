"""Every committed evidence set and how it is made: the one list that the stamps, the staleness
check (:func:`~paper_repro.evidence.golden.stale_evidence`), the regeneration
(:mod:`~paper_repro.evidence.regenerate`) and the contributor page's list of commands read.

A set is a folder under ``figures/`` made by one command, run from the repository's root.
Some read what others made (``after``): the moving speeds read the moving study's flights, for
example. The speed tables measure the machine (``timed``): they are made last, each alone on
the machine, so that no other job shares its cores.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from paper_repro.paths import atomic_text

LEVERS = ("none reaction-0.5s reaction-1s reaction-2s h-0.03s d_min-2 d_min-3 "
          "d_min-2+reaction-0.5s sweep-0.5s sweep-1s moving-d_min-3 moving-d_min-3+sweep-0.5s "
          "moving-d_min-3+sweep-1s lookahead-3s lookahead-5s moving-d_min-3+lookahead-4s "
          "moving-d_min-2+lookahead-3s")
"""The levers the committed screening flies (``benchmarks/moving_levers.py``)."""
FULL_LEVERS = "none d_min-3 moving-d_min-3 moving-d_min-3+sweep-1s moving-d_min-2+lookahead-3s"
"""The levers it flies on all 50 crossings and on the static passages."""


@dataclass(frozen=True)
class EvidenceSet:
    """One evidence set.

    folder : under ``figures/`` (``""``: ``figures/`` itself, the paper mission).
    command : what makes it, as typed from the repository's root.
    one_core : options that make the command use a single core (appended by the
        regeneration, which runs one job per core).
    after : the sets whose results it reads, or whose runs it shares through the run cache:
        made before it.
    timed : its tables are the machine's speed: made last, alone on the machine.
    fresh : files (under the set's folder) deleted before the command, which would otherwise
        resume from them (the tuning's trial storage).
    cores : the cores the command uses (``reproduce`` flies its two missions at once).
    """

    folder: str
    command: str
    one_core: str = ""
    after: tuple[str, ...] = ()
    timed: bool = False
    fresh: tuple[str, ...] = ()
    cores: int = 1

    @property
    def label(self) -> str:
        """``figures/<folder>``, as the stale list and the logs name it."""
        return f"figures/{self.folder}" if self.folder else "figures"


STUDY_NOTEBOOKS = {"monte_carlo": "09_monte_carlo", "eta_sweep": "10_eta_sweep",
                   "sensor_noise": "13_sensor_noise", "sensing_window": "15_smooth_sensing",
                   "moving_obstacles": "16_moving_obstacles", "timeline": "11_timeline",
                   "guidance": "17_guidance", "hardware_combined": "18_hardware"}
"""The notebook that draws each study's figures from its saved table."""


_STUDY = "--workers 1 --no-progress"

SETS = (
    EvidenceSet("", "python -m paper_repro reproduce", cores=2),
    EvidenceSet("presets/paper-timeline", "python -m paper_repro reproduce --preset paper-timeline",
                cores=2),
    EvidenceSet("studies/timeline", "python -m paper_repro study timeline", _STUDY),
    EvidenceSet("fidelity", "python benchmarks/fidelity.py", "--jobs 1"),
    EvidenceSet("ground_robot", "python benchmarks/ground_robot.py"),
    EvidenceSet("hardware", "python benchmarks/rotorpy_agreement.py"),
    EvidenceSet("studies/hardware_vehicle", "python -m paper_repro study hardware_vehicle",
                _STUDY),
    EvidenceSet("studies/hardware_air_latency",
                "python -m paper_repro study hardware_air_latency", _STUDY,
                after=("studies/hardware_vehicle",)),
    EvidenceSet("studies/hardware_combined", "python -m paper_repro study hardware_combined",
                _STUDY, after=("studies/hardware_vehicle", "studies/hardware_air_latency")),
    EvidenceSet("solver_speed/encounter",
                "python benchmarks/solver_speed.py --scenario encounter --steps 2000 --save",
                timed=True),
    EvidenceSet("solver_speed/crossing",
                "python benchmarks/solver_speed.py --scenario crossing --steps 3000 --solvers rti "
                "rti-damped rti-hpipm sqp-2 rti-riccati rti-damped-riccati --save", timed=True),
    EvidenceSet("solver_speed/swept_pillar",
                "python benchmarks/swept_pillar.py --save --steps 1200", timed=True),
    EvidenceSet("throughput",
                "python benchmarks/throughput.py --steps 20000 --scenario paper --save",
                timed=True, cores=2),
    EvidenceSet("build_time", "python benchmarks/build_time.py --save", timed=True, cores=2),
    EvidenceSet("throughput/profile", "python benchmarks/profile_step.py --save",
                after=("throughput",), timed=True),
    EvidenceSet("studies/monte_carlo", "python -m paper_repro study monte_carlo", _STUDY),
    EvidenceSet("studies/eta_sweep", "python -m paper_repro study eta_sweep", _STUDY),
    EvidenceSet("studies/sensor_noise", "python -m paper_repro study sensor_noise", _STUDY),
    EvidenceSet("studies/sensing_window", "python -m paper_repro study sensing_window", _STUDY),
    EvidenceSet("studies/moving_obstacles", "python -m paper_repro study moving_obstacles", _STUDY),
    EvidenceSet("studies/moving_obstacles_definition",
                "python benchmarks/moving_definition_form.py", "--workers 1"),
    EvidenceSet("studies/qp_failures", "python benchmarks/qp_failures.py --save --min-solves 10",
                "--workers 1", after=("studies/moving_obstacles", "studies/moving_heldout")),
    EvidenceSet("studies/avoidability", "python benchmarks/avoidability.py --save",
                after=("studies/moving_obstacles", "studies/moving_heldout")),
    EvidenceSet("studies/moving_levers",
                f"python benchmarks/moving_levers.py --save --seeds 2,3,5,6,12,17,19,25,26 "
                f"--levers {LEVERS} --full-seeds 0-49 --full-levers {FULL_LEVERS} "
                f"--static-seeds 0-29", "--workers 1",
                after=("studies/moving_obstacles", "studies/monte_carlo")),
    EvidenceSet("studies/moving_heldout",
                "python benchmarks/moving_heldout.py --save --seeds 50-149", "--workers 1"),
    EvidenceSet("studies/moving_speeds", "python benchmarks/moving_speeds.py --save",
                after=("studies/moving_obstacles", "studies/moving_heldout")),
    EvidenceSet("studies/guidance", "python -m paper_repro study guidance", _STUDY,
                after=("studies/monte_carlo",)),
    EvidenceSet("guidance_cost", "python benchmarks/guidance_cost.py --passages 5 --save",
                timed=True),
    EvidenceSet("guide_filter",
                "python benchmarks/guide_filter.py --save --passages 20 --taus 0,1", "--workers 1",
                after=("studies/guidance",)),
    EvidenceSet("tuning", "python -m paper_repro tune --trials 40", "--workers 1",
                after=("studies/monte_carlo",), fresh=("tuning.db",)),
)
"""Every committed evidence set, in the order of the contributor page's list."""

EVIDENCE_SETS = tuple(s.folder for s in SETS)
"""Every committed evidence set, as a folder under ``figures/``."""


def last_wall_time_s(folder: Path) -> float | None:
    """How long the command that made the set in ``folder`` took, by its ``timings.json``
    (s; ``None`` where neither the command nor the regeneration recorded it)."""
    timing = Path(folder) / "timings.json"
    if not timing.is_file():
        return None
    data = json.loads(timing.read_text())
    return data.get("wall_time_s", data.get("wall_time_s_last_call")) or None


def resumed(folder: Path) -> tuple[int, int, float] | None:
    """A study whose last call found some of its runs in the cache: ``(flown, runs, cached)``,
    the runs that call flew, the study's runs, and about how much longer a call from an empty
    cache would take on the same machine (s): the cached runs' own flight times
    (``timings.csv``'s ``wall_time_s``, each recorded when the run flew) shared among its
    cores (``timings.json``). ``None`` for a set that is not a study, or whose last call flew
    every run."""
    import pandas as pd

    folder = Path(folder)
    if not ((folder / "timings.csv").is_file() and (folder / "timings.json").is_file()):
        return None
    t = pd.read_csv(folder / "timings.csv")
    if not {"simulated", "wall_time_s"} <= set(t.columns):  # not a study's
        return None
    flown = int(t["simulated"].fillna(False).astype(bool).sum())
    if flown == len(t):
        return None
    cores = json.loads((folder / "timings.json").read_text()).get("meta", {}).get("cpu_count")
    cached = t.loc[~t["simulated"].fillna(False).astype(bool), "wall_time_s"].sum()
    return flown, len(t), float(cached) / max(int(cores or 1), 1)


RECORDED_BY = "paper_repro.evidence.sets.record_wall_time"
"""What :func:`record_wall_time` writes in the ``timings.json`` it owns."""


def record_wall_time(folder: Path, seconds: float) -> bool:
    """Record in ``folder/timings.json`` that the command that made the set took ``seconds``
    (s, its wall time), with the versions, commit and machine, for a set whose command does
    not record it itself (the benchmark scripts that fly outside the study engine). The
    command's stamp (:func:`~paper_repro.evidence.golden.stamp`) records the time its process
    ran until then, so a set made by hand shows its own run; the regeneration then replaces
    it with the command's whole run as it measured it. A ``timings.json`` the command wrote
    is left as it is; one this function wrote before is replaced. Returns whether it
    wrote."""
    from paper_repro.sim.result import run_metadata

    if not (isinstance(seconds, (int, float)) and seconds >= 0):
        raise ValueError(f"seconds must be a number >= 0, got {seconds!r}")
    timing = Path(folder) / "timings.json"
    if timing.is_file() and json.loads(timing.read_text()).get("recorded_by") != RECORDED_BY:
        return False
    record = {"wall_time_s": float(seconds), "recorded_by": RECORDED_BY, "meta": run_metadata()}
    atomic_text(timing, json.dumps(record, indent=1, default=str) + "\n")
    return True
