"""Numbers that summarise a closed-loop run: solve times, chattering of the inputs, clearance.

The paper's comparison (Section V, Figs. 4 and 8) is visual: the smoothed distance gives
thrusts that "evolve continuously", the Euclidean one "high-frequency variations and
chattering". :func:`chattering_metrics` puts numbers on that, for thrusts u (K, 4) sampled at
T_s:

- total variation TV = Σ_k Σ_i |u_{k+1,i} − u_{k,i}|, N (a smooth signal's TV is its range
  swept; chattering adds twice its amplitude per oscillation);
- max |Δu|, N, the largest step-to-step jump;
- the share of the power of u above ``cutoff_hz`` and the RMS of that high-frequency part, N
  (Welch's power spectrum, :func:`input_spectrum`);
- the number of sign changes of Δu (direction reversals), ignoring |Δu| below a dead band.

Why 5 Hz: the prediction horizon is N·T_s = 0.35 s, so a manoeuvre the NMPC plans has a
time scale of at least about 1/0.35 s ≈ 2.9 Hz, and the mission's motion (≈0.3 m/s over
tens of metres) lives far below that. Content above 5 Hz, up to the Nyquist frequency of
50 Hz, cannot be a planned manoeuvre: it is step-to-step switching of the solution, i.e.
chattering.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

TIMING_COLUMNS = ("solve_mean_ms", "solve_median_ms", "solve_p95_ms", "solve_p99_ms",
                  "solve_max_ms", "wall_time_s", "steps_per_s")
"""Columns of :func:`summary_row` that the machine and its load determine, not the flight:
tables keep them apart (:func:`split_timings`), so that what a flight determines is
byte-stable."""

DEFAULT_CUTOFF_HZ = 5.0
"""Cut-off between planned motion and chattering, Hz (see the module docstring)."""

SPECTRUM_SEGMENT = 1024
"""Welch segment length, samples: 10.24 s at T_s = 0.01 s, a resolution of 0.1 Hz, far finer
than the 5 Hz cut-off."""

DEFAULT_DEADBAND = 1e-3
"""|Δu| below this (N) is solver noise, not a direction change: 1 mN, about 1e-4 of the
0–12 N input range and well above IPOPT's tolerance on the inputs."""


def chattering_metrics(u, ts: float, cutoff_hz: float = DEFAULT_CUTOFF_HZ,
                       deadband: float = DEFAULT_DEADBAND) -> dict:
    """Chattering of a sampled input signal.

    Parameters
    ----------
    u : (K,) or (K, m) array, one row per sampling instant (e.g. thrusts, N).
    ts : sampling time T_s, s.
    cutoff_hz : frequency above which energy counts as high-frequency, Hz;
        0 < cutoff < 1/(2·ts).
    deadband : |Δu| at or below this is ignored when counting sign changes (units of u).

    Returns
    -------
    dict with (sums over the m channels)
        ``total_variation`` : Σ|Δu|, units of u.
        ``max_abs_du`` : max |Δu|, units of u.
        ``hf_energy_fraction`` : share of the power of u above ``cutoff_hz``, in [0, 1], from
            :func:`input_spectrum` (Welch: slow trends removed, so a ramp is no chattering).
        ``hf_rms`` : RMS of the part of u above ``cutoff_hz``, units of u.
        ``du_sign_changes`` : number of reversals of the direction of u.
        ``cutoff_hz`` : the cut-off used.
    """
    u = _as_signal(u)
    _check_ts(ts)
    nyquist = 0.5 / ts
    if not (np.isfinite(cutoff_hz) and 0 < cutoff_hz < nyquist):
        raise ValueError(
            f"cutoff_hz must lie in (0, {nyquist:g}) Hz (the Nyquist frequency), got {cutoff_hz!r}")
    if not (np.isfinite(deadband) and deadband >= 0):
        raise ValueError(f"deadband must be a finite number >= 0, got {deadband!r}")

    du = np.diff(u, axis=0)
    freqs, psd = input_spectrum(u, ts)
    df = freqs[1] - freqs[0] if len(freqs) > 1 else 0.0
    high = freqs > cutoff_hz
    total = float(np.sum(psd[1:]) * df)
    hf_power = float(np.sum(psd[high]) * df)
    # A spectrum at rounding level (a ramp, a constant) has no shape to speak of.
    negligible = total <= 1e-24 * float(np.mean(np.sum(u**2, axis=1)))
    return {
        "total_variation": float(np.sum(np.abs(du))),
        "max_abs_du": float(np.max(np.abs(du))) if len(du) else 0.0,
        "hf_energy_fraction": 0.0 if negligible else min(1.0, hf_power / total),
        "hf_rms": 0.0 if negligible else float(np.sqrt(hf_power)),
        "du_sign_changes": int(sum(sign_changes(du[:, i], deadband) for i in range(u.shape[1]))),
        "cutoff_hz": float(cutoff_hz),
    }


