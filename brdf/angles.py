"""Rusinkiewicz angles and MERL's bin indices of them.

The conversions between direction pairs and (theta_h, theta_d, phi_d) live in brdf.rusinkiewicz
(re-exported here, where callers have always found them); this module maps those angles to MERL's
(90, 90, 180) bins: merl_bin_index (MERL's own clamped indices), merl_bin_coordinates (continuous,
for interpolation) and merl_flat_index_local (the render hot path: local directions straight to
flat bins). All angles are radians.
"""

import numpy as np

from flashbrdf.brdf.merl import N_PHI_D, N_THETA_D, N_THETA_H, theta_h_bin_coordinate
from flashbrdf.brdf.rusinkiewicz import (cos_in_out, half_diff_from_local, half_diff_from_world,  # noqa: F401
                               half_diff_thetas, local_from_half_diff, phi_h_from_local)


def check_finite(*arrays, what="directions"):
    """ValueError when any array holds NaN or inf: a bin index cast from NaN points anywhere."""
    for a in arrays:
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what} hold NaN or inf: no MERL bin is defined there")


def merl_bin_index(theta_h, theta_d, phi_d):
    """MERL's own bin indices (i, j, k) as int arrays, clamped as in its BRDFRead.cpp.

    theta_h uses square-root spacing, theta_d and phi_d 1-degree bins; phi_d is folded into [0, pi).
    """
    theta_h = np.asarray(theta_h, dtype=np.float64)
    check_finite(theta_h, theta_d, phi_d, what="angles")
    i = theta_h_bin_coordinate(np.clip(theta_h, 0, None))
    j = np.asarray(theta_d, dtype=np.float64) / (np.pi / 2) * N_THETA_D
    k = np.mod(np.asarray(phi_d, dtype=np.float64), np.pi) / np.pi * N_PHI_D
    return (np.clip(i, 0, N_THETA_H - 1).astype(np.intp),
            np.clip(j, 0, N_THETA_D - 1).astype(np.intp),
            np.clip(k, 0, N_PHI_D - 1).astype(np.intp))


def merl_bin_coordinates(theta_h, theta_d, phi_d):
    """Continuous bin coordinates (u_h, u_d, u_p) where integer values are bin centres.

    u_h and u_d are clamped to [0, 89]; u_p is in [-0.5, 179.5) and periodic with period 180.
    """
    check_finite(theta_h, theta_d, phi_d, what="angles")
    u_h = theta_h_bin_coordinate(np.clip(np.asarray(theta_h, dtype=np.float64), 0, None)) - 0.5
    u_d = np.degrees(np.asarray(theta_d, dtype=np.float64)) - 0.5
    u_p = np.mod(np.degrees(np.asarray(phi_d, dtype=np.float64)), 180.0) - 0.5
    return (np.clip(u_h, 0, N_THETA_H - 1), np.clip(u_d, 0, N_THETA_D - 1), u_p)


def merl_flat_index_local(wi, wo, three_d=True):
    """Flat MERL bin index (...) of local-frame pairs: ((i * 90) + j) * 180 + k, or i * 90 + j.

    Hot-path copy of merl_bin_index(*half_diff_from_local(wi, wo)) for rendering: the same
    half-vector frame, phi_d folded into [0, pi), fixed tangent at theta_h = 0, and MERL's clamped
    indexing, in fewer array passes (tests/test_render_brdf.py checks they agree; at theta_d = 0
    exactly phi_d is undefined and the bin may differ, see brdf.rusinkiewicz).
    """
    # np.clip and np.mod are several times slower than minimum/maximum/where here.
    h = wi + wo
    h = h / np.maximum(np.sqrt(np.einsum("...k,...k->...", h, h)), 1e-300)[..., None]
    hx, hy, hz = h[..., 0], h[..., 1], h[..., 2]
    sin_h = np.sqrt(hx * hx + hy * hy)
    theta_h = np.arctan2(sin_h, hz)
    # brdf.merl.theta_h_bin_coordinate, specialised (tests/test_render_brdf.py checks they agree)
    i = np.minimum(np.sqrt(theta_h * (180.0 / np.pi)) * (90.0 / np.sqrt(90.0)), 89.0)
    cos_d = np.minimum(np.maximum(np.einsum("...k,...k->...", wi, h), -1.0), 1.0)
    j = np.minimum(np.arccos(cos_d) * (180.0 / np.pi), 89.0)
    if not three_d:
        return i.astype(np.intp) * 90 + j.astype(np.intp)
    safe = sin_h > 1e-12
    inv = 1.0 / np.where(safe, sin_h, 1.0)
    px = np.where(safe, hx * inv, 1.0)
    py = np.where(safe, hy * inv, 0.0)
    wx, wy, wz = wi[..., 0], wi[..., 1], wi[..., 2]
    along_t = hz * (wx * px + wy * py) - sin_h * wz
    along_b = wy * px - wx * py
    phi_d = np.arctan2(along_b, along_t)
    phi_d = np.where(phi_d < 0.0, phi_d + np.pi, phi_d)   # fold into [0, pi)
    k = np.minimum(phi_d * (180.0 / np.pi), 179.0)
    return (i.astype(np.intp) * 90 + j.astype(np.intp)) * 180 + k.astype(np.intp)
