"""Problem (21): the smoothed point-to-cloud distance and the optimal control problem that
both solvers read.

=================  ==================================================================
``distance``       D_{η,σ} (eq. 8-13), its projection and gradient, the Euclidean baseline
``scan``           the LiDAR scan as parameters of the problem (region slots, padding)
``ocp``            :class:`OCP`: costs, CBF penalty, bounds, artificial equilibrium;
                   :class:`NMPCSolution` and the :class:`Controller` protocol
=================  ==================================================================
"""

from paper_repro.problem.distance import (
    CloudWeights,
    check_cloud,
    clearance,
    euclidean_distance,
    euclidean_distance_symbolic,
    sensing_window,
    smooth_distance,
    smooth_distance_gradient,
    smooth_distance_symbolic,
    smooth_projection,
)
from paper_repro.problem.ocp import OCP, Controller, NMPCSolution, selected_states
from paper_repro.problem.scan import PAD_LOG_WEIGHT, ScanLayout, check_visible

__all__ = [
    "check_cloud",
    "check_visible",
    "clearance",
    "CloudWeights",
    "Controller",
    "euclidean_distance",
    "euclidean_distance_symbolic",
    "NMPCSolution",
    "OCP",
    "PAD_LOG_WEIGHT",
    "ScanLayout",
    "selected_states",
    "sensing_window",
    "smooth_distance",
    "smooth_distance_gradient",
    "smooth_distance_symbolic",
    "smooth_projection",
]
