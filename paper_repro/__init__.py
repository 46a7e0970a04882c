"""paper_repro: Point-to-Cloud NMPC with Smooth Avoidance Constraints, reproduced.

Modules
-------
config      every default parameter (frozen dataclasses)
model       quadrotor of Table I: continuous dynamics, RK4 prediction, plant integration
distance    smoothed point-to-cloud distance D_{η,σ}, projection, Euclidean baseline
scene       workspace, Halton point-cloud regions, virtual LiDAR (optionally imperfect)
safety      checks of a mission before it flies, and the unsafe set-ups it reports
"""

from .config import (
                     BarrierParams,
                     Config,
                     DistanceParams,
                     NMPCParams,
                     QuadrotorParams,
                     SensorParams,
                     SimulationParams,
)
from .distance import (
                     CloudWeights,
                     clearance,
                     euclidean_distance,
                     smooth_distance,
                     smooth_distance_gradient,
                     smooth_projection,
)
from .model import continuous_dynamics, equilibrium, plant_step, rk4_discretisation
from .scene import Lidar, Scene, make_scene

__version__ = "0.1.0"

__all__ = [
    "BarrierParams", "CloudWeights", "Config", "DistanceParams", "Lidar", "NMPCParams",
    "QuadrotorParams", "Scene", "SensorParams", "SimulationParams", "clearance",
    "continuous_dynamics", "equilibrium", "euclidean_distance", "make_scene", "plant_step",
    "rk4_discretisation",
    "smooth_distance", "smooth_distance_gradient", "smooth_projection",
]
