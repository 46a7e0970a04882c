"""The mission's clock: the tracking NMPC linearised at hover, solved exactly as an LQ problem.

Far from the clouds, and at the small speeds the printed weights give, the OCP (21) is a linear
quadratic problem: the quadrotor linearised at hover, no active bound and no barrier term.
Its decision variables are the inputs u_0..u_{N−1} and the artificial equilibrium. The
quadrotor's equilibria are exactly (position, yaw) with hover thrust, so
x_a = E·a, a = (p_a, ψ_a) ∈ R⁴, u_a = m·g/4 (see
:func:`paper_repro.vehicles.quadrotor.equilibrium`), and ::

    min_{u, a}  Σ_{j<N} ‖x_j − E a‖²_Q + ‖u_j − u_a‖²_R + ‖p_a − y_t‖²_T
    s.t.        x_{j+1} = A x_j + B (u_j − u_a),   x_N = E a

is solved once, exactly, through its KKT system for every initial state and target at the
same time. Its first input is a linear feedback u_0 = u_a + K x + K_t y_t. Closing the loop
with the plant (the continuous linearisation, discretised exactly over T_s under zero-order
hold) gives a linear system whose eigenvalues λ set the time constants τ = −T_s / ln|λ| of the
lateral (x, y), vertical (z) and yaw motions, and whose iteration predicts when each target is
reached, in milliseconds instead of minutes of flight.

Why the clock is slow. Every prediction must end at rest at x_a within N·h (h is the
prediction step, ``NMPCParams.prediction_step``; 0.35 s as printed). Lateral motion passes
through four integrations (thrust difference → pitch rate → pitch → velocity → position), so
moving x_a a distance δ ahead of the UAV costs the stage terms about c·δ² with c large, while
only the offset term ‖p_a − y_t‖²_T pulls x_a forward. The UAV therefore moves at a speed
proportional to its distance from the target: an exponential approach with τ of order c/T.
The vertical chain has two integrations and converges much faster.

What this leaves out: obstacles (the barrier terms are zero far from every cloud), the state
and input bounds (inactive at these speeds), and the nonlinearity of the model (angles of a
few milliradians). :func:`predicted_mission_time` therefore flies an obstacle-free mission.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.linalg import expm

from paper_repro.config import Config
from paper_repro.vehicles.quadrotor import (
    N_INPUTS,
    N_STATES,
    equilibrium,
    rk4_discretisation,
    symbolic_dynamics,
)

#: State indices of each motion at hover (the linearised axes decouple).
LATERAL = (0, 1, 3, 4, 6, 7, 9, 10)  # x, y, φ, θ, ẋ, ẏ, φ̇, θ̇
VERTICAL = (2, 8)  # z, ż
YAW = (5, 11)  # ψ, ψ̇
_AXES = {"lateral": LATERAL, "vertical": VERTICAL, "yaw": YAW}
N_EQ = 4  # a = (p_a, ψ_a)


@dataclass(frozen=True)
class ClockAnalysis:
    """The linearised, unconstrained tracking NMPC in closed loop with the plant at hover.

    Attributes
    ----------
    tau_lateral_s, tau_vertical_s, tau_yaw_s : s, time constant τ = −T_s/ln|λ| of the slowest
        closed-loop mode of each motion (the envelope of its exponential approach).
        ``tau_yaw_s`` is ``inf``: the OCP has no set-point on ψ (T weighs position only), so
        the loop keeps whatever yaw it has, a neutral mode with λ = 1.
    eigenvalues : (12,) complex, eigenvalues λ of the closed loop over one T_s, slowest first.
    axes : (12,) str, ``"lateral"``, ``"vertical"`` or ``"yaw"`` for each eigenvalue, from
        where its eigenvector lives.
    gain_state : K, (4, 12), N per state unit: u_0 = u_a + K·x + K_t·y_t.
    gain_target : K_t, (4, 3), N/m.
    closed_loop : A + B·K, (12, 12), one plant step T_s.
    target_input : B·K_t, (12, 3): x_{k+1} = A_cl·x_k + (B·K_t)·y_t.
    ts : T_s, s, the plant's (and controller's) sampling period.
    prediction_ts : h, s, the prediction model's step.
    horizon : N.
    """

    tau_lateral_s: float
    tau_vertical_s: float
    tau_yaw_s: float
    eigenvalues: np.ndarray
    axes: tuple[str, ...]
    gain_state: np.ndarray
    gain_target: np.ndarray
    closed_loop: np.ndarray
    target_input: np.ndarray
    ts: float
    prediction_ts: float
    horizon: int


def clock(config: Config | None = None) -> ClockAnalysis:
    """Closed-loop time constants of the tracking NMPC linearised at hover.

    Parameters
    ----------
    config : run configuration; uses ``quadrotor`` and ``nmpc`` (N, T_s, prediction step,
        Q, R, T). Obstacles, bounds and λ play no part (see the module docstring).

    Returns
    -------
    :class:`ClockAnalysis`.
    """
    cfg = config or Config()
    p = cfg.nmpc
    gain_x, gain_t = lq_feedback(cfg)
    a_p, b_p = plant_linearisation(cfg)
    a_cl = a_p + b_p @ gain_x
    lam, vec = np.linalg.eig(a_cl)
    order = np.argsort(-np.abs(lam))
    lam, vec = lam[order], vec[:, order]
    # Each eigenvector lives on one decoupled axis; the largest share of its energy names it.
    energy = np.abs(vec) ** 2
    shares = {name: energy[list(idx)].sum(axis=0) for name, idx in _AXES.items()}
    axes = tuple(max(shares, key=lambda n: shares[n][i]) for i in range(len(lam)))
    tau = {name: _time_constant(max((abs(v) for v, a in zip(lam, axes) if a == name),
                                    default=0.0), p.ts)
           for name in _AXES}
    return ClockAnalysis(tau["lateral"], tau["vertical"], tau["yaw"], lam, axes, gain_x,
                         gain_t, a_cl, b_p @ gain_t, p.ts, p.prediction_step, p.horizon)


def predicted_mission_time(config: Config | None = None, start=(22.0, -22.0, 0.0),
                           targets=((-12.0, 18.0, 11.0), (-21.0, 18.0, 0.0)),
                           tolerance: float | None = None, max_time: float = 20_000.0,
                           analysis: ClockAnalysis | None = None):
    """When the linearised closed loop reaches each target, ignoring obstacles.

    Starts at rest at ``start`` (yaw 0), heads for each target in turn and switches when the
    position is within ``tolerance`` of it, as :func:`paper_repro.sim.loop.simulate` does.
    The regions are ignored: this is the mission's clock, not its path.

    Parameters
    ----------
    config : run configuration.
    start : (3,) m, the paper's [22, −22, 0] by default.
    targets : (k, 3) m, the paper's [−12, 18, 11] then [−21, 18, 0] by default.
    tolerance : m, ``config.simulation.tolerance`` (0.3, *paper*) if omitted.
    max_time : s, give up after this long (targets not reached get ``inf``).
    analysis : a :func:`clock` of the same config, to skip recomputing it.

    Returns
    -------
    times : (k,) s, time at which each target is reached (cumulative, from the start).
    total : s, the mission time (the last entry of ``times``).
    """
    cfg = config or Config()
    tol = cfg.simulation.tolerance if tolerance is None else float(tolerance)
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tolerance must be a finite number > 0 (m), got {tolerance!r}")
    if not (np.isfinite(max_time) and max_time > 0):
        raise ValueError(f"max_time must be a finite number > 0 (s), got {max_time!r}")
    start = np.asarray(start, float)
    targets = np.atleast_2d(np.asarray(targets, float))
    if start.shape != (3,) or targets.ndim != 2 or targets.shape[1] != 3 or not (
            np.all(np.isfinite(start)) and np.all(np.isfinite(targets))):
        raise ValueError("start must be a finite (3,) and targets a finite (k, 3) array, m")
    an = analysis or clock(cfg)
    ts = an.ts
    # Error dynamics about the target's equilibrium: e_{k+1} = A_cl·e_k (translation
    # invariance of the linearised loop; checked in the tests). Blocks of `chunk` steps are
    # evaluated at once from precomputed powers, so the first crossing is found step-exactly.
    chunk = 1000
    powers = np.empty((chunk, N_STATES, N_STATES))
    m = np.eye(N_STATES)
    for i in range(chunk):
        m = an.closed_loop @ m
        powers[i] = m
    jump = powers[-1]
    state, _ = equilibrium(start)
    k, limit = 0, int(np.ceil(max_time / ts))
    times = np.full(len(targets), np.inf)
    for i, target in enumerate(targets):
        rest, _ = equilibrium(target)
        e = state - rest
        while k < limit:
            path = powers @ e  # (chunk, 12): e_{k+1}..e_{k+chunk}
            inside = np.flatnonzero(np.linalg.norm(path[:, :3], axis=1) < tol)
            if inside.size:
                step = int(inside[0]) + 1
                k += step
                e = path[step - 1]
                times[i] = k * ts
                break
            k += chunk
            e = jump @ e
        else:
            break
        state = e + rest
    return times, float(times[-1])


# --- levers: the clock under one changed parameter ------------------------------------------

def _scaled(values, factor, indices=None):
    out = list(values)
    for i in indices if indices is not None else range(len(out)):
        out[i] = float(out[i]) * factor
    return tuple(out)


LEVERS: dict[str, tuple[str, Callable]] = {
    "T": ("T / T_printed", lambda p, v: {"t": _scaled(p.t, v)}),
    "R": ("R / R_printed", lambda p, v: {"r": _scaled(p.r, v)}),
    "rate weights": ("Q_rates / printed (φ̇, θ̇, ψ̇)",
                     lambda p, v: {"q": _scaled(p.q, v, (9, 10, 11))}),
    "N": ("N", lambda p, v: {"horizon": int(v)}),
    "prediction_ts": ("h [s]", lambda p, v: {"prediction_ts": float(v)}),
}
"""The parameters that set the clock: name → (axis label, ``(NMPCParams, value) -> overrides``).
T, R and the rate weights are scaled by the value (1 is printed); N and h are set to it."""


def lever_config(lever: str, value: float, base: Config | None = None) -> Config:
    """``base`` (default :class:`Config`) with one lever of :data:`LEVERS` set to ``value``."""
    if lever not in LEVERS:
        raise ValueError(f"lever must be one of {sorted(LEVERS)}, got {lever!r}")
    base = base or Config()
    over = LEVERS[lever][1](base.nmpc, value)
    return dataclasses.replace(base, nmpc=dataclasses.replace(base.nmpc, **over))


def lever_sweep(lever: str, values, base: Config | None = None):
    """The linear loop's clock with one lever set to each of ``values``.

    Parameters
    ----------
    lever : a key of :data:`LEVERS`.
    values : factors (T, R, rate weights; 1 is printed) or values (N; h in s).
    base : the configuration changed (default :class:`Config`).

    Returns
    -------
    pandas DataFrame, one row per value: ``lever``, ``value``, ``tau_lateral_s``,
    ``tau_vertical_s``, ``first_target_s`` and ``mission_time_s`` of the obstacle-free paper
    mission (:func:`predicted_mission_time`), ``mission_ratio`` (to 500 s).
    """
    import pandas as pd

    rows = []
    for v in values:
        cfg = lever_config(lever, v, base)
        an = clock(cfg)
        times, total = predicted_mission_time(cfg, analysis=an)
        rows.append({"lever": lever, "value": float(v), "tau_lateral_s": an.tau_lateral_s,
                     "tau_vertical_s": an.tau_vertical_s, "first_target_s": float(times[0]),
                     "mission_time_s": total, "mission_ratio": total / PAPER_MISSION_TIME_S})
    return pd.DataFrame(rows)


# --- flights: the clock of a closed-loop run -------------------------------------------------

PAPER_MISSION_TIME_S = 500.0
"""s, the end of the paper's time axes (ticks 0…50, "×10", Figs. 4–8): the paper's mission."""

PAPER_AVOIDANCE_S = (50.0, 120.0)
"""s, "between 50 and 120 seconds": when the paper's avoidance phases happen (Section V)."""


