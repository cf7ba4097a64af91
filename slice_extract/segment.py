"""Segment a flash photo into materials: labels 1..K per object pixel, 0 elsewhere.

Why here: segmentation reads exactly what extraction reads, each flash pixel's BRDF sample
rho = pixel r^2 / (I cos theta_i) at its theta_h (slice_extract.samples), so it lives beside it
and shares its traced samples (slice_extract.extract.collect_samples); no other stage is needed.

What separates materials is what the photo says about the material, not about shading:
- features (material_features): the chromaticity of rho, r/(r+g+b) and g/(r+g+b), and
  ln(r+g+b) of rho. rho has cos(theta_i)/r^2 divided out, so away from the specular lobe it is
  the material's albedo; inside the lobe (theta_h bins where the per-bin median of ln rho rises
  above its off-lobe level) ln rho is taken relative to that median, so a highlight does not
  become a material of its own. The mixture is fitted on off-lobe pixels where there are enough.
- clustering (scikit-learn GaussianMixture, full covariances, on a subsample): K from 1 to
  max_materials by BIC; then components that are not distinct materials are merged: a pair
  whose means are closer than `separation` pooled standard deviations (Mahalanobis, the
  pair's mean covariance) is one material, and so is a component holding less than
  `min_fraction` of the pixels. A single material's non-Gaussian spread is what makes BIC
  split it; the separation test undoes that, so one material gives K = 1.
- refinement ("k slices"): each pixel goes to the material whose slice (per-bin median of
  ln rho per channel, filled across empty bins) explains its sample best; that fixes highlight
  pixels, whose colour alone is ambiguous. "Explains" (_residuals) weighs the sample's
  brightness offset from the slice BRIGHTNESS_WEIGHT times its colour offset: within one
  material brightness varies pixel to pixel (texture, glitter, bumps), colour far less.
- the stated criterion for K > 1: every material but the largest must be explained clearly
  better by its own slice than by the one-slice model of the whole object: the mean residual
  (_residuals, capped at 1 per pixel) of its pixels at most `explained` times as large.
  (A material only slightly better explained is a shading or noise split of one material.)
  Or, where two materials share the theta_h bins, its partner must be explained by its own
  slice at most `explained`/2 times as badly as by the two's joint slice (_partner_ratio).
  The alike merge also takes for one material a brighter one that is the other plus its own
  colour squared (interreflection_gaps: light come back after one more bounce on it, in a dent,
  a fold, a bowl), when most of the brighter's pixels lie where the surface can see itself
  (nonconvex_mask, from the normals): interreflection is not in the pixel model, and a coloured
  metal lights its own concavities many times brighter and deeper in colour.
  This test and the alike merge read, for each pixel of the work subsample, the sample 2 px away
  (neighbour_samples) under the pixel's label, so the noise that chose a label is not read back
  as a difference; and they read ln rho above the photo's resolution floor (resolution_floor:
  where an 8-bit or JPEG file holds a channel in a few codes), so quantisation and block
  errors in a metal's dark pixels are not read as colour.
- the last assignment of every pixel (_assign_all) first takes off a flash-coloured (white)
  highlight term where the pixel is brighter than a coloured material's slice (_added_white,
  dichromatic model): a foil's highlight no longer passes for a paler material.
- names across theta_h rings (align_bin_labels): the assignment decides bin by bin, so where
  two materials' names came out exchanged over some rings, the pixels adjacent across the
  rings' edges put them back.
- spatial clean-up (OpenCV connected components and labelled distance transform): patches
  smaller than `min_area_fraction` of the object merge into the nearest larger patch (unless
  the photo's frame cuts them, or the material has no larger patch: a pattern of dots), and
  object pixels without a sample (silhouette ring, grazing, clipped, shadowed) take the
  nearest label.

Labels are numbered by decreasing pixel count (1 = the largest material).
"""

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree
from threadpoolctl import threadpool_limits

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import N_THETA_H, theta_h_centres

LOG_FLOOR_REL = 1e-3  # rho below this fraction of the median brightness counts as black
# weight of a sample's brightness offset from a slice (the mean over channels of ln rho - ln
# slice) against its colour offset (what is left per channel) in _residuals: texture, glitter,
# bumps and printed albedo move a material's brightness pixel to pixel, far less its colour
BRIGHTNESS_WEIGHT = 0.25
# a slice whose channels spread by less than this share of their mean is grey: an added white
# (flash-coloured) highlight term cannot be told from its brightness there, so _residuals does
# not take one off. 0.1: the ~10% at which two ln-rho slices count as one material (alike).
GREY_SPREAD = 0.1
# the white term takes at most this share of a sample's weakest channel: all of it would leave
# that channel at the log floor, where ln rho measures the floor, not the pixel (planar cards:
# labels in their all-view cluster 96.2% with 1.0, 96.8% with 0.9; results/cards_labels.md)
WHITE_CAP = 0.9
# a photo resolves a value when the step to its next level is at most this share of it
# (resolution_floor). 20%: 10% (the alike threshold) took pot2's 8-bit linear materials to a
# slice gap of 0.14 against 0.1 (0.34 without the floor); 30% left a phone-JPEG nickel split
RESOLVED_GAP = 0.2


@dataclass(frozen=True)
class SegmentOptions:
    max_materials: int = 6
    fit_samples: int = 5000        # pixels the mixture is fitted on
    work_samples: int = 50000      # pixels materials and slices are found on; all are assigned
    separation: float = 3.0        # pooled sigmas between two materials' feature means
    min_fraction: float = 0.02     # share of the sampled pixels a material must hold
    explained: float = 0.6         # residual ratio K slices / one slice needed for K > 1
    min_area_fraction: float = 0.002
    refine_iterations: int = 3
    alike: float = 0.1             # ln-rho slices closer than this (~10%) are one material
    # how far the sample the K tests read lies (neighbour_samples): 2 px, the nearest whose value
    # a bilinear demosaic makes without the pixel's own raw sample (demosaiced single materials
    # kept whole: 111 of 122 at 1 px, 117 at 2, 120 at 3; the cards' criterion margin 0.49, 0.54,
    # 0.55 against 0.6; benchmarks/results/segment_sweep_demosaic.md, README)
    neighbour_px: int = 2
    seed: int = 0


