"""Property tests (hypothesis) of the GP path: the jittered Cholesky, Eq. 8's likelihood and its
gradients, the posterior, and a whole DS-GPLVM fit, on Grams and kernels made near-singular by
near-duplicate training rows (gaps from 1e-3 down to 0, the float64 round-off of a copied table)
and on latent scales from 1e-6 to 1e3. Whatever the rows, every number is finite and the
posterior variance lies between the noise and the prior variance. RuntimeWarnings are errors
(pyproject.toml), so an overflow on the way fails too.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flashbrdf.infer.dsgplvm import DSGPLVM, LOG_THETA_BOUNDS
from flashbrdf.infer.gp import GPPosterior, kernel_matrix, prior_variance, robust_cholesky, view_nll

UNIT_ROUNDOFF = np.finfo(float).eps / 2


def near_duplicates(rng, rows, copies, gap):
    """rows (N, D) with rows 1..copies replaced by row 0 plus noise of size `gap` (0: exact)."""
    rows = rows.copy()
    for i in range(1, copies + 1):
        rows[i] = rows[0] + gap * rng.normal(size=rows.shape[1])
    return rows


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.integers(2, 12), st.integers(1, 12), st.integers(0, 11),
       st.sampled_from([0.0, 1e-16, 1e-12, 1e-8]), st.integers(-290, 290))
def test_robust_cholesky_factors_rank_deficient_grams_at_any_scale(seed, n, d, copies, gap,
                                                                   exponent):
    """A Gram Y Yᵀ of d < n rows or of near-duplicate rows is singular to working precision, at
    any scale 1e-290..1e290: the factor exists, with a jitter relative to the diagonal (an
    absolute one would swamp a Gram of 1e-290 or be lost on one of 1e290)."""
    rng = np.random.default_rng(seed)
    rows = near_duplicates(rng, rng.normal(size=(n, d)), min(copies, n - 1), gap)
    gram = (rows * 10.0 ** (exponent / 2)) @ (rows * 10.0 ** (exponent / 2)).T
    chol, jitter = robust_cholesky(gram)
    a = gram + jitter * np.eye(n)
    # Cholesky's backward error (Higham 2002, Thm 10.3): |L Lᵀ − A| ≤ γ_{n+1} |L||Lᵀ|, and
    # (|L||Lᵀ|)_ij ≤ sqrt(a_ii a_jj) ≤ max diag(A) (Cauchy-Schwarz on the rows of L)
    gamma = (n + 1) * UNIT_ROUNDOFF / (1 - (n + 1) * UNIT_ROUNDOFF)
    assert np.isfinite(chol).all() and np.all(np.diag(chol) > 0)
    assert np.abs(chol @ chol.T - a).max() <= gamma * np.diag(a).max()
    assert 0 <= jitter <= 1e-2 * np.mean(np.diag(gram))  # the largest jitter tried


@st.composite
def near_singular_problem(draw):
    """(latent (N, q), log_theta (4,) inside LOG_THETA_BOUNDS, view rows (N, D))."""
    n, q, d = draw(st.integers(3, 10)), draw(st.integers(1, 4)), draw(st.integers(1, 30))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    copies = draw(st.integers(0, n - 1))
    gap = draw(st.sampled_from([0.0, 1e-16, 1e-12, 1e-8, 1e-3]))
    latent = rng.normal(size=(n, q)) * 10.0 ** draw(st.integers(-6, 3))
    rows = rng.normal(size=(n, d)) * 10.0 ** draw(st.integers(-3, 3))
    log_theta = np.array([draw(st.floats(lo, hi)) for lo, hi in LOG_THETA_BOUNDS])
    return (near_duplicates(rng, latent, copies, gap), log_theta,
            near_duplicates(rng, rows, copies, gap))


@settings(max_examples=150, deadline=None)
@given(near_singular_problem())
def test_gp_is_finite_and_bounded_on_near_singular_kernels(problem):
    latent, log_theta, rows = problem
    n = len(latent)
    k, _, _ = kernel_matrix(latent, log_theta)
    chol, jitter = robust_cholesky(k)
    # backward error as in the test above
    a = k + jitter * np.eye(n)
    gamma = (n + 1) * UNIT_ROUNDOFF / (1 - (n + 1) * UNIT_ROUNDOFF)
    assert np.abs(chol @ chol.T - a).max() <= gamma * np.diag(a).max()
    assert 0 <= jitter <= 1e-2 * np.mean(np.diag(k))  # the largest jitter tried

    nll, d_latent, d_log_theta = view_nll(latent, log_theta, rows @ rows.T, rows.shape[1])
    assert np.isfinite(nll) and np.isfinite(d_latent).all() and np.isfinite(d_log_theta).all()

    # new points: on a training point, beside it, and far from all of them
    new = np.vstack([latent[:1], latent[:1] + 1e-3, latent.mean(0) + 1e3])
    weights, variance = GPPosterior(latent, log_theta).weights(new)
    assert np.isfinite(weights).all()
    # conditioning never adds variance: the prior's, up to rounding of a sum of n + 2 terms
    # (weights clamps it below at the noise 1/θ4)
    assert (variance <= prior_variance(log_theta) * (1 + 4 * (n + 2) * UNIT_ROUNDOFF)).all()


@settings(max_examples=6, deadline=None)
@given(st.integers(0, 2 ** 32 - 1), st.sampled_from([0.0, 1e-15, 1e-9, 1e-4]),
       st.integers(1, 3), st.sampled_from([1e-6, 1.0, 1e6]))
def test_dsgplvm_fits_and_predicts_finite_from_near_duplicate_rows(seed, gap, copies, scale):
    """A whole fit (3 ADM cycles: LOO back-mappings, Step 1's L-BFGS on Eq. 13, the posterior)
    on 7 training rows of which `copies` repeat row 0 within `gap`, at a feature scale `scale`."""
    rng = np.random.default_rng(seed)
    views = {"1d": scale * near_duplicates(rng, rng.normal(size=(7, 6)), copies, gap),
             "2d": scale * near_duplicates(rng, rng.normal(size=(7, 15)), copies, gap)}
    model = DSGPLVM(max_cycles=3).fit(views)
    probe = np.vstack([views["1d"][0], views["1d"][-1], 10 * scale * rng.normal(size=6)])
    mean, variance = model.predict(probe, "2d")
    assert np.isfinite(mean).all() and np.isfinite(variance).all() and (variance > 0).all()
    weights, _ = model.predict_weights(probe, "2d")
    # the view mean is folded in: each row of weights sums to 1 (rounding of 7 terms)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-9)
    assert np.isfinite(model.novelty(probe)).all()


def test_a_matrix_no_jitter_mends_names_the_largest_jitter_tried():
    """[[1, 0], [0, -1]] stays indefinite under every jitter tried (1e-10 to 1e-2 of its mean
    |diagonal|, 1): the error names 0.01, the last one tried, not a tenfold one never tried."""
    with pytest.raises(np.linalg.LinAlgError, match=r"jitter 0\.01$"):
        robust_cholesky(np.diag([1.0, -1.0]))
