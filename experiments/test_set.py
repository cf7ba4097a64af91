"""The external test-set protocol of `flashbrdf evaluate --test-dir`: train every method on one set
of tables, score it on another that it never saw.

Training is exactly `flashbrdf train` (infer.training.train_model: the same hyperparameter
selection, the same model file), and every method in the model file is scored as `flashbrdf infer`
loads it (through the file, dsgplvm anchored), so a number here is what a user gets from
`train` + `infer`. Two methods are not in the model file and are fitted beside it:
`dsgplvm-paper` (experiments.evaluate.build_method: log-LAB features, unanchored, default β) and the
`oracle` (the true table projected on the training PCA basis, default ridge).

Scores per test table (2D, ρ(θh, θd) against the table's own 2D view):
- all six Table 1 errors of brdf.metrics;
- the same six per θd band: the bins j whose centre j + 0.5° lies in [lo, hi) (THETA_D_BANDS_DEG);
  the report's band columns are LAB-log;
- the prediction's wall time (one slice, 2D).
Then mean and median across test tables.
"""

import json
import os
import sys
import tempfile
import time

import numpy as np

from flashbrdf.brdf import merl, metrics
from flashbrdf.files.atomic import write_text
from flashbrdf.infer import METHODS, TrainingSet, make_method
from flashbrdf.experiments.evaluate import PAPER, warm_up, build_method
from flashbrdf.infer.model_file import load_methods
from flashbrdf.infer.model_selection import check_training_size
from flashbrdf.infer.training_set import check_unseen
from flashbrdf.experiments.table1_report import summarise_errors
from flashbrdf.infer.training import train_model

THETA_D_BANDS_DEG = ((0, 30), (30, 60), (60, 75), (75, 90))
METRICS = tuple(f"{s}_{t}" for s in metrics.SPACES for t in metrics.TRANSFORMS)
BESIDE_MODEL = (PAPER, "oracle")          # scored methods that the model file does not hold
INFER_OVERRIDES = {"dsgplvm": {"anchor": True}}   # what `infer` and `run` pass without --no-anchor


def band_label(band):
    """(30, 60) -> "30-60"."""
    return f"{band[0]}-{band[1]}"


def band_errors(pred_2d, true_2d, bands=THETA_D_BANDS_DEG):
    """The six Table 1 errors of a 2D prediction per θd band: {"0-30": {"lab_log": …, …}, …}.

    pred_2d, true_2d: (90, 90, 3) over (θh, θd) in 1/sr, NaN where no data. A band holds the θd
    bins j with j + 0.5 degrees in [lo, hi); errors are brdf.metrics' over its valid bins.
    """
    centres = np.arange(merl.N_THETA_D) + 0.5
    out = {}
    for lo, hi in bands:
        sel = (centres >= lo) & (centres < hi)
        out[band_label((lo, hi))] = metrics.brdf_errors(np.asarray(pred_2d)[:, sel],
                                                        np.asarray(true_2d)[:, sel])
    return out


def default_methods():
    """Every method `infer` offers, then dsgplvm-paper and the oracle."""
    return [m for m in METHODS if not make_method(m).evaluation_only] + list(BESIDE_MODEL)


def _fit_beside_model(name, train, seed):
    """dsgplvm-paper or the oracle, fitted on `train` in memory: -> (method, seconds)."""
    start = time.perf_counter()
    method = build_method(PAPER, seed=seed) if name == PAPER else make_method(name)
    return method.fit(train), time.perf_counter() - start


def _score(method, test):
    """Per-material scores of one fitted method on every table of `test`: {name: {...}}."""
    out = {}
    for i, name in enumerate(test.names):
        truth = test.scored_table(i)   # no-data bins NaN, whether or not the set was filled
        start = time.perf_counter()
        if method.evaluation_only:
            pred = method.predict_truth(truth)
        else:
            pred = method.predict(test.slices[i], "2d")[0]
        seconds = time.perf_counter() - start
        out[name] = metrics.brdf_errors(pred, truth) | {
            "bands": band_errors(pred, truth), "predict_ms": 1e3 * seconds}
    return out


