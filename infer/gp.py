"""Gaussian-process pieces of the DS-GPLVM: the RBF + bias + noise kernel (Eq. 3), the negative log
likelihood of one view from its Gram matrix (Eq. 8) with analytic gradients, and the posterior.

Hyperparameters live in log space: log_theta = (ln θ1, ln θ2, ln θ3, ln θ4) with
k(x_i, x_j) = θ1 exp(-θ2/2 |x_i - x_j|²) + θ3 + δ_ij / θ4   (θ4 is the noise *precision*, as in the paper).
"""

import numpy as np
from scipy import linalg

N_THETA = 4
LN_2PI = np.log(2.0 * np.pi)


def robust_cholesky(matrix, max_tries=10):
    """Lower Cholesky factor of a symmetric (near) positive-definite matrix, adding jitter if needed.

    matrix: (N, N). Jitter starts at 1e-10 × mean|diag| and grows ×10 per failed try (near-duplicate
    training BRDFs make K rank deficient up to its noise term). Returns (L (N, N) lower, jitter float).
    Raises numpy.linalg.LinAlgError if even the largest jitter fails (e.g. NaN in the matrix).
    """
    matrix = np.asarray(matrix, dtype=float)
    if not np.all(np.isfinite(matrix)):
        raise np.linalg.LinAlgError("matrix has non-finite entries")
    scale = float(np.mean(np.abs(np.diag(matrix)))) or 1.0
    jitters = [0.0] + [scale * 1e-10 * 10.0 ** k for k in range(max_tries - 1)]
    for jitter in jitters:
        try:
            factor = linalg.cholesky(matrix + jitter * np.eye(len(matrix)), lower=True,
                                     check_finite=False)
            return factor, jitter
        except linalg.LinAlgError:
            pass
    raise np.linalg.LinAlgError(f"not positive definite even with jitter {jitters[-1]:g}")


def squared_distances(a, b=None):
    """Pairwise squared Euclidean distances, (M, q) × (N, q) -> (M, N), clipped at 0."""
    b = a if b is None else b
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d2, 0.0)


def kernel_matrix(latent, log_theta):
    """Training kernel K (N, N) of Eq. 3 and its RBF part (N, N) and squared distances (N, N)."""
    theta = np.exp(log_theta)
    d2 = squared_distances(latent)
    k_rbf = theta[0] * np.exp(-0.5 * theta[1] * d2)
    k = k_rbf + theta[2] + np.eye(len(latent)) / theta[3]
    return k, k_rbf, d2


def cross_kernel(latent_new, latent, log_theta):
    """Noise-free kernel between new latent points (M, q) and training points (N, q) -> (M, N)."""
    theta = np.exp(log_theta)
    return theta[0] * np.exp(-0.5 * theta[1] * squared_distances(latent_new, latent)) + theta[2]


def prior_variance(log_theta):
    """k(x*, x*) including the noise term: variance of a new noisy observation before conditioning."""
    theta = np.exp(log_theta)
    return theta[0] + theta[2] + 1.0 / theta[3]


def view_nll(latent, log_theta, gram, n_dims):
    """Negative log likelihood of one view, Eq. 8, and its analytic gradients.

    latent: (N, q) shared latent X. log_theta: (4,). gram: (N, N) = Y Yᵀ of the (centred) view, so the
    cost does not depend on the view's dimension D = n_dims (only the Gram does).
    Returns (nll float, d_latent (N, q), d_log_theta (4,)).
    """
    theta = np.exp(log_theta)
    n = len(latent)
    k, k_rbf, d2 = kernel_matrix(latent, log_theta)
    chol, _ = robust_cholesky(k)
    k_inv = linalg.cho_solve((chol, True), np.eye(n), check_finite=False)
    k_inv_gram = k_inv @ gram
    log_det = 2.0 * np.sum(np.log(np.diag(chol)))
    nll = 0.5 * n_dims * log_det + 0.5 * np.trace(k_inv_gram) + 0.5 * n * n_dims * LN_2PI
    # dL/dK = ½ (D K⁻¹ − K⁻¹ S K⁻¹), symmetric
    d_k = 0.5 * (n_dims * k_inv - k_inv_gram @ k_inv)
    d_k = 0.5 * (d_k + d_k.T)
    p = d_k * k_rbf
    d_latent = -2.0 * theta[1] * (p.sum(1)[:, None] * latent - p @ latent)
    d_log_theta = np.array([
        p.sum(),
        np.sum(p * (-0.5 * theta[1] * d2)),
        theta[2] * d_k.sum(),
        -np.trace(d_k) / theta[3],
    ])
    return nll, d_latent, d_log_theta


class GPPosterior:
    """Posterior of one view's GP given the latent X (N, q) and log_theta: weights and variances.

    For a new latent point x*, the mean of the centred view is wᵀ Y with w = K⁻¹ k* (N,), and the
    predictive variance (of a noisy observation, same for every output dimension) is
    k(x*, x*) − k*ᵀ K⁻¹ k*.  Working with w keeps D out of everything but the final combination.
    """

    def __init__(self, latent, log_theta):
        self.latent = np.asarray(latent, dtype=float)
        self.log_theta = np.asarray(log_theta, dtype=float)
        k, _, _ = kernel_matrix(self.latent, self.log_theta)
        self.chol, self.jitter = robust_cholesky(k)

    def weights(self, latent_new):
        """latent_new (M, q) -> (weights (M, N), variance (M,)) in units of the centred, scaled view."""
        k_star = cross_kernel(np.atleast_2d(latent_new), self.latent, self.log_theta)
        w = linalg.cho_solve((self.chol, True), k_star.T, check_finite=False).T
        var = prior_variance(self.log_theta) - np.sum(w * k_star, axis=1)
        return w, np.maximum(var, 1.0 / np.exp(self.log_theta[3]))


def loo_bin_variance(posterior, data):
    """Closed-form leave-one-out residual variance of a GP view, per output column, relative to the
    mean LOO predictive variance: (D,) ≥ 0. With K⁻¹ the inverse training kernel, the LOO residual
    of row i is (K⁻¹Y)_i / (K⁻¹)_ii and its predictive variance 1 / (K⁻¹)_ii (Rasmussen & Williams
    2006, Eq. 5.12). The ratio says which bins a GP of one isotropic variance under- or over-states."""
    k_inv = linalg.cho_solve((posterior.chol, True), np.eye(len(data)), check_finite=False)
    diag = np.diag(k_inv)
    resid = (k_inv @ np.nan_to_num(data)) / diag[:, None]
    return np.mean(resid ** 2, axis=0) / np.mean(1.0 / diag)
