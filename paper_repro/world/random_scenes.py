"""Seeded random scenes: a field of nonconvex point-cloud regions across a straight flight.

A random scene is a *field* of 2-6 regions (boxes, vertical cylinders, L- and T-walls,
U-channels, walls with a window) laid across the straight line from a start to a single
target, at flight altitude, so that the line is *blocked*: the straight segment from the start
to the target passes within ``blocking_distance`` (0.5 m) of a cloud point, i.e. through a
region. Each region is filled with a scrambled Halton cloud (3 points/m³) as in Section V, and
everything, clouds included, is rebuilt exactly from the seed.

The scene serves two kinds of run: a *mission* (reach the target, as the paper) and a
*passage*, which ends at the scene's finish line, ``finish_margin`` (2 m) past the farthest
cloud point of the field along the line. The start lies ``lead_in`` (4 m) before the field
and the target ``run_out`` (40 m) beyond it, so that the UAV crosses the field at about the
speed of the paper's mission (under the printed weights the speed is about the distance to
the target over 155 s, ≈0.3 m/s here). A passage is then ``lead_in`` + field + 2 m, 8-17 m
(median 14 m) along the line, i.e. 30-60 s or 3,000-6,000 steps of 10 ms before detours.

Geometry. The flight line is horizontal, at altitude h, with a heading drawn at random among
those for which the start, the field and the target fit in the workspace with a margin: with
a 40 m run-out the flight is 46-56 m long, more than the 48 m available along an axis, so the
headings lie between about 10° and 80° off the x axis (modulo 90°, most near a diagonal).
Shapes are axis-aligned boxes and vertical cylinders, so they are built in the frame of the
axis closest to the heading ("along" the flight and "across" it) and the line crosses them
obliquely. The first region is placed on the line, the others up to ``lateral_spread`` to
either side of it. Every region covers the flight altitude; its top is at most
``altitude[1] + height[1]`` (16 m by default), so a detour over the field always exists, and
its width is bounded, so a detour sideways exists too.

Moving variant. ``random_scene(seed, moving=True)`` (``make_scene("random-crossing", seed)``)
is the same field, clouds included, with every region crossing the flight line: each gets a
constant horizontal velocity perpendicular to the line, of speed uniform in ``speed``
(0.5-1.5 m/s) and random sign, timed so that its centre is on the line when the UAV, flying
straight, is expected to reach it (give or take ``crossing_spread``, 5 s). The draws come after
the layout's, from the same generator, so the static scene of a seed is unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from paper_repro.world.motion import Motion
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Region, Scene
from paper_repro.world.shapes import Box, Cylinder, Difference, Union, halton_cloud

REGION_KINDS = ("box", "cylinder", "L-wall", "T-wall", "U-channel", "window")
"""Names of the region kinds; a region of a random scene is named ``f"{kind}-{i}"``."""

NONCONVEX_KINDS = ("L-wall", "T-wall", "U-channel", "window")
"""The region kinds whose solid is nonconvex."""


@dataclass(frozen=True)
class RandomSceneParams:
    """Everything that shapes a random scene (lengths in m, ranges as ``(low, high)``).

    Attributes
    ----------
    regions : (low, high) integers, number of regions in the field, drawn uniformly;
        default (2, 6).
    depth : (low, high), m, depth of the field along the line: every region's bounding box
        lies in a slab of this thickness across the line (the field is at most this deep).
        A field of more regions is deeper: the depth is drawn uniformly from
        [low + ½·f·(high − low), high], f = (n − regions[0]) / (regions[1] − regions[0]) for
        n regions (f = 0 when the count is fixed). Default (4, 12) m.
    lateral_spread : m, regions other than the one that blocks the line are offset across the
        line by at most this much (their anchor, not their extent). Default 8 m.
    width : (low, high), m, extent across the line of boxes, walls and channels. Default
        (2, 6) m.
    box_depth : (low, high), m, extent along the line of boxes and U-channels. Default
        (1, 4) m.
    thickness : (low, high), m, thickness of walls (L-, T-walls, windows, the walls of a
        U-channel). Default (0.8, 1.5) m.
    arm : (low, high), m, length along the line of the second arm of an L- or T-wall.
        Default (2, 5) m.
    radius : (low, high), m, radius of cylinders. Default (0.6, 2) m.
    height : (low, high), m, vertical extent of a region (a region whose bottom would be
        below 1 m stands on the ground instead). Default (3, 8) m.
    altitude : (low, high), m, altitude h of the flight line (start and target). Default
        (2, 8) m.
    density : points/m³, Halton density of the clouds, as :class:`~paper_repro.world.scene.Region`
        (3). Default 3.
    lead_in : m, distance along the line from the start to the field's nearest face
        (bounding boxes); ≥ ``clearance``. Default 4 m.
    run_out : m, distance along the line from the field's farthest cloud point to the target;
        > ``finish_margin``. Default 40 m.
    finish_margin : m, the finish line of a passage is this far past the field's farthest
        cloud point along the line. Default 2 m.
    clearance : m, the start and the target are at least this far from every cloud point.
        Default 3 m (the LiDAR range r_s).
    blocking_distance : m, the straight segment start → target counts as blocked when it
        passes within this distance of a cloud point. Default 0.5 m.
    separation : m, minimum gap between two regions (between the bounding boxes of their
        parts: the two boxes of an L- or T-wall, the outer box of a U-channel or a window).
        Default 1 m.
    workspace_margin : m, the start, the target and every region keep this distance from the
        side walls of the workspace. Default 1 m.
    kinds : region kinds to draw from, a non-empty subset of :data:`REGION_KINDS`; the
        region that blocks the line and the others are drawn uniformly among them.
    max_attempts : int ≥ 1, layouts tried before :func:`random_scene` gives up. Default 500.
    speed : (low, high), m/s, speed of a region of a moving scene (``moving=True``) across the
        line, drawn uniformly. Default (0.5, 1.5).
    approach_time : s, the UAV's expected speed is (distance to target)/``approach_time``
        (150 s, near the printed weights' 155 s): flying straight from rest it is s(t) = L·(1 −
        e^{−t/approach_time}) along a line of length L, which times the crossings of a
        moving scene. Default 150 s.
    crossing_spread : s, in a moving scene region i's centre crosses the line at
        T_i + U(−spread, spread), T_i the time s(t) reaches the region's centre. Default 5 s.
    """

    regions: tuple[int, int] = (2, 6)
    depth: tuple[float, float] = (4.0, 12.0)
    lateral_spread: float = 8.0
    width: tuple[float, float] = (2.0, 6.0)
    box_depth: tuple[float, float] = (1.0, 4.0)
    thickness: tuple[float, float] = (0.8, 1.5)
    arm: tuple[float, float] = (2.0, 5.0)
    radius: tuple[float, float] = (0.6, 2.0)
    height: tuple[float, float] = (3.0, 8.0)
    altitude: tuple[float, float] = (2.0, 8.0)
    density: float = 3.0
    lead_in: float = 4.0
    run_out: float = 40.0
    finish_margin: float = 2.0
    clearance: float = 3.0
    blocking_distance: float = 0.5
    separation: float = 1.0
    workspace_margin: float = 1.0
    kinds: tuple[str, ...] = REGION_KINDS
    max_attempts: int = 500
    speed: tuple[float, float] = (0.5, 1.5)
    approach_time: float = 150.0
    crossing_spread: float = 5.0

    def __post_init__(self):
        if not (_is_pair(self.regions)
                and all(isinstance(v, (int, np.integer)) for v in self.regions)
                and 1 <= self.regions[0] <= self.regions[1] <= 12):
            raise ValueError(f"regions must be integers (low, high) with 1 ≤ low ≤ high ≤ 12, "
                             f"got {self.regions!r}")
        _require_interval("depth", self.depth, 1.0, 30.0)
        _require_interval("width", self.width, 1.0, 15.0)
        _require_interval("box_depth", self.box_depth, 0.5, 10.0)
        _require_interval("thickness", self.thickness, 0.5, 5.0)
        _require_interval("arm", self.arm, 0.5, 10.0)
        _require_interval("radius", self.radius, 0.3, 5.0)
        _require_interval("height", self.height, 1.5, 20.0)
        _require_interval("altitude", self.altitude, 0.5, 20.0)
        room = WORKSPACE_UPPER[2] - 2 * self.clearance
        if self.altitude[1] + self.height[1] > room:
            raise ValueError(f"altitude[1] + height[1] must be ≤ {room:g} m (25 m less twice "
                             f"the clearance, so a detour over the field exists), got "
                             f"{self.altitude[1] + self.height[1]:g} m")
        for name in ("lateral_spread", "separation"):
            _require_number(name, getattr(self, name), 0.0, 20.0)
        _require_number("density", self.density, 0.1, 100.0, low_open=True)
        _require_number("clearance", self.clearance, 0.0, 20.0)
        _require_number("lead_in", self.lead_in, self.clearance, 20.0)
        _require_number("finish_margin", self.finish_margin, 0.0, 20.0)
        _require_number("blocking_distance", self.blocking_distance, 0.0, 5.0, low_open=True)
        _require_number("workspace_margin", self.workspace_margin, 0.0, 10.0)
        span = float(np.min(WORKSPACE_UPPER[:2] - WORKSPACE_LOWER[:2]))
        longest = (span - 2 * self.workspace_margin) * math.sqrt(2)
        high = longest - self.lead_in - self.depth[1]
        low = max(self.finish_margin, self.clearance)
        if not (math.isfinite(self.run_out) and low < self.run_out <= high):
            raise ValueError(f"run_out must lie in ({low:g}, {high:g}] m (beyond the finish "
                             f"line and the clearance, and start + field + run-out must fit "
                             f"along the workspace diagonal), got {self.run_out!r}")
        if not (isinstance(self.kinds, tuple) and self.kinds
                and all(k in REGION_KINDS for k in self.kinds)):
            raise ValueError(f"kinds must be a non-empty tuple of names from {REGION_KINDS}, "
                             f"got {self.kinds!r}")
        if not (isinstance(self.max_attempts, int) and self.max_attempts >= 1):
            raise ValueError(f"max_attempts must be an integer ≥ 1, got {self.max_attempts!r}")
        if not (_is_pair(self.speed) and all(
                isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)
                for v in self.speed) and 0.0 < self.speed[0] <= self.speed[1] <= 20.0):
            raise ValueError(f"speed must be a pair (low, high) with 0 < low ≤ high ≤ 20 m/s, "
                             f"got {self.speed!r}")
        _require_number("approach_time", self.approach_time, 0.0, 10_000.0, low_open=True)
        _require_number("crossing_spread", self.crossing_spread, 0.0, 1_000.0)


def random_scene(seed: int, params: RandomSceneParams | None = None,
                 moving: bool = False) -> Scene:
    """A random field of regions across a straight flight, rebuilt exactly from ``seed``.

    Parameters
    ----------
    seed : int ≥ 0. Seeds ``numpy.random.default_rng`` for the layout and, as
        ``Scene(seed=seed)``, the Halton clouds (region i uses ``seed + i``).
    params : the distributions of the layout (default :class:`RandomSceneParams`).
    moving : ``False`` (static regions) or ``True``: the same field, clouds included, named
        ``f"random-crossing-{seed}"``, each region with a constant velocity across the line
        (see :func:`crossing_motions`); its stored clouds are the static layout's, where each
        region is at its crossing time offset by its lateral position.

    Returns
    -------
    Scene named ``f"random-{seed}"`` with one target and a finish line
    ``(point, direction)``: ``direction`` (3,) is the unit heading of the line, ``point`` (3,)
    lies on the line ``finish_margin`` past the field's farthest cloud point along it. The
    scene satisfies, by construction and by check:

    * *blocked*: the straight segment start → target passes within ``blocking_distance`` of
      some cloud point (it goes through a region);
    * the start and the target are at least ``clearance`` from every cloud point, and the
      start is ``lead_in`` before the field's nearest face along the line;
    * every region lies in the workspace, the start, the target and the finish point lie
      ``workspace_margin`` inside its side walls;
    * regions are at least ``separation`` apart (bounding boxes of their parts).

    Raises
    ------
    ValueError : ``seed`` is not an integer ≥ 0, or no valid layout was found in
        ``params.max_attempts`` attempts (parameters too tight for the workspace).
    """
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        raise ValueError(f"seed must be an integer ≥ 0, got {seed!r}")
    seed = int(seed)
    params = RandomSceneParams() if params is None else params
    rng = np.random.default_rng(seed)
    # The number and kinds of regions are drawn once, so that retries redraw only the
    # geometry and the counts and kinds keep their uniform distributions.
    count = int(rng.integers(params.regions[0], params.regions[1] + 1))
    kinds = tuple(params.kinds[int(k)] for k in rng.integers(len(params.kinds), size=count))
    if not isinstance(moving, (bool, np.bool_)):
        raise ValueError(f"moving must be a bool, got {moving!r}")
    for _ in range(params.max_attempts):
        scene = _try_layout(rng, seed, kinds, params)
        if scene is not None:
            if moving:  # drawn after the layout: the static scene of a seed is unchanged
                scene = dataclasses.replace(scene, name=f"random-crossing-{seed}",
                                            motions=crossing_motions(scene, rng, params))
            return scene
    raise ValueError(f"random_scene({seed}): no valid layout in {params.max_attempts} "
                     f"attempts; loosen the parameters (run_out, depth, sizes or margins)")


def crossing_motions(scene: Scene, rng: np.random.Generator,
                     params: RandomSceneParams | None = None) -> tuple[Motion, ...]:
    """One constant-velocity :class:`~paper_repro.world.motion.Motion` per region of a one-target
    scene, each crossing the straight line from the start to the target.

    For region i, with u the unit heading start → target, n = (−u_y, u_x, 0) the horizontal
    normal, L the line's length, a_i and b_i the along and across coordinates of the centre
    of its cloud (mean point) relative to the start, drawn from ``rng`` in this order:

    * speed s_i ~ U(``speed``), m/s, and a direction ±n (each with probability ½);
    * the crossing time t_i = T_i + U(−``crossing_spread``, ``crossing_spread``), s, where
      T_i = −``approach_time``·ln(1 − a_i/L) is when the UAV, flying straight from rest at
      the expected speed, reaches the region's centre.

    The region's centre is on the line at t_i: c_i(t) = ±s_i·n·(t − t_i) − b_i·n. The
    motions keep the regions at their heights and along-line positions, so the start and the
    target stay as far from every region as in the static layout, at every t.
    """
    params = RandomSceneParams() if params is None else params
    start = np.asarray(scene.start, float)
    target = np.atleast_2d(np.asarray(scene.targets, float))[0]
    length = float(np.linalg.norm(target - start))
    u = (target - start) / length
    n = np.array([-u[1], u[0], 0.0])
    n /= np.linalg.norm(n)
    motions = []
    for cloud in scene.clouds:
        speed = float(rng.uniform(*params.speed))
        velocity = speed * n * (1.0 if rng.random() < 0.5 else -1.0)
        centre = np.mean(cloud, axis=0) - start
        along = min(max(float(centre @ u), 0.0), 0.99 * length)
        arrival = -params.approach_time * math.log(1.0 - along / length)
        crossing = arrival + float(rng.uniform(-params.crossing_spread,
                                               params.crossing_spread))
        motions.append(Motion.constant(_floats(velocity),
                                       _floats(-velocity * crossing - float(centre @ n) * n)))
    return tuple(motions)


def passage_progress(scene: Scene, y) -> float | np.ndarray:
    """Signed distance (m) of position(s) ``y`` past the scene's finish line.

    Parameters
    ----------
    scene : a scene with a ``finish`` (point, unit direction).
    y : (3,) or (n, 3) positions, m.

    Returns
    -------
    float, or (n,) array: ``(y − point)·direction``, negative before the line; a passage
    ends when it becomes ≥ 0.
    """
    if scene.finish is None:
        raise ValueError(f"scene {scene.name!r} has no finish line (not a passage scene)")
    point, direction = (np.asarray(v, float) for v in scene.finish)
    y = np.asarray(y, float)
    if y.shape[-1:] != (3,) or y.ndim > 2:
        raise ValueError(f"y must be a (3,) or (n, 3) array of positions, got shape {y.shape}")
    progress = (y - point) @ direction
    return float(progress) if y.ndim == 1 else progress


# --- helpers --------------------------------------------------------------------------------

def _try_layout(rng: np.random.Generator, seed: int, kinds: tuple[str, ...],
                p: RandomSceneParams) -> Scene | None:
    """One attempt: a heading, a field of regions of these ``kinds`` (the first one blocks the
    line) in the line's frame, a placement in the workspace and the clouds; ``None`` when a
    check fails (the caller draws again from the same ``rng``)."""
    heading = rng.uniform(0.0, 2 * math.pi)
    u = np.array([math.cos(heading), math.sin(heading), 0.0])
    v = np.array([-u[1], u[0], 0.0])
    frame = _nearest_axis_frame(u)
    h = rng.uniform(*p.altitude)
    crowding = (len(kinds) - p.regions[0]) / max(1, p.regions[1] - p.regions[0])
    depth = rng.uniform(p.depth[0] + 0.5 * crowding * (p.depth[1] - p.depth[0]), p.depth[1])

    # Field in a frame whose origin is the slab's entry point on the line (xy), at z = 0.
    placed: list[tuple[str, object]] = []
    for i, kind in enumerate(kinds):
        for _ in range(50):
            shape = _build_shape(kind, rng, p, frame, h)
            lo, hi = _projection(shape, u)
            if hi - lo > depth:
                continue
            t = rng.uniform(-lo, depth - hi)
            lateral = 0.0 if i == 0 else rng.uniform(-p.lateral_spread, p.lateral_spread)
            shape = _translate(shape, t * u + lateral * v)
            if all(_gap(shape, other) >= p.separation for _, other in placed):
                placed.append((kind, shape))
                break
        else:
            return None
    near = min(_projection(s, u)[0] for _, s in placed)
    far = max(_projection(s, u)[1] for _, s in placed)
    start = (near - p.lead_in) * u
    farthest_target = (far + p.run_out) * u

    # Place the whole layout in the workspace, margin inside the side walls.
    lows, highs = zip(*(s.bounds() for _, s in placed))
    pts = np.vstack([start, farthest_target, *lows, *highs])[:, :2]
    room_lo = WORKSPACE_LOWER[:2] + p.workspace_margin - pts.min(axis=0)
    room_hi = WORKSPACE_UPPER[:2] - p.workspace_margin - pts.max(axis=0)
    if np.any(room_lo > room_hi):
        return None
    offset = np.append(rng.uniform(room_lo, room_hi), 0.0)
    start = start + offset + [0.0, 0.0, h]
    regions = tuple(Region(f"{kind}-{i}", _translate(shape, offset), p.density)
                    for i, (kind, shape) in enumerate(placed))

    clouds = tuple(halton_cloud(r.shape, r.density, seed + i) for i, r in enumerate(regions))
    if any(len(c) == 0 for c in clouds):
        return None
    points = np.concatenate(clouds)
    field_end = float(np.max((points - start) @ u))
    target = start + (field_end + p.run_out) * u
    finish = start + (field_end + p.finish_margin) * u
    if (_segment_distance(points, start, target) > p.blocking_distance
            or np.min(np.linalg.norm(points - start, axis=1)) < p.clearance
            or np.min(np.linalg.norm(points - target, axis=1)) < p.clearance):
        return None
    return Scene(f"random-{seed}", regions, _floats(start), (_floats(target),), seed,
                 (_floats(finish), _floats(u)), clouds)


def _nearest_axis_frame(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(along, across): the axis-aligned horizontal unit vector closest to heading ``u`` and
    that vector turned by +90°, each (3,)."""
    i = int(np.argmax(np.abs(u[:2])))
    along = np.zeros(3)
    along[i] = math.copysign(1.0, u[i])
    return along, np.array([-along[1], along[0], 0.0])


