"""A second vehicle: a unicycle ground robot in a planar scene, flown by both solvers.

This is "bring your own model" in practice, and the class of robot of recent point-cloud
CBF-MPC work. The robot has state x = (p_x, p_y, θ) (m, m, rad), inputs u = (v, ω) (m/s,
rad/s) and output y = (p_x, p_y) ∈ R², with ṗ_x = v cos θ, ṗ_y = v sin θ, θ̇ = ω. Its model
(:func:`unicycle_model`) is a few lines of CasADi, with its equilibria parametrised as
a = (p_x, p_y, θ), (v, ω) = 0: the rows x_a = f(x_a, u_a) would say v cos θ = v sin θ = 0, two
dependent equations that IPOPT fails on. Everything else, problem (21), the smoothed
distance, the CBF penalty and both solvers, is the quadrotor's code, unchanged.

The scene (:func:`~paper_repro.world.planar.planar_scene`) is a nonconvex point cloud, an
L-shaped wall whose corner faces the robot, seen through a 2-D LiDAR; the quadrotor's closed
loop, :func:`~paper_repro.sim.loop.simulate`, flies it: scan, solve, apply u_0, integrate.
"""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np

from paper_repro.config import BarrierParams, Config, NMPCParams
from paper_repro.vehicles.base import Equilibria, VehicleModel


def unicycle_model(max_speed: float = 1.0, max_turn_rate: float = 1.5,
                   half_width: float = 20.0) -> VehicleModel:
    """The unicycle as the NMPC sees it.

    Parameters
    ----------
    max_speed : m/s, |v| ≤ this.  max_turn_rate : rad/s, |ω| ≤ this.
    half_width : m, the workspace is [−half_width, half_width]² (θ is bounded by ±4π only to
        keep the box finite).
    """
    x, u = ca.SX.sym("x", 3), ca.SX.sym("u", 2)
    xdot = ca.vertcat(u[0] * ca.cos(x[2]), u[0] * ca.sin(x[2]), u[1])
    at_rest = Equilibria(state=ca.Function("x_a", [x], [x]),
                         input=ca.Function("u_a", [x], [ca.DM.zeros(2)]),
                         of_state=lambda xs: np.array(xs, float))
    return VehicleModel(
        "unicycle",
        dynamics=ca.Function("f_c", [x, u], [xdot], ["x", "u"], ["xdot"]),
        output=ca.Function("h", [x], [x[:2]]),
        state_lower=(-half_width, -half_width, -4 * np.pi),
        state_upper=(half_width, half_width, 4 * np.pi),
        input_lower=(-max_speed, -max_turn_rate), input_upper=(max_speed, max_turn_rate),
        equilibria=at_rest, position=(0, 1), state_names=("p_x", "p_y", "theta"),
        input_names=("v", "omega"))


def unicycle_config(metric: str = "smooth", solver: str = "rti") -> Config:
    """Settings for the unicycle: T_s = 0.05 s, N = 30 (a 1.5 s horizon), weights sized for
    (p_x, p_y, θ) and (v, ω), d_min = 0.32 m² (about 0.8 m from the smoothed cloud)."""
    base = Config()
    nmpc = dataclasses.replace(
        NMPCParams(), horizon=30, ts=0.05, q=(1.0, 1.0, 0.1), r=(1.0, 0.5), t=(20.0, 20.0),
        region_slots=1, points_per_region=96)
    return dataclasses.replace(
        base, nmpc=nmpc, barrier=BarrierParams(d_min=0.32, mu=1e3),
        solver=dataclasses.replace(base.solver, nlp_solver=solver),
        distance=dataclasses.replace(base.distance, metric=metric))
