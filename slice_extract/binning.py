"""Robust per-bin estimates of rho over the 90 MERL theta_h bins, fully vectorised.

Per bin and channel: the median m and the median absolute deviation (MAD), sigma = 1.4826 MAD (the
standard deviation for Gaussian noise). A sample is an outlier when any channel lies more than
k sigma from its bin's median (k = 3 by default: 0.3% false rejections for Gaussian noise, while
hot pixels, specks of dust and mis-registered edges sit far out). sigma is floored at
rel_floor x |m| so that noise-free data (MAD = 0) does not reject tiny rounding differences.
The estimate is the per-channel mean of the inliers ("trimmed mean"), or the median when asked.

Clipped (too bright) pixels are right-censored samples: their rho is a lower bound (+inf when
unknown). Where another photo measured the bin, a censored sample whose bound lies at or below
the bin's Kaplan-Meier median (the median of right-censored data) in every channel says only
"above a value the median already clears", so it is set aside: across an exposure series given
as separate photos, the long photo's clipped highlight, which the short photo measured (not
within one photo: dominated_censored says why). The others count as +inf: the median of a bin
is still exact while fewer than half of its samples are censored, so such bins use the median,
and bins that are half or more censored are left empty (a trimmed mean of the unclipped rest
would be biased low).

Bin-centre correction: the slice is defined at bin centres, but a bin's samples can sit off
centre (a bin half outside the observed range at grazing angles, or uneven pixel density across
a bin). The trimmed mean is moved along the local slope (a count-weighted line through the
estimates of the bins within two of it), from the samples' mean theta_h to the bin centre.
"""

import numpy as np

from flashbrdf.brdf.merl import N_THETA_H, theta_h_centres

MAD_TO_SIGMA = 1.4826


def _bin_statistics(rho, theta_h, censored, counts, k, rel_floor):
    """Per-bin robust statistics of samples sorted by bin (contiguous runs of `counts`).

    rho: (C, N) channel-major, so every per-bin slice is C contiguous rows.
    One pass per non-empty bin, each fully vectorised (a partition-based median is O(n)): the loop
    runs over the 90 bins, never over pixels. Returns median, sigma, mean of the inliers
    (n_bins, C), mean theta_h of the inliers (n_bins,), inlier counts (n_bins,), inlier mask (N,).
    """
    channels, n_bins = rho.shape[0], len(counts)
    median, sigma, mean = (np.full((n_bins, channels), np.nan) for _ in range(3))
    theta_mean = np.full(n_bins, np.nan)
    n = np.zeros(n_bins, dtype=np.int64)
    inlier = np.zeros(rho.shape[1], dtype=bool)
    ends = np.cumsum(counts)
    # inf (clipped) samples make inf − inf; float32 samples near 3.4e38 overflow a median's sum
    with np.errstate(invalid="ignore", over="ignore"):
        for i in np.flatnonzero(counts):
            lo, hi = ends[i] - counts[i], ends[i]
            segment = rho[:, lo:hi]
            median[i] = np.median(segment, axis=1)
            deviation = np.abs(segment - median[i][:, None])
            sigma[i] = MAD_TO_SIGMA * np.median(deviation, axis=1)
            limit = k * np.maximum(sigma[i], rel_floor * np.abs(median[i]) + 1e-30)
            keep = np.all(deviation <= limit[:, None].astype(rho.dtype), axis=0)
            keep &= ~censored[lo:hi]
            inlier[lo:hi] = keep
            n[i] = np.count_nonzero(keep)
            if n[i]:
                mean[i] = np.compress(keep, segment, axis=1).mean(axis=1, dtype=np.float64)
                if theta_h is not None:
                    theta_mean[i] = theta_h[lo:hi][keep].mean()
    return median, sigma, mean, theta_mean, n, inlier