def input_spectrum(u, ts: float, segment: int = SPECTRUM_SEGMENT):
    """Power spectral density of u, summed over channels (Welch's method).

    Hann windows of ``segment`` samples (fewer for a shorter signal), half overlapping, each
    with its least-squares line removed, so slow trends and the mismatch of the end points
    do not leak into high frequencies.

    Returns
    -------
    freqs : (F,) Hz.   psd : (F,) units of u squared per Hz; Σ psd·Δf over f > 0 is the
        power (mean square about the trends) of u.
    """
    from scipy.signal import welch

    u = _as_signal(u)
    _check_ts(ts)
    if len(u) < 4:
        return np.array([0.0]), np.zeros(1)
    nperseg = min(int(segment), len(u))
    freqs, psd = welch(u, fs=1.0 / ts, window="hann", nperseg=nperseg, detrend="linear",
                       axis=0)
    return freqs, psd.sum(axis=1)


def sign_changes(du, deadband: float = DEFAULT_DEADBAND) -> int:
    """Number of sign changes in the sequence ``du`` (1-D), skipping |du| ≤ ``deadband``.

    Steps inside the dead band are dropped, not treated as a sign, so a pause between two
    increases is no reversal.
    """
    du = np.asarray(du, float).ravel()
    s = np.sign(du[np.abs(du) > deadband])
    return int(np.count_nonzero(s[1:] != s[:-1]))


def tracking_error(result) -> np.ndarray:
    """e = y − y_t, (K, 3) m: position minus the set-point active at each step."""
    targets = np.asarray(result.targets, float)
    return result.positions[:-1] - targets[np.asarray(result.target_index, int)]


COLLISION_CLEARANCE = 0.35
"""m: a run *collides* when its true clearance drops below this, about the rotor arm
(h = 0.332 m, Table I): a rotor would touch a cloud point."""


def encounters(min_clearance, sensor_range: float) -> int:
    """How many runs met a region: their minimum clearance (m, one per run) fell within the
    LiDAR's ``sensor_range`` (m). A clear run that never met a region is no avoidance."""
    return int((np.asarray(min_clearance, float) < sensor_range).sum())


def region_distances(result) -> np.ndarray:
    """(K, n_regions) m: the true Euclidean distance from the output y_k (the position, the
    first p states of either vehicle) to each region where it is at t_k, over all its points
    (not only those the LiDAR sees); ``inf`` for a region without points. The minimum over
    regions is ``result.clearance``."""
    scene = result.scene
    y = np.asarray(result.x, float)[:-1, :scene.dim]
    t = np.asarray(result.t, float)
    out = np.full((len(y), len(scene.clouds)), np.inf)
    for i, cloud in enumerate(scene.clouds):
        if len(cloud):
            moved = y if scene.motions is None else y - scene.motions[i].offsets_at(t)
            out[:, i] = cKDTree(cloud).query(moved)[0]
    return out


def cbf_condition_share(result) -> float:
    """Share of the closed-loop steps k with a region in view (true distance ≤ the sensor's
    range) at which the discrete CBF condition (15), β(y_{k+1}) ≥ δ·β(y_k), fails for one of
    them, with β = ½d² − d_min on the true Euclidean distance d to the region where it is (the
    set that the barrier of either metric guards) and the run's δ and d_min. The paper's
    controller enforces (15) softly over its prediction; this counts what the closed loop did.
    NaN when no region came into view."""
    cfg = result.config
    d = region_distances(result)
    if len(d) < 2:
        return float("nan")
    beta = 0.5 * d**2 - cfg.barrier.d_min
    in_view = d[:-1] <= cfg.sensor.range
    with np.errstate(invalid="ignore"):  # inf − inf of a region without points: never in view
        failed = in_view & (beta[1:] < cfg.barrier.delta * beta[:-1])
    steps = in_view.any(axis=1)
    return float(failed.any(axis=1).sum() / steps.sum()) if steps.any() else float("nan")


