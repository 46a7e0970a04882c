"""The two solvers of problem (21), and the choice between them.

=================  ==================================================================
``ipopt``          :class:`TrackingNMPC`, the reference: IPOPT, exact Hessian (the paper)
``rti``            :class:`RealTimeNMPC`, the real-time iteration (SQP, Gauss-Newton)
``linearisation``  the linearisation of (21) at the previous plan and the QP's layout
``line_search``    the step size: backtracking on the ℓ1 merit function, and damping
``riccati_qp``     the stage-wise QP solved by a Riccati recursion (C, compiled once)
``relaxed_qp``     the same QP with soft state bounds (exact ℓ1), when it has no solution
``factory``        :func:`make_controller`: the solver a config names
=================  ==================================================================
"""

from paper_repro.solvers.factory import make_controller
from paper_repro.solvers.ipopt import TrackingNMPC
from paper_repro.solvers.line_search import MeritLineSearch
from paper_repro.solvers.rti import QPChain, RealTimeNMPC

__all__ = ["make_controller", "MeritLineSearch", "QPChain", "RealTimeNMPC", "TrackingNMPC"]
