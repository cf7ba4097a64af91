"""CIELAB against colour-science, the feature map, the Table 1/2 metrics, slice.csv parsing."""

import colour
import numpy as np
import pytest

from flashbrdf.brdf.colour import (D65_WHITE_XYZ, FEATURE_OFFSET, SRGB_TO_XYZ, features_to_rho,
                         lab_to_linear_rgb, linear_rgb_to_lab, rho_to_features)
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.metrics import brdf_error, brdf_errors, delta_e_log, summarise
from flashbrdf.brdf.views import read_slice_csv, write_slice_csv


def test_lab_matches_colour_science():
    rng = np.random.default_rng(0)
    rgb = np.concatenate([rng.uniform(0, 1, (500, 3)), rng.uniform(0, 20, (500, 3)),
                          rng.uniform(0, 0.001, (100, 3))])
    xyz = colour.RGB_to_XYZ(rgb, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False)
    reference = colour.XYZ_to_Lab(xyz)
    np.testing.assert_allclose(linear_rgb_to_lab(rgb), reference, atol=1e-9)
    # colour-science's sRGB matrix is rounded to 4 digits, so white lands 0.008 off neutral.
    np.testing.assert_allclose(linear_rgb_to_lab([1.0, 1.0, 1.0]), [100, 0, 0], atol=1e-2)


def test_written_out_constants_are_colour_sciences():
    # written out so that `run` need not import colour-science: they must be its values, bit
    # for bit (a newer colour-science with other constants makes this fail, not drift)
    matrix = np.array(colour.RGB_COLOURSPACES["sRGB"].matrix_RGB_to_XYZ, dtype=np.float64)
    white = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    assert np.array_equal(SRGB_TO_XYZ, matrix)
    assert np.array_equal(D65_WHITE_XYZ, np.asarray(white, dtype=np.float64))


def test_lab_inverse():
    rng = np.random.default_rng(1)
    rgb = rng.uniform(-1, 30, (1000, 3))
    np.testing.assert_allclose(lab_to_linear_rgb(linear_rgb_to_lab(rgb)), rgb, atol=1e-9)


def test_feature_map_is_invertible_and_finite_at_the_extremes():
    rho = np.array([[0.0, 0.0, 0.0], [1e-3, 2e-3, 5e-4], [4e3, 3.5e3, 3.9e3], [0.02, 0.05, 0.1]])
    features = rho_to_features(rho)
    assert np.all(np.isfinite(features))
    np.testing.assert_allclose(features[0], 0.0, atol=1e-12)  # black -> ln(1) = 0 -> Lab 0
    np.testing.assert_allclose(features_to_rho(features), rho, rtol=1e-9, atol=1e-15)
    for space in ("lab", "rgb"):
        np.testing.assert_allclose(features_to_rho(rho_to_features(rho, space), space), rho,
                                   rtol=1e-9, atol=1e-15)
    assert FEATURE_OFFSET == 1e-3
    assert np.all(np.isnan(rho_to_features(np.full((1, 3), np.nan))))


def test_float32_features_match_float64_and_keep_the_layout():
    # The 3D streaming path maps float32 tables held channel-first (a transposed (3, n) buffer).
    rng = np.random.default_rng(2)
    rho = 10.0 ** rng.uniform(-4, 3.6, (3, 20000))
    rho[:, :10] = 0.0
    rho32 = rho.astype(np.float32).T
    feats32 = rho_to_features(rho32)
    assert feats32.dtype == np.float32 and feats32.flags["F_CONTIGUOUS"]
    # ln(1+ρ/1e-3) ≤ 16.2 and Lab ≤ ~500·cbrt; float32 keeps 2^-24 relative, so a few 1e-4 Lab units.
    np.testing.assert_allclose(feats32, rho_to_features(rho32.astype(np.float64)), atol=1e-3)


def test_metrics_of_a_table_against_itself_are_zero():
    rng = np.random.default_rng(2)
    true = rng.uniform(0, 5, (90, 90, 3))
    true[50:, 80:] = np.nan
    assert all(v == 0 for v in brdf_errors(true, true).values())


def test_constant_offset_gives_hand_computed_errors():
    true = np.full((10, 3), 1.0)
    pred = true + 3.0  # rho = 4
    assert brdf_error(pred, true, "lin", "rgb") == pytest.approx(3.0)
    assert brdf_error(pred, true, "root", "rgb") == pytest.approx(1.0)
    assert brdf_error(pred, true, "log", "rgb") == pytest.approx(np.log(5) - np.log(2))
    # Grey triplets: Lab has a = b = 0, so Delta E is the L* difference, L* = 116 Y^(1/3) - 16.
    # (a*, b* of grey are 0.008 * L*/100 with colour-science's rounded matrix: below 1e-4 rel.)
    assert brdf_error(pred, true, "lin", "lab") == pytest.approx(116 * (4 ** (1 / 3) - 1), rel=1e-4)
    e = brdf_error(pred, true, "log", "lab")
    assert e == pytest.approx(116 * (np.log(5) ** (1 / 3) - np.log(2) ** (1 / 3)), rel=1e-4)


