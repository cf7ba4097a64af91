"""`train` / `infer` on several --merl-dir folders and `evaluate --test-dir` (experiments.test_set),
in-process on a few MERL (NBRDF proxy) tables."""

import json
import shutil

import numpy as np
import pytest

from flashbrdf.brdf import merl, metrics, views
from flashbrdf.experiments.test_set import THETA_D_BANDS_DEG, band_errors, band_label
from flashbrdf.cli.main import main

FOLDER_A = ["gold-metallic-paint", "blue-acrylic", "white-fabric"]
FOLDER_B = ["red-plastic", "nickel"]
TEST = ["green-plastic", "pink-felt"]
METHODS = ["dsgplvm", "pca", "noll", "chandraker", "ashikhmin", "dsgplvm-paper", "oracle"]


def _folder(root, name, paths):
    folder = root / name
    folder.mkdir()
    for p in paths:
        shutil.copy(p, folder / p.name)
    return folder


@pytest.fixture(scope="module")
def folders(merl_proxy, tmp_path_factory):
    root = tmp_path_factory.mktemp("test_set")
    a = _folder(root, "a", merl_proxy(*FOLDER_A))
    b = _folder(root, "b", merl_proxy(*FOLDER_B))
    test = _folder(root, "rgl_like", merl_proxy(*TEST))
    model = root / "model.npz"
    assert main(["train", "--merl-dir", str(a), "--merl-dir", str(b), "--out", str(model)]) == 0
    return root, a, b, test, model


def test_train_on_repeated_merl_dirs_is_the_union_and_infers_3d_from_both(folders, tmp_path):
    root, a, b, test, model = folders
    with np.load(model) as z:
        assert [str(n) for n in z["names"]] == sorted(FOLDER_A) + sorted(FOLDER_B)  # by folder
        assert [str(d) for d in z["merl_dirs"]] == [str(a), str(b)]
    slice_csv = tmp_path / "slice.csv"
    assert main(["merl-slice", str(test / f"{TEST[0]}.binary"), "--out", str(slice_csv)]) == 0
    out = tmp_path / "pca3d.binary"
    # 3D needs every training table: three are in a, two in b (matched by name).
    assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(out),
                 "--method", "pca", "--merl-dir", str(a), "--merl-dir", str(b)]) == 0
    assert json.loads(out.with_suffix(".json").read_text())["view"] == "3d"
    assert np.isfinite(merl.read_merl(out)[merl.merl_valid_mask()]).all()


