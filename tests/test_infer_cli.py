"""`flashbrdf train`, `infer` and `evaluate --quick` in-process on a few MERL (NBRDF proxy) tables."""

import json
import shutil
import time

import numpy as np
import pytest

from flashbrdf.brdf import merl, views
from flashbrdf.cli.main import main
from flashbrdf.infer.model_selection import small_training_note

TRAIN = ["gold-metallic-paint", "blue-acrylic", "white-fabric", "red-plastic", "nickel"]
TEST = "green-plastic"
# The smoke run: evaluate --quick on 12 proxy materials (5 folds of 2-3), under 3 minutes.
QUICK = TRAIN + [TEST, "pink-felt", "black-obsidian", "chrome", "violet-rubber", "white-paint",
                 "specular-orange-phenolic"]


@pytest.fixture(scope="module")
def trained(merl_proxy, tmp_path_factory):
    folder = tmp_path_factory.mktemp("merl_train")
    for p in merl_proxy(*TRAIN):
        shutil.copy(p, folder / p.name)
    model = folder.parent / "model.npz"
    assert main(["train", "--merl-dir", str(folder), "--out", str(model)]) == 0
    slice_csv = folder.parent / "slice.csv"
    assert main(["merl-slice", str(merl_proxy(TEST)), "--out", str(slice_csv)]) == 0
    return folder, model, slice_csv


@pytest.mark.parametrize("method", ["dsgplvm", "pca", "noll", "chandraker", "ashikhmin"])
def test_infer_writes_merl_file_and_json(trained, tmp_path, method):
    folder, model, slice_csv = trained
    out = tmp_path / f"{method}.binary"
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--method", method]) == 0
    assert out.stat().st_size == 34_992_012
    raw = np.fromfile(out, np.float64, offset=12).reshape(3, 90, 90, 180)
    below = ~merl.merl_valid_mask()
    assert (raw[:, below] < 0).all()              # below the horizon: negative, as MERL
    table = merl.read_merl(out)
    ok = merl.merl_valid_mask()
    assert np.isfinite(table[ok]).all()
    # at θd bin 0 the prediction carries the slice (exact for chandraker/noll, close for others)
    rho, _ = views.read_slice_csv(slice_csv)
    pred_slice, _ = views.flash_slice(table)
    err = np.abs(np.log1p(pred_slice) - np.log1p(rho)).mean()
    assert err < (1e-6 if method in ("chandraker", "noll") else 0.5)
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["method"] == method and report["timings"]["predict_s"] >= 0
    assert report["view"] == ("3d" if method in ("chandraker", "ashikhmin") else "2d")
    if method == "dsgplvm":
        assert report["uncertainty"]["mean"] > 0


def test_infer_3d_with_merl_dir(trained, tmp_path):
    folder, model, slice_csv = trained
    out = tmp_path / "pca3d.binary"
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--method", "pca", "--merl-dir", str(folder)]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["view"] == "3d"
    table = merl.read_merl(out)
    assert np.isfinite(table[merl.merl_valid_mask()]).all()


def test_infer_bad_input_exit_2(trained, tmp_path, capsys):
    folder, model, slice_csv = trained
    out = tmp_path / "x.binary"
    assert main(["infer", "--model", str(tmp_path / "none.npz"), "--slice", str(slice_csv),
                 "--out", str(out)]) == 2
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--view", "3d"]) == 2
    assert "merl-dir" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.slow
def test_evaluate_quick(merl_proxy, tmp_path):
    folder = tmp_path / "merl"
    folder.mkdir()
    for p in merl_proxy(*QUICK):
        shutil.copy(p, folder / p.name)
    out = tmp_path / "eval"
    start = time.perf_counter()
    assert main(["evaluate", "--merl-dir", str(folder), "--out", str(out), "--quick"]) == 0
    # Measured 32 s on 2 cores beside a render benchmark; the budget is 3 minutes.
    assert time.perf_counter() - start < 180
    result = json.loads((out / "table1.json").read_text())
    for view in ("2d", "3d"):
        for m in ("dsgplvm", "dsgplvm-paper", "pca", "noll", "chandraker", "ashikhmin", "oracle"):
            assert np.isfinite(result["summary"][view][m]["lab_log"]["mean"])
    assert (out / "table1.md").read_text().count("MERL (NBRDF proxy)") >= 1
    assert (out / "error_vs_runtime.png").stat().st_size > 1000
    assert not list(out.glob(".cache*"))


