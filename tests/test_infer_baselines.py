"""Baselines of infer: each reproduces what its method guarantees, on synthetic materials whose answer
is known (built on MERL bin centres from brdf.merl), plus missing-data and extreme slices."""

import numpy as np
import pytest

from flashbrdf.infer import PCA, Ashikhmin, Chandraker, Noll, Oracle, TrainingSet
from flashbrdf.brdf.shadowing import denominator
from flashbrdf.infer.baselines.ashikhmin import schlick
from flashbrdf.brdf.bins import cos_in_out_valid, mean_over_phi_d, valid_bins_3d
from flashbrdf.brdf import merl


def ap_material(roughness, r0, colour, diffuse=0.0):
    """Ashikhmin–Premože material on the valid 3D bins: Beckmann p(θh), Schlick F, the model's
    denominator; optional Lambertian term. -> ρ (n_valid, 3) in 1/sr."""
    ih, jd, _ = valid_bins_3d()
    th = merl.theta_h_centres()[ih]
    cos_d = np.cos(merl.theta_d_centres()[jd])
    p = np.exp(-np.tan(th) ** 2 / roughness ** 2) / (np.pi * roughness ** 2 * np.cos(th) ** 4)
    spec = p * schlick(cos_d, r0) / denominator(*cos_in_out_valid())
    return spec[:, None] * np.asarray(colour) + diffuse * np.asarray(colour) / np.pi


def training_set(rows):
    """TrainingSet from ρ on valid 3D bins (list of (n_valid, 3)); slices = θd bin 0 of the 2D."""
    tables = np.array([mean_over_phi_d(r) for r in rows])
    return TrainingSet([f"m{i}" for i in range(len(rows))], tables[:, :, 0, :].copy(), tables,
                       valid_3d=np.array(rows, np.float32))


# six (roughness, r0, diffuse) specs spanning sharp to broad lobes, weak to strong diffuse
SIX_AP_SPECS = [(0.08, 0.04, 0.1), (0.2, 0.5, 0.3), (0.35, 0.1, 0.02), (0.5, 0.9, 0.5),
                (0.15, 0.2, 0.05), (0.7, 0.05, 0.8)]


def coloured_ap_set(seed, specs):
    """training_set of ap_material rows, one per (roughness, r0, diffuse) in specs, each with a
    random colour in [0.1, 1)³ from a generator seeded with `seed`."""
    rng = np.random.default_rng(seed)
    return training_set([ap_material(a, r0, rng.uniform(0.1, 1, 3), diffuse=d)
                         for a, r0, d in specs])


@pytest.fixture(scope="module")
def ap_set():
    rows = [ap_material(a, 0.08, c) for a, c in [(0.1, (0.9, 0.8, 0.6)), (0.25, (0.5, 0.5, 0.5)),
                                                 (0.4, (0.2, 0.3, 0.9)), (0.6, (1.0, 0.4, 0.3))]]
    return training_set(rows)


@pytest.fixture(scope="module")
def mixed_set():
    rng = np.random.default_rng(3)
    rows = [ap_material(a, r0, rng.uniform(0.1, 1, 3), diffuse=d)
            for a, r0, d in [(0.08, 0.04, 0.1), (0.2, 0.5, 0.3), (0.35, 0.1, 0.02), (0.5, 0.9, 0.5),
                             (0.15, 0.2, 0.05), (0.7, 0.05, 0.8)]]
    return training_set(rows)


def test_chandraker_copies_slice_exactly(ap_set):
    s = ap_set.slices[1]
    table, _ = Chandraker().fit(None).predict(s, "2d")
    np.testing.assert_array_equal(table[:, 0], s)
    np.testing.assert_array_equal(table[:, 40], s)  # θd-invariant by construction


