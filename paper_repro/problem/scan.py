"""The LiDAR scan as parameters of problem (21): a fixed number of region slots of a fixed
number of points, and the one accepted form of a scan."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from dataclasses import dataclass

import casadi as ca
import numpy as np

from paper_repro.problem import distance as dist
from paper_repro.validation import as_vector

PAD_LOG_WEIGHT = -1e30
"""log w of a padding point of a slot: exp(log w) = 0, so padding never weighs in."""

SWEEP_SAMPLES = 5
"""Copies of a moving region along its swept path (``BarrierParams.sweep_time``): at 1.5 m/s
and t_s = 1 s they stand 0.375 m apart, about the clouds' spacing."""

MOVING_SPEEDS = (0.1, 0.3)
"""Predicted speeds, m/s, between which ``BarrierParams.moving_d_min`` ramps in."""

_FAR_AWAY = 1e3  # coordinate of the single dummy point of an inactive slot (its F is exactly 0)


# --- the LiDAR scan as parameters --------------------------------------------------------------

def region_shift(velocity, tau):
    """c = v·τ, m: how far a region seen moving at ``velocity`` v (p,) m/s is predicted to be
    from where it was seen, ``tau`` s after the scan (τ_j of ``NMPCParams.stage_time``). Its
    points are predicted at a_j + c; for the distance, D^{𝒜+c}(y) = D^𝒜(y − c). NumPy or
    CasADi, as given. Both solvers (through :meth:`ScanLayout.region_barrier`) and the
    figures of predicted points read it from here."""
    return velocity * tau


