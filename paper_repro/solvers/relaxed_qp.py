"""The stage QP with soft state bounds: a QP that always has a solution.

The real-time iteration's QP (:class:`~paper_repro.solvers.linearisation.QPLayout`) keeps the
state bounds 𝒳 and the terminal rows x_N = x_a hard. From some states no input meets them:
a vehicle falling at 2 m/s 0.2 m above the ground cannot stop before it, and a plan that
must end at rest cannot be found in one horizon. The linearised QP is then infeasible and
every QP method fails (``benchmarks/qp_failures.py`` measured this on the moving crossings).

:class:`RelaxedQP` solves the same QP with those constraints made soft, the standard way
(acados calls them soft constraints): each bounded state component x_j,i gets a slack
v_j,i ≥ 0 and the bound becomes lb_i − v_j,i ≤ x_j,i ≤ ub_i + v_j,i; each terminal row r gets
a slack t_r ≥ 0 and becomes |r(w)| ≤ t_r. The cost gains ρ·(Σv + Σt), an exact ℓ1 penalty:
for ρ above the largest multiplier of the hard QP, the relaxed QP has the hard QP's solution
whenever the hard QP has one (Fletcher, *Practical Methods of Optimization*, 2nd ed., §14.3).
The dynamics stay hard and the inputs and the artificial equilibrium keep their boxes, so a
feasible point always exists: any input, the states it gives, and slacks large enough.

HPIPM solves it on the stage structure: the slacks of stage j are extra inputs of stage j
and the soft bounds are its general rows. The casadi interface has no inputs at the last
stage, so the slacks of x_N and of the terminal rows sit at stage N−1, with x_N written as
the linearised dynamics of stage N−1.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from paper_repro.solvers.linearisation import QPLayout

L1_WEIGHT = 1e6
"""ρ, the ℓ1 weight of a unit of violation (a metre, a radian, m/s, rad/s). The penalty is
exact only above the hard QP's largest multiplier. The terminal rows' multipliers grow with
the distance to the target: 8·10⁴ for a quadrotor at rest 40 m from it, where ρ = 10⁴ gave a
step 34 units away from the hard QP's and ρ = 10⁶ the same step to 10⁻⁸."""

SLACK_CURVATURE = 1e-6
"""A small quadratic weight on every slack, so that HPIPM's Riccati recursion sees positive
curvature on the slack inputs (an LP direction otherwise)."""


