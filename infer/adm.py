"""Objectives of the DS-GPLVM's ADM learning (Algorithm 1): Eq. 13 (Step 1, with gradients) and Eq. 12.

Parameters of Step 1 are packed in one vector: X (N, q) row-major, then ln θ (4,) per view.
"""

import numpy as np

from .gp import N_THETA, view_nll
from .prior import prior_energy


def pack(latent, log_thetas):
    """X (N, q) and a list of V (4,) ln θ -> flat vector."""
    return np.concatenate([latent.ravel()] + [np.asarray(t, float) for t in log_thetas])


def unpack(params, n, q, n_views):
    """Inverse of pack -> (X (N, q), ln θ (V, 4))."""
    latent = params[:n * q].reshape(n, q)
    return latent, params[n * q:].reshape(n_views, N_THETA)


def likelihood_prior(latent, log_thetas, grams, n_dims, laplacian, beta, view_weights):
    """L_s(X) of Eq. 7 (with optional per-view weights on Eq. 8) and gradients.

    Returns (value, d_latent (N, q), d_log_thetas (V, 4)).
    """
    value, d_latent = prior_energy(latent, laplacian, beta)
    d_thetas = np.zeros((len(grams), N_THETA))
    for v, (gram, dims, weight) in enumerate(zip(grams, n_dims, view_weights)):
        nll, d_x, d_t = view_nll(latent, log_thetas[v], gram, dims)
        value += weight * nll
        d_latent = d_latent + weight * d_x
        d_thetas[v] = weight * d_t
    return value, d_latent, d_thetas


def step1_objective(params, n, q, grams, n_dims, laplacian, beta, view_weights, targets, mu):
    """Eq. 13: L_s(X) + μ/2 Σ_v |X − K_bc A^(v) + Λ^(v)/μ|²_F, and its gradient (flat).

    targets: list of V (N, q) arrays K_bc^(v) A^(v) − Λ^(v)/μ (fixed during Step 1).
    """
    latent, log_thetas = unpack(params, n, q, len(grams))
    value, d_latent, d_thetas = likelihood_prior(latent, log_thetas, grams, n_dims, laplacian,
                                                 beta, view_weights)
    for target in targets:
        resid = latent - target
        value += 0.5 * mu * float(np.sum(resid ** 2))
        d_latent = d_latent + mu * resid
    return value, pack(d_latent, d_thetas)


def augmented_lagrangian(ls_value, latent, bc_kernels, weights, multipliers, lambdas, mu):
    """Eq. 12: L_s + Σ_v [λ/2 tr(AᵀK_bc A) + <Λ, X − K_bc A> + μ/2 |X − K_bc A|²]. Returns
    (value, max |X − K_bc A| over views)."""
    value, worst = ls_value, 0.0
    for k_bc, a, lag, lam in zip(bc_kernels, weights, multipliers, lambdas):
        ka = k_bc @ a
        resid = latent - ka
        value += 0.5 * lam * float(np.sum(a * ka)) + float(np.sum(lag * resid))
        value += 0.5 * mu * float(np.sum(resid ** 2))
        worst = max(worst, float(np.max(np.abs(resid))))
    return value, worst
