"""Interreflection: where the surface sees itself (nonconvex_mask) a material lights itself, and
its brighter, deeper-coloured pixels are not another material (interreflection_gaps); the alike
merge joins materials whose slices agree, or that differ by such light come back.
"""

import numpy as np

from flashbrdf.slice_extract.segment.features import binned_median

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


def merge_alike_slices(log_rho, bins, labels, k, options, min_count=10, min_common=3,
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
    raw = np.stack([binned_median(log_rho[labels == j], bins[labels == j],
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
