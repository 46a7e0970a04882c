"""Studies: many runs as data, flown on Dask, cached, tabled; and the tuning.

==================  ==================================================================
``runs``            :class:`RunSpec` and the run cache, keyed by config, scene and golden hash
``catalogue``       the studies (Monte Carlo, η sweep, sensor noise, sensing window, moving
                    obstacles, the timeline of the clock)
``engine``          :func:`run_study` on an embedded or remote Dask cluster; the tables
``cluster``         the one Dask set-up, for studies and tuning
``reproduce``       :func:`reproduce`: fly the paper's missions, run every notebook
``tuning_space``    the tuning's search space, objectives and constraints
``tuning_scenes``   its training and held-out scenes, a trial's runs and its score
``tuning``          :func:`tune`: Optuna over random passages
``tuning_results``  reading a tuning: trials, front, importances, held-out comparison
==================  ==================================================================
"""

from paper_repro.studies.catalogue import (
    CANDIDATES,
    ETAS,
    NOISY_LIDAR,
    PASSAGE_STEPS,
    QUICK_STEPS,
    SENSING_WINDOWS,
    SIGMAS,
    STUDIES,
    STUDY_NOTEBOOK_QUICK,
    STUDY_NOTEBOOKS,
    TIMELINE_QUICK_STEPS,
    Study,
    candidate_config,
    eta_sweep,
    make_study,
    monte_carlo,
    moving_obstacles,
    passage_config,
    passage_spec,
    sensing_window,
    sensor_noise,
    timeline_flights,
    timeline_study,
)
from paper_repro.studies.cluster import dask_client
from paper_repro.studies.engine import (
    CSV_ROWS,
    TIMING_COLUMNS,
    StudyResult,
    controller_key,
    load_table,
    run_study,
    run_task,
    saved_table,
)
from paper_repro.studies.reproduce import (
    DESCRIPTION,
    METRICS,
    NOTEBOOKS,
    NotebookSpec,
    ReproduceReport,
    check_parameters,
    declared_parameters,
    default_result_dir,
    execute_notebook,
    notebook_parameters,
    notebook_path,
    run_specs,
)
from paper_repro.studies.runs import (
    DamagedCacheWarning,
    RunSpec,
    ensure_result,
    fly,
    is_cached,
    rekey,
    run_key,
    store,
    usable_or_set_aside,
)

__all__ = [
    "candidate_config",
    "CANDIDATES",
    "check_parameters",
    "controller_key",
    "CSV_ROWS",
    "DamagedCacheWarning",
    "dask_client",
    "declared_parameters",
    "default_result_dir",
    "DESCRIPTION",
    "ensure_result",
    "eta_sweep",
    "ETAS",
    "execute_notebook",
    "fly",
    "is_cached",
    "load_table",
    "make_study",
    "METRICS",
    "monte_carlo",
    "moving_obstacles",
    "NOISY_LIDAR",
    "notebook_parameters",
    "notebook_path",
    "NOTEBOOKS",
    "NotebookSpec",
    "passage_config",
    "passage_spec",
    "PASSAGE_STEPS",
    "QUICK_STEPS",
    "ReproduceReport",
    "rekey",
    "run_key",
    "run_specs",
    "run_study",
    "run_task",
    "saved_table",
    "RunSpec",
    "sensing_window",
    "SENSING_WINDOWS",
    "sensor_noise",
    "SIGMAS",
    "store",
    "STUDIES",
    "Study",
    "STUDY_NOTEBOOK_QUICK",
    "STUDY_NOTEBOOKS",
    "StudyResult",
    "timeline_flights",
    "TIMELINE_QUICK_STEPS",
    "timeline_study",
    "TIMING_COLUMNS",
    "usable_or_set_aside",
]
