"""Time to contact from the growth of a track's image (the scale-change cue).

Independent of depth and of the road plane: an object at depth Z closing at
speed c grows in the image at the rate k = c / Z (1/s), so ``TTC = 1 / k`` is
the time until it reaches the camera's image plane (collision-course.md:
``TTC ~ dt * s / ds``).

The growth is measured from the correspondences of the track's cluster, not
from the extent of its box: the particles' flow was measured to a tenth of a
pixel, the box edges (min/max of diffusing particles) wobble by pixels. With
the refined rotation's flow removed, the translational flow of points on one
rigid object at one depth is ``f_i = f_bar + kappa (x_{i,t-1} - x_bar)`` (a
shift plus an isotropic expansion; roll only adds curl and drops out of the
fit), where ``1 + kappa`` is the frame-to-frame scale ratio s_t / s_{t-1}. The
weighted least-squares slope kappa and its variance are the measurement; a
scalar extended Kalman filter on k with the exact constant-velocity prediction
``k' = k / (1 - k dt)`` (i.e. TTC' = TTC - dt) smooths it over time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import PinholeCamera, euler_to_matrix, rotational_flow

# below this rms spread of the points (px) the expansion is not measurable
MIN_SPREAD_PX = 2.0
MIN_POINTS = 4


@dataclass(frozen=True)
class Expansion:
    """One frame's scale-change measurement: kappa (scale ratio - 1, per frame) and its variance."""

    kappa: float
    var: float
    n: int


def measure_expansion(positions: NDArray[np.floating], flows: NDArray[np.floating],
                      weights: NDArray[np.floating], rotation: NDArray[np.floating] | None,
                      camera: PinholeCamera, axes: tuple[int, ...] = (0, 1),
                      window_px: float = 0.0) -> Expansion | None:
    """Fit ``f_i - f_bar = kappa (x_prev_i - x_bar)`` to an object's correspondences.

    positions (N, 2): x_t px (distorted image pixels); flows (N, 2): x_t - x_{t-1};
    weights (N,) >= 0; rotation: refined inter-frame Euler angles (rad) whose flow
    is removed, or None. ``axes``: the image axes fitted (0 = u, 1 = v); an object cut
    by the left or right image border is fitted along v only, where the cut does not
    mix what enters the image with what stays. Up to two refits without outliers
    (3.5 robust sigma). None when fewer than 4 points or a spread below 2 px.

    The variance treats the flows as independent measurements, but flows whose LK
    windows (``window_px`` square, 0 = ignore) overlap share their errors: the number
    of independent ones is at most the number of windows that tile the points' box
    (:func:`independent_windows`). Forty particles on a pedestrian 10 x 32 px wide count
    as four; on a car 100 x 60 px they stay forty.
    """
    ax = list(axes)
    if not ax:
        return None
    cur = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    f = np.asarray(flows, dtype=np.float64).reshape(-1, 2)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    ok = np.all(np.isfinite(cur), axis=1) & np.all(np.isfinite(f), axis=1) & (w > 0)
    cur, f, w = cur[ok], f[ok], w[ok]
    if len(cur) < MIN_POINTS:
        return None
    cur_i = camera.undistort(cur)
    prev_i = camera.undistort(cur - f)
    trans = cur_i - prev_i
    if rotation is not None and np.all(np.isfinite(rotation)):
        trans = trans - rotational_flow(camera, prev_i, euler_to_matrix(np.asarray(rotation)))
    keep = np.ones(len(cur), dtype=bool)
    result: Expansion | None = None
    for _ in range(3):
        n = int(np.count_nonzero(keep))
        if n < MIN_POINTS:
            return result
        ww = w[keep] / np.sum(w[keep])
        dx = (prev_i[keep] - ww @ prev_i[keep])[:, ax]
        df = (trans[keep] - ww @ trans[keep])[:, ax]
        d = len(ax)
        sxx = float(np.sum(ww * np.sum(dx * dx, axis=1)))
        if sxx * 2 / d < MIN_SPREAD_PX ** 2:   # rms spread, per axis as for two
            return result
        kappa = float(np.sum(ww * np.sum(dx * df, axis=1)) / sxx)
        r2 = np.sum((df - kappa * dx) ** 2, axis=1)
        n_eff = 1.0 / float(np.sum(ww * ww))
        if window_px > 0.0:
            n_eff = min(n_eff, independent_windows(prev_i[keep], window_px))
        # residual variance per component; fitted: one shift per axis and kappa
        sigma2 = max(float(np.sum(ww * r2)) / d * d * n_eff / max(d * n_eff - d - 1, 1.0),
                     0.05 ** 2)
        result = Expansion(kappa=kappa, var=sigma2 / (sxx * n_eff), n=n)
        # robust scale of the residuals (median norm of a 2-D Gaussian is 1.177 sigma, of a
        # 1-D one 0.674 sigma)
        robust = max(float(np.median(np.sqrt(r2))) / (1.177 if d == 2 else 0.674), 0.05)
        bad = np.sqrt(r2) > 3.5 * robust
        if not np.any(bad):
            break
        keep[np.flatnonzero(keep)[bad]] = False
    return result


def independent_windows(points: NDArray[np.floating], window_px: float) -> float:
    """How many ``window_px`` squares tile the box of ``points`` (N, 2) px, at least one
    window along each axis."""
    extent = np.ptp(np.asarray(points, dtype=np.float64).reshape(-1, 2), axis=0)
    return float(np.prod(np.maximum(extent, window_px))) / window_px ** 2


@dataclass(frozen=True)
class ScaleState:
    """Expansion rate k (1/s) = 1 / TTC to the image plane, its variance, and how many
    measurements it has absorbed."""

    k: float
    var: float
    n: int


def scale_predict(s: ScaleState, dt: float, process_std: float) -> ScaleState:
    """Constant closing velocity: TTC' = TTC - dt, i.e. k' = k / (1 - k dt)."""
    if dt <= 0.0:
        return s
    denom = 1.0 - s.k * dt
    if denom < 0.2:
        # the predicted contact is within this step: keep k rather than blow it up
        return ScaleState(k=s.k, var=s.var + process_std ** 2 * dt, n=s.n)
    F = 1.0 / (denom * denom)
    return ScaleState(k=s.k / denom, var=F * s.var * F + process_std ** 2 * dt, n=s.n)


def scale_update(s: ScaleState | None, m: Expansion, dt: float, init_var: float = 1.0
                 ) -> ScaleState:
    """Absorb one measurement kappa over the frame interval ``dt`` s (k = ln(1 + kappa) / dt)."""
    if dt <= 0.0 or m.kappa <= -0.9:
        return s if s is not None else ScaleState(k=0.0, var=init_var, n=0)
    k_meas = math.log1p(m.kappa) / dt
    r = m.var / ((1.0 + m.kappa) ** 2 * dt * dt)
    if s is None:
        return ScaleState(k=k_meas, var=r, n=1)
    gain = s.var / (s.var + r)
    return ScaleState(k=s.k + gain * (k_meas - s.k), var=(1.0 - gain) * s.var, n=s.n + 1)


def scale_ttc(s: ScaleState | None, min_measurements: int) -> tuple[float, float] | None:
    """(TTC, std) in s to the image plane, or None when the object is not closing
    significantly (k < 2 sigma) or too few measurements were absorbed."""
    if s is None or s.n < min_measurements or s.var <= 0.0:
        return None
    sd = math.sqrt(s.var)
    if s.k <= 2.0 * sd or s.k <= 0.0:
        return None
    return (1.0 / s.k, sd / (s.k * s.k))