def _summary(per_material):
    """Mean/median over materials of the six errors, the bands and the prediction time."""
    rows = list(per_material.values())
    six = summarise_errors([{k: r[k] for k in METRICS} for r in rows])
    bands = {b: summarise_errors([r["bands"][b] for r in rows]) for b in rows[0]["bands"]}
    ms = metrics.summarise([r["predict_ms"] for r in rows])
    return {"lab_log_mean": six["lab_log"]["mean"], "lab_log_median": six["lab_log"]["median"],
            "predict_ms": ms["mean"], "predict_ms_median": ms["median"],
            "summary": six, "bands": bands}


def score_methods(train, test, methods=None, seed=0, feature_space="auto"):
    """Train on `train`, score on `test` (both TrainingSet): the held-out protocol, for any split
    (e.g. MERL plus every RGL fold but one; call it once per fold):

        data = TrainingSet.from_merl_dirs([merl_dir, rgl_dir])
        score_methods(data.subset(train_index), data.subset(fold_index))

    methods: names from default_methods() (None: all). Returns {"train": {"materials", "train_s",
    "tuning_s"}, "test": {"materials"}, "bands_deg", "methods": {name: {"lab_log_mean",
    "lab_log_median", "predict_ms" (mean over test tables), "predict_ms_median", "fit_s",
    "params", "summary" (six errors: mean, median, n), "bands" ({band: the same}),
    "per_material" ({name: six errors, "bands", "predict_ms"})}}}.
    fit_s: dsgplvm's final DS-GPLVM fit (its validation fits are in train.tuning_s); the other
    model-file methods' fit when loaded (what `infer` does); dsgplvm-paper and oracle their fit.
    """
    names = list(methods or default_methods())
    unknown = [n for n in names if n not in default_methods()]
    if unknown:
        raise ValueError(f"unknown method {unknown[0]!r}; expected some of {default_methods()}")
    warm_up()   # geometry caches, so that the first prediction's time is a prediction's
    from_file = [n for n in names if n not in BESIDE_MODEL]
    fitted, fit_s, record = {}, {}, {"materials": list(train.names)}
    if from_file:
        with tempfile.TemporaryDirectory(prefix="flashbrdf_test_set_") as folder:
            path = os.path.join(folder, "model.npz")
            params = train_model(train, path, seed=seed, feature_space=feature_space)
            fitted = load_methods(path, from_file, overrides=INFER_OVERRIDES, fit_seconds=fit_s)
        record |= {"train_s": params["train_seconds"],
                   "tuning_s": params["fit_seconds"]["tuning"]}
        if "dsgplvm" in fit_s:
            fit_s["dsgplvm"] = params["fit_seconds"]["dsgplvm"]
    for name in names:
        if name in BESIDE_MODEL:
            fitted[name], fit_s[name] = _fit_beside_model(name, train, seed)
    result = {"train": record, "test": {"materials": list(test.names)},
              "bands_deg": [list(b) for b in THETA_D_BANDS_DEG], "methods": {}}
    for name in names:
        per_material = _score(fitted[name], test)
        result["methods"][name] = _summary(per_material) | {
            "fit_s": fit_s[name], "params": fitted[name].fitted_params(),
            "per_material": per_material}
    return result


def run_test_set(merl_dirs, test_dir, out_dir, seed=0, label=None, command=None):
    """`flashbrdf evaluate --merl-dir ... --test-dir DIR`: train on every table of `merl_dirs`,
    score every method on the tables of `test_dir`; write out_dir/test_set.json and test_set.md.
    label: how the test data is named in the report (default: the test folder's name). Material
    names must be unique across all folders, the test folder's included, and no test table may
    hold a training table's values under another name (InputError naming both files): a test
    table is never also a training table."""
    merl.list_merl_dirs(list(merl_dirs) + [test_dir], "the --merl-dir and --test-dir folders",
                        ": a test table is never also a training table")
    train = TrainingSet.from_merl_dirs(merl_dirs)
    check_training_size(len(train), "--merl-dir")
    test = TrainingSet.from_merl_dir(test_dir, fill=False)  # scored only: holes stay holes
    check_unseen(test, train)
    start = time.perf_counter()
    result = score_methods(train, test, seed=seed)
    label = label or os.path.basename(os.path.normpath(test_dir))
    result = {"command": command or "flashbrdf " + " ".join(sys.argv[1:]),
              "train_dirs": [str(d) for d in merl_dirs], "test_dir": str(test_dir),
              "label": label, "seed": seed, "wall_s": time.perf_counter() - start} | result
    write_text(os.path.join(out_dir, "test_set.json"),
               json.dumps(result, indent=1, default=str) + "\n")
    write_text(os.path.join(out_dir, "test_set.md"), test_set_markdown(result))
    return result


