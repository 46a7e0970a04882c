"""The guide: its path keeps clear of what the map has seen, its set-point is free and turns
smoothly, it replans when the map blocks the path or the vehicle is stuck, and it takes the
paper's controller past a deadlock."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from paper_repro.analysis.metrics import COLLISION_CLEARANCE
from paper_repro.config import Config, GuideParams, SensorParams
from paper_repro.config_history import ADDED, as_keyed
from paper_repro.sim.loop import simulate
from paper_repro.studies.catalogue import passage_config, with_guide, with_map
from paper_repro.world.guide import NEIGHBOURS, Guide, shortest_path, turn_towards
from paper_repro.world.local_map import VoxelMap
from paper_repro.world.shapes import Box, halton_cloud

LOWER, UPPER = np.array([-10.0, -10.0, 0.1]), np.array([10.0, 10.0, 10.0])
START, GOAL = np.array([-4.0, 0.0, 3.0]), np.array([8.0, 0.0, 3.0])


def _mapped_wall(width=8.0):
    """A map that has confirmed a wall 1 m thick and ``width`` m wide across the line from
    START to GOAL, 3 m in front of the start (as if seen from the far side of it)."""
    wall = halton_cloud(Box((0.0, 0.0, 3.0), (1.0, width, 6.0)), 3.0, 0)
    m = VoxelMap(keep_radius=30.0)
    for k in range(5):
        m.update([wall], np.array([0.0, 0.0, 3.0]), 0.01 * k)
    return m, m.point[m.occupied_mask]


def _checks(guide, local_map, y, n, t0=0.0):
    """The set-points of ``n`` successive checks with the vehicle held at y."""
    return [guide.set_point(local_map, y, t0 + i * guide.check_period, GOAL).copy()
            for i in range(n)]


def test_an_empty_map_hands_over_the_goal_itself():
    guide = Guide(LOWER, UPPER)
    points = _checks(guide, VoxelMap(), START, 20)
    assert all(np.array_equal(p, GOAL) for p in points)
    assert guide.stats["plans"] == 1  # the straight path, never blocked: planned once


def test_the_path_and_the_set_point_keep_clear_of_every_mapped_point():
    local_map, wall = _mapped_wall()
    guide = Guide(LOWER, UPPER, stuck_time=100.0)
    points = _checks(guide, local_map, START, 80)
    tree = cKDTree(wall)
    # Every cell of the path (the goal, last, aside) lies farther than the inflation from
    # every mapped point, and so does every set-point handed over.
    assert tree.query(guide.path[:-1])[0].min() > guide.inflation
    assert tree.query(np.array(points))[0].min() > guide.inflation
    assert np.all((np.array(points) >= LOWER) & (np.array(points) <= UPPER))
    # The path goes round the wall: its cells leave the line by more than half the wall.
    assert np.abs(guide.path[:, 1]).max() > 4.0 or guide.path[:, 2].max() > 6.0
    # and the pull turned away from the straight line through the wall.
    final = points[-1] - START
    angle = math.degrees(math.acos(np.dot(final, GOAL - START)
                                   / np.linalg.norm(final) / np.linalg.norm(GOAL - START)))
    assert angle > 10.0


def test_the_pull_turns_by_at_most_max_turn_per_check():
    local_map, _ = _mapped_wall()
    guide = Guide(LOWER, UPPER, max_turn=3.0, stuck_time=100.0)
    # pulled straight at the goal over an empty map, then the wall is mapped across the line
    points = np.array(_checks(guide, VoxelMap(), START, 3)
                      + _checks(guide, local_map, START, 60, t0=1.0))
    level = points[:, :2] - START[:2]
    level /= np.linalg.norm(level, axis=1, keepdims=True)
    turns = np.degrees(np.arccos(np.clip(np.sum(level[1:] * level[:-1], axis=1), -1, 1)))
    assert turns.max() <= 3.0 + 1e-6
    assert turns.sum() > 10.0  # it did turn


def test_turn_is_a_bounded_rotation_that_reaches_its_goal():
    rng = np.random.default_rng(1)
    for k in range(200):
        current, want = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 2 + k % 2)))
        turned = turn_towards(current, want, math.radians(5.0))
        assert np.linalg.norm(turned) == pytest.approx(1.0)
        step = math.acos(np.clip(np.dot(turned, current), -1, 1))
        before = math.acos(np.clip(np.dot(current, want), -1, 1))
        after = math.acos(np.clip(np.dot(turned, want), -1, 1))
        assert step <= math.radians(5.0) + 1e-9
        assert after == pytest.approx(max(before - math.radians(5.0), 0.0), abs=1e-7)
    # straight opposite: it still turns, by exactly the limit
    turned = turn_towards(np.array([1.0, 0, 0]), np.array([-1.0, 0, 0]), 0.1)
    assert math.acos(turned[0]) == pytest.approx(0.1)


def test_a_wall_across_the_path_makes_a_plan_and_a_wall_beside_it_does_not():
    guide = Guide(LOWER, UPPER, stuck_time=100.0)  # held still, but not stuck
    empty = VoxelMap(keep_radius=30.0)
    _checks(guide, empty, START, 3)
    assert guide.stats["plans"] == 1
    beside = halton_cloud(Box((2.0, 7.0, 3.0), (1.0, 1.0, 1.0)), 3.0, 1)  # 7 m off the line
    for k in range(4):
        empty.update([beside], np.array([2.0, 7.0, 3.0]), 0.01 * k)
    _checks(guide, empty, START, 20, t0=1.0)
    assert guide.stats["plans"] == 1
    local_map, _ = _mapped_wall()
    _checks(guide, local_map, START, 20, t0=3.0)
    assert guide.stats["plans"] == 2


def test_a_stuck_vehicle_avoids_the_cells_before_it_and_plans_again():
    """Held still far from the goal with the goal in sight (the map sees no obstacle), the
    vehicle is stuck after stuck_time: the cells towards its aim are avoided and the path
    goes elsewhere."""
    guide = Guide(LOWER, UPPER, stuck_time=2.5)
    _checks(guide, VoxelMap(), START, 40)  # 4 s without moving
    assert guide.stats["stuck"] >= 1 and guide.stats["plans"] >= 2
    assert guide.avoid.any()
    centres = guide._centres(np.stack(np.unravel_index(np.flatnonzero(guide.avoid),
                                                       guide.shape), axis=1))
    # the avoided cells lie between the vehicle and its goal, and the new path avoids them
    assert np.all(centres[:, 0] > START[0]) and np.abs(centres[:, 1]).max() < 1.0
    cells = guide._flat(guide._cell(guide.path[:-1]))
    assert not guide.avoid[cells].any()


def test_guide_parameters_are_checked_and_need_the_map():
    for name, bad in (("cell", 0.0), ("inflation", -1.0), ("check_period", math.nan),
                      ("max_turn", 0.0), ("stuck_time", -2.0), ("climb", 0.0)):
        with pytest.raises(ValueError, match=rf"^{name} must be a finite number > 0"):
            GuideParams(**{name: bad})
    with pytest.raises(ValueError, match=r"^lookahead must be a finite number >= cell"):
        GuideParams(lookahead=0.5)
    with pytest.raises(ValueError, match=r"^planner must be one of"):
        GuideParams(planner="rrt")
    with pytest.raises(ValueError, match=r"^guide.planner 'grid' plans on the local map"):
        Config(guide=GuideParams(planner="grid"))
    with pytest.raises(ValueError, match=r"^lower and upper must be"):
        Guide(UPPER, LOWER)
    for bad in (-0.1, math.inf, math.nan):
        with pytest.raises(ValueError, match=r"^set_point_filter must be a finite number"):
            GuideParams(set_point_filter=bad)
        with pytest.raises(ValueError, match=r"^set_point_filter must be a finite number"):
            Guide(LOWER, UPPER, set_point_filter=bad)


def test_the_guide_off_keeps_every_key_and_on_enters_it():
    """A config without the guide is keyed as before the part existed (config_history.ADDED), reads
    back from a file that lacks it, and a guided config keys and reads back whole."""
    assert ("guide", None) in ADDED
    cfg = Config()
    before = as_keyed(cfg.to_dict())  # the quadrotor's box where keys name it
    for part, name in ADDED:  # the parts added whole (the guide, the tracker), then settings
        if name is None:
            del before[part]
    for (part, name), value in ADDED.items():  # a setting at the value it was added with
        if name is not None and part in before and before[part][name] == value:
            del before[part][name]
    assert cfg.key_dict() == before and Config.from_dict(before) == cfg
    guided = Config(sensor=SensorParams(map_voxel=0.5), guide=GuideParams(planner="grid"))
    assert guided.key_dict()["guide"]["planner"] == "grid"
    assert Config.from_dict(guided.key_dict()) == guided
    # The set-point filter came later (on by default): off, a guided run keeps the key it
    # had without it, and a guided part written without it reads back off, as it flew.
    assert guided.key_dict()["guide"]["set_point_filter"] == GuideParams().set_point_filter > 0
    unfiltered = dataclasses.replace(guided, guide=GuideParams(planner="grid",
                                                               set_point_filter=0.0))
    assert "set_point_filter" not in unfiltered.key_dict()["guide"]
    assert Config.from_dict(unfiltered.key_dict()) == unfiltered
    # The guide off flies the same whatever its filter: keyed as the paper's default.
    off = dataclasses.replace(cfg, guide=GuideParams(set_point_filter=0.0))
    assert off.key_dict() == cfg.key_dict()


def test_map_and_guide_take_the_paper_controller_past_a_deadlock():
    """Random passage 24 (a cylinder, a U-channel and an L-wall across the line): the paper's
    controller stalls in front of the channel; reading the map, with the guide handing it its
    set-points, it completes the passage without a collision, and the set-point it was handed
    was never within the inflation of a cloud point."""
    paper = simulate(passage_config(Config(), 24), progress=False)
    assert paper.outcome == "stalled"
    guided = simulate(passage_config(with_guide(Config()), 24), progress=False)
    assert guided.outcome == "completed"
    assert guided.clearance.min() > COLLISION_CLEARANCE
    assert guided.set_points is not None and guided.set_points.shape == (guided.steps, 3)
    tree = cKDTree(guided.scene.all_points)
    away = tree.query(guided.set_points)[0]
    assert away.min() > GuideParams().inflation - 0.5  # mapped points sit within a voxel
    assert guided.meta["guide"]["plans"] >= 2


def test_the_map_alone_does_not_move_the_set_point():
    cfg = with_map(Config())
    assert cfg.guide.planner == "none" and cfg.sensor.map_voxel > 0
    result = simulate(dataclasses.replace(passage_config(cfg, 24), simulation=dataclasses.replace(
        passage_config(cfg, 24).simulation, max_steps=50)), progress=False)
    assert result.set_points is None


def _dijkstra_from_goal(guide: Guide, goal: int) -> np.ndarray:
    """Every cell's distance to ``goal`` on the free 26-grid, by scipy's Dijkstra over the
    whole lattice built from scratch (the reference the guide's A* must match)."""
    index = np.arange(guide.blocked.size).reshape(guide.shape)
    rows, cols, weights = [], [], []
    for d, step in zip(NEIGHBOURS, guide._steps):
        src = tuple(slice(max(0, -o), n - max(0, o)) for o, n in zip(d, guide.shape))
        dst = tuple(slice(max(0, o), n + min(0, o)) for o, n in zip(d, guide.shape))
        u, v = index[src].ravel(), index[dst].ravel()
        keep = ~(guide.blocked[u] | guide.blocked[v])
        rows.append(u[keep]), cols.append(v[keep]), weights.append(np.full(keep.sum(), step))
    n = guide.blocked.size
    graph = csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n))
    return dijkstra(graph, directed=True, indices=goal)


