"""Colour transforms and the paper's BRDF feature map.

CIELAB here is colour-science's `RGB_to_XYZ` (linear sRGB, no decoding, no adaptation) followed by
`XYZ_to_Lab` with the D65 white at Y = 1, as the contract fixes. The same arithmetic is done with
colour-science's matrix and white written out (SRGB_TO_XYZ, D65_WHITE_XYZ), because the 3D tables
have 4.4 M bins and the metrics run over hundreds of them; tests check it against colour-science.
"""

import functools

import numpy as np

FEATURE_OFFSET = 1e-3  # 1/sr; see rho_to_features

_DELTA = 6.0 / 29.0


# colour-science's sRGB RGB->XYZ matrix (the IEC 61966-2-1 one, as its RGB_COLOURSPACES["sRGB"]
# gives it) and its D65 white XYZ (Y = 1), written out: importing colour-science for them cost
# every `run` ~0.6 s of CPU. A test checks they equal colour-science's to the last bit.
SRGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805],
                        [0.2126, 0.7152, 0.0722],
                        [0.0193, 0.1192, 0.9505]], dtype=np.float64)
D65_WHITE_XYZ = np.array([0.9504559270516716, 1.0, 1.0890577507598784], dtype=np.float64)


@functools.lru_cache(maxsize=1)
def _srgb_matrices():
    return SRGB_TO_XYZ, np.linalg.inv(SRGB_TO_XYZ), D65_WHITE_XYZ


def srgb_encode(linear):
    """The sRGB transfer curve (IEC 61966-2-1): linear values in [0, 1] -> encoded [0, 1], any
    shape. For display only; every colour metric here works on linear values."""
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def linear_rgb_to_lab(rgb):
    """CIELAB (..., 3) of linear sRGB triplets (..., 3); white (1, 1, 1) -> L = 100.

    Negative inputs follow the CIE function's linear segment, so the map is defined (and
    invertible) on all of R^3. Channels are combined one at a time: a (N, 3) @ (3, 3) product
    and a two-branch np.where are ten times slower on the 3.3 M values (1.1 M bins) of a 3D table.
    float32 input stays float32 (and keeps its memory layout); anything else is computed in float64.
    """
    rgb_to_xyz, _, white = _srgb_matrices()
    rgb = np.asarray(rgb)
    dtype = np.float32 if rgb.dtype == np.float32 else np.float64
    rgb = rgb.astype(dtype, copy=False)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    f = []
    for i in range(3):
        m = (rgb_to_xyz[i] / white[i]).astype(dtype)
        t = m[0] * r
        t += m[1] * g
        t += m[2] * b
        ft = np.asarray(np.cbrt(t))  # 0-d for a single triplet: still assignable
        small = t <= _DELTA ** 3
        if small.any():
            ft[small] = t[small] / dtype(3 * _DELTA ** 2) + dtype(4.0 / 29.0)
        f.append(ft)
    lab = np.empty_like(rgb)
    lab[..., 0] = 116.0 * f[1] - 16.0
    lab[..., 1] = 500.0 * (f[0] - f[1])
    lab[..., 2] = 200.0 * (f[1] - f[2])
    return lab


def lab_to_linear_rgb(lab):
    """Linear sRGB (..., 3) of CIELAB triplets (..., 3); the inverse of linear_rgb_to_lab."""
    _, xyz_to_rgb, white = _srgb_matrices()
    lab = np.asarray(lab, dtype=np.float64)
    fy = (lab[..., 0] + 16.0) / 116.0
    f = np.stack([fy + lab[..., 1] / 500.0, fy, fy - lab[..., 2] / 200.0], axis=-1)
    t = np.where(f > _DELTA, f ** 3, 3 * _DELTA ** 2 * (f - 4.0 / 29.0))
    return (t * white) @ xyz_to_rgb.T


def rho_to_features(rho, space="lab"):
    """The paper's feature map of BRDF values: natural log, then CIELAB. (..., 3) -> (..., 3).

    The log is ln(1 + rho / FEATURE_OFFSET) with FEATURE_OFFSET = 1e-3 1/sr: it is finite and 0 for
    rho = 0 (black materials), and ln(rho) + 6.9 for rho >> 1e-3, so chrome's six decades map to a
    range of about 16. space="rgb" skips the CIELAB step (the log-RGB ablation). NaN propagates.
    float32 input gives float32 features (the 3D streaming path); anything else float64.
    """
    rho = np.asarray(rho)
    dtype = np.float32 if rho.dtype == np.float32 else np.float64
    log_rgb = np.maximum(rho.astype(dtype, copy=True), 0.0)   # maximum keeps NaN
    log_rgb *= dtype(1.0 / FEATURE_OFFSET)
    np.log1p(log_rgb, out=log_rgb)
    if space == "rgb":
        return log_rgb
    if space != "lab":
        raise ValueError(f"unknown feature space {space!r}")
    return linear_rgb_to_lab(log_rgb)


def features_to_rho(features, space="lab"):
    """BRDF values (..., 3) in 1/sr from features; the inverse of rho_to_features, clamped >= 0."""
    log_rgb = np.asarray(features, dtype=np.float64)
    if space == "lab":
        log_rgb = lab_to_linear_rgb(log_rgb)
    elif space != "rgb":
        raise ValueError(f"unknown feature space {space!r}")
    return np.maximum(FEATURE_OFFSET * np.expm1(np.minimum(log_rgb, 700.0)), 0.0)