def _frame_box(frame, along: float, across: float, z_lo: float, size_along: float,
               size_across: float, height: float) -> Box:
    """Axis-aligned box given in the (along, across, z) frame: centre (along, across) in the
    plane, bottom at z_lo, sizes in m."""
    a, b = frame
    centre = along * a + across * b
    size = np.abs(size_along * a + size_across * b)
    return Box((float(centre[0]), float(centre[1]), z_lo + height / 2),
               (float(size[0]), float(size[1]), height))


def _vertical_extent(rng, p: RandomSceneParams, h: float) -> tuple[float, float]:
    """(bottom, height), m, of a region covering altitude h with 0.5 m to spare above and
    below; a bottom below 1 m is lowered to the ground (no thin gap under a region)."""
    height = rng.uniform(*p.height)
    bottom = rng.uniform(max(0.0, h - height + 0.5), max(0.0, h - 0.5))
    top = max(bottom + height, h + 0.5)
    if bottom < 1.0:
        bottom = 0.0
    return float(bottom), float(top - bottom)


def _box(rng, p, frame, h):
    """A block; the line crosses it at a random point of its width (≥ 0.5 m inside)."""
    d, w = rng.uniform(*p.box_depth), rng.uniform(*p.width)
    z, height = _vertical_extent(rng, p, h)
    return _frame_box(frame, 0.0, _crossing(rng, w), z, d, w, height)