@dataclass(frozen=True)
class ScanLayout:
    """How a LiDAR scan enters the problem: ``slots`` region slots of ``capacity`` points.

    Per slot the parameters are (points (capacity, p) column-major, ln W (capacity,), ln V,
    active) for the smooth metric and (points, mask (capacity,), active) for the Euclidean
    one. Unused point slots have ln W = −1e30 (mask 0), so their terms are exactly zero; an
    unused region slot holds one dummy point and active = 0, which multiplies its penalty. W
    and V are computed from the visible points (the vehicle only knows what is in range).

    With a sensing window (``window`` > 0, smooth metric) each visible point is weighted by
    ψ(r), r its range from the sensor (the vehicle's position), in the centroid, W and V
    (:func:`~paper_repro.problem.distance.sensing_window`): ln ψ is folded into ln W, so the
    solvers'
    expressions are unchanged and a point at the edge of the range contributes nothing.

    Attributes
    ----------
    metric : ``"smooth"`` or ``"euclidean"``.  eta, sigma : η, σ, m.  d_min : m².
    slots : region slots.  capacity : points per slot.  dim : p, 3 or 2.
    window : w, m (0: off).  sensor_range : r_s, m.
    moving : each slot also carries the region's predicted velocity v (p,), m/s, after
        ``active``; the region at τ s after the scan is the scanned cloud moved by v·τ.
    reaction_time : t_r, s (0: off), with ``moving`` only. The margin of a moving region grows
        with its speed: β = D − ½(√(2·d_min) + ‖v‖·t_r)², the safe distance √(2·d_min)
        lengthened by the way the region covers in t_r (see
        :class:`~paper_repro.config.BarrierParams`). A region at rest keeps β = D − d_min.
    sweep_time : t_s, s (0: off), with ``moving`` only: D of the region's path over the next
        t_s seconds (:data:`SWEEP_SAMPLES` copies).
    moving_d_min : m² (0: off), with ``moving`` only: the margin of a region predicted to
        move, ramped in between the speeds of :data:`MOVING_SPEEDS`.
    equilibrium_lookahead : t_a, s (0: off), with ``moving`` only: β at the artificial
        equilibrium y_a (``beta(y, tau, at_equilibrium=True)``) is that of the region's path
        over the t_a seconds after the horizon (:data:`SWEEP_SAMPLES` copies), so the point
        the prediction rests at must stay clear of where the region is going.
    eta_squared : ``None``, or the symbol of η² when η and d_min are symbols read at run time
        (:meth:`with_symbols`).
    """

    metric: str
    eta: float
    sigma: float
    d_min: float
    slots: int
    capacity: int
    dim: int = 3
    window: float = 0.0
    sensor_range: float = 3.0
    moving: bool = False
    reaction_time: float = 0.0
    sweep_time: float = 0.0
    moving_d_min: float = 0.0
    equilibrium_lookahead: float = 0.0
    eta_squared: object = None

    @property
    def size(self) -> int:
        """Number of parameters of a whole scan."""
        per_point = self.dim + 1
        per_slot = self.capacity * per_point + (2 if self.metric == "smooth" else 1)
        return self.slots * (per_slot + (self.dim if self.moving else 0))

    def with_capacity(self, capacity: int) -> ScanLayout:
        return dataclasses.replace(self, capacity=capacity)

    def with_symbols(self, eta, eta_squared, d_min) -> ScanLayout:
        """This layout with η, η² and d_min as symbols (CasADi SX): values read at run time,
        so that another η or d_min does not build the code again. Only for building
        expressions: :meth:`pack` needs the numbers."""
        return dataclasses.replace(self, eta=eta, eta_squared=eta_squared, d_min=d_min)

    @functools.cached_property
    def _unused_scan(self) -> np.ndarray:
        """The parameters of a scan that fills no region slot: in each slot one dummy point far
        away, active = 0 (the same wherever the vehicle is, so made once; :meth:`pack`
        copies it and writes the regions in view over it)."""
        cap, dim = self.capacity, self.dim
        pts = np.full((cap, dim), _FAR_AWAY)
        log_w = np.full(cap, PAD_LOG_WEIGHT)
        mask = np.zeros(cap)
        log_w[0], mask[0] = 0.0, 1.0
        tail = [np.zeros(dim)] if self.moving else []
        if self.metric == "smooth":
            slot = np.concatenate([pts.ravel(order="F"), log_w, [0.0, 0.0], *tail])
        else:
            slot = np.concatenate([pts.ravel(order="F"), mask, [0.0], *tail])
        return np.tile(slot, self.slots)

    @functools.cached_property
    def _at_rest(self) -> np.ndarray:
        """The velocity of a region without a prediction, (p,) zeros, m/s."""
        return np.zeros(self.dim)

    def pack(self, visible: Sequence[np.ndarray], position, velocities=None) -> np.ndarray:
        """Pack a LiDAR scan into the parameter layout.

        Parameters
        ----------
        visible : per region, the (k_i, p) visible points (see :func:`check_visible`); regions
            with none are skipped.
        position : (p,) position of the vehicle, m. If more regions are visible than there are
            slots, the nearest regions are kept; if a region shows more points than a slot
            holds, the nearest points are kept.
        velocities : with a ``moving`` layout, one (p,) predicted velocity per region of
            ``visible``, m/s (``None``: all at rest).

        Returns
        -------
        (size,) array.
        """
        slots, cap, dim = self.slots, self.capacity, self.dim
        ref = as_vector("position", position, dim)
        visible = check_visible(visible, dim)
        if velocities is not None and not self.moving:
            raise ValueError("velocities need a layout built for moving regions (a controller "
                             "built with nmpc.prediction 'oracle' or 'kalman')")
        if velocities is not None and len(velocities) != len(visible):
            raise ValueError(f"velocities must hold one ({dim},) array per region of visible "
                             f"({len(visible)}), got {len(velocities)}")
        windowed = self.window > 0 and self.metric == "smooth"
        in_view = [i for i, v in enumerate(visible) if len(v)]
        # Squared ranges rank the regions and the points when a slot is short of room, and
        # set the sensing window; they are not needed otherwise (most scans).
        crowded = len(in_view) > slots
        # Per region in view: (points, squared ranges or None, ln ψ or None, velocity).
        seen = []
        for i in in_view:
            v = visible[i]
            sq = (np.sum((v - ref) ** 2, axis=1) if windowed or crowded or len(v) > cap
                  else None)
            log_p = None
            if windowed:
                log_p = dist.sensing_window(np.sqrt(sq), self.sensor_range, self.window)
                inside = np.isfinite(log_p)
                if not inside.any():
                    continue
                v, sq, log_p = v[inside], sq[inside], log_p[inside]
            velocity = (self._at_rest if velocities is None
                        else as_vector(f"velocities[{i}]", velocities[i], dim))
            seen.append((v, sq, log_p, velocity))
        if len(seen) > slots:
            order = np.argsort([s[1].min() for s in seen])[:slots]
            seen = [seen[i] for i in order]
        # Every slot unused, then the regions in view written over the first ones.
        out = self._unused_scan.copy()
        per_slot = len(out) // slots
        for slot, (cloud, sq, log_p, velocity) in enumerate(seen):
            # The scan's regions are checked (finite (k, p) floats): weigh them unchecked.
            _, log_w, log_v = dist.cloud_constants(cloud, self.sigma, log_p)
            if len(cloud) > cap:  # the nearest points, in cloud order
                keep = np.sort(np.argsort(sq)[:cap])
                cloud, log_w = cloud[keep], log_w[keep]
            self._fill_slot(out[slot * per_slot:(slot + 1) * per_slot], cloud, log_w, log_v,
                            velocity)
        return out

    def _fill_slot(self, block: np.ndarray, points: np.ndarray, log_w: np.ndarray,
                   log_v: float, velocity: np.ndarray) -> None:
        """Write a region into a slot's parameters ``block`` that hold an unused slot: its
        ``points`` (k ≤ capacity, p), column-major, then ln W (k,) (the Euclidean metric: the
        mask, 1 for each point), ln V, active = 1 and (``moving``) its velocity. The padding
        of an unused slot (points far away, ln W = −1e30, mask 0) stays beyond the k points
        (the unused slot's one dummy point, ln W = 0 and mask 1, is overwritten by the
        first)."""
        cap, dim, k = self.capacity, self.dim, len(points)
        block[:cap * dim].reshape(dim, cap)[:, :k] = points.T
        at = cap * dim
        if self.metric == "smooth":
            block[at:at + k] = log_w
            block[at + cap] = log_v
            at += cap + 1
        else:
            block[at:at + k] = 1.0
            at += cap
        block[at] = 1.0  # active
        if self.moving:
            block[at + 1:at + 1 + dim] = velocity

    def region_barrier(self):
        """Symbolic parameters of one region slot and β(y) = D(y) − d_min (eq. 17).

        Returns ``(params, beta, active)``: ``params`` is the slot's parameter column,
        ``beta(y, tau)`` the CasADi expression for a (p, 1) output y at ``tau`` seconds after
        the scan (moving layouts take ``at_equilibrium=True`` for y = y_a, see
        ``equilibrium_lookahead``), and ``active`` the slot's flag. A moving region is the
        scanned cloud translated by v·τ, and for a rigid translation D^{A+c}(y) = D^A(y − c):
        β(y − v·τ).
        Static (the paper), ``tau`` is ignored.
        """
        cap, dim = self.capacity, self.dim
        pts = ca.SX.sym("points", cap, dim)
        y = ca.SX.sym("y", dim)
        active = ca.SX.sym("active")
        if self.metric == "smooth":
            log_w = ca.SX.sym("log_w", cap)
            log_v = ca.SX.sym("log_v")
            d = dist.smooth_distance_symbolic(y, pts, log_w, log_v, self.eta, self.eta_squared)
            extra = [log_w, log_v]
        else:
            mask = ca.SX.sym("mask", cap)
            d = dist.euclidean_distance_symbolic(y, pts, mask)
            extra = [mask]
        # η, η² and d_min when they are symbols read at run time (:meth:`with_symbols`)
        shared = [v for v in (self.eta, self.eta_squared, self.d_min) if isinstance(v, ca.SX)]
        beta_fn = ca.Function("beta", [y, pts, *extra, *shared], [d - self.d_min])
        given = [*extra, *shared]
        if not self.moving:
            params = ca.vertcat(ca.vec(pts), *extra, active)
            return params, lambda yy, tau=0.0: beta_fn(yy, pts, *given), active
        velocity = ca.SX.sym("velocity", dim)
        params = ca.vertcat(ca.vec(pts), *extra, active, velocity)
        if (self.sweep_time == 0 and self.moving_d_min == 0 and self.reaction_time == 0
                and self.equilibrium_lookahead == 0):
            return (params, lambda yy, tau=0.0, at_equilibrium=False:
                    beta_fn(yy - region_shift(velocity, tau), pts, *given), active)
        # ‖v‖ of a parameter: never differentiated, so its kink at v = 0 does not matter.
        speed = ca.norm_2(velocity)
        lo, hi = MOVING_SPEEDS
        ramp = ca.fmin(ca.fmax((speed - lo) / (hi - lo), 0), 1)
        in_motion = ramp**2 * (3 - 2 * ramp)  # 0 at rest, 1 when moving: a smoothstep
        margin = self.d_min
        if self.moving_d_min > 0:
            margin = margin + (self.moving_d_min - self.d_min) * in_motion
        if self.reaction_time > 0:
            margin = 0.5 * (ca.sqrt(2.0 * margin) + speed * self.reaction_time) ** 2
        extra_margin = margin - self.d_min  # beta_fn already subtracts d_min

        def swept(yy, tau, span):
            """β of the region's path from τ to τ + span (the region itself when span = 0)."""
            if span == 0:
                return beta_fn(yy - region_shift(velocity, tau), pts, *given)
            copies = [beta_fn(yy - region_shift(velocity, tau + s), pts, *given)
                      for s in np.linspace(0.0, span, SWEEP_SAMPLES)]
            if self.metric == "euclidean":
                # the exact distance to the union of the copies (they coincide at rest)
                return ca.mmin(ca.vertcat(*copies))
            # D of the union of the region now and its copies ahead, these weighted by
            # `in_motion`: −η ln(e^{−D_0/η} + moving·Σ_{k≥1} e^{−D_k/η}), never above D_0 (never
            # less safe than the region now) and D_0 itself at rest. Shifted by the least
            # D_k so that no exponential overflows.
            low = ca.mmin(ca.vertcat(*copies))
            ahead = sum(ca.exp(-(c - low) / self.eta) for c in copies[1:])
            return low - self.eta * ca.log(ca.exp(-(copies[0] - low) / self.eta)
                                           + in_motion * ahead)

        def beta(yy, tau=0.0, at_equilibrium=False):
            span = self.sweep_time + (self.equilibrium_lookahead if at_equilibrium else 0.0)
            return swept(yy, tau, span) - extra_margin
        return params, beta, active

    def barriers(self):
        """Every slot at once: ``(params, beta, active)`` with ``params`` the scan's parameter
        column, ``beta(y, tau, at_equilibrium=False)`` the (slots,) expression of β at output
        y, ``tau`` s after the scan (``at_equilibrium``: y is the artificial equilibrium y_a,
        see ``equilibrium_lookahead``), and ``active`` the (slots,) flags."""
        slots = [self.region_barrier() for _ in range(self.slots)]
        params = ca.vertcat(*[s[0] for s in slots])
        active = ca.vertcat(*[s[2] for s in slots])
        if self.moving:
            def beta(y, tau=0.0, at_equilibrium=False):
                return ca.vertcat(*[s[1](y, tau, at_equilibrium) for s in slots])
        else:
            def beta(y, tau=0.0, at_equilibrium=False):
                return ca.vertcat(*[s[1](y, tau) for s in slots])
        return params, beta, active


