"""Numbers drawn from results: metrics of a run, statistics of a study, the mission's clock.

=================  ==================================================================
``metrics``        chattering, tracking error, clearance, one summary row per run
``statistics``     rates, paired differences, bootstrap intervals over a study table
``clock``          the tracking NMPC at hover as an LQ problem: time constants, mission time
``avoidability``   could a vehicle as agile as the quadrotor fly a moving scene clear at all
=================  ==================================================================
"""

from paper_repro.analysis.clock import (
    LATERAL,
    LEVERS,
    N_EQ,
    PAPER_AVOIDANCE_S,
    PAPER_MISSION_TIME_S,
    VERTICAL,
    YAW,
    ClockAnalysis,
    avoidance_windows,
    equilibrium_map,
    first_target_time,
    flight_clock,
    format_windows,
    lever_config,
    lever_sweep,
    lq_feedback,
    plant_linearisation,
    predicted_mission_time,
    prediction_linearisation,
)
from paper_repro.analysis.metrics import (
    COLLISION_CLEARANCE,
    DEFAULT_CUTOFF_HZ,
    DEFAULT_DEADBAND,
    SCAN_NEIGHBOURHOOD,
    SCAN_STEP_THRESHOLD,
    SPECTRUM_SEGMENT,
    TIMING_COLUMNS,
    chattering_metrics,
    input_spectrum,
    scan_change_steps,
    scan_changes,
    sign_changes,
    split_timings,
    summary_row,
    summary_table,
    tracking_error,
)
from paper_repro.analysis.statistics import EVENTS, PAIRED_COLUMNS, by_setting, ecdf, paired, rates

__all__ = [
    "avoidance_windows",
    "by_setting",
    "chattering_metrics",
    "ClockAnalysis",
    "COLLISION_CLEARANCE",
    "DEFAULT_CUTOFF_HZ",
    "DEFAULT_DEADBAND",
    "ecdf",
    "equilibrium_map",
    "EVENTS",
    "first_target_time",
    "flight_clock",
    "format_windows",
    "input_spectrum",
    "LATERAL",
    "lever_config",
    "lever_sweep",
    "LEVERS",
    "lq_feedback",
    "N_EQ",
    "paired",
    "PAIRED_COLUMNS",
    "PAPER_AVOIDANCE_S",
    "PAPER_MISSION_TIME_S",
    "plant_linearisation",
    "predicted_mission_time",
    "prediction_linearisation",
    "rates",
    "scan_change_steps",
    "scan_changes",
    "SCAN_NEIGHBOURHOOD",
    "SCAN_STEP_THRESHOLD",
    "sign_changes",
    "SPECTRUM_SEGMENT",
    "split_timings",
    "summary_row",
    "summary_table",
    "TIMING_COLUMNS",
    "tracking_error",
    "VERTICAL",
    "YAW",
]
