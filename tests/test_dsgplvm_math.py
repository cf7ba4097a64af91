"""DS-GPLVM maths: Eq. 13 gradients, closed-form LOO (Eq. 19), Cholesky jitter, prior (Eq. 4-6)."""

import numpy as np
import pytest

from flashbrdf.infer import adm
from flashbrdf.infer.backmap import (backmap_kernel, krr_weights, loo_error, masked_squared_distances)
from flashbrdf.infer.gp import robust_cholesky
from flashbrdf.infer.prior import distances_from_gram, joint_laplacian, prior_energy


def _problem(seed=0, n=9, q=3, dims=(12, 40)):
    rng = np.random.default_rng(seed)
    ys = [rng.normal(size=(n, d)) for d in dims]
    grams = [y @ y.T for y in ys]
    latent = rng.normal(size=(n, q))
    log_thetas = [np.log([1.3, 0.7, 0.2, 15.0]), np.log([0.8, 1.6, 0.05, 40.0])]
    labels = np.array([0, 1] * (n // 2) + [0] * (n % 2))
    laplacian = joint_laplacian(grams, labels, 1e-3)
    targets = [rng.normal(size=(n, q)) for _ in dims]
    args = (n, q, grams, list(dims), laplacian, 50.0, [1.0, 0.3], targets, 2.5)
    return adm.pack(latent, log_thetas), args


def test_step1_gradient_matches_finite_differences():
    # Central differences with h = 1e-5 have truncation error ~h² |f'''| ≈ 1e-9 relative and rounding
    # error ~eps |f| / h ≈ 1e-10 |f|; the analytic gradient must agree to 1e-5 relative (a sign or
    # factor-2 slip in any term of Eq. 8, 6 or 13 gives errors of order 1).
    params, args = _problem()
    _, grad = adm.step1_objective(params, *args)
    h = 1e-5
    numeric = np.empty_like(params)
    for i in range(len(params)):
        step = np.zeros_like(params)
        step[i] = h
        numeric[i] = (adm.step1_objective(params + step, *args)[0]
                      - adm.step1_objective(params - step, *args)[0]) / (2 * h)
    n, q = args[0], args[1]
    for part, sl in (("X", slice(0, n * q)), ("log theta", slice(n * q, None))):
        rel = np.linalg.norm(grad[sl] - numeric[sl]) / np.linalg.norm(numeric[sl])
        assert rel < 1e-5, f"gradient wrt {part}: relative error {rel:.2e}"


def test_loo_closed_form_equals_brute_force():
    # Eq. 19 must equal refitting Eq. 16 on N-1 samples and predicting the left-out x_i (Eq. 18).
    rng = np.random.default_rng(3)
    n, q, mu, gamma, lam = 11, 2, 3.0, 0.4, 0.05
    y = rng.normal(size=(n, 5))
    d2 = distances_from_gram(y @ y.T)
    latent, lag = rng.normal(size=(n, q)), rng.normal(size=(n, q))
    closed = loo_error(d2, latent, lag, mu, gamma, lam)
    brute = 0.0
    for i in range(n):
        rest = np.delete(np.arange(n), i)
        a_rest = krr_weights(d2[np.ix_(rest, rest)], latent[rest], lag[rest], mu, gamma, lam)
        x_hat = backmap_kernel(d2[i, rest], gamma) @ a_rest
        brute += 0.5 * np.sum((latent[i] - x_hat) ** 2)
    assert abs(closed - brute) <= 1e-8 * max(1.0, brute)


def test_robust_cholesky_adds_jitter_for_rank_deficient_matrix():
    # two identical rows make Y Yᵀ singular: plain Cholesky fails, the jittered one must not, and the
    # jitter stays tiny relative to the diagonal (1e-10 .. 1e-1 × mean diag by construction)
    y = np.array([[1.0, 2.0], [1.0, 2.0], [0.5, -1.0]])
    gram = y @ y.T
    chol, jitter = robust_cholesky(gram)
    assert 0 < jitter < 1e-3 * np.mean(np.diag(gram))
    assert np.allclose(chol @ chol.T, gram + jitter * np.eye(3), atol=1e-12)


def test_prior_pulls_same_class_together():
    # Eq. 4-6: with β > 0 the energy of two same-class points is lower when they are closer, while a
    # different-class pair only feels the ξ I ridge.
    y = np.array([[0.0, 0.0], [0.1, 0.0], [3.0, 0.0]])
    lap = joint_laplacian([y @ y.T], np.array([0, 0, 1]), 1e-3)
    far = np.array([[0.0], [2.0], [5.0]])
    near = np.array([[0.0], [0.1], [5.0]])
    assert prior_energy(near, lap, 50.0)[0] < prior_energy(far, lap, 50.0)[0]
    # class 1 has a single member: only ξ acts on it
    assert lap[2, 2] == pytest.approx(1e-3) and np.allclose(lap[2, :2], 0)


def test_masked_distances_skip_nan_and_rescale():
    train = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 3.0, 4.0]])
    probe = np.array([[1.0, np.nan, 3.0, 4.0]])
    d2 = masked_squared_distances(probe, train)
    # observed dims 0, 2, 3: sums 26 and 0, rescaled by 4/3
    assert np.allclose(d2, [[26 * 4 / 3, 0.0]])
    with pytest.raises(ValueError):
        masked_squared_distances(np.full((1, 4), np.nan), train)
