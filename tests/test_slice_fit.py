"""Slice-fit weights (infer.slice_fit) and their use in the DS-GPLVM's prediction: known mixtures are
recovered, the weights stay convex off the training hull, a material that is an exact mixture of
training materials is predicted exactly when the weights come from the fit alone, and a slice past
the out-of-training threshold is predicted by the fit alone."""

import numpy as np
import pytest

from flashbrdf.brdf import colour
from flashbrdf.infer import DSGPLVMMethod
from flashbrdf.infer.adapter import table_features
import flashbrdf.infer.adapter
from flashbrdf.infer.slice_fit import (OUT_OF_TRAINING_NOVELTY, convex_slice_weights, mixed_weights,
                             slice_fit_share)
from tests.test_infer_baselines import SIX_AP_SPECS, coloured_ap_set


def test_a_convex_mixture_of_training_rows_is_recovered_with_missing_dimensions():
    rows = np.random.default_rng(3).normal(size=(12, 40))
    target = 0.3 * rows[2] + 0.7 * rows[5]
    target[[0, 7, 19]] = np.nan                                  # unobserved: left out of the fit
    w = convex_slice_weights(rows, target)
    # 12 generic rows in 37 observed dimensions: the mixture is the unique exact fit; the
    # sum-to-one row (weight 1e3) holds Σw = 1 to ~1e-7
    want = np.zeros(12)
    want[[2, 5]] = 0.3, 0.7
    np.testing.assert_allclose(w, want, atol=1e-6)


def test_off_the_hull_the_weights_are_the_nearest_convex_point():
    rows = np.array([[0.0, 0.0], [2.0, 0.0]])
    w = convex_slice_weights(rows, np.array([0.5, 3.0]))         # projects onto the segment at x = 0.5
    np.testing.assert_allclose(w, [0.75, 0.25], atol=1e-6)
    w = convex_slice_weights(rows, np.array([-4.0, 1.0]))        # beyond an end: all on that row
    np.testing.assert_allclose(w, [1.0, 0.0], atol=1e-6)
    assert (convex_slice_weights(rows, np.array([np.nan, np.nan])) == 0.5).all()  # nothing seen
    np.testing.assert_allclose(mixed_weights([1.0, 0.0], [0.0, 1.0], 0.25), [0.75, 0.25])


def test_near_duplicate_training_rows_share_the_weight_and_stay_finite():
    rows = np.random.default_rng(4).normal(size=(6, 30))
    rows = np.vstack([rows, rows[1] + 1e-12])                    # a near-duplicate of row 1
    w = convex_slice_weights(rows, rows[1])
    assert np.isfinite(w).all() and (w >= 0).all() and w.sum() == pytest.approx(1.0, abs=1e-6)
    assert w[1] + w[6] == pytest.approx(1.0, abs=1e-6)


@pytest.fixture(scope="module")
def materials():
    return coloured_ap_set(11, SIX_AP_SPECS)


def test_a_material_mixed_from_training_materials_is_predicted_exactly_by_the_fit(materials):
    """A test table whose log-RGB features are 0.4·(material 1) + 0.6·(material 4): with λ = 1 the
    prediction is that mixture of the training tables, i.e. the truth (anchoring then changes
    nothing: the θd = 0 row already passes through the slice; the row blend and the consensus
    are off)."""
    feats = table_features(materials.tables_2d, "rgb").reshape(-1, 90, 90, 3)
    mixed = colour.features_to_rho(0.4 * feats[1] + 0.6 * feats[4], space="rgb")
    mixed[~np.isfinite(materials.tables_2d[0]).all(-1)] = np.nan
    flash_slice = mixed[:, 0]
    method = DSGPLVMMethod(max_cycles=3, anchor=True, feature_space="rgb", slice_fit=1.0,
                           row_blend_deg=0.0, consensus=False).fit(materials)
    pred, _ = method.predict(flash_slice, "2d")
    ok = np.isfinite(mixed).all(-1)
    # NNLS to ~1e-7 in the weights, times features of O(10): ρ within 1e-5 relative
    np.testing.assert_allclose(pred[ok], mixed[ok], rtol=1e-5, atol=1e-9)
    # the GP's weights alone (the paper's prediction) do not find it: the fit is what recovers it
    gp_only = method.set_params(slice_fit=0.0).predict(flash_slice, "2d")[0]
    assert np.nanmax(np.abs(np.log((gp_only[ok] + 1e-3) / (mixed[ok] + 1e-3)))) > 0.05
    # and anchor=False is the paper's prediction: no slice fit there
    paper = method.set_params(anchor=False, slice_fit=1.0).predict(flash_slice, "2d")[0]
    np.testing.assert_allclose(paper, DSGPLVMMethod.from_model(
        method.model_, materials, **(method.get_params() | {"slice_fit": 0.0})).predict(
        flash_slice, "2d")[0], rtol=1e-12)


def test_the_share_is_the_fit_alone_past_the_out_of_training_threshold_only():
    assert OUT_OF_TRAINING_NOVELTY == 1.0          # the threshold of infer's warning
    for novelty in (0.0, 0.3, 1.0, None, float("nan")):  # inside, at the threshold, unknown
        assert slice_fit_share(novelty, 0.5) == 0.5
    for novelty in (1.0001, 1.5, 40.0):
        assert slice_fit_share(novelty, 0.5) == 1.0
    assert slice_fit_share(2.0, 0.0) == 1.0        # even a GP-only share switches (the caller
                                                   # then has no fit: anchor=False never asks)


def test_an_out_of_training_slice_is_predicted_by_the_slice_fit_alone(materials, monkeypatch):
    """A training material's own slice (novelty 0) keeps the λ = 0.5 mixture; the same slice with
    its channels scaled 30× and 1/30× lies far outside the six materials (novelty > 1) and is
    predicted exactly as with slice_fit = 1, which differs from the λ = 0.5 mixture."""
    method = DSGPLVMMethod(max_cycles=3, anchor=True, feature_space="rgb",
                           row_blend_deg=0.0, consensus=False).fit(materials)
    inside = materials.slices[2]
    outside = inside * np.array([30.0, 1.0, 1.0 / 30.0])
    assert method.novelty(inside) < 1.0 < method.novelty(outside)
    fit_alone = method.set_params(slice_fit=1.0)
    want_out = fit_alone.predict(outside, "2d")[0]
    method.set_params(slice_fit=0.5)
    got_out, var_out = method.predict(outside, "2d")
    np.testing.assert_allclose(got_out, want_out, rtol=1e-12)   # same weights, same arithmetic
    got_in = method.predict(inside, "2d")[0]
    monkeypatch.setattr(flashbrdf.infer.adapter, "slice_fit_share", lambda novelty, share: share)
    np.testing.assert_array_equal(method.predict(inside, "2d")[0], got_in)  # inside: no change
    mixed_out, var_mixed = method.predict(outside, "2d")
    ok = np.isfinite(got_out).all(-1)
    # the two weight vectors differ there: the λ = 0.5 mixture moves ln ρ by more than 1%
    assert np.nanmax(np.abs(np.log((mixed_out[ok] + 1e-3) / (got_out[ok] + 1e-3)))) > 0.01
    # the switch moves the mean only: the variance is the λ = 0.5 combination's, bit for bit
    np.testing.assert_array_equal(var_out, var_mixed)