def _f(x, digits=2):
    return "—" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def test_set_markdown(result):
    """The report of run_test_set: summary, per band, per material (LAB-log), then each method's
    per-material table of all six errors, the bands and the prediction time."""
    methods = result["methods"]
    bands = [band_label(b) for b in result["bands_deg"]]
    test_names = result["test"]["materials"]
    best = min(methods, key=lambda m: methods[m]["lab_log_mean"])
    lines = [f"# External test set: {result['label']}", "",
             f"Command: `{result['command']}`", "",
             f"Trained on {len(result['train']['materials'])} tables from "
             + ", ".join(f"`{d}`" for d in result["train_dirs"])
             + f"; scored on the {len(test_names)} tables of `{result['test_dir']}`, none of "
             "them trained on. 2D predictions from each table's full θd = 0 slice; errors as "
             "the contract defines them (Table 1). Training is `flashbrdf train`'s (same "
             "hyperparameter selection, seed "
             f"{result['seed']}); dsgplvm is anchored as `flashbrdf infer` makes it. "
             "dsgplvm-paper is the paper's DS-GPLVM (log-LAB, unanchored); the oracle projects "
             "the true table on the training PCA basis, so no method is expected to reach it.", "",
             "## Summary (LAB-log, mean / median over test tables)", "",
             "| method | LAB-log | " + " | ".join(f"θd {b}°" for b in bands)
             + " | predict ms | fit s |", "|---|---|" + "---|" * len(bands) + "---|---|"]
    for m, r in methods.items():
        mark = "**" if m == best else ""
        lines.append(f"| {m} | {mark}{_f(r['lab_log_mean'])} / {_f(r['lab_log_median'])}{mark} | "
                     + " | ".join(f"{_f(r['bands'][b]['lab_log']['mean'])} / "
                                  f"{_f(r['bands'][b]['lab_log']['median'])}" for b in bands)
                     + f" | {_f(r['predict_ms'], 1)} | {_f(r['fit_s'], 1)} |")
    lines += ["", "## All six errors (mean / median over test tables)", "",
              "| method | " + " | ".join(METRICS) + " |", "|---|" + "---|" * len(METRICS)]
    for m, r in methods.items():
        lines.append(f"| {m} | " + " | ".join(
            f"{_f(r['summary'][k]['mean'], 3)} / {_f(r['summary'][k]['median'], 3)}"
            for k in METRICS) + " |")
    lines += ["", "## LAB-log per test table", "",
              "| material | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for name in test_names:
        lines.append(f"| {name} | " + " | ".join(
            _f(methods[m]["per_material"][name]["lab_log"]) for m in methods) + " |")
    for m, r in methods.items():
        lines += ["", f"## {m} per test table", "",
                  "| material | " + " | ".join(METRICS) + " | "
                  + " | ".join(f"θd {b}°" for b in bands) + " | ms |",
                  "|---|" + "---|" * (len(METRICS) + len(bands) + 1)]
        for name in test_names:
            row = r["per_material"][name]
            lines.append(f"| {name} | " + " | ".join(_f(row[k], 3) for k in METRICS) + " | "
                         + " | ".join(_f(row["bands"][b]["lab_log"]) for b in bands)
                         + f" | {_f(row['predict_ms'], 1)} |")
    train = result["train"]
    if "train_s" in train:
        lines += ["", f"Training took {train['train_s']:.1f} s, of which {train['tuning_s']:.1f} s "
                  "were the validation fits that choose hyperparameters; the whole run "
                  f"{result['wall_s']:.0f} s."]
    return "\n".join(lines) + "\n"
