"""The validation grid search that picks hyperparameters, for `flashbrdf train` (tune_baselines)
and for every experiment of the Table 1 protocol (experiments.evaluate).

Methods are scored by the mean LAB-log error (brdf.metrics) of their 2D predictions on held-out
materials; grids are scikit-learn ParameterGrids over the methods' constructor arguments.
"""

import os
import time

import numpy as np
from joblib import Parallel, delayed
from sklearn.model_selection import ParameterGrid

from brdf import metrics
from infer import make_method
from infer.adapter import calibration_factor

DS_GRID = {"q": [None], "beta": [50.0, 100.0], "feature_space": ["lab", "rgb"]}
DS_FIXED = {"anchor": True}                      # "dsgplvm" is the anchored DS-GPLVM of infer/run
PCA_GRID = {"n_components": [3, 6, 12, 24, None], "ridge": [1e-3, 1e-2, 1e-1, 1.0, 10.0]}


def errors_2d(method, data, index):
    """[brdf_errors dict] of a fitted method's 2D predictions for materials `index` of `data`."""
    return [metrics.brdf_errors(_predict_2d(method, data.slices[i], data.tables_2d[i]),
                                data.tables_2d[i]) for i in index]


def _predict_2d(method, rho, table):
    """A fitted method's 2D prediction from slice rho; evaluation-only methods see the table."""
    return method.predict_truth(table) if method.evaluation_only else method.predict(rho, "2d")[0]


def lab_log(errs):
    return float(np.mean([e["lab_log"] for e in errs]))


def valid_lab_log(method, data, index):
    """lab_log(errors_2d(method, data, index)), computing that one error only (the grid's score)."""
    return float(np.mean([metrics.brdf_error(_predict_2d(method, data.slices[i], data.tables_2d[i]),
                                             data.tables_2d[i], "log", "lab") for i in index]))


def _trial(name, params, train, valid, data):
    """Fit one grid point and score it on the validation materials: -> trial dict."""
    t0 = time.perf_counter()
    m = make_method(name, **params).fit(train)
    fit_s = time.perf_counter() - t0
    return {"params": params, "valid_lab_log": valid_lab_log(m, data, valid), "fit_s": fit_s,
            "method": m}


def select(name, grid, train, valid, data, fixed=None, workers=1):
    """Grid search on validation LAB-log: -> (best fitted method, best params, [(params, err, s)]).

    workers > 1 fits the grid points in that many processes (joblib); each fit is the same
    deterministic computation in any process (DSGPLVM.fit runs its BLAS on one thread), so the
    result does not depend on `workers`; ties go to the first grid point either way.
    """
    # in the grid's key order (ParameterGrid sorts them), as the reports print them
    combos = [{k: combo[k] for k in grid} | (fixed or {}) for combo in ParameterGrid(grid)]
    workers = max(1, min(workers, len(combos)))
    if workers == 1:
        trials = [_trial(name, params, train, valid, data) for params in combos]
    else:
        trials = Parallel(n_jobs=workers)(delayed(_trial)(name, params, train, valid, data)
                                          for params in combos)
    best = min(trials, key=lambda t: t["valid_lab_log"])     # min keeps the first of equals
    return best["method"], best["params"], trials


def training_workers():
    """Processes for the validation fits of `train`: $FLASHBRDF_THREADS (a worker's share of the
    cores, as in infer.estimator), else one per core, at most 2 (the "auto" feature-space grid
    has two points)."""
    return max(1, int(os.environ.get("FLASHBRDF_THREADS") or min(os.cpu_count() or 1, 2)))


def tune_baselines(training, seed=0, feature_space="auto", workers=None):
    """Hyperparameters for `flashbrdf train`: ashikhmin r0 on all; pca and (feature_space "auto")
    the DS-GPLVM's feature space on a seeded 80/20 split, scored like Table 1's validation.
    workers: processes for the DS-GPLVM validation fits (default training_workers(); the
    result is the same for any number)."""
    workers = training_workers() if workers is None else workers
    n = len(training)
    order = np.random.default_rng(seed).permutation(n)
    cut = max(1, n // 5)
    valid, train = np.sort(order[:cut]), np.sort(order[cut:])
    grid = {k: [v for v in vals if v is None or v < len(train)] for k, vals in PCA_GRID.items()}
    _, pca_params, _ = select("pca", grid, training.subset(train), valid, training)
    spaces = DS_GRID["feature_space"] if feature_space == "auto" else [feature_space]
    best, ds, _ = select("dsgplvm", {"feature_space": spaces},
                         training.subset(train), valid, training, fixed=DS_FIXED, workers=workers)
    # the per-bin variance is calibrated on the same held-out 20%: central 90% intervals there
    # cover 90% of the bins
    kappa = calibration_factor(best, training.slices[valid], training.tables_2d[valid])
    return {"pca": pca_params, "ashikhmin": make_method("ashikhmin").fit(training).fitted_params(),
            "noll": {}, "chandraker": {},
            "dsgplvm": {"feature_space": ds["feature_space"], "calibration": kappa}}