def _cylinder(rng, p, frame, h):
    """A vertical column; the line passes within 0.6·radius of its axis."""
    r = float(rng.uniform(*p.radius))
    z, height = _vertical_extent(rng, p, h)
    centre = rng.uniform(-0.6, 0.6) * r * frame[1]
    return Cylinder((float(centre[0]), float(centre[1]), z), r, height)


def _wall_with_arm(rng, p, frame, h, at_end: bool):
    """A wall across the line with a second arm along it, at one end (L) or in the middle
    (T); the arm points towards the start or away from it (a concave corner either way)."""
    w, t, arm = rng.uniform(*p.width), rng.uniform(*p.thickness), rng.uniform(*p.arm)
    z, height = _vertical_extent(rng, p, h)
    across = _crossing(rng, w)
    side = rng.choice([-1.0, 1.0])
    arm_across = across + (side * (w - t) / 2 if at_end else 0.0)
    towards = rng.choice([-1.0, 1.0])
    return Union((_frame_box(frame, 0.0, across, z, t, w, height),
                  _frame_box(frame, towards * (arm + t / 2) / 2, arm_across, z,
                             arm + t / 2, t, height)))


def _l_wall(rng, p, frame, h):
    return _wall_with_arm(rng, p, frame, h, at_end=True)


