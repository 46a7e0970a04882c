"""A guide for the tracking NMPC: a path through what the local map has seen, and the
set-point it hands the controller.

The paper's NMPC is local. Its set-point is the final target, so a concave obstacle between
the two (a U-channel, a wall with a window, a T-wall across the line) is a trap where it
stalls. Its tracking formulation is built for the remedy: the artificial equilibrium keeps the
problem feasible under changing, piecewise-constant set-points. :class:`Guide` supplies them,
from a path on the :class:`~paper_repro.world.local_map.VoxelMap`:

* **The grid.** The workspace box is cut into cubic cells of side ``cell`` (1 m). A cell is
  *blocked* when an occupied voxel's point lies within ``inflation`` (2 m) of its centre:
  the safe distance √(2·d_min) = 1.41 m of the printed barrier, and a little more. Unknown
  space counts as free, so with an empty map the path is the straight line and the guide
  hands over the final target, exactly as the paper.
* **The path.** The shortest path on the 26-connected grid of free cells, from the free
  cells around the vehicle (each entered at its distance from the vehicle) to the goal's
  cell: A* under the straight-line heuristic, which is consistent on this grid, so the path
  is as short as Dijkstra's algorithm over the whole grid would make it, at a small share of
  its cost (``_grid_path.c``, built once per machine like the map). A metre up or down
  costs ``climb`` (2) metres along the level, so the path keeps the flight's altitude unless
  a way over or under is much shorter. It is replanned when the map changes the path: every
  ``check_period`` (0.1 s) the voxels that became occupied since the last plan block their
  cells, and a path that crosses a newly blocked cell is planned again, at most once per
  ``replan_period`` (1 s). A path that stays free is kept, so the guide does not hesitate
  between two ways round an obstacle.
* **The set-point.** At each check the guide takes the path's *look-ahead point*: the farthest
  path cell within ``lookahead`` (8 m) that the vehicle sees along a free straight segment.
  The set-point y_t lies in the level direction of that point, at its altitude, as far away
  as the path still has to run to the goal. Under the printed weights the vehicle approaches
  its set-point at about (distance)/150 s (:mod:`paper_repro.analysis.clock`), so a set-point
  a few metres ahead would crawl; this one pulls the vehicle along the path as hard as the
  final target pulls it along the straight line. When the goal itself is in sight, y_t is the
  goal, and with an empty map that is at once: the paper's set-point.
* **When stuck.** A vehicle that moved less than :data:`STUCK_DISTANCE` over ``stuck_time``
  (2.5 s) far from the goal is in a trap the grid does not show (a gap wider than the
  inflation that the NMPC still cannot pass): the cells between it and its aim are avoided
  from then on, and the path is planned again, before the closed loop would call it stalled.

Feasible and smooth:

* y_t is never in a blocked cell, hence never within ``inflation`` of a mapped point, so never
  in the unsafe set D < d_min of what the map has seen, and it is inside the workspace box
  (the λ-relaxed box of the artificial equilibrium). It is the farthest free point of its ray;
  the ray is cut at the box, never bent along it, so the pull keeps its direction.
* y_t is piecewise constant, for at least ``check_period``. The level direction of the pull
  turns by at most ``max_turn`` (3°) per check, 30°/s, towards the look-ahead point: a new
  look-ahead point, a new path or the goal coming into sight never makes the pull swing. The
  artificial equilibrium absorbs each small move, as at the switch between two targets of the
  paper's mission.

Optionally filtered: with ``set_point_filter`` τ > 0 the set-point handed over is a first-order
filter of the one above, y_f ← y_f + (1 − e^(−Δt/τ))·(y_t − y_f) at every call, so it glides
where y_t steps every check. It is then a convex combination of past set-points: inside the
box, but no longer kept out of blocked cells; the barrier keeps the vehicle clear.

A :class:`Guide` is numpy, with its search in C; its cost is reported by ``stats``.
"""

from __future__ import annotations

import ctypes
import functools
import itertools
import math
import time
from collections import deque
from importlib import resources

import numpy as np

from paper_repro._native import load_library
from paper_repro.validation import require_positive

