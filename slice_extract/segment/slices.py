"""The k-slice model: each material is its ln-rho slice over theta_h, and a sample belongs to the
slice that explains it best (residuals), once a flash-coloured highlight term is taken off.
"""

import numpy as np

from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.slice_extract.segment.features import (
    binned_median,
    fill_bins,
    log_samples,
    theta_h_bins,
)

# weight of a sample's brightness offset from a slice (the mean over channels of ln rho - ln
# slice) against its colour offset (what is left per channel) in residuals: texture, glitter,
# bumps and printed albedo move a material's brightness pixel to pixel, far less its colour
BRIGHTNESS_WEIGHT = 0.25


# a slice whose channels spread by less than this share of their mean is grey: an added white
# (flash-coloured) highlight term cannot be told from its brightness there, so residuals does
# not take one off. 0.1: the ~10% at which two ln-rho slices count as one material (alike).
GREY_SPREAD = 0.1


# the white term takes at most this share of a sample's weakest channel: all of it would leave
# that channel at the log floor, where ln rho measures the floor, not the pixel (planar cards:
# labels in their all-view cluster 96.2% with 1.0, 96.8% with 0.9; docs/results.md, one-off: cards_labels)
WHITE_CAP = 0.9


def material_slices(log_rho, bins, labels, k):
    """Per-material ln-rho slices (k, n_bins, 3), empty bins filled along theta_h."""
    out = np.zeros((k, N_THETA_H, 3))
    for j in range(k):
        mine = labels == j
        out[j] = fill_bins(binned_median(log_rho[mine], bins[mine], min_count=3)
                            if mine.any() else np.full((N_THETA_H, 3), np.nan))
    return out


def slice_white_terms(slice_log, offset):
    """Per theta_h bin of one ln-rho slice (n_bins, 3): its linear value's channel mean (n_bins,),
    the channels' deviations from it (n_bins, 3), and whether the slice is coloured (n_bins,)
    bool: channels spread by at least GREY_SPREAD of their mean. A grey slice's own colour is
    the flash's: an added white term there is just brightness, which the residual weighs."""
    linear = np.maximum(np.exp(slice_log) - offset, 0)
    mean = linear.mean(axis=1)
    deviation = linear - mean[:, None]
    spread = np.sqrt((deviation ** 2).mean(axis=1))
    return mean, deviation, spread >= GREY_SPREAD * mean


def added_white(rho, mean, deviation, coloured):
    """(N,) the flash-coloured (white) term s >= 0 to take off each sample before it is compared
    with a slice: least squares rho_c = a slice_c + s over the 3 channels, kept where the slice is
    coloured and the body a >= 1 (a highlight adds to the material, it does not replace part of
    it), and at most WHITE_CAP of the sample's weakest channel. rho: 3 arrays (N,) (linear, per
    channel); mean (N,), deviation: 3 arrays (N,), coloured (N,) bool: slice_white_terms taken at
    each sample's bin. Zero elsewhere."""
    dtype = rho[0].dtype
    norm = deviation[0] * deviation[0] + deviation[1] * deviation[1] + deviation[2] * deviation[2]
    covariance = deviation[0] * rho[0] + deviation[1] * rho[1] + deviation[2] * rho[2]
    with np.errstate(divide="ignore", invalid="ignore"):  # a grey bin (norm 0) is not kept
        body = covariance / norm
        white = (rho[0] + rho[1] + rho[2]) / dtype.type(3) - body * mean
    weakest = np.minimum(np.minimum(rho[0], rho[1]), rho[2])
    keep = coloured & (body >= 1) & (white > 0)
    return np.where(keep, np.minimum(white, dtype.type(WHITE_CAP) * weakest), dtype.type(0))


def residuals(log_rho, bins, slices, floor=None):
    """(N, k) how badly slice_k explains each sample: with d = ln rho - ln slice_k(theta_h)
    (N, 3) and its brightness offset m = mean over channels of d, the mean over channels of
    |d - m| (colour) plus BRIGHTNESS_WEIGHT |m|, capped at 1 (an outlier pixel counts as a bad
    fit, not as an unbounded one). With floor (log_rho's: log_rho = ln(rho + floor/3)), rho
    is first relieved of the white term added_white finds for slice_k (dichromatic model: a
    flash highlight adds the flash's colour, white after white balance): the final assignment's
    rule (assign_all). Without, the plain rule that finds the materials and their slices."""
    if floor is not None:
        offset = floor / 3
        rho = np.maximum(np.exp(log_rho) - offset, 0)
        columns = [rho[:, c] for c in range(3)]
    out = []
    for s in slices:
        d = log_rho - s[bins]
        if floor is not None:
            mean, deviation, coloured = slice_white_terms(s, offset)
            white = added_white(columns, mean[bins], [deviation[bins, c] for c in range(3)],
                                 coloured[bins])
            lifted = white > 0
            d[lifted] = (np.log(rho[lifted] - white[lifted, None] + offset)
                         - s[bins[lifted]])
        m = d.mean(axis=1, keepdims=True)
        out.append(np.minimum(np.abs(d - m).mean(axis=1) + BRIGHTNESS_WEIGHT * np.abs(m[:, 0]),
                              1.0))
    return np.stack(out, 1)


