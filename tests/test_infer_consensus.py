"""The consensus (infer.consensus) and the warning (infer.warning): the average is taken in the metric's
space, so it is never worse than its members' weighted error; equal members give themselves back;
the spread and the disagreement have their closed forms; the DS-GPLVM predicts the consensus of its
members and warns exactly past the threshold."""

import warnings

import numpy as np
import pytest

from flashbrdf.brdf import merl
from flashbrdf.brdf.bins import valid_bins_3d
from flashbrdf.infer import DSGPLVMMethod
from flashbrdf.brdf.metrics import lab_log_features, rho_from_lab_log
from flashbrdf.infer.anchoring import AnchoredSpace
from flashbrdf.infer.consensus import (CONSENSUS_WEIGHTS, consensus_table,
                                       member_spread, weights_per_bin)
from flashbrdf.infer.estimator import LinearSpace
from flashbrdf.infer.warning import (DISAGREEMENT_WARN_DE, LEVEL_ADVICE, MAX_FLASH_ALBEDO,
                                     disagreement, prediction_warning)
from tests.test_infer_baselines import SIX_AP_SPECS, coloured_ap_set

THETA_D = np.degrees(merl.theta_d_centres())


def _tables(seed, n):
    rng = np.random.default_rng(seed)
    return np.exp(rng.normal(-1.0, 1.5, size=(n, 90, 90, 3)))     # ρ over six decades


def test_weights_are_convex_and_bilinear_between_the_knots():
    knots = np.random.default_rng(0).uniform(0.1, 1.0, size=(3, 4, 3))
    w = weights_per_bin(knots)
    assert w.shape == (90, 90, 3) and (w >= 0).all()
    np.testing.assert_allclose(w.sum(axis=2), 1.0, rtol=1e-12)
    unit = knots / knots.sum(axis=2, keepdims=True)
    np.testing.assert_allclose(w[0, 0], unit[0, 0], rtol=1e-12)      # θh 0.01° < 5°, θd 0.5° < 15°
    np.testing.assert_allclose(w[-1, -1], unit[-1, -1], rtol=1e-12)  # θh 89°, θd 89.5°: last knots
    theta_h = np.degrees(merl.theta_h_centres())
    i = int(np.argmin(np.abs(theta_h - 15.0)))                       # between θh knots 5° and 25°
    a = (theta_h[i] - 5.0) / 20.0
    d = (30.5 - 15.0) / 30.0                                         # θd bin 30, between 15° and 45°
    raw = ((1 - a) * ((1 - d) * knots[0, 0] + d * knots[0, 1])
           + a * ((1 - d) * knots[1, 0] + d * knots[1, 1]))
    np.testing.assert_allclose(w[i, 30], raw / raw.sum(), rtol=1e-9)
    # a (D, M) array is the same weights for every θh
    flat = weights_per_bin(knots[1])
    np.testing.assert_allclose(flat[0], flat[-1], rtol=1e-12)
    assert weights_per_bin().shape == (90, 90, len(CONSENSUS_WEIGHTS[0, 0]))


def test_equal_members_give_themselves_back_and_the_map_inverts():
    t = _tables(1, 1)[0]
    np.testing.assert_allclose(rho_from_lab_log(lab_log_features(t)), t, rtol=1e-9)
    np.testing.assert_allclose(consensus_table(np.stack([t, t, t])), t, rtol=1e-9)


def test_the_consensus_error_is_at_most_the_weighted_error_of_its_members_bin_by_bin():
    """ΔE*ab is a norm in the space the average is taken in, so by the triangle inequality
    |Σ w_m f_m − f| ≤ Σ w_m |f_m − f| at every bin; with members off in different directions it is
    strictly smaller wherever two members weigh."""
    members, truth = _tables(2, 3), _tables(3, 1)[0]
    cons = consensus_table(members)
    f_true = lab_log_features(truth)
    err = np.linalg.norm(lab_log_features(cons) - f_true, axis=-1)           # (90, 90)
    each = np.linalg.norm(lab_log_features(members) - f_true, axis=-1)       # (3, 90, 90)
    bound = np.einsum("hdm,mhd->hd", weights_per_bin(), each)
    assert (err <= bound + 1e-9).all()
    # equality needs the members' errors to point the same way; random members never do, so where
    # two members weigh 0.1 or more it is strict at every bin
    mixed = np.sort(weights_per_bin(), axis=2)[..., -2] >= 0.1
    assert mixed.sum() > 2000 and (err[mixed] < bound[mixed] - 1e-6).all()


