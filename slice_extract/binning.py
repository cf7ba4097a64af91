"""Robust per-bin estimates of rho over the 90 MERL theta_h bins, fully vectorised.

Per bin and channel: the median m and the median absolute deviation (MAD), sigma = 1.4826 MAD (the
standard deviation for Gaussian noise). A sample is an outlier when any channel lies more than
k sigma from its bin's median (k = 3 by default: 0.3% false rejections for Gaussian noise, while
hot pixels, specks of dust and mis-registered edges sit far out). sigma is floored at
rel_floor x |m| so that noise-free data (MAD = 0) does not reject tiny rounding differences.
The estimate is the per-channel mean of the inliers ("trimmed mean"), or the median when asked.
"""

import numpy as np

from brdf.merl import N_THETA_H

MAD_TO_SIGMA = 1.4826


def group_median(groups, values, n_groups):
    """Median of `values` (N,) within each group, groups (N,) int in [0, n_groups). NaN if empty.

    One lexsort, no loop: within the sorted order each group is a contiguous run.
    """
    order = np.lexsort((values, groups))
    sorted_values = values[order]
    counts = np.bincount(groups, minlength=n_groups)
    starts = np.cumsum(counts) - counts
    out = np.full(n_groups, np.nan)
    filled = counts > 0
    lo = starts[filled] + (counts[filled] - 1) // 2
    hi = starts[filled] + counts[filled] // 2
    out[filled] = 0.5 * (sorted_values[lo] + sorted_values[hi])
    return out


def robust_bins(bin_index, rho, k=3.0, rel_floor=1e-3, estimator="trimmed_mean",
                n_bins=N_THETA_H):
    """Robust per-bin estimate of samples rho (N, 3) in bins bin_index (N,) int.

    Returns (estimate (n_bins, 3) NaN where empty, n (n_bins,) inlier counts,
    spread (n_bins, 3) robust sigma of the bin's samples (NaN where empty),
    inlier (N,) bool).
    """
    bin_index = np.asarray(bin_index, dtype=np.intp)
    rho = np.asarray(rho, dtype=np.float64)
    channels = rho.shape[1]
    median = np.stack([group_median(bin_index, rho[:, c], n_bins) for c in range(channels)], 1)
    deviation = np.abs(rho - median[bin_index])
    mad = np.stack([group_median(bin_index, deviation[:, c], n_bins) for c in range(channels)], 1)
    spread = MAD_TO_SIGMA * mad
    limit = k * np.maximum(spread, rel_floor * np.abs(median) + 1e-300)
    inlier = np.all(deviation <= limit[bin_index], axis=1)
    n = np.bincount(bin_index[inlier], minlength=n_bins)
    if estimator == "median":
        estimate = median
    else:
        sums = np.stack([np.bincount(bin_index[inlier], weights=rho[inlier, c], minlength=n_bins)
                         for c in range(channels)], 1)
        with np.errstate(invalid="ignore", divide="ignore"):
            estimate = sums / n[:, None]
    estimate = np.where(n[:, None] > 0, estimate, np.nan)
    spread = np.where(n[:, None] > 0, spread, np.nan)
    return estimate, n, spread, inlier
