"""Could any vehicle as agile as the quadrotor have flown a moving scene without a collision?

A controller that collides on a crossing is at fault only if the crossing could be flown at all.
This module answers that question apart from every controller of the package: it searches for a
passage of a *point mass* with the quadrotor's velocity bounds and its tilt-limited acceleration,
which knows every region's future motion (full foresight) and sees the whole scene (no 3 m
LiDAR). Such a vehicle is at least as agile as the quadrotor: the quadrotor's centre of mass
moves with the same bounds, and has attitude dynamics and a short sensing range on top.

The search (:func:`find_passage`)
  * The point mass p̈ = a with piecewise-constant a on a coarse grid (``dt``, 0.25 s), so that
    p(t) between the grid points is exact (a double integrator), over the whole passage
    (``horizon``, the study's step limit): starts at rest at the scene's start, ends past its
    finish line, stays in the 50 × 50 × 25 m workspace.
  * Bounds: |v_x|, |v_y| ≤ 5 m/s and |v_z| ≤ 3 m/s (the quadrotor's 𝒳); |a_x|, |a_y| ≤ g·tan θ_max
    (5.66 m/s² at the 30° tilt bound), −g ≤ a_z ≤ 4·f_max/m − g (11.6 m/s²). A box of
    accelerations holds the quadrotor's tilt cone, so it is at least as agile.
  * IPOPT minimises Σ‖a_k‖²·dt. The clearance constraints ‖p(t) − a_ij(t)‖ ≥ r are added where
    they are needed (constraint generation): after each solve, p(t) is checked every 10 ms
    against every point of every region where the region is at t; the closest points of the
    closest approaches below r + ``margin`` become constraints at those very times (p(t) is
    linear in the grid's variables), and IPOPT solves again, warm-started.
  * A passage is *verified* when the check at 10 ms finds every clearance ≥ r: it is a proof
    that the crossing is avoidable (for the point mass, up to the 10 ms sampling).
  * Several first guesses (straight at several speeds, a wait, detours to either side and
    above): IPOPT is local, so a crossing is declared ``"no_passage_found"`` only when none of
    them leads to a verified passage. That is the outcome of a search, not a proof; the report
    says so.

r is :data:`~paper_repro.analysis.metrics.COLLISION_CLEARANCE` (0.35 m), the clearance below
which a run counts as a collision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.spatial import cKDTree

from paper_repro.analysis.metrics import COLLISION_CLEARANCE
from paper_repro.config import Config
from paper_repro.validation import is_number, require_int, require_positive

FINE_STEP = 0.01
"""s: the check of a passage samples p(t) at this step (the controller's T_s)."""

# --- the vehicle: the quadrotor's bounds on a point mass -----------------------------------------


@dataclass(frozen=True)
class PointMassBounds:
    """Boxes on the velocity (m/s) and the acceleration (m/s²) of the point mass, (3,) each, and
    the workspace it stays in (m)."""

    velocity_lower: tuple
    velocity_upper: tuple
    acceleration_lower: tuple
    acceleration_upper: tuple
    position_lower: tuple
    position_upper: tuple

    @classmethod
    def of_quadrotor(cls, config: Config | None = None) -> PointMassBounds:
        """The bounds of ``config``'s quadrotor: velocities and workspace from 𝒳
        (``quadrotor.state_lower``/``state_upper``), lateral acceleration g·tan θ_max at the tilt
        bound, vertical acceleration from −g to 4·f_max/m − g."""
        cfg = config or Config()
        q = cfg.quadrotor
        lo, hi = np.asarray(q.state_lower), np.asarray(q.state_upper)
        tilt = min(abs(lo[3]), hi[3], abs(lo[4]), hi[4])
        lateral = q.gravity * math.tan(tilt)
        up = 4 * max(q.input_upper) / q.mass - q.gravity
        return cls(tuple(lo[6:9]), tuple(hi[6:9]), (-lateral, -lateral, -q.gravity),
                   (lateral, lateral, up), tuple(lo[:3]), tuple(hi[:3]))


# --- the answer ------------------------------------------------------------------------------


@dataclass
class Passage:
    """The outcome of :func:`find_passage` for one scene.

    Attributes
    ----------
    outcome : ``"avoidable"`` (a passage was found and verified) or ``"no_passage_found"``
        (no first guess led to one: a search, not a proof).
    clearance : m, the verified passage's minimum clearance every 10 ms (NaN when none).
    time : s, when the passage crosses the finish line (NaN when none).
    guess : name of the first guess that led to it (``""`` when none).
    t, p : (n,) s and (n, 3) m, the passage sampled every 10 ms up to the horizon (empty when
        none).
    tries : per first guess, (rounds of constraint generation, constraints, final minimum
        clearance in m, IPOPT's status).
    """

    outcome: str
    clearance: float
    time: float
    guess: str
    t: np.ndarray
    p: np.ndarray
    tries: dict

    @property
    def avoidable(self) -> bool:
        return self.outcome == "avoidable"


def find_passage(scene, horizon: float, config: Config | None = None, dt: float = 0.25,
                 clearance: float = COLLISION_CLEARANCE, margin: float = 0.15,
                 rounds: int = 25, guesses: tuple | None = None,
                 solid: bool = True) -> Passage:
    """Search for a collision-free passage of ``scene`` (start at rest → past the finish line)
    by the point mass of :class:`PointMassBounds` with full foresight; see the module's text.

    Parameters
    ----------
    scene : a :class:`~paper_repro.world.scene.Scene` with a ``finish`` line (a passage).
    horizon : s > 0, the time allowed (e.g. the study's step limit × T_s).
    config : gives the quadrotor's bounds (default: the printed set-up).
    dt : s > 0, the step of the coarse grid.
    clearance : m > 0, r: the passage must keep at least this from every point.
    margin : m ≥ 0, constraints are added for approaches below r + margin and ask for
        r + margin, so that the 10 ms check passes with fewer rounds.
    rounds : solves per first guess, at most.
    guesses : names among :data:`GUESSES` to try, in order (default: all).
    solid : regions are solid (default): each cloud is completed by a lattice of its shape's
        interior (:func:`solid_spacing`), so that no passage threads the gaps of a sampled
        cloud. ``False`` checks the cloud points alone, the collision test of the studies.
    """
    if getattr(scene, "finish", None) is None:
        raise ValueError(f"scene {getattr(scene, 'name', scene)!r} has no finish line: the "
                         "avoidability check needs a passage (a random or crossing scene)")
    require_positive("horizon", horizon)
    require_positive("dt", dt)
    require_positive("clearance", clearance)
    if not (is_number(margin) and math.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a finite number >= 0 (m), got {margin!r}")
    require_int("rounds", rounds, 1)
    if not isinstance(solid, bool):
        raise ValueError(f"solid must be True or False, got {solid!r}")
    names = tuple(GUESSES) if guesses is None else tuple(guesses)
    unknown = [g for g in names if g not in GUESSES]
    if unknown or not names:
        raise ValueError(f"guesses must be a non-empty selection of {tuple(GUESSES)}, got "
                         f"{guesses!r}")
    problem = _Problem(scene, PointMassBounds.of_quadrotor(config), horizon, dt,
                       solid_spacing(clearance) if solid else None)
    tries = {}
    for name in names:
        found, record = problem.solve(GUESSES[name](problem), clearance, margin, rounds)
        tries[name] = record
        if found is not None:
            t, p = problem.sample(found)
            return Passage("avoidable", problem.min_clearance(t, p), problem.finish_time(t, p),
                           name, t, p, tries)
    return Passage("no_passage_found", math.nan, math.nan, "", np.zeros(0), np.zeros((0, 3)),
                   tries)


def solid_spacing(clearance: float) -> float:
    """m: the spacing s of a cubic lattice whose every point of space lies within
    ``clearance`` of a node (s·√3/2 = clearance)."""
    return 2.0 * clearance / math.sqrt(3.0)


def interior_lattice(shape, spacing: float) -> np.ndarray:
    """(n, 3) m: the nodes of a cubic lattice of ``spacing`` inside ``shape`` (its
    ``bounds()`` and ``contains``), the region's points where its offset is zero."""
    lo, hi = (np.asarray(b, float) for b in shape.bounds())
    axes = [np.arange(lo[i], hi[i] + 1e-9, spacing) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid[shape.contains(grid)]


# --- the transcription -----------------------------------------------------------------------


class _Problem:
    """The double integrator on the coarse grid, the scene's regions as KD-trees, and the check
    every 10 ms."""

    def __init__(self, scene, bounds: PointMassBounds, horizon: float, dt: float,
                 spacing: float | None):
        self.scene, self.bounds, self.dt = scene, bounds, float(dt)
        self.K = max(1, int(math.ceil(horizon / dt)))
        self.start = np.asarray(scene.start, float)
        point, direction = (np.asarray(v, float) for v in scene.finish)
        self.finish_point, self.finish_dir = point, direction / np.linalg.norm(direction)
        self.clouds = [np.asarray(c, float) for c in scene.clouds]
        if spacing is not None:
            self.clouds = [np.concatenate([c, interior_lattice(r.shape, spacing)])
                           for c, r in zip(self.clouds, scene.regions, strict=True)]
        self.trees = [cKDTree(c) for c in self.clouds]
        self.motions = scene.motions or (None,) * len(self.clouds)

    # The path: grid variables w = (p_0..p_K, v_0..v_K, a_0..a_{K-1}), p(t) exact in between.

    def split(self, w):
        K = self.K
        p = ca.reshape(w[:3 * (K + 1)], 3, K + 1)
        v = ca.reshape(w[3 * (K + 1):6 * (K + 1)], 3, K + 1)
        a = ca.reshape(w[6 * (K + 1):], 3, K)
        return p, v, a

    def position_at(self, w, t: float):
        """p(t) as an expression of the grid variables (linear in them)."""
        p, v, a = self.split(w)
        k = min(int(t // self.dt), self.K - 1)
        tau = t - k * self.dt
        return p[:, k] + v[:, k] * tau + 0.5 * a[:, k] * tau**2

    def sample(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(t, p(t)) every 10 ms over the horizon, from the solution's grid values."""
        K, dt = self.K, self.dt
        p = w[:3 * (K + 1)].reshape(K + 1, 3)
        v = w[3 * (K + 1):6 * (K + 1)].reshape(K + 1, 3)
        a = w[6 * (K + 1):].reshape(K, 3)
        t = np.arange(0.0, K * dt + 1e-9, FINE_STEP)
        k = np.minimum((t // dt).astype(int), K - 1)
        tau = (t - k * dt)[:, None]
        return t, p[k] + v[k] * tau + 0.5 * a[k] * tau**2

    def offset(self, i: int, t: float) -> np.ndarray:
        m = self.motions[i]
        return np.zeros(3) if m is None else m.offset(t)

    def nearest(self, t: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n, regions) distances from p(t) to each region where it is at t, and the index of
        the nearest point of each."""
        dist = np.full((len(t), len(self.clouds)), np.inf)
        index = np.zeros((len(t), len(self.clouds)), int)
        for i, tree in enumerate(self.trees):
            if len(self.clouds[i]) == 0:
                continue
            shift = self.motions[i].offsets_at(t) if self.motions[i] else 0.0
            dist[:, i], index[:, i] = tree.query(p - shift)
        return dist, index

    def min_clearance(self, t, p) -> float:
        upto = self._before_finish(t, p)
        return float(self.nearest(t[:upto], p[:upto])[0].min())

    def _before_finish(self, t, p) -> int:
        """Samples up to the first one past the finish line (the passage ends there)."""
        past = np.nonzero((p - self.finish_point) @ self.finish_dir >= 0)[0]
        return len(t) if len(past) == 0 else int(past[0]) + 1

    def finish_time(self, t, p) -> float:
        return float(t[self._before_finish(t, p) - 1])

    def solve(self, guess: np.ndarray, clearance: float, margin: float, rounds: int):
        """Constraint generation from ``guess``: (verified grid values or None, record)."""
        constraints: list = []  # (t, region, point)
        w0, status, worst = guess, "", math.nan
        for r in range(1, rounds + 1):
            w, status = self._ipopt(w0, constraints, clearance + margin)
            if w is None:
                return None, (r, len(constraints), worst, status)
            t, p = self.sample(w)
            upto = self._before_finish(t, p)
            dist, index = self.nearest(t[:upto], p[:upto])
            worst = float(dist.min())
            if worst >= clearance:
                return w, (r, len(constraints), worst, status)
            new = self._closest_approaches(t[:upto], dist, index, clearance + margin)
            constraints.extend(c for c in new if c not in constraints)
            w0 = w
        return None, (rounds, len(constraints), worst, status)

    @staticmethod
    def _closest_approaches(t, dist, index, below: float) -> list:
        """(t, region, point) at each local minimum of a region's distance below ``below``, and
        at the samples 50 ms either side (a region is passed over a stretch of time)."""
        out = []
        for i in range(dist.shape[1]):
            d = dist[:, i]
            close = np.nonzero(d < below)[0]
            if len(close) == 0:
                continue
            # Local minima among the close samples, and the two ends of every close stretch.
            keep = {int(close[0]), int(close[-1])}
            for j in close:
                if (j == 0 or d[j] <= d[j - 1]) and (j == len(d) - 1 or d[j] <= d[j + 1]):
                    keep.add(int(j))
            breaks = np.nonzero(np.diff(close) > 1)[0]
            keep.update(int(close[b]) for b in breaks)
            keep.update(int(close[b + 1]) for b in breaks)
            for j in sorted(keep):
                for s in (j - 5, j, j + 5):
                    if 0 <= s < len(t):
                        out.append((round(float(t[s]), 6), i, int(index[s, i])))
        return list(dict.fromkeys(out))

    def _ipopt(self, w0, constraints, radius: float):
        K, dt, b = self.K, self.dt, self.bounds
        n = 9 * K + 6
        w = ca.MX.sym("w", n)
        p, v, a = self.split(w)
        g, lbg, ubg = [], [], []
        # The double integrator, exact for piecewise-constant a.
        g.append(ca.vec(p[:, 1:] - p[:, :-1] - dt * v[:, :-1] - 0.5 * dt**2 * a))
        g.append(ca.vec(v[:, 1:] - v[:, :-1] - dt * a))
        lbg += [0.0] * (6 * K)
        ubg += [0.0] * (6 * K)
        # Past the finish line at the end of the horizon.
        g.append(ca.dot(p[:, K] - self.finish_point, self.finish_dir))
        lbg.append(0.0)
        ubg.append(ca.inf)
        for t, i, j in constraints:
            d = self.position_at(w, t) - (self.clouds[i][j] + self.offset(i, t))
            g.append(ca.dot(d, d))
            lbg.append(radius**2)
            ubg.append(ca.inf)
        lbw = np.concatenate([np.tile(b.position_lower, K + 1), np.tile(b.velocity_lower, K + 1),
                              np.tile(b.acceleration_lower, K)])
        ubw = np.concatenate([np.tile(b.position_upper, K + 1), np.tile(b.velocity_upper, K + 1),
                              np.tile(b.acceleration_upper, K)])
        lbw[:3] = ubw[:3] = self.start  # at rest at the start
        lbw[3 * (K + 1):3 * (K + 1) + 3] = ubw[3 * (K + 1):3 * (K + 1) + 3] = 0.0
        solver = ca.nlpsol("passage", "ipopt",
                           {"x": w, "f": ca.sumsqr(a) * dt, "g": ca.vertcat(*g)},
                           {"ipopt.print_level": 0, "print_time": False,
                            "ipopt.max_iter": 500, "ipopt.tol": 1e-6,
                            "ipopt.sb": "yes"})
        sol = solver(x0=np.clip(w0, lbw, ubw), lbx=lbw, ubx=ubw, lbg=np.array(lbg),
                     ubg=np.array(ubg))
        status = solver.stats()["return_status"]
        if status not in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
            return None, status
        return np.asarray(sol["x"]).ravel(), status


# --- first guesses ---------------------------------------------------------------------------


def _through(problem: _Problem, waypoints, speed: float, wait: float = 0.0) -> np.ndarray:
    """Grid values of a path from the start through ``waypoints`` (m) to 2 m past the finish
    line at ``speed`` (m/s) after ``wait`` s at rest, then at rest; velocities by differences,
    accelerations zero (IPOPT makes them consistent)."""
    K, dt = problem.K, problem.dt
    end = problem.finish_point + 2.0 * problem.finish_dir
    corners = np.array([problem.start, *waypoints, end])
    lengths = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(lengths)])
    t = np.arange(K + 1) * dt
    s = np.clip((t - wait) * speed, 0.0, along[-1])
    p = np.stack([np.interp(s, along, corners[:, c]) for c in range(3)], axis=1)
    lo, hi = np.asarray(problem.bounds.position_lower), np.asarray(problem.bounds.position_upper)
    p = np.clip(p, lo, hi)
    v = np.vstack([np.diff(p, axis=0) / dt, np.zeros((1, 3))])
    return np.concatenate([p.ravel(), v.ravel(), np.zeros(3 * K)])


def _detour(problem: _Problem, side: np.ndarray, speed: float) -> np.ndarray:
    middle = 0.5 * (problem.start + problem.finish_point)
    return _through(problem, [middle + side], speed)


def _lateral(problem: _Problem) -> np.ndarray:
    d = problem.finish_point - problem.start
    side = np.cross(d, [0.0, 0.0, 1.0])
    return side / (np.linalg.norm(side) or 1.0)


GUESSES = {
    "straight-1": lambda pb: _through(pb, [], 1.0),
    "straight-3": lambda pb: _through(pb, [], 3.0),
    "straight-5": lambda pb: _through(pb, [], 5.0),
    "wait-10-s": lambda pb: _through(pb, [], 2.0, wait=10.0),
    "left": lambda pb: _detour(pb, 6.0 * _lateral(pb), 2.0),
    "right": lambda pb: _detour(pb, -6.0 * _lateral(pb), 2.0),
    "over": lambda pb: _detour(pb, np.array([0.0, 0.0, 6.0]), 2.0),
}
"""First guesses of the search, by name: straight to the finish line at 1, 3 and 5 m/s, a 10 s
wait then straight at 2 m/s, and 6 m detours to either side and above at 2 m/s."""


def passage_row(seed: int, passage: Passage) -> dict:
    """One row of an avoidability table: the scene's seed, the outcome and the passage's
    numbers."""
    return {"scene_seed": int(seed), "outcome": passage.outcome,
            "avoidable": passage.avoidable, "clearance_m": passage.clearance,
            "finish_time_s": passage.time, "guess": passage.guess,
            "guesses_tried": len(passage.tries)}


