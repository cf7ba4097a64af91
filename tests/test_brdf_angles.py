"""Half/difference angles: round trips, the singular theta_h = 0 frame, reciprocity, lookup."""

import numpy as np
import pytest

from flashbrdf.brdf.angles import (half_diff_from_local, half_diff_from_world, local_from_half_diff,
                         merl_bin_index, phi_h_from_local)
from flashbrdf.brdf.frame import Frame
from flashbrdf.brdf.lookup import evaluate_directions, evaluate_table
from flashbrdf.brdf.merl import merl_valid_mask, phi_d_centres, theta_d_centres, theta_h_centres
from flashbrdf.brdf.rusinkiewicz import cos_in_out


def _hemisphere(rng, n, min_cos=0.0):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v[v[:, 2] > min_cos]


def _special_pairs():
    n = np.array([0.0, 0.0, 1.0])
    grazing = np.array([np.cos(1e-7), 0.0, np.sin(1e-7)])
    off = np.array([0.6, 0.0, 0.8])
    tilt = np.array([0.0, np.sin(1e-9), np.cos(1e-9)])
    return np.array([[n, n], [off, off], [grazing, grazing], [grazing, -grazing * [1, 1, -1]],
                     [tilt, n], [n, off], [grazing, n]])


def test_io_hd_io_roundtrip_within_1e9():
    rng = np.random.default_rng(1)
    wi, wo = _hemisphere(rng, 20000), _hemisphere(rng, 20000)
    m = min(len(wi), len(wo))
    wi, wo = wi[:m], wo[:m]
    special = _special_pairs()
    wi, wo = np.concatenate([wi, special[:, 0]]), np.concatenate([wo, special[:, 1]])
    th, td, pd = half_diff_from_local(wi, wo, fold=False)
    assert np.all(np.isfinite(th) & np.isfinite(td) & np.isfinite(pd))
    wi2, wo2 = local_from_half_diff(th, td, pd, phi_h_from_local(wi, wo))
    assert np.max(np.abs(wi2 - wi)) < 1e-9
    assert np.max(np.abs(wo2 - wo)) < 1e-9


def test_folded_phi_d_is_reciprocal_and_in_range():
    rng = np.random.default_rng(2)
    wi, wo = _hemisphere(rng, 5000)[:4000], _hemisphere(rng, 5000)[:4000]
    a = np.stack(half_diff_from_local(wi, wo))
    b = np.stack(half_diff_from_local(wo, wi))
    assert np.all((a[2] >= 0) & (a[2] < np.pi))
    # Swapping the directions moves phi_d by pi, which folding removes (modulo the seam at 0/pi).
    diff = np.abs(a - b)
    diff[2] = np.minimum(diff[2], np.pi - diff[2])
    assert diff.max() < 1e-9


def test_theta_h_zero_is_finite():
    wi = np.array([[0.3, 0.1, np.sqrt(1 - 0.1)], [0.0, 0.0, 1.0]])
    wo = wi * [-1, -1, 1]  # mirror pair: h = n exactly
    th, td, pd = half_diff_from_local(wi, wo)
    assert np.all(np.isfinite(pd)) and np.max(th) < 1e-12


def test_world_frame_equals_local_frame_after_rotation():
    rng = np.random.default_rng(3)
    wi, wo = _hemisphere(rng, 300)[:200], _hemisphere(rng, 300)[:200]
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    n = np.array([0.0, 0.0, 1.0])
    local = np.stack(half_diff_from_local(wi, wo))
    world = np.stack(half_diff_from_world(wi @ q.T, wo @ q.T, n @ q.T))
    diff = np.abs(local - world)
    diff[2] = np.minimum(diff[2], np.pi - diff[2])
    assert diff.max() < 1e-9


def test_bin_centres_index_their_own_bins():
    i, j, k = merl_bin_index(theta_h_centres(), theta_d_centres(), phi_d_centres()[:90])
    np.testing.assert_array_equal(i, np.arange(90))
    np.testing.assert_array_equal(j, np.arange(90))
    np.testing.assert_array_equal(k, np.arange(90))
    assert merl_bin_index(0.0, 0.0, -1e-3)[2] == 179  # negative phi_d folds to the last bin