# --- the one accepted form of inputs -----------------------------------------------------------

def check_visible(visible, dim: int = 3) -> tuple[np.ndarray, ...]:
    """The one accepted form of a LiDAR scan, checked and never reshaped.

    ``visible`` must be a list or tuple with one finite (k_i, p) array (or nested list) per
    region, k_i ≥ 0, p = ``dim``. A bare array, even (k, p), is rejected: iterating over it
    would make every point a region of its own. Returns the regions as float arrays (no copy
    when they already are), in a tuple that later calls recognise as checked, so the check
    costs a few microseconds once per solve. Raises ``ValueError`` naming ``visible[i]``.
    """
    if type(visible) is _CheckedScan and visible.dim == dim:
        return visible
    if not isinstance(visible, (list, tuple)):
        shape = f" of shape {visible.shape}" if isinstance(visible, np.ndarray) else ""
        raise ValueError(f"visible must be a list or tuple with one (k_i, {dim}) array per "
                         f"region, got {type(visible).__name__}{shape}; wrap one region's "
                         "points in a list: [points]")
    regions = []
    for i, v in enumerate(visible):
        arr = v if type(v) is np.ndarray and v.dtype == np.float64 else _region_array(i, v)
        if arr.ndim != 2 or arr.shape[1] != dim:
            raise ValueError(f"visible[{i}] must be a (k, {dim}) array of points (k ≥ 0), got "
                             f"shape {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"visible[{i}] must hold finite coordinates only (drop the "
                             "non-finite returns before solving)")
        regions.append(arr)
    return _CheckedScan(regions, dim)


def drop_non_finite(visible, dim: int = 3) -> tuple[Sequence[np.ndarray], int]:
    """A LiDAR scan without its non-finite points (a bad return is dropped, not flown on), and
    how many were dropped.

    ``visible`` : one (k_i, p) array per region. When every region then is a (k_i, ``dim``)
    float array, the scan comes back in the form :func:`check_visible` returns (its regions
    are finite now, so a solver does not check them again); otherwise as a list, for
    :func:`check_visible` to refuse with its message.
    """
    clean, dropped, checked = [], 0, True
    for v in visible:
        if len(v) and not np.isfinite(v).all():  # the points of the rows that are not finite
            ok = np.isfinite(v).all(axis=1)
            v = v[ok]
            dropped += int(len(ok) - ok.sum())
        clean.append(v)
        checked = checked and (type(v) is np.ndarray and v.dtype == np.float64
                               and v.ndim == 2 and v.shape[1] == dim)
    return (_CheckedScan(clean, dim) if checked else clean), dropped


class _CheckedScan(tuple):
    """A scan that :func:`check_visible` has accepted (so it is not checked twice)."""

    def __new__(cls, regions, dim: int):
        scan = super().__new__(cls, regions)
        scan.dim = dim
        return scan


def _region_array(i: int, value) -> np.ndarray:
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"visible[{i}] must be a (k, p) array of points, got "
                         f"{type(value).__name__}") from None


