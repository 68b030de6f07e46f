"""Section 3: MAP refinement of the camera motion by preemptive MSAC and Levenberg-Marquardt.

The MAP estimate minimises the negative log posterior of eqs. 9 and 10,

    L(theta) = 1/2 sum_k ((theta_k - theta_bar_k) / sigma_k)^2 + sum_i d_i^2 / (2 sigma_l^2),

which is eq. 18 with the factor 1/2 of eq. 9 kept on the prior term (eq. 18 as
printed drops it, which would double the prior's weight against eq. 14). As
least squares: residuals ``(theta - theta_bar) / sigma`` and ``d_i / sigma_l``.
``d_i`` is the epipolar distance of eqs. 11-13 in pixels. At a standstill the
translation has no direction; the state shrinks to the three Euler angles and
``d_i`` becomes the pure-rotation transfer error ``|x_cur - H x_prev|``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import RefinementConfig
from appliance.vision.epipolar import epipolar_distances_rays, rays, transfer_residuals_rays
from appliance.vision.geometry import FloatArray
from appliance.vision.lm import BatchedResiduals, batched_lm
from appliance.vision.msac import truncated_loss, weighted_minimal_samples

MIN_CORRESPONDENCES = 12      # fewer correspondences or inliers: the prior is kept, not confident
SAMPLE_SIZE = 5               # correspondences per minimal sample (fig. 6, step 1): five unknowns
HYPOTHESIS_ITERATIONS = 3     # Levenberg-Marquardt iterations of each minimal-sample hypothesis
FINAL_ITERATIONS = 8          # Levenberg-Marquardt iterations of the final MAP estimate at most
HYPOTHESIS_TOLERANCE = 1e-6   # rad: 1e-6 rad moves a pixel by < 0.001 px, enough to score
FINAL_TOLERANCE = 1e-7        # rad: 1e-7 rad moves a pixel by < 1e-4 px


@dataclass(frozen=True)
class MapProblem:
    """The prior of eq. 9 and the camera: theta_bar (P,), sigma (P,) rad, K (3, 3).

    P = 5 ``(phi, psi, r_x, r_y, r_z)`` when the camera translates, P = 3 ``(r_x, r_y,
    r_z)`` at a standstill (``translating`` False).
    """

    theta_bar: FloatArray
    sigma: FloatArray
    K: FloatArray
    sigma_l_px: float
    translating: bool


@dataclass(frozen=True)
class Refinement:
    """Result of :func:`refine_motion`.

    theta: (P,) MAP estimate; inliers: (M,) bool, correspondences within the MSAC
    threshold of it; confident: False when too few correspondences (or inliers)
    were left and theta is the prior mean.
    """

    theta: FloatArray
    inliers: NDArray[np.bool_]
    confident: bool


def _wrap(a: FloatArray) -> FloatArray:
    wrapped: FloatArray = (a + np.pi) % (2.0 * np.pi) - np.pi
    return wrapped


def correspondence_errors(problem: MapProblem, theta: NDArray[np.floating],
                          x_prev: NDArray[np.floating], x_cur: NDArray[np.floating]) -> FloatArray:
    """Error delta_i (px) of each correspondence under states theta (B, P) -> (B, M).

    Moving: the absolute epipolar distance (eq. 11); standstill: the transfer error.
    """
    theta = np.atleast_2d(theta)
    a, b = rays(x_prev, problem.K), rays(x_cur, problem.K)
    if problem.translating:
        return np.abs(epipolar_distances_rays(theta, a, b, problem.K))
    norms: FloatArray = np.linalg.norm(transfer_residuals_rays(theta, a, b, problem.K), axis=-1)
    return norms


def map_residuals(problem: MapProblem, x_prev: NDArray[np.floating],
                  x_cur: NDArray[np.floating]) -> BatchedResiduals:
    """Least-squares residuals of the MAP functional for :func:`batched_lm`.

    x_prev, x_cur: (M, 2) ideal pixels shared by all problems, or (B, M, 2), one set
    per problem (the minimal samples of MSAC).
    """
    per_problem = np.ndim(x_prev) == 3
    a0, b0 = rays(x_prev, problem.K), rays(x_cur, problem.K)
    repeated: dict[int, tuple[FloatArray, FloatArray]] = {}

    def residuals(theta: FloatArray) -> FloatArray:
        B, E, P = theta.shape
        flat = theta.reshape(B * E, P)
        a, b = a0, b0
        if per_problem:
            if E not in repeated:
                repeated[E] = (np.repeat(a0, E, axis=0), np.repeat(b0, E, axis=0))
            a, b = repeated[E]
        if problem.translating:
            data = epipolar_distances_rays(flat, a, b, problem.K)         # eq. 11
        else:
            data = transfer_residuals_rays(flat, a, b, problem.K).reshape(B * E, -1)
        prior = _wrap(flat - problem.theta_bar) / problem.sigma          # eq. 9
        out = np.concatenate([data / problem.sigma_l_px, prior], axis=1)  # eq. 18
        return out.reshape(B, E, -1)

    return residuals


def refine_motion(problem: MapProblem, x_prev: NDArray[np.floating], x_cur: NDArray[np.floating],
                  sample_weights: NDArray[np.floating], cfg: RefinementConfig,
                  rng: np.random.Generator) -> Refinement:
    """Preemptive MSAC (fig. 6) with MAP hypotheses, then the MAP estimate on the inliers.

    x_prev, x_cur: (M, 2) ideal pixels of static-pool correspondences;
    sample_weights: (M,) ``1 - p(x)`` at each correspondence (fig. 6, step 1).
    Hypotheses are the prior mean plus ``cfg.msac_hypotheses`` MAP estimates from
    minimal samples; the one with the least truncated loss wins and is re-estimated
    on its inliers. Fewer than :data:`MIN_CORRESPONDENCES` correspondences or
    inliers keep the prior (``confident`` False).
    """
    x_prev = np.asarray(x_prev, dtype=np.float64).reshape(-1, 2)
    x_cur = np.asarray(x_cur, dtype=np.float64).reshape(-1, 2)
    m = x_prev.shape[0]
    keep_prior = Refinement(problem.theta_bar.copy(), np.zeros(m, dtype=bool), False)
    if m < MIN_CORRESPONDENCES:
        return keep_prior

    # fig. 6 steps 1-2: minimal samples drawn with probability 1 - p(x), MAP estimate of each
    idx = weighted_minimal_samples(rng, sample_weights, cfg.msac_hypotheses, SAMPLE_SIZE)
    start = np.repeat(problem.theta_bar[None, :], cfg.msac_hypotheses, axis=0)
    hyp, _ = batched_lm(map_residuals(problem, x_prev[idx], x_cur[idx]), start,
                        HYPOTHESIS_ITERATIONS, tolerance=HYPOTHESIS_TOLERANCE)
    candidates = np.vstack([problem.theta_bar[None, :], hyp])
    # fig. 6 steps 3-4: errors of every correspondence, truncated loss, least loss wins
    delta = correspondence_errors(problem, candidates, x_prev, x_cur)
    loss = truncated_loss(delta, cfg.msac_threshold_px)
    best = int(np.argmin(loss))
    inliers = delta[best] < cfg.msac_threshold_px
    if int(inliers.sum()) < MIN_CORRESPONDENCES:
        return keep_prior
    final, _ = batched_lm(map_residuals(problem, x_prev[inliers], x_cur[inliers]),
                          candidates[best][None, :], FINAL_ITERATIONS, tolerance=FINAL_TOLERANCE)
    theta = final[0]
    inliers = correspondence_errors(problem, theta, x_prev, x_cur)[0] < cfg.msac_threshold_px
    return Refinement(theta, inliers, True)