def refine_labels(log_rho, bins, labels, k, options):
    """k slices: each sample to the material whose slice explains it best, a few rounds.
    Returns (labels 0..k'-1, k'); a material left with < min_fraction of the samples goes."""
    n = len(labels)
    for _ in range(options.refine_iterations):
        residual = residuals(log_rho, bins, material_slices(log_rho, bins, labels, k))
        new = residual.argmin(axis=1)
        keep = np.bincount(new, minlength=k) >= options.min_fraction * n
        if not keep.all():  # a material the slices no longer support: give its pixels away
            residual[:, ~keep] = np.inf
            new = np.unique(residual.argmin(axis=1), return_inverse=True)[1]
            k = int(keep.sum())
        changed = n if not keep.all() else np.count_nonzero(new != labels)
        labels = new
        if k == 1 or changed < 1e-3 * n:
            break
    return labels, k


def assign_all(rho, theta_h, pick, labels, k):
    """Labels (N,) of every sample: the material (of the k found on samples `pick`, labelled
    `labels`) whose slice explains it best (residuals' criterion with the white term, first
    material on a tie). Why the white term here and not while the materials and slices are
    found: there each material's slice must come from pixels of its own colour, and allowing
    the term let highlight pixels of one material into another's slice (planar cards: 95.2% of
    pixels in their all-view cluster against 96.8%, benchmarks/docs/results.md, one-off: cards_labels).

    Why column by column in float32: this is the one pass over all (12 million) pixels, and
    numpy's reductions over a length-3 axis and (N, 3) gathers cost more than the arithmetic."""
    log_rho, _, floor = log_samples(rho[pick])
    slices = material_slices(log_rho, theta_h_bins(theta_h[pick]), labels, k)
    white_terms = [[np.ascontiguousarray(t, np.float32) for t in (mean, *deviation.T, coloured)]
                   for mean, deviation, coloured in (slice_white_terms(s, floor / 3)
                                                     for s in slices)]
    slices = slices.astype(np.float32)
    columns = [[np.ascontiguousarray(slices[j, :, c]) for c in range(3)] for j in range(k)]
    offset = np.float32(floor / 3)
    out = np.empty(len(rho), np.int64)
    for start in range(0, len(rho), 1 << 20):  # in chunks: bounded memory at 12 megapixels
        part = slice(start, start + (1 << 20))
        bins = theta_h_bins(theta_h[part])
        linear = [np.maximum(rho[part, c], 0).astype(np.float32) for c in range(3)]
        logs = [np.log(linear[c] + offset) for c in range(3)]
        best, best_residual = np.zeros(len(bins), np.int64), None
        for j in range(k):
            terms = [t.take(bins) for t in white_terms[j]]
            white = added_white(linear, terms[0], terms[1:4], terms[4] > 0)
            lifted = np.flatnonzero(white)  # a minority of pixels: only they need new logs
            d = []
            for c in range(3):
                dc = logs[c] - columns[j][c].take(bins)
                dc[lifted] = (np.log(np.maximum(linear[c][lifted] - white[lifted], 0) + offset)
                              - columns[j][c].take(bins[lifted]))
                d.append(dc)
            m = (d[0] + d[1] + d[2]) / np.float32(3)
            residual = np.abs(d[0] - m)
            residual += np.abs(d[1] - m)
            residual += np.abs(d[2] - m)
            residual /= np.float32(3)
            residual += np.float32(BRIGHTNESS_WEIGHT) * np.abs(m)
            np.minimum(residual, np.float32(1), out=residual)
            if best_residual is None:
                best_residual = residual
                continue
            better = residual < best_residual
            best[better] = j
            np.minimum(best_residual, residual, out=best_residual)
        out[part] = best
    return out