def _centre_correction(estimate, theta_mean, centres, n, usable, reach=2):
    """Move each usable bin's estimate (n_bins, 3) to its centre along the local slope.

    The slope is a least-squares line through the (mean theta_h, estimate) points of the bins
    within `reach` of it (itself included), weighted by their sample counts, so that a sparse,
    noisy neighbour barely tilts it. Needs at least two such bins.
    """
    n_bins = len(centres)
    ok = usable & np.all(np.isfinite(estimate), 1) & (n > 0)
    neighbours = np.arange(n_bins)[:, None] + np.arange(-reach, reach + 1)  # (n_bins, 2r+1)
    inside = (neighbours >= 0) & (neighbours < n_bins)
    neighbours = np.clip(neighbours, 0, n_bins - 1)
    w = np.where(inside & ok[neighbours], n[neighbours], 0).astype(np.float64)
    t = np.where(w > 0, theta_mean[neighbours], 0.0)
    m = np.where((w > 0)[..., None], estimate[neighbours], 0.0)  # (n_bins, 2r+1, 3)
    total = w.sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        t_bar = (w * t).sum(1) / total
        m_bar = (w[..., None] * m).sum(1) / total[:, None]
        dt = np.where(w > 0, t - t_bar[:, None], 0.0)
        slope = ((w * dt)[..., None] * (m - m_bar[:, None])).sum(1) / (w * dt ** 2).sum(1)[:, None]
    has_slope = ok & (np.count_nonzero(w, axis=1) >= 2) & np.all(np.isfinite(slope), 1)
    out = estimate.copy()
    out[has_slope] += slope[has_slope] * (centres[has_slope] - theta_mean[has_slope])[:, None]
    return out


def _km_median(values, censored):
    """The Kaplan-Meier median of right-censored samples values (n,) (a censored one: the true
    value is at or above it), +inf when over half the mass lies past the last measured value.
    At a tie a measured value comes first (a bound equal to it says nothing more)."""
    order = np.lexsort((censored, values))
    at_risk = len(values) - np.arange(len(values))
    survival = np.cumprod(np.where(censored[order], 1.0, 1.0 - 1.0 / at_risk))
    past = np.flatnonzero(survival <= 0.5)
    return values[order[past[0]]] if len(past) else np.inf


def dominated_censored(bin_index, rho, censored, photo, n_bins=N_THETA_H):
    """(N,) bool: the censored samples whose lower bound rho (N, C) is at or below their bin's
    Kaplan-Meier median in every channel, in bins where another photo (photo (N,) int) measured.
    They add nothing the median does not already honour. Only across photos: a
    pixel counts as clipped when any channel clips, so its other channels are values, not
    bounds, and within one photo setting such pixels aside by noise in those channels biases
    the bin (+3-6% where one channel of a coloured highlight clips).
    A loop over the bins that hold a candidate, each vectorised: the measured samples' median is
    a lower bound of the Kaplan-Meier median (censoring only moves mass up), so a bound under it
    needs no sort."""
    out = np.zeros(len(censored), dtype=bool)
    with np.errstate(invalid="ignore"):
        candidate = censored & np.all(np.isfinite(rho), axis=1)
    if candidate.any():
        photo = np.asarray(photo, dtype=np.int64)
        width = int(photo.max()) + 1
        measured = ~censored
        in_bin = np.bincount(bin_index[measured], minlength=n_bins)
        in_bin_photo = np.bincount(bin_index[measured] * width + photo[measured],
                                   minlength=n_bins * width)
        others = in_bin[bin_index] - in_bin_photo[bin_index * width + photo]
        candidate &= others > 0
    bins = np.unique(bin_index[candidate])
    if len(bins) == 0:
        return out
    idx = np.flatnonzero(np.isin(bin_index, bins))
    idx = idx[np.argsort(bin_index[idx], kind="stable")]
    for run in np.split(idx, np.cumsum(np.bincount(bin_index[idx], minlength=n_bins))[bins[:-1]]):
        values, cens, mine = np.asarray(rho[run], dtype=np.float64), censored[run], candidate[run]
        if cens.all():
            continue
        below = np.all(values <= np.median(values[~cens], axis=0), axis=1) & mine
        rest = mine & ~below
        if rest.any():
            median = np.array([_km_median(values[:, c], cens) for c in range(values.shape[1])])
            if np.all(np.isfinite(median)):  # else over half the bin lies past its measurements
                below |= rest & np.all(values <= median, axis=1)
        out[run] = below
    return out


