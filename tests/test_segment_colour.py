"""Segmentation reads colour before brightness (slice_extract.segment): a brighter pixel of a
material (glitter, a bump, a coloured metal's highlight) stays that material; the 12-megapixel
assignment applies the same rule as the k-slice refinement."""

import numpy as np

from flashbrdf.brdf.merl import N_THETA_H
from flashbrdf.slice_extract.segment.features import log_samples, theta_h_bins
from flashbrdf.slice_extract.segment.slices import (assign_all, material_slices,
                                                    residuals)
from flashbrdf.slice_extract.segment import material_features


def test_a_brighter_pixel_of_a_colour_keeps_its_material():
    # slice A grey 0.1; slice B (0.15, 0.12, 0.18): nearer to the sample in plain mean |Δ ln ρ|
    # (0.137 against 0.4) but another colour. The sample is A 1.49x brighter (+0.4 in ln ρ):
    # colour offset 0 + 0.25 * 0.4 = 0.10 from A, 0.14 + 0.25 * 0.007 from B.
    a = np.full((N_THETA_H, 3), np.log(0.1))
    b = np.broadcast_to(np.log([0.15, 0.12, 0.18]), (N_THETA_H, 3))
    sample = np.log(np.full((1, 3), 0.1)) + 0.4
    residual = residuals(sample, np.array([10]), [a, b])
    np.testing.assert_allclose(residual[0], [0.1, 0.1417], atol=2e-3)
    assert residual[0].argmin() == 0


def test_chromaticity_features_do_not_move_with_a_coloured_highlight():
    # a gold-like pixel 10x brighter in its lobe (every channel scaled): same colour columns
    rho = np.array([[0.20, 0.12, 0.04]] * 60 + [[2.0, 1.2, 0.4]] * 40)
    theta_h = np.radians(np.r_[np.full(60, 30.0), np.full(40, 2.0)])
    features, _ = material_features(rho, theta_h)
    np.testing.assert_allclose(features[0, :2], [0.20 / 0.36, 0.12 / 0.36], rtol=1e-9)
    np.testing.assert_allclose(features[-1, :2], features[0, :2], rtol=1e-9)


def test_every_pixel_assignment_agrees_with_the_refinement_rule():
    # _assign_all (float32, column by column) against argmin of _residuals (float64, with the
    # white term) on 20000 samples of 3 materials (30% log-normal scatter); ties within float32 rounding
    # (1e-5) may differ
    rng = np.random.default_rng(3)
    material = rng.integers(0, 3, 20000)
    colours = np.log([[0.1, 0.05, 0.2], [0.2, 0.1, 0.05], [0.1, 0.1, 0.1]])
    rho = np.exp(colours[material] + rng.normal(0, 0.3, (20000, 3)))
    theta_h = np.radians(rng.uniform(0, 80, 20000))
    labels = material[:5000]
    pick = np.arange(5000)
    fast = assign_all(rho, theta_h, pick, labels, 3)
    log_rho, _, floor = log_samples(rho[pick])
    slices = material_slices(log_rho, theta_h_bins(theta_h[pick]), labels, 3)
    residual = residuals(log_samples(rho, floor)[0], theta_h_bins(theta_h), slices, floor)
    exact = residual.argmin(axis=1)
    best_two = np.sort(residual, axis=1)[:, :2]
    clear = best_two[:, 1] - best_two[:, 0] > 1e-5
    assert clear.mean() > 0.99
    assert np.array_equal(fast[clear], exact[clear])
