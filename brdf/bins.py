"""MERL bin geometry on the valid bins: which (θh, θd, φd) bins hold data, the light/view cosines
at their centres, and the maps between per-valid-bin values and whole tables.

Tables follow brdf.merl: 3D (90, 90, 180, ...) over (θh, θd, φd), 2D (90, 90, ...) over (θh, θd);
"valid" bins are those of merl_valid_mask() (both directions above the horizon), 1,096,216 of them,
in C order of the 3D table. Angles in radians at bin centres; cosines dimensionless.
"""

import functools

import numpy as np

from flashbrdf.brdf.merl import (MERL_SHAPE, N_PHI_D, N_THETA_D, N_THETA_H, merl_valid_mask, phi_d_centres,
                       theta_d_centres, theta_h_centres)
from flashbrdf.brdf.rusinkiewicz import cos_in_out


@functools.lru_cache(maxsize=1)
def valid_bins_3d():
    """Flat indices of MERL's valid 3D bins: (ih, id, kd) int arrays, each (n_valid,) (1,096,216)."""
    ih, jd, kd = np.nonzero(merl_valid_mask())
    return ih.astype(np.int16), jd.astype(np.int16), kd.astype(np.int16)


@functools.lru_cache(maxsize=1)
def valid_flat_3d():
    """valid_bins_3d() as flat indices phi_d + 180*(theta_d + 90*theta_h), (n_valid,) int64."""
    ih, jd, kd = (b.astype(np.int64) for b in valid_bins_3d())
    return kd + N_PHI_D * (jd + N_THETA_D * ih)


@functools.lru_cache(maxsize=1)
def valid_mask_2d():
    """(90, 90) bool: (θh, θd) bins with at least one valid φd bin."""
    return merl_valid_mask().any(axis=2)


@functools.lru_cache(maxsize=1)
def cos_in_out_valid():
    """cos θi, cos θo at every valid 3D bin centre, each (n_valid,) float64."""
    ih, jd, kd = valid_bins_3d()
    return cos_in_out(theta_h_centres()[ih], theta_d_centres()[jd], phi_d_centres()[kd])


def mean_over_phi_d(values_valid):
    """Mean over valid φd bins of per-valid-bin values (n_valid, ...) -> (90, 90, ...), NaN where none."""
    ih, jd, _ = valid_bins_3d()
    flat = ih.astype(np.int64) * N_THETA_D + jd
    n_2d = N_THETA_H * N_THETA_D
    rest = values_valid.shape[1:]
    columns = values_valid.reshape(len(flat), -1)
    count = np.bincount(flat, minlength=n_2d).astype(float)
    out = np.full((n_2d, columns.shape[1]), np.nan)
    seen = count > 0
    for c in range(columns.shape[1]):
        out[seen, c] = np.bincount(flat, columns[:, c], minlength=n_2d)[seen] / count[seen]
    return out.reshape((N_THETA_H, N_THETA_D) + rest)


def scatter_valid(values_valid):
    """(n_valid, 3) values on valid bins -> (90, 90, 180, 3) table, NaN elsewhere."""
    table = np.full(MERL_SHAPE + (3,), np.nan)
    ih, jd, kd = valid_bins_3d()
    table[ih, jd, kd] = values_valid
    return table