def test_a_bin_a_baseline_misses_takes_the_dsgplvm_value_and_one_it_misses_stays_missing():
    members = _tables(4, 3)
    members[1, 5, 7] = np.nan                    # noll has no value there: the DS-GPLVM's stands in
    cons = consensus_table(members)
    filled = members.copy()
    filled[1, 5, 7] = members[0, 5, 7]
    np.testing.assert_allclose(cons, consensus_table(filled), rtol=1e-12)
    members[0, 8, 9] = np.nan                    # the DS-GPLVM has none: no data
    cons = consensus_table(members)
    assert np.isnan(cons[8, 9]).all() and np.isfinite(cons).all(-1).sum() == 90 * 90 - 1


def test_spread_is_the_weighted_variance_of_two_members():
    a, b = np.zeros((90, 90, 3)), np.full((90, 90, 3), 2.0)
    knots = np.array([[0.25, 0.75]] * 4)
    # w(1 − w)(a − b)² = 0.25 · 0.75 · 4
    np.testing.assert_allclose(member_spread(np.stack([a, b]), knots), 0.75, rtol=1e-12)


def test_the_3d_space_applies_the_2d_correction_per_theta_h_theta_d():
    log_c = np.zeros((90, 90, 3))
    log_c[10, 20] = np.log(2.0)
    space = AnchoredSpace(LinearSpace(), log_c)
    ih, jd, _ = valid_bins_3d()
    sel = np.flatnonzero((ih == 10) & (jd == 20))[:3]
    sel = np.concatenate([sel, np.flatnonzero((ih == 11) & (jd == 20))[:3]])
    rho = np.full((len(sel), 3), 0.5)
    out = space.inverse(rho, sel)
    e = 1e-3  # (ρ + e)·2 − e at the corrected bin, unchanged elsewhere
    np.testing.assert_allclose(out[:3], (0.5 + e) * 2 - e, rtol=1e-12)
    np.testing.assert_allclose(out[3:], 0.5, rtol=1e-12)


def test_disagreement_counts_only_theta_d_past_30_degrees():
    t = _tables(5, 1)[0]
    other = t.copy()
    other[:, THETA_D < 30] *= 10.0                       # differs only where it is not counted
    assert disagreement(t, other) == 0.0
    grey = np.full((90, 90, 3), np.e - 1.0)             # ln(1 + ρ) = 1 against 0: L* of Y = 1
    assert disagreement(grey, np.zeros_like(grey)) == pytest.approx(100.0, rel=1e-6)


class _FakeMethod:
    """What prediction_warning asks of a method: novelty and member tables."""

    def __init__(self, own, noll, novelty=0.2):
        self.own, self.noll, self.score = own, noll, novelty

    name = "dsgplvm"

    def novelty(self, rho):
        return self.score

    def member_tables(self, rho):
        return {"dsgplvm": self.own, "noll": self.noll, "pca": self.own}


def test_the_warning_fires_exactly_past_the_disagreement_threshold():
    rho = np.full((90, 3), 0.1)
    grey = lambda v: np.full((90, 90, 3), v)                                # noqa: E731
    # ΔE between ln(1+ρ) = 0 and a grey with ln(1+ρ) = y is L*(y) = 116 y^(1/3) − 16 (y > 0.0089)
    y_at = lambda d: ((d + 16.0) / 116.0) ** 3                              # noqa: E731
    below = _FakeMethod(grey(0.0), grey(np.expm1(y_at(DISAGREEMENT_WARN_DE - 0.5))))
    above = _FakeMethod(grey(0.0), grey(np.expm1(y_at(DISAGREEMENT_WARN_DE + 0.5))))
    record, line = prediction_warning(below, rho, "s.csv")
    assert line is None and record["out_of_distribution"] is False
    assert record["disagreement"] == pytest.approx(DISAGREEMENT_WARN_DE - 0.5, rel=1e-6)
    record, line = prediction_warning(above, rho, "s.csv")
    assert record["out_of_distribution"] is True and line.startswith("warning: s.csv:")
    assert "noll" in line and "reference photo" in line and record["advice"] in line
    # the GP's novelty past 1 is recorded, not warned on; a slice of 3 bins warns on its own
    record, line = prediction_warning(_FakeMethod(grey(0.0), grey(0.0), 1.5), rho)
    assert record["beyond_training"] and not record["out_of_distribution"] and line is None
    sparse = np.full((90, 3), np.nan)
    sparse[:3] = 0.1
    record, line = prediction_warning(below, sparse)
    assert record["out_of_distribution"] and "only 3 theta_h bins" in line
    # a baseline run on its own is not told to prefer itself: what to capture instead
    noll = type("Noll", (), {"name": "noll", "novelty": lambda self, rho: None})()
    record, line = prediction_warning(noll, sparse, "s.csv")
    assert line.startswith("warning: s.csv: noll's prediction rests on little of the slice (")
    assert "prefer noll" not in line and "photograph more of the highlight" in line
    assert record["advice"] in line