def test_ashikhmin_exact_on_its_own_model(ap_set):
    # r0 = 0.08 for every training material: the fit must find it (log r0 to ~1e-4) and then the
    # model predicts every 2D bin of a new AP material exactly up to that r0 error (< 1e-3 relative).
    method = Ashikhmin().fit(ap_set.subset([0, 1, 2]))
    assert method.r0_ == pytest.approx(0.08, rel=2e-3)
    table, _ = method.predict(ap_set.slices[3], "2d")
    truth = ap_set.tables_2d[3]
    ok = np.isfinite(truth).all(-1)
    np.testing.assert_allclose(table[ok], truth[ok], rtol=1e-3, atol=1e-12)
    table3, _ = method.predict(ap_set.slices[3], "3d")
    ih, jd, kd = valid_bins_3d()
    np.testing.assert_allclose(table3[ih, jd, kd], ap_set.valid_3d[3], rtol=1e-3, atol=1e-12)


def test_noll_passes_through_observed_samples(mixed_set):
    method = Noll().fit(mixed_set.subset([0, 1, 2, 3]))
    s = mixed_set.slices[5].copy()
    table, _ = method.predict(s, "2d")
    # correction (ρ_obs + δ)/(fit + δ), δ = 1e-9 1/sr: exact up to δ
    np.testing.assert_allclose(table[:, 0], s, rtol=1e-6, atol=2e-9)


def test_noll_recovers_a_nonnegative_mixture_of_training_materials(mixed_set):
    """Nöll's assumption holds exactly: the material is 0.3 m0 + 0.5 m2 + 0.2 m4 of the training
    set. Its slice fixes the weights (the six slices are independent), the correction is then 1,
    and every 2D and 3D bin comes back. Tolerance: the 3D rows are float32 (half-ulp 6e-8
    relative) and least squares stops near 1e-8 relative; 1e-6 is well above both."""
    w = np.array([0.3, 0.0, 0.5, 0.0, 0.2, 0.0])
    mixture = training_set([np.einsum("i,ijc->jc", w, np.asarray(mixed_set.valid_3d, float))])
    method = Noll().fit(mixed_set)
    np.testing.assert_allclose(method.weights(mixture.slices[0]), w, atol=1e-6)
    table, _ = method.predict(mixture.slices[0], "2d")
    truth = mixture.tables_2d[0]
    ok = np.isfinite(truth).all(-1)
    np.testing.assert_allclose(table[ok], truth[ok], rtol=1e-6)
    table3, _ = method.predict(mixture.slices[0], "3d")
    ih, jd, kd = valid_bins_3d()
    np.testing.assert_allclose(table3[ih, jd, kd], mixture.valid_3d[0], rtol=1e-6)


def test_noll_takes_a_training_table_darker_than_float32_holds(mixed_set):
    """A training table at 1e-300 x a material (1e-303 1/sr: stored as 0 in MODEL.npz's float32
    2D tables) beside ordinary ones. Its slice needed a weight past 1e300 to fit a bright slice:
    the NNLS start overflowed and least_squares raised (a traceback from `infer` and from the
    default, whose consensus runs noll). Noll reads such a slice as the stored tables hold it, 0.
    The prediction passes through the slice as test_noll_passes_through_observed_samples says
    (correction exact up to delta = 1e-9 1/sr, relative 1e-15 at 1e6 1/sr)."""
    slices = mixed_set.slices.copy()
    slices[3] *= 1e-300
    tables = mixed_set.tables_2d.copy()
    tables[3] = np.asarray(tables[3] * 1e-300, np.float32)
    dark = TrainingSet(mixed_set.names, slices, tables)
    for s in (np.full((90, 3), 1e6), mixed_set.slices[5].copy()):
        table, _ = Noll().fit(dark).predict(s, "2d")
        valid = np.isfinite(mixed_set.tables_2d[0]).all(-1)
        assert np.isfinite(table[valid]).all() and (table[valid] >= 0).all()
        np.testing.assert_allclose(table[:, 0], s, rtol=1e-6, atol=2e-9)


