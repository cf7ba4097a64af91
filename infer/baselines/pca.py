"""Linear PCA inference of Nielsen, Jensen & Ramamoorthi 2015 ("On optimal, minimal BRDF sampling for
reflectance acquisition", TOG 34(6)); the paper's "simpler linear methods".

Mapping (their log-relative mapping, per bin and channel):
    m(ρ) = ln((ρ·w + ε) / (ρ_ref·w + ε)),   ε = 1e-3 1/sr,
w = cos θi cos θo the cosine weight of the bin (its φd-mean for a 2D bin), ρ_ref the per-bin median
of the training set. PCA of the mapped, centred training 2D tables (dual form through the N×N Gram
matrix) gives components U (D, k) with variances s²; from the observed slice bins (θd bin 0) the
coefficients are the ridge solution
    c = argmin ‖U_obs c − (m_obs − m̄_obs)‖² + η Σ_k c_k² / s_k²
(a ridge scaled by the component variances, i.e. MAP under the PCA Gaussian; η = 0 is plain least
squares). k and η are hyperparameters picked on validation data.
3D: the same fit expressed as weights of the training materials (U = Ycᵀ V / s) is applied to their 3D
tables in the same mapping, with the 2D median copied across φd as ρ_ref and w = cos θi cos θo per
3D bin. This is a departure: Nielsen et al. build the basis from 3D data directly.
"""

import functools

import numpy as np

from flashbrdf.brdf.bins import cos_in_out_valid, mean_over_phi_d, valid_bins_3d, valid_mask_2d
from flashbrdf.brdf.merl import N_THETA_D, N_THETA_H
from flashbrdf.infer.blas import on_one_blas_thread
from flashbrdf.infer.estimator import InferenceMethod, LinearSpace

EPS = 1e-3


@functools.lru_cache(maxsize=1)
def cosine_weights():
    """(w on valid 3D bins (n_valid,), w per 2D bin (90, 90) as the φd-mean, NaN where invalid)."""
    cos_i, cos_o = cos_in_out_valid()
    w3 = np.clip(cos_i, 0, None) * np.clip(cos_o, 0, None)
    return w3, mean_over_phi_d(w3)


def to_mapped(rho, ref, w):
    return np.log((np.maximum(rho, 0.0) * w + EPS) / (ref * w + EPS))


def from_mapped(m, ref, w):
    return np.maximum(((ref * w + EPS) * np.exp(np.clip(m, -700, 700)) - EPS) / w, 0.0)


class LogRelative3D(LinearSpace):
    """The log-relative mapping on valid 3D bins with a 2D reference ρ_ref (90, 90, 3)."""

    def __init__(self, ref_2d):
        self.ref_2d = ref_2d

    def _ref_w(self, sel):
        ih, jd, _ = valid_bins_3d()
        return self.ref_2d[ih[sel], jd[sel]], cosine_weights()[0][sel, None]

    def forward(self, rho, sel=slice(None)):
        return to_mapped(rho, *self._ref_w(sel))

    def inverse(self, mapped, sel=slice(None)):
        return from_mapped(mapped, *self._ref_w(sel))


