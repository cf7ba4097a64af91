"""Flash slices as every method takes them: checked, and filled where a method needs every bin.

A flash slice is ρ(θh) at θd bin 0 in 1/sr, shape (90, 3) over MERL's θh bins (brdf.merl), NaN
where the bin is empty (missing data, never 0).
"""

import numpy as np

from brdf.errors import InputError
from brdf.merl import N_THETA_H


def check_slice(flash_slice):
    """Validate a flash slice: (90, 3) float, finite or NaN, ≥ 0. Returns float64 copy. InputError."""
    rho = np.array(flash_slice, dtype=float)
    if rho.shape != (N_THETA_H, 3):
        raise InputError("slice", f"expected {N_THETA_H} theta_h bins x 3 channels, got shape "
                                  f"{rho.shape}")
    if np.isinf(rho).any():
        raise InputError("slice", "infinite BRDF value")
    if (rho < 0).any():
        raise InputError("slice", "negative BRDF value")
    if not np.isfinite(rho).all(axis=1).any():
        raise InputError("slice", "no theta_h bin has a sample")
    rho[~np.isfinite(rho).all(axis=1)] = np.nan
    return rho


def fill_slice(rho, offset=1e-3):
    """Fill empty θh bins of a checked slice by linear interpolation of ln(1 + ρ/offset) over the bin
    index (nearest value beyond the ends). For methods that need ρ at every θh; (90, 3) -> (90, 3)."""
    ok = np.isfinite(rho).all(axis=1)
    if ok.all():
        return rho.copy()
    idx = np.arange(N_THETA_H)
    out = np.empty_like(rho)
    for c in range(3):
        out[:, c] = np.interp(idx, idx[ok], np.log1p(rho[ok, c] / offset))
    return np.expm1(out) * offset
