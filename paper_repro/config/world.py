"""The world a closed loop flies: the mission, the LiDAR, the region tracker, the guide and the
plant (the simulator, its effects, the wind, the state estimate and the delay)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from paper_repro.validation import (
    is_number,
    require_choice,
    require_int,
    require_positive,
    require_range,
)


@dataclass(frozen=True)
class SimulationParams:
    """The mission a closed loop flies: the scene, when it ends, and how its end is judged.

    Attributes
    ----------
    scenario : scene name (``"paper"``, ``"encounter"``, ``"random"``, or with moving
        regions ``"crossing"``, ``"oncoming"``, ``"random-crossing"``, see
        :func:`paper_repro.world.scenarios.make_scene`).
    kind : ``"mission"`` (reach every target in turn, as the paper) or ``"passage"`` (the run
        ends when the UAV crosses the scene's finish line, 2 m past the obstacle field of a
        random scene; needs a scene with a ``finish``).
    tolerance : m, *paper* 0.3. A target counts as reached when the UAV is closer than this.
    max_steps : upper bound on closed-loop steps (one step is T_s).
    seed : seed of the scene: the Halton point clouds (region i uses ``seed + i``) and, for
        ``"random"``, the layout.
    stall_speed, stall_time, stall_distance : m/s, s, m, *chosen* 0.01, 5, 2. The NMPC is
        local and can deadlock in front of a cloud: the run is *stalled*, and ends, when the
        speed stays below ``stall_speed`` for more than ``stall_time`` while the UAV is more
        than ``stall_distance`` from its target. Under the printed weights the speed of a
        free approach is about (distance to target)/155 s, i.e. 1 cm/s at 1.5 m, so a
        threshold of 1 m would flag every normal final approach; 2 m leaves a third above it.
    approach_time : s, *chosen* 150 (near the printed set-up's lateral time constant, 155 s,
        :func:`paper_repro.analysis.clock.clock`). The pace a
        ``"random-crossing"`` scene times its crossings to (``RandomSceneParams``): a faster
        controller needs them sooner, or it passes first. Other scenes refuse another value.
    fault_steps : *chosen* 100 (1 s). A step whose measured state is not finite, or whose
        solve cannot start, is a *fault*: it is recorded and the previous plan is applied
        (shifted, as after a failed solve). After more than ``fault_steps`` faults in a row
        the run ends with the outcome ``"fault"``; the previous plan ends at rest at its
        artificial equilibrium, so holding it for a second is safe.
    workspace_exit : m, *chosen* 0, or ``None`` (no such rule). The run ends with the outcome
        ``"left_workspace"`` when the vehicle's position is farther than this outside the
        workspace (the quadrotor's 50 × 50 × 25 m box: its walls, the ground and the
        ceiling). A vehicle below the ground has crashed; without the rule the simulation
        flies on through it.
    """

    scenario: str = "paper"
    kind: str = "mission"
    tolerance: float = 0.3
    max_steps: int = 200_000
    seed: int = 7
    stall_speed: float = 0.01
    stall_time: float = 5.0
    stall_distance: float = 2.0
    fault_steps: int = 100
    approach_time: float = 150.0
    workspace_exit: float | None = 0.0

    def __post_init__(self):
        require_choice("kind", self.kind, ("mission", "passage"))
        if self.workspace_exit is not None and not (
                is_number(self.workspace_exit) and 0 <= self.workspace_exit < math.inf):
            raise ValueError(f"workspace_exit must be None or a finite number of metres >= 0, "
                             f"got {self.workspace_exit!r}")
        require_positive("tolerance", self.tolerance)
        for name in ("stall_speed", "stall_time", "stall_distance"):
            require_positive(name, getattr(self, name))
        if not (isinstance(self.scenario, str) and self.scenario):
            raise ValueError(f"scenario must be a scene name (a non-empty str), got "
                             f"{self.scenario!r}")
        require_int("max_steps", self.max_steps, 1)
        require_int("seed", self.seed, 0)
        require_int("fault_steps", self.fault_steps, 1)
        if not (is_number(self.approach_time) and 0 < self.approach_time <= 10_000 and (
                self.approach_time == 150.0 or self.scenario == "random-crossing")):
            raise ValueError(f"approach_time must be a number in (0, 10000] s, and 150 unless "
                             f"scenario is 'random-crossing', got {self.approach_time!r} for "
                             f"{self.scenario!r}")


@dataclass(frozen=True)
class SensorParams:
    """The virtual LiDAR (:class:`paper_repro.world.lidar.Lidar`): its range and, for studies,
    its imperfections.

    The defaults are a perfect sensor, as in the paper: every point within r_s is returned
    exactly, and nothing else. Noise is drawn from a generator seeded with ``seed``, so a
    flight is reproducible.

    Attributes
    ----------
    range : r_s, m, *paper* 3. The detection radius: a point is seen when it lies within r_s
        of the UAV. The problem reads it too, as the edge of the smooth sensing window
        (``distance.window``).
    range_noise : m, *chosen* 0. Standard deviation of Gaussian noise on the measured range,
        along the ray from the sensor to the point (the direction is exact).
    dropout : probability in [0, 1) that a point within range is not returned, *chosen* 0.
    spurious_rate : expected number of spurious returns per scan (Poisson), *chosen* 0; each
        lies uniformly inside the sensing sphere and is attributed to the region whose cloud
        holds the point nearest to it.
    seed : seed of the sensor's noise generator, an integer >= 0.
    map_voxel : m, *chosen* 0 (off: the controller reads the raw scan, as in the paper). With
        a voxel side > 0, the scans build a :class:`~paper_repro.world.local_map.VoxelMap`
        and the controller reads the map's points within r_s instead: what was seen
        persists, and noise averages down. Regions predicted to move (speed above
        ``MAPPED_SPEED``) stay out of the map and are read from the raw scan. In (0, r_s).
    """

    range: float = 3.0
    range_noise: float = 0.0
    dropout: float = 0.0
    spurious_rate: float = 0.0
    seed: int = 0
    map_voxel: float = 0.0

    def __post_init__(self):
        require_positive("range", self.range)
        for name in ("range_noise", "spurious_rate"):
            v = getattr(self, name)
            if not (is_number(v) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        require_range("dropout", self.dropout, 0.0, 1.0)
        require_int("seed", self.seed, 0)
        if not (is_number(self.map_voxel) and 0 <= self.map_voxel < self.range):
            raise ValueError(f"map_voxel must be 0 (off) or a voxel side in (0, range = "
                             f"{self.range}) m, got {self.map_voxel!r}")

    @property
    def perfect(self) -> bool:
        """True when the sensor adds no noise, drops nothing and invents nothing."""
        return self.range_noise == 0 and self.dropout == 0 and self.spurious_rate == 0


@dataclass(frozen=True)
class TrackerParams:
    """The region tracker of ``nmpc.prediction = "kalman"``
    (:class:`paper_repro.world.tracking.RegionTracker`): one constant-velocity Kalman filter
    per region, on the centroid of its visible points.

    Attributes
    ----------
    accel_noise : σ_a > 0, m/s², *chosen* 3: the white-acceleration process noise.
    centroid_noise : r > 0, m, *chosen* 0.02: the visible centroid's noise, per axis.
    forget_after : > 0, s, *chosen* 1: a region unseen this long is forgotten.
    velocity_prior : > 0, m/s, *chosen* 2: the velocity's standard deviation at first sight.
    gate_probability : in (0, 1), *chosen* 0.999, or ``None``: the innovation gate.
    subset_jump : ≥ 0, *chosen* 2 (0: off): the position variance added when the number of
        visible points changes, in RMS radii of the visible set.

    :class:`~paper_repro.world.tracking.RegionTracker` says what each does and why it has
    its default.
    """

    accel_noise: float = 3.0
    centroid_noise: float = 0.02
    forget_after: float = 1.0
    velocity_prior: float = 2.0
    gate_probability: float | None = 0.999
    subset_jump: float = 2.0

    def __post_init__(self):
        for name in ("accel_noise", "centroid_noise", "forget_after", "velocity_prior"):
            require_positive(name, getattr(self, name))
        p = self.gate_probability
        if p is not None and not (is_number(p) and 0.0 < p < 1.0):
            raise ValueError(f"gate_probability must lie in (0, 1), or be None (no gate), got "
                             f"{p!r}")
        if not (is_number(self.subset_jump) and math.isfinite(self.subset_jump)
                and self.subset_jump >= 0):
            raise ValueError(f"subset_jump must be a finite number >= 0 (0 is off), got "
                             f"{self.subset_jump!r}")


GUIDES = ("none", "grid")
"""What hands the NMPC its set-point (``GuideParams.planner``)."""


@dataclass(frozen=True)
class GuideParams:
    """The guide (:class:`paper_repro.world.guide.Guide`): a path on the local map's inflated
    occupancy, whose look-ahead point becomes the NMPC's set-point y_t.

    Attributes
    ----------
    planner : ``"none"`` (*paper*: the set-point is the mission's target) or ``"grid"``
        (the shortest path, by A*, on a 26-connected grid of the workspace; needs the local map,
        ``sensor.map_voxel`` > 0, and a 3-D scene).
    cell : m, *chosen* 1. Side of a grid cell.
    inflation : m, *chosen* 2. A cell is blocked when a mapped point lies within this of its
        centre: the printed barrier's safe distance √(2·d_min) = 1.41 m, and the half-cell a
        path between cell centres may cut. With 1.5 m the path led through gaps the NMPC
        cannot pass (under a wall, by the floor) and the vehicle stalled there.
    lookahead : m, *chosen* 8. The look-ahead point is the farthest path cell within this that
        the vehicle sees along a free segment.
    check_period : s, *chosen* 0.1. How often the guide reads the map and moves the set-point
        on (so y_t is constant for at least this long).
    replan_period : s, *chosen* 1. The least time between two plans; a plan is made when a
        newly mapped voxel blocks the path.
    max_turn : degrees, *chosen* 3. The most the guide's pull turns per check (30°/s), so
        that a new look-ahead point does not make the thrusts jump.
    climb : *chosen* 2. What a metre up or down costs the path, in metres along the level:
        the path keeps the flight's altitude unless a detour over or under is much shorter.
    stuck_time : s, *chosen* 2.5. A vehicle that moved less than 5 cm over this long, far
        from its goal, is stuck: the cells between it and its aim are avoided and the path is
        planned again (before the closed loop calls the run stalled, after 5 s).
    set_point_filter : s, *chosen* 0.5 (0: none). Time constant of a first-order filter on
        the set-point handed to the NMPC: the guide's set-point moves in small steps at every
        check, whose 10 Hz content reaches the thrusts; the filter makes it glide instead
        (``benchmarks/guide_filter.py`` measures it against none).
    """

    planner: str = "none"
    cell: float = 1.0
    inflation: float = 2.0
    lookahead: float = 8.0
    check_period: float = 0.1
    replan_period: float = 1.0
    max_turn: float = 3.0
    climb: float = 2.0
    stuck_time: float = 2.5
    set_point_filter: float = 0.5

    def __post_init__(self):
        require_choice("planner", self.planner, GUIDES)
        require_range("set_point_filter", self.set_point_filter, 0.0, math.inf)
        for name in ("cell", "inflation", "check_period", "replan_period", "max_turn", "climb",
                     "stuck_time"):
            require_positive(name, getattr(self, name))
        if not (is_number(self.lookahead) and math.isfinite(self.lookahead)
                and self.lookahead >= self.cell):
            raise ValueError(f"lookahead must be a finite number >= cell = {self.cell} m, got "
                             f"{self.lookahead!r}")


PLANT_SIMULATORS = ("ours", "rotorpy")
"""What integrates the vehicle (``PlantParams.simulator``)."""

TURBULENCE = ("none", "light", "moderate", "severe")
"""Dryden turbulence levels of MIL-F-8785C (``PlantParams.turbulence``)."""

ESTIMATES = {
    "perfect": (0.0, 0.0, 0.0, 0.0, 0),
    "mocap": (0.002, 0.002, 0.03, 0.01, 1),
    "vio": (0.02, 0.01, 0.05, 0.02, 3),
}
"""The state estimates of ``PlantParams.estimation``: (σ_position m, σ_angle rad,
σ_velocity m/s, σ_rate rad/s, latency in steps of T_s). ``mocap``: a motion-capture system,
1–3 mm and about 3 cm/s, 6–7 ms late (one step of 10 ms). ``vio``: visual-inertial
odometry, centimetres, 20–50 ms late (three steps); these magnitudes are an assumption, not
a measurement of one system."""


@dataclass(frozen=True)
class PlantParams:
    """What the vehicle flies in, besides its model: the simulator, the effects the NMPC's
    model leaves out, the wind, the state estimate and the computation delay
    (:func:`paper_repro.sim.plant.plant_for`). The defaults are the paper's: our own
    integration of the NMPC's model, perfect state, no delay. The NMPC always predicts with
    its nominal model.

    Attributes
    ----------
    simulator : ``"ours"`` (default, :class:`~paper_repro.sim.plant.QuadrotorPlant`) or
        ``"rotorpy"`` (:class:`~paper_repro.sim.rotorpy_plant.RotorpyPlant`, RotorPy's
        multirotor, the ``hardware`` extra). The effects below need ``"rotorpy"``.
    motor_lag : τ_m, s, >= 0. Time constant of the rotor speeds' first-order lag (0: none).
        *typical* 0.03 (PX4's simulators use 0.0125–0.05; fitted x500 thrust lags
        0.045–0.071).
    rotor_drag : k_d, N/(rad/s · m/s), >= 0. In-plane rotor drag (H force), −ω_i·k_d·v_air.
        *typical* 8e-5 to 2.6e-4 (the x500's ``rotorDragCoefficient``).
    induced_inflow : k_z, N/(rad/s · m/s), >= 0. The same along the rotor axis.
    translational_lift : k_h, N/(m/s)², >= 0. Extra thrust k_h·(in-plane airspeed)².
    blade_flapping : k_flap, N·m/(rad/s · m/s), >= 0. Flapping moment at each hub.
    parasitic_drag : (c_Dx, c_Dy, c_Dz), N/(m/s)², each >= 0. Body drag −‖v‖·diag(c_D)·v
        (airspeed in the body frame). *typical* about 1e-2.
    thrust_scale : > 0. True thrust coefficient over the nominal b (1: none; ±10 %: 0.9, 1.1).
        The rotors turn at the speed the nominal b gives for the commanded thrust, √(f/b), and
        produce thrust_scale·f. The yaw-torque coefficient k_τ is unchanged.
    mass_scale : > 0. True mass over the nominal one (1: none). The inertia is unchanged.
    com_offset : (3,) m. Centre of mass from the geometric centre, body frame. The rotors are
        placed at their arm positions minus this offset; the inertia is unchanged. The state
        is the centre of mass's (RotorPy integrates the centre of mass).
    wind : (3,) m/s, the mean wind in the world frame. Wind acts through drag, so it needs
        ``rotor_drag``, ``induced_inflow`` or ``parasitic_drag`` above 0.
    turbulence : Dryden turbulence on top of the mean wind, one of :data:`TURBULENCE`
        (:func:`paper_repro.world.wind.dryden_turbulence`, at the start's altitude).
    gust : (3,) m/s, the peak of one 1-cosine gust (0: none), lasting ``gust_duration`` s
        from ``gust_start`` s.
    gust_clearance : m, or ``None`` (default). The gust starts instead at the first step at
        which the vehicle is within this distance of a cloud point: timed to meet it where it
        passes closest to an obstacle.
    estimation : the state the controller is given, one of :data:`ESTIMATES`: the true
        state (``"perfect"``, default) or an estimate with noise and latency.
    delay_steps : computation delay, in steps of T_s (0, 1 or 2 typical): the input computed
        from the measurement at step k is applied from step k + delay_steps; hover thrust
        until then.
    estimate_filter_time : τ, s, or ``None`` (default). A number > 0: a remedy for the
        estimate's noise. The estimate is filtered with the nominal model and time constant
        τ (:class:`~paper_repro.sim.imperfect.EstimateFilter`). Needs an estimate other than
        ``"perfect"``.
    compensate_latency : ``False`` (default). ``True``: a remedy for the latency. The
        controller is given the state its next input will meet: the measured state rolled
        forward with the nominal model through the inputs sent over the estimate's latency
        and the delay (:class:`~paper_repro.sim.imperfect.LatencyCompensation`). Needs a
        latency: an estimate other than ``"perfect"`` or ``delay_steps`` above 0.
    hover_thrust_time : τ, s, or ``None`` (default). A number > 0: a remedy for a vehicle
        heavier or weaker than the nominal one. The thrusts sent are divided by an estimate
        of the thrust the vehicle makes over the nominal, learnt from its vertical
        acceleration with time constant τ
        (:class:`~paper_repro.sim.imperfect.HoverThrustEstimate`). *typical* 2.
    motor_lag_compensation : τ̂, s, or ``None`` (default). A number > 0: a remedy for the
        motor lag. Each thrust is sent with a lead, u + τ̂·u̇, the inverse of a first-order
        lag of time constant τ̂ (:class:`~paper_repro.sim.imperfect.MotorLagCompensation`).
        τ̂ is the rotors' time constant as identified; *typical* ``motor_lag``.
    seed : seed of the turbulence and of the estimate's noise, an integer >= 0.
    """

    simulator: str = "ours"
    motor_lag: float = 0.0
    rotor_drag: float = 0.0
    induced_inflow: float = 0.0
    translational_lift: float = 0.0
    blade_flapping: float = 0.0
    parasitic_drag: tuple[float, float, float] = (0.0, 0.0, 0.0)
    thrust_scale: float = 1.0
    mass_scale: float = 1.0
    com_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    turbulence: str = "none"
    gust: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gust_duration: float = 0.75
    gust_start: float = 0.0
    gust_clearance: float | None = None
    estimation: str = "perfect"
    delay_steps: int = 0
    estimate_filter_time: float | None = None
    compensate_latency: bool = False
    hover_thrust_time: float | None = None
    motor_lag_compensation: float | None = None
    seed: int = 0

    def __post_init__(self):
        require_choice("simulator", self.simulator, PLANT_SIMULATORS)
        require_choice("turbulence", self.turbulence, TURBULENCE)
        require_choice("estimation", self.estimation, tuple(ESTIMATES))
        for name in ("motor_lag", "rotor_drag", "induced_inflow", "translational_lift",
                     "blade_flapping", "gust_start"):
            value = getattr(self, name)
            if not (is_number(value) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        for name in ("thrust_scale", "mass_scale", "gust_duration"):
            require_positive(name, getattr(self, name))
        for name, low in (("parasitic_drag", 0.0), ("com_offset", -math.inf),
                          ("wind", -math.inf), ("gust", -math.inf)):
            value = getattr(self, name)
            if not (isinstance(value, (tuple, list)) and len(value) == 3
                    and all(is_number(v) and math.isfinite(v) and v >= low for v in value)):
                what = "finite numbers >= 0" if low == 0 else "finite numbers"
                raise ValueError(f"{name} must be 3 {what}, got {value!r}")
        require_int("delay_steps", self.delay_steps, 0)
        require_int("seed", self.seed, 0)
        if self.gust_clearance is not None and not (
                is_number(self.gust_clearance) and 0 < self.gust_clearance < math.inf):
            raise ValueError(f"gust_clearance must be None or a finite number of metres > 0, "
                             f"got {self.gust_clearance!r}")
        if self.gust_clearance is not None and not any(self.gust):
            raise ValueError("gust_clearance times a gust: set gust (its peak, m/s) too")
        if not isinstance(self.compensate_latency, bool):
            raise ValueError(f"compensate_latency must be True or False, got "
                             f"{self.compensate_latency!r}")
        if self.compensate_latency and self.latency_steps() == 0:
            raise ValueError("compensate_latency needs a latency to compensate: an estimation "
                             "other than 'perfect' or delay_steps above 0")
        if self.estimate_filter_time is not None and self.estimation == "perfect":
            raise ValueError("estimate_filter_time filters a noisy estimate: set estimation "
                             f"to one of {[e for e in ESTIMATES if e != 'perfect']}")
        for name in ("estimate_filter_time", "hover_thrust_time", "motor_lag_compensation"):
            value = getattr(self, name)
            if value is not None and not (is_number(value) and 0 < value < math.inf):
                raise ValueError(f"{name} must be None or a finite number of seconds > 0, "
                                 f"got {value!r}")
        extra = self.effects()
        if self.simulator == "ours" and extra:
            raise ValueError(f"{extra[0]} is an effect our plant (the NMPC's own model) does "
                             "not have: it needs simulator 'rotorpy'")
        if self.moving_air() and not self.aerodynamic:
            raise ValueError("wind, turbulence and gusts act through drag: set rotor_drag, "
                             "induced_inflow or parasitic_drag above 0")

    def effects(self) -> list[str]:
        """The names of the settings that are not our plant's (off: their default)."""
        return [f.name for f in fields(self)
                if f.name in _EFFECTS and getattr(self, f.name) != f.default]

    def latency_steps(self) -> int:
        """L + d, steps of T_s: the estimate's latency and the computation delay."""
        return ESTIMATES[self.estimation][-1] + self.delay_steps

    def moving_air(self) -> bool:
        """Whether the air moves: a mean wind, turbulence or a gust."""
        return (any(self.wind) or self.turbulence != "none" or any(self.gust))

    @property
    def aerodynamic(self) -> bool:
        """Whether any aerodynamic effect is on (only then does wind act)."""
        return any(v > 0 for v in (self.rotor_drag, self.induced_inflow,
                                   self.translational_lift, self.blade_flapping,
                                   *self.parasitic_drag))


_EFFECTS = ("motor_lag", "rotor_drag", "induced_inflow", "translational_lift", "blade_flapping",
            "parasitic_drag", "thrust_scale", "mass_scale", "com_offset", "wind", "turbulence",
            "gust")