def test_dsgplvm_extreme_and_gappy_slices(trained):
    from flashbrdf.infer import load_method
    folder, model, slice_csv = trained
    method = load_method(model, "dsgplvm")
    valid = method.predict(np.full((90, 3), 0.1), "2d")[0]
    valid = np.isfinite(valid).all(-1)
    th = np.linspace(0, 1, 90)[:, None]
    chrome = 10 ** (np.log10(4e3) - (np.log10(4e3) + 3) * th) * np.ones((1, 3))
    for s in (chrome, np.zeros((90, 3))):
        table, var = method.predict(s, "2d")
        assert np.isfinite(table[valid]).all() and np.isfinite(var[valid]).all()
    full, _ = views.read_slice_csv(slice_csv)
    gap, zero = full.copy(), full.copy()
    gap[30:45], zero[30:45] = np.nan, 0.0
    p_full, p_gap, p_zero = (np.nan_to_num(method.predict(s, "2d")[0]) for s in (full, gap, zero))
    d_gap = np.abs(np.log1p(p_gap) - np.log1p(p_full)).mean()
    d_zero = np.abs(np.log1p(p_zero) - np.log1p(p_full)).mean()
    assert d_gap < d_zero  # a gap is missing data: zeros would pull the prediction further


def test_anchored_3d_carries_the_2d_correction_over_theta_d_and_phi_d(trained):
    from flashbrdf.brdf.colour import FEATURE_OFFSET as e
    from flashbrdf.infer import load_method
    folder, model, slice_csv = trained
    rho, _ = views.read_slice_csv(slice_csv)
    # the anchoring alone (no observed-row blend, which is tested with the blend below, no
    # slice fit, which changes the weights: tests/test_slice_fit.py, and no consensus:
    # tests/test_infer_consensus.py)
    plain, anchored = (load_method(model, "dsgplvm", merl_dir=folder, anchor=a, row_blend_deg=0,
                                   slice_fit=0, consensus=False) for a in (0, 1))
    u2, a2 = plain.predict(rho, "2d")[0], anchored.predict(rho, "2d")[0]
    u3, a3 = plain.predict(rho, "3d")[0], anchored.predict(rho, "3d")[0]
    ok = merl.merl_valid_mask() & (a3[..., 0] > 0)            # unclamped bins
    c2 = ((a2[:, 0] + e) / (u2[:, 0] + e))                    # (90, 3): the 2D correction
    c3 = (a3 + e) / (u3 + e)                                  # same, per 3D bin
    ih = np.nonzero(ok)[0]
    # One correction per theta_h, computed on the 2D prediction, multiplies every 3D bin: equal up
    # to float64 rounding of the two products.
    np.testing.assert_allclose(c3[ok], c2[ih], rtol=1e-9)
    # At theta_d = 0.5 deg phi_d hardly matters, so the 3D row's phi_d-mean is the 2D row: they
    # differ by where the feature map's log is taken (of the phi_d-mean, or before it) and by the
    # float32 3D path, measured 3.7e-5 relative; 2e-4 leaves a margin of five.
    row3 = np.nanmean(a3[:, 0], axis=1)
    np.testing.assert_allclose(row3, a2[:, 0], rtol=2e-4)
    # With the observed-row blend and the consensus (the default) both views blend toward the
    # same row with the same weights per (theta_h, theta_d) bin, and the 3D view takes the 2D
    # consensus' level per bin, so the same bound holds at theta_d = 0.5 deg.
    blended = load_method(model, "dsgplvm", merl_dir=folder, anchor=1)
    b2, b3 = blended.predict(rho, "2d")[0], blended.predict(rho, "3d")[0]
    np.testing.assert_allclose(np.nanmean(b3[:, 0], axis=1), b2[:, 0], rtol=2e-4)


