"""Per-bin uncertainty, its calibration, the novelty warning, the estimator contract of the DS-GPLVM
adapter and the relative representation, on synthetic Ashikhmin–Premože materials whose tables are
known (tests/test_infer_baselines.py builds them on MERL bin centres)."""

import numpy as np
import pytest

from flashbrdf.infer import (DSGPLVMMethod, RelativeDSGPLVMMethod, method_from_model,
                             novelty_warning, prediction_warning)
from flashbrdf.infer.adapter import slice_features
from flashbrdf.infer.uncertainty import calibration_factor, mixture_spread, weights_disagreement
from flashbrdf.infer.relative import channel_levels, from_ratio, ratio_field
from flashbrdf.infer.slices import fill_slice
from tests.test_infer_baselines import coloured_ap_set


@pytest.fixture(scope="module")
def materials():
    return coloured_ap_set(7, [(0.08, 0.04, 0.1), (0.2, 0.5, 0.3), (0.35, 0.1, 0.02),
                               (0.5, 0.9, 0.5), (0.15, 0.2, 0.05), (0.7, 0.05, 0.8),
                               (0.25, 0.3, 0.2), (0.12, 0.06, 0.4), (0.45, 0.15, 0.1)])


@pytest.fixture(scope="module")
def fitted(materials):
    return DSGPLVMMethod(max_cycles=3, anchor=True, feature_space="rgb").fit(materials.subset(range(7)))


def test_variance_is_per_bin_and_scales_with_calibration(fitted, materials):
    table, var = fitted.predict(materials.slices[7], "2d")
    valid = np.isfinite(materials.tables_2d[7]).all(-1)
    assert var.shape == (90, 90, 3) and np.isfinite(var[valid]).all() and (var[valid] > 0).all()
    # per bin, not one number per view: the leave-one-out shape varies over (θh, θd)
    assert np.nanstd(var) / np.nanmean(var) > 0.1
    # κ multiplies the variance and nothing else
    scaled = method_from_model("dsgplvm", fitted.model_, materials.subset(range(7)),
                               **(fitted.get_params() | {"calibration": 4.0}))
    table4, var4 = scaled.predict(materials.slices[7], "2d")
    np.testing.assert_array_equal(table4, table)
    np.testing.assert_allclose(var4[valid], 4.0 * var[valid], rtol=1e-12)


def test_calibration_factor_undoes_a_known_miscalibration(fitted, materials):
    held = [7, 8]
    kappa = calibration_factor(fitted, materials.slices[held], materials.tables_2d[held])
    assert np.isfinite(kappa) and kappa > 0
    # z ∝ 1/sqrt(κ): a method already scaled by c needs κ/c, exactly (same residuals)
    scaled = method_from_model("dsgplvm", fitted.model_, materials.subset(range(7)),
                               **(fitted.get_params() | {"calibration": 3.0}))
    again = calibration_factor(scaled, materials.slices[held], materials.tables_2d[held])
    assert again == pytest.approx(kappa / 3.0, rel=1e-9)
    calibrated = method_from_model("dsgplvm", fitted.model_, materials.subset(range(7)),
                               **(fitted.get_params() | {"calibration": kappa}))
    # after calibration, the 90% quantile of |z| on the same bins is the normal one: κ becomes 1
    assert calibration_factor(calibrated, materials.slices[held],
                              materials.tables_2d[held]) == pytest.approx(1.0, rel=1e-9)


def test_novelty_is_zero_on_training_slices_and_warns_off_them(fitted, materials):
    score, warning = novelty_warning(fitted, materials.slices[0])
    assert score < 1e-6 and warning is None
    th = np.linspace(0, 1, 90)[:, None]
    chrome = 10 ** (np.log10(4e3) - (np.log10(4e3) + 3) * th) * np.ones((1, 3))
    one_bin = np.full((90, 3), np.nan)
    one_bin[40] = 0.1
    grazing = np.full((90, 3), np.nan)
    grazing[80:] = 0.05                                   # only θh > 70° observed
    valid = np.isfinite(materials.tables_2d[0]).all(-1)
    for s in (chrome, np.zeros((90, 3)), one_bin, grazing):
        record, warning = prediction_warning(fitted, s, "s.csv")
        # far from every training slice: recorded; a slice that says too little: warned
        # (infer.warning; the consensus' disagreement is tested in test_infer_consensus.py)
        if s is one_bin or s is grazing:
            assert warning.startswith("warning: s.csv:") and "\n" not in warning
        else:
            assert record["beyond_training"]
        table, var = fitted.predict(s, "2d")
        assert np.isfinite(table[valid]).all() and np.isfinite(var[valid]).all()


