"""Spatio-temporal filtering of the particle weights into p(x) (section 4 of the paper).

"At each sample position the probability for an independently moving object is
calculated (the sample weight). These probabilities are inserted in an otherwise
empty image and Gauss filtered [...] the resulting sequence is temporally
filtered [...] passed through a digital low pass filter."

Choices where the paper is silent:

* The spatial filter is a *normalised* convolution: the Gaussian-filtered weight
  image divided by the Gaussian-filtered particle count plus a pseudo-count
  ``EVIDENCE_PARTICLES``. The result is a local weighted mean of the weights, so
  it stays in [0, 1] whatever the particle density, a dense patch of low-weight
  (static) particles stays low, and a lone particle counts for less than many.
* The temporal low pass is a first-order IIR filter per pixel,
  ``p_t = alpha * p_spatial + (1 - alpha) * p_{t-1}``; before blending, the
  previous map is warped by the homography ``K R K^-1`` of the refined camera
  rotation (depth independent), so a pan of the PTU or a yaw of the car does not
  smear the map. The IIR memory bridges interruptions of a few frames (a wiper,
  a parked car occluding a pedestrian); the tracker bridges the rest.

All arrays are at 1/``scale`` of the image resolution (``ProbabilityMap``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.config import ProbabilityMapConfig
from appliance.messages import ParticleSet
from appliance.vision.geometry import PinholeCamera, euler_to_matrix

FloatMap = NDArray[np.float32]

# particles, pseudo-count of the normalised convolution: one lone particle of weight w gives
# p = w / (1 + EVIDENCE_PARTICLES)
EVIDENCE_PARTICLES = 1.0


def map_shape(camera: PinholeCamera, scale: int) -> tuple[int, int]:
    """(rows, cols) of the probability map for ``camera`` at 1/``scale``."""
    return (math.ceil(camera.height / scale), math.ceil(camera.width / scale))


def empty_map(camera: PinholeCamera, scale: int) -> FloatMap:
    """A map of zeros: no independent motion anywhere yet."""
    return np.zeros(map_shape(camera, scale), dtype=np.float32)


def gaussian_sigma_map_px(window_px: int, scale: int) -> float:
    """Std (map px) of the Gaussian of an odd window ``window_px`` (image px).

    OpenCV's rule for a window of size k: ``sigma = 0.3 ((k - 1) / 2 - 1) + 0.8``.
    """
    sigma_img = 0.3 * ((window_px - 1) * 0.5 - 1.0) + 0.8
    return max(sigma_img / scale, 0.3)


def _blur_peak_one(image: FloatMap, sigma: float) -> FloatMap:
    """Gaussian filter whose kernel has value 1 at its centre (not sum 1).

    A lone unit impulse stays 1 at its own pixel, so the filtered count image
    reads as "number of particles within about one sigma".
    """
    k = 2 * math.ceil(3.0 * sigma) + 1
    g = cv2.getGaussianKernel(k, sigma, cv2.CV_64F)
    peak = float(g[k // 2, 0]) ** 2
    out = cv2.GaussianBlur(image, (k, k), sigmaX=sigma, sigmaY=sigma,
                           borderType=cv2.BORDER_CONSTANT)
    return (out / peak).astype(np.float32)


def insert_particles(particles: ParticleSet, shape: tuple[int, int], scale: int
                     ) -> tuple[FloatMap, FloatMap]:
    """Sum of weights and number of valid particles per map cell, each of shape ``shape``."""
    rows, cols = shape
    weights = np.zeros(shape, dtype=np.float32)
    counts = np.zeros(shape, dtype=np.float32)
    pos = np.asarray(particles.positions, dtype=np.float64).reshape(-1, 2)
    if pos.shape[0] == 0:
        return weights, counts
    w = np.asarray(particles.weights, dtype=np.float64).reshape(-1)
    ok = np.asarray(particles.valid, dtype=bool).reshape(-1) & np.all(np.isfinite(pos), axis=1)
    ok &= np.isfinite(w)
    safe = np.where(np.isfinite(pos), pos, -1.0)
    col = np.floor(safe[:, 0] / scale).astype(np.int64)
    row = np.floor(safe[:, 1] / scale).astype(np.int64)
    ok &= (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    flat = row[ok] * cols + col[ok]
    n = rows * cols
    weights += np.bincount(flat, weights=np.clip(w[ok], 0.0, 1.0), minlength=n).reshape(shape)
    counts += np.bincount(flat, minlength=n).reshape(shape).astype(np.float32)
    return weights, counts


def spatial_probability(particles: ParticleSet, shape: tuple[int, int], scale: int,
                        cfg: ProbabilityMapConfig) -> FloatMap:
    """Gaussian-interpolated probability of independent motion of one frame, in [0, 1].

    ``(G * W) / (G * C + EVIDENCE_PARTICLES)`` with W the weight image, C the
    count image and G the Gaussian of ``gauss_window_px`` (peak normalised).
    """
    weights, counts = insert_particles(particles, shape, scale)
    if not np.any(counts):
        return np.zeros(shape, dtype=np.float32)
    sigma = gaussian_sigma_map_px(cfg.gauss_window_px, scale)
    gw = _blur_peak_one(weights, sigma)
    gc = _blur_peak_one(counts, sigma)
    denom = gc + np.float32(EVIDENCE_PARTICLES)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(denom > 1e-6, gw / np.maximum(denom, 1e-6), 0.0)
    return np.clip(p, 0.0, 1.0).astype(np.float32)


def warp_by_rotation(prev: FloatMap, rotation: NDArray[np.floating], camera: PinholeCamera,
                     scale: int) -> FloatMap:
    """The previous map moved by the camera rotation ``R`` (Euler, rad) to the current frame.

    A pixel x of the previous frame maps to ``K R K^-1 x`` in the current one
    (pure rotation, depth independent); map cells are scaled pixels.
    """
    R = euler_to_matrix(np.asarray(rotation, dtype=np.float64))
    S = np.diag([1.0 / scale, 1.0 / scale, 1.0])
    H = S @ camera.K @ R @ camera.K_inv @ np.linalg.inv(S)
    if not np.all(np.isfinite(H)):
        return prev
    rows, cols = prev.shape
    return np.asarray(cv2.warpPerspective(prev, H, (cols, rows), flags=cv2.INTER_LINEAR,
                                          borderMode=cv2.BORDER_CONSTANT, borderValue=0.0),
                      dtype=np.float32)


def spatio_temporal_filter(prev: FloatMap | None, particles: ParticleSet,
                           rotation: NDArray[np.floating] | None, camera: PinholeCamera,
                           cfg: ProbabilityMapConfig) -> FloatMap:
    """p(x) of this frame: spatial interpolation, then the temporal low pass.

    prev: last frame's filtered map (None on the first frame), shape
    ``map_shape(camera, cfg.scale)``; rotation: the refined inter-frame camera
    rotation (Euler, rad) or None to skip the compensation.
    """
    shape = map_shape(camera, cfg.scale)
    spatial = spatial_probability(particles, shape, cfg.scale, cfg)
    if prev is None or prev.shape != shape:
        return spatial
    if rotation is not None and np.all(np.isfinite(rotation)):
        prev = warp_by_rotation(prev, rotation, camera, cfg.scale)
    alpha = np.float32(cfg.temporal_alpha)
    out = alpha * spatial + (np.float32(1.0) - alpha) * prev
    return np.clip(out, 0.0, 1.0).astype(np.float32)