@pytest.mark.parametrize("interpolate", [False, True])
def test_lookup_at_bin_centres_returns_the_table(interpolate):
    rng = np.random.default_rng(4)
    table = rng.uniform(0.1, 2.0, size=(90, 90, 180, 3))
    i, j, k = rng.integers(0, 90, 500), rng.integers(0, 90, 500), rng.integers(0, 180, 500)
    values = evaluate_table(table, theta_h_centres()[i], theta_d_centres()[j],
                            phi_d_centres()[k], interpolate=interpolate)
    np.testing.assert_allclose(values, table[i, j, k], rtol=1e-9)


def test_interpolation_skips_no_data_and_is_linear():
    table = np.full((90, 90, 3), np.nan)
    table[10, 20] = 1.0
    table[10, 21] = 3.0
    v = evaluate_table(table, theta_h_centres()[10], np.deg2rad(21.25), 0.0, interpolate=True)
    np.testing.assert_allclose(v, 2.5)  # 1 and 3 at 20.5 and 21.5 deg, weights 0.25/0.75
    v = evaluate_table(table, theta_h_centres()[40], np.deg2rad(50.0), 0.0, interpolate=True)
    np.testing.assert_array_equal(v, 0.0)


def test_lookup_is_reciprocal_and_zero_below_horizon():
    rng = np.random.default_rng(5)
    table = rng.uniform(0.1, 2.0, size=(90, 90, 180, 3))
    wi, wo = _hemisphere(rng, 3000, 0.05)[:1000], _hemisphere(rng, 3000, 0.05)[:1000]
    n = np.array([0.0, 0.0, 1.0])
    for interpolate in (False, True):
        a = evaluate_directions(table, wi, wo, n, interpolate)
        b = evaluate_directions(table, wo, wi, n, interpolate)
        # Nearest lookups can differ only where phi_d sits on the 0/pi seam; none do here.
        np.testing.assert_allclose(a, b, rtol=1e-9)
    below = wo * [1, 1, -1]
    assert np.all(evaluate_directions(table, wi, below, n) == 0)


def test_cos_in_out_is_the_z_of_local_from_half_diff():
    # brdf.rusinkiewicz.cos_in_out (MERL's valid mask, the baselines' 1/cos terms) is the closed
    # form of the directions' z components: equal to rounding (1e-12 on unit vectors), any phi_h.
    rng = np.random.default_rng(3)
    th, td, pd, ph = rng.uniform(0, [np.pi / 2, np.pi / 2, 2 * np.pi, 2 * np.pi], (5000, 4)).T
    wi, wo = local_from_half_diff(th, td, pd, ph)
    cos_i, cos_o = cos_in_out(th, td, pd)
    assert np.abs(cos_i - wi[:, 2]).max() < 1e-12 and np.abs(cos_o - wo[:, 2]).max() < 1e-12


def test_valid_mask_is_both_cosines_positive_at_bin_centres():
    # 1,096,216 valid bins: the count the MERL format (and brdf.bins) is built around.
    assert int(merl_valid_mask().sum()) == 1_096_216


@pytest.mark.parametrize("normal", [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8],
                                    [0.0, 1e-9, -1.0 + 1e-18]])
def test_frame_is_orthonormal_and_round_trips(normal):
    # Duff et al.'s frame has no singularity, n = -z included; round trips are exact to 1e-15.
    rng = np.random.default_rng(4)
    n = np.asarray(normal) / np.linalg.norm(normal)
    frame = Frame.from_normal(np.broadcast_to(n, (100, 3)))
    assert np.abs(np.cross(frame.tangent, frame.bitangent) - n).max() < 1e-14
    assert np.abs(np.einsum("nk,nk->n", frame.tangent, frame.normal)).max() < 1e-14
    v = rng.normal(size=(100, 3))
    assert np.abs(frame.to_world(frame.to_local(v)) - v).max() < 1e-14
    assert np.abs(frame.to_local(n)[..., 2] - 1.0).max() < 1e-15
    if normal == [0.0, 0.0, 1.0]:
        np.testing.assert_array_equal(frame.tangent[0], [1.0, 0.0, 0.0])  # the fixed tangent