def test_refit_on_other_data_equals_a_fresh_fit(materials):
    # fit() must not keep the first data set's model: fit(A) then fit(B) == fresh fit(B)
    a, b = materials.subset(range(5)), materials.subset(range(3, 9))
    method = DSGPLVMMethod(max_cycles=2, feature_space="rgb")
    before = method.get_params()
    method.fit(a)
    assert method.get_params() == before                  # the constructor arguments are untouched
    refit = method.fit(b).predict(materials.slices[2], "2d")[0]
    fresh = DSGPLVMMethod(max_cycles=2, feature_space="rgb").fit(b).predict(materials.slices[2],
                                                                            "2d")[0]
    np.testing.assert_allclose(refit, fresh, rtol=1e-12, equal_nan=True)


def test_relative_representation_round_trips_and_anchors_exactly(materials):
    table = materials.tables_2d[4]
    levels = channel_levels(table[:, 0])
    filled = fill_slice(table[:, 0])
    ratio = np.moveaxis(ratio_field(table, filled, levels).reshape(3, 90, 90), 0, -1)
    # the inverse of the representation is exact up to float round-off
    np.testing.assert_allclose(from_ratio(ratio, filled, levels), table, rtol=1e-9, atol=1e-15)
    assert np.all(np.abs(ratio[:, 0]) < 1e-12)            # θd = 0 is the slice itself
    method = RelativeDSGPLVMMethod(max_cycles=2).fit(materials.subset(range(7)))
    pred, var = method.predict(materials.slices[8], "2d")
    # every training ratio row is 0 at θd = 0, so the prediction's θd = 0 row is the observation
    np.testing.assert_allclose(pred[:, 0], materials.slices[8], rtol=1e-9)
    assert var.shape == (90, 90, 3) and np.isfinite(pred[np.isfinite(materials.tables_2d[8])]).all()


def test_mixture_spread_is_the_weighted_variance_of_the_combined_rows():
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(6, 40))
    w = rng.dirichlet(np.ones(6))
    mean = w @ rows
    np.testing.assert_allclose(mixture_spread(w, rows), w @ (rows - mean) ** 2, rtol=1e-10, atol=1e-12)
    # all weight on one row: that row is the prediction, nothing spreads
    np.testing.assert_allclose(mixture_spread(np.eye(6)[2], rows), 0.0, atol=1e-12)
    # GP weights may be negative: |w| weighs the spread around the (signed) prediction
    signed = np.array([1.5, -0.5, 0, 0, 0, 0])
    mean = signed @ rows
    expect = (0.75 * (rows[0] - mean) ** 2 + 0.25 * (rows[1] - mean) ** 2)
    np.testing.assert_allclose(mixture_spread(signed, rows), expect, rtol=1e-10)


def test_weights_disagreement_is_the_two_point_variance():
    rows = np.array([[0.0, 2.0], [4.0, 2.0]])
    # GP all on row 0, fit all on row 1: estimates {0, 4} in column 0, weights 1/2 each: variance 4
    np.testing.assert_allclose(weights_disagreement([1, 0], [0, 1], rows, 0.5), [4.0, 0.0])
    np.testing.assert_allclose(weights_disagreement([1, 0], [0, 1], rows, 0.25), [3.0, 0.0])
    assert (weights_disagreement([0.3, 0.7], [0.3, 0.7], rows, 0.5) == 0).all()


def test_anchored_variance_adds_the_combination_terms_and_the_paper_keeps_the_gp_alone(fitted, materials):
    # the DS-GPLVM's own variance: the consensus' spread (tests/test_infer_consensus.py) left out
    fitted = method_from_model("dsgplvm", fitted.model_, materials.subset(range(7)),
                               **(fitted.get_params() | {"consensus": False}))
    rho = materials.slices[7]
    _, var = fitted.predict(rho, "2d")
    parts = fitted._weight_parts(slice_features(rho, fitted.feature_space), "2d")
    extra = fitted._combination_variance(parts)
    assert extra is not None and (extra >= 0).all() and extra.max() > 0
    paper = method_from_model("dsgplvm", fitted.model_, materials.subset(range(7)),
                              **(fitted.get_params() | {"anchor": False}))
    assert paper._combination_variance(parts) is None
    _, var_paper = paper.predict(rho, "2d")
    nov = max(1.0, fitted.novelty(rho)) ** 2
    gp_only = fitted.bin_variance(parts[1]) * nov
    valid = np.isfinite(var_paper)
    # the paper's variance is the GP term alone; the anchored one exceeds it by exactly the extra
    np.testing.assert_allclose(var_paper[valid], gp_only[valid], rtol=1e-10)
    np.testing.assert_allclose((var - gp_only)[valid].sum(),
                               fitted.calibration * nov * extra.sum(), rtol=1e-8)