def _t_wall(rng, p, frame, h):
    return _wall_with_arm(rng, p, frame, h, at_end=False)


def _u_channel(rng, p, frame, h):
    """A box with a channel cut through one of its four side faces (the face towards the
    start, away from it, or either side), closed above and below like the paper's U-channel,
    or open through its whole height (a U-shaped wall)."""
    d = max(rng.uniform(*p.box_depth), 2 * p.thickness[0] + 1.0)
    w = max(rng.uniform(*p.width), 2 * p.thickness[0] + 1.0)
    t = min(rng.uniform(*p.thickness), (d - 1.0) / 2, (w - 1.0) / 2)
    z, height = _vertical_extent(rng, p, h)
    across = _crossing(rng, w)
    outer = _frame_box(frame, 0.0, across, z, d, w, height)
    face = int(rng.integers(4))  # 0: towards the start, 1: away, 2: left, 3: right
    # The channel keeps walls of thickness t on the three closed faces and runs out through
    # the open one (one wall thickness beyond it, so the cut is clean).
    lo_a, hi_a = -d / 2 + t, d / 2 - t
    lo_b, hi_b = across - w / 2 + t, across + w / 2 - t
    if face == 0:
        lo_a = -d / 2 - t
    elif face == 1:
        hi_a = d / 2 + t
    elif face == 2:
        hi_b = across + w / 2 + t
    else:
        lo_b = across - w / 2 - t
    closed = rng.random() < 0.5 and height > 2 * t + 1.0
    z_in, h_in = (z + t, height - 2 * t) if closed else (z - 1.0, height + 2.0)
    inner = _frame_box(frame, (lo_a + hi_a) / 2, (lo_b + hi_b) / 2, z_in,
                       hi_a - lo_a, hi_b - lo_b, h_in)
    return Difference(outer, inner)