class PCA(InferenceMethod):
    name = "pca"

    def __init__(self, n_components=None, ridge=1e-2):
        self.n_components = n_components   # None: all N-1
        self.ridge = ridge

    @on_one_blas_thread
    def fit(self, training):
        self.training_ = training
        valid = valid_mask_2d()
        _, w2 = cosine_weights()
        self.w_ = w2[valid][:, None]                                     # (n2, 1)
        tables = np.asarray(training.tables_2d)[:, valid, :]             # (N, n2, 3)
        stored = getattr(training, "fitted_pca", None)
        if stored is not None and stored["params"] == self.get_params():
            return self._restore(stored, tables)
        self.ref_ = np.median(tables, axis=0)                            # (n2, 3)
        mapped = to_mapped(tables, self.ref_, self.w_).reshape(len(tables), -1)
        self.mean_ = mapped.mean(axis=0)
        centred = mapped - self.mean_
        eigval, eigvec = np.linalg.eigh(centred @ centred.T)
        order = np.argsort(eigval)[::-1]
        k = len(tables) - 1 if self.n_components is None else min(self.n_components, len(tables) - 1)
        keep = order[:max(k, 1)]
        keep = keep[eigval[keep] > 1e-12 * max(eigval.max(), 1e-300)]
        self.var_ = eigval[keep]                                         # s² (k,)
        self.dual_ = eigvec[:, keep] / np.sqrt(self.var_)                # V / s  (N, k)
        # U = centred.T @ dual_ (D, k) is formed only where asked (components_): a prediction
        # needs its slice rows and a weighted sum of the training rows, not the D x N x k product
        self.centred_ = centred
        self._components = None
        # observed bins: θd bin 0 of every θh (all valid), 3 channels each
        flat = np.flatnonzero(valid.ravel())
        self.slice_rows_ = np.searchsorted(flat, np.arange(N_THETA_H) * N_THETA_D)     # index of (θh, 0) in n2
        return self

    def state(self):
        """What fit computed beyond the training tables, for MODEL.npz: {"params", "ref", "mean",
        "var", "dual"} (arrays; params the hyperparameters)."""
        return {"params": self.get_params(), "ref": self.ref_, "mean": self.mean_,
                "var": self.var_, "dual": self.dual_}

    def _restore(self, stored, tables):
        """fit's state from state() of a fit on the same tables: only the mapped rows are made."""
        self.ref_, self.mean_ = stored["ref"], stored["mean"]
        self.var_, self.dual_ = stored["var"], stored["dual"]
        mapped = to_mapped(tables, self.ref_, self.w_).reshape(len(tables), -1)
        self.centred_ = mapped - self.mean_
        self._components = None
        flat = np.flatnonzero(valid_mask_2d().ravel())
        self.slice_rows_ = np.searchsorted(flat, np.arange(N_THETA_H) * N_THETA_D)
        return self

    @property
    def components_(self):
        """U (D, k): the orthonormal principal directions of the mapped training tables."""
        if self._components is None:
            self._components = self.centred_.T @ self.dual_
        return self._components

    def coefficients(self, rho):
        ok = np.isfinite(rho).all(axis=1)
        rows = self.slice_rows_[ok]
        m_obs = to_mapped(rho[ok], self.ref_[rows], self.w_[rows]).ravel()
        cols = (rows[:, None] * 3 + np.arange(3)).ravel()
        u_obs = (self._components[cols] if self._components is not None
                 else self.centred_[:, cols].T @ self.dual_)
        r = m_obs - self.mean_[cols]
        lhs = u_obs.T @ u_obs + self.ridge * np.diag(1.0 / self.var_)
        return np.linalg.solve(lhs + 1e-12 * np.trace(lhs) * np.eye(len(lhs)), u_obs.T @ r)

    def _table_from_mapped(self, mapped):
        valid = valid_mask_2d()
        table = np.full((N_THETA_H, N_THETA_D, 3), np.nan)
        table[valid] = from_mapped(mapped.reshape(-1, 3), self.ref_, self.w_)
        return table

    @on_one_blas_thread
    def _predict_2d(self, rho):
        c = self.coefficients(rho)
        return self._table_from_mapped(self.mean_ + self.centred_.T @ (self.dual_ @ c)), None

    def training_weights(self, c):
        """Weights b (N,) with  mean + U c = Σ_i b_i m_i  (m_i the mapped training tables)."""
        a = self.dual_ @ c
        return a + (1.0 - a.sum()) / len(a)

    def reference_2d(self):
        ref = np.full((N_THETA_H, N_THETA_D, 3), np.nan)
        ref[valid_mask_2d()] = self.ref_
        return ref

    @on_one_blas_thread
    def combination(self, rho):
        return self.training_weights(self.coefficients(rho)), LogRelative3D(self.reference_2d())
