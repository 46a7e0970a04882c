"""paper_repro: Point-to-Cloud NMPC with Smooth Avoidance Constraints, reproduced.

The paper's core, which imports nothing above it:

============  ===========================================================================
``config``    every default parameter (frozen dataclasses), and ``presets`` of them
``vehicles``  the model interface and the vehicles: the quadrotor of Table I, a unicycle
``problem``   the smoothed distance D_{η,σ} and problem (21), the one description
``solvers``   IPOPT (the reference) and the real-time iteration, both reading problem (21)
============  ===========================================================================

Around it, each layer importing only the layers above it in this list:

============  ===========================================================================
``world``     shapes, scenes, random scenes, motion, the LiDAR, the region tracker
``sim``       the closed loop for any vehicle, its result, the plant, set-up checks
``analysis``  metrics of a run, statistics of a study, the mission's clock
``evidence``  golden flights, the stamps, the tables of the README and the book
``studies``   the run cache, the catalogue of studies, the engine on Dask, the tuning
``plots``     figures, drawn from saved results
``book``      the HTML book: the pages of docs/ and the executed notebooks
``cli``       ``python -m paper_repro COMMAND``
============  ===========================================================================

The names below are the ones the README, the book and the notebooks use.
"""

import paper_repro._blas  # noqa: F401, I001  (first: it asks OpenBLAS for one kernel)
from importlib.metadata import version

from paper_repro.config import (
    BarrierParams,
    Config,
    DistanceParams,
    NMPCParams,
    QuadrotorParams,
    SensorParams,
    SimulationParams,
    SolverParams,
)
from paper_repro.problem.distance import (
    CloudWeights,
    clearance,
    euclidean_distance,
    smooth_distance,
    smooth_distance_gradient,
    smooth_projection,
)
from paper_repro.sim.loop import Faults, simulate
from paper_repro.sim.result import SimulationResult
from paper_repro.solvers.factory import make_controller
from paper_repro.studies.catalogue import make_study
from paper_repro.studies.engine import load_table, run_study
from paper_repro.vehicles.base import Equilibria, VehicleModel
from paper_repro.vehicles.quadrotor import (
    continuous_dynamics,
    equilibrium,
    plant_step,
    rk4_discretisation,
)
from paper_repro.world.lidar import Lidar
from paper_repro.world.scenarios import make_scene
from paper_repro.world.scene import Region, Scene

__version__ = version("paper_repro")

__all__ = [
    "BarrierParams", "CloudWeights", "Config", "DistanceParams", "Equilibria", "Faults",
    "Lidar", "NMPCParams", "QuadrotorParams", "Region", "Scene", "SensorParams",
    "SimulationParams", "SimulationResult", "SolverParams", "VehicleModel", "clearance",
    "continuous_dynamics",
    "equilibrium", "euclidean_distance", "load_table", "make_controller", "make_scene",
    "make_study", "plant_step", "rk4_discretisation", "run_study", "simulate",
    "smooth_distance", "smooth_distance_gradient", "smooth_projection",
]