def test_chandraker_recovers_a_theta_d_invariant_material():
    """Chandraker's assumption holds exactly: ρ depends on θh alone (a Blinn-like lobe over a
    diffuse floor). The 2D and 3D predictions from its slice equal the truth on every valid bin
    (the same values copied: exact but for the float32 3D rows, 6e-8 relative)."""
    ih, _, _ = valid_bins_3d()
    th = merl.theta_h_centres()
    per_theta_h = (0.05 + 20.0 * np.cos(th) ** 200)[:, None] * np.array([0.9, 0.6, 0.3])
    material = training_set([per_theta_h[ih]])
    table, _ = Chandraker().fit(None).predict(material.slices[0], "2d")
    truth = material.tables_2d[0]
    ok = np.isfinite(truth).all(-1)
    np.testing.assert_allclose(table[ok], truth[ok], rtol=1e-12)
    table3, _ = Chandraker().fit(None).predict(material.slices[0], "3d")
    jd, kd = valid_bins_3d()[1:]
    np.testing.assert_allclose(table3[ih, jd, kd], material.valid_3d[0], rtol=1e-6)


def test_noll_leaves_a_tables_hole_to_the_others(mixed_set):
    """The slice of training material 0 is fitted by material 0 (weight 1, the others ~1e-10):
    a hole in material 2's 2D table (NaN at θd > 0, where the others hold data) must not void
    the prediction there (1e-10 × NaN is NaN in a plain weighted sum)."""
    tables = mixed_set.tables_2d.copy()
    tables[2, 30:40, 10:20] = np.nan
    holed = TrainingSet(mixed_set.names, mixed_set.slices, tables,
                        valid_3d=mixed_set.valid_3d)
    table, _ = Noll().fit(holed).predict(mixed_set.slices[0].copy(), "2d")
    want = mixed_set.tables_2d[0]
    seen = np.isfinite(want).all(axis=-1)
    assert np.isfinite(table[seen]).all()
    np.testing.assert_allclose(table[30:40, 10:20], want[30:40, 10:20], rtol=1e-6)


def test_pca_all_components_recovers_training_material(mixed_set):
    method = PCA(n_components=None, ridge=0.0).fit(mixed_set)
    for i in (0, 3):
        table, _ = method.predict(mixed_set.slices[i], "2d")
        truth = mixed_set.tables_2d[i]
        ok = np.isfinite(truth).all(-1)
        np.testing.assert_allclose(table[ok], truth[ok], rtol=1e-6, atol=1e-9)


def test_oracle_projects_training_table_exactly(mixed_set):
    method = Oracle(ridge=0.0).fit(mixed_set)
    truth = mixed_set.tables_2d[2]
    ok = np.isfinite(truth).all(-1)
    np.testing.assert_allclose(method.predict_truth(truth)[ok], truth[ok], rtol=1e-6, atol=1e-9)


def test_oracle_projects_a_table_with_no_data_bins_on_the_bins_it_has(mixed_set):
    """A true table with holes (MERL's no data) is projected on the bins it holds: a training
    table is still recovered exactly, holes included (one NaN made every coefficient NaN, and
    the oracle, the lower bound, scored worst)."""
    method = Oracle(ridge=0.0).fit(mixed_set)
    truth = mixed_set.tables_2d[2]
    holed = truth.copy()
    holed[30:40, 10:20] = np.nan
    ok = np.isfinite(truth).all(-1)
    np.testing.assert_allclose(method.predict_truth(holed)[ok], truth[ok], rtol=1e-6, atol=1e-9)


def test_pca_3d_streams_training_tables(mixed_set):
    # all components, training slice: the dual weights select that material, so its 3D comes back
    method = PCA(n_components=None, ridge=0.0).fit(mixed_set)
    table3, _ = method.predict(mixed_set.slices[4], "3d")
    ih, jd, kd = valid_bins_3d()
    np.testing.assert_allclose(table3[ih, jd, kd], mixed_set.valid_3d[4], rtol=1e-4, atol=1e-7)
    assert np.isnan(table3[~merl.merl_valid_mask()]).all()


