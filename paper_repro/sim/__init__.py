"""The closed loop: LiDAR scan → controller → plant, and what it leaves.

=================  ==================================================================
``loop``           :func:`simulate`, the step loop, and :class:`Faults` to inject
``result``         :class:`SimulationResult` (saves itself, becomes a DataFrame)
``perception``     what the controller is given: scan, faults, predictor, local map
``plant``          what the loop flies (:class:`Plant`); the quadrotor's, RK45 in C
``rotorpy_plant``  RotorPy's multirotor as a plant (the ``hardware`` extra)
``imperfect``      an estimated state (noise, latency) and a delayed input, around a plant
``termination``    when a flight ends: targets, finish line, stall, faults, leaving
``checks``         checks of a mission before it flies, and the hazards it warns of
=================  ==================================================================
"""

from paper_repro.sim.checks import SetupHazardWarning, check_setup, setup_hazards
from paper_repro.sim.loop import Faults, simulate
from paper_repro.sim.plant import ModelPlant, Plant, QuadrotorPlant, plant_for
from paper_repro.sim.result import (
    FAULT_STATUSES,
    MANIFEST,
    OUTCOMES,
    RESULT_ARRAYS,
    DamagedResult,
    SimulationResult,
    run_metadata,
    verify_result,
    write_manifest,
)

__all__ = [
    "check_setup",
    "DamagedResult",
    "FAULT_STATUSES",
    "Faults",
    "MANIFEST",
    "ModelPlant",
    "OUTCOMES",
    "Plant",
    "QuadrotorPlant",
    "plant_for",
    "RESULT_ARRAYS",
    "run_metadata",
    "setup_hazards",
    "SetupHazardWarning",
    "simulate",
    "SimulationResult",
    "verify_result",
    "write_manifest",
]