def test_the_path_search_is_as_short_as_dijkstra_over_the_whole_grid():
    """The guide's A* (from several start cells, each entered at its gap) must find the
    least gap + distance to the goal that Dijkstra over the whole grid gives, through a chain
    of free 26-neighbours from a start to the goal, whose lengths to the goal are Dijkstra's;
    and no path where Dijkstra finds none (a goal walled in)."""
    guide = Guide(np.array([-2.5, -2.5, 0.0]), np.array([12.5, 10.5, 8.0]))
    rng = np.random.default_rng(1)
    step_of = {tuple(d): s for d, s in zip(NEIGHBOURS, guide._steps)}
    for share in (0.0, 0.05, 0.2, 0.35):
        guide.blocked[:] = rng.random(guide.blocked.size) < share
        free = np.flatnonzero(~guide.blocked)
        goal = int(rng.choice(free))
        sources = rng.choice(free[free != goal], size=5, replace=False)
        gaps = rng.uniform(0.0, guide.cell, size=5)
        dist = _dijkstra_from_goal(guide, goal)
        found = shortest_path(guide.shape, guide._steps, guide.blocked, sources, gaps, goal,
                               guide.cell, guide.climb)
        best = np.min(gaps + dist[sources])
        if not np.isfinite(best):
            assert found is None
            continue
        chain, along = found
        assert chain[0] in sources and chain[-1] == goal
        assert not guide.blocked[chain].any()
        ijk = np.stack(np.unravel_index(chain, guide.shape), axis=1)
        lengths = [step_of[tuple(d)] for d in np.diff(ijk, axis=0)]  # KeyError: not neighbours
        assert np.allclose(along, np.cumsum(lengths[::-1])[::-1].tolist() + [0.0], rtol=1e-12)
        assert along[0] + gaps[list(sources).index(chain[0])] == pytest.approx(best, rel=1e-12)
        assert np.allclose(along, dist[chain], rtol=1e-12, atol=0.0)
    guide.blocked[:] = False
    goal = int(np.ravel_multi_index((5, 5, 5), guide.shape))
    walls = np.array(np.unravel_index(np.arange(guide.blocked.size), guide.shape)).T
    guide.blocked[np.abs(walls - 5).max(axis=1) == 1] = True  # a shell of cells round it
    assert shortest_path(guide.shape, guide._steps, guide.blocked, np.array([0]),
                          np.array([0.0]), goal, guide.cell, guide.climb) is None


