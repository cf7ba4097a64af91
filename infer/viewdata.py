"""Per-view training data for the DS-GPLVM: missing-data handling, centring, scaling and the Gram matrix.

A view is an (N, D) feature matrix (float array or memmap; D up to ~4.4 M for 3D). It is read in column
blocks so a 3D view never needs a float64 copy in memory unless the caller asks to keep it.
"""

from dataclasses import dataclass

import numpy as np

from flashbrdf.files.errors import InputError

COLUMN_BLOCK = 262_144  # columns per block: 60 rows × 256 k × 8 B = 126 MB peak per block


@dataclass
class ViewData:
    """One view after preparation.

    keep: (D,) bool, columns with at least one finite training value (others are predicted NaN).
    mean: (D,) column means over finite values (NaN where not kept), or None when not stored.
    scale: float, one scale per view: sqrt of the mean per-dimension variance, so the centred, scaled
        view has unit average variance (GP hyperparameters then have view-independent sizes).
    gram: (N, N) Ỹ Ỹᵀ of the centred, scaled view. n_dims: number of kept columns (D of Eq. 8).
    data: (N, n_dims) centred, scaled kept columns, or None when not stored.
    """
    keep: np.ndarray
    mean: np.ndarray
    scale: float
    gram: np.ndarray
    n_dims: int
    data: np.ndarray = None


def _column_stats(block):
    finite = np.isfinite(block)
    count = finite.sum(0)
    total = np.where(finite, block, 0.0).sum(0)
    mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return count > 0, mean


def prepare_view(features, store=True, block=COLUMN_BLOCK):
    """Prepare one (N, D) view. Missing training values (NaN) are imputed by their column mean, i.e.
    they sit at 0 after centring and add nothing to distances; all-missing columns are dropped.
    Returns ViewData; data and mean are kept only when store is True.
    """
    n, d = features.shape
    keep = np.zeros(d, dtype=bool)
    mean = np.full(d, np.nan) if store else None
    gram = np.zeros((n, n))
    kept_blocks = []
    for start in range(0, d, block):
        part = np.asarray(features[:, start:start + block], dtype=float)
        ok, col_mean = _column_stats(part)
        keep[start:start + part.shape[1]] = ok
        centred = part[:, ok] - col_mean[ok]
        centred[~np.isfinite(centred)] = 0.0
        gram += centred @ centred.T
        if store:
            mean[start:start + part.shape[1]] = col_mean
            kept_blocks.append(centred)
    n_dims = int(keep.sum())
    if n_dims == 0:
        raise ValueError("view has no finite value")
    mean_var = np.trace(gram) / (n * n_dims)
    scale = float(np.sqrt(mean_var)) if mean_var > 0 else 1.0
    data = np.concatenate(kept_blocks, axis=1) / scale if store else None
    return ViewData(keep=keep, mean=mean, scale=scale, gram=gram / scale ** 2, n_dims=n_dims,
                    data=data)


def pca_latent(grams, n_dims, q=None, variance=0.95):
    """Initial latent X0 (N, q) by PCA of the concatenated views, each view weighted 1/sqrt(D_v) so
    that every view contributes the same total variance (the raw concatenation would be all 3D).

    grams: list of (N, N) centred scaled Grams; n_dims: list of D_v. q None -> smallest q explaining
    `variance` of the variance (at least 1, at most N - 1). X0 is scaled so its first column has unit
    standard deviation (relative geometry kept). Returns (X0, q).
    """
    g = sum(gm / dv for gm, dv in zip(grams, n_dims))
    n = len(g)
    s, u = np.linalg.eigh(g)
    order = np.argsort(s)[::-1]
    s, u = np.maximum(s[order], 0.0), u[:, order]
    if q is None:
        frac = np.cumsum(s) / max(s.sum(), 1e-300)
        q = int(np.searchsorted(frac, variance) + 1)
    q = int(max(1, min(q, n - 1)))
    scores = u[:, :q] * np.sqrt(s[:q])
    std0 = scores[:, 0].std()
    return scores / (std0 if std0 > 0 else 1.0), q


def restore_rows(model, view, rows):
    """Give a loaded DSGPLVM the centred, scaled training rows of `view` back from the raw rows
    (N, D) they were made of, checked against the stored keep mask, scale and Gram matrix (they
    must describe the same data; a model file whose tables were swapped fails here)."""
    stored = model.view_data_[view]
    rebuilt = prepare_view(rows)
    if not np.array_equal(rebuilt.keep, stored.keep) or \
            not np.isclose(rebuilt.scale, stored.scale, rtol=1e-4):
        raise InputError("model", f"the stored tables do not match the trained DS-GPLVM ({view})")
    ratio = rebuilt.scale / stored.scale
    data = rebuilt.data * ratio
    # the Gram of `data` is the rebuilt one rescaled: no second (N x D) @ (D x N) product
    if not np.allclose(rebuilt.gram * ratio ** 2, stored.gram, rtol=1e-3,
                       atol=1e-3 * np.abs(stored.gram).max()):
        raise InputError("model", f"the stored tables do not match the trained DS-GPLVM's Gram "
                                  f"({view})")
    model.view_data_[view] = ViewData(keep=stored.keep, mean=rebuilt.mean, scale=stored.scale,
                                      gram=stored.gram, n_dims=stored.n_dims, data=data)

