"""How many materials and which sample is which: a Gaussian mixture over material features, K by
BIC, merged to distinct materials, refined by k slices, and tested against one slice for all.
"""

from dataclasses import dataclass

import numpy as np

from flashbrdf.slice_extract.segment.features import (
    log_samples,
    material_features,
    neighbour_samples,
    theta_h_bins,
)
from flashbrdf.slice_extract.segment.interreflection import merge_alike_slices, nonconvex_mask
from flashbrdf.slice_extract.segment.slices import (
    assign_all,
    material_slices,
    refine_labels,
    residuals,
)


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
    (BIC per K, merged K, residuals) that say why K was chosen."""
    labels: np.ndarray
    k: int
    criterion: dict


def merge_components(means, covariances, weights, separation, min_fraction, margins=None):
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


def cluster_samples(rho, theta_h, options=None, pixels=None, shape=None, at_least=0.0,
                    normals=None):
    """Material of each sample: (labels (N,) int 0..K-1, K, criterion dict).

    rho (N, 3) 1/sr, finite; theta_h (N,) radians. See the module docstring for the method.
    Materials and their slices are found on a random subsample of options.work_samples
    samples (all of them if there are fewer); then every sample goes to the material whose
    slice explains it best once a flash-coloured highlight term is taken off (assign_all).
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
    region's interreflection as the material it comes from (merge_alike_slices,
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
    return assign_all(rho, theta_h, pick, labels, k), k, criterion


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
    groups = merge_components(best.means_, best.covariances_, best.weights_,
                               options.separation, options.min_fraction, margins)
    criterion.update(bic={k + 1: b for k, b in enumerate(bic)}, bic_k=best.n_components,
                     merged_k=len(groups))
    if len(groups) == 1:
        return np.zeros(n, int), 1, criterion
    component_to_group = np.zeros(best.n_components, int)
    for g, members in enumerate(groups):
        component_to_group[members] = g
    labels = component_to_group[best.predict(x)]
    log_rho, _, floor = log_samples(rho)
    bins = theta_h_bins(theta_h)
    # the tests read the neighbours (same floor: one brightness scale for both); residual_one
    # in the criterion is then the neighbours' too. They read ln rho above the photo's
    # resolution floor when it is the higher: what a coarse photo does not resolve is no
    # evidence of a material (resolution_floor)
    test_floor = max(floor, at_least)
    criterion["resolution_floor"] = float(at_least)
    log_test, bins_test = (log_samples(rho, test_floor)[0], bins) if check is None else \
        (log_samples(check[0], test_floor)[0], theta_h_bins(check[1]))
    # how badly one slice for the whole object explains each sample (the explained test's base)
    single = residuals(log_test, bins_test,
                        material_slices(log_test, bins_test, np.zeros(n, int), 1))[:, 0]
    k = len(groups)
    for _ in range(options.max_materials):  # refine, merge look-alikes, until nothing merges
        labels, k = refine_labels(log_rho, bins, labels, k, options)
        labels, merged = merge_alike_slices(log_test, bins_test, labels, k, options,
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
        tested = residuals(log_test, bins_test, material_slices(log_test, bins_test, labels, k))
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
        residual = residuals(log_rho, bins, material_slices(log_rho, bins, labels, k))
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
    joint = material_slices(log_test[pair], bins_test[pair], np.zeros(int(pair.sum()), int), 1)
    theirs = labels == partner
    joint_residual = residuals(log_test[theirs], bins_test[theirs], joint)[:, 0]
    return float(own[theirs].mean() / max(joint_residual.mean(), 1e-12))