def test_the_segments_are_seen_as_one_segment_at_a_time_would_see_them():
    """``_sees`` samples every segment together. Each must be seen exactly as its own samples
    say: s = skip, skip + cell/4, … below its length L, and L itself, each in a free cell
    (a segment no longer than skip is seen), on grids from nearly empty to crowded."""
    guide = Guide(np.array([-2.5, -2.5, 0.0]), np.array([12.5, 10.5, 8.0]))
    rng = np.random.default_rng(2)
    for share in (0.0, 0.01, 0.05, 0.2):
        guide.blocked[:] = rng.random(guide.blocked.size) < share
        y = rng.uniform(guide.lower, guide.upper)
        targets = y + rng.normal(size=(40, 3)) * rng.uniform(0.2, 6.0, size=(40, 1))
        one_at_a_time = []
        for target in targets:
            length = float(np.linalg.norm(target - y))
            s = np.append(np.arange(guide._skip, length, guide.cell / 4), length)
            samples = y + np.outer(s / length, target - y)
            one_at_a_time.append(length <= guide._skip or bool(guide._free(samples).all()))
        seen = guide._sees(y, targets)
        assert seen.tolist() == one_at_a_time
        assert 0 < seen.sum() < len(seen) or share == 0.0
    assert guide._sees(y, np.zeros((0, 3))).shape == (0,)