def test_train_refuses_duplicate_names_and_empty_folders(folders, tmp_path, capsys):
    root, a, b, test, model = folders
    dup = _folder(tmp_path, "dup", [a / f"{FOLDER_A[0]}.binary"])
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "m.npz"
    capsys.readouterr()
    assert main(["train", "--merl-dir", str(a), "--merl-dir", str(dup), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(a / f"{FOLDER_A[0]}.binary") in err[0] \
        and str(dup / f"{FOLDER_A[0]}.binary") in err[0]
    assert main(["train", "--merl-dir", str(a), "--merl-dir", str(empty), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(empty) in err[0]
    # a test table that is also a training table is refused the same way
    eval_out = tmp_path / "eval"
    assert main(["evaluate", "--merl-dir", str(a), "--merl-dir", str(b), "--test-dir", str(dup),
                 "--out", str(eval_out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()   # it names the test folder as one
    assert len(err) == 1 and "across the --merl-dir and --test-dir folders" in err[0]
    # and so is one under another name: a copy of a training table scored as unseen
    renamed = _folder(tmp_path, "renamed", [test / f"{TEST[0]}.binary"])
    shutil.copy(b / f"{FOLDER_B[1]}.binary", renamed / "my-metal.binary")
    assert main(["evaluate", "--merl-dir", str(a), "--merl-dir", str(b), "--test-dir",
                 str(renamed), "--out", str(eval_out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"flashbrdf evaluate: error: {renamed}")
    assert "my-metal.binary: holds the same table as the training table" in err[0]
    assert str(b / f"{FOLDER_B[1]}.binary") in err[0]
    assert not out.exists() and not eval_out.exists()
    assert not list(tmp_path.glob(".*"))                      # no staged leftovers


def test_train_takes_a_copy_of_a_table_under_another_name(folders, tmp_path, capsys):
    """A table given twice (a user's folder holding a copy of one of MERL's) is a duplicate
    training BRDF, which the GPs' jittered Cholesky takes: train succeeds and the copy is a
    material of the model. Four tables of which only three differ are refused, naming the copy."""
    root, a, b, test, model = folders
    copy = tmp_path / "copy"
    copy.mkdir()
    shutil.copy(a / f"{FOLDER_A[0]}.binary", copy / "my-gold.binary")
    out = tmp_path / "m.npz"
    assert main(["train", "--merl-dir", str(a), "--merl-dir", str(b), "--merl-dir", str(copy),
                 "--out", str(out)]) == 0
    slice_csv = tmp_path / "s.csv"
    assert main(["merl-slice", str(test / f"{TEST[0]}.binary"), "--out", str(slice_csv)]) == 0
    assert main(["infer", "--model", str(out), "--slice", str(slice_csv), "--out",
                 str(tmp_path / "p.binary")]) == 0
    predicted = merl.read_merl(tmp_path / "p.binary")
    assert np.isfinite(predicted[merl.merl_valid_mask()]).all()   # NaN: below the horizon
    capsys.readouterr()
    out3 = tmp_path / "m3.npz"
    assert main(["train", "--merl-dir", str(a), "--merl-dir", str(copy), "--out", str(out3)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(copy / "my-gold.binary") in err[0] and "3 of the 4" in err[0]
    assert not out3.exists()
    # the rule is on the whole training set, not per folder: a folder of two tables given twice
    # each (2 of 4 differ) trains beside folder b
    pairs = tmp_path / "pairs"
    pairs.mkdir()
    for name in FOLDER_A[:2]:
        for copy_name in (name, f"{name}-again"):
            shutil.copy(a / f"{name}.binary", pairs / f"{copy_name}.binary")
    assert main(["train", "--merl-dir", str(pairs), "--merl-dir", str(b), "--out",
                 str(tmp_path / "m4.npz")]) == 0


def test_band_errors_partition_theta_d():
    rng = np.random.default_rng(0)
    truth = np.where(merl.merl_valid_mask().any(axis=2)[..., None],
                     rng.uniform(0.01, 2.0, (90, 90, 3)), np.nan)
    pred = truth.copy()
    pred[:, 60:75] *= 3.0          # bins j = 60..74 have centres 60.5..74.5: the 60-75 band only
    errs = {b: e["lab_log"] for b, e in band_errors(pred, truth).items()}
    assert list(errs) == ["0-30", "30-60", "60-75", "75-90"]
    assert errs["0-30"] == errs["30-60"] == errs["75-90"] == 0.0 and errs["60-75"] > 1.0
    # The bands partition theta_d, and LAB-log is a mean over valid bins: the whole-table error is
    # the bands' errors weighted by their valid-bin counts, up to float64 summation order.
    valid = np.isfinite(truth).all(-1)
    counts = [valid[:, lo:hi].sum() for lo, hi in THETA_D_BANDS_DEG]
    whole = sum(c * errs[band_label(b)] for c, b in zip(counts, THETA_D_BANDS_DEG)) / sum(counts)
    assert whole == pytest.approx(metrics.brdf_error(pred, truth, "log", "lab"), rel=1e-12)


def test_evaluate_test_dir_scores_every_method_on_every_table_as_infer_does(folders, tmp_path,
                                                                             capsys):
    root, a, b, test, model = folders
    out = tmp_path / "eval"
    # the cross-validation protocol's options change nothing here, and it says so
    assert main(["evaluate", "--merl-dir", str(a), "--merl-dir", str(b), "--test-dir", str(test),
                 "--out", str(out), "--quick", "--workers", "2"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "change nothing" in line]
    assert len(warned) == 1 and warned[0].startswith("warning: --quick, --workers shape")
    result = json.loads((out / "test_set.json").read_text())
    assert result["label"] == "rgl_like" and result["train"]["materials"] == sorted(FOLDER_A) + sorted(FOLDER_B)
    assert list(result["methods"]) == METHODS
    for name, r in result["methods"].items():
        assert sorted(r["per_material"]) == sorted(TEST)
        for row in r["per_material"].values():
            assert np.isfinite([row[k] for k in ("lab_log", "rgb_lin", "lab_root")]).all()
            assert list(row["bands"]) == ["0-30", "30-60", "60-75", "75-90"]
            assert all(np.isfinite(e["lab_log"]) and len(e) == 6 for e in row["bands"].values())
        mean = np.mean([row["lab_log"] for row in r["per_material"].values()])
        assert r["lab_log_mean"] == pytest.approx(mean, rel=1e-12)
        assert r["predict_ms"] > 0 and r["fit_s"] >= 0
    md = (out / "test_set.md").read_text()
    assert "rgl_like" in md and all(f"## {m} per test table" in md for m in METHODS)
    # What `infer` writes from `train`'s model on the same slice scores the same, to rounding:
    # same training code, same model file, same anchoring (the slice CSV holds repr() floats).
    for name in TEST:
        slice_csv, brdf = tmp_path / f"{name}.csv", tmp_path / f"{name}.binary"
        assert main(["merl-slice", str(test / f"{name}.binary"), "--out", str(slice_csv)]) == 0
        assert main(["infer", "--model", str(model), "--slice", str(slice_csv), "--out", str(brdf),
                     "--view", "2d"]) == 0
        truth = views.table_2d(merl.read_merl(test / f"{name}.binary"))
        ours = metrics.brdf_errors(views.table_2d(merl.read_merl(brdf)), truth)
        scored = result["methods"]["dsgplvm"]["per_material"][name]
        for k, v in ours.items():
            assert scored[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