@dataclass(eq=False)
class Segmentation:
    """labels (H, W) uint16, 0 = not the object, 1..K; k: K; criterion: JSON-ready numbers
    (BIC per K, merged K, residuals) that say why K was chosen; sample_labels (N,) int 1..K of
    the samples it was computed from (before spatial clean-up, 0 for censored)."""
    labels: np.ndarray
    k: int
    criterion: dict
    sample_labels: np.ndarray


def _bins(theta_h):
    return merl_bin_index(theta_h, 0.0, 0.0)[0]


def _binned_median(values, bins, n_bins=N_THETA_H, min_count=5):
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


def _fill_bins(curve):
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


def _log_rho(rho, floor=None):
    """ln(rho + floor/3) (N, 3), ln of its channel sum + floor (N,), and floor (by default
    LOG_FLOOR_REL times the median brightness)."""
    total = rho.sum(axis=1)
    if floor is None:
        floor = LOG_FLOOR_REL * max(float(np.median(total)), 1e-12)
    return np.log(np.maximum(rho, 0) + floor / 3), np.log(np.maximum(total, 0) + floor), floor


def specular_lobe_bins(log_total, bins, rise=np.log(1.5)):
    """(n_bins,) bool: the theta_h bins from 0 up to where the median ln(rho) has fallen back to
    within `rise` of its off-lobe level (the median over bins with theta_h in 20..60 deg)."""
    median = _binned_median(log_total, bins)
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
    _, log_total, floor = _log_rho(rho)
    # chromaticity, not channel differences over one global scale: differences grow with the
    # pixel's brightness, so a coloured metal's highlight (gold and teal foil on the planar
    # cards) became a material of its own (cards: 5 materials, 85% of pixels in the all-view
    # colour cluster of their material; chromaticity: 3 and 94%, cards_diagnosis.md). A
    # dielectric's highlight, which fades chromaticity to grey, is the k-slice refinement's job.
    total = np.maximum(rho.sum(axis=1), floor)[:, None]
    chroma = np.maximum(rho[:, :2], 0) / total
    bins = _bins(theta_h)
    lobe, median = specular_lobe_bins(log_total, bins)
    centres = np.degrees(theta_h_centres())
    body = np.isfinite(median) & (centres >= 20) & (centres <= 60)
    level = np.median(median[body]) if body.any() else np.nanmedian(median)
    reference = np.where(lobe & np.isfinite(median), median, level)
    brightness = log_total - reference[bins]
    return np.column_stack([chroma, brightness]), ~lobe[bins]


def _merge_components(means, covariances, weights, separation, min_fraction, margins=None):
    """Groups of mixture components that are one material: list of index lists.

    margins: a dict that receives "separations_merged" (the distances of the pairs merged as
    one material) and "separation_kept" (the closest pair kept apart, None if one is left)."""
    groups = [[i] for i in range(len(weights))]
    mu = [m.copy() for m in means]
    cov = [c.copy() for c in covariances]
    w = list(weights)

    def distance(a, b):
        pooled = 0.5 * (cov[a] + cov[b])
        d = mu[a] - mu[b]
        return float(np.sqrt(d @ np.linalg.solve(pooled, d)))

    while len(groups) > 1:
        pairs = [(distance(a, b), a, b) for a in range(len(groups))
                 for b in range(a + 1, len(groups))]
        small = [i for i in range(len(groups)) if w[i] < min_fraction]
        if small:  # a sliver is merged into the component nearest to it
            a = min(small, key=lambda i: w[i])
            _, x, y = min(p for p in pairs if a in p[1:])
        else:
            d, x, y = min(pairs)
            if d >= separation:
                if margins is not None:
                    margins["separation_kept"] = round(d, 3)
                break
            if margins is not None:
                margins.setdefault("separations_merged", []).append(round(d, 3))
        total = w[x] + w[y]
        m = (w[x] * mu[x] + w[y] * mu[y]) / total
        c = (w[x] * (cov[x] + np.outer(mu[x] - m, mu[x] - m))
             + w[y] * (cov[y] + np.outer(mu[y] - m, mu[y] - m))) / total
        mu[x], cov[x], w[x] = m, c, total
        groups[x] = groups[x] + groups[y]
        del mu[y], cov[y], w[y], groups[y]
    return groups


def _slices(log_rho, bins, labels, k):
    """Per-material ln-rho slices (k, n_bins, 3), empty bins filled along theta_h."""
    out = np.zeros((k, N_THETA_H, 3))
    for j in range(k):
        mine = labels == j
        out[j] = _fill_bins(_binned_median(log_rho[mine], bins[mine], min_count=3)
                            if mine.any() else np.full((N_THETA_H, 3), np.nan))
    return out


def _white_terms(slice_log, offset):
    """Per theta_h bin of one ln-rho slice (n_bins, 3): its linear value's channel mean (n_bins,),
    the channels' deviations from it (n_bins, 3), and whether the slice is coloured (n_bins,)
    bool: channels spread by at least GREY_SPREAD of their mean. A grey slice's own colour is
    the flash's: an added white term there is just brightness, which the residual weighs."""
    linear = np.maximum(np.exp(slice_log) - offset, 0)
    mean = linear.mean(axis=1)
    deviation = linear - mean[:, None]
    spread = np.sqrt((deviation ** 2).mean(axis=1))
    return mean, deviation, spread >= GREY_SPREAD * mean


