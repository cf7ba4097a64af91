"""Per-pixel diffuse albedo for textured materials (printed or painted colour on one material).

Model: at a surface point x of material k,
    rho(x; wi, wo) = T_k(wi, wo) + delta(x),    delta(x) = A(x)/pi - f_k   (RGB, 1/sr)
where T_k is the material's BRDF, f_k its diffuse floor and A(x) the point's diffuse albedo: the
texture replaces the material's flat diffuse floor and leaves its specular lobe alone. So texture
is not forced into extra clusters, and a material of uniform colour gets delta ~ 0 (noise).

Estimate from the flash photo: each pixel's sample rho_obs(x) sits at theta_h(x), theta_d ~ 0,
where T_k reproduces the material's slice S_k(theta_h) (the per-bin median over its pixels), so
    delta(x) = rho_obs(x) - S_k(theta_h(x)),
clipped to >= -f_k (an albedo is not negative). f_k is the slice's floor over theta_h: per
channel, its minimum over bins with >= `floor_min_count` pixels (the same floor the Mitsuba
export's split_diffuse takes off a table). A residual is trusted only where the lobe is at most
`max_specular` times the floor: in a highlight it is ruled by how steep the lobe is (a small
normal error gives a large residual), not by the albedo. Trusted residuals are smoothed over
`smooth_px` pixels (normalised Gaussian convolution inside the material, so colours do not bleed
across material borders); the others (highlight, clipped, silhouette) take the smoothed value of
their neighbourhood at `fill_px`, and 0 (the material's own BRDF) where nothing is near.
"""

from dataclasses import dataclass

import numpy as np

from flashbrdf.brdf.angles import merl_bin_index
from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.slice_extract.segment.features import binned_median, fill_bins


@dataclass(frozen=True)
class AlbedoOptions:
    max_specular: float = 1.0    # trust a residual where S_k(theta_h) - f_k <= this x f_k
    smooth_px: float = 1.0       # Gaussian sigma of the trusted residuals, pixels
    fill_px: float = 8.0         # Gaussian sigma that fills untrusted pixels, pixels
    floor_min_count: int = 20    # pixels a theta_h bin needs to define the floor
    min_weight: float = 0.05     # normalised-convolution weight below which nothing is known


@dataclass(eq=False)
class AlbedoMap:
    """albedo (H, W, 3) float32: diffuse albedo A = pi (f_k + delta), 0 off the object;
    delta (H, W, 3) float32 1/sr; floors (K, 3) float64 1/sr, f_k of label k = 1..K;
    trusted (H, W) bool: pixels whose own residual was used."""
    albedo: np.ndarray
    delta: np.ndarray
    floors: np.ndarray
    trusted: np.ndarray


def _binned(values, bins, min_count):
    """Per-theta_h-bin median (N_THETA_H, 3) of values (N, 3), NaN below min_count."""
    return binned_median(values, bins, N_THETA_H, min_count)


def material_floor_and_slice(rho, theta_h, options=None):
    """(floor (3,), slice (N_THETA_H, 3)) of one material's samples rho (N, 3) 1/sr at theta_h
    (N,) rad: the per-bin median slice (empty bins filled along theta_h, flat at the ends) and
    its per-channel minimum over bins with >= floor_min_count samples (>= 3 if none has that
    many)."""
    options = options or AlbedoOptions()
    bins = merl_bin_index(theta_h, 0.0, 0.0)[0]
    median = _binned(rho, bins, 3)
    well = _binned(rho, bins, options.floor_min_count)
    ok = np.all(np.isfinite(well), axis=1)
    floor_from = well[ok] if ok.any() else median[np.all(np.isfinite(median), axis=1)]
    floor = (np.maximum(floor_from.min(axis=0), 0.0) if len(floor_from)
             else np.zeros(3))
    return floor, fill_bins(median)


def _normalised_blur(values, weight, sigma):
    """Gaussian normalised convolution: (blurred values (H, W, 3), blurred weight (H, W))."""
    import cv2
    if sigma <= 0:
        return values * weight[..., None], weight.copy()
    size = 2 * int(np.ceil(3 * sigma)) + 1
    num = cv2.GaussianBlur(values * weight[..., None], (size, size), sigma)
    den = cv2.GaussianBlur(weight, (size, size), sigma)
    return num, den


def estimate_albedo_map(samples, labels, options=None):
    """AlbedoMap of FlashSamples (the first flash photo's) and a label image (H, W) int 1..K
    in its pixel grid (0 = not the object); see the module docstring for the method."""
    options = options or AlbedoOptions()
    labels = np.asarray(labels)
    shape = tuple(labels.shape)
    k_max = int(labels.max())
    usable = ((samples.photo == 0) & ~samples.censored
              & np.all(np.isfinite(samples.rho), axis=1))
    pixels, rho, theta_h = samples.pixels[usable], samples.rho[usable], samples.theta_h[usable]
    of_sample = np.take(labels.ravel(), pixels)
    residual = np.zeros(shape + (3,), np.float32)
    trusted = np.zeros(shape, bool)
    floors = np.zeros((k_max, 3))
    for k in range(1, k_max + 1):
        mine = of_sample == k
        if mine.sum() < 3:
            continue
        floor, curve = material_floor_and_slice(rho[mine], theta_h[mine], options)
        floors[k - 1] = floor
        bins = merl_bin_index(theta_h[mine], 0.0, 0.0)[0]
        predicted = curve[bins]
        lobe = (predicted - floor).max(axis=1)
        ok = lobe <= options.max_specular * max(float(floor.max()), 1e-12)
        ok &= floor.max() > 0   # black or chrome: no diffuse floor to texture
        where = pixels[mine][ok]
        residual.reshape(-1, 3)[where] = np.maximum(rho[mine][ok] - predicted[ok], -floor)
        trusted.ravel()[where] = True
    delta = np.zeros(shape + (3,), np.float32)
    for k in range(1, k_max + 1):
        inside = labels == k
        weight = (trusted & inside).astype(np.float32)
        if not weight.any():
            continue
        near_num, near_den = _normalised_blur(residual, weight, options.smooth_px)
        far_num, far_den = _normalised_blur(residual, weight, options.fill_px)
        with np.errstate(invalid="ignore", divide="ignore"):
            near = near_num / near_den[..., None]
            far = far_num / far_den[..., None]
        value = np.where((trusted & inside)[..., None] & (near_den[..., None] > 0), near,
                         np.where(far_den[..., None] > options.min_weight, far, 0.0))
        value = np.maximum(np.nan_to_num(value), -floors[k - 1])
        delta[inside] = value[inside]
    on = labels > 0
    albedo = np.zeros(shape + (3,), np.float32)
    albedo[on] = np.maximum(np.pi * (floors[labels[on] - 1] + delta[on]), 0.0)  # rounding
    return AlbedoMap(albedo, delta, floors, trusted)


def face_means(image, face_image, n_faces):
    """Mean (F, C) of an image (H, W, C) over each mesh face's pixels (face_image (H, W) int,
    -1 none), and seen (F,) bool; unseen faces are 0."""
    image = image.reshape(len(face_image.ravel()), -1)
    seen = face_image.ravel() >= 0
    faces = face_image.ravel()[seen]
    count = np.bincount(faces, minlength=n_faces)
    out = np.zeros((n_faces, image.shape[1]), np.float64)
    for c in range(image.shape[1]):
        out[:, c] = np.bincount(faces, weights=image[seen, c], minlength=n_faces)
    has = count > 0
    out[has] /= count[has, None]
    return out, has
