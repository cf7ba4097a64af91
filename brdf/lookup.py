"""Evaluate a tabulated BRDF (MERL 3D or its 2D phi_d-average) at arbitrary angles."""

import numpy as np

from flashbrdf.brdf.angles import half_diff_from_world, merl_bin_coordinates, merl_bin_index
from flashbrdf.brdf.merl import N_PHI_D


def evaluate_table(table, theta_h, theta_d, phi_d, interpolate=False):
    """BRDF values (..., 3) in 1/sr of `table` at the given angles (radians, broadcastable).

    table: (90, 90, 180, 3) MERL table or (90, 90, 3) 2D table, NaN (or negative) = no data.
    Nearest-bin uses MERL's own indexing. Interpolation is (tri)linear between bin centres, wraps
    in phi_d (period pi) and averages over the neighbours that have data; no-data gives 0.
    """
    table = np.asarray(table)
    theta_h, theta_d, phi_d = np.broadcast_arrays(theta_h, theta_d, phi_d)
    is_3d = table.ndim == 4
    if not interpolate:
        i, j, k = merl_bin_index(theta_h, theta_d, phi_d)
        values = table[i, j, k] if is_3d else table[i, j]
        return np.where(np.isfinite(values) & (values > 0), values, 0.0)

    u_h, u_d, u_p = merl_bin_coordinates(theta_h, theta_d, phi_d)
    axes = [(u_h, table.shape[0], False), (u_d, table.shape[1], False)]
    if is_3d:
        axes.append((u_p, N_PHI_D, True))
    corners = []
    for u, size, periodic in axes:
        lo = np.floor(u)
        frac = u - lo
        lo = lo.astype(np.intp)
        hi = lo + 1
        if periodic:
            lo, hi = np.mod(lo, size), np.mod(hi, size)
        else:
            hi = np.minimum(hi, size - 1)
        corners.append(((lo, 1.0 - frac), (hi, frac)))

    total = np.zeros(theta_h.shape + (3,))
    weight = np.zeros(theta_h.shape + (1,))
    for bits in range(2 ** len(corners)):
        index, w = [], 1.0
        for axis, (lo, hi) in enumerate(corners):
            idx, wa = hi if (bits >> axis) & 1 else lo
            index.append(idx)
            w = w * wa
        values = table[tuple(index)]
        ok = np.all(np.isfinite(values) & (values >= 0), axis=-1, keepdims=True)
        w = w[..., None] * ok
        total += w * np.where(ok, values, 0.0)
        weight += w
    return np.where(weight > 0, total / np.maximum(weight, 1e-300), 0.0)


def evaluate_directions(table, wi, wo, normal, interpolate=False):
    """BRDF values (..., 3) in 1/sr for direction pairs about `normal` ((..., 3), any frame).

    Pairs with either direction at or below the horizon give 0.
    """
    wi, wo, normal = np.broadcast_arrays(wi, wo, normal)
    values = evaluate_table(table, *half_diff_from_world(wi, wo, normal), interpolate=interpolate)
    above = (np.einsum("...i,...i->...", wi, normal) > 0) & (np.einsum("...i,...i->...", wo, normal) > 0)
    return values * above[..., None]