def test_infer_3d_with_one_of_two_training_folders(merl_proxy, trained, tmp_path, capsys):
    """A model trained on two folders, read with only the first: the absent tables stand in by
    their 2D tables copied across φd. Made φd-constant on purpose, so the stand-in is exact and
    the two 3D predictions must agree: rtol 1e-5 for float32 rows, atol 1e-6 1/sr for the file
    round trip's rounding, far below the metrics' 1e-3 1/sr log offset."""
    folder, _, slice_csv = trained
    flat = tmp_path / "flat"
    flat.mkdir()
    for p in merl_proxy("pink-felt", "chrome"):
        merl.write_merl(flat / p.name, views.table_3d_from_2d(views.table_2d(merl.read_merl(p))))
    model = tmp_path / "model2.npz"
    assert main(["train", "--merl-dir", str(folder), "--merl-dir", str(flat), "--out", str(model)]) == 0
    both, one = tmp_path / "both.binary", tmp_path / "one.binary"
    common = ["infer", "--model", str(model), "--slice", str(slice_csv), "--method", "pca"]
    assert main(common + ["--merl-dir", str(folder), "--merl-dir", str(flat), "--out", str(both)]) == 0
    capsys.readouterr()
    assert main(common + ["--merl-dir", str(folder), "--out", str(one)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "2 of the model's training tables" in err[0]
    assert json.loads(one.with_suffix(".json").read_text())["training_tables_2d_only"] == \
        ["chrome", "pink-felt"]
    ok = merl.merl_valid_mask()
    np.testing.assert_allclose(merl.read_merl(one)[ok], merl.read_merl(both)[ok], rtol=1e-5,
                               atol=1e-6)
    # a folder holding none of the model's tables is still refused
    empty = tmp_path / "other"
    empty.mkdir()
    shutil.copy(merl_proxy("black-obsidian"), empty / "black-obsidian.binary")
    assert main(common + ["--merl-dir", str(empty), "--out", str(tmp_path / "x.binary")]) == 2


def test_evaluate_render_takes_its_envmaps_from_a_flag(tmp_path, capsys, monkeypatch):
    """Nothing may depend on files outside the project unless a flag names them: `evaluate
    --render --envmap FILE` renders Table 2 under FILE, and reads it (exit 2 naming it when it is
    missing) before any training, without ../shared's maps."""

    from synthetic import write_exr
    monkeypatch.setenv("FLASHBRDF_SHARED", str(tmp_path / "no_shared"))
    folder = tmp_path / "merl"
    folder.mkdir()
    (folder / "a.binary").write_bytes(b"")
    missing = tmp_path / "gone_latlong.hdr"
    assert main(["evaluate", "--merl-dir", str(folder), "--out", str(tmp_path / "ev"), "--render",
                 "--envmap", str(missing)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{missing}: file not found" in err[0]
    assert not (tmp_path / "ev").exists()
    from flashbrdf.pipeline.evaluate_job import render_envmaps
    mine = tmp_path / "mine_latlong.exr"
    write_exr(mine, np.ones((4, 8, 3)))
    assert render_envmaps([str(mine)], render=True) == [mine]


def test_evaluate_render_without_envmap_reads_no_file(monkeypatch):
    """The contract's `evaluate ... --render` needs no --envmap: Table 2's default maps are made
    in code (render.envmap.default_envmaps), so nothing is read from ../shared (it was before)."""

    from flashbrdf.pipeline.evaluate_job import render_envmaps
    monkeypatch.setenv("FLASHBRDF_SHARED", "/nonexistent")  # the old fallback's override
    assert render_envmaps(None, render=True) is None


def test_sparse_tail_bins_are_missing_for_inference(trained, tmp_path, capsys):
    """The last θh bins a photo fills are its periphery (rim, corners): bins past the last one of
    >= 20 samples are read as missing. A slice whose two outermost filled bins hold 5 samples
    each, at a tenth of their true value, predicts exactly what the slice without them predicts
    (bit for bit: the same input), lists them in BRDF.json and says so in one stderr line; with
    30 samples each the same bins are read, and the prediction past them drops (checked: > 20%
    in ln ρ on the θd = 0 row past the slice, because anchoring carries their correction on)."""
    from flashbrdf.infer.slices import sparse_tail
    assert np.flatnonzero(sparse_tail(np.r_[0, 5, 30, 40, 25, 7, 3, np.zeros(83)])).tolist() == [5, 6]
    assert not sparse_tail(np.r_[5, 7, 19, np.zeros(87)]).any()  # nothing better observed: kept
    assert not sparse_tail(None).any()
    # A small slice: "sparse" is relative, a quarter of the fullest bin (30 -> 7.5 samples), so
    # only the two bins under 7.5 go, not the seven under 20.
    small = np.r_[25, 30, 22, 18, 15, 12, 10, 8, 6, 4, np.zeros(80)]
    assert np.flatnonzero(sparse_tail(small)).tolist() == [8, 9]
    # A bin whose value is missing holds no sample, whatever its count says: bin 4 (n = 40, empty)
    # does not make bin 3 (7 samples) interior; both sparse bins around it go.
    from flashbrdf.infer.slices import without_sparse_tail
    values = np.ones((90, 3))
    values[4], values[6:] = np.nan, np.nan
    _, ignored = without_sparse_tail(values, np.r_[0, 30, 40, 7, 40, 3, np.zeros(84)])
    assert ignored == [3, 5]
    folder, model, slice_csv = trained
    rho, n = views.read_slice_csv(slice_csv)
    rho[60:], n[60:] = np.nan, 0                       # a slice that ends at bin 59 ...
    last = [58, 59]

    def predict(counts, values, name):
        r, c = rho.copy(), n.copy()
        r[last], c[last] = values, counts
        path = tmp_path / f"{name}.csv"
        views.write_slice_csv(path, r, c)
        out = tmp_path / f"{name}.binary"
        assert main(["infer", "--model", str(model), "--slice", str(path), "--out", str(out)]) == 0
        table = merl.read_merl(out)
        return table, json.loads(out.with_suffix(".json").read_text()), capsys.readouterr().err

    clean, _, _ = predict(0, np.nan, "without")
    sparse, report, err = predict(5, rho[last] * 0.1, "sparse")  # ... or with two dim, sparse bins
    assert np.array_equal(sparse, clean, equal_nan=True)
    assert report["sparse_tail_ignored"]["n"] == [5, 5]
    assert report["observed_theta_h_bins"] == 58
    assert err.count("\n") == 1 and "2 theta_h bin(s)" in err and "treats them as missing" in err
    read, report, _ = predict(30, rho[last] * 0.1, "read")
    assert report["sparse_tail_ignored"] is None
    past = (slice(62, 90), 0, 0)  # θd = 0 row past the slice, one φd bin (copied across φd)
    drop = np.log(clean[past] + 1e-3) - np.log(read[past] + 1e-3)
    assert np.median(drop) > 0.2


def test_sparse_tail_record_tells_the_threshold_used(tmp_path, capsys):
    """An empty bin's n (a count with no value) sets no threshold (without_sparse_tail): so it
    must not set the one BRDF.json and the stderr note tell either. Bins 20-60 of 8 samples and
    61-70 of 1: the threshold is 8 / 4 = 2 whether the empty bin 5 says n = 0 or n = 400 (that
    said 20, the fixed cap, while the 8-sample bins it called sparse were read)."""
    rho = np.full((90, 3), np.nan)
    rho[20:71] = 0.1
    n = np.zeros(90, np.int64)
    n[20:61], n[61:71] = 8, 1
    reports = []
    for count in (0, 400):
        n[5] = count
        path, out = tmp_path / f"s{count}.csv", tmp_path / f"b{count}.binary"
        views.write_slice_csv(path, rho, n)
        assert main(["infer", "--method", "chandraker", "--slice", str(path), "--out",
                     str(out)]) == 0
        record = json.loads(out.with_suffix(".json").read_text())["sparse_tail_ignored"]
        assert record["min_samples"] == 2.0 and record["n"] == [1] * 10
        err = capsys.readouterr().err
        # ten bins of one sample: said once, not ten counts
        assert "past the last one of >= 2 samples (" in err and "deg, 1 sample each)" in err
        reports.append(record)
    assert reports[0] == reports[1]


def test_the_model_stores_its_pca_and_infer_restores_it(trained):
    """train stores the consensus' PCA fit (pca_* arrays); reading the model hands it to the
    training set, and PCA.fit with the same hyperparameters restores it: the predictions equal a
    fresh fit's to 1e-10 (the same eigen-decomposition, read back instead of recomputed)."""
    import zipfile

    from flashbrdf.infer import make_method
    from flashbrdf.infer.model_file import read_model
    model = trained[1]
    members = set(zipfile.ZipFile(model).namelist())
    assert {"pca_params.npy", "pca_ref.npy", "pca_mean.npy", "pca_var.npy",
            "pca_dual.npy"} <= members
    training, params, _ = read_model(model)
    assert training.fitted_pca is not None
    pca_params = params["dsgplvm"]["pca_params"] or {}
    restored = make_method("pca", **pca_params).fit(training)
    training.fitted_pca = None
    fresh = make_method("pca", **pca_params).fit(training)
    flash = training.slices[0]
    np.testing.assert_allclose(restored.predict(flash, "2d")[0], fresh.predict(flash, "2d")[0],
                               rtol=1e-10, equal_nan=True)


def test_train_fills_a_training_table_s_no_data_bins(merl_proxy, tmp_path, capsys):
    """MERL's negative values mean no data. A training table with one (θh, θd) bin of none (every
    φd) and a partial one (half its φd bins) must train, not void a PCA basis or a GP's features
    with NaN (it was a LinAlgError traceback); the note names the table. The fill is ln-linear
    along θh, so on a smooth table it lands within 2% of the value removed (nickel: 1.5%; 0.01%
    to 1.5% over five MERL tables)."""
    folder = tmp_path / "merl"
    folder.mkdir()
    for p in merl_proxy(*TRAIN[:4]):
        shutil.copy(p, folder / p.name)
    table = merl.read_merl(merl_proxy(TRAIN[4]))
    truth = views.table_2d(table)[40, 40].copy()
    table[40, 40] = np.nan                  # write_merl stores NaN as MERL's no-data value
    table[41, 40, :90] = np.nan
    merl.write_merl(folder / "holed.binary", table)
    capsys.readouterr()
    model = tmp_path / "model.npz"
    assert main(["train", "--merl-dir", str(folder), "--out", str(model)]) == 0
    out, err = capsys.readouterr()
    assert "holed.binary: 1 (θh, θd) bin(s) hold no data" in out
    # 5 tables: fewer than any measured model (60: the note names both), and nothing at 60
    assert "note: 5 materials are fewer than any model we measured (60 or more)" in err
    assert small_training_note(60) is None and small_training_note(59).startswith("note: 59 ")
    from flashbrdf.infer.training_set import TrainingSet
    training = TrainingSet.from_merl_dir(folder)
    filled = training.tables_2d[training.names.index("holed")]
    assert np.isfinite(filled[merl.merl_valid_mask().any(axis=2)]).all()
    np.testing.assert_allclose(filled[40, 40], truth, rtol=0.02)
    assert training.filled_bins == {str(folder / "holed.binary"): 1}


def test_the_python_api_predicts_what_infer_writes(trained, tmp_path):
    """load_method(model, "dsgplvm") is the method `flashbrdf infer` runs (the shipped default,
    anchored), not the paper's unanchored one (about twice the error): the same 2D table, to
    the file's float64 round trip."""
    from flashbrdf.infer import load_method
    folder, model, slice_csv = trained
    out = tmp_path / "cli.binary"
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out)]) == 0
    rho, _ = views.read_slice_csv(slice_csv)
    table, _ = load_method(model, "dsgplvm").predict(rho, "2d")
    written = views.table_2d(merl.read_merl(out))
    ok = np.isfinite(written).all(-1)
    np.testing.assert_allclose(table[ok], written[ok], rtol=1e-9, atol=1e-12)
    paper, _ = load_method(model, "dsgplvm", anchor=False).predict(rho, "2d")
    assert not np.allclose(paper[ok], written[ok], rtol=1e-3)


def test_infer_without_model_uses_the_shipped_one_as_run_does(trained, tmp_path):
    """`infer --slice S --out B` as `run` does it: the shipped model, named in BRDF.json (it
    exited 2, "needs a trained model", while -h showed --model as optional)."""
    from flashbrdf.pipeline.options import DEFAULT_MODEL
    _, _, slice_csv = trained
    out = tmp_path / "b.binary"
    assert main(["infer", "--slice", str(slice_csv), "--out", str(out)]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["model"] == str(DEFAULT_MODEL)


@pytest.mark.parametrize("step", [1e-6, 1e-9])
def test_near_duplicate_training_tables_give_a_model_that_loads(merl_proxy, tmp_path, capsys, step):
    """Five copies of one table scaled by 1 + k·step: train exited 0, then infer refused its own
    model as damaged ("the stored tables do not match the trained DS-GPLVM"): the fit saw the
    float64 tables, the file keeps float32, and tables this close differ by little more than
    its rounding. Fitted on the float32 tables the load rebuilds the fit's rows exactly; the
    prediction from one of them is finite and within 1% of it where the slice was observed."""
    folder = tmp_path / "near"
    folder.mkdir()
    table = merl.read_merl(merl_proxy(TRAIN[0]))
    for k in range(5):
        merl.write_merl(folder / f"copy{k}.binary", table * (1 + k * step))
    model = tmp_path / "model.npz"
    assert main(["train", "--merl-dir", str(folder), "--out", str(model)]) == 0
    slice_csv = tmp_path / "s.csv"
    assert main(["merl-slice", str(folder / "copy2.binary"), "--out", str(slice_csv)]) == 0
    out = tmp_path / "o.binary"
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--view", "2d"]) == 0, capsys.readouterr().err
    predicted = views.table_2d(merl.read_merl(out))
    truth = views.table_2d(table)
    assert np.isfinite(predicted[merl.merl_valid_mask().any(axis=2)]).all()
    np.testing.assert_allclose(predicted[:, 0], truth[:, 0], rtol=0.01)


def test_evaluate_scores_no_data_bins_as_missing_and_survives_them(merl_proxy, tmp_path):
    """MERL's negative values mean no data. evaluate's cross-validation filled them for training
    (as it must) but then scored predictions against the filled values, and in 3D one no-data bin
    made the oracle's Gram NaN (a LinAlgError traceback). A table with a whole (θh, θd) bin and
    one more 3D bin of no data: its 2D errors are brdf.metrics' over the bins that hold data,
    exactly, and the 3D figures are finite."""
    from flashbrdf.brdf import metrics
    from flashbrdf.infer import make_method
    folder = tmp_path / "merl"
    folder.mkdir()
    for p in merl_proxy(*TRAIN, TEST):
        shutil.copy(p, folder / p.name)
    table = merl.read_merl(folder / f"{TRAIN[1]}.binary")
    table[50, 60] = np.nan                  # write_merl stores NaN as MERL's no-data value
    table[45, 10, 90] = np.nan
    merl.write_merl(folder / f"{TRAIN[1]}.binary", table)
    out = tmp_path / "eval"
    assert main(["evaluate", "--merl-dir", str(folder), "--out", str(out), "--quick",
                 "--experiments", "5"]) == 0
    result = json.loads((out / "table1.json").read_text())
    (reported,) = [e["errors_2d"]["chandraker"][e["test"].index(TRAIN[1])]
                   for e in result["per_experiment"] if TRAIN[1] in e["test"]]
    truth = views.table_2d(table)
    assert np.isnan(truth[50, 60]).all()
    prediction = make_method("chandraker").fit(None).predict(views.flash_slice(table)[0], "2d")[0]
    want = metrics.brdf_errors(prediction, truth)
    for key, value in want.items():
        assert reported[key] == pytest.approx(value, rel=1e-9), key
    for m in ("dsgplvm", "pca", "noll", "chandraker", "ashikhmin", "oracle"):
        assert np.isfinite(result["summary"]["3d"][m]["lab_log"]["mean"])


def test_infer_3d_checks_that_merl_dir_holds_the_models_tables(trained, tmp_path, capsys):
    """The 3D prediction mixes the --merl-dir tables matched by name, and tables under the
    model's names but of other materials gave LAB-log 30 where the right ones give 4, at exit 0.
    Another material (its θd = 0 slice off by more than a factor 2) is refused, naming the file;
    a table off by 5% (real MERL files beside a model trained on proxies) is used, with a
    warning and a record in BRDF.json."""
    folder, model, slice_csv = trained
    swapped, scaled = tmp_path / "swapped", tmp_path / "scaled"
    for d in (swapped, scaled):
        shutil.copytree(folder, d)
    shutil.copy(folder / f"{TRAIN[4]}.binary", swapped / f"{TRAIN[0]}.binary")  # nickel as gold
    table = merl.read_merl(folder / f"{TRAIN[1]}.binary")
    merl.write_merl(scaled / f"{TRAIN[1]}.binary", table * 1.05)
    capsys.readouterr()
    out = tmp_path / "a.binary"
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--merl-dir", str(swapped)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{TRAIN[0]}.binary: is not the table" in err[0] and not out.exists()
    # a 2D prediction reads none of them: not refused over them
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--merl-dir", str(swapped), "--view", "2d"]) == 0
    out.unlink()
    out.with_suffix(".json").unlink()
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--merl-dir", str(scaled)]) == 0
    err = capsys.readouterr().err
    assert "1 of the --merl-dir tables differ" in err and "5%" in err
    record = json.loads(out.with_suffix(".json").read_text())
    # 5%, less what the comparison's 1e-4 1/sr offset takes off dark bins (ρ ~ 0.02 there: 0.5%)
    assert record["training_tables_differing"] == {TRAIN[1]: pytest.approx(0.05, rel=0.01)}


def test_a_3d_prediction_carries_the_2d_views_per_bin_variance(trained, tmp_path):
    """A 3D prediction's variance was the GP's one number for the whole table (mean = median =
    max in BRDF.json), uncalibrated, while the docs promise a per-bin variance; it is the 2D
    prediction's per-(θh, θd, channel) variance, calibrated, the same across φd."""
    from flashbrdf.infer import load_method
    folder, model, slice_csv = trained
    method = load_method(model, "dsgplvm", folder)
    rho = views.read_slice_csv(slice_csv)[0]
    table_3d, variance_3d = method.predict(rho, "3d")
    variance_2d = method.predict(rho, "2d")[1]
    assert variance_3d.shape == table_3d.shape == (90, 90, 180, 3)
    assert np.array_equal(np.isnan(variance_3d), np.isnan(table_3d))   # no value, no variance
    seen = np.isfinite(table_3d[:, :, 37])
    np.testing.assert_array_equal(variance_3d[:, :, 37][seen], variance_2d[seen])
    finite = variance_2d[np.isfinite(variance_2d)]
    assert finite.size > 10_000 and finite.max() > 2 * np.median(finite)


def test_train_refuses_tables_that_are_one_once_mapped(tmp_path, capsys):
    """Five constant tables of 0 to 4e-25 1/sr differ in float32, so training took them, and
    wrote a model every `infer` then refused as damaged (their pca-mapped rows are one row:
    no component). train says so itself: exit 2, one line naming --merl-dir, no model."""
    from flashbrdf.brdf import merl
    folder = tmp_path / "dark"
    folder.mkdir()
    valid = merl.merl_valid_mask()[..., None]
    for k, value in enumerate([0.0, 1e-25, 2e-25, 3e-25, 4e-25]):
        merl.write_merl(folder / f"t{k}.binary",
                        np.where(valid, value, np.nan) * np.ones(merl.MERL_SHAPE + (3,)))
    capsys.readouterr()
    assert main(["train", "--merl-dir", str(folder), "--out", str(tmp_path / "m.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--merl-dir: the 5 training tables are one table" in err[0]
    assert not (tmp_path / "m.npz").exists()
