"""The IPOPT transcription of problem (21): the reference solver, as the paper.

:class:`TrackingNMPC` transcribes the :class:`~paper_repro.problem.ocp.OCP` (the problem, its terms
and
its bounds are described there, once) into one NLP by multiple shooting: the variables are
x_0..x_N, u_0..u_{N−1} and the artificial equilibrium's a ((x_a, u_a) = E(a), see
:meth:`~paper_repro.problem.ocp.OCP.equilibrium`: the quadrotor's position and yaw), the equalities
x_0 = x (as bounds), x_{j+1} = f(x_j, u_j), x_N = x_a, and x_a = f(x_a, u_a) for a model
without an equilibrium parametrisation; IPOPT solves it with the exact Hessian. It is built once;
:meth:`TrackingNMPC.solve` is the hot path. What the LiDAR sees enters as parameters
(:class:`~paper_repro.problem.scan.ScanLayout`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import casadi as ca
import numpy as np

from paper_repro.config import Config
from paper_repro.problem.ocp import OCP, NMPCSolution
from paper_repro.problem.scan import check_visible
from paper_repro.validation import as_vector
from paper_repro.vehicles.base import VehicleModel

_SUCCESS_STATUSES = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


class TrackingNMPC:
    """The paper's tracking NMPC, solved by IPOPT with the exact Hessian (the reference path).

    Parameters
    ----------
    config : :class:`~paper_repro.config.Config`; uses its ``distance``, ``barrier`` and
        ``nmpc`` parts (and ``quadrotor`` when ``model`` is omitted).
    model : the vehicle, the quadrotor by default (see :class:`~paper_repro.problem.ocp.OCP`).
    max_iter : IPOPT iteration limit per solve.
    tol : IPOPT convergence tolerance.
    apply_unconverged : count a solve that stops at ``max_iter`` as a success, so that the
        closed loop applies IPOPT's last iterate (what a loop that does not read the solver's
        status does). ``False`` (default): it is a failed solve, and the loop applies the
        previous plan, shifted. It matters for the Euclidean metric only: its ½·min d² is not
        differentiable where the nearest point changes, and IPOPT stops at the iteration
        limit at most instants with a region in view (``benchmarks/fidelity.py``).
    """

    def __init__(self, config: Config | None = None, model: VehicleModel | None = None,
                 max_iter: int = 200, tol: float = 1e-8, apply_unconverged: bool = False):
        # Builds the NLP and IPOPT instance once: several seconds.
        if not (isinstance(max_iter, int) and max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
        if not (tol > 0):
            raise ValueError(f"tol must be > 0, got {tol!r}")
        if not isinstance(apply_unconverged, bool):
            raise ValueError(f"apply_unconverged must be True or False, got "
                             f"{apply_unconverged!r}")
        self.apply_unconverged = apply_unconverged
        self.ocp = OCP(config, model)
        self.config = self.ocp.config
        self.horizon = self.ocp.horizon
        self._build(max_iter, tol)

    # --- public ------------------------------------------------------------------------------

    def solve(self, x0, target, visible: Sequence[np.ndarray] = (),
              previous: NMPCSolution | None = None, velocities=None) -> NMPCSolution:
        """Solve the OCP from state ``x0`` towards output set-point ``target``.

        Parameters
        ----------
        x0 : (n_x,) current state.
        target : (p,) set-point y_t, m.
        visible : the LiDAR scan in its one accepted form (see
            :func:`~paper_repro.problem.scan.check_visible`): a list or tuple with one finite (k_i,
            p)
            array per region, k_i ≥ 0 (what
            :meth:`paper_repro.world.lidar.Lidar.scan` returns); ``()`` when nothing is in view.
        previous : the plan of the previous sampling instant; the warm start is that plan
            shifted by one step (see :meth:`NMPCSolution.shifted`). Hover at the current
            position if omitted.
        velocities : moving regions (a controller built with ``nmpc.prediction`` other
            than ``"static"``): one (p,) predicted velocity per region of ``visible``, m/s;
            region i at stage j is the scanned cloud moved by velocities[i]·j·h.
        """
        start = time.perf_counter()  # solve_time includes packing the scan: the whole call
        ocp = self.ocp
        x0 = as_vector("x0", x0, ocp.nx)
        target = as_vector("target", target, ocp.ny)
        visible = check_visible(visible, ocp.ny)
        params = np.concatenate([target, self.obstacle_parameters(visible, ocp.output(x0),
                                                                  velocities)])
        guess = previous.shifted() if previous is not None else self.hover_guess(x0)
        w0 = self._pack(guess.x, guess.u, self.ocp.parameters_of(guess.x_a, guess.u_a))
        w0[self._ix[0]] = x0
        lbw, ubw = self._lbw.copy(), self._ubw.copy()
        lbw[self._ix[0]] = x0
        ubw[self._ix[0]] = x0
        lbw[self._ix[1:]], ubw[self._ix[1:]] = ocp.state_box(x0)  # 𝒳, relaxed if x0 ∉ 𝒳

        sol = self._solver(x0=w0, p=params, lbx=lbw, ubx=ubw, lbg=0.0, ubg=0.0)
        elapsed = time.perf_counter() - start
        stats = self._solver.stats()
        w = np.asarray(sol["x"]).ravel()
        x, u, a = self._unpack(w)
        x_a, u_a = self.ocp.equilibrium_of(a)
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False)) or status in _SUCCESS_STATUSES or (
            self.apply_unconverged and status == "Maximum_Iterations_Exceeded")
        success = success and bool(np.all(np.isfinite(w)))
        return NMPCSolution(u, x, x_a, u_a, success, status, int(stats.get("iter_count", -1)),
                            elapsed, float(sol["f"]))

    def reset(self) -> None:
        """Nothing to forget: each IPOPT solve starts from the guess it is given."""

    def hover_guess(self, x0) -> NMPCSolution:
        """Initial guess: rest where the vehicle is for the whole horizon (for the quadrotor,
        hover at its position and yaw)."""
        return self.ocp.rest(x0)

    def obstacle_parameters(self, visible: Sequence[np.ndarray], position,
                            velocities=None) -> np.ndarray:
        """The LiDAR scan in the NLP's parameter layout (:meth:`ScanLayout.pack`)."""
        return self.ocp.scan.pack(visible, position, velocities)

    # --- construction --------------------------------------------------------------------------

    def _build(self, max_iter: int, tol: float) -> None:
        ocp = self.ocp
        n, nx, nu = ocp.horizon, ocp.nx, ocp.nu
        f, h = ocp.f, ocp.h

        X = ca.SX.sym("X", nx, n + 1)
        U = ca.SX.sym("U", nu, n)
        a = ca.SX.sym("a", ocp.na)
        xa, ua = ocp.equilibrium(a)
        yt = ca.SX.sym("y_t", ocp.ny)

        cost = 0
        constraints = []
        for j in range(n):
            cost += ca.sumsqr(ocp.tracking_residual(X[:, j], U[:, j], xa, ua))
            constraints.append(X[:, j + 1] - f(X[:, j], U[:, j]))
        ya = h(xa)
        cost += ca.sumsqr(ocp.offset_residual(ya, yt))
        constraints.append(X[:, n] - xa)
        constraints.append(ocp.equilibrium_rows(a))

        scan, beta, active = ocp.scan.barriers()
        outputs = [h(X[:, j]) for j in range(n + 1)] + [ya]  # y_0..y_N, then y_{N+1} = y_a
        betas = [beta(y, ocp.stage_time(j), j == n + 1)  # y_{N+1} = y_a
                 for j, y in enumerate(outputs)]
        for i in range(ocp.scan.slots):
            gs = ocp.violations([b[i] for b in betas])
            cost += ocp.mu * active[i] * sum(ocp.penalty(g) for g in gs)

        w = ca.vertcat(ca.vec(X), ca.vec(U), a)
        params = ca.vertcat(yt, scan)
        nlp = {"x": w, "p": params, "f": cost, "g": ca.vertcat(*constraints)}
        opts = {"ipopt": {"print_level": 0, "max_iter": max_iter, "tol": tol,
                          "sb": "yes", "mu_strategy": "adaptive"},
                "print_time": False}
        self._solver = ca.nlpsol("tracking_nmpc", "ipopt", nlp, opts)

        # Index maps into w, and bounds.
        idx = np.arange(w.shape[0])
        self._ix = idx[: nx * (n + 1)].reshape(n + 1, nx)
        off = nx * (n + 1)
        self._iu = idx[off: off + nu * n].reshape(n, nu)
        off += nu * n
        self._ia = idx[off: off + ocp.na]
        (xl, xu), (ul, uu) = ocp.state_bounds, ocp.input_bounds
        lbw, ubw = np.empty(w.shape[0]), np.empty(w.shape[0])
        lbw[self._ix], ubw[self._ix] = xl, xu
        lbw[self._iu], ubw[self._iu] = ul, uu
        lbw[self._ia], ubw[self._ia] = ocp.equilibrium_box
        self._lbw, self._ubw = lbw, ubw

    def _pack(self, x, u, a) -> np.ndarray:
        return np.concatenate([np.asarray(x).ravel(), np.asarray(u).ravel(), a])

    def _unpack(self, w):
        return w[self._ix], w[self._iu], w[self._ia]
