"""Every default parameter of the reproduction, in one place.

All settings are frozen dataclasses; make variants with :func:`dataclasses.replace`.
Values printed in the paper (Section V) are marked *paper*; values the paper leaves
open are marked *chosen* and justified here and in ``environment.md``.

=================  ==================================================================
``problem``        the quadrotor, the distance, the barrier, the NMPC, the solver
``world``          the mission, the LiDAR, the region tracker, the guide, the plant
(here)             :class:`Config`, every part of one run
=================  ==================================================================
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from paper_repro.config.problem import (
    COLD_STARTS,
    PREDICTIONS,
    QP_SOLVERS,
    BarrierParams,
    DistanceParams,
    NMPCParams,
    QuadrotorParams,
    SolverParams,
    relaxed_box,
)
from paper_repro.config.world import (
    ESTIMATES,
    GUIDES,
    PLANT_SIMULATORS,
    TURBULENCE,
    GuideParams,
    PlantParams,
    SensorParams,
    SimulationParams,
    TrackerParams,
)
from paper_repro.config_history import keyed, moved_settings, with_added

__all__ = ["BarrierParams", "COLD_STARTS", "Config", "DistanceParams", "ESTIMATES", "GUIDES",
           "GuideParams", "NMPCParams", "PLANT_SIMULATORS", "PlantParams", "PREDICTIONS",
           "QP_SOLVERS", "QuadrotorParams", "relaxed_box", "SensorParams", "SimulationParams",
           "SolverParams", "TrackerParams", "TURBULENCE"]


@dataclass(frozen=True)
class Config:
    """Everything that defines one run; saved as ``config.json`` beside each result.

    The problem's data are ``quadrotor``, ``distance``, ``barrier``, ``nmpc`` and the LiDAR's
    range (``sensor.range``); ``solver`` says how the problem is solved, and ``simulation``,
    the rest of ``sensor``, ``tracker``, ``guide`` and ``plant`` describe the world it is
    flown in.

    A ``config.json`` written before a part existed (e.g. ``sensor``) loads with that part's
    defaults, and one written before a setting moved loads it in its new place
    (:meth:`from_dict`, :data:`~paper_repro.config_history.MOVED`).
    """

    quadrotor: QuadrotorParams = field(default_factory=QuadrotorParams)
    distance: DistanceParams = field(default_factory=DistanceParams)
    barrier: BarrierParams = field(default_factory=BarrierParams)
    nmpc: NMPCParams = field(default_factory=NMPCParams)
    solver: SolverParams = field(default_factory=SolverParams)
    simulation: SimulationParams = field(default_factory=SimulationParams)
    sensor: SensorParams = field(default_factory=SensorParams)
    guide: GuideParams = field(default_factory=GuideParams)
    tracker: TrackerParams = field(default_factory=TrackerParams)
    plant: PlantParams = field(default_factory=PlantParams)

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if not isinstance(getattr(self, f.name), f.default_factory):
                raise ValueError(f"{f.name} must be a {f.default_factory.__name__}, got "
                                 f"{getattr(self, f.name)!r}")
        if self.distance.window >= self.sensor.range:
            raise ValueError(f"distance.window must be < sensor.range = "
                             f"{self.sensor.range} m (a window as wide as the range "
                             f"sees nothing at full weight), got {self.distance.window!r}")
        if self.guide.planner != "none" and self.sensor.map_voxel == 0:
            raise ValueError(f"guide.planner {self.guide.planner!r} plans on the local map: "
                             "set sensor.map_voxel > 0 (a voxel side in m, e.g. 0.5)")
        for name in ("reaction_time", "sweep_time", "moving_d_min", "equilibrium_lookahead"):
            value = getattr(self.barrier, name)
            if value > 0 and self.nmpc.prediction == "static":
                raise ValueError(f"barrier.{name} needs nmpc.prediction 'oracle' or 'kalman': "
                                 "the static prediction (the paper's) hands the problem no "
                                 f"region velocity to act on, got {name} {value!r}")
        # Cross-field: the artificial equilibrium (hover at rest, eq. 7) must exist in
        # λ(𝒳 × 𝒰), or the OCP is infeasible at every step.
        q = self.quadrotor
        xl, xu, ul, uu = q.relaxed_bounds(self.nmpc.lam)
        if not np.all((ul <= q.hover_thrust) & (q.hover_thrust <= uu)):
            raise ValueError(f"quadrotor.input_lower/input_upper must hold the hover thrust "
                             f"m·g/4 = {q.hover_thrust:.4g} N inside λ(𝒰) = [{ul.min():.4g}, "
                             f"{uu.max():.4g}] N per rotor, got input bounds "
                             f"{q.input_lower!r} to {q.input_upper!r}")
        for i in (3, 4, *range(6, 12)):  # roll, pitch, velocities and rates are 0 at rest
            if not xl[i] <= 0.0 <= xu[i]:
                raise ValueError(f"quadrotor.state_lower[{i}] < 0 < quadrotor.state_upper[{i}] "
                                 "is needed "
                                 f"for hover (at rest this state is 0), got λ-relaxed bounds "
                                 f"[{xl[i]:.4g}, {xu[i]:.4g}]")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def key_dict(self) -> dict:
        """What a run's cache key hashes: :meth:`to_dict` without the settings of
        :data:`~paper_repro.config_history.ADDED` that hold the value they were added with,
        and the settings of :data:`~paper_repro.config_history.KEYED_IN_FORMER_PLACE` in
        their former place (:func:`~paper_repro.config_history.keyed`)."""
        return keyed(self.to_dict(), Config().to_dict())

    @classmethod
    def from_dict(cls, data: dict) -> Config:
        """Inverse of :meth:`to_dict` and of :meth:`key_dict`; a missing part (an older file)
        takes its defaults, a setting in its former place
        (:data:`~paper_repro.config_history.MOVED`) is read into its new one, and a setting
        added since a part was written (:data:`~paper_repro.config_history.ADDED`) takes the
        value that flies as before it (``with_added``), not its default."""
        if not isinstance(data, dict):
            raise ValueError(f"config must be a dict of parts, got {type(data).__name__}")
        data = with_added(moved_settings(data))
        unknown = set(data) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ValueError(f"config has unknown parts {sorted(unknown)}")
        parts = {}
        for f in dataclasses.fields(cls):
            sub_cls = f.default_factory
            sub = dict(data.get(f.name, {}))
            for sf in dataclasses.fields(sub_cls):
                if sf.name in sub and isinstance(sub[sf.name], list):
                    sub[sf.name] = tuple(sub[sf.name])
            unknown = set(sub) - {sf.name for sf in dataclasses.fields(sub_cls)}
            if unknown:
                raise ValueError(f"unknown {f.name} parameters: {sorted(unknown)}")
            parts[f.name] = sub_cls(**sub)
        return cls(**parts)

