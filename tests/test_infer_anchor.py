"""Slice anchoring (infer.anchoring.anchor_to_slice): what it guarantees and what smoothing buys."""

import numpy as np
import pytest

from flashbrdf.brdf.colour import FEATURE_OFFSET as E
from flashbrdf.infer.anchoring import anchor_to_slice


def _smooth_table():
    th, td = np.meshgrid(np.linspace(0, 1, 90), np.linspace(0, 1, 90), indexing="ij")
    base = 0.05 + 2.0 * np.exp(-th / 0.05) * (1 + td)        # a lobe over theta_h, rising in theta_d
    return np.stack([base, 0.5 * base, 0.25 * base], axis=-1)


@pytest.mark.parametrize("sigma", [0.0, 2.0])
def test_a_uniform_level_error_is_removed_everywhere(sigma):
    truth = _smooth_table()
    # A prediction off by one factor in (rho + e), the feature map's log space: the correction is
    # constant along theta_h, so smoothing leaves it exact and every theta_d is recovered.
    pred = (truth + E) * 2.0 - E
    fixed = anchor_to_slice(pred, truth[:, 0], smoothing_bins=sigma)
    np.testing.assert_allclose(fixed, truth, rtol=1e-12)


def test_without_smoothing_the_row_passes_through_the_slice_and_gaps_are_interpolated():
    truth = _smooth_table()
    pred = truth * np.linspace(0.5, 2.0, 90)[:, None, None]
    observed = truth[:, 0].copy()
    observed[30:33] = np.nan                                   # empty bins: missing, never zero
    fixed = anchor_to_slice(pred, observed, smoothing_bins=0.0)
    ok = np.isfinite(observed[:, 0])
    np.testing.assert_allclose(fixed[ok, 0], observed[ok], rtol=1e-12)
    assert np.all(fixed[30:33, 0] > 0.5 * truth[30:33, 0])    # zero would give e-sized values


def test_smoothing_keeps_a_one_bin_artefact_from_striping_every_theta_d():
    truth = _smooth_table()
    pred = truth.copy()
    pred[40, 0] = (truth[40, 0] + E) * 1.5 - E                  # a bump in the theta_d = 0 row only
    far = slice(30, 60)                                          # theta_d columns away from it
    ratio = lambda fixed: (fixed + E) / (truth + E)              # the correction's own (rho + e) scale
    stripe = ratio(anchor_to_slice(pred, truth[:, 0], smoothing_bins=0.0))[40, far]
    # Cancelling the bump bin by bin multiplies the whole row by 1/1.5 (in rho + e).
    assert np.max(np.abs(stripe - 1)) == pytest.approx(1 - 1 / 1.5, rel=1e-9)
    smooth = ratio(anchor_to_slice(pred, truth[:, 0], smoothing_bins=2.0))[:, far]
    # A Gaussian of 2 bins spreads ln 1.5 over ~5 bins: the peak is ln 1.5 / (2 sqrt(2 pi)) = 0.081.
    assert np.max(np.abs(np.log(smooth))) < 0.09


def test_past_the_observed_range_the_correction_is_held_or_faded(monkeypatch):
    # a prediction 2x too low in ln(1 + rho/e) terms where the slice is seen (bins 0-39)
    from flashbrdf.infer import anchoring
    first = np.full((90, 3), 0.1)
    observed = np.full((90, 3), np.nan)
    observed[:40] = 2 * (0.1 + E) - E
    held = anchoring.anchor_log_correction(first, observed, smoothing_bins=0)
    assert np.allclose(held, np.log(2.0))            # held: the last bin's ln 2 up to bin 89
    monkeypatch.setattr(anchoring, "ANCHOR_FADE_BINS", 3.0)
    faded = anchoring.anchor_log_correction(first, observed, smoothing_bins=0)
    assert np.allclose(faded[:40], np.log(2.0))      # the observed range is untouched
    # d bins past the last observed one: ln 2 exp(-d^2 / 18); at d = 3, exp(-1/2)
    assert np.isclose(faded[42, 0], np.log(2.0) * np.exp(-0.5))
    assert np.all(np.abs(faded[55:]) < 1e-6)


@pytest.mark.parametrize("sigma", [0.5, 2.0, 3.7, 10.0])
@pytest.mark.parametrize("rows", [1, 5, 90])
def test_smoothing_is_scipys_gaussian_filter_to_the_bit(sigma, rows):
    """anchoring's own Gaussian (no scipy.ndimage import at predict time) gives exactly
    gaussian_filter1d(mode="nearest"): same kernel, same order of the sums."""
    from scipy.ndimage import gaussian_filter1d

    from flashbrdf.infer.anchoring import gaussian_smooth_rows
    values = np.random.default_rng(rows).normal(size=(rows, 3)) * 37.0
    assert np.array_equal(gaussian_smooth_rows(values, sigma),
                          gaussian_filter1d(values, sigma, axis=0, mode="nearest"))
