"""The vehicles: what the NMPC needs to know about a vehicle, and the two it flies.

=================  ==================================================================
``base``           :class:`VehicleModel` (f_c, h, the boxes 𝒳 and 𝒰, the equilibria), RK4
``quadrotor``      the quadrotor of Table I: dynamics, equilibrium, plant step
``unicycle``       a ground robot (p_x, p_y, θ) with inputs (v, ω), and its settings
=================  ==================================================================
"""

from paper_repro.vehicles.base import Equilibria, VehicleModel, rk4
from paper_repro.vehicles.quadrotor import (
    N_INPUTS,
    N_STATES,
    continuous_dynamics,
    equilibrium,
    hover_input,
    plant_step,
    quadrotor_model,
    rk4_discretisation,
    symbolic_dynamics,
)
from paper_repro.vehicles.unicycle import unicycle_config, unicycle_model

__all__ = [
    "continuous_dynamics",
    "Equilibria",
    "equilibrium",
    "hover_input",
    "N_INPUTS",
    "N_STATES",
    "plant_step",
    "quadrotor_model",
    "rk4",
    "rk4_discretisation",
    "symbolic_dynamics",
    "unicycle_config",
    "unicycle_model",
    "VehicleModel",
]
