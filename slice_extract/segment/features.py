"""Per-sample features and per-theta_h-bin statistics of flash samples (the segmentation's inputs).

rho (N, 3) 1/sr and theta_h (N,) radians are FlashSamples' (slice_extract.extract); bins are MERL
theta_h bins (0..89).
"""

import numpy as np

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.brdf.merl import N_THETA_H, theta_h_centres

LOG_FLOOR_REL = 1e-3  # rho below this fraction of the median brightness counts as black


# a photo resolves a value when the step to its next level is at most this share of it
# (resolution_floor). 20%: 10% (the alike threshold) took pot2's 8-bit linear materials to a
# slice gap of 0.14 against 0.1 (0.34 without the floor); 30% left a phone-JPEG nickel split
RESOLVED_GAP = 0.2


def theta_h_bins(theta_h):
    return merl_bin_index(theta_h, 0.0, 0.0)[0]


def binned_median(values, bins, n_bins=N_THETA_H, min_count=5):
    """Per-bin median of values (N,) or (N, C): (n_bins,) or (n_bins, C), NaN below min_count."""
    values = values.reshape(len(values), -1)
    order = np.argsort(bins, kind="stable")
    counts = np.bincount(bins, minlength=n_bins)
    ends = np.cumsum(counts)
    out = np.full((n_bins, values.shape[1]), np.nan)
    sorted_values = values[order]
    for i in np.flatnonzero(counts >= min_count):
        out[i] = np.median(sorted_values[ends[i] - counts[i]:ends[i]], axis=0)
    return out if values.shape[1] > 1 else out[:, 0]


def fill_bins(curve):
    """Fill NaN bins (n_bins, C) by linear interpolation over the bin index, flat at the ends."""
    curve = np.array(curve, dtype=float, copy=True)
    index = np.arange(len(curve))
    for c in range(curve.shape[1]):
        ok = np.isfinite(curve[:, c])
        if ok.any():
            curve[:, c] = np.interp(index, index[ok], curve[ok, c])
        else:
            curve[:, c] = 0.0
    return curve


def log_samples(rho, floor=None):
    """ln(rho + floor/3) (N, 3), ln of its channel sum + floor (N,), and floor (by default
    LOG_FLOOR_REL times the median brightness)."""
    total = rho.sum(axis=1)
    if floor is None:
        floor = LOG_FLOOR_REL * max(float(np.median(total)), 1e-12)
    return np.log(np.maximum(rho, 0) + floor / 3), np.log(np.maximum(total, 0) + floor), floor


def specular_lobe_bins(log_total, bins, rise=np.log(1.5)):
    """(n_bins,) bool: the theta_h bins from 0 up to where the median ln(rho) has fallen back to
    within `rise` of its off-lobe level (the median over bins with theta_h in 20..60 deg)."""
    median = binned_median(log_total, bins)
    centres = np.degrees(theta_h_centres())
    body = np.isfinite(median) & (centres >= 20) & (centres <= 60)
    lobe = np.zeros(N_THETA_H, bool)
    if not body.any():
        return lobe, median
    level = np.median(median[body])
    high = np.isfinite(median) & (median > level + rise)
    # the lobe is the run of high bins at small theta_h (empty bins inside it count as lobe)
    for i in range(N_THETA_H):
        if centres[i] >= 45:
            break
        if high[i] or (not np.isfinite(median[i]) and high[i:].any()):
            lobe[i] = True
        elif np.isfinite(median[i]):
            break
    return lobe, median