class RelaxedQP:
    """The stage QP of ``layout`` with soft state bounds and soft terminal rows, by HPIPM.

    Parameters
    ----------
    layout : the hard QP's :class:`QPLayout`.
    bounded : (n_x,) bool, the state components with a finite bound (𝒳 of the OCP).
    weight : ρ, the ℓ1 weight (:data:`L1_WEIGHT`).

    Attributes
    ----------
    last_violation : the sum of the slacks at the last solve, in the units of the states:
        0 (to HPIPM's tolerance) when the hard QP had a solution.
    last_status : HPIPM's return status at the last solve.
    """

    def __init__(self, layout: QPLayout, bounded: np.ndarray, weight: float = L1_WEIGHT):
        lay = self.layout = layout
        n = lay.horizon
        if n < 2:
            raise ValueError(f"the relaxed QP needs a horizon of at least 2 stages, got {n}")
        self.weight = float(weight)
        self.ib = ib = np.flatnonzero(np.asarray(bounded, bool))
        nb, nc = len(ib), lay.nc
        # slacks per stage: x_j's at stage j (1 ≤ j ≤ N−1); x_N's and the terminal rows' at N−1
        self.n_slack = ns = [0] + [nb] * (n - 1) + [0]
        ns[n - 1] += nb + nc
        shift = np.concatenate([[0], np.cumsum(ns)])  # slacks before stage j
        stage_of = np.repeat(np.arange(n + 1), lay.sizes)
        self.new_of = np.arange(lay.nw) + shift[stage_of]  # old w index -> new index
        self.nn = lay.nw + int(shift[-1])
        # the slacks' indices: after stage j's own entries
        self.slack_of = [lay.offsets[j + 1] + shift[j] + np.arange(ns[j]) for j in range(n + 1)]
        self.slack_of[n] = np.arange(0)
        self.is_slack = np.zeros(self.nn, bool)
        for s in self.slack_of:
            self.is_slack[s] = True

        # rows: stage by stage, the gap rows of stage j, then its soft rows
        gap_rows = np.concatenate([[0], np.cumsum([lay.nz[j + 1] for j in range(n)])])
        self._plan = []  # (kind, stage, old rows or components, new row offset)
        row = 0
        for j in range(n):
            self._plan.append(("gap", j, np.arange(gap_rows[j], gap_rows[j + 1]), row))
            row += gap_rows[j + 1] - gap_rows[j]
            if j >= 1:
                self._plan.append(("x", j, None, row))
                row += 2 * nb
            if j == n - 1:
                self._plan.append(("x_N", j, None, row))
                row += 2 * nb
                self._plan.append(("terminal", j, None, row))
                row += 2 * nc
        self.n_rows = row
        ng = [0] + [2 * nb] * (n - 1) + [0]
        ng[n - 1] += 2 * nb + 2 * nc
        nu = [lay.nu + ns[j] for j in range(n)] + [0]

        # the sparsity: the matrices of random positive data (no cancellation)
        rng = np.random.default_rng(0)
        h0 = rng.uniform(1, 2, lay.hessian_entries[2].max() + 1)
        j0 = rng.uniform(1, 2, lay.n_ab + lay.nc * lay.nz[n])
        H, A = self._dense(h0, j0)[:2]
        self._h_sp = ca.Sparsity.triplet(self.nn, self.nn, *map(list, np.nonzero(H.T)[::-1]))
        self._a_sp = ca.Sparsity.triplet(self.n_rows, self.nn, *map(list, np.nonzero(A.T)[::-1]))
        self._h_at = self._h_sp.get_triplet()
        self._a_at = self._a_sp.get_triplet()
        self.solver = ca.conic("relaxed_qp", "hpipm", {"h": self._h_sp, "a": self._a_sp},
                               {"N": n, "nx": lay.nz, "nu": nu, "ng": ng,
                                # HPIPM's default residual tolerances (1e-8, absolute)
                                # are out of reach at ρ's scale; 1e-6 is reached in ~10
                                # iterations, and the barrier starts at ρ's order.
                                "hpipm": {"iter_max": 100, "mode": "robust", "mu0": 1e3,
                                          "res_g_max": 1e-6, "res_b_max": 1e-6,
                                          "res_d_max": 1e-6, "res_m_max": 1e-6},
                                "inf": 1e8,
                                "error_on_fail": False, "print_problem": False})
        self.last_violation = np.nan
        self.last_status = None

    def solve(self, h, q, j, gap, eq, lb, ub) -> np.ndarray | None:
        """The step Δw (n_w,) of the relaxed QP for the hard QP's data (the arguments of
        :meth:`~paper_repro.solvers.rti.QPChain.solve`); ``None`` if HPIPM fails on it."""
        lay, nn = self.layout, self.nn
        H, A, lba, uba = self._dense(h, j, gap, eq, lb, ub)
        g = np.zeros(nn)
        g[self.new_of] = q
        g[self.is_slack] = self.weight
        lbx, ubx = np.full(nn, -np.inf), np.full(nn, np.inf)
        lbx[self.new_of], ubx[self.new_of] = lb, ub
        soft = lay.ix[:, self.ib].ravel()
        lbx[self.new_of[soft]], ubx[self.new_of[soft]] = -np.inf, np.inf
        lbx[self.is_slack] = 0.0
        sol = self.solver(h=ca.DM(self._h_sp, H[self._h_at].tolist()), g=g,
                          a=ca.DM(self._a_sp, A[self._a_at].tolist()),
                          lba=lba, uba=uba, lbx=lbx, ubx=ubx)
        stats = self.solver.stats()
        self.last_status = str(stats.get("return_status", "unknown"))
        z = np.asarray(sol["x"]).ravel()
        if not stats.get("success", False) or not np.isfinite(z).all():
            self.last_violation = np.nan
            return None
        self.last_violation = float(z[self.is_slack].sum())
        return z[self.new_of]

    def _dense(self, h, j, gap=None, eq=None, lb=None, ub=None):
        """The relaxed QP's dense H (nn, nn) and A (rows, nn), and with the data the rows'
        bounds (lba, uba)."""
        lay, nb = self.layout, len(self.ib)
        H0, A0 = lay.dense(h, j)
        H = np.zeros((self.nn, self.nn))
        H[np.ix_(self.new_of, self.new_of)] = H0
        H[self.is_slack, self.is_slack] = SLACK_CURVATURE * self.weight
        A = np.zeros((self.n_rows, self.nn))
        lba, uba = np.full(self.n_rows, -np.inf), np.full(self.n_rows, np.inf)
        n = lay.horizon
        with_data = gap is not None
        # x_N and z_N as the linearised dynamics of stage N−1: z_N = G w + gap_{N−1}
        last = self._plan[-4][2]  # stage N−1's gap rows
        z_n = lay.offsets[n] + np.arange(lay.nz[n])
        G = A0[last].copy()
        G[:, z_n] = 0.0
        gap_last = gap[last] if with_data else 0.0
        for kind, stage, rows, r in self._plan:
            if kind == "gap":
                A[r:r + len(rows), self.new_of] = A0[rows]
                if with_data:
                    lba[r:r + len(rows)] = uba[r:r + len(rows)] = -gap[rows]
                continue
            if kind == "terminal":
                C = A0[lay.n_gap_rows:][:, z_n]
                rows_w = C @ G
                slack = self.slack_of[stage][2 * nb:]
                offset = C @ gap_last + eq if with_data else 0.0
                lo = hi = -offset
            else:  # the bounded components of x_j (j = stage) or of x_N
                x_of = lay.ix[stage - 1 if kind == "x" else n - 1, self.ib]
                if kind == "x":
                    rows_w = np.zeros((nb, lay.nw))
                    rows_w[np.arange(nb), x_of] = 1.0
                    slack, offset = self.slack_of[stage][:nb], 0.0
                else:
                    rows_w = G[self.ib]
                    slack = self.slack_of[stage][nb:2 * nb]
                    offset = gap_last[self.ib] if with_data else 0.0
                if with_data:
                    lo, hi = lb[x_of] - offset, ub[x_of] - offset
            k = len(rows_w)
            A[r:r + k, self.new_of] = rows_w
            A[r + k:r + 2 * k, self.new_of] = rows_w
            A[r + np.arange(k), slack] = 1.0  # w + v ≥ lower
            A[r + k + np.arange(k), slack] = -1.0  # w − v ≤ upper
            if with_data:
                lba[r:r + k] = lo
                uba[r + k:r + 2 * k] = hi
        return H, A, lba, uba
