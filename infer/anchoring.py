"""Anchoring: a θh correction that takes a predicted table's θd = 0 row to the observed flash slice,
carried over every θd (and φd), like Nöll et al.'s correction functions. ρ in 1/sr; ln c (90, 3).
"""

import numpy as np

from flashbrdf.brdf.bins import valid_bins_3d
from flashbrdf.brdf.colour import FEATURE_OFFSET
from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.infer.estimator import LinearSpace


ANCHOR_SMOOTHING_BINS = 2.0  # see anchor_to_slice; chosen in benchmarks, not on test data
# how ln c continues past the observed θh range, in θh bins: it fades to 0 (the model's own
# prediction) as exp(-d²/2s²) at d bins from the nearest observed bin; inf holds it constant.
# Held: on held-out MERL/RGL (NBRDF proxy) slices cut to a 0-19°, 10-25° or 20-40° window, every
# fade (8, 3, 0 bins) predicted the θd = 0 row past the window worse (docs/results.md, one-off: sparse_slices)
ANCHOR_FADE_BINS = np.inf


def anchor_log_correction(first_row, flash_slice, smoothing_bins=None):
    """ln c (90, 3): the per-θh, per-channel correction that takes a predicted θd = 0 row
    `first_row` (90, 3) to the observed `flash_slice` (90, 3, NaN where empty), both in 1/sr.

    c = (ρ_obs + e) / (ρ_pred + e), e = brdf.colour.FEATURE_OFFSET, i.e. a shift in the ln(1 + ρ/e)
    feature space. Empty slice bins take ln c interpolated along θh (held constant beyond the
    observed range, or faded: ANCHOR_FADE_BINS). ln c is then smoothed along θh with a Gaussian
    of `smoothing_bins` bins (None: ANCHOR_SMOOTHING_BINS): a bump of the prediction's θd = 0
    row that its other rows lack is the blend's own artefact, and cancelling it bin by bin
    would stamp a dark line across every θd.
    0 makes the θd = 0 row pass exactly through the observation. None when no bin is observed.
    """
    e = FEATURE_OFFSET
    if smoothing_bins is None:
        smoothing_bins = ANCHOR_SMOOTHING_BINS
    log_c = (np.log(np.asarray(flash_slice, dtype=float) + e)
             - np.log(np.maximum(np.asarray(first_row, dtype=float), 0.0) + e))
    known = np.isfinite(log_c).all(axis=1)
    if not known.any():
        return None
    bins = np.arange(N_THETA_H)
    log_c = np.stack([np.interp(bins, bins[known], log_c[known, c]) for c in range(3)], axis=1)
    if np.isfinite(ANCHOR_FADE_BINS):
        seen = bins[known]
        beyond = np.maximum(seen[0] - bins, 0) + np.maximum(bins - seen[-1], 0)
        log_c *= np.exp(-0.5 * (beyond / max(ANCHOR_FADE_BINS, 1e-9)) ** 2)[:, None]
    if smoothing_bins > 0:
        log_c = gaussian_smooth_rows(log_c, smoothing_bins)
    return log_c


def gaussian_smooth_rows(values, sigma, truncate=4.0):
    """values (n, c) smoothed along axis 0 by a Gaussian of `sigma` rows, edges repeated: what
    scipy.ndimage.gaussian_filter1d(values, sigma, axis=0, mode="nearest") gives, to the bit
    (its kernel, its symmetric summation order). Written out because importing scipy.ndimage
    costs `flashbrdf infer` a tenth of a second for a 90-row sum."""
    radius = int(truncate * float(sigma) + 0.5)
    offsets = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 / (float(sigma) * float(sigma)) * offsets ** 2)
    kernel = kernel / kernel.sum()
    values = np.asarray(values, dtype=np.float64)
    padded = np.concatenate([np.repeat(values[:1], radius, axis=0), values,
                             np.repeat(values[-1:], radius, axis=0)])
    n = len(values)
    out = values * kernel[radius]
    for j in range(radius, 0, -1):  # outermost first, left + right: scipy's order of the sums
        out = out + (padded[radius - j:radius - j + n] + padded[radius + j:radius + j + n]) \
            * kernel[radius - j]
    return out


def apply_log_correction(rho, log_c):
    """ρ' = (ρ + e)·exp(ln c) − e, clamped ≥ 0, NaN kept; ρ (..., 3), ln c broadcastable to it."""
    e = FEATURE_OFFSET
    rho = np.asarray(rho, dtype=float)
    out = np.maximum((np.maximum(rho, 0.0) + e) * np.exp(log_c) - e, 0.0)
    out[np.isnan(rho)] = np.nan
    return out


def anchor_to_slice(table, flash_slice, smoothing_bins=None):
    """Correct a predicted table so that its θd = 0 row follows the observed slice, like Nöll et
    al.'s correction functions: anchor_log_correction of its θd = 0 row (the φd-mean for a 3D
    table), carried over every θd (and φd). table: (90, 90, 3) or (90, 90, 180, 3) in 1/sr, NaN
    where no data; flash_slice: (90, 3), NaN where empty. Returns a new table.
    """
    table = np.asarray(table, dtype=float)
    first = table[:, 0] if table.ndim == 3 else np.nanmean(table[:, 0], axis=1)
    log_c = anchor_log_correction(first, flash_slice, smoothing_bins)
    if log_c is None:
        return table.copy()
    shape = (N_THETA_H, 1, 3) if table.ndim == 3 else (N_THETA_H, 1, 1, 3)
    return apply_log_correction(table, log_c.reshape(shape))


class AnchoredSpace(LinearSpace):
    """Another method's combination space whose inverse also applies a log correction ln c, so
    streamed 3D predictions are corrected like the 2D ones: per θh (90, 3) (the anchoring,
    anchor_log_correction) or per (θh, θd) (90, 90, 3) (the consensus,
    infer.consensus.consensus_log_correction); each 3D bin takes its own bin's."""

    def __init__(self, base, log_c):
        self.base, self.log_c = base, log_c
        self.clip_to_training = base.clip_to_training

    def forward(self, rho, sel=slice(None)):
        return self.base.forward(rho, sel)

    def inverse(self, mapped, sel=slice(None)):
        ih, jd, _ = valid_bins_3d()
        log_c = self.log_c[ih[sel]] if self.log_c.ndim == 2 else self.log_c[ih[sel], jd[sel]]
        return apply_log_correction(self.base.inverse(mapped, sel), log_c)