def test_the_set_point_filter_is_a_first_order_lag_of_the_guides_set_point():
    """With an empty map the guide's own set-point is the goal. When the goal steps, the
    filtered set-point glides to it as g₂ + (g₁ − g₂)·e^(−(t − t₁)/τ), whatever the call
    times; it starts at the first set-point and stays on the segment between the two. With
    no filter the same calls hand over the goal itself."""
    tau, g1, g2 = 0.5, GOAL, np.array([9.0, 0.0, 5.0])  # on the same level line
    # The vehicle is held at START: a stuck_time beyond the test keeps the path as it is.
    guide = Guide(LOWER, UPPER, set_point_filter=tau, stuck_time=1e3)
    plain = Guide(LOWER, UPPER, stuck_time=1e3)
    empty = VoxelMap()
    assert np.array_equal(guide.set_point(empty, START, 0.0, g1), g1)
    rng = np.random.default_rng(4)
    times = np.cumsum(rng.uniform(0.005, 0.05, 200)) + 1.0
    for t in times:
        got = guide.set_point(empty, START, t, g2)
        want = g2 + (g1 - g2) * math.exp(-(t - 0.0) / tau)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        along = np.dot(got - g1, g2 - g1) / np.dot(g2 - g1, g2 - g1)
        assert 0.0 < along < 1.0
        np.testing.assert_allclose(got, g1 + along * (g2 - g1), atol=1e-12)
        assert np.array_equal(plain.set_point(empty, START, t, g2), g2)
    guide.reset()
    assert np.array_equal(guide.set_point(empty, START, 0.0, g2), g2)