def resolution_floor(rho, values, resolved=RESOLVED_GAP):
    """Brightness (rho channel sum, 1/sr) below which the photo does not resolve a sample: per
    channel, the lowest of the photo's levels (its distinct values among the samples) from which
    on the step to the next level is at most `resolved` of the level, summed over the channels
    and taken to rho by the samples' median rho / pixel ratio. rho (N, 3) the samples (a
    subsample of ~50,000 is enough), values (N, 3) their pixels in the photo. An 8-bit gamma
    file (a phone's JPEG) resolves 20% from code ~11 (~0.1% of its white), an 8-bit linear one
    from code 5 (2%), photon counts from 5 photons; a float photo (distinct values all
    through) gives 0. Why: below it a channel is a few codes, and a JPEG's block error or the
    rounding of a code moves it by tens of per cent, so dark pixels of one metal took
    different colours and split it (phone-JPEG sweep: chrome, nickel, tungsten-carbide;
    benchmarks/results/segment_sweep_jpeg90.md)."""
    values = np.asarray(values, float)
    total = values.sum(axis=1)
    lit = total > 0
    if not lit.any():
        return 0.0
    floor = 0.0
    for c in range(3):
        levels = np.unique(values[:, c][values[:, c] > 0])
        if len(levels) < 2:
            continue
        fine = np.flatnonzero(np.diff(levels) <= resolved * levels[:-1])
        if not len(fine):      # no level resolved: the channel is coarse throughout
            floor += levels[-1]
        elif fine[0] > 0:      # coarse below levels[fine[0]]; a float photo is fine from its
            floor += levels[fine[0]]  # lowest value on and adds nothing
    ratio = rho.sum(axis=1)[lit] / total[lit]
    return floor * float(np.median(ratio))


def material_features(rho, theta_h):
    """Features (N, 3) of samples rho (N, 3) 1/sr at theta_h (N,) rad, and off_lobe (N,) bool.

    Columns: r/(r+g+b), g/(r+g+b) and ln(r+g+b) of rho, the last taken relative to its per-bin
    median inside the specular lobe (specular_lobe_bins) and relative to the off-lobe level
    elsewhere, so it is ~0 for the typical pixel everywhere.
    """
    _, log_total, floor = log_samples(rho)
    # chromaticity, not channel differences over one global scale: differences grow with the
    # pixel's brightness, so a coloured metal's highlight (gold and teal foil on the planar
    # cards) became a material of its own (cards: 5 materials, 85% of pixels in the all-view
    # colour cluster of their material; chromaticity: 3 and 94%, docs/results.md, one-off: cards_diagnosis). A
    # dielectric's highlight, which fades chromaticity to grey, is the k-slice refinement's job.
    total = np.maximum(rho.sum(axis=1), floor)[:, None]
    chroma = np.maximum(rho[:, :2], 0) / total
    bins = theta_h_bins(theta_h)
    lobe, median = specular_lobe_bins(log_total, bins)
    centres = np.degrees(theta_h_centres())
    body = np.isfinite(median) & (centres >= 20) & (centres <= 60)
    level = np.median(median[body]) if body.any() else np.nanmedian(median)
    reference = np.where(lobe & np.isfinite(median), median, level)
    brightness = log_total - reference[bins]
    return np.column_stack([chroma, brightness]), ~lobe[bins]


def neighbour_samples(pixels, shape, which=None, distance=1):
    """(M,) for each sample in `which` (indices into pixels; default all N) the index of the sample
    `distance` pixels to its right, left, below or above (the first that holds one), or the sample
    itself where none does. pixels (N,): flat indices into an (H, W) image, one sample per pixel."""
    height, width = shape
    pixels = np.asarray(pixels, np.int64)
    which = np.arange(len(pixels)) if which is None else np.asarray(which, np.int64)
    at = np.full(height * width, -1, np.int32)      # sample index per pixel (< 2^31 samples)
    at[pixels] = np.arange(len(pixels), dtype=np.int32)
    out = np.full(len(which), -1, np.int64)
    row, col = np.divmod(pixels[which], width)
    for d_row, d_col in ((0, distance), (0, -distance), (distance, 0), (-distance, 0)):
        todo = out < 0
        r, c = row[todo] + d_row, col[todo] + d_col
        inside = (r >= 0) & (r < height) & (c >= 0) & (c < width)
        found = np.full(len(r), -1, np.int64)
        found[inside] = at[r[inside] * width + c[inside]]
        out[np.flatnonzero(todo)] = found
    alone = out < 0
    out[alone] = which[alone]
    return out