def first_target_time(result) -> float:
    """s, when the first target was reached (NaN if it was not)."""
    k = int(np.asarray(result.reached)[0])
    return float(k * result.config.nmpc.ts) if k >= 0 else float("nan")


def avoidance_windows(result, merge_gap_s: float = 5.0) -> np.ndarray:
    """Intervals of the flight with a cloud within the LiDAR's range r_s (3 m).

    A step is *in avoidance* when the LiDAR returns a point (``visible_points > 0``): only
    then can a barrier term of eq. (20) act. Runs of such steps become intervals; two
    intervals less than ``merge_gap_s`` apart are one phase (a UAV skimming the edge of the
    sensing sphere sees a point come and go).

    Parameters
    ----------
    result : a :class:`~paper_repro.sim.result.SimulationResult`.
    merge_gap_s : s, >= 0.

    Returns
    -------
    (n, 2) array, s: start and end of each phase (end = time of its last step + T_s).
    """
    if not (np.isfinite(merge_gap_s) and merge_gap_s >= 0):
        raise ValueError(f"merge_gap_s must be a finite number >= 0 (s), got {merge_gap_s!r}")
    ts = result.config.nmpc.ts
    seen = np.asarray(result.visible_points) > 0
    edges = np.diff(np.concatenate([[0], seen.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out: list[list[float]] = []
    for a, b in zip(starts, ends, strict=True):
        t0, t1 = float(result.t[a]), float(result.t[b - 1]) + ts
        if out and t0 - out[-1][1] < merge_gap_s:
            out[-1][1] = t1
        else:
            out.append([t0, t1])
    return np.asarray(out, float).reshape(-1, 2)


def flight_clock(result, merge_gap_s: float = 5.0) -> dict:
    """The clock of one flight beside the paper's.

    Returns
    -------
    dict: ``mission_time_s`` (last target reached, NaN if not), ``first_target_s``,
    ``avoidance`` ((n, 2) s, :func:`avoidance_windows`), ``avoidance_span_s`` (start of the
    first phase, end of the last; NaNs when none), ``mission_ratio`` (mission time / 500 s),
    ``within_10_percent`` (of 500 s).
    """
    reached = np.asarray(result.reached)
    ts = result.config.nmpc.ts
    mission = float(reached[-1] * ts) if np.all(reached >= 0) else float("nan")
    windows = avoidance_windows(result, merge_gap_s)
    span = (float(windows[0, 0]), float(windows[-1, 1])) if len(windows) else (
        float("nan"), float("nan"))
    ratio = mission / PAPER_MISSION_TIME_S
    return {"mission_time_s": mission, "first_target_s": first_target_time(result),
            "avoidance": windows, "avoidance_span_s": span, "mission_ratio": ratio,
            "within_10_percent": bool(abs(ratio - 1.0) <= 0.10)}


def format_windows(windows: np.ndarray) -> str:
    """``"41–58, 112–131 s"``: avoidance windows for a table (``"–"`` when none)."""
    windows = np.asarray(windows, float).reshape(-1, 2)
    if not len(windows):
        return "–"
    return ", ".join(f"{a:.0f}–{b:.0f}" for a, b in windows) + " s"


def lq_feedback(config: Config | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First input of the linearised, unconstrained OCP as an affine feedback.

    Solves the equality-constrained LQ problem of the module docstring in the decision
    variables (u_0..u_{N−1}, a) exactly, through its KKT system, with one right-hand side per
    unit initial state and unit target.

    Returns
    -------
    K : (4, 12), N per state unit; K_t : (4, 3), N/m. The optimal first input is
    u_0 = u_a + K·x_0 + K_t·y_t (u_a = m·g/4).
    """
    cfg = config or Config()
    p = cfg.nmpc
    n, nx, nu = p.horizon, N_STATES, N_INPUTS
    a, b = prediction_linearisation(cfg)
    q, r, t = (np.diag(np.asarray(v, float)) for v in (p.q, p.r, p.t))
    e = equilibrium_map()
    nz = nu * n + N_EQ

    # x_j = Φ_j x_0 + Γ_j U; the stage residual is x_j − E a = Φ_j x_0 + L_j z, z = (U, a).
    phi = [np.eye(nx)]
    for _ in range(n):
        phi.append(a @ phi[-1])
    gam = np.zeros((n + 1, nx, nu * n))
    for j in range(1, n + 1):
        gam[j, :, : nu * (j - 1)] = a @ gam[j - 1, :, : nu * (j - 1)]
        gam[j, :, nu * (j - 1): nu * j] = b
    hess = np.zeros((nz, nz))
    lin_x = np.zeros((nz, nx))  # gradient = lin_x·x_0 + lin_t·y_t (factor 2 dropped)
    for j in range(n):
        lj = np.hstack([gam[j], -e])
        hess += lj.T @ q @ lj
        lin_x += lj.T @ q @ phi[j]
    hess[: nu * n, : nu * n] += np.kron(np.eye(n), r)
    sel = np.zeros((3, nz))
    sel[:, nu * n: nu * n + 3] = np.eye(3)  # p_a
    hess += sel.T @ t @ sel
    lin_t = -sel.T @ t
    # x_N = E a  ⇔  Γ_N U − E a = −Φ_N x_0.
    con = np.hstack([gam[n], -e])
    kkt = np.block([[hess, con.T], [con, np.zeros((nx, nx))]])
    rhs = np.vstack([np.hstack([-lin_x, -lin_t]),
                     np.hstack([-phi[n], np.zeros((nx, 3))])])
    # Row and column equilibration: the input-to-state blocks span h⁴ to 1 in scale.
    scale = 1.0 / np.sqrt(np.max(np.abs(kkt), axis=1))
    sol = scale[:, None] * np.linalg.solve(scale[:, None] * kkt * scale[None, :],
                                           scale[:, None] * rhs)
    u0 = sol[:nu]
    return u0[:, :nx], u0[:, nx:]


def prediction_linearisation(config: Config | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians (A, B) of the RK4 prediction model (eq. 1) at hover, step h.

    Returns (12, 12) and (12, 4) arrays; h = ``config.nmpc.prediction_step``.
    """
    cfg = config or Config()
    f = rk4_discretisation(cfg.nmpc.prediction_step, cfg.quadrotor)
    return _jacobians(f, cfg)


def plant_linearisation(config: Config | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The plant linearised at hover, discretised exactly over T_s under zero-order hold.

    Returns (12, 12) and (12, 4) arrays: exp(A_c T_s) and ∫₀^{T_s} exp(A_c s) ds · B_c.
    """
    cfg = config or Config()
    a_c, b_c = _jacobians(symbolic_dynamics(cfg.quadrotor), cfg)
    aug = np.zeros((N_STATES + N_INPUTS, N_STATES + N_INPUTS))
    aug[:N_STATES, :N_STATES], aug[:N_STATES, N_STATES:] = a_c, b_c
    d = expm(aug * cfg.nmpc.ts)
    return d[:N_STATES, :N_STATES], d[:N_STATES, N_STATES:]


def equilibrium_map() -> np.ndarray:
    """E, (12, 4): x_a = E·a for a = (p_a, ψ_a), the quadrotor's equilibrium states."""
    e = np.zeros((N_STATES, N_EQ))
    e[[0, 1, 2, 5], [0, 1, 2, 3]] = 1.0
    return e


def _jacobians(f: ca.Function, cfg: Config) -> tuple[np.ndarray, np.ndarray]:
    x = ca.SX.sym("x", N_STATES)
    u = ca.SX.sym("u", N_INPUTS)
    out = f(x, u)
    jac = ca.Function("hover_jacobians", [x, u], [ca.jacobian(out, x), ca.jacobian(out, u)])
    x0, u0 = equilibrium(np.zeros(3), 0.0, cfg.quadrotor)
    a, b = jac(x0, u0)
    return np.asarray(a), np.asarray(b)


def _time_constant(modulus: float, ts: float) -> float:
    """τ = −T_s/ln|λ| in s (0 for λ = 0, inf for |λ| = 1 to rounding, or above)."""
    if modulus <= 0.0:
        return 0.0
    if modulus >= 1.0 - 1e-12:  # yaw's neutral mode is 1 up to the KKT solve's rounding
        return float("inf")
    return float(-ts / np.log(modulus))
