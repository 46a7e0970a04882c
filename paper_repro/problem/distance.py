"""Smoothed point-to-cloud distance of Section III and its Euclidean baseline.

For a cloud 𝒜 = {a_j} and an output y (eq. 8-11)::

    D_{η,σ}(y) = −η² ln( (1/V) Σ_j W_j exp(−‖y − a_j‖² / (2η²)) )
    W_j = exp(−‖a_j − Cen(𝒜)‖² / (2σ²)),   V = Σ_j W_j

and the smoothed projection Π (eq. 12) is the softmax-weighted mean of the points, with
∇D = y − Π (eq. 13). As η → 0, D tends to **½·d²**, half the squared Euclidean distance
d = min_j ‖y − a_j‖ (not to d): D is in m², and so are d_min and the Euclidean baseline
½·min_j ‖y − a_j‖² that the paper's comparison uses here so that both metrics share units.

Numerics: D is evaluated as a shifted log-sum-exp. With exponents
e_j = ln W_j − ‖y − a_j‖²/(2η²) and s = max_j e_j (the smallest ‖·‖²/(2η²) − ln W_j),
D = −η²(s + ln Σ_j exp(e_j − s) − ln V). The naive formula underflows to ln 0 about 11 m
from a cloud at η = 0.3; the shifted one is exact at any distance.

The y-independent quantities (centroid, ln W_j, ln V) live in :class:`CloudWeights`, computed
once per cloud. The same expression code serves NumPy (vectorised over query points) and
CasADi (symbolic, for the NLP). Points and outputs live in R³ (the quadrotor) or R² (a ground
robot): every function takes clouds of shape (m, 3) or (m, 2) with y of the same dimension.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

# Number of (query, point) pairs evaluated at once by the NumPy path; bounds memory to ~50 MB.
_CHUNK_PAIRS = 2_000_000


@dataclass(frozen=True)
class CloudWeights:
    """Per-cloud constants of eq. (9)-(11).

    Attributes
    ----------
    points : (m, p) array, m (p = 3, or 2 for a planar cloud).
    centroid : (p,) array, Cen(𝒜), m.
    log_weights : (m,) array, ln W_σ(a_j) = −‖a_j − Cen‖²/(2σ²).
    log_volume : float, ln V_σ = ln Σ_j W_j (shifted log-sum-exp).
    sigma : σ, m.
    """

    points: np.ndarray
    centroid: np.ndarray
    log_weights: np.ndarray
    log_volume: float
    sigma: float

    @classmethod
    def from_cloud(cls, cloud, sigma: float, log_presence=None) -> CloudWeights:
        """Validate a cloud and compute its weights. ``cloud`` : (m, p) array, m ≥ 1, p = 2 or 3.

        ``log_presence`` : optional (m,) ln ψ_j ≤ 0, how much each point is in view (see
        :func:`sensing_window`). Point j then counts with weight ψ_j everywhere: in the
        centroid (Σψ_j a_j / Σψ_j), in W_j (ln W_j gains ln ψ_j) and so in V = Σ ψ_j W_j. A
        point with ψ_j → 0 contributes nothing, continuously.
        """
        points = check_cloud(cloud)
        _check_scale("sigma", sigma)
        log_p = None
        if log_presence is not None:
            log_p = np.asarray(log_presence, float)
            if log_p.shape != (len(points),) or np.any(log_p > 0) or np.any(np.isnan(log_p)) \
                    or not np.isfinite(log_p).any():
                raise ValueError(f"log_presence must be ({len(points)},) values <= 0, at least "
                                 "one finite")
        return cls(points, *cloud_constants(points, sigma, log_p), float(sigma))


def cloud_constants(points: np.ndarray, sigma: float,
                    log_presence: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """(Cen (p,), ln W (m,), ln V) of eq. (9)-(11): the numbers of
    :meth:`CloudWeights.from_cloud` without its checks, for points already checked (a
    scan's regions, which :func:`~paper_repro.problem.scan.check_visible` accepted).

    ``points`` : (m, p) finite float array, m ≥ 1, m.  ``sigma`` : σ > 0, m.
    ``log_presence`` : ``None`` or (m,) float ln ψ_j ≤ 0, at least one finite.
    """
    if log_presence is None:
        centroid = points.mean(axis=0)
        log_w = -np.sum((points - centroid) ** 2, axis=1) / (2.0 * sigma**2)
    else:
        presence = np.exp(log_presence - log_presence.max())
        centroid = presence @ points / presence.sum()
        log_w = log_presence - np.sum((points - centroid) ** 2, axis=1) / (2.0 * sigma**2)
    return centroid, log_w, float(_logsumexp_np(log_w))


def sensing_window(r, sensor_range: float, width: float) -> np.ndarray:
    """ln ψ(r) of the smooth sensing window: ψ = 1 for r ≤ r_s − w, 0 for r ≥ r_s, and in
    between the C∞ step ψ = e^{−1/t} / (e^{−1/t} + e^{−1/(1−t)}), t = (r_s − r)/w.

    Every derivative of ψ vanishes at both ends, so a point that crosses r_s enters D, ∇D
    and every higher derivative continuously (a hard cut-off makes D jump).

    Parameters
    ----------
    r : (m,) distances from the sensor, m.  sensor_range : r_s, m.  width : w, 0 < w ≤ r_s, m.

    Returns
    -------
    (m,) ln ψ ≤ 0 (−inf at and beyond r_s).
    """
    t = (sensor_range - np.asarray(r, float)) / width
    out = np.zeros_like(t)
    out[t <= 0] = -np.inf
    mid = (t > 0) & (t < 1)
    tm = t[mid]
    a, b = -1.0 / tm, -1.0 / (1.0 - tm)
    out[mid] = a - np.logaddexp(a, b)
    return out


def smooth_distance(y, cloud, eta: float, sigma: float):
    """Smoothed point-to-cloud distance D_{η,σ}(y), eq. (8).

    Parameters
    ----------
    y : (3,) or (n, 3) array, m ((2,) or (n, 2) with a planar cloud).
    cloud : (m, 3) array of points (or (m, 2)), m, or a precomputed :class:`CloudWeights`.
    eta : η > 0, m.  sigma : σ > 0, m (ignored when ``cloud`` is a ``CloudWeights``).

    Returns
    -------
    float for y of shape (3,), (n,) array for y of shape (n, 3); m² (tends to ½·d² as η → 0).
    """
    weights, ys, single = _prepare(y, cloud, eta, sigma)
    out = np.empty(len(ys))
    for sl, sq in _chunks(ys, weights.points):
        out[sl] = _distance_expression(sq, weights.log_weights, weights.log_volume, eta,
                                       _logsumexp_np)
    return float(out[0]) if single else out


def smooth_projection(y, cloud, eta: float, sigma: float):
    """Smoothed projection Π_{η,σ}(y), eq. (12): softmax-weighted mean of the points.

    Same arguments as :func:`smooth_distance`. Returns (3,) for y of shape (3,), (n, 3) for
    (n, 3); m. The gradient of D is y − Π (eq. 13).
    """
    weights, ys, single = _prepare(y, cloud, eta, sigma)
    out = np.empty(ys.shape)
    for sl, sq in _chunks(ys, weights.points):
        e = weights.log_weights - sq / (2.0 * eta**2)
        p = np.exp(e - e.max(axis=-1, keepdims=True))
        out[sl] = (p @ weights.points) / p.sum(axis=-1, keepdims=True)
    return out[0] if single else out


def smooth_distance_gradient(y, cloud, eta: float, sigma: float):
    """∇_y D_{η,σ}(y) = y − Π_{η,σ}(y), eq. (13); shape of ``y``, m."""
    proj = smooth_projection(y, cloud, eta, sigma)
    return np.asarray(y, dtype=float) - proj


def euclidean_distance(y, cloud):
    """Euclidean baseline ½·min_j ‖y − a_j‖² (m², same units as D).

    ``y`` : (3,) or (n, 3); returns float or (n,).
    """
    ys, single = _check_queries(y)
    points = check_cloud(cloud, ys.shape[1])
    out = np.empty(len(ys))
    for sl, sq in _chunks(ys, points):
        out[sl] = 0.5 * sq.min(axis=-1)
    return float(out[0]) if single else out


def clearance(y, cloud) -> float | np.ndarray:
    """True minimum Euclidean distance from y to the cloud, m (reporting, not optimisation)."""
    return np.sqrt(2.0 * euclidean_distance(y, cloud))


def smooth_distance_symbolic(y, points, log_weights, log_volume, eta, eta_squared=None):
    """CasADi expression of D_{η,σ}(y) for the NLP.

    Parameters
    ----------
    y : (p, 1) CasADi SX/MX, m (p = 3, or 2 in the plane).
    points : (m, p) CasADi matrix (symbolic parameters or constants), m.
    log_weights : (m, 1) ln W_j. A slot whose ln W is ≤ −1e30 is padding: its term is
        exp(−1e30 − s) = 0 exactly, so it contributes nothing to D or to any derivative.
    log_volume : scalar ln V of the (visible) cloud.
    eta : η > 0, m: a number fixed when the NLP is built, or a symbol read at run time.
    eta_squared : η² as the symbol that stands for it (then ``eta`` is not read), so that
        its value is η**2 as Python computes it for a number.
    """
    if eta_squared is None:
        _check_scale("eta", eta)
    sq = _sq_dist_casadi(y, points)
    return _distance_expression(sq, log_weights, log_volume, eta, _logsumexp_casadi,
                                eta_squared)


def euclidean_distance_symbolic(y, points, mask):
    """CasADi expression of ½·min_j ‖y − a_j‖² over the slots with ``mask`` = 1.

    Padding slots (mask 0) are lifted by 1e30 so they never attain the minimum.
    """
    sq = _sq_dist_casadi(y, points)
    return 0.5 * ca.mmin(sq + (1.0 - mask) * 1e30)


def check_cloud(cloud, dim: int | None = None) -> np.ndarray:
    """Return the cloud as a float (m, p) array or raise a ``ValueError`` naming ``cloud``.

    p is 3 (or 2 for a planar cloud); ``dim`` demands one of them (that of the query y).
    """
    arr = cloud.points if isinstance(cloud, CloudWeights) else np.asarray(cloud, dtype=float)
    shape = "(m, 3)" if dim == 3 else "(m, 2)" if dim == 2 else "(m, 3) or (m, 2)"
    if arr.ndim != 2 or arr.shape[1] not in ((dim,) if dim else (2, 3)):
        mate = " (the dimension of y)" if dim else ""
        raise ValueError(f"cloud must have shape {shape}{mate} with m >= 1, got {arr.shape}")
    if isinstance(cloud, CloudWeights):
        return arr
    if arr.shape[0] == 0:
        raise ValueError("cloud must hold at least one point (m >= 1), got an empty cloud")
    if not np.all(np.isfinite(arr)):
        raise ValueError("cloud must contain only finite coordinates")
    return arr


def _prepare(y, cloud, eta, sigma):
    _check_scale("eta", eta)
    ys, single = _check_queries(y)
    check_cloud(cloud, ys.shape[1])
    weights = cloud if isinstance(cloud, CloudWeights) else CloudWeights.from_cloud(cloud, sigma)
    return weights, ys, single


def _check_queries(y):
    arr = np.asarray(y, dtype=float)
    if arr.shape in ((3,), (2,)):
        arr, single = arr[None, :], True
    elif arr.ndim == 2 and arr.shape[1] in (2, 3):
        single = False
    else:
        raise ValueError(f"y must have shape (3,) or (n, 3) (or (2,), (n, 2) in the plane), "
                         f"got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("y must contain only finite coordinates")
    return arr, single


def _check_scale(name: str, value) -> None:
    if not (isinstance(value, (int, float, np.floating, np.integer)) and math.isfinite(value)
            and value > 0):
        raise ValueError(f"{name} must be a finite number > 0 (m), got {value!r}")


def _distance_expression(sq, log_weights, log_volume, eta, logsumexp, eta_squared=None):
    """Eq. (8) from squared distances: the single definition behind both backends
    (``eta_squared``: η², when given apart)."""
    eta_sq = eta**2 if eta_squared is None else eta_squared
    return -eta_sq * (logsumexp(log_weights - sq / (2.0 * eta_sq)) - log_volume)


def _chunks(ys: np.ndarray, points: np.ndarray):
    """Yield (slice, squared distances (k, m)) over blocks of query points.

    Differences are formed explicitly (not as ‖y‖² + ‖a‖² − 2y·a) so that D = ½‖y − a‖²
    holds to rounding even far from the origin.
    """
    step = max(1, _CHUNK_PAIRS // len(points))
    for start in range(0, len(ys), step):
        block = ys[start:start + step]
        diff = block[:, None, :] - points[None, :, :]
        yield slice(start, start + len(block)), np.einsum("kmi,kmi->km", diff, diff)


def _logsumexp_np(e: np.ndarray):
    """Shifted log-sum-exp along the last axis."""
    s = e.max(axis=-1, keepdims=True)
    return (s + np.log(np.sum(np.exp(e - s), axis=-1, keepdims=True)))[..., 0]


def _logsumexp_casadi(e):
    """Shifted log-sum-exp of a CasADi column; the shift cancels exactly in every derivative."""
    s = ca.mmax(e)
    return s + ca.log(ca.sum1(ca.exp(e - s)))


def _sq_dist_casadi(y, points):
    m, p = points.shape
    diff = ca.repmat(ca.reshape(y, 1, p), m, 1) - points
    return ca.sum2(diff * diff)