@pytest.fixture(scope="module")
def materials():
    return coloured_ap_set(11, SIX_AP_SPECS)


def test_the_default_predicts_the_consensus_of_its_members_and_widens_its_variance(materials):
    method = DSGPLVMMethod(max_cycles=3, anchor=True, feature_space="rgb").fit(materials)
    rho = materials.slices[3] * 1.3
    table, var = method.predict(rho, "2d")
    members = method.member_tables(rho)
    assert list(members) == ["dsgplvm", "noll", "pca"]
    np.testing.assert_allclose(table, consensus_table(np.stack(list(members.values()))),
                               rtol=1e-12, equal_nan=True)
    alone = method.set_params(consensus=False)
    alone = DSGPLVMMethod.from_model(method.model_, materials, **alone.get_params())
    own, var_own = alone.predict(rho, "2d")
    np.testing.assert_allclose(own, members["dsgplvm"], rtol=1e-12, equal_nan=True)
    ok = np.isfinite(var_own)
    assert (var[ok] >= var_own[ok]).all() and (var[ok] > var_own[ok]).mean() > 0.5
    # 3D: the φd-mean of the streamed prediction is the 2D consensus, up to the φd structure the
    # DS-GPLVM's own 3D table has around its own 2D one (anchored, row-blended)
    method = DSGPLVMMethod.from_model(method.model_, materials,
                                      **(alone.get_params() | {"consensus": True}))
    calls = []
    predict_2d = method._predict_2d
    method._predict_2d = lambda *a: calls.append(1) or predict_2d(*a)
    t3, var3 = method.predict(rho, "3d")
    # its variance is the 2D prediction's across φd, and the 2D prediction is made once
    assert len(calls) == 1
    seen = np.isfinite(var3)
    assert seen.any(axis=2).mean() > 0.5
    np.testing.assert_allclose(np.broadcast_to(var[:, :, None, :], var3.shape)[seen], var3[seen],
                               rtol=1e-12)
    own3, _ = alone.predict(rho, "3d")
    with warnings.catch_warnings():                      # all-NaN φd rows below the horizon
        warnings.simplefilter("ignore", RuntimeWarning)
        ratio = np.nanmean(t3, axis=2) / np.nanmean(own3, axis=2)
    want = (table + 1e-3) / (own + 1e-3)
    both = np.isfinite(ratio) & np.isfinite(want) & (own > 0.01)
    assert np.median(np.abs(np.log(ratio[both] / want[both]))) < 0.02


def test_a_slice_brighter_than_any_surface_warns_to_fix_its_level():
    """A Lambertian slice ρ = a/π reads flash_albedo a exactly (the median of equal bins); past
    MAX_FLASH_ALBEDO the level is named as the cause, for the default and a baseline alike."""
    quiet = _FakeMethod(np.zeros((90, 90, 3)), np.zeros((90, 90, 3)))   # members agree
    noll = type("Noll", (), {"name": "noll", "novelty": lambda self, rho: None})()
    lambertian = lambda a: np.full((90, 3), a / np.pi)                      # noqa: E731
    record, line = prediction_warning(quiet, lambertian(MAX_FLASH_ALBEDO * 0.99), "s.csv")
    assert line is None and record["flash_albedo"] == pytest.approx(MAX_FLASH_ALBEDO * 0.99)
    for method in (quiet, noll):
        record, line = prediction_warning(method, lambertian(MAX_FLASH_ALBEDO * 1.01), "s.csv")
        assert record["out_of_distribution"] and record["advice"] == LEVEL_ADVICE
        assert line.startswith("warning: s.csv: the slice's level is off (its diffuse level reads "
                               "albedo pi*rho = 1.52")
        assert "grey card" in line
    # only the diffuse body counts: a bright highlight below 40 deg is a material, not a level
    glossy = lambertian(0.5)
    glossy[:20] = 1e3
    assert prediction_warning(quiet, glossy)[0]["flash_albedo"] == pytest.approx(0.5)
    # no body bin observed: no level read, nothing claimed
    high = np.full((90, 3), np.nan)
    high[:30] = 10.0
    assert prediction_warning(quiet, high)[0]["flash_albedo"] is None