@pytest.mark.parametrize("make", [lambda: Chandraker(), lambda: Ashikhmin(r0=0.1), lambda: Noll(),
                                  lambda: PCA(None, 1e-3)])
def test_empty_bins_are_missing_not_zero(mixed_set, make):
    method = make().fit(mixed_set.subset([0, 1, 2, 3, 5]))
    full = mixed_set.slices[4]
    gap, zero = full.copy(), full.copy()
    gap[30:45], zero[30:45] = np.nan, 0.0
    p_full, p_gap, p_zero = (np.nan_to_num(method.predict(s, "2d")[0]) for s in (full, gap, zero))
    err_gap = np.abs(np.log1p(p_gap) - np.log1p(p_full)).mean()
    err_zero = np.abs(np.log1p(p_zero) - np.log1p(p_full)).mean()
    assert err_gap < 0.5 * err_zero  # treating the gap as zeros would change the prediction more
    assert np.all(p_gap[30:45, 0] > 0)


@pytest.mark.parametrize("make", [lambda: Chandraker(), lambda: Ashikhmin(r0=0.1), lambda: Noll(),
                                  lambda: PCA(None, 1e-2)])
def test_extreme_slices_give_finite_predictions(mixed_set, make):
    method = make().fit(mixed_set)
    th = np.linspace(0, 1, 90)[:, None]
    chrome = 10 ** (np.log10(4e3) - (np.log10(4e3) + 3) * th) * np.ones((1, 3))  # 4e3 .. 1e-3
    black = np.zeros((90, 3))
    valid2 = np.isfinite(mixed_set.tables_2d[0]).all(-1)
    views = [("2d", valid2)]
    if isinstance(method, (Chandraker, Ashikhmin)):  # streamed 3D is covered by the pca 3D test
        views.append(("3d", merl.merl_valid_mask()))
    for s in (chrome, black):
        for view, valid in views:
            table, _ = method.predict(s, view)
            assert np.isfinite(table[valid]).all() and (table[valid] >= 0).all()


def test_dsgplvm_adapter_duplicate_training_brdfs(mixed_set):
    # two identical training materials make the Gram matrices singular: training must still succeed
    from flashbrdf.infer import DSGPLVMMethod
    dup = mixed_set.subset([0, 1, 2, 3, 4, 4])
    method = DSGPLVMMethod(max_cycles=3).fit(dup)
    table, var = method.predict(mixed_set.slices[5], "2d")
    valid = np.isfinite(mixed_set.tables_2d[0]).all(-1)
    assert np.isfinite(table[valid]).all() and np.isfinite(var[valid]).all()
    weights, space = method.combination(mixed_set.slices[5])
    assert weights.shape == (6,) and abs(weights.sum() - 1) < 1e-9  # affine: view mean folded in


def test_streamed_3d_metrics_equal_brdf_metrics(mixed_set):
    # evaluate_3d shares the truth's transforms across methods and sums chunk by chunk: it must
    # give brdf.metrics.brdf_errors on the full tables (float64 round-off only)
    from flashbrdf.brdf import metrics
    from flashbrdf.experiments.eval3d import evaluate_3d
    train, test = np.arange(5), np.array([5])
    training = mixed_set.subset(train)
    methods = {"chandraker": Chandraker().fit(None), "pca": PCA(None, 1e-2).fit(training)}
    got = evaluate_3d(mixed_set.valid_3d, train, test, methods, mixed_set.slices[test],
                      chunk=100_000, stride=3)            # every 3rd φd bin, in 4 chunks
    keep = valid_bins_3d()[2] % 3 == 0
    truth = mixed_set.valid_3d[5].astype(float)[keep]
    ih, jd, kd = (a[keep] for a in valid_bins_3d())
    for name, m in methods.items():
        want = metrics.brdf_errors(m.predict(mixed_set.slices[5], "3d")[0][ih, jd, kd], truth)
        for key, value in want.items():
            assert got[name][0][key] == pytest.approx(value, rel=1e-9)