def test_metric_uses_ground_truth_bins_and_counts_nan_prediction_as_zero():
    true = np.array([[1.0, 1.0, 1.0], [np.nan] * 3])
    pred = np.array([[np.nan] * 3, [9.0, 9.0, 9.0]])
    assert brdf_error(pred, true, "lin", "rgb") == pytest.approx(1.0)
    assert brdf_error(-np.ones((1, 3)), np.ones((1, 3)), "lin", "rgb") == pytest.approx(1.0)


def test_delta_e_log_and_summary():
    assert delta_e_log(np.ones(3), np.ones(3)) == 0
    grey = delta_e_log(np.full(3, np.e - 1), np.zeros(3))  # ln(1 + e - 1) = 1 -> L* = 100
    assert grey == pytest.approx(100.0, rel=1e-4)
    assert summarise([1, 2, 6, np.nan]) == {"mean": 3.0, "median": 2.0}


def test_slice_csv_roundtrip_keeps_empty_bins_empty(tmp_path):
    rng = np.random.default_rng(3)
    rho = rng.uniform(0, 10, (90, 3))
    rho[60:] = np.nan
    n = np.where(np.isfinite(rho[:, 0]), 37, 0)
    path = tmp_path / "s.csv"
    write_slice_csv(path, rho, n, comments=["made by a test"])
    text = path.read_text().splitlines()
    assert text[0] == "# made by a test" and text[1] == "theta_h_deg,r,g,b,n"
    assert text[-1].split(",")[1:] == ["", "", "", "0"]
    rho2, n2 = read_slice_csv(path)
    np.testing.assert_array_equal(rho2, rho)
    np.testing.assert_array_equal(n2, n)


def test_slice_csv_reads_rounded_centres_and_a_byte_order_mark(tmp_path):
    """An outside slice.csv may print theta_h_deg with 4 decimals (bin 0's centre 0.0027778 as
    0.0028) and start with a UTF-8 byte-order mark; it is still the contract's file."""
    centres = 90.0 * ((np.arange(90) + 0.5) / 90) ** 2
    lines = ["theta_h_deg,r,g,b,n"] + [f"{c:.4f},{0.1 * (k + 1)},0.2,0.3,{k}"
                                       for k, c in enumerate(centres)]
    path = tmp_path / "s.csv"
    path.write_text("\ufeff" + "\n".join(lines) + "\n", encoding="utf-8")
    rho, n = read_slice_csv(path)
    assert rho[0, 0] == pytest.approx(0.1) and rho[89, 0] == pytest.approx(9.0)
    assert n[89] == 89 and n.sum() == 4005


@pytest.mark.parametrize("decimals", [2, 1, 0])
def test_slice_csv_reads_centres_rounded_to_their_printed_precision(tmp_path, decimals):
    """theta_h_deg rounded to 2 decimals (bin 0's 0.0027778 as 0.00, bin 1's 0.025 as 0.03), or
    fewer, names its bin within half a unit of its last digit; n printed as 180.0 is 180."""
    centres = 90.0 * ((np.arange(90) + 0.5) / 90) ** 2
    lines = ["theta_h_deg,r,g,b,n"] + [f"{c:.{decimals}f},0.1,0.2,0.3,180.0" for c in centres]
    path = tmp_path / "s.csv"
    path.write_text("\n".join(lines) + "\n")
    rho, n = read_slice_csv(path)
    assert n.tolist() == [180] * 90 and rho[45].tolist() == [0.1, 0.2, 0.3]


@pytest.mark.parametrize("mutate, words", [
    (lambda lines: lines[:-1], "expected 90 data rows"),
    (lambda lines: ["theta,r,g,b,n"] + lines[1:], "header"),
    (lambda lines: lines[:5] + ["0.5,1,2,x,3"] + lines[6:], "not a number"),
    (lambda lines: lines[:5] + [lines[5].rsplit(",", 4)[0] + ",nan,1,1,3"] + lines[6:], "NaN"),
    (lambda lines: lines[:5] + [lines[5].rsplit(",", 4)[0] + ",1,,1,3"] + lines[6:], "all given"),
    (lambda lines: lines[:5] + ["7.0,1,1,1,3"] + lines[6:], "centre"),
    # uniform 1° spacing is not the contract's binning, whatever its printed precision
    (lambda lines: lines[:1] + [f"{k}.5,1,1,1,3" for k in range(90)], "centre"),
    (lambda lines: lines[:5] + [lines[5].rsplit(",", 1)[0] + ",2.5"] + lines[6:], "whole"),
])
def test_bad_slice_files_name_the_problem(tmp_path, mutate, words):
    path = tmp_path / "s.csv"
    write_slice_csv(path, np.ones((90, 3)), np.ones(90, int))
    lines = path.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(mutate(lines)) + "\n")
    with pytest.raises(InputError, match=words) as err:
        read_slice_csv(bad)
    assert str(bad) in str(err.value)