STUCK_DISTANCE = 0.05
"""m: a vehicle that moves less than this over ``stuck_time`` is stuck (a mean speed below
2 cm/s for the default 2.5 s; the closed loop calls a run stalled after 5 s below 1 cm/s)."""

NEIGHBOURS = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if any(d)])
"""The 26 offsets of a cell's neighbours, (26, 3)."""


class Guide:
    """The path on a voxel map's inflated occupancy, and the set-point it hands the NMPC.

    Parameters
    ----------
    lower, upper : (3,) corners of the box the path and the set-points stay in, m (the
        λ-relaxed position box of the artificial equilibrium).
    cell : side of a grid cell, m (> 0).
    inflation : m (> 0): a cell is blocked when an occupied voxel's point lies within this of
        its centre.
    lookahead : m (≥ cell): the look-ahead point is the farthest path cell within this that the
        vehicle sees along a free segment.
    check_period, replan_period : s (> 0): how often the map is read and the look-ahead point
        moved on, and the least time between two plans.
    max_turn : degrees (> 0): the most the pull turns (in the horizontal plane) per check.
    climb : (> 0) what a metre up or down costs the path, in metres along the level.
    stuck_time : s (> 0): a vehicle that moved less than :data:`STUCK_DISTANCE` over this
        long, farther than ``lookahead`` from the goal, is stuck: the cells between it and its
        aim are avoided from then on, and the path is planned again.
    set_point_filter : s (≥ 0): time constant of the filter on the set-point handed over (0:
        none, the piecewise-constant set-point itself).
    """

    def __init__(self, lower, upper, cell: float = 1.0, inflation: float = 2.0,
                 lookahead: float = 8.0, check_period: float = 0.1,
                 replan_period: float = 1.0, max_turn: float = 3.0, climb: float = 2.0,
                 stuck_time: float = 2.5, set_point_filter: float = 0.5):
        for name, value in (("cell", cell), ("inflation", inflation), ("max_turn", max_turn),
                            ("climb", climb), ("stuck_time", stuck_time),
                            ("check_period", check_period), ("replan_period", replan_period)):
            require_positive(name, value)
        if not (math.isfinite(set_point_filter) and set_point_filter >= 0):
            raise ValueError(f"set_point_filter must be a finite number >= 0 s, got "
                             f"{set_point_filter!r}")
        if not (math.isfinite(lookahead) and lookahead >= cell):
            raise ValueError(f"lookahead must be a finite number >= cell = {cell} m, got "
                             f"{lookahead!r}")
        lo, hi = np.asarray(lower, float), np.asarray(upper, float)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
            raise ValueError(f"lower and upper must be (3,) corners with upper > lower, got "
                             f"{lower!r} and {upper!r}")
        self.lower, self.upper, self.cell = lo, hi, float(cell)
        self.inflation, self.lookahead = float(inflation), float(lookahead)
        self.check_period, self.replan_period = float(check_period), float(replan_period)
        self.max_turn, self.climb = math.radians(max_turn), float(climb)
        self.stuck_time, self.set_point_filter = float(stuck_time), float(set_point_filter)
        self.shape = tuple(int(n) for n in np.maximum(np.ceil((hi - lo) / cell), 1))
        self._counts = np.array(self.shape)
        # What a step to each neighbour costs, m: its length, a metre up or down weighing climb.
        self._steps = np.array([self.cell * float(np.linalg.norm(d * (1.0, 1.0, self.climb)))
                                for d in NEIGHBOURS])
        reach = int(math.ceil(self.inflation / self.cell)) + 1
        self._stencil = np.array(list(itertools.product(range(-reach, reach + 1), repeat=3)))
        # Blocked cells near the vehicle are not counted against a segment that starts there:
        # the barrier keeps the vehicle about √(2·d_min) from a wall, inside the inflation.
        self._skip = self.inflation + math.sqrt(3.0) * self.cell / 2
        near = int(math.ceil(self._skip / self.cell)) + 1  # the cells a plan may start from
        self._near = np.array(list(itertools.product(range(-near, near + 1), repeat=3)))
        self.reset()

    def reset(self) -> None:
        """Forget the map, the path and the set-point (a new flight)."""
        self.blocked = np.zeros(int(np.prod(self.shape)), bool)
        self.avoid = np.zeros_like(self.blocked)  # cells the vehicle got stuck in front of
        self.trail = deque()                 # (t, y) of the checks over the last stuck_time
        self.mapped = np.zeros(0, np.int64)  # map keys behind ``blocked``, sorted
        self.path = None                     # (m, 3) points, the goal last
        self.remaining = None                # (m,) m, path length from each point to the goal
        self.progress = 0                    # index of the path point the vehicle is at
        self.ahead = None                    # index of the look-ahead point (None: the goal)
        self.goal, self._goal = None, None
        self.point = None                    # the guide's set-point y_t, (3,)
        self.filtered, self.filtered_at = None, None  # y_f and its time (set_point_filter)
        self.aim = None                      # the look-ahead point (or the goal), (3,)
        self.want = None                     # horizontal unit direction of the aim, (2,)
        self.direction = None                # horizontal unit direction of the pull, (2,)
        self.length = 0.0                    # m, how far the pull reaches
        self.next_check, self.next_plan = -math.inf, -math.inf
        self.stale = False                   # a newly blocked cell lies on the path
        self.stats = {"plans": 0, "checks": 0, "moves": 0, "stuck": 0, "plan_s": 0.0,
                      "check_s": 0.0}

    # --- what the closed loop calls ---------------------------------------------------------

    def set_point(self, local_map, y, t: float, goal) -> np.ndarray:
        """The set-point at time ``t`` (s) for a vehicle at ``y`` ((3,), m) bound for ``goal``
        ((3,), m), from ``local_map`` (a :class:`~paper_repro.world.local_map.VoxelMap`): y_t,
        the previous one between checks, or its filter y_f (``set_point_filter`` > 0)."""
        point = self._set_point(local_map, y, t, goal)
        if self.set_point_filter == 0.0:
            return point
        if self.filtered is None:
            self.filtered = point.copy()
        else:
            gain = -math.expm1(-(t - self.filtered_at) / self.set_point_filter)
            self.filtered = self.filtered + gain * (point - self.filtered)
        self.filtered_at = t
        return self.filtered

    def _set_point(self, local_map, y, t: float, goal) -> np.ndarray:
        """y_t: the guide's own set-point, piecewise constant."""
        goal = np.asarray(goal, float)
        if self.goal is None or goal.tolist() != self._goal:  # as np.array_equal, cheaper
            self.goal, self.path, self.point = goal.copy(), None, goal.copy()
            self.want, self.next_plan, self._goal = None, -math.inf, goal.tolist()
        if t < self.next_check:
            return self.point
        self.next_check = t + self.check_period
        start = time.perf_counter()
        y = np.asarray(y, float)
        keys, points = _occupied(local_map)
        if self._block_new(keys, points) and self._path_blocked():
            self.stale = True
        if self._stuck(y, t):
            self.stale, self.next_plan = True, t
        if (self.path is None or self.stale) and t >= self.next_plan:
            self._plan(keys, points, y)
            self.next_plan = t + self.replan_period
        self._move_on(y)
        self.stats["checks"] += 1
        self.stats["check_s"] += time.perf_counter() - start
        return self.point

    # --- the grid ---------------------------------------------------------------------------

    def _cell(self, points: np.ndarray) -> np.ndarray:
        """(k, 3) integer cell indices of (k, 3) points (not clipped)."""
        return np.floor((points - self.lower) / self.cell).astype(np.int64)

    def _flat(self, ijk: np.ndarray) -> np.ndarray:
        """Flat cell numbers of (k, 3) in-box indices."""
        return np.ravel_multi_index(ijk.T, self.shape)

    def _inside(self, ijk: np.ndarray) -> np.ndarray:
        return ((ijk >= 0) & (ijk < self._counts)).all(axis=1)

    def _centres(self, ijk: np.ndarray) -> np.ndarray:
        return self.lower + (ijk + 0.5) * self.cell

    def _blocked_by(self, points: np.ndarray) -> np.ndarray:
        """Flat numbers of the cells whose centre lies within ``inflation`` of a point."""
        if len(points) == 0:
            return np.zeros(0, np.int64)
        ijk = (self._cell(points)[:, None, :] + self._stencil[None]).reshape(-1, 3)
        near = np.linalg.norm(self._centres(ijk) - np.repeat(points, len(self._stencil), 0),
                              axis=1) <= self.inflation
        ijk = ijk[near & self._inside(ijk)]
        return np.unique(self._flat(ijk))

    def _block_new(self, keys: np.ndarray, points: np.ndarray) -> bool:
        """Block the cells of the voxels occupied since the last plan; True if any."""
        at = np.searchsorted(self.mapped, keys)
        new = at >= len(self.mapped)
        new[~new] = self.mapped[at[~new]] != keys[~new]
        if not new.any():
            return False
        self._newly = self._blocked_by(points[new])
        self.blocked[self._newly] = True
        self.mapped = np.union1d(self.mapped, keys[new])
        return True

    def _free(self, points: np.ndarray) -> np.ndarray:
        """(k,) bool: each point is in the box and in a free cell."""
        ijk = self._cell(points)
        ok = ((ijk >= 0) & (ijk < self._counts) & (points >= self.lower)
              & (points <= self.upper)).all(axis=1)
        ok[ok] = ~self.blocked[self._flat(ijk[ok])]
        return ok

    def _sees(self, y: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """(k,) bool: the segment from y to each of the (k, 3) ``targets`` crosses no blocked
        cell (beyond the blocked cells the vehicle is among at the start). A segment of length
        L is sampled at s = skip, skip + cell/4, … below L, and at L (one no longer than skip
        is seen); the samples of every segment are looked up together."""
        ways = targets - y
        lengths = np.array([math.sqrt(w.dot(w)) for w in ways])  # as np.linalg.norm
        seen = np.ones(len(targets), bool)
        far = np.flatnonzero(lengths > self._skip)
        if len(far) == 0:
            return seen
        step = self.cell / 4
        # np.arange(skip, L, step) for each L: a prefix of the longest one (same values).
        counts = np.array([math.ceil((length - self._skip) / step) for length in
                           lengths[far].tolist()]) + 1  # the end point L too
        s = np.arange(self._skip, float(lengths[far].max()), step)
        segment = np.repeat(np.arange(len(far)), counts)
        starts = np.cumsum(counts) - counts
        within = np.arange(len(segment)) - starts[segment]
        last = within == counts[segment] - 1
        length = lengths[far][segment]
        at = np.where(last, length, s[np.minimum(within, len(s) - 1)])
        samples = y + (at / length)[:, None] * ways[far][segment]
        seen[far] = np.logical_and.reduceat(self._free(samples), starts)
        return seen

    # --- the path ---------------------------------------------------------------------------

    def _plan(self, keys: np.ndarray, points: np.ndarray, y: np.ndarray) -> None:
        """Block every cell of the map as it is now, and plan from y to the goal."""
        start = time.perf_counter()
        self.blocked[:] = False
        self.blocked[self._blocked_by(points)] = True
        self.blocked |= self.avoid
        self.mapped = keys.copy()
        self.path, self.remaining, self.progress, self.ahead = None, None, 0, None
        self.stale = False
        goal_cell = self._nearest_free(self.goal, self.goal)
        origin = self._nearest_free(y, None) if goal_cell is not None else None
        if origin is not None:
            candidates, gaps = origin
            found = shortest_path(self.shape, self._steps, self.blocked, candidates, gaps,
                                   goal_cell, self.cell, self.climb)
            if found is not None:
                chain, along = found
                ijk = np.stack(np.unravel_index(chain, self.shape), axis=1)
                self.path = np.vstack([self._centres(ijk), self.goal])
                tail = float(np.linalg.norm(self.goal - self.path[-2]))
                self.remaining = np.append(along + tail, 0.0)
        self.stats["plans"] += 1
        self.stats["plan_s"] += time.perf_counter() - start

    def _nearest_free(self, p: np.ndarray, exact):
        """The goal's cell (``exact`` given: the free cell nearest it, as a flat number), or the
        vehicle's candidates: the free cells within reach of it and their distances to it."""
        ijk = self._cell(p[None])[0] + self._near
        ijk = ijk[self._inside(ijk)]
        flat = self._flat(ijk)
        free = ~self.blocked[flat]
        if not free.any():
            return None
        gaps = np.linalg.norm(self._centres(ijk[free]) - p, axis=1)
        if exact is not None:
            return int(flat[free][np.argmin(gaps)])
        near = gaps <= self._skip + self.cell
        return (flat[free][near], gaps[near]) if near.any() else None

    def _path_blocked(self) -> bool:
        """A newly blocked cell lies on the path still ahead."""
        if self.path is None:
            return True
        ahead = self.path[self.progress:-1]
        if len(ahead) == 0:
            return False
        return bool(np.isin(self._flat(self._cell(ahead)), self._newly).any())

    def _stuck(self, y: np.ndarray, t: float) -> bool:
        """The vehicle has moved less than :data:`STUCK_DISTANCE` over ``stuck_time`` while
        far from the goal: the cells from it to its aim (within ``lookahead``) are avoided."""
        self.trail.append((t, y.copy()))
        while len(self.trail) > 1 and self.trail[1][0] <= t - self.stuck_time:
            self.trail.popleft()  # the oldest kept is at least stuck_time back
        if (t - self.trail[0][0] < self.stuck_time or self.aim is None
                or np.linalg.norm(self.goal - y) <= self.lookahead
                or any(_norm(p - y) >= STUCK_DISTANCE for _, p in self.trail)):
            return False
        gap = float(np.linalg.norm(self.aim - y))
        s = np.arange(self.cell, min(gap, self.lookahead), self.cell / 4)
        ijk = self._cell(y + np.outer(s / gap, self.aim - y)) if gap > self.cell else None
        if ijk is None or len(ijk) == 0:
            ijk = self._cell(self.aim[None])
        ijk = ijk[self._inside(ijk)]
        near = np.linalg.norm(self._centres(ijk) - y, axis=1) <= self.cell
        goal = self._cell(self.goal[None])[0]
        ijk = ijk[~near & np.any(ijk != goal, axis=1)]
        self.avoid[self._flat(ijk)] = True
        self.trail.clear()
        self.stats["stuck"] += 1
        return True

    # --- the set-point ----------------------------------------------------------------------

    def _move_on(self, y: np.ndarray) -> None:
        """Aim at the look-ahead point (or the goal, once in sight), and turn the pull
        towards it by at most ``max_turn``."""
        ahead = None  # no path (none exists, or the map is empty), or the goal in sight
        if self.path is not None:
            gaps = np.linalg.norm(self.path[self.progress:] - y, axis=1)
            nearest = int(np.argmin(gaps))
            progress = self.progress + nearest
            within = np.flatnonzero(gaps[nearest:] <= self.lookahead) + progress
            seen = self._sees(y, np.vstack([self.goal, self.path[within]]))
            if not seen[0]:  # the goal out of sight: the farthest path point in sight
                self.progress = progress
                ahead = int(within[seen[1:]][-1]) if seen[1:].any() else progress
        if ahead != self.ahead or self.want is None:
            self.ahead = ahead
            self.aim = self.goal if ahead is None else self.path[ahead]
            level = self.aim[:2] - y[:2]
            gap = float(np.linalg.norm(level))
            self.want = level / gap if gap > self.cell else np.zeros(2)
            self.length = float(np.linalg.norm(self.aim - y)) + (
                0.0 if ahead is None else float(self.remaining[ahead]))
        if self.direction is not None and np.array_equal(self.direction, self.want):
            return
        self.direction = turn_towards(self.direction, self.want, self.max_turn)
        if np.array_equal(self.direction, self.want) and (ahead is None or not self.want.any()):
            point = self.aim.copy()  # the goal in sight (or the aim straight above or below)
        else:
            start = np.append(y[:2], self.aim[2])
            way = np.append(self.direction, 0.0)
            point = self._pull_back(start, way, self.length)
        if self.point is None or not np.array_equal(point, self.point):
            self.stats["moves"] += 1
        self.point = point

    def _pull_back(self, start: np.ndarray, way: np.ndarray, length: float) -> np.ndarray:
        """The farthest free point on the ray from ``start`` (clipped into the box) along the
        unit vector ``way``, at most ``length`` away and inside the box: the ray is cut at the
        box, never bent, so the pull keeps its direction (the previous set-point if no point
        is free)."""
        start = np.clip(start, self.lower, self.upper)
        with np.errstate(divide="ignore", invalid="ignore"):
            exits = np.where(way > 0, (self.upper - start) / way,
                             np.where(way < 0, (self.lower - start) / way, np.inf))
        reach = min(float(length), float(exits.min()))
        s = np.arange(reach, 0.0, -self.cell / 4)
        samples = start + np.outer(s, way)
        free = np.flatnonzero(self._free(samples))
        return samples[free[0]] if len(free) else self.point.copy()


def shortest_path(shape, steps: np.ndarray, blocked: np.ndarray, sources: np.ndarray,
                   gaps: np.ndarray, goal: int, cell: float, climb: float):
    """The shortest path on the grid of ``shape`` cells through the cells not ``blocked``
    ((n,) bool), from any of the flat cells ``sources`` (entered at the costs ``gaps``, m) to
    the flat cell ``goal``, a step to neighbour d costing ``steps[d]`` (m, the offsets of
    :data:`NEIGHBOURS`): A* in ``_grid_path.c``. Returns (chain, along): the path's flat
    cells, a start first and the goal last, and each one's length to the goal along it, m;
    ``None`` when the goal cannot be reached."""
    dims = np.array(shape, np.int64)
    offsets = np.ascontiguousarray(NEIGHBOURS, np.int64)
    steps = np.ascontiguousarray(steps, float)
    cells = np.ascontiguousarray(blocked, np.uint8)
    sources = np.ascontiguousarray(sources, np.int64)
    gaps = np.ascontiguousarray(gaps, float)
    chain, along = np.empty(cells.size, np.int64), np.empty(cells.size)
    m = _library().grid_path(dims.ctypes.data, offsets.ctypes.data, steps.ctypes.data,
                             cells.ctypes.data, len(sources), sources.ctypes.data,
                             gaps.ctypes.data, int(goal), float(cell), float(climb),
                             chain.ctypes.data, along.ctypes.data)
    if m < 0:
        raise MemoryError("the guide's path search could not allocate its workspace")
    return (chain[:m].copy(), along[:m].copy()) if m else None


@functools.cache
def _library() -> ctypes.CDLL:
    """The compiled path search (``_grid_path.c``), built once per machine."""
    source = resources.files("paper_repro.world").joinpath("_grid_path.c").read_bytes()
    lib = load_library("grid_path", source, flags=("-ffp-contract=off",))
    ptr, i64, dbl = ctypes.c_void_p, ctypes.c_int64, ctypes.c_double
    lib.grid_path.restype = i64
    lib.grid_path.argtypes = [ptr, ptr, ptr, ptr, i64, ptr, ptr, i64, dbl, dbl, ptr, ptr]
    return lib


def turn_towards(current, want: np.ndarray, max_turn: float) -> np.ndarray:
    """The unit vector ``current`` (2-D or 3-D) turned towards the unit vector ``want`` by at
    most ``max_turn`` rad, in their common plane (``want`` itself when there is no
    ``current``, when either is zero, or when it is close enough)."""
    if current is None or not want.any() or not current.any():
        return want
    cos = float(np.clip(np.dot(current, want), -1.0, 1.0))
    if math.acos(cos) <= max_turn:
        return want
    side = want - cos * current
    norm = float(np.linalg.norm(side))
    if norm < 1e-9:  # straight opposite: turn to the left, in the horizontal plane
        side = np.zeros_like(current)
        side[:2] = -current[1], current[0]
        norm = float(np.linalg.norm(side))
        if norm < 1e-9:  # straight up or down
            side, norm = np.eye(len(current))[0], 1.0
    return math.cos(max_turn) * current + math.sin(max_turn) * side / norm


def _norm(v: np.ndarray) -> float:
    """‖v‖ of a 1-D array, as ``np.linalg.norm`` computes it (√(v·v)), without its checks."""
    return math.sqrt(v.dot(v))


def _occupied(local_map) -> tuple[np.ndarray, np.ndarray]:
    """The occupied voxels of a map: their keys (sorted) and representative points."""
    mask = local_map.occupied_mask
    return local_map.keys[mask], local_map.point[mask]
