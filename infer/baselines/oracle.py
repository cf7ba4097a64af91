"""Oracle (evaluation only): the best any linear data-driven method could do from this training set.

It sees the TRUE table (2D or 3D), maps it with the pca baseline's log-relative mapping and takes its
ridge projection onto the training PCA basis with all N−1 components:
    c_k = u_kᵀ (m_true − m̄) · s_k² / (s_k² + η).
In dual form (training-material weights) it needs only raw inner products of mapped tables, so the
3D case is computed from a streamed N×N Gram matrix: see `dual_weights`.
"""

import numpy as np

from flashbrdf.infer.baselines.pca import PCA, LogRelative3D, to_mapped
from flashbrdf.brdf.bins import valid_mask_2d
from flashbrdf.infer.blas import on_one_blas_thread


def dual_weights(raw_gram, cross, ridge):
    """Weights b (N,) with  m̄ + Σ_k c_k u_k = Σ_i b_i m_i  for the ridge projection of a table t.

    raw_gram: (N, N) m_i·m_j of the mapped training tables; cross: (N,) m_i·t; ridge: η ≥ 0.
    """
    n = len(cross)
    h = np.eye(n) - 1.0 / n
    gram = h @ raw_gram @ h
    g = h @ (cross - raw_gram.mean(axis=1))
    eigval, eigvec = np.linalg.eigh((gram + gram.T) / 2)
    keep = eigval > 1e-10 * max(eigval.max(), 1e-300)
    v = eigvec[:, keep]
    a = v @ ((v.T @ g) / (eigval[keep] + ridge))
    return a + (1.0 - a.sum()) / n


class Oracle(PCA):
    name = "oracle"
    evaluation_only = True
    n_components = None  # all N−1 components (PCA.fit reads it); not a hyperparameter here

    def __init__(self, ridge=1e-6):
        self.ridge = ridge

    @on_one_blas_thread
    def predict_truth(self, true_table_2d):
        """Ridge projection of the true 2D table (90, 90, 3) -> predicted (90, 90, 3), NaN invalid."""
        m = to_mapped(np.asarray(true_table_2d)[valid_mask_2d()], self.ref_, self.w_).ravel()
        known = np.isfinite(m)
        if known.all():
            proj = self.components_.T @ (m - self.mean_)
            c = proj * self.var_ / (self.var_ + self.ridge)
        else:  # bins the truth lacks: the same ridge fit on the others (U is not orthonormal there)
            u = self.components_[known]
            lhs = u.T @ u + np.diag(self.ridge / self.var_)
            c = np.linalg.solve(lhs + 1e-12 * np.trace(lhs) * np.eye(len(lhs)),
                                u.T @ (m[known] - self.mean_[known]))
        return self._table_from_mapped(self.mean_ + self.components_ @ c)

    def space_3d(self):
        return LogRelative3D(self.reference_2d())

    def predict(self, flash_slice, view="2d"):
        raise NotImplementedError("the oracle needs the true table: use predict_truth")