def _window(rng, p, frame, h):
    """A wall across the line with a rectangular hole through it (at least 1 m of wall on
    every side); the hole may or may not be wide enough to fly through."""
    w, t = rng.uniform(*p.width), rng.uniform(*p.thickness)
    z, height = _vertical_extent(rng, p, h)
    across = _crossing(rng, w)
    wall = _frame_box(frame, 0.0, across, z, t, w, height)
    hole_w = rng.uniform(1.0, max(1.0, w - 2.0))
    hole_h = rng.uniform(1.0, max(1.0, height - 2.0))
    hole_across = across + rng.uniform(-1, 1) * max(0.0, (w - hole_w) / 2 - 1.0)
    hole_z = z + rng.uniform(1.0, max(1.0, height - hole_h - 1.0))
    return Difference(wall, _frame_box(frame, 0.0, hole_across, hole_z, t + 2.0, hole_w,
                                       hole_h))


def _build_shape(kind: str, rng, p: RandomSceneParams, frame, h: float):
    """A shape of this kind, in the line's frame: the line (across = 0, altitude h) passes
    through its bounding box at along = 0."""
    builders = {"box": _box, "cylinder": _cylinder, "L-wall": _l_wall, "T-wall": _t_wall,
                "U-channel": _u_channel, "window": _window}
    return builders[kind](rng, p, frame, h)


