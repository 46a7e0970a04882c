"""Pick the solver of problem (21) that a configuration names.

Both solvers build from the same :class:`~paper_repro.problem.ocp.OCP` and honour the
:class:`~paper_repro.problem.ocp.Controller` protocol, so the closed loop never needs to know which
it
flies with.
"""

from __future__ import annotations

from paper_repro.config import Config
from paper_repro.problem.ocp import Controller
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.rti import RealTimeNMPC
from paper_repro.vehicles.base import VehicleModel


def make_controller(config: Config | None = None, model: VehicleModel | None = None,
                    **options) -> Controller:
    """The controller named by ``config.solver.nlp_solver``: ``"rti"`` (:class:`RealTimeNMPC`,
    with ``solver.sqp_iterations``, ``solver.line_search``, ``solver.qp_solver``,
    ``solver.cold_start``, ``solver.relaxed_qp`` and ``solver.shared_barrier``) or
    ``"reference"`` (:class:`TrackingNMPC`).

    ``model`` : the vehicle (the quadrotor by default). ``options`` go to the controller's
    constructor (e.g. ``max_iter`` for IPOPT, ``capacities`` for the real-time solver).
    """
    config = config or Config()
    s = config.solver
    if s.nlp_solver == "reference":
        return TrackingNMPC(config, model, **options)
    options.setdefault("max_iter", s.sqp_iterations)
    options.setdefault("qp_solver", s.qp_solver)
    # line_search, cold_start, relaxed_qp and shared_barrier: the controller reads them from
    # config.solver unless an option says otherwise.
    return RealTimeNMPC(config, model, **options)
