"""Figures, drawn from saved results and tables (nothing here simulates).

=================  ==================================================================
``common``         colours, axes helpers, decimation, :func:`save_figure`, :func:`show_figure`
``flight``         the paper's figures of one flight, and summary figures
``distance``       the smoothed distance on a 2-D slice (the tutorial)
``barrier``        the CBF penalty F(g) and the decay g ≤ 0 allows (the tutorial)
``animation``      animations of a flight
``studies``        rates, paired differences, ECDFs, sweeps of a study table
``clock``          the mission's clock
``sensing``        the smooth sensing window
``moving``         moving obstacles and their prediction
``tuning``         the tuning's front, importances and held-out comparison
``guidance``       a passage flown with and without the local map and the guide
=================  ==================================================================

This namespace holds the figures, :func:`save_figure` and :func:`show_figure`, and the few
helpers the notebooks call. The axes helpers and colours stay in their modules.

The paper's figures (Section V): Fig. 1 :func:`plot_flight_3d`; Figs. 2, 3
:func:`plot_projection` (``plane="xz"`` / ``"xy"``); Figs. 4, 8 :func:`plot_thrusts`;
Figs. 5, 7 :func:`plot_tracking_errors`; Fig. 6 :func:`plot_states`.
"""

from paper_repro.plots.animation import animate_flight, save_animation
from paper_repro.plots.barrier import plot_barrier_penalty
from paper_repro.plots.clock import plot_clock_levers, plot_flight_clocks
from paper_repro.plots.common import (
    CLOUD_COLOR,
    SPHERE_COLOR,
    save_figure,
    show_figure,
)
from paper_repro.plots.distance import (
    plot_distance_slice,
    plot_eta_sigma,
    plot_gradient_field,
    plot_half_squared_limit,
    slice_grid,
    slice_through,
)
from paper_repro.plots.flight import (
    avoidance_window,
    lidar_instants,
    plot_flight_3d,
    plot_input_spectrum,
    plot_projection,
    plot_regions,
    plot_solve_times,
    plot_states,
    plot_thrusts,
    plot_tracking_errors,
    view_window,
)
from paper_repro.plots.guidance import plot_guided_passage, plot_guided_thrusts
from paper_repro.plots.moving import (
    animate_crossing,
    plot_clearance_time,
    plot_crossing_closest,
    plot_prediction_study,
    prediction_velocities,
)
from paper_repro.plots.sensing import (
    plot_scan_change_du,
    plot_scan_change_study,
    plot_scan_change_thrusts,
    plot_sensing_window,
)
from paper_repro.plots.studies import (
    METRIC_COLOURS,
    plot_cells,
    plot_clearance_ecdf,
    plot_paired,
    plot_paired_by,
    plot_rates,
    plot_study_solve_times,
    plot_sweep,
)
from paper_repro.plots.tuning import plot_front, plot_heldout, plot_importances

__all__ = [
    "animate_crossing",
    "animate_flight",
    "avoidance_window",
    "CLOUD_COLOR",
    "lidar_instants",
    "METRIC_COLOURS",
    "plot_barrier_penalty",
    "plot_cells",
    "plot_clearance_ecdf",
    "plot_clearance_time",
    "plot_clock_levers",
    "plot_crossing_closest",
    "plot_distance_slice",
    "plot_eta_sigma",
    "plot_flight_3d",
    "plot_flight_clocks",
    "plot_front",
    "plot_gradient_field",
    "plot_guided_passage",
    "plot_guided_thrusts",
    "plot_half_squared_limit",
    "plot_heldout",
    "plot_importances",
    "plot_input_spectrum",
    "plot_paired",
    "plot_paired_by",
    "plot_prediction_study",
    "plot_projection",
    "plot_regions",
    "plot_rates",
    "plot_scan_change_du",
    "plot_scan_change_study",
    "plot_scan_change_thrusts",
    "plot_sensing_window",
    "plot_solve_times",
    "plot_states",
    "plot_study_solve_times",
    "plot_sweep",
    "plot_thrusts",
    "plot_tracking_errors",
    "prediction_velocities",
    "save_animation",
    "save_figure",
    "show_figure",
    "slice_grid",
    "slice_through",
    "SPHERE_COLOR",
    "view_window",
]
