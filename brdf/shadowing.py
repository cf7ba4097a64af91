"""The microfacet shadowing/normalisation term over MERL's bins, shared by the Ashikhmin–Premože
baseline (infer.baselines.ashikhmin) and the observed-row blend (infer.row_blend).

Ashikhmin & Premože's distribution-based BRDF divides the half-vector distribution by
D(θh, θd, φd) = 4 (cos θi + cos θo − cos θi cos θo) (> 0 above the horizon). For a fixed θh it is
what changes when the light and the eye move apart (θd > 0): a flash slice sees it only at θd = 0.
"""

import functools


from flashbrdf.brdf.bins import cos_in_out_valid, mean_over_phi_d, valid_bins_3d


def denominator(cos_i, cos_o):
    """The shadowing/normalisation denominator 4 (cos θi + cos θo − cos θi cos θo), broadcasting."""
    return 4.0 * (cos_i + cos_o - cos_i * cos_o)


@functools.lru_cache(maxsize=1)
def inverse_denominator():
    """(1/D on the valid 3D bins (n_valid,), ⟨1/D⟩ over φd at θd bin 0 per θh (90,), the φd-mean
    of 1/D (90, 90)); D dimensionless."""
    inv_d = 1.0 / denominator(*cos_in_out_valid())
    inv_d_2d = mean_over_phi_d(inv_d)
    return inv_d, inv_d_2d[:, 0], inv_d_2d


@functools.lru_cache(maxsize=1)
def geometry_ratio_valid():
    """(n_valid,) ⟨1/D⟩ ratio of each valid 3D bin to its θh's θd = 0 bin: how a microfacet BRDF
    with a fixed distribution changes away from the flash configuration (Fresnel left out)."""
    inv_d, inv_d0, _ = inverse_denominator()
    ratio = inv_d / inv_d0[valid_bins_3d()[0]]
    ratio.flags.writeable = False      # cached and shared by every 3D blend
    return ratio


@functools.lru_cache(maxsize=1)
def geometry_ratio_2d():
    """(90, 90) the φd-mean of geometry_ratio_valid per (θh, θd), NaN where no φd bin is valid."""
    _, inv_d0, inv_d_2d = inverse_denominator()
    ratio = inv_d_2d / inv_d0[:, None]
    ratio.flags.writeable = False
    return ratio