def _crossing(rng, width: float) -> float:
    """Across-offset (m) of a shape of this width so that the line (across = 0) crosses it at
    least 0.5 m inside its edges."""
    return float(rng.uniform(-1, 1) * max(0.0, width / 2 - 0.5))


def _translate(shape, offset: np.ndarray):
    """The same shape moved by ``offset`` (3,), m."""
    off = np.asarray(offset, float)
    if isinstance(shape, Box):
        return Box(_floats(np.asarray(shape.center) + off), shape.size)
    if isinstance(shape, Cylinder):
        return Cylinder(_floats(np.asarray(shape.base) + off), shape.radius, shape.height)
    if isinstance(shape, Union):
        return Union(tuple(_translate(s, off) for s in shape.parts))
    if isinstance(shape, Difference):
        return Difference(_translate(shape.outer, off), _translate(shape.inner, off))
    raise TypeError(f"cannot translate {shape!r}")


def _projection(shape, u: np.ndarray) -> tuple[float, float]:
    """(min, max) of ``p·u`` over the corners of the shape's bounding box, m."""
    lo, hi = shape.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    proj = corners @ u
    return float(proj.min()), float(proj.max())


def _gap(a, b) -> float:
    """Lower bound (m) on the distance between two shapes: the smallest distance between the
    bounding boxes of their parts (a union's parts, a difference's outer shape), 0 when
    they overlap. Parts rather than whole bounding boxes let L- and T-walls nest."""
    return min(float(np.linalg.norm(np.maximum(0.0, np.maximum(alo - bhi, blo - ahi))))
               for alo, ahi in _part_bounds(a) for blo, bhi in _part_bounds(b))


