"""Per-bin predictive uncertainty of a weighted combination of training tables, and its calibration.

The anchored DS-GPLVM (infer.adapter) predicts a table as Σ_i w_i x_i over the training tables'
features x_i (N, D), with w = (1 − λ) w_GP + λ w_fit (infer.slice_fit). Three things say how far that
can be off at a bin, all in feature units²:

- the GP's own predictive variance, one number per view, shaped over the bins by the view's
  leave-one-out residuals (infer.gp.loo_bin_variance);
- the spread of the combined tables at that bin, Σ_i a_i (x_i − x̄)² with a = |w| / Σ|w| and x̄ the
  prediction (mixture_spread): materials that reproduce the slice equally well but disagree at a
  bin leave that bin uncertain, however confident the GP is in its latent point;
- the disagreement of the two weight vectors, λ(1 − λ) ((w_GP − w_fit) · x)² (weights_disagreement):
  the variance of the two-point estimate {GP, slice fit} the blend averages.

Why all three: calibrated on held-out MERL (NBRDF proxy) materials and checked on RGL (NBRDF proxy),
κ for the GP term alone ranged from 1.5 to 3.3 over four validation splits, so a split's κ did not
transfer (central-90% coverage 78.3% on the RGL folds); with the sum it ranged from 0.07 to 0.10
(coverage 79–87% at each split's own κ). The remaining spread of κ is the sampling error of ~20
held-out materials, so κ is the 90th percentile of a material-level bootstrap (calibration_factor):
the intervals hold 90% of the bins with 90% confidence over the held-out sample, in the manner of a
90/90 tolerance interval, and a lucky split does not make every later interval overconfident.
"""

from statistics import NormalDist

import numpy as np

from flashbrdf.brdf import colour

BOOTSTRAP_RESAMPLES = 200
BOOTSTRAP_QUANTILE = 0.9      # with 90% intervals: a 90%/90% tolerance bound


def mixture_spread(weights, rows, rows_squared=None):
    """Σ_i a_i (x_i − x̄)² per column, a = |w| / Σ|w|, x̄ = Σ_i w_i x_i: (D,) ≥ 0. weights (N,)
    summing to 1 (negative entries allowed, as GP weights have them); rows (N, D) finite, float64
    or float32 (the products then run in float32); rows_squared: rows ** 2 if at hand (a model
    keeps it)."""
    w = np.asarray(weights, dtype=float)
    rows = np.asarray(rows)
    a = np.abs(w) / max(float(np.abs(w).sum()), 1e-300)
    sq = rows ** 2 if rows_squared is None else rows_squared
    # vector-matrix products in the rows' own dtype (a mixed-dtype product skips BLAS: 25× slower)
    mean, a_rows, a_sq = (np.asarray(v, rows.dtype) @ m for v, m in ((w, rows), (a, rows), (a, sq)))
    # Σ a (x − x̄)² = a·x² − 2 x̄ (a·x) + x̄² (Σ a = 1), without an (N, D) temporary
    mean, a_rows, a_sq = (v.astype(float) for v in (mean, a_rows, a_sq))
    return np.maximum(a_sq - 2.0 * mean * a_rows + mean ** 2, 0.0)


def weights_disagreement(gp_weights, fit_weights, rows, share):
    """share (1 − share) ((w_GP − w_fit) · x)² per column: (D,) ≥ 0, the variance of the two-point
    estimate whose mean (1 − share) w_GP · x + share w_fit · x the blend predicts."""
    rows = np.asarray(rows)
    diff = np.asarray(np.subtract(gp_weights, fit_weights), rows.dtype) @ rows
    return share * (1.0 - share) * diff.astype(float) ** 2


def standardised_residuals(method, rho, true):
    """|z| of one held-out material: the residual of each (θh, θd > 0, channel) bin in the
    method's feature space over its predicted standard deviation, (n,) for the bins with a
    finite truth and a positive variance. rho (90, 3) slice, true (90, 90, 3) table, 1/sr. The
    θd = 0 row is left out: anchoring makes it the observation."""
    pred, var = method.predict(rho, "2d")
    space = getattr(method, "feature_space", "rgb")
    resid = (colour.rho_to_features(np.nan_to_num(true), space=space)
             - colour.rho_to_features(np.nan_to_num(pred), space=space))
    ok = np.isfinite(true).all(-1)[..., None] & np.isfinite(var) & (var > 0)
    ok[:, 0] = False
    return np.abs(resid[ok]) / np.sqrt(var[ok])


def quantile_factor(z_per_material, coverage=0.9):
    """The squared ratio of the `coverage` quantile of the pooled |z| to the normal one: the factor
    on the variance that makes central `coverage` intervals hold that share of the bins."""
    z = np.concatenate(z_per_material) if len(z_per_material) else np.empty(0)
    if not z.size:
        return 1.0
    return float((np.quantile(z, coverage) / NormalDist().inv_cdf(0.5 + coverage / 2)) ** 2)


def calibration_factor(method, slices, tables_2d, coverage=0.9, seed=0):
    """κ for a fitted method's per-bin variance from held-out materials: slices (M, 90, 3), tables_2d
    (M, 90, 90, 3) in 1/sr, never trained on. Each bootstrap resample of the M materials (with
    replacement; BOOTSTRAP_RESAMPLES, seeded) gives the factor that makes its central `coverage`
    intervals hold that share of its bins (quantile_factor); κ is their BOOTSTRAP_QUANTILE
    quantile. κ scales exactly: a method whose variance is already c times larger gets κ / c."""
    z = [standardised_residuals(method, rho, true) for rho, true in zip(slices, tables_2d)]
    z = [v for v in z if v.size]
    if not z:
        return 1.0
    rng = np.random.default_rng(seed)
    factors = [quantile_factor([z[i] for i in rng.integers(0, len(z), len(z))], coverage)
               for _ in range(BOOTSTRAP_RESAMPLES)]
    return float(np.quantile(factors, BOOTSTRAP_QUANTILE))
