"""Nöll et al. 2014 ([28] of the paper), "basis decomposition plus correction functions", as the paper
describes its use from a flash slice.

1. Basis decomposition: non-negative weights w (N,) of the training BRDFs fitted to the observed slice
   bins in a robust log metric: minimise Σ_bins,ch soft-L1( ln(1 + ρ_obs/ε) − ln(1 + Σ_i w_i ρ_i/ε) ),
   ε = 1e-3 1/sr, started from the relative-error NNLS solution.
2. Correction function along θh: c(θh, ch) = (ρ_obs + δ) / (Σ_i w_i ρ_i,slice + δ) on observed bins
   (δ = 1e-9 1/sr guards black fits), interpolated in log over empty bins; it is carried unchanged
   over all θd, φd:  ρ(θh, θd, φd) = c(θh) · Σ_i w_i ρ_i(θh, θd, φd).
   The prediction therefore passes through the observed samples at θd bin 0.
Departures from the original: Nöll et al. fit sparse samples scattered over the whole 3D domain and
fit correction functions along several axes at several resolutions, with outlier rejection; from a
flash slice only the θh axis is observed, so there is one correction function, along θh, and the
robust (soft-L1) loss stands in for their outlier handling.
"""

import numpy as np
from scipy.optimize import least_squares, nnls

from flashbrdf.brdf.bins import valid_bins_3d
from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.infer.blas import one_blas_thread
from flashbrdf.infer.estimator import InferenceMethod, LinearSpace

EPS = 1e-3     # 1/sr, log metric offset
DELTA = 1e-9   # 1/sr, keeps the correction ratio finite for black fits


class _Corrected(LinearSpace):
    """Identity space; the inverse applies the θh correction c (90, 3)."""

    def __init__(self, correction):
        self.correction = correction

    def inverse(self, mapped, sel=slice(None)):
        return np.maximum(mapped, 0.0) * self.correction[valid_bins_3d()[0][sel]]


class Noll(InferenceMethod):
    name = "noll"

    def fit(self, training):
        self.training_ = training
        slices = np.asarray(training.slices, float)                       # (N, 90, 3)
        # a slice value the stored 2D tables (float32) hold as 0 is 0 here too: a table of
        # ~1e-300 1/sr needs a weight past 1e300 to fit any slice, which overflowed the fit
        with np.errstate(over="ignore"):  # past float32's range is inf, not 0: kept
            self.slices_ = np.where(slices.astype(np.float32) == 0, 0.0, slices)
        return self

    def weights(self, rho):
        """Robust non-negative basis weights (N,) for a checked slice (90, 3)."""
        ok = np.isfinite(rho).all(axis=1)
        basis = self.slices_[:, ok, :].reshape(len(self.slices_), -1).T   # (n_obs*3, N)
        basis = np.nan_to_num(basis)
        target = rho[ok].ravel()
        rel = 1.0 / (target + EPS)
        w0, _ = nnls(basis * rel[:, None], target * rel, maxiter=50 * basis.shape[1])
        y = np.log1p(target / EPS)

        def residual(w):
            return np.log1p(np.maximum(basis @ w, 0.0) / EPS) - y

        if not np.any(target > 0):
            return np.zeros(len(w0))
        # one BLAS thread (infer.blas): the weights must not depend on the core count
        with one_blas_thread():
            fit = least_squares(residual, w0, bounds=(0.0, np.inf), loss="soft_l1",
                                f_scale=0.1, max_nfev=200, x_scale="jac")
        return fit.x

    def correction(self, rho, weights):
        """c(θh, ch) (90, 3): observed / fitted at observed bins, log-interpolated over empty ones."""
        fitted = np.einsum("i,ijc->jc", weights, np.nan_to_num(self.slices_))
        ok = np.isfinite(rho).all(axis=1)
        log_c = np.log((rho + DELTA) / (fitted + DELTA))
        idx = np.arange(N_THETA_H)
        for c in range(3):
            log_c[:, c] = np.interp(idx, idx[ok], log_c[ok, c])
        return np.exp(log_c)

    def combination(self, rho):
        w = self.weights(rho)
        return w, _Corrected(self.correction(rho, w))

    def _predict_2d(self, rho):
        w, space = self.combination(rho)
        # a training table with a hole (NaN) leaves the mixture there to the others, their
        # weights scaled up to the same total: in a plain sum, even a weight of 1e-10 times NaN
        # voids the bin for every prediction
        tables = self.training_.tables_2d
        present = np.isfinite(tables)
        share = np.einsum("i,ijkc->jkc", w, present)
        mixed = np.einsum("i,ijkc->jkc", w, np.where(present, tables, 0.0))
        holes = ~present.all(axis=0)  # (bins every table holds keep the plain sum's bits)
        if w.sum() != 0 and holes.any():  # all-zero weights (a black slice) mix to 0
            with np.errstate(invalid="ignore", divide="ignore"):
                mixed[holes] *= w.sum() / share[holes]
        return np.maximum(mixed, 0.0) * space.correction[:, None, :], None