def _part_bounds(shape) -> list[tuple[np.ndarray, np.ndarray]]:
    if isinstance(shape, Union):
        return [b for part in shape.parts for b in _part_bounds(part)]
    if isinstance(shape, Difference):
        return _part_bounds(shape.outer)
    return [shape.bounds()]


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance (m) from the segment a → b to the points (n, 3)."""
    ab = b - a
    s = np.clip((points - a) @ ab / (ab @ ab), 0.0, 1.0)
    return float(np.min(np.linalg.norm(points - (a + s[:, None] * ab), axis=1)))


def _floats(v: np.ndarray) -> tuple[float, ...]:
    return tuple(float(c) for c in v)


def _is_pair(value) -> bool:
    return isinstance(value, tuple) and len(value) == 2


def _require_interval(name: str, value, low: float, high: float) -> None:
    if not (_is_pair(value) and all(isinstance(v, (int, float, np.integer, np.floating))
                                    and math.isfinite(v) for v in value)
            and low <= value[0] <= value[1] <= high):
        raise ValueError(f"{name} must be a pair (low, high) with {low:g} ≤ low ≤ high ≤ "
                         f"{high:g} m, got {value!r}")


def _require_number(name: str, value, low: float, high: float, low_open: bool = False) -> None:
    ok = (isinstance(value, (int, float, np.integer, np.floating)) and math.isfinite(value)
          and (low < value if low_open else low <= value) and value <= high)
    if not ok:
        bracket = "(" if low_open else "["
        raise ValueError(f"{name} must lie in {bracket}{low:g}, {high:g}], got {value!r}")
