"""The world the vehicle flies in: obstacle regions as point clouds, how they move, and what
the LiDAR sees of them, and what the robot makes of it: a map and a guide.

=================  ==================================================================
``shapes``         boxes, cylinders, unions, differences; Halton clouds inside them
``motion``         :class:`Motion`, a region's piecewise-constant velocity
``scene``          :class:`Region`, :class:`Scene` (saved with every result)
``scenarios``      the named scenes, :func:`make_scene`
``random_scenes``  seeded random obstacle fields across a straight flight
``planar``         a planar scene (p = 2) for a ground robot
``scan_files``     :func:`read_scan`, points from .npy, .npz, .csv/.xyz/.txt, .ply, .pcd
``scan_regions``   :func:`scan_scene`, scan files placed, split into regions, thinned
``lidar``          :class:`Lidar`, the virtual LiDAR (optionally imperfect)
``truth``          what no sensor sees: true region offsets, velocities, clearance
``tracking``       :class:`RegionTracker`, a Kalman filter of the regions' velocities
``local_map``      :class:`VoxelMap`, a bounded log-odds map of the scans (an option)
``guide``          :class:`Guide`, a path on the map handing the NMPC its set-points
``wind``           mean wind, Dryden turbulence, 1-cosine gusts (for a plant)
=================  ==================================================================
"""

from paper_repro.world.guide import Guide
from paper_repro.world.lidar import Lidar
from paper_repro.world.local_map import VoxelMap
from paper_repro.world.motion import Motion
from paper_repro.world.planar import planar_scene
from paper_repro.world.random_scenes import (
    NONCONVEX_KINDS,
    REGION_KINDS,
    RandomSceneParams,
    crossing_motions,
    passage_progress,
    random_scene,
)
from paper_repro.world.scan_files import SCAN_SUFFIXES, read_scan
from paper_repro.world.scan_regions import (
    REGION_VOXEL,
    place_scan,
    scan_regions,
    scan_scene,
    split_regions,
)
from paper_repro.world.scenarios import (
    CROSSING_SPEED,
    MEETING_TIME,
    ONCOMING_SPEED,
    SCENARIOS,
    crossing_scene,
    encounter_scene,
    make_scene,
    oncoming_scene,
    paper_scene,
)
from paper_repro.world.scene import WORKSPACE_LOWER, WORKSPACE_UPPER, Region, Scene
from paper_repro.world.shapes import (
    Box,
    Cylinder,
    Difference,
    Union,
    halton_cloud,
    shape_from_dict,
    shape_to_dict,
)
from paper_repro.world.tracking import RegionTracker, centroid_of, chi2_quantile

__all__ = [
    "Box",
    "centroid_of",
    "chi2_quantile",
    "crossing_motions",
    "crossing_scene",
    "CROSSING_SPEED",
    "Cylinder",
    "Difference",
    "encounter_scene",
    "Guide",
    "halton_cloud",
    "Lidar",
    "make_scene",
    "MEETING_TIME",
    "Motion",
    "NONCONVEX_KINDS",
    "oncoming_scene",
    "ONCOMING_SPEED",
    "paper_scene",
    "passage_progress",
    "place_scan",
    "planar_scene",
    "random_scene",
    "read_scan",
    "RandomSceneParams",
    "Region",
    "REGION_VOXEL",
    "REGION_KINDS",
    "RegionTracker",
    "SCAN_SUFFIXES",
    "scan_regions",
    "scan_scene",
    "SCENARIOS",
    "Scene",
    "shape_from_dict",
    "shape_to_dict",
    "split_regions",
    "Union",
    "VoxelMap",
    "WORKSPACE_LOWER",
    "WORKSPACE_UPPER",
]
