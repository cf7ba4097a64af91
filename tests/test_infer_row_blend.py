"""The observed-row blend (infer.row_blend): exact at θd = 0, gone at grazing θd, missing bins kept."""

import numpy as np

from flashbrdf.brdf.colour import FEATURE_OFFSET as E
from flashbrdf.brdf.bins import cos_in_out_valid, scatter_valid, valid_bins_3d
from flashbrdf.brdf.shadowing import denominator
from flashbrdf.brdf.views import table_2d, table_3d_from_2d
from flashbrdf.infer.row_blend import RowBlendSpace, blend_toward_row, row_weights


def _table():
    th, td = np.meshgrid(np.linspace(0, 1, 90), np.linspace(0, 1, 90), indexing="ij")
    base = 0.05 + 2.0 * np.exp(-th / 0.05) * (1 + td)        # a lobe over theta_h, rising in theta_d
    return np.stack([base, 0.5 * base, 0.25 * base], axis=-1)


def test_row_passes_through_the_slice_and_grazing_theta_d_keeps_the_prediction():
    truth = _table()
    pred = (truth + E) * 3.0 - E                              # off by ln 3 in the log features
    out = blend_toward_row(pred, truth[:, 0])
    gap = np.log((out + E) / (truth + E))                     # what is left of the ln 3 error
    w = row_weights()
    # ln(out + e) = ln(pred + e) − w·ln 3 + w·ln(row/truth(θd)); at θd = 0.5° the row is the truth
    np.testing.assert_allclose(gap[:, 0], (1 - w[0]) * np.log(3.0), rtol=1e-9)
    assert w[0] > 0.999                                       # exp(−0.5·(0.5/20)²)
    # past θd = 60° the weight is < 0.011: the prediction's ln 3 gap stays within 1.1% of itself
    far = np.degrees(np.deg2rad(np.arange(90) + 0.5)) > 60
    assert np.all(np.abs(gap[:, far] - np.log(3.0)) < 0.011 * np.log(3.0) + np.abs(
        np.log((truth[:, :1] + E) / (truth[:, far] + E))) * 0.011)


def test_missing_slice_bins_keep_the_prediction_and_zero_scale_is_the_identity():
    truth = _table()
    pred = truth * 2.0
    observed = truth[:, 0].copy()
    observed[30:60] = np.nan
    out = blend_toward_row(pred, observed)
    np.testing.assert_allclose(out[30:60], pred[30:60], rtol=1e-12)   # w = 0 on unobserved bins
    assert np.abs(out[:30, 0] / truth[:30, 0] - 1).max() < 2e-3      # observed: (1 − w(0.5°))·ln 2
    np.testing.assert_allclose(blend_toward_row(pred, observed, scale_deg=0), pred, rtol=1e-12)


def test_the_3d_space_blends_like_the_2d_table():
    truth2d = _table()
    pred2d = truth2d * 1.7
    ih, jd, kd = valid_bins_3d()
    observed = truth2d[:, 0].copy()
    observed[10:20] = np.nan
    space = RowBlendSpace(_Identity(), observed)
    sel = slice(0, 5000)
    got = space.inverse(pred2d[ih[sel], jd[sel]], sel)
    want = blend_toward_row(table_3d_from_2d(pred2d), observed)[ih[sel], jd[sel], kd[sel]]
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_a_microfacet_brdf_is_its_own_row_extension():
    """ρ = p(θh)/D(θh, θd, φd) (a fixed distribution, no Fresnel): its flash slice extended by the
    geometry ratio is ρ itself, so blending any prediction toward it with full weight gives ρ."""
    ih, jd, kd = valid_bins_3d()
    p = 0.02 + 3.0 * np.exp(-np.arange(90) / 6.0)                  # a lobe over θh, 1/sr
    rho_valid = (p[ih] / denominator(*cos_in_out_valid()))[:, None] * [1.0, 0.6, 0.3]
    truth = scatter_valid(rho_valid)
    flash_slice = np.nanmean(truth[:, 0], axis=1)                   # the φd-mean at θd bin 0
    # τ = 10⁶ deg: 1 − w ≤ θd²/2τ² = 4·10⁻⁹ at 90°, so the ln 5 error leaves < 7·10⁻⁹ of itself
    out = blend_toward_row(truth * 5.0, flash_slice, scale_deg=1e6)
    np.testing.assert_allclose(out[ih, jd, kd], rho_valid, rtol=1e-8)
    # in 2D the target is the φd-mean of the 3D one: the 2D table of ρ
    out_2d = blend_toward_row(table_2d(truth) * 5.0, flash_slice, scale_deg=1e6)
    np.testing.assert_allclose(out_2d, table_2d(truth), rtol=1e-8)


class _Identity:
    clip_to_training = False

    def forward(self, rho, sel=slice(None)):
        return rho

    def inverse(self, mapped, sel=slice(None)):
        return mapped
