"""Batched Levenberg-Marquardt for many small least-squares problems at once.

Why our own and not ``scipy.optimize.least_squares(method="lm")``: preemptive MSAC
estimates 32 five-parameter MAP problems per frame; MINPACK solves one problem
per call, and the Python round trips dominate (``python -m benchmarks vision``
prints both side by side). Here every hypothesis is one row of a batch, the
forward-difference Jacobian of all rows is one residual call, and each LM step
is one batched 5x5 solve.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import FloatArray

# residuals(theta) with theta (B, E, P) -> residual vectors (B, E, Q): E evaluation points
# per problem (the estimate and its finite-difference neighbours), B problems.
BatchedResiduals = Callable[[FloatArray], FloatArray]

JACOBIAN_STEP = 1e-7   # rad, forward-difference step (states are angles of order 0.01-1)
LAMBDA_START = 1e-3
LAMBDA_UP = 10.0
LAMBDA_DOWN = 0.1
RELATIVE_DECREASE = 1e-9   # an accepted step that lowers no cost by more than this: converged


def _evaluate(residuals: BatchedResiduals, theta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Residuals r (B, Q), Jacobian J (B, P, Q) and cost (B,) at theta (B, P)."""
    P = theta.shape[1]
    points = np.repeat(theta[:, None, :], P + 1, axis=1)
    points[:, 1:, :] += np.eye(P) * JACOBIAN_STEP
    r_all = residuals(points)                                   # (B, P + 1, Q)
    r = r_all[:, 0, :]
    J = (r_all[:, 1:, :] - r[:, None, :]) / JACOBIAN_STEP
    cost = np.sum(r * r, axis=1)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    return r, J, cost


def batched_lm(residuals: BatchedResiduals, theta0: NDArray[np.floating],
               iterations: int, tolerance: float = 1e-10) -> tuple[FloatArray, FloatArray]:
    """Minimise ``sum(r(theta)^2)`` for B independent problems by Levenberg-Marquardt.

    theta0: (B, P) start states. Returns the estimates (B, P) and their costs (B,).
    A step is kept only where it lowers the cost (then the damping falls tenfold,
    otherwise it rises tenfold); at most ``iterations`` steps, fewer once every
    problem's proposed step is shorter than ``tolerance`` (rad) in each component, or
    once a step lowers no problem's cost by more than ``RELATIVE_DECREASE`` of it.
    """
    theta = np.array(theta0, dtype=np.float64, copy=True)
    B, P = theta.shape
    lam = np.full(B, LAMBDA_START)
    r, J, cost = _evaluate(residuals, theta)
    eye = np.eye(P)
    for _ in range(iterations):
        A = np.einsum("bpq,brq->bpr", J, J)
        g = np.einsum("bpq,bq->bp", J, r)
        A = np.where(np.isfinite(A), A, 0.0)
        g = np.where(np.isfinite(g), g, 0.0)
        damped = A + lam[:, None, None] * (A * eye + 1e-12 * eye)
        delta = np.linalg.solve(damped, -g[:, :, None])[:, :, 0]
        r_new, J_new, cost_new = _evaluate(residuals, theta + delta)
        better = cost_new < cost
        settled = np.all(~better | (cost - cost_new <= RELATIVE_DECREASE * cost))
        theta = np.where(better[:, None], theta + delta, theta)
        r = np.where(better[:, None], r_new, r)
        J = np.where(better[:, None, None], J_new, J)
        cost = np.where(better, cost_new, cost)
        lam = np.clip(np.where(better, lam * LAMBDA_DOWN, lam * LAMBDA_UP), 1e-12, 1e12)
        if np.all(np.abs(delta) < tolerance) or (settled and np.any(better)):
            break
    return theta, cost