SCAN_STEP_THRESHOLD = 0.01
"""A thrust step above this (N) at a change of the visible set counts as a jump (10 mN, ten
times the sign-change dead band)."""


SCAN_NEIGHBOURHOOD = 20
"""Steps (0.2 s at T_s = 0.01 s) either side of a change of the visible set whose thrust steps
are the comparison for the steps at the changes: the same phase of flight, near the same cloud.
All other steps would mostly be cruise in free space, where |Δu| is ~1e-10 N, and any step
near a cloud would look like a jump against them."""


def scan_changes(result) -> np.ndarray:
    """(K − 1,) bool, entry k − 1 true when scan k holds a different number of points from
    scan k − 1: the changes of the LiDAR's visible set (a proxy: a swap at equal count is
    missed). The one definition every measure and figure of scan changes reads."""
    return np.diff(np.asarray(result.visible_points)) != 0


def scan_change_steps(result, neighbourhood: int | None = SCAN_NEIGHBOURHOOD
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The thrust steps where the LiDAR's visible set changed, and those around them.

    Step k is max_i |u_{k,i} − u_{k−1,i}| (N), the largest rotor step into the first solve
    that sees scan k. It counts as a change of the visible set when scan k holds a different
    number of points from scan k − 1 (a proxy: a swap at equal count is missed).

    Parameters
    ----------
    result : a :class:`~paper_repro.sim.result.SimulationResult`.
    neighbourhood : the comparison steps are those within this many steps of a change (and
        not changes themselves); ``None``: every other step.

    Returns
    -------
    (at_changes, around) : 1-D arrays of |Δu| in N.
    """
    u = np.asarray(result.u, float)
    du = np.abs(np.diff(u, axis=0)).max(axis=1)
    change = scan_changes(result)
    if neighbourhood is None:
        return du[change], du[~change]
    near = np.zeros(len(change), bool)
    for k in np.flatnonzero(change):
        near[max(0, k - neighbourhood):k + neighbourhood + 1] = True
    return du[change], du[near & ~change]


def summary_row(result, cutoff_hz: float = DEFAULT_CUTOFF_HZ) -> dict:
    """One row of the summary table for a :class:`~paper_repro.sim.result.SimulationResult`.

    Times in ms (solves) and s (flight), thrusts in N, clearance in m.

    * ``outcome`` (``completed``, ``stalled``, ``step_limit``) and ``completed``: every target
      reached, or for a passage the finish line crossed; ``time_to_complete_s`` (NaN when not
      completed); ``mission_time_s``, the time the last target was reached (NaN if not).
    * ``collision``: clearance below :data:`COLLISION_CLEARANCE`; ``stalled``: the run ended
      in a deadlock (see :class:`~paper_repro.config.SimulationParams`).
    * chattering over the whole run (:func:`chattering_metrics`), with the total variation
      also per second of flight (``tv_u_rate_N_per_s``), so runs of different lengths compare.
    * solve times (median, p95, p99, max), ``failed_solves``, ``relaxed_solves`` (steps whose
      QP had no solution and was solved relaxed, :mod:`~paper_repro.solvers.relaxed_qp`),
      ``dropped_points`` (non-finite scan points) and ``fault_steps`` (steps without a usable
      state or solve).
    * ``steps_outside_state_box``: steps whose state lies outside the box 𝒳 of
      ``config.nmpc`` (where :meth:`~paper_repro.problem.ocp.OCP.state_box` relaxes the bounds of
      the non-position entries); NaN for a vehicle with another state.
    * the set-up's hazards (``meta["hazards"]``, :func:`paper_repro.sim.checks.setup_hazards`):
      ``start_unsafe``, ``target_unsafe``, ``target_unreachable``.
    * ``cbf_condition_violated_share``: the share of steps with a region in view at which the
      closed loop broke the discrete CBF condition (15) (:func:`cbf_condition_share`).
    * thrust steps at changes of the visible set (:func:`scan_change_steps`): ``scan_changes``,
      the median |Δu| there and within :data:`SCAN_NEIGHBOURHOOD` steps around them, and the
      share of changes with a step above :data:`SCAN_STEP_THRESHOLD`.
    * a flight against another plant, or with a latency (``config.plant``), adds
      :func:`plant_columns`.
    """
    row = {**_identity(result), **_outcome(result), **_solver_columns(result),
           **_hazard_columns(result), **_input_columns(result, cutoff_hz),
           **_scan_change_columns(result)}
    wall = float(result.meta.get("wall_time_s", float("nan")))
    row.update(wall_time_s=wall,
               steps_per_s=result.steps / wall if wall > 0 else float("nan"))
    if result.config.plant.simulator != "ours" or result.config.plant.latency_steps():
        row.update(plant_columns(result))
    return row


def _identity(result) -> dict:
    """Which run: its scene, metric, scenario, solver and length."""
    cfg = result.config
    return {"run": f"{result.scene.name}/{cfg.distance.metric}",
            "metric": cfg.distance.metric,
            "scenario": cfg.simulation.scenario,
            "scene": result.scene.name,
            "scene_fingerprint": result.scene.fingerprint(),
            "kind": cfg.simulation.kind,
            "solver": cfg.solver.nlp_solver,
            "steps": int(result.steps),
            "simulated_time_s": result.steps * cfg.nmpc.ts}


def _outcome(result) -> dict:
    """How the run ended, when, and how close it came."""
    ts = result.config.nmpc.ts
    reached = np.asarray(result.reached)
    completed = result.outcome == "completed"
    min_clearance = float(np.min(result.clearance))
    return {"outcome": result.outcome,
            "completed": completed,
            "targets_reached": f"{int(np.sum(reached >= 0))}/{len(reached)}",
            "time_to_complete_s": result.steps * ts if completed else float("nan"),
            "mission_time_s": (float(reached[-1] * ts) if bool(np.all(reached >= 0))
                               else float("nan")),
            "stalled": result.outcome == "stalled",
            "collision": min_clearance < COLLISION_CLEARANCE,
            "min_clearance_m": min_clearance}


def _solver_columns(result) -> dict:
    """Solve times (ms), iterations, failures, faults and the steps outside 𝒳."""
    solve_ms = np.asarray(result.solve_time, float) * 1e3
    x = np.asarray(result.x, float)[1:]  # the states reached, not the start
    box = result.config.quadrotor
    lower, upper = np.asarray(box.state_lower), np.asarray(box.state_upper)
    outside = (float(np.sum(np.any((x < lower) | (x > upper), axis=1)))
               if x.ndim == 2 and x.shape[1] == lower.size else float("nan"))
    return {"solve_mean_ms": float(np.mean(solve_ms)),
            "solve_median_ms": float(np.median(solve_ms)),
            "solve_p95_ms": float(np.percentile(solve_ms, 95)),
            "solve_p99_ms": float(np.percentile(solve_ms, 99)),
            "solve_max_ms": float(np.max(solve_ms)),
            "iterations_mean": float(np.mean(result.iterations)),
            "iterations_max": int(np.max(result.iterations)),
            "failed_solves": int(np.sum(~np.asarray(result.success, bool))),
            "relaxed_solves": int(np.sum(np.asarray(result.status) == "relaxed")),
            "dropped_points": int(np.sum(result.dropped_points)),
            "fault_steps": int(np.isin(result.status, ("state_fault", "solve_error")).sum()),
            "steps_outside_state_box": outside}


def _hazard_columns(result) -> dict:
    """The set-up's hazards (``meta["hazards"]``)."""
    hazards = result.meta.get("hazards") or {}
    return {"start_unsafe": bool(hazards.get("start_unsafe", False)),
            "target_unsafe": bool(any(hazards.get("targets_unsafe") or [])),
            "target_unreachable": bool(any(hazards.get("targets_unreachable") or []))}


def _input_columns(result, cutoff_hz: float) -> dict:
    """Chattering of the thrusts (:func:`chattering_metrics`) and the CBF condition's share."""
    chat = chattering_metrics(result.u, result.config.nmpc.ts, cutoff_hz)
    return {"tv_u_N": chat["total_variation"],
            "tv_u_rate_N_per_s": (chat["total_variation"]
                                  / (result.steps * result.config.nmpc.ts)),
            "max_abs_du_N": chat["max_abs_du"],
            "hf_energy_fraction": chat["hf_energy_fraction"],
            "hf_rms_N": chat["hf_rms"],
            "du_sign_changes": chat["du_sign_changes"],
            "cutoff_hz": chat["cutoff_hz"],
            "cbf_condition_violated_share": cbf_condition_share(result)}


def _scan_change_columns(result) -> dict:
    """Thrust steps at changes of the visible set (:func:`scan_change_steps`)."""
    at_changes, around = scan_change_steps(result)
    return {"scan_changes": int(len(at_changes)),
            "du_scan_change_median_N": _median(at_changes),
            "du_around_changes_median_N": _median(around),
            "scan_change_jump_share": (float(np.mean(at_changes > SCAN_STEP_THRESHOLD))
                                       if len(at_changes) else float("nan"))}


def plant_columns(result) -> dict:
    """What a flight against another plant, or with a latency, adds to its row.

    * ``saturation_time_s``: time with a rotor at a bound of 𝒰 (within 1 mN), s;
    * ``body_rate_rms_rad_s``: RMS of the body rates ‖(p, q, r)‖ from the Euler angles and
      their rates (ZYX), rad/s;
    * ``margin_time_s``: time inside the barrier's margin, clearance below √(2·d_min) (the
      ½d² reading of d_min), s;
    * ``calls_over_ts``: solves longer than T_s.
    """
    cfg, ts = result.config, result.config.nmpc.ts
    u = np.asarray(result.u, float)
    lower, upper = np.asarray(cfg.quadrotor.input_lower), np.asarray(cfg.quadrotor.input_upper)
    at_bound = np.any((u <= lower + 1e-3) | (u >= upper - 1e-3), axis=1)
    margin = np.sqrt(2 * cfg.barrier.d_min)
    return {"saturation_time_s": float(np.sum(at_bound) * ts),
            "body_rate_rms_rad_s": float(np.sqrt(np.mean(np.sum(
                body_rates(np.asarray(result.x, float)[1:]) ** 2, axis=1)))),
            "margin_time_s": float(np.sum(np.asarray(result.clearance) < margin) * ts),
            "calls_over_ts": int(np.sum(np.asarray(result.solve_time, float) > ts))}


def body_rates(x) -> np.ndarray:
    """(K, 3) body rates (p, q, r), rad/s, of quadrotor states x (K, 12): Euler angles
    (φ, θ, ψ) in x[:, 3:6] and their rates in x[:, 9:12], R = Rz(ψ)Ry(θ)Rx(φ)."""
    phi, theta = x[:, 3], x[:, 4]
    dphi, dtheta, dpsi = x[:, 9], x[:, 10], x[:, 11]
    return np.column_stack([dphi - dpsi * np.sin(theta),
                            dtheta * np.cos(phi) + dpsi * np.cos(theta) * np.sin(phi),
                            -dtheta * np.sin(phi) + dpsi * np.cos(theta) * np.cos(phi)])


def split_timings(table, columns=TIMING_COLUMNS):
    """``(flight, timings)``: ``table`` without ``columns``, and those columns alone (with
    the table's index)."""
    timing = [c for c in columns if c in table.columns]
    return table.drop(columns=timing), table[timing]


def _median(values) -> float:
    return float(np.median(values)) if len(values) else float("nan")


def summary_table(results, cutoff_hz: float = DEFAULT_CUTOFF_HZ):
    """pandas DataFrame, one row per run (indexed by ``run``, e.g. ``"paper/smooth"``)."""
    import pandas as pd

    rows = [summary_row(r, cutoff_hz) for r in results]
    if not rows:
        raise ValueError("summary_table needs at least one result")
    return pd.DataFrame(rows).set_index("run")


def _as_signal(u) -> np.ndarray:
    u = np.asarray(u, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    if u.ndim != 2 or len(u) == 0:
        raise ValueError(f"u must have shape (K,) or (K, m) with K >= 1, got {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("u must contain only finite values")
    return u


def _check_ts(ts) -> None:
    if not (np.isfinite(ts) and ts > 0):
        raise ValueError(f"ts must be a finite number > 0 (s), got {ts!r}")