def robust_bins(bin_index, rho, censored=None, theta_h=None, k=3.0, rel_floor=1e-3,
                estimator="trimmed_mean", n_bins=N_THETA_H, photo=None):
    """Robust per-bin estimate of samples rho (N, 3) in bins bin_index (N,) int.

    censored (N,) bool: right-censored samples (clipped pixels), counted as above every measured
    sample of their bin whatever their rho, except that with photo (N,) int (the photo of each
    sample) a finite rho is a lower bound, and one at or below its bin's Kaplan-Meier median
    where another photo measured is set aside (not an inlier; dominated_censored);
    theta_h (N,) radians: the samples' angles, for the bin-centre correction (None = no
    correction; the MERL theta_h bin centres are used).
    Returns (estimate (n_bins, 3) NaN where empty, n (n_bins,) inlier counts, spread (n_bins, 3)
    robust sigma of the bin's samples (NaN where empty), inlier (N,) bool).
    """
    bin_index = np.asarray(bin_index, dtype=np.intp)
    if photo is not None and censored is not None and np.any(censored):
        rho, censored = np.asarray(rho), np.asarray(censored, dtype=bool)
        aside = dominated_censored(bin_index, rho, censored, photo, n_bins)
        if aside.any():
            kept = ~aside
            estimate, n, spread, inlier = _robust_bins(
                bin_index[kept], rho[kept], censored[kept],
                None if theta_h is None else np.asarray(theta_h)[kept], k, rel_floor, estimator,
                n_bins)
            inlier_by_input = np.zeros(len(kept), dtype=bool)
            inlier_by_input[kept] = inlier
            return estimate, n, spread, inlier_by_input
    return _robust_bins(bin_index, rho, censored, theta_h, k, rel_floor, estimator, n_bins)


def _robust_bins(bin_index, rho, censored, theta_h, k, rel_floor, estimator, n_bins):
    """robust_bins once the dominated censored samples are set aside: the rest count as +inf."""
    order = np.argsort(bin_index.astype(np.int16), kind="stable")  # radix sort: O(n)
    # channel-major float32 copy in bin order (np.take: several times faster than fancy
    # indexing); float32 keeps 7 digits, and means accumulate in float64
    with np.errstate(over="ignore"):   # past float32's ±3.4e38 a sample reads ±inf
        rho = np.take(np.asarray(rho, dtype=np.float32).T, order, axis=1)
    censored = (np.zeros(len(order), dtype=bool) if censored is None
                else np.take(np.asarray(censored, dtype=bool), order))
    rho[:, censored] = np.inf
    if theta_h is not None:
        theta_h = np.take(np.asarray(theta_h, dtype=np.float64), order)
    total = np.bincount(bin_index, minlength=n_bins)
    sorted_bins = np.repeat(np.arange(n_bins), total)
    n_censored = np.bincount(sorted_bins[censored], minlength=n_bins)
    median, spread, estimate, theta_mean, n, inlier = _bin_statistics(
        rho, theta_h, censored, total, k, rel_floor)
    if estimator == "median":
        estimate = median
    else:
        if theta_h is not None:
            estimate = _centre_correction(estimate, theta_mean, theta_h_centres()[:n_bins], n,
                                          n_censored == 0)
        estimate = np.where(n_censored[:, None] > 0, median, estimate)
    empty = (n == 0) | (2 * n_censored >= total)
    n = np.where(empty, 0, n)
    estimate = np.where(empty[:, None], np.nan, estimate)
    spread = np.where(empty[:, None] | ~np.isfinite(spread), np.nan, spread)
    inlier_by_input = np.empty(len(order), dtype=bool)
    inlier_by_input[order] = inlier & ~empty[sorted_bins]
    return estimate, n, spread, inlier_by_input