def test_streamed_3d_combination_is_thread_count_independent(mixed_set):
    from flashbrdf.infer.adapter import FeatureSpace
    from flashbrdf.infer.estimator import stream_combination
    w = np.array([0.5, -0.2, 0.0, 0.4, 0.3] + [0.0] * (len(mixed_set) - 5))
    one = stream_combination(mixed_set, w, FeatureSpace(), workers=1)
    two = stream_combination(mixed_set, w, FeatureSpace(), workers=2)
    # Same float32 terms summed in float64 in another order: equal to float64 rounding.
    np.testing.assert_allclose(two, one, rtol=1e-12, atol=1e-15)
    # A one-hot weight gives the table back through the float32 feature map and its inverse. The
    # Lab features reach a few hundred, where float32's half-ulp is 1.5e-5; that is an absolute error
    # of the same order in ln ρ, so ρ comes back within a few 1e-5 relative (measured 1.3e-5).
    hot = np.eye(len(mixed_set))[2]
    np.testing.assert_allclose(stream_combination(mixed_set, hot, FeatureSpace()),
                               mixed_set.valid_3d[2], rtol=5e-5, atol=1e-9)


def test_streamed_combination_clips_to_the_training_range_when_asked(mixed_set):
    from flashbrdf.infer.adapter import FeatureSpace
    from flashbrdf.infer.estimator import LinearSpace, stream_combination
    # 3·T0 − 2·T1 extrapolates beyond both tables; a GP mean with large ± weights does the same.
    w = np.zeros(len(mixed_set))
    w[[0, 1]] = 3.0, -2.0
    plain = stream_combination(mixed_set, w, LinearSpace())          # identity space, no clip
    clipped = stream_combination(mixed_set, w, FeatureSpace("rgb"))  # the DS-GPLVM's space
    tables = np.asarray(mixed_set.valid_3d, float)
    lo, hi = tables.min(axis=0), tables.max(axis=0)               # the range of every training table
    outside = lambda rho: (rho < lo * (1 - 1e-4)) | (rho > hi * (1 + 1e-4))  # noqa: E731
    assert np.mean(outside(plain)) > 0.1
    # log-RGB features are monotonic per channel, so a clip in feature space keeps each ρ channel
    # within the training tables (up to the float32 path, 1e-4 relative).
    assert not np.any(outside(clipped))


def test_near_duplicate_training_brdfs_leave_novelty_and_its_variance_as_without_them(mixed_set):
    """Every training material beside its copy ×(1 + 1e-9): novelty's scale, the nearest-
    neighbour distance of the training slices, fell to round-off, and a slice just beside one
    scored 2.75e4 (its variance 1e5, against 1e-4 on the slice itself). Copies are not
    neighbours: the novelty of a held-out slice is what the set without copies gives, within
    the change one more row makes to the fitted latent space (a factor 2)."""
    from dataclasses import replace
    from flashbrdf.infer import DSGPLVMMethod
    base = mixed_set.subset([0, 1, 2, 3, 4])
    doubled = mixed_set.subset([0, 1, 2, 3, 4, 0, 1, 2, 3, 4])
    doubled = replace(doubled, names=[f"{n}-{i}" for i, n in enumerate(doubled.names)],
                      slices=doubled.slices * np.where(np.arange(10) >= 5, 1 + 1e-9, 1.0)[
                          :, None, None],
                      tables_2d=doubled.tables_2d * np.where(np.arange(10) >= 5, 1 + 1e-9, 1.0)[
                          :, None, None, None])
    alone = DSGPLVMMethod(max_cycles=3).fit(base).novelty(mixed_set.slices[5])
    with_copies = DSGPLVMMethod(max_cycles=3).fit(doubled).novelty(mixed_set.slices[5])
    assert 0.5 < with_copies / alone < 2.0, (alone, with_copies)