def _added_white(rho, mean, deviation, coloured):
    """(N,) the flash-coloured (white) term s >= 0 to take off each sample before it is compared
    with a slice: least squares rho_c = a slice_c + s over the 3 channels, kept where the slice is
    coloured and the body a >= 1 (a highlight adds to the material, it does not replace part of
    it), and at most WHITE_CAP of the sample's weakest channel. rho: 3 arrays (N,) (linear, per
    channel); mean (N,), deviation: 3 arrays (N,), coloured (N,) bool: _white_terms taken at
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


def _residuals(log_rho, bins, slices, floor=None):
    """(N, k) how badly slice_k explains each sample: with d = ln rho - ln slice_k(theta_h)
    (N, 3) and its brightness offset m = mean over channels of d, the mean over channels of
    |d - m| (colour) plus BRIGHTNESS_WEIGHT |m|, capped at 1 (an outlier pixel counts as a bad
    fit, not as an unbounded one). With floor (_log_rho's: log_rho = ln(rho + floor/3)), rho
    is first relieved of the white term _added_white finds for slice_k (dichromatic model: a
    flash highlight adds the flash's colour, white after white balance): the final assignment's
    rule (_assign_all). Without, the plain rule that finds the materials and their slices."""
    if floor is not None:
        offset = floor / 3
        rho = np.maximum(np.exp(log_rho) - offset, 0)
        columns = [rho[:, c] for c in range(3)]
    out = []
    for s in slices:
        d = log_rho - s[bins]
        if floor is not None:
            mean, deviation, coloured = _white_terms(s, offset)
            white = _added_white(columns, mean[bins], [deviation[bins, c] for c in range(3)],
                                 coloured[bins])
            lifted = white > 0
            d[lifted] = (np.log(rho[lifted] - white[lifted, None] + offset)
                         - s[bins[lifted]])
        m = d.mean(axis=1, keepdims=True)
        out.append(np.minimum(np.abs(d - m).mean(axis=1) + BRIGHTNESS_WEIGHT * np.abs(m[:, 0]),
                              1.0))
    return np.stack(out, 1)


def _refine(log_rho, bins, labels, k, options):
    """k slices: each sample to the material whose slice explains it best, a few rounds.
    Returns (labels 0..k'-1, k'); a material left with < min_fraction of the samples goes."""
    n = len(labels)
    for _ in range(options.refine_iterations):
        residual = _residuals(log_rho, bins, _slices(log_rho, bins, labels, k))
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


# The lowest eigenvalue of the normal's derivative when the normals hold only noise (a flat
# surface) of std sigma per component: below -2.56 sigma for 0.1% of pixels (and below 0 for 85%,
# which is what made a noisy normal map's plane or sphere read non-convex). Simulated: central
# differences of N(0, sigma^2) components, 2e6 draws.
NOISE_MARGIN = 2.56
# E|x| over the 90% smallest |x| of a N(0, 6) variable (a second difference of unit noise), so
# that trimmed mean / this = sigma; the 10% kept out are creases, silhouettes and dents.
_TRIMMED_ABS_SECOND_DIFFERENCE = 1.608


def normal_noise(second_differences):
    """Estimated std (float) of a normal component's pixel-to-pixel noise from its second
    differences n(+1) + n(-1) - 2 n(0) (M,) along the image axes: on a smooth surface they are
    about 0 (a sphere's image-plane normal is linear in the pixel) and noise gives them std
    sqrt(6) sigma. A trimmed mean of |.|, not a median: a normal map quantised to 8 bits has
    most second differences exactly 0 and a median would read no noise. 0 when there are none."""
    x = np.abs(np.asarray(second_differences, np.float64))
    if x.size == 0:
        return 0.0
    kept = x[x <= np.quantile(x, 0.9)]
    return float(kept.mean() / _TRIMMED_ABS_SECOND_DIFFERENCE)


def nonconvex_mask(normals, pixels=None, shape=None):
    """(H, W) bool, or (M,) bool at `pixels` (M,) flat indices: object pixels where the surface is
    not convex, so that it can see (and light) itself. normals: (H, W, 3) unit normals in the
    camera frame (x right, y down; 0 off the object), or a callable giving them (M, 3) at flat
    pixel indices (M,) of an image of `shape` (H, W) (FlashSamples.normals_at: extraction then
    traces only the pixels asked and their neighbours, no 12-MP normal image). The normal's
    image-plane part (nx, ny) is differentiated over the pixel grid (central differences); on a
    convex surface it turns the way the pixel moves (a sphere seen orthographically: the
    identity over its radius), so the symmetric part of its 2 x 2 derivative has no negative
    eigenvalue; one below 0 is a dent, a valley, a crease, the inside of a bowl or of a torus.
    "Below 0" is below -NOISE_MARGIN sigma, sigma the normals' pixel noise (normal_noise, from
    the asked pixels' second differences): noise alone gives a negative eigenvalue at 85% of a
    plane's pixels, at 0.1% past the margin; exact normals (a mesh) have sigma ~ 0. A
    pixel whose four neighbours are not all on the object (no central difference) is never
    non-convex. An orthographic reading: with a pinhole, a convex surface's silhouette can read
    non-convex over a few pixels (the caller asks it of a majority of a material's pixels)."""
    if callable(normals):
        normals_at, (height, width) = normals, shape
    else:
        flat = np.asarray(normals).reshape(-1, 3)
        height, width = np.asarray(normals).shape[:2]

        def normals_at(p):
            return flat[p]
    image = pixels is None
    pixels = np.arange(height * width) if image else np.asarray(pixels, np.int64)
    row, col = np.divmod(pixels, width)
    valid = (row > 0) & (row < height - 1) & (col > 0) & (col < width - 1)
    at = np.where(valid, pixels, 0)
    # one look-up for the pixels and their four neighbours
    looked_up = np.asarray(normals_at(np.concatenate(
        [at + off for off in (1, -1, width, -width, 0)])), np.float64).reshape(5, len(at), 3)
    steps = list(looked_up[:4])
    for v in looked_up:
        valid &= np.einsum("ij,ij->i", v, v) > 0.25
    a, c = 0.5 * (steps[0][:, :2] - steps[1][:, :2]).T   # d nx / d col, d ny / d col
    b, d = 0.5 * (steps[2][:, :2] - steps[3][:, :2]).T   # d nx / d row, d ny / d row
    off = 0.5 * (b + c)
    half_trace = 0.5 * (a + d)
    lowest = half_trace - np.sqrt(np.maximum(half_trace ** 2 - (a * d - off * off), 0))
    centre = looked_up[4][valid, :2]
    second = np.concatenate([steps[0][valid, :2] + steps[1][valid, :2] - 2 * centre,
                             steps[2][valid, :2] + steps[3][valid, :2] - 2 * centre]).ravel()
    out = valid & (lowest < -NOISE_MARGIN * normal_noise(second))
    return out.reshape(height, width) if image else out


def interreflection_gaps(base, other):
    """How well ln-rho slice `other` (n, 3) is `base` (n, 3) plus base's own light come back after
    one more bounce on it: (surplus gap, scaled gap), medians over the n bins of the mean
    |difference| over channels after the fitted term. Surplus: other = base (1 + t base) per
    channel with t >= 0 fitted per bin (least squares on other / base - 1), i.e. an added term
    of base's colour squared. Scaled: other = c base, a brightness factor per bin, the colour
    left as it is.

    Why: in a concave region (a dent, a fold, a bowl, the hole of a torus) light reaches the
    pixel also after bouncing off the object itself, and each bounce on the material multiplies
    the light by its reflectance again: the pixel is brighter by a term of the material's colour
    squared (cubed, ...), so a coloured material looks more saturated there, and a coloured metal
    (gold, copper), which sends its highlight into its own concavities, many times brighter and
    deeper in colour. The pixel model (rho = pixel / cos theta_i) has no such term, so these
    pixels read as another material (Mitsuba path-traced dented sphere, gold: K = 3 with 8
    bounces, K = 1 with direct light only). A brighter material of the base's colour fits the
    scaling as well as the surplus; only a colour change towards base squared tells them apart,
    so the caller asks the surplus to fit twice as well as the scaling. A grey base: the two fit
    alike, and the two materials stay apart (interreflection on a grey material looks like a
    brighter grey, which nothing in one flash photo tells from a paler material)."""
    base = np.asarray(base, float)
    other = np.asarray(other, float)
    s = np.exp(base)
    t = np.maximum(((np.exp(other - base) - 1) * s).sum(axis=1) / (s * s).sum(axis=1), 0)
    surplus = np.abs(other - base - np.log1p(t[:, None] * s)).mean(axis=1)
    d = other - base
    scaled = np.abs(d - d.mean(axis=1, keepdims=True)).mean(axis=1)
    return float(np.median(surplus)), float(np.median(scaled))


def _merge_alike_slices(log_rho, bins, labels, k, options, min_count=10, min_common=3,
                        margins=None, nonconvex=None):
    """Materials whose slices agree are one material: merge every pair whose ln-rho slices
    differ by less than options.alike (median over the theta_h bins both observe, with at least
    min_count samples each, of the mean |difference| over channels). A material seen at grazing
    angles only (or only in the highlight) then joins the one it continues. Returns
    (labels 0..k'-1, k'). margins: a dict whose "alike_gaps" list receives every pair's gap.
    nonconvex: None, or a callable giving (N,) bool: the samples on surface that can see itself
    (nonconvex_mask). A pair that is not alike is still one material when the brighter is the
    other plus its own light come back (interreflection_gaps), provided most of the brighter's
    samples lie where the surface can see itself: a convex object cannot light itself."""
    raw = np.stack([_binned_median(log_rho[labels == j], bins[labels == j],
                                   min_count=min_count) for j in range(k)])
    parent = list(range(k))

    def root(j):
        while parent[j] != j:
            j = parent[j]
        return j

    for a in range(k):
        for b in range(a + 1, k):
            common = np.all(np.isfinite(raw[a]) & np.isfinite(raw[b]), axis=1)
            if common.sum() < min_common:
                continue
            gap = np.median(np.abs(raw[a][common] - raw[b][common]).mean(axis=1))
            if margins is not None:
                margins.setdefault("alike_gaps", []).append(round(float(gap), 4))
            if gap < options.alike:
                parent[root(b)] = root(a)
                continue
            # the brighter one may be the other's own light come back (interreflection)
            if nonconvex is None:
                continue
            for base, other in ((a, b), (b, a)):
                surplus, scaled = interreflection_gaps(raw[base][common], raw[other][common])
                if surplus >= options.alike or surplus > scaled / 2:
                    continue
                share = float(np.mean(nonconvex()[labels == other]))
                if margins is not None:
                    margins.setdefault("interreflection_gaps", []).append(
                        [round(surplus, 4), round(scaled, 4), round(share, 3)])
                if share >= 0.5:
                    parent[root(b)] = root(a)
                    break
    roots = np.array([root(j) for j in range(k)])
    _, remap = np.unique(roots, return_inverse=True)
    return remap[labels], int(remap.max()) + 1


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


def cluster_samples(rho, theta_h, options=None, pixels=None, shape=None, at_least=0.0,
                    normals=None):
    """Material of each sample: (labels (N,) int 0..K-1, K, criterion dict).

    rho (N, 3) 1/sr, finite; theta_h (N,) radians. See the module docstring for the method.
    Materials and their slices are found on a random subsample of options.work_samples
    samples (all of them if there are fewer); then every sample goes to the material whose
    slice explains it best once a flash-coloured highlight term is taken off (_assign_all).
    pixels (N,), shape (H, W): where each sample lies in the photo (flat indices), or None. The
    tests that decide K (alike, explained) then read, for each sample of the work subsample, the
    sample options.neighbour_px pixels away (neighbour_samples) under the sample's label: its
    noise, and a demosaic's false colour around an edge, are then nearly independent of the
    label. Read on the samples the labels were
    chosen from, the noise that chose them passes for a difference of materials (near-black
    pixels of chrome-steel and of a dark blue car paint split off,
    benchmarks/results/segment_sweep.md). at_least: the photo's resolution_floor.
    normals: camera-frame normals of the photo, (H, W, 3) or a callable at flat pixel indices
    (FlashSamples.normals_at), or None; with pixels, the alike merge may then read a concave
    region's interreflection as the material it comes from (_merge_alike_slices,
    nonconvex_mask).
    """
    options = options or SegmentOptions()
    n = len(rho)
    pick = (np.arange(n) if n <= options.work_samples else
            np.random.default_rng(options.seed).choice(n, options.work_samples, replace=False))
    check = None
    if pixels is not None:
        neighbours = neighbour_samples(pixels, shape, pick, options.neighbour_px)
        check = (rho[neighbours], theta_h[neighbours])
    nonconvex = None
    if normals is not None and pixels is not None:
        cache = []

        def nonconvex():  # only when a pair asks
            if not cache:
                cache.append(nonconvex_mask(normals, pixels[pick], shape))
            return cache[0]
    labels, k, criterion = _cluster(rho[pick], theta_h[pick], options, check, at_least,
                                    nonconvex)
    criterion.update(samples=int(n), work_samples=int(len(pick)))
    if k == 1:
        return np.zeros(n, int), 1, criterion
    return _assign_all(rho, theta_h, pick, labels, k), k, criterion


def _assign_all(rho, theta_h, pick, labels, k):
    """Labels (N,) of every sample: the material (of the k found on samples `pick`, labelled
    `labels`) whose slice explains it best (_residuals' criterion with the white term, first
    material on a tie). Why the white term here and not while the materials and slices are
    found: there each material's slice must come from pixels of its own colour, and allowing
    the term let highlight pixels of one material into another's slice (planar cards: 95.2% of
    pixels in their all-view cluster against 96.8%, benchmarks/results/cards_labels.md).

    Why column by column in float32: this is the one pass over all (12 million) pixels, and
    numpy's reductions over a length-3 axis and (N, 3) gathers cost more than the arithmetic."""
    log_rho, _, floor = _log_rho(rho[pick])
    slices = _slices(log_rho, _bins(theta_h[pick]), labels, k)
    white_terms = [[np.ascontiguousarray(t, np.float32) for t in (mean, *deviation.T, coloured)]
                   for mean, deviation, coloured in (_white_terms(s, floor / 3) for s in slices)]
    slices = slices.astype(np.float32)
    columns = [[np.ascontiguousarray(slices[j, :, c]) for c in range(3)] for j in range(k)]
    offset = np.float32(floor / 3)
    out = np.empty(len(rho), np.int64)
    for start in range(0, len(rho), 1 << 20):  # in chunks: bounded memory at 12 megapixels
        part = slice(start, start + (1 << 20))
        bins = _bins(theta_h[part])
        linear = [np.maximum(rho[part, c], 0).astype(np.float32) for c in range(3)]
        logs = [np.log(linear[c] + offset) for c in range(3)]
        best, best_residual = np.zeros(len(bins), np.int64), None
        for j in range(k):
            terms = [t.take(bins) for t in white_terms[j]]
            white = _added_white(linear, terms[0], terms[1:4], terms[4] > 0)
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


def _cluster(rho, theta_h, options, check=None, at_least=0.0, nonconvex=None):
    """cluster_samples on the samples given, all of them; check: (rho, theta_h) of the samples'
    neighbours, which the alike and explained tests read (None: the samples themselves)."""
    from sklearn.mixture import GaussianMixture  # lazy: +2.4 s on every import of slice_extract
    n = len(rho)
    criterion = {"samples": int(n)}
    if n < 50:
        criterion["reason"] = "fewer than 50 samples: one material"
        return np.zeros(n, int), 1, criterion
    features, off_lobe = material_features(rho, theta_h)
    rng = np.random.default_rng(options.seed)
    pool = np.flatnonzero(off_lobe) if off_lobe.sum() >= max(0.3 * n, 50) else np.arange(n)
    fit = rng.choice(pool, size=min(options.fit_samples, len(pool)), replace=False)
    scale = features[fit].std(axis=0) + 1e-6
    x = features / scale
    models, bic = [], []
    for k in range(1, options.max_materials + 1):
        gm = GaussianMixture(k, covariance_type="full", reg_covar=1e-4, init_params="k-means++",
                             random_state=options.seed).fit(x[fit])
        models.append(gm)
        bic.append(float(gm.bic(x[fit])))
    best = models[int(np.argmin(bic))]
    margins = criterion.setdefault("margins", {})
    groups = _merge_components(best.means_, best.covariances_, best.weights_,
                               options.separation, options.min_fraction, margins)
    criterion.update(bic={k + 1: b for k, b in enumerate(bic)}, bic_k=best.n_components,
                     merged_k=len(groups))
    if len(groups) == 1:
        return np.zeros(n, int), 1, criterion
    component_to_group = np.zeros(best.n_components, int)
    for g, members in enumerate(groups):
        component_to_group[members] = g
    labels = component_to_group[best.predict(x)]
    log_rho, _, floor = _log_rho(rho)
    bins = _bins(theta_h)
    # the tests read the neighbours (same floor: one brightness scale for both); residual_one
    # in the criterion is then the neighbours' too. They read ln rho above the photo's
    # resolution floor when it is the higher: what a coarse photo does not resolve is no
    # evidence of a material (resolution_floor)
    test_floor = max(floor, at_least)
    criterion["resolution_floor"] = float(at_least)
    log_test, bins_test = (_log_rho(rho, test_floor)[0], bins) if check is None else \
        (_log_rho(check[0], test_floor)[0], _bins(check[1]))
    # how badly one slice for the whole object explains each sample (the explained test's base)
    single = _residuals(log_test, bins_test,
                        _slices(log_test, bins_test, np.zeros(n, int), 1))[:, 0]
    k = len(groups)
    for _ in range(options.max_materials):  # refine, merge look-alikes, until nothing merges
        labels, k = _refine(log_rho, bins, labels, k, options)
        labels, merged = _merge_alike_slices(log_test, bins_test, labels, k, options,
                                             margins=margins, nonconvex=nonconvex)
        if merged == k:
            break
        k = merged
    criterion["alike_merged_k"] = int(k)
    # each material but the largest must be explained clearly better by its own slice than by
    # the one-slice model, or its partner by its own than by the two's joint slice
    # (_partner_ratio: why, and why half); one that is neither is given back to the others
    ratios, rescued = {}, {}
    while k > 1:
        tested = _residuals(log_test, bins_test, _slices(log_test, bins_test, labels, k))
        own = tested[np.arange(n), labels]
        counts = np.bincount(labels, minlength=k)
        ratio = np.array([own[labels == j].mean() / max(single[labels == j].mean(), 1e-12)
                          for j in range(k)])
        ratio[np.argmax(counts)] = 0.0  # the largest material is the reference
        ratios, rescued = {int(j): float(r) for j, r in enumerate(ratio)}, {}
        for j in np.flatnonzero(ratio > options.explained):
            partner = _partner_ratio(log_test, bins_test, labels, j, tested, own)
            margins.setdefault("partner_vs_joint_slice", []).append(round(partner, 4))
            if partner <= options.explained / 2:
                rescued[int(j)] = partner
        failing = np.where(np.isin(np.arange(k), list(rescued)), 0.0, ratio)
        worst = int(np.argmax(failing))
        margins.setdefault("worst_own_vs_one_slice", []).append(round(float(failing[worst]), 4))
        if failing[worst] <= options.explained:
            break
        residual = _residuals(log_rho, bins, _slices(log_rho, bins, labels, k))
        residual[:, worst] = np.inf
        labels = np.unique(residual.argmin(axis=1), return_inverse=True)[1]
        k -= 1
    criterion.update(residual_one=float(single.mean()), explained=options.explained,
                     own_vs_one_slice=ratios, partner_vs_joint_slice=rescued, final_k=int(k))
    if k == 1 and not ratios:
        criterion["reason"] = "the clusters' slices agree: one material"
        return np.zeros(n, int), 1, criterion
    if k == 1:
        criterion["reason"] = ("no material other than the largest is explained by its own "
                               f"slice better than {options.explained} x by one slice: one material")
        return np.zeros(n, int), 1, criterion
    # the largest material's ratio is 0 (the reference); the others pass on their own or by
    # their partner
    plain = [r for j, r in ratios.items() if j not in rescued and r > 0]
    parts = ([f"each material but the largest fits its own slice at most {max(plain):.2f} x as "
              f"badly as one slice for the object (needs <= {options.explained})"] if plain
             else [])
    if rescued:
        parts.append(f"{len(rescued)} material(s) whose partner fits its own slice at most "
                     f"{max(rescued.values()):.2f} x as badly as the two's joint slice (needs <= "
                     f"{options.explained / 2})")
    criterion["reason"] = "; ".join(parts) or "one material besides the largest"
    return labels, k, criterion


def _partner_ratio(log_test, bins_test, labels, j, tested, own):
    """How much better material j's partner (the material most of j's samples would go to) is
    explained by its own slice than by one slice for the two: the mean of its own residuals over
    the mean of its residuals under the two's joint slice. Why: where two materials share the
    theta_h bins about equally, one slice for the object follows whichever holds more samples in
    each bin, so it fits many of the smaller material's samples as well as their own slice does,
    and the smaller's ratio alone says little (a photon-starved black beside a bright wood: 0.64
    against 0.6, while the wood's is 0.03). A split of one material leaves both ratios near 1.
    The caller asks this ratio to be half the `explained` one: a partner that is itself a mix of
    two materials is also helped by its own slice (a colour-changing flake paint beside nickel,
    mixed across its clusters: 0.52), while two clean materials sharing the bins give ~0.05."""
    mine = labels == j
    others = tested[mine].copy()
    others[:, j] = np.inf
    partner = int(np.bincount(others.argmin(axis=1), minlength=tested.shape[1]).argmax())
    pair = mine | (labels == partner)
    joint = _slices(log_test[pair], bins_test[pair], np.zeros(int(pair.sum()), int), 1)
    theirs = labels == partner
    joint_residual = _residuals(log_test[theirs], bins_test[theirs], joint)[:, 0]
    return float(own[theirs].mean() / max(joint_residual.mean(), 1e-12))


# a theta_h bin's materials are renamed (align_bin_labels) only when the new names agree with at
# least this many times as many pixels adjacent across the bin's edge as the old: a region of one
# material is far wider than a bin's ring, so right names agree on most such pairs
RENAME_GAIN = 2.0


def align_bin_labels(labels, bins, pixels, shape, present=0.05):
    """(labels (N,) 0..K-1, number of theta_h bins renamed): each theta_h bin's material names
    permuted to agree with the pixels adjacent to it in the neighbouring bins, outward from the
    bin with the most samples. bins (N,) the samples' theta_h bins, pixels (N,) flat indices into
    an (H, W) image, one sample per pixel.

    Why: the k-slice assignment decides bin by bin, so nothing ties material 1 in one bin to
    material 1 in the next. Where the mixture's first labels swap two materials over a range of
    bins (a dark glossy paint brighter than a white paper in the highlight), the slices learn
    the swap and keep it: whole rings of pixels, each ring split right, carry each other's names
    (white paper beside a glossy dark paint in blobs: 84.1% of pixels right; 98.8% renamed).
    Regions cross the rings, so the pixels adjacent across a bin's edge say which names belong
    together. Only materials holding at least `present` of both bins are renamed: a material
    boundary that follows a ring (a cap round the highlight) leaves one material per side and
    nothing to rename. A ring where one name holds both materials breaks the chain: the bins
    beyond it are then named against it, right or wrong (a phone-JPEG nickel beside a
    colour-changing paint: 77% -> 57% of pixels right)."""
    k = int(labels.max()) + 1 if len(labels) else 1
    if k < 2:
        return labels, 0
    # bins and labels as small-integer images (no sample: a bin far from every other), so the
    # pairs across a bin's edge come from whole-image differences, not 12-MP index gathers
    bin_image = np.full(shape[0] * shape[1], -1000, np.int16)
    bin_image[pixels] = bins
    bin_image = bin_image.reshape(shape)
    label_image = np.zeros(shape[0] * shape[1], np.int16)
    label_image[pixels] = labels
    label_image = label_image.reshape(shape)
    codes, same, pairs_in_bin = [], 0, 0
    for here, there in ((np.s_[:, :-1], np.s_[:, 1:]), (np.s_[:-1, :], np.s_[1:, :])):
        step = bin_image[there] - bin_image[here]
        inside = step == 0
        inside &= bin_image[here] >= 0
        same += int(np.count_nonzero(label_image[here][inside] == label_image[there][inside]))
        pairs_in_bin += int(np.count_nonzero(inside))
        for sign, low, high in ((1, here, there), (-1, there, here)):
            edge = step == sign
            codes.append((bin_image[low][edge].astype(np.int64) * k + label_image[low][edge]) * k
                         + label_image[high][edge])
    codes = np.concatenate(codes)
    shares = np.bincount(labels, minlength=k) / len(labels)
    if same <= (shares ** 2).sum() * pairs_in_bin:
        # neighbours share their material no more often than chance (a 1-px pattern, or noise):
        # adjacency says nothing about names
        return labels, 0
    n_bins = N_THETA_H
    # pairs[b, i, j]: adjacent pixels, the one in bin b labelled i, the one in bin b + 1 labelled j
    pairs = np.bincount(codes, minlength=n_bins * k * k).reshape(n_bins, k, k).astype(float)
    counts = np.bincount(bins * k + labels, minlength=n_bins * k).reshape(n_bins, k)
    names = np.tile(np.arange(k), (n_bins, 1))  # names[b, i]: what label i of bin b becomes
    reference = int(np.argmax(counts.sum(axis=1)))

    def rename(here, fixed, agree):
        """names for bin `here` given the already named bin `fixed`; agree[i, j]: pairs between
        label i here and label j there (original labels)."""
        named = np.zeros((k, k))
        np.add.at(named.T, names[fixed], agree.T)  # columns under bin `fixed`'s new names
        there = np.bincount(names[fixed], weights=counts[fixed], minlength=k)
        shared = [j for j in range(k) if counts[here, j] >= present * counts[here].sum() > 0
                  and there[j] >= present * there.sum() > 0]
        out = np.arange(k)
        if len(shared) < 2:
            return out
        sub = named[np.ix_(shared, shared)]
        rows, cols = linear_sum_assignment(-sub)
        moved = rows != cols
        # every renamed material must itself agree RENAME_GAIN x better under its new name (a
        # region that merely changes label across one ring edge is a mislabel, not a swap), and
        # 3 sigma better than a coin toss would (a few pairs at a grazing ring are noise)
        new, old = sub[rows, cols][moved], sub[rows, rows][moved]
        if moved.any() and np.all((new > RENAME_GAIN * old)
                                  & (new - old >= 3 * np.sqrt(new + old))):
            out[np.array(shared)[rows]] = np.array(shared)[cols]
        return out

    for here in range(reference + 1, n_bins):
        names[here] = rename(here, here - 1, pairs[here - 1].T)
    for here in range(reference - 1, -1, -1):
        names[here] = rename(here, here + 1, pairs[here])
    renamed = int(np.count_nonzero((names != np.arange(k)).any(axis=1)))
    return names[bins, labels], renamed


# a patch of a material under this many pixels is speckle whatever the material's shape: the
# clean-up's floor (clean_label_image)
MIN_PATCH_PX = 4


def clean_label_image(labels, object_mask, min_area_fraction):
    """Spatial clean-up of a label image (H, W) int (0 = no sample) over object_mask (H, W).

    Connected patches smaller than min_area_fraction of the object (at least MIN_PATCH_PX
    pixels) are cleared, unless they touch the photo's frame: such a patch continues outside the
    photo, so its visible area does not say it is noise (an object larger than the frame: the
    planar cards' scales cut by the frame). A material none of whose patches is larger is a
    pattern (dots, print), not speckle round a region of it, so only its patches under
    MIN_PATCH_PX go. Then every object pixel takes the label of the nearest labelled pixel.
    Labels are renumbered 1..K by decreasing area. Returns (H, W) uint16.
    Works on the object's bounding box only (the rest stays 0): the same result, less image.
    """
    object_mask = np.asarray(object_mask, bool)
    out = np.zeros(object_mask.shape, np.uint16)
    rows, cols = np.flatnonzero(object_mask.any(axis=1)), np.flatnonzero(object_mask.any(axis=0))
    if not len(rows):
        return out
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    frame = np.zeros(object_mask.shape, bool)
    frame[[0, -1], :] = frame[:, [0, -1]] = True
    out[box] = _clean_labels(np.asarray(labels)[box], object_mask[box], min_area_fraction,
                             int(object_mask.sum()), frame[box])
    return out


def _clean_labels(labels, object_mask, min_area_fraction, object_pixels, frame):
    """clean_label_image on a crop holding the whole object; frame (crop) bool: the photo's
    outermost pixels."""
    labels = labels.astype(np.int32)
    min_area = max(MIN_PATCH_PX, int(min_area_fraction * max(object_pixels, 1)))
    for k in range(1, int(labels.max()) + 1):
        count, comp, stats, _ = cv2.connectedComponentsWithStats(
            (labels == k).view(np.uint8), connectivity=8)
        if count <= 2:  # absent, or one patch: nothing to clear
            continue
        area = stats[:, cv2.CC_STAT_AREA]
        clear = area < min_area
        clear[0] = False                      # the background of this label's mask
        clear[np.unique(comp[frame])] = False  # cut by the frame: its size is unknown
        if clear[1:].all():                   # no patch is a region: a pattern (dots, print)
            clear &= area < MIN_PATCH_PX
        if clear[1:].all():                   # all tiny: keep the largest
            clear[1 + int(np.argmax(area[1:]))] = False
        if clear.any():
            labels[clear[comp]] = 0           # a lookup table: no per-patch pass
    if not np.any(labels > 0):
        return np.where(object_mask, 1, 0).astype(np.uint16)
    # nearest labelled pixel of every pixel: OpenCV's labelled distance transform numbers the
    # labelled (zero) pixels in row-major order; 4x faster than scipy's exact one at 12 MP
    unlabelled = (labels == 0).view(np.uint8)
    _, nearest = cv2.distanceTransformWithLabels(unlabelled, cv2.DIST_L2, 5,
                                                 labelType=cv2.DIST_LABEL_PIXEL)
    filled = labels[labels > 0].take(nearest - 1)
    filled[~object_mask] = 0
    area = np.bincount(filled.ravel(), minlength=int(filled.max()) + 1)
    order = [k for k in np.argsort(-area, kind="stable") if k > 0 and area[k] > 0]
    renumber = np.zeros(len(area), np.uint16)
    renumber[order] = np.arange(1, len(order) + 1)
    return renumber[filled]


# Width of the band along a border between two materials whose samples a material's slice is
# not extracted from, as a share of the object's size (the square root of its pixel count), at
# least one pixel. Why: labels are least sure at a border (mixed pixels from lens blur,
# demosaicing and resampling; a k-slice assignment that flips on noise), and a wrong pixel
# costs more in a slice (it moves its material's per-bin estimate, most in a bin with few of
# that material's pixels) than at render. A share of the object, not pixels, so a 12-MP photo
# and a 0.3-MP photo of one object drop the same part of it: 0.3% is 3 px on the 1-MP planar
# cards and 1 px (the floor, like extraction's silhouette_px) on DiLiGenT's ~190-px pot2.
BORDER_FRACTION = 0.003
# a theta_h bin keeps its border samples when the interior leaves it fewer than this many: 1,
# so dropping the border never costs a material a bin, and a bin the interior does observe is
# measured from the interior alone, however few its pixels. (20, the n of a trusted bin
# elsewhere, kept the border in the small-theta_h bins, where a material's few pixels are the
# ones a wrong label moves most: planar cards 11.39 against 10.92 with 1, flat tables.)
BORDER_MIN_BIN = 1


def border_width_px(object_pixels, fraction=BORDER_FRACTION):
    """Width (int pixels, >= 1) of the border band for an object of object_pixels pixels."""
    return max(1, int(round(fraction * np.sqrt(max(object_pixels, 0)))))


def material_interior(labels, width):
    """(H, W) bool: object pixels (labels > 0) farther than `width` pixels (Euclidean) from any
    pixel of another material. The object's outline (label 0) is no border here: extraction's
    silhouette_px handles it. Labels (H, W) int, 0 = not the object."""
    labels = np.asarray(labels)
    inside = labels > 0
    out = np.zeros(labels.shape, bool)
    if not inside.any():
        return out
    for k in np.unique(labels[inside]):
        other = inside & (labels != k)
        if not other.any():
            out |= labels == k
            continue
        # distance of every pixel to the nearest pixel of another material (zeros of the input)
        distance = cv2.distanceTransform((~other).view(np.uint8), cv2.DIST_L2, 5)
        out |= (labels == k) & (distance > width)
    return out


def segment_samples(samples, materials="auto", options=None):
    """Segmentation of FlashSamples (slice_extract.extract.collect_samples) of the first flash
    photo; materials: "auto" or an int K >= 1 (then the mixture has K components, unmerged)."""
    options = options or SegmentOptions()
    with threadpool_limits(1):  # tiny 3x3 algebra: BLAS threads only contend on a busy machine
        return _segment_samples(samples, materials, options)


def _segment_samples(samples, materials, options):
    first = (samples.photo == 0) & ~samples.censored & np.all(np.isfinite(samples.rho), axis=1)
    if first.all():  # the usual case (one flash photo, nothing clipped): no 12-MP copies
        rho, theta_h, pixels = samples.rho, samples.theta_h, samples.pixels
    else:
        rho, theta_h, pixels = samples.rho[first], samples.theta_h[first], samples.pixels[first]
    if not len(rho):  # nothing to segment: the error extracting a slice would give
        raise samples.no_sample_error()
    if materials == "auto":
        every = slice(None, None, max(1, len(rho) // 50000))  # no 12-MP gather for a floor
        at_least = resolution_floor(rho[every], samples.radiance.reshape(-1, 3)[pixels[every]])
        labels, k, criterion = cluster_samples(rho, theta_h, options, pixels, samples.shape,
                                               at_least, samples.normals_at)
    else:
        k = int(materials)
        if k > 1 and len(rho) < 2 * k:  # a K-component mixture needs 2K samples at least
            raise InputError("--materials", f"{k} materials need at least {2 * k} usable object "
                                            f"pixels; the flash photo has {len(rho)}")
        labels, criterion = _fixed_k(rho, theta_h, k, options)
    labels, renamed = align_bin_labels(labels, _bins(theta_h), pixels, samples.shape)
    criterion["bins_renamed"] = renamed
    image = np.zeros(samples.shape, np.int32)
    image.ravel()[pixels] = labels + 1
    cleaned = clean_label_image(image, samples.object_mask, options.min_area_fraction)
    criterion["chosen_k"] = int(cleaned.max())
    sample_labels = np.zeros(len(samples.pixels), int)
    sample_labels[first] = np.take(cleaned.ravel(), pixels)
    return Segmentation(cleaned, int(cleaned.max()), criterion, sample_labels)


def _fixed_k(rho, theta_h, k, options):
    """K given by the user: a K-component mixture, refined by K slices, no merging."""
    from sklearn.mixture import GaussianMixture  # lazy: +2.4 s on every import of slice_extract
    n = len(rho)
    if k == 1 or n < 2 * k:
        return np.zeros(n, int), {"samples": int(n), "reason": f"--materials {k}"}
    rng = np.random.default_rng(options.seed)
    pick = rng.choice(n, size=min(options.work_samples, n), replace=False)
    features, _ = material_features(rho[pick], theta_h[pick])
    fit = rng.choice(len(pick), size=min(options.fit_samples, len(pick)), replace=False)
    x = features / (features[fit].std(axis=0) + 1e-6)
    gm = GaussianMixture(k, covariance_type="full", reg_covar=1e-4, init_params="k-means++",
                         random_state=options.seed).fit(x[fit])
    log_rho, _, _ = _log_rho(rho[pick])
    labels, k = _refine(log_rho, _bins(theta_h[pick]), gm.predict(x), k, options)
    return _assign_all(rho, theta_h, pick, labels, k), {"samples": int(n),
                                                        "reason": f"--materials {k}"}


def check_labels(labels, shape, where, count=None):
    """K = labels.max() of a label image (H, W) int. InputError (naming `where`) when it is not
    `shape`, when a label in 1..K has no pixel, or when K != count (the number of tables)."""
    if labels.shape != tuple(shape):
        raise InputError(where, f"is {labels.shape[1]}x{labels.shape[0]} but the flash photo is "
                                f"{shape[1]}x{shape[0]}")
    if labels.size and labels.min() < 0:
        raise InputError(where, f"holds a negative label ({int(labels.min())}); labels are 0 "
                                "(not the object) or 1..K")
    k = int(labels.max()) if labels.size else 0
    # the labels used: a count per value only when K is no more than the pixels (one pixel of
    # 2^31 - 1 in an int32 TIFF asked np.bincount for 16 GiB; past that some label is missing
    # anyway), else np.unique, which sorts (0.34 s against 0.02 s on 12 MP)
    used = (np.flatnonzero(np.bincount(labels.ravel().astype(np.int64), minlength=k + 1)[1:]) + 1
            if k <= labels.size else np.unique(labels[labels > 0]))
    missing = k - len(used)
    if k == 0 or missing:
        # the first missing labels lie within 1..len(used) + 5
        empty = np.setdiff1d(np.arange(1, min(k, len(used) + 5) + 1), used)[:5].tolist()
        shown = ", ".join(map(str, empty or [1])) + (", ..." if missing > 5 else "")
        raise InputError(where, f"label(s) {shown} have no pixel ({missing or 1} in all): "
                                "labels must be 1..K, each used")
    if count is not None and count != k:
        raise InputError(where, f"has {k} material label(s) but {count} BRDF table(s) were "
                                "given")
    return k


def face_labels(labels, face_image, faces_centroids):
    """Label per mesh face (F,) int32 from a label image (H, W) and the face each pixel hits
    (H, W) int (-1 none); faces_centroids (F, 3). A seen face takes its pixels' majority label;
    an unseen face the label of the nearest seen face (by centroid)."""
    n_faces = len(faces_centroids)
    seen = (face_image >= 0) & (labels > 0)
    k = int(labels.max())
    votes = np.zeros((n_faces, k + 1), np.int64)
    np.add.at(votes, (face_image[seen], labels[seen].astype(np.int64)), 1)
    out = votes.argmax(axis=1).astype(np.int32)
    has = votes[:, 1:].sum(axis=1) > 0
    if not has.any():
        return np.ones(n_faces, np.int32)
    if not has.all():
        tree = cKDTree(faces_centroids[has])
        _, nearest = tree.query(faces_centroids[~has])
        out[~has] = out[has][nearest]
    return out
